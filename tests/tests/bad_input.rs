//! Bad input gets a clear error naming the file and the problem — never a panic.
//!
//! One test binary with one panic hook: any panic anywhere during these imports (even one the
//! importer would catch) fails the test.

use kage_engine::scene::import::{ImportOptions, import};
use kage_engine::scene::{EnvMap, Scene};
use kage_tests::{asset, scratch};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

static PANICS: AtomicUsize = AtomicUsize::new(0);

fn count_panics() {
    std::panic::set_hook(Box::new(|info| {
        PANICS.fetch_add(1, Ordering::SeqCst);
        eprintln!("PANIC: {info}");
    }));
}

/// A one-triangle glTF with an external `.bin`; `edit` tweaks the JSON before writing.
fn write_gltf(
    dir: &Path,
    name: &str,
    positions: &[[f32; 3]],
    indices: &[u32],
    edit: impl FnOnce(&mut Value),
) -> PathBuf {
    let mut bin: Vec<u8> = positions.iter().flatten().flat_map(|f| f.to_le_bytes()).collect();
    let pos_len = bin.len();
    bin.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
    let bin_name = format!("{name}.bin");
    std::fs::write(dir.join(&bin_name), &bin).unwrap();
    let mut doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1.0]}}],
        "buffers": [{"uri": bin_name, "byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": pos_len},
            {"buffer": 0, "byteOffset": pos_len, "byteLength": bin.len() - pos_len}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": positions.len(), "type": "VEC3",
             "min": [-1.0, -1.0, -1.0], "max": [1.0, 1.0, 1.0]},
            {"bufferView": 1, "componentType": 5125, "count": indices.len(), "type": "SCALAR"}
        ]
    });
    edit(&mut doc);
    let path = dir.join(format!("{name}.gltf"));
    std::fs::write(&path, serde_json::to_vec_pretty(&doc).unwrap()).unwrap();
    path
}

const TRI: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]];

fn expect_error(path: &Path, needle: &str) {
    let err = match import(path, ImportOptions::default()) {
        Ok(_) => panic!("{} imported but should fail with '{needle}'", path.display()),
        Err(e) => e.to_string(),
    };
    let file = path.file_name().unwrap().to_str().unwrap();
    assert!(err.contains(file), "error names the file: {err}");
    assert!(err.contains(needle), "error for {file} says '{needle}': {err}");
}

fn synthetic_files_are_rejected_clearly() {
    let dir = scratch!("bad-input");
    let ok = write_gltf(&dir, "ok", &TRI, &[0, 1, 2], |_| {});
    import(&ok, ImportOptions::default()).expect("the unmodified file is valid");

    let malformed = dir.join("malformed.gltf");
    std::fs::write(&malformed, b"{\"asset\": {\"version\": \"2.0\"").unwrap();
    expect_error(&malformed, "not a readable glTF file");
    expect_error(&dir.join("does_not_exist.gltf"), "No such file");
    let p = write_gltf(&dir, "missing_buffer", &TRI, &[0, 1, 2], |d| d["buffers"][0]["uri"] = json!("gone.bin"));
    expect_error(&p, "cannot load buffer data");
    let p = write_gltf(&dir, "vec2_positions", &TRI, &[0, 1, 2], |d| {
        d["accessors"][0]["type"] = json!("VEC2");
        d["accessors"][0]["min"] = json!([-1.0, -1.0]);
        d["accessors"][0]["max"] = json!([1.0, 1.0]);
    });
    expect_error(&p, "attributes[\"POSITION\"].min: Invalid value");
    let p = write_gltf(&dir, "scalar_normals", &TRI, &[0, 1, 2], |d| {
        d["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = json!(1)
    });
    expect_error(&p, "attribute Normals has type Scalar U32");
    let p = write_gltf(&dir, "index_oob", &TRI, &[0, 1, 7], |_| {});
    expect_error(&p, "triangle 0 uses vertex index 7");
    let p = write_gltf(&dir, "accessor_oob", &TRI, &[0, 1, 2], |d| d["accessors"][0]["count"] = json!(30));
    expect_error(&p, "30 elements do not fit");
    // A stride shorter than a float VEC3: an error before the gltf crate's reader asserts.
    let p = write_gltf(&dir, "short_stride", &TRI, &[0, 1, 2], |d| d["bufferViews"][0]["byteStride"] = json!(4));
    expect_error(&p, "bufferViews[0].byteStride 4 is smaller than one element (12 bytes)");
    // Found by tests/tests/fuzz.rs: the gltf crate's readers subtract 1 from a count of 0 and
    // unwrap an image's URI.
    let p = write_gltf(&dir, "count_zero", &TRI, &[0, 1, 2], |d| d["accessors"][1]["count"] = json!(0));
    expect_error(&p, "accessors[1]: count is 0");
    let p = write_gltf(&dir, "image_without_source", &TRI, &[0, 1, 2], |d| d["images"] = json!([{"name": "x"}]));
    expect_error(&p, "images[0]: needs exactly one of uri and bufferView");
    let p = write_gltf(&dir, "cycle", &TRI, &[0, 1, 2], |d| {
        d["nodes"] = json!([{"mesh": 0, "children": [1]}, {"children": [2]}, {"children": [1]}]);
    });
    expect_error(&p, "two parents");
    let p = write_gltf(&dir, "pure_cycle", &TRI, &[0, 1, 2], |d| {
        d["nodes"] = json!([{"mesh": 0}, {"children": [2]}, {"children": [1]}]);
    });
    expect_error(&p, "cycle through nodes[1]");
    let nan = [[0.0, f32::NAN, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]];
    expect_error(&write_gltf(&dir, "nan", &nan, &[0, 1, 2], |_| {}), "vertex 0 has a NaN or infinite coordinate");
    let inf = [[0.0, 0.0, 0.0], [f32::INFINITY, 0.0, 0.0], [0.0, 0.0, -1.0]];
    expect_error(&write_gltf(&dir, "inf", &inf, &[0, 1, 2], |_| {}), "vertex 1 has a NaN or infinite coordinate");
    let line = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
    expect_error(&write_gltf(&dir, "degenerate", &line, &[0, 1, 2], |_| {}), "triangle 0 is degenerate");
    let emitter = write_gltf(&dir, "zero_area_light", &line, &[0, 1, 2], |d| {
        d["materials"][0]["emissiveFactor"] = json!([1.0, 1.0, 1.0]);
    });
    expect_error(&emitter, "degenerate");
    // Dropping degenerate triangles leaves the emitter with none: still an error.
    let err = import(&emitter, ImportOptions { drop_degenerate: true, ..Default::default() })
        .err()
        .expect("zero-area emitter")
        .to_string();
    assert!(err.contains("zero_area_light.gltf") && err.contains("emitter has zero area"), "{err}");
    let p = write_gltf(&dir, "huge_scale", &TRI, &[0, 1, 2], |d| d["nodes"][0]["scale"] = json!([1e20, 1e20, 1e20]));
    expect_error(&p, "beyond kage's limit of ±1e12 m");
    let p = write_gltf(&dir, "large_scale", &TRI, &[0, 1, 2], |d| d["nodes"][0]["scale"] = json!([1e9, 1e9, 1e9]));
    import(&p, ImportOptions::default()).expect("a million-kilometre triangle is still a scene");
    let p = write_gltf(&dir, "points", &TRI, &[0, 1, 2], |d| d["meshes"][0]["primitives"][0]["mode"] = json!(0));
    expect_error(&p, "only triangles are supported");
    let p = write_gltf(&dir, "draco", &TRI, &[0, 1, 2], |d| {
        d["extensionsRequired"] = json!(["KHR_draco_mesh_compression"])
    });
    expect_error(&p, "requires extension KHR_draco_mesh_compression");
    let p = write_gltf(&dir, "infinite_matrix", &TRI, &[0, 1, 2], |d| d["nodes"][0]["scale"] = json!([1e39, 1.0, 1.0]));
    expect_error(&p, "transform is not finite");
    // Light reaches (extras.kage.light_reach): malformed, or not holding the light.
    let light = |name: &str, reach: Value| {
        write_gltf(&dir, name, &TRI, &[0, 1, 2], |d| {
            d["materials"][0]["emissiveFactor"] = json!([1.0, 1.0, 1.0]);
            d["nodes"][0] = json!({"name": "lamp", "mesh": 0, "translation": [0.0, 2.0, 0.0], "extras": {"kage": {"light_reach": reach}}});
        })
    };
    expect_error(
        &light("reach_word", json!("moving")),
        "nodes[0] ('lamp'): extras.kage.light_reach: expected \"fixed\"",
    );
    expect_error(
        &light("reach_flipped", json!({"min": [1, 0, 0], "max": [0, 1, 1]})),
        "nodes[0] ('lamp'): extras.kage.light_reach: min",
    );
    let p = light("reach_misses", json!({"min": [0, 0, -1], "max": [1, 1, 0]}));
    expect_error(
        &p,
        "nodes[0] ('lamp'): the light (bounds [0, 2, -1] … [1, 2, 0]) lies outside its extras.kage.light_reach box",
    );
    let fixed = import(&light("reach_fixed", json!("fixed")), ImportOptions::default()).unwrap();
    let reach = fixed.world.query::<&kage_engine::scene::PolygonLight>().iter().map(|l| l.reach).collect::<Vec<_>>();
    assert_eq!(reach, [Some([glam::Vec3::new(0.0, 2.0, -1.0), glam::Vec3::new(1.0, 2.0, 0.0)])]);
    let p = write_gltf(&dir, "reach_unlit", &TRI, &[0, 1, 2], |d| {
        d["nodes"][0]["extras"] = json!({"kage": {"light_reach": "fixed"}});
    });
    let warnings = import(&p, ImportOptions::default()).unwrap().warnings;
    assert!(warnings.len() == 1 && warnings[0].contains("light_reach ignored (no emissive primitive)"), "{warnings:?}");
    // A sheared group imports (rendering does not need rigidity) but is refused where a rigid
    // frame is required.
    let p = write_gltf(&dir, "shear", &TRI, &[0, 1, 2], |d| {
        d["nodes"][0]["matrix"] =
            json!([1.0, 0.0, 0.0, 0.0, 0.6, 0.8, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
    });
    let scene = import(&p, ImportOptions::default()).unwrap();
    let err = scene.check_rigid_groups().unwrap_err().to_string();
    assert!(err.contains("shear.gltf") && err.contains("must be rigid: shear"), "{err}");
    let mirrored = import(&asset("scenes/cube_on_plane_mirrored_light.gltf"), ImportOptions::default()).unwrap();
    mirrored.check_rigid_groups().expect("a uniform mirror is rigid");
    // One emitter placed once, its 4,097 triangles in a fan that is not flat: one light
    // polygon each, past kage's limit.
    let n = kage_engine::scene::import::MAX_LIGHTS + 1;
    let rim = (0..=n).map(|k| {
        let a = k as f32 / n as f32 * std::f32::consts::PI;
        [a.cos(), 0.1 * (k % 2) as f32, -a.sin()]
    });
    let fan: Vec<[f32; 3]> = std::iter::once([0.0, 0.0, 0.0]).chain(rim).collect();
    let indices: Vec<u32> = (1..=n as u32).flat_map(|k| [0, k, k + 1]).collect();
    let many = write_gltf(&dir, "many_light_polygons", &fan, &indices, |d| {
        d["materials"][0]["emissiveFactor"] = json!([1.0, 1.0, 1.0]);
    });
    expect_error(&many, "more than 4096 light polygons");
    std::fs::remove_dir_all(dir).unwrap();
}

fn bad_environment_maps_are_rejected_clearly() {
    let dir = scratch!("bad-env");
    let garbage = dir.join("garbage.hdr");
    std::fs::write(&garbage, b"#?RADIANCE\nthis is not an image").unwrap();
    // Headers that claim more texels than the limit, or (EXR) a display window larger than the
    // pixels the file holds, are refused before anything is decoded.
    let (huge_hdr, huge_exr) = (dir.join("huge.hdr"), dir.join("huge.exr"));
    std::fs::write(&huge_hdr, b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 200000\n\x02\x02").unwrap();
    let mut exr = std::fs::read(asset("envmaps/sky.exr")).unwrap();
    let window = b"displayWindow\0box2i\0\x10\0\0\0";
    let at = exr.windows(window.len()).position(|w| w == window).unwrap() + window.len();
    exr[at + 12..at + 16].copy_from_slice(&33023i32.to_le_bytes()); // yMax
    std::fs::write(&huge_exr, exr).unwrap();
    for (path, needle) in [
        (huge_hdr, "declares 200000×100000 texels, more than the limit"),
        (huge_exr, "display window (512×33024) is larger than its data window (512×256)"),
        (asset("edge_cases/fuzz/sky_display_window_too_large.exr"), "display window (512×33024) is larger"),
        (garbage, "cannot decode"),
        (dir.join("absent.exr"), "No such file"),
        (asset("scenes/stained_glass.png"), "must be .hdr or .exr"),
    ] {
        let err = EnvMap::load(&path).err().unwrap_or_else(|| panic!("{} loaded", path.display())).to_string();
        assert!(err.contains(path.file_name().unwrap().to_str().unwrap()) && err.contains(needle), "{err}");
    }
    std::fs::remove_dir_all(dir).unwrap();
}

/// Every file of the Khronos validator corpus: an error naming the file, or a scene — and
/// every file the validator marks as broken in a way kage relies on is an error.
fn edge_case_corpus_never_panics() {
    let mut files = Vec::new();
    let mut stack = vec![asset("edge_cases")];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if matches!(p.extension().and_then(|e| e.to_str()), Some("gltf" | "glb")) {
                files.push(p);
            }
        }
    }
    files.sort();
    assert!(files.len() >= 70, "corpus found: {}", files.len());
    let must_fail = [
        "draco/suzanne_draco.glb",
        "glb/invalid_version.glb",
        "glb/empty_file.glb",
        "mesh/unresolved_positions.gltf",
        "node/node_loop.gltf",
        "node/node_loop_scene.gltf",
        "node/node_parent_override.gltf",
        "node/infinite_transform.gltf",
        "buffer/not_found.gltf",
        "buffer/wrong_bytelength.glb",
    ];
    // Valid by the spec (the validator reports 0 errors): accessors without a buffer view are
    // zeros, a buffer without URI is legal until a used accessor reads it. node/valid.gltf's
    // meshes are all zeros (no surface): a clear error under kage's geometry rules, and with
    // degenerate triangles dropped (as the error suggests) a scene without them.
    let must_import = [
        "accessor/valid.gltf",
        "mesh/valid.gltf",
        "buffer/valid.gltf",
        "buffer/valid.glb",
        "scene/valid.gltf",
        "asset/valid.gltf",
        "glb/valid.glb",
    ];
    let (mut ok, mut failed) = (0, 0);
    for f in &files {
        let name = f.to_string_lossy().replace('\\', "/");
        match import(f, ImportOptions::default()) {
            Ok(scene) => {
                ok += 1;
                assert!(!must_fail.iter().any(|m| name.ends_with(m)), "{name} should be rejected");
                let _: &Scene = &scene;
            }
            Err(e) => {
                failed += 1;
                let msg = e.to_string();
                assert!(!must_import.iter().any(|m| name.ends_with(m)), "{name} is valid glTF: {msg}");
                assert!(msg.contains(f.file_name().unwrap().to_str().unwrap()), "error names the file: {msg}");
            }
        }
    }
    eprintln!("corpus: {} files, {ok} imported, {failed} rejected with an error", files.len());
    let zeros = asset("edge_cases/validator/node/valid.gltf");
    let e = import(&zeros, ImportOptions::default()).err().expect("degenerate").to_string();
    assert!(e.contains("degenerate") && e.contains("--drop-degenerate"), "{e}");
    let dropped = import(&zeros, ImportOptions { drop_degenerate: true, ..Default::default() }).unwrap();
    assert!(dropped.warnings.iter().any(|w| w.contains("no surface left")), "{:?}", dropped.warnings);
}

/// A scene reads only regular files inside its own folder, never more than it declares; the
/// error names the URI and the rule. A wider root the user allows reads what it covers.
fn uris_stay_inside_the_scene_folder() {
    let dir = scratch!("confinement");
    let scene_dir = dir.join("scene");
    std::fs::create_dir_all(&scene_dir).unwrap();
    let ok = write_gltf(&scene_dir, "inside", &TRI, &[0, 1, 2], |_| {});
    import(&ok, ImportOptions::default()).expect("a buffer beside the scene is read");
    std::fs::copy(scene_dir.join("inside.bin"), dir.join("outside.bin")).unwrap();
    let outside = dir.join("outside.bin").display().to_string();
    std::os::unix::fs::symlink(dir.join("outside.bin"), scene_dir.join("link.bin")).unwrap();
    for (name, uri, rule) in [
        ("dotdot", "../outside.bin".to_string(), "leads outside"),
        ("encoded", "%2E%2E%2Foutside.bin".to_string(), "leads outside"),
        ("symlink", "link.bin".to_string(), "leads outside"),
        ("absolute", outside.clone(), "absolute paths are not read"),
        ("file_scheme", format!("file://{outside}"), "only data: URIs and relative paths"),
        ("device", "/dev/zero".to_string(), "absolute paths are not read"),
    ] {
        let p = write_gltf(&scene_dir, name, &TRI, &[0, 1, 2], |d| d["buffers"][0]["uri"] = json!(uri));
        expect_error(&p, rule);
        let err = import(&p, ImportOptions::default()).err().unwrap().to_string();
        assert!(err.contains(&uri) && err.contains("buffers[0]"), "the error names the buffer and its URI: {err}");
    }
    let escape =
        write_gltf(&scene_dir, "escape", &TRI, &[0, 1, 2], |d| d["buffers"][0]["uri"] = json!("../outside.bin"));
    let wider = ImportOptions { allow_root: Some(dir.clone()), ..Default::default() };
    import(&escape, wider).expect("--allow-root covers the parent folder");
    // A file longer than declared is read up to byteLength only; a shorter one is an error.
    let long = write_gltf(&scene_dir, "long", &TRI, &[0, 1, 2], |_| {});
    let mut bytes = std::fs::read(scene_dir.join("long.bin")).unwrap();
    bytes.extend([0u8; 1 << 20]);
    std::fs::write(scene_dir.join("long.bin"), &bytes).unwrap();
    import(&long, ImportOptions::default()).expect("trailing bytes are not read");
    let short = write_gltf(&scene_dir, "short", &TRI, &[0, 1, 2], |d| d["buffers"][0]["byteLength"] = json!(1000));
    expect_error(&short, "bytes where 1000 are declared");
}

#[test]
fn bad_input_never_panics() {
    count_panics();
    synthetic_files_are_rejected_clearly();
    uris_stay_inside_the_scene_folder();
    bad_environment_maps_are_rejected_clearly();
    edge_case_corpus_never_panics();
    let _ = std::panic::take_hook();
    assert_eq!(PANICS.load(Ordering::SeqCst), 0, "no panic");
    assert_eq!(kage_engine::error::contained_panics(), 0, "none even contained as an error");
}
