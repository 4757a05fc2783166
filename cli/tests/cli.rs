//! The `kage` binary as a user runs it: outputs, exit codes, error messages, determinism.

use kage_engine::output::read_vertex_csv;
use std::path::{Path, PathBuf};
use std::process::Command;

mod common;

use common::{asset, kage, kage_as_shipped, scratch, stderr};

#[test]
fn info_describes_the_default_scene() {
    let o = kage(&["info"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8(o.stdout).unwrap();
    for needle in
        ["scene: builtin:default", "groups: 5", "lights: 1 polygons", "cameras: 1", "environment: procedural:sky"]
    {
        assert!(out.contains(needle), "missing '{needle}' in:\n{out}");
    }
}

/// A scene nothing lights (no emissive quad, no environment) renders black with a warning
/// that says why and how to light it; with `--env` it renders without one.
#[test]
fn an_unlit_scene_is_warned_about() {
    let d = scratch("unlit");
    let (scene, sky) = (asset("scenes/bunny_two_groups.gltf"), asset("envmaps/sky.hdr"));
    let (png, db) = (d.join("a.png"), d.join("bake.redb"));
    let args = ["render", scene.as_str(), "--size", "16x9", "-o", png.to_str().unwrap(), "--db", db.to_str().unwrap()];
    let o = kage(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let warned = stderr(&o);
    assert!(
        warned.contains("warning:") && warned.contains("nothing lights it") && warned.contains("--env"),
        "{warned}"
    );
    let said = String::from_utf8_lossy(&o.stdout);
    assert!(said.contains("indirect: skipped, nothing lights the scene"), "{said}");
    let o = kage(&[&args[..], &["--env", sky.as_str()]].concat());
    assert!(o.status.success() && !stderr(&o).contains("nothing lights it"), "{}", stderr(&o));
}

/// A scene of glTF's default material (metallic 1) under `--method prt` is black, with a note
/// that says why and which method shows it; the default method needs none.
#[test]
fn metals_under_prt_are_explained() {
    let d = scratch("metals");
    let (scene, city) = (asset("khronos/BoxTextured/BoxTextured.gltf"), asset("envmaps/city.hdr"));
    let png = d.join("box.png");
    let args = ["render", scene.as_str(), "--env", city.as_str(), "--size", "16x9", "-o", png.to_str().unwrap()];
    let o = kage(&[&args[..], &["--method", "prt", "--db", d.join("bake.redb").to_str().unwrap()]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let noted = stderr(&o);
    assert!(noted.contains("1 of 1 instances are metals") && noted.contains("--method baked"), "{noted}");
    let o = kage(&[&args[..], &["--method", "ltc-unshadowed"]].concat());
    assert!(o.status.success() && !stderr(&o).contains("metals"), "{}", stderr(&o));
    // A ball banded by its metallic-roughness texture is black where it is metal.
    let banded = asset("scenes/textured_materials.gltf");
    let args = ["render", banded.as_str(), "--env", city.as_str(), "--size", "16x9", "-o", png.to_str().unwrap()];
    let o = kage(&[&args[..], &["--method", "prt", "--db", d.join("banded.redb").to_str().unwrap()]].concat());
    let noted = stderr(&o);
    assert!(o.status.success() && noted.contains("1 of 4 are metal where their metallic-roughness texture"), "{noted}");
}

/// A small object under a dark studio map: the metered exposure keeps its highlights (at most
/// 5 % of the pixels showing it clip), where metering all pixels alike would let the black
/// around it push the object into white.
#[test]
fn a_small_object_under_a_dark_sky_keeps_its_highlights() {
    use kage_engine::math::color::{metered_exposure, metered_exposure_keeping};
    let d = scratch("exposure");
    let (png, exr, db) = (d.join("box.png"), d.join("box.exr"), d.join("bake.redb"));
    let (gltf, env) = (asset("khronos/BoxTextured/BoxTextured.gltf"), asset("envmaps/studio.hdr"));
    let path = |p: &Path| p.to_str().unwrap().to_owned();
    let mut printed = String::new();
    for out in [&png, &exr] {
        let args = ["render", gltf.as_str(), "--env", env.as_str(), "--eye", "2.5,1.5,3.5", "--target", "0,0,0"];
        let o = kage(&[&args[..], &["--size", "64x48", "-o", &path(out), "--db", &path(&db)]].concat());
        assert!(o.status.success(), "{}", stderr(&o));
        printed += &String::from_utf8(o.stdout).unwrap();
    }
    let metered = printed.lines().find_map(|l| l.strip_prefix("exposure: ")).expect("metered exposure printed");
    let stops: f32 = metered.split_whitespace().next().unwrap().parse().unwrap();
    let all: Vec<glam::Vec3> =
        image::open(&exr).unwrap().into_rgb32f().pixels().map(|p| glam::Vec3::from(p.0)).collect();
    let mut scene = kage_engine::scene::import::import(Path::new(&gltf), Default::default()).unwrap();
    scene.set_environment(kage_engine::scene::EnvironmentLight::new(
        kage_engine::scene::EnvMap::load(Path::new(&env)).unwrap(),
    ));
    let renderer = kage_engine::reference::Renderer::new(&scene);
    let camera =
        kage_engine::scene::Camera::look_at(glam::Vec3::new(2.5, 1.5, 3.5), glam::Vec3::ZERO, 45f32.to_radians());
    let surfaces = kage_engine::raster::surface_pixels(&renderer, &camera, 64, 48);
    let on: Vec<glam::Vec3> = all.iter().zip(&surfaces).filter(|(_, s)| **s).map(|(p, _)| *p).collect();
    let (keeping, alike) = (metered_exposure_keeping(&all, &on), metered_exposure(all.iter().copied()));
    assert!((stops - keeping).abs() < 0.006, "printed {stops}, the EXR meters {keeping}");
    assert!(
        alike > keeping + 0.5,
        "metering all pixels alike: {alike} stops, keeping the object's highlights: {keeping}"
    );
    let luminance = kage_engine::math::color::luminance;
    let clipped = on.iter().filter(|p| luminance(**p) * stops.exp2() > 1.0).count();
    assert!(clipped as f32 <= 0.05 * on.len() as f32 + 1.0, "{clipped} of the object's {} pixels clip", on.len());
}

#[test]
fn render_writes_png_exr_and_vertex_csv() {
    let d = scratch("render");
    let (png, exr, csv) = (d.join("a.png"), d.join("a.exr"), d.join("v.csv"));
    let db = d.join("bake.redb");
    let mut printed = Vec::new();
    for (out, extra) in [(&png, vec![]), (&exr, vec!["--vertices-out", csv.to_str().unwrap()])] {
        let mut args =
            vec!["render", "--spp", "2", "--size", "40x24", "-o", out.to_str().unwrap(), "--db", db.to_str().unwrap()];
        args.extend(extra);
        let o = kage(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        printed.push(String::from_utf8(o.stdout).unwrap());
    }
    let exr_img = image::open(&exr).unwrap().into_rgb32f();
    assert!(exr_img.pixels().any(|p| p.0[0] > 1.0), "EXR keeps linear radiance above 1 (the light)");
    // The PNG's exposure is metered on the pixels that show a surface (and printed); an EXR
    // is never exposed.
    let metered = printed[0].lines().find_map(|l| l.strip_prefix("exposure: ")).expect("metered exposure printed");
    let stops: f32 = metered.split_whitespace().next().unwrap().parse().unwrap();
    assert!(!printed[1].contains("exposure:"));
    let scene = kage_engine::scene::default_scene();
    let renderer = kage_engine::reference::Renderer::new(&scene);
    let surfaces = kage_engine::raster::surface_pixels(&renderer, &scene.first_camera().unwrap(), 40, 24);
    assert!(surfaces.iter().any(|s| !s) && surfaces.iter().any(|s| *s), "the view shows the sky and the scene");
    let all: Vec<glam::Vec3> = exr_img.pixels().map(|p| glam::Vec3::from(p.0)).collect();
    let on: Vec<glam::Vec3> = all.iter().zip(&surfaces).filter(|(_, s)| **s).map(|(p, _)| *p).collect();
    let expected = kage_engine::math::color::metered_exposure_keeping(&all, &on);
    assert!((stops - expected).abs() < 0.006, "printed {stops}, the EXR meters {expected}");
    let png_img = image::open(&png).unwrap().into_rgb8();
    assert_eq!(png_img.dimensions(), (40, 24));
    for (p, e) in png_img.pixels().zip(exr_img.pixels()) {
        for c in 0..3 {
            let want = kage_engine::output::display_srgb(e.0[c] * expected.exp2()) * 255.0;
            assert!((f32::from(p.0[c]) - want).abs() <= 1.5, "{p:?} vs {e:?}");
        }
    }
    // Stops are given as numbers, negative ones without `=`; anything else is refused.
    let fixed = d.join("fixed.png");
    let (fixed_s, db_s) = (fixed.to_str().unwrap(), db.to_str().unwrap());
    let o = kage(&["render", "--spp", "1", "--size", "8x8", "--exposure", "-1.5", "-o", fixed_s, "--db", db_s]);
    assert!(o.status.success() && !String::from_utf8_lossy(&o.stdout).contains("exposure:"), "{}", stderr(&o));
    let o = kage(&["render", "--exposure", "bright", "-o", fixed_s, "--db", db_s]);
    assert!(!o.status.success() && stderr(&o).contains("expected 'auto' or stops"), "{}", stderr(&o));
    let rows = read_vertex_csv(&csv).unwrap();
    assert_eq!(rows.len(), 1681 + 1625 + 1225 + 24);
    assert!(rows.iter().all(|r| r.radiance.is_finite() && r.radiance.min_element() >= 0.0));
    std::fs::remove_dir_all(d).unwrap();
}

#[test]
fn vertices_are_identical_on_one_and_two_threads() {
    let d = scratch("threads");
    let scene = asset("scenes/cube_on_plane.gltf");
    // The default method (baked) bakes into a database of each run's own: both bake cold.
    let run = |threads: &str, name: &str| {
        let (csv, db) = (d.join(name), d.join(format!("{name}.redb")));
        let (csv_arg, db_arg) = (csv.to_str().unwrap(), db.to_str().unwrap());
        let o =
            kage(&["render", &scene, "--threads", threads, "--spp", "4", "--vertices-out", csv_arg, "--db", db_arg]);
        assert!(o.status.success(), "{}", stderr(&o));
        std::fs::read(csv).unwrap()
    };
    assert_eq!(run("1", "one.csv"), run("2", "two.csv"));
    std::fs::remove_dir_all(d).unwrap();
}

#[test]
fn bad_input_exits_non_zero_with_a_message() {
    let d = scratch("bad");
    let broken = d.join("broken.gltf");
    std::fs::write(&broken, "{ not json").unwrap();
    let cases: Vec<(Vec<String>, &str)> = vec![
        (vec!["info".into(), broken.display().to_string()], "broken.gltf: not a readable glTF file"),
        (vec!["info".into(), d.join("nope.glb").display().to_string()], "nope.glb"),
        (vec!["info".into(), "--env".into(), d.join("sky.hdr").display().to_string()], "sky.hdr"),
        (
            vec![
                "render".into(),
                "-o".into(),
                d.join("x.bmp").display().to_string(),
                "--spp".into(),
                "1".into(),
                "--size".into(),
                "4x4".into(),
            ],
            "must be .exr",
        ),
        (vec!["render".into(), "--size".into(), "0x10".into()], "bad size"),
        (
            vec!["info".into(), asset("edge_cases/validator/mesh/unresolved_positions.gltf")],
            "accessor 0 does not exist",
        ),
    ];
    for (args, needle) in cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = kage(&args);
        let err = stderr(&o);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(err.contains(needle), "{args:?}: '{needle}' not in {err}");
        assert!(err.matches("(os error").count() <= 1, "{args:?}: the OS's words said twice: {err}");
        assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    }
    std::fs::remove_dir_all(d).unwrap();
}

#[test]
fn env_and_camera_overrides_apply() {
    let d = scratch("env");
    let out = d.join("b.png");
    let o = kage(&[
        "render",
        &asset("models/bunny.glb"),
        "--env",
        &asset("envmaps/city.hdr"),
        "--env-rotation",
        "90",
        "--eye",
        "0,8,25",
        "--target",
        "0,4,0",
        "--spp",
        "2",
        "--size",
        "32x32",
        "-o",
        out.to_str().unwrap(),
        "--db",
        d.join("bake.redb").to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(out.exists());
    let o = kage(&["info", "--env", &asset("envmaps/sky.exr"), "--env-intensity", "2"]);
    let text = String::from_utf8(o.stdout).unwrap();
    assert!(text.contains("sky.exr (512×256), intensity 2"), "{text}");
    // Its sun, 48° up, is split off for the baked look.
    assert!(text.contains("sun (shaded apart by the baked look): toward (-0.378, 0.742, 0.554)"), "{text}");
    std::fs::remove_dir_all(d).unwrap();
}

#[test]
fn polygon_light_methods_render_images_and_vertices() {
    let d = scratch("methods");
    let scene = asset("scenes/cube_on_plane.gltf");
    for method in ["bspvt", "ltc-unshadowed", "ltc-exact-vis"] {
        let (png, csv) = (d.join(format!("{method}.png")), d.join(format!("{method}.csv")));
        let o = kage(&[
            "render",
            &scene,
            "--method",
            method,
            "--face-res",
            "8",
            "--size",
            "32x18",
            "--spp",
            "1",
            "-o",
            png.to_str().unwrap(),
            "--vertices-out",
            csv.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{method}: {}", stderr(&o));
        let out = String::from_utf8_lossy(&o.stdout);
        assert!(out.contains("shade:"), "{out}");
        assert_eq!(method == "bspvt", out.contains("bake:"), "{out}");
        assert_eq!(read_vertex_csv(&csv).unwrap().len(), 1705);
        assert!(png.exists());
    }
    let o = kage(&["render", &scene, "--method", "bspvt", "--face-res", "2"]);
    assert!(!o.status.success() && stderr(&o).contains("--face-res"));
    std::fs::remove_dir_all(d).unwrap();
}

#[test]
fn polygon_methods_shade_a_scene_without_polygonal_lights_with_or_without_a_database() {
    // A database plans no BSPVT for such a scene: `--method bspvt` used to panic on the
    // missing trees there, while the in-memory path rendered.
    let d = scratch("no-polygon-lights");
    let scene = asset("scenes/bunny_two_groups.gltf");
    let (db, csv, png) = (d.join("bake.redb"), d.join("v.csv"), d.join("x.png"));
    for with_db in [false, true] {
        let mut args = vec!["render", &scene, "--method", "bspvt", "--face-res", "8", "--size", "16x9", "--spp", "1"];
        args.extend(["-o", png.to_str().unwrap(), "--vertices-out", csv.to_str().unwrap()]);
        if with_db {
            args.extend(["--db", db.to_str().unwrap()]);
        }
        let o = kage(&args);
        assert!(o.status.success(), "database {with_db}: {}", stderr(&o));
        let rows = read_vertex_csv(&csv).unwrap();
        assert!(!rows.is_empty() && rows.iter().all(|r| r.radiance == glam::Vec3::ZERO), "no light, no radiance");
    }
    assert!(db.exists());
    std::fs::remove_dir_all(d).unwrap();
}

/// Whether some pixel of the PNG at `path` has exactly `rgb`.
fn png_has_colour(path: &Path, rgb: [u8; 3]) -> bool {
    image::open(path).unwrap().to_rgb8().pixels().any(|p| p.0 == rgb)
}

#[test]
fn report_writes_markdown_csv_and_plot() {
    let d = scratch("report");
    let out = d.join("rep");
    let o =
        kage(&["report", &asset("scenes/cube_on_plane.gltf"), "--out", out.to_str().unwrap(), "--reference-spp", "64"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    for method in [
        "| baked-polygonal | trees 64², ε 2, LTC per pixel |",
        "| bspvt | 64² faces, ε 2 |",
        "| ltc-exact-vis |",
        "| ltc-unshadowed |",
        "| monte-carlo | 16 spp |",
        "| ratio-estimator | 4 rays per light |",
        "| indirect-gather | 256 rays per vertex",
        "| hsh-cache | order 3, a 0.3:",
        "| hsh-cache-no-gradients |",
        "| hsh-cache-numerical-gradients |",
        "| hsh-cache-wide-blend | order 3, a 0.2:",
    ] {
        assert!(md.contains(method), "{method} missing:\n{md}");
    }
    let csv = std::fs::read_to_string(out.join("report.csv")).unwrap();
    // The baked look's polygonal part (no environment), 13 polygonal-light rows, then 3
    // gathers and 19 cache configurations.
    assert_eq!(csv.lines().count(), 1 + 1 + 13 + 3 + 19);
    let column = |prefix: &str, k: usize| {
        let line = csv.lines().find(|l| l.starts_with(prefix)).unwrap();
        line.rsplit(',').nth(k).unwrap().to_string()
    };
    // The tree's own error (against exact visibility at 64²): only on 64² rows, and small.
    let tree_error = |config: &str| column(&format!("bspvt,\"{config}\","), 1);
    // Indirect rows count their rays (the rays plot's axis); others have none.
    assert_eq!(column("indirect-gather,256 rays per vertex", 0).parse::<usize>().unwrap() % 256, 0);
    assert_eq!(column("bspvt,\"16² faces", 0), "");
    // A configuration holding commas is one quoted field.
    assert!(csv.lines().any(|l| l.starts_with("hsh-cache,\"order 3, a 0.3: ")), "{csv}");
    assert_eq!(tree_error("16² faces, ε 2"), "");
    let e: f64 = tree_error("64² faces, ε 2").parse().unwrap();
    assert!(e > 0.0 && e < 0.01, "tree error {e}");
    for (stem, axis) in [("report", "shade time per frame (s)"), ("report-rays", "rays cast")] {
        let png = image::open(out.join(format!("{stem}.png"))).unwrap().to_rgb8();
        assert_eq!((png.width(), png.height()), (960, 600));
        // Drawn text and series, not a blank frame: dark glyph pixels and every series colour.
        assert!(png.pixels().filter(|p| p.0.iter().all(|c| *c < 80)).count() > 2000, "{stem}.png has no text");
        let svg = std::fs::read_to_string(out.join(format!("{stem}.svg"))).unwrap();
        for text in ["kage report: cube_on_plane.gltf", axis, "relative RMSE against the reference"] {
            assert!(svg.contains(text), "{stem}.svg lacks {text:?}");
        }
        assert!(md.contains(&format!("]({stem}.svg)")), "report.md links {stem}.svg");
    }
    let svg = std::fs::read_to_string(out.join("report.svg")).unwrap();
    for legend in ["bspvt", "monte-carlo", "ratio-estimator", "64² faces, ε 2"] {
        assert!(svg.contains(legend), "the legend or a point label lacks {legend:?}");
    }
    assert!(png_has_colour(&out.join("report.png"), [220, 50, 40]), "the bspvt series is drawn");
    let only = d.join("only");
    let scene = asset("scenes/cube_on_plane.gltf");
    let o = kage(&["report", &scene, "--out", only.to_str().unwrap(), "--reference-spp", "64", "--only", "cache"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let csv = std::fs::read_to_string(only.join("report.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 3 + 19, "only the cache section:\n{csv}");
    std::fs::remove_dir_all(d).unwrap();
}

/// On a scene whose materials are all GGX (as every imported glTF asset's are) the cache
/// section measures the glossy receivers' bounce, and the PRT section, which needs a Lambertian
/// surface, says so instead of measuring nothing.
#[test]
fn report_measures_glossy_receivers_and_says_why_prt_is_skipped() {
    let d = scratch("report-glossy");
    let mut gltf: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(asset("scenes/cube_on_plane.gltf")).unwrap()).unwrap();
    for m in gltf["materials"].as_array_mut().unwrap() {
        m["extensions"].as_object_mut().unwrap().remove("KHR_materials_specular");
    }
    let scene = d.join("glossy.gltf");
    std::fs::write(&scene, gltf.to_string()).unwrap();
    let scene = scene.to_str().unwrap();
    let out = d.join("rep");
    let common = ["--reference-spp", "16", "--out", out.to_str().unwrap()];
    let o = kage(&[&["report", scene, "--only", "cache"][..], &common].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("(1705 vertices, 0 of them Lambertian;"), "{md}");
    let csv = std::fs::read_to_string(out.join("report.csv")).unwrap();
    for line in csv.lines().skip(1) {
        // rel_rmse, then pixel_rel_rmse, tree_rel_rmse and rays (the quoted config holds commas).
        let rel: f64 = line.rsplit(',').nth(3).unwrap().parse().unwrap();
        assert!(rel > 0.0 && rel < 1.0, "measured against a non-empty reference: {line}");
    }
    let o = kage(&[&["report", scene, "--only", "prt", "--env", &asset("envmaps/sky.hdr")][..], &common].concat());
    assert!(!o.status.success());
    assert!(stderr(&o).contains("needs a Lambertian surface and the scene has none"), "{}", stderr(&o));
    std::fs::remove_dir_all(d).unwrap();
}

#[test]
fn refine_tessellates_a_named_instance_for_every_command() {
    let scene = asset("scenes/teapot_quad_light.gltf");
    let o = kage(&["info", &scene, "--refine", "teapot=5000"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8(o.stdout).unwrap();
    assert!(out.contains("5000 vertices") && out.contains("totals: 7601 vertices"), "{out}");
    let o = kage(&["info", &scene, "--refine", "kettle=5000"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("teapot_quad_light.gltf: no mesh instance or group named 'kettle'"), "{}", stderr(&o));
    let o = kage(&["info", &scene, "--refine", "teapot=many"]);
    assert!(!o.status.success() && stderr(&o).contains("teapot=many"), "{}", stderr(&o));
}

#[test]
fn prt_methods_plan_render_and_move_groups() {
    let d = scratch("prt");
    let db = d.join("bake.redb");
    let scene = asset("scenes/bunny_two_groups.gltf");
    let env = asset("envmaps/city.hdr");
    let run = |method: &str, extra: &[&str], name: &str| {
        let csv = d.join(format!("{name}.csv"));
        let png = d.join(format!("{name}.png"));
        let mut args = vec!["render", &scene, "--env", &env, "--method", method, "--size", "48x27", "--spp", "1"];
        args.extend_from_slice(&["-o", png.to_str().unwrap(), "--vertices-out", csv.to_str().unwrap()]);
        args.extend_from_slice(&["--db", db.to_str().unwrap()]);
        args.extend_from_slice(extra);
        let o = kage(&args);
        assert!(o.status.success(), "{method} {extra:?}: {}", stderr(&o));
        assert!(png.exists());
        (String::from_utf8_lossy(&o.stdout).into_owned(), read_vertex_csv(&csv).unwrap())
    };
    let (out, planned) = run("prt", &[], "planned");
    assert!(out.contains("plan: SH order") && out.contains("regions:"), "{out}");
    let explicit = ["--sh-order", "4", "--regions", "8", "--sh-window", "none"];
    let (out, base) = run("prt", &explicit, "base");
    assert!(!out.contains("plan:") && out.contains("order 4"), "{out}");
    assert_eq!(base.len(), planned.len());
    let (_, own) = run("prt-self", &explicit, "self");
    // Shadows between groups only take light away.
    assert!(base.iter().zip(&own).all(|(a, b)| a.radiance.cmple(b.radiance + 1e-6).all()));
    let mut moved_args = explicit.to_vec();
    moved_args.extend_from_slice(&["--move", "group_bunny=0.5,0,0.5", "--rotate", "group_box_sphere=0,1,0,90"]);
    let (_, moved) = run("prt", &moved_args, "moved");
    let bunny_moved =
        moved.iter().zip(&base).filter(|(m, _)| m.node == 1).all(|(m, b)| (m.position - b.position).length() > 0.7);
    assert!(bunny_moved, "--move moves the bunny's group");
    assert!(moved.iter().zip(&base).any(|(m, b)| m.node == 0 && m.radiance != b.radiance), "the ground's shadows move");
    for (bad, needle) in [
        (vec!["--move", "nope=1,0,0"], "no rigid group 'nope'"),
        (vec!["--rotate", "group_bunny=0,0,0,10"], "axis is zero"),
    ] {
        let mut args = vec!["render", &scene, "--env", &env, "--method", "prt"];
        args.extend(bad);
        let o = kage(&args);
        assert!(!o.status.success() && stderr(&o).contains(needle), "{}", stderr(&o));
    }
    let o = kage(&["render", &asset("scenes/cube_on_plane.gltf"), "--method", "prt"]);
    assert!(!o.status.success() && stderr(&o).contains("has none"), "{}", stderr(&o));
    std::fs::remove_dir_all(d).unwrap();
}

/// The PRT budget's order survives a group's move (it reads no placement), its region count is
/// measured again on the new arrangement with the database's transfer, and both agree with a
/// plan made from scratch; a rotation plans the order again, from the cached pilot, also as a
/// plan from scratch does.
#[test]
fn the_prt_plan_keeps_its_order_across_moves_and_matches_a_fresh_plan() {
    let d = scratch("prt-plan");
    let scene = asset("scenes/bunny_two_groups.gltf");
    let env = asset("envmaps/city.hdr");
    let bake = |db: &str, edit: &[&str]| {
        let db = d.join(db);
        let mut args = vec!["bake", &scene, "--env", &env, "--face-res", "8", "--directions", "256"];
        args.extend_from_slice(&["--db", db.to_str().unwrap()]);
        args.extend_from_slice(edit);
        let o = kage(&args);
        assert!(o.status.success(), "{edit:?}: {}", stderr(&o));
        let out = String::from_utf8_lossy(&o.stdout).into_owned();
        let lines: Vec<String> = out.lines().filter(|l| l.starts_with("plan: ")).map(str::to_string).collect();
        (out, lines)
    };
    let moved = ["--move", "group_bunny=0.5,0,0.5"];
    let (_, first) = bake("a.redb", &[]);
    assert!(first[0].contains("against order 12") && first[1].contains("against Monte Carlo"), "{first:?}");
    let (out, warm) = bake("a.redb", &moved);
    let order = first[0].split(':').nth(1).unwrap().trim().to_string();
    assert!(warm[0].starts_with(&format!("plan: {order},")) && warm[0].ends_with("(cached plan)"), "{order} {warm:?}");
    let cached = out.lines().find_map(|l| l.trim().split_once(" chunks cached")).map(|(n, _)| n.to_string());
    let all = cached.as_deref().and_then(|n| n.split_once(" of ")).is_some_and(|(a, b)| a == b);
    assert!(all, "a move re-bakes no PRT: {out}");
    let (_, fresh) = bake("b.redb", &moved);
    assert_eq!(warm[1], fresh[1], "the same measurements, with the stored transfer and with a pilot's");
    assert_eq!(fresh[0], first[0], "the order reads no placement");
    // A rotation plans the order again (with the cached pilot), as a fresh plan does.
    let turned = ["--rotate", "group_bunny=0,1,0,40"];
    let (_, rotated) = bake("a.redb", &turned);
    assert!(rotated[0].contains("against order 12"), "{rotated:?}");
    assert_eq!(rotated[..2], bake("c.redb", &turned).1[..2]);
    std::fs::remove_dir_all(d).unwrap();
}

/// Per-vertex BSPVT radiance rendered from the database at `db` (the CSV's bytes).
fn vertices_from_db(scene: &str, db: &Path, out: &Path) -> Vec<u8> {
    let o = kage(&[
        "render",
        scene,
        "--method",
        "bspvt",
        "--face-res",
        "32",
        "--db",
        db.to_str().unwrap(),
        "--vertices-out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("0 baked cold, 0 warm"),
        "rendering a baked scene bakes nothing"
    );
    std::fs::read(out).unwrap()
}

#[test]
fn a_bake_killed_at_random_points_resumes_to_a_clean_bakes_result() {
    let d = scratch("crash");
    let scene = d.join("scene.gltf");
    std::fs::copy(asset("scenes/emissive_strength_cubes.gltf"), &scene).unwrap();
    let scene = scene.to_str().unwrap().to_string();
    let clean = d.join("clean.redb");
    let o = kage(&["bake", &scene, "--face-res", "32", "--db", clean.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    // The default database: beside the scene.
    let db = d.join(".kage/bake.redb");
    let mut seed = 0x2545_F491_4F6C_DD1Du64;
    for round in 0..10 {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        let delay = 50 + seed % 900;
        let mut child = Command::new(env!("CARGO_BIN_EXE_kage"))
            .args(["bake", &scene, "--face-res", "32"])
            .env("KAGE_REFINE_RECEIVERS", "0")
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(std::time::Duration::from_millis(delay));
        let _ = child.kill(); // SIGKILL: no chance to clean up
        let _ = child.wait();
        if db.exists() {
            let o = kage(&["db", "check", "--db", db.to_str().unwrap()]);
            assert!(
                o.status.success(),
                "round {round} (killed after {delay} ms): {}{}",
                stderr(&o),
                String::from_utf8_lossy(&o.stdout)
            );
        }
    }
    let o = kage(&["bake", &scene, "--face-res", "32"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    let resumed =
        out.lines().find_map(|l| l.trim().split_once(" of 11 chunks cached")).map(|(n, _)| n.parse::<usize>().unwrap());
    assert!(resumed.is_some_and(|n| n > 0), "the killed runs left finished chunks behind:\n{out}");
    assert_eq!(vertices_from_db(&scene, &db, &d.join("a.csv")), vertices_from_db(&scene, &clean, &d.join("b.csv")));
    let o = kage(&["db", "info", "--db", clean.to_str().unwrap()]);
    let out = String::from_utf8_lossy(&o.stdout);
    let tiles = format!("memo \"bspvt tiles v{} res 32 eps 2\": ", kage_engine::bspvt::ALGORITHM_VERSION);
    assert!(out.contains(&tiles), "{out}");
    // `--watch` holds the database: another process gets a clear error.
    let mut holder = Command::new(env!("CARGO_BIN_EXE_kage"))
        .args(["bake", &scene, "--face-res", "32", "--watch"])
        // As `kage()` does: refined receivers would follow the moved slab and bake cold.
        .env("KAGE_REFINE_RECEIVERS", "0")
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // The watcher's output, line by line, so the test waits for events rather than guessing.
    let (tx, lines) = std::sync::mpsc::channel::<String>();
    let stdout = holder.stdout.take().unwrap();
    std::thread::spawn(move || {
        use std::io::BufRead;
        for line in std::io::BufReader::new(stdout).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    let wait_for = |needle: &str| -> Vec<String> {
        let mut seen = Vec::new();
        while let Ok(line) = lines.recv_timeout(std::time::Duration::from_secs(120)) {
            let hit = line.contains(needle);
            seen.push(line);
            if hit {
                return seen;
            }
        }
        panic!("`kage bake --watch` never printed '{needle}':\n{}", seen.join("\n"));
    };
    wait_for("watching");
    let o = kage(&["bake", &scene, "--face-res", "32"]);
    assert!(!o.status.success() && stderr(&o).contains("in use by another process"), "{}", stderr(&o));
    // An editor-style save (write a temporary file, rename it over the scene) re-bakes warm.
    // The slab's translation y (the only "1.2," in the file) goes up by 5 cm.
    let text = std::fs::read_to_string(&scene).unwrap().replacen("1.2,", "1.25,", 1);
    let tmp = d.join("scene.gltf.tmp");
    std::fs::write(&tmp, text).unwrap();
    std::fs::rename(&tmp, &scene).unwrap();
    let after = wait_for("baked ");
    let _ = holder.kill();
    let _ = holder.wait();
    let summary = after.last().unwrap();
    let warm = summary.split(" cold and ").nth(1).and_then(|r| r.split(' ').next()?.parse::<usize>().ok());
    assert!(
        after.iter().any(|l| l.contains("plan for")) && warm.is_some_and(|n| n > 0),
        "--watch re-planned after the save:\n{}",
        after.join("\n")
    );
    std::fs::remove_dir_all(d).unwrap();
}

/// The Khronos validator's report on `file` (npm package in tools/gltf-validator, installed on
/// first use; `.ci/run` installs it up front).
fn validate_gltf(file: &Path) -> (bool, String) {
    let tools = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tools/gltf-validator");
    if !tools.join("node_modules/gltf-validator").exists() {
        let o = Command::new("npm")
            .args(["install", "--no-audit", "--no-fund", "--silent", "--prefix"])
            .arg(&tools)
            .output()
            .expect("npm (Node.js) is needed to install the glTF validator");
        assert!(o.status.success(), "installing the glTF validator failed: {}", stderr(&o));
    }
    let o = Command::new("node").arg(tools.join("validate.js")).arg(file).output().expect("node runs");
    (o.status.success(), String::from_utf8_lossy(&o.stdout).into_owned())
}

/// The columns of a vertex CSV after the ids (vertex, position, radiance).
fn values(csv: &Path) -> Vec<String> {
    std::fs::read_to_string(csv)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.splitn(4, ',').nth(3).unwrap().to_string())
        .collect()
}

#[test]
fn export_writes_valid_packs_that_render_like_the_database() {
    let d = scratch("pack");
    // The BSPVT scene's light is textured: the pack carries its texture (PNG) and UVs.
    for (file, method, extra) in [
        ("scenes/textured_light", "bspvt", vec!["--face-res", "16"]),
        ("scenes/bunny_two_groups", "prt", vec!["--sh-order", "4", "--regions", "8"]),
        ("scenes/textured_light", "baked", vec!["--face-res", "16", "--sh-order", "3", "--regions", "8"]),
        // Base-colour and metallic-roughness textures, TEXCOORD_1, a UV transform, vertex colours.
        ("scenes/textured_materials", "baked", vec!["--face-res", "16", "--sh-order", "3", "--regions", "8"]),
        // A cut-out (alphaMode MASK): the mask travels as a PNG's alpha, the preview is MASK too.
        ("scenes/cutout_lattice", "baked", vec!["--face-res", "16", "--sh-order", "3", "--regions", "8"]),
    ] {
        let name = Path::new(file).file_name().unwrap().to_str().unwrap();
        for ext in ["gltf", "bin"] {
            std::fs::copy(asset(&format!("{file}.{ext}")), d.join(format!("{name}.{ext}"))).unwrap();
        }
        for png in ["stained_glass.png", "checker.png", "metal_rough.png", "poster.png", "lattice.png"] {
            std::fs::copy(asset(&format!("scenes/{png}")), d.join(png)).unwrap();
        }
        let scene = d.join(format!("{name}.gltf")).to_str().unwrap().to_string();
        if method == "bspvt" {
            // A light that stays put: the pack carries its reach.
            declare_fixed_light(&scene);
        }
        let db = d.join(format!("{method}.redb"));
        let pack = d.join(format!("{method}.glb"));
        let env = asset("envmaps/sky.hdr");
        let mut args =
            vec!["export", &scene, "--db", db.to_str().unwrap(), "-o", pack.to_str().unwrap(), "--env", &env];
        args.extend(&extra);
        let o = kage(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        let (ok, report) = validate_gltf(&pack);
        assert!(ok && report.contains(": 0 errors"), "{report}");
        let carries_reach = std::fs::read(&pack).unwrap().windows(10).any(|w| w == b"lightReach");
        assert_eq!(carries_reach, method == "bspvt");
        let (a, b) = (d.join("a.csv"), d.join("b.csv"));
        let o = kage(&[
            "render",
            "--pack",
            pack.to_str().unwrap(),
            "--method",
            method,
            "--vertices-out",
            a.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let mut args = vec![
            "render",
            &scene,
            "--env",
            &env,
            "--method",
            method,
            "--db",
            db.to_str().unwrap(),
            "--vertices-out",
            b.to_str().unwrap(),
        ];
        args.extend(&extra);
        let o = kage(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(values(&a) == values(&b), "{method}: the pack shades exactly like the database");
        // Any glTF tool can read it: kage's own importer sees the groups and the preview.
        let o = kage(&["info", pack.to_str().unwrap()]);
        assert!(o.status.success(), "{}", stderr(&o));
        if method == "bspvt" {
            // A damaged tree record (offsets intact) fails its checksum; written so by a writer
            // that sealed it anyway, it is a malformed record: errors naming the pack, not panics.
            damage_first_tree_record(&pack);
            let o = kage(&["render", "--pack", pack.to_str().unwrap(), "--method", method]);
            let e = stderr(&o);
            assert!(!o.status.success() && e.contains("bspvt.records (buffer view") && e.contains("bspvt.glb"), "{e}");
            let (doc, bin) = glb_parts(&std::fs::read(&pack).unwrap());
            std::fs::write(&pack, sealed_glb(doc, &bin)).unwrap();
            let o = kage(&["render", "--pack", pack.to_str().unwrap(), "--method", method]);
            let e = stderr(&o);
            assert!(!o.status.success() && e.contains("malformed BSPVT record") && e.contains("bspvt.glb"), "{e}");
        }
    }
    let o = kage(&["render", "--pack", &asset("scenes/cube_on_plane.gltf"), "--method", "bspvt"]);
    assert!(!o.status.success() && stderr(&o).contains("not a kage pack"), "{}", stderr(&o));
    std::fs::remove_dir_all(d).unwrap();
}

/// A pack shades with its lights and groups moved, with no bake: a light moved 0.5 m shades
/// the pack as the database shades the scene after the same move; a light the pack does not
/// have, and options a pack cannot take, are errors naming them.
#[test]
fn a_pack_shades_with_its_lights_and_groups_moved() {
    let (d, scene, db) = teapot_copy("pack-moves");
    let pack = d.join("moves.glb");
    let (pack, csv) = (pack.to_str().unwrap(), d.join("v.csv"));
    let o = kage(&["export", &scene, "--db", &db, "-o", pack, "--face-res", "8", "--refine-receivers", "0"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let shade = |args: &[&str]| {
        let mut all = vec!["render", "--method", "bspvt", "--vertices-out", csv.to_str().unwrap()];
        all.extend(args);
        let o = kage(&all);
        assert!(o.status.success(), "{}", stderr(&o));
        values(&csv)
    };
    let still = shade(&["--pack", pack]);
    let moved = shade(&["--pack", pack, "--move-light", "light=0,0,-0.5"]);
    let scene_moved =
        shade(&[&scene, "--db", &db, "--face-res", "8", "--refine-receivers", "0", "--move-light", "0=0,0,-0.5"]);
    assert_ne!(still, moved, "the moved light shades differently");
    assert_eq!(moved, scene_moved, "the pack shades the moved light as the database does");
    let turned = shade(&["--pack", pack, "--move", "teapot=0.3,0,0", "--rotate-light", "light=1,0,0,20"]);
    assert_ne!(turned, still);
    let o = kage(&["render", "--pack", pack, "--move-light", "lamp=0,0,1"]);
    assert!(!o.status.success() && stderr(&o).contains("no light 'lamp' (lights: 0 'light')"), "{}", stderr(&o));
    let o = kage(&["render", "--pack", pack, "--env", &asset("envmaps/sky.hdr")]);
    assert!(!o.status.success() && stderr(&o).contains("--env does not apply to a pack"), "{}", stderr(&o));
    std::fs::remove_dir_all(d).unwrap();
}

/// A scratch folder for test `name` holding a copy of the teapot scene: (folder, scene, database).
fn teapot_copy(name: &str) -> (PathBuf, String, String) {
    let d = scratch(name);
    for ext in ["gltf", "bin"] {
        let file = format!("teapot_quad_light.{ext}");
        std::fs::copy(asset(&format!("scenes/{file}")), d.join(file)).unwrap();
    }
    let scene = d.join("teapot_quad_light.gltf").to_str().unwrap().to_string();
    (d.clone(), scene, d.join("bake.redb").to_str().unwrap().to_string())
}

/// Declares the node 'light' of glTF file `scene` fixed (`extras.kage.light_reach`).
fn declare_fixed_light(scene: &str) {
    edit_light(scene, |lamp| lamp["extras"] = serde_json::json!({"kage": {"light_reach": "fixed"}}));
}

/// Edits the node 'light' of glTF file `scene` in place.
fn edit_light(scene: &str, edit: impl FnOnce(&mut serde_json::Value)) {
    let mut doc: serde_json::Value = serde_json::from_slice(&std::fs::read(scene).unwrap()).unwrap();
    let lamp =
        doc["nodes"].as_array_mut().unwrap().iter_mut().find(|n| n.get("mesh").is_some() && n["name"] == "light");
    edit(lamp.expect("the scene has a node 'light'"));
    std::fs::write(scene, serde_json::to_vec(&doc).unwrap()).unwrap();
}

/// A light with a declared reach box is refined for the whole box: moved inside it, the
/// refined receivers and every bake key stay the same, so nothing is baked again.
#[test]
fn a_light_moved_within_its_reach_bakes_nothing_again() {
    let (d, scene, db) = teapot_copy("reach-move");
    // The light (at 1.5, 4, 0; ±0.43 × ±0.25 × ±1 m) may move within 2 × 1 × 3 m.
    let reach = serde_json::json!({"kage": {"light_reach": {"min": [0.5, 3.5, -1.5], "max": [2.5, 4.5, 1.5]}}});
    edit_light(&scene, |lamp| lamp["extras"] = reach);
    let bake = || {
        let o = kage(&["bake", &scene, "--db", &db, "--refine-receivers", "1500"]);
        assert!(o.status.success(), "{}", stderr(&o));
        let refined = stderr(&o).lines().find(|l| l.starts_with("refined receivers")).map(str::to_string);
        (refined.expect("refinement ran"), String::from_utf8_lossy(&o.stdout).into_owned())
    };
    let (before, first) = bake();
    assert!(!first.contains("; 0 to bake"), "{first}");
    edit_light(&scene, |lamp| lamp["translation"] = serde_json::json!([1.9, 4.1, 0.3]));
    let (after, second) = bake();
    // The lines but for how long refinement took.
    let untimed =
        |line: &str| line.split_once(" in ").map(|(a, b)| format!("{a}{}", &b[b.find(" s ").unwrap()..])).unwrap();
    let kept = untimed(&before).replace(")", ", all 2 instances kept in the bake database)");
    assert_eq!(kept, untimed(&after), "the refinement is read back");
    assert!(second.contains("; 0 to bake"), "the moved light re-baked something: {second}");
    std::fs::remove_dir_all(d).unwrap();
}

/// The plan's cost estimate counts only the tiles a declared light reach leaves to cast.
#[test]
fn the_plan_estimate_shrinks_with_a_declared_light_reach() {
    let (_, scene, db) = teapot_copy("reach-estimate");
    let estimate = || {
        let o = kage(&["bake", &scene, "--db", &db, "--dry-run"]);
        assert!(o.status.success(), "{}", stderr(&o));
        let out = String::from_utf8_lossy(&o.stdout).into_owned();
        let at = out.find("estimated ").unwrap_or_else(|| panic!("no estimate in {out}")) + "estimated ".len();
        (out[at..].split(' ').next().unwrap().parse::<f64>().unwrap(), out)
    };
    let (roaming, _) = estimate();
    declare_fixed_light(&scene);
    let (fixed, out) = estimate();
    assert!(out.contains("lights within 1 reach box"), "{out}");
    assert!(fixed > 0.0 && fixed * 5.0 < roaming, "fixed {fixed} s, roaming {roaming} s");
}

/// A pack's glTF JSON and binary chunk.
fn glb_parts(bytes: &[u8]) -> (serde_json::Value, Vec<u8>) {
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let doc = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    (doc, bytes[20 + json_len + 8..].to_vec())
}

/// A pack of `doc` and `bin` with its integrity record computed afresh, as a writer that got
/// the data wrong would seal it.
fn sealed_glb(doc: serde_json::Value, bin: &[u8]) -> Vec<u8> {
    let mut json = serde_json::to_vec(&doc).unwrap();
    json.resize(json.len().next_multiple_of(4), b' ');
    let chunk = |kind: &[u8; 4], data: &[u8]| [&(data.len() as u32).to_le_bytes()[..], kind, data].concat();
    let body = [chunk(b"JSON", &json), chunk(b"BIN\0", bin)].concat();
    let glb = [&b"glTF"[..], &2u32.to_le_bytes(), &(12 + body.len() as u32).to_le_bytes(), &body].concat();
    kage_bake_db::pack::reseal(&glb).unwrap()
}

/// A pack whose data was damaged after kage wrote it, or that was written wrong, is refused
/// with the field named: a flipped bit in a PRT transfer (checksum; sealed anyway: the
/// transfer's bound), a negative bounce, a light radiance beyond f32, a JSON edit, an unknown
/// version.
#[test]
fn damaged_or_out_of_range_packs_are_refused_naming_the_field() {
    let d = scratch("pack-integrity");
    for ext in ["gltf", "bin"] {
        std::fs::copy(asset(&format!("scenes/textured_light.{ext}")), d.join(format!("textured_light.{ext}"))).unwrap();
    }
    std::fs::copy(asset("scenes/stained_glass.png"), d.join("stained_glass.png")).unwrap();
    let (scene, pack) = (d.join("textured_light.gltf"), d.join("scene.glb"));
    let o = kage(&[
        "export",
        scene.to_str().unwrap(),
        "--db",
        d.join("db.redb").to_str().unwrap(),
        "-o",
        pack.to_str().unwrap(),
        "--env",
        &asset("envmaps/sky.hdr"),
        "--face-res",
        "8",
        "--sh-order",
        "3",
        "--regions",
        "4",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (doc, bin) = glb_parts(&std::fs::read(&pack).unwrap());
    let image = d.join("image.png");
    let render = |bytes: Vec<u8>| {
        let damaged = d.join("damaged.glb");
        std::fs::write(&damaged, bytes).unwrap();
        let o =
            kage(&["render", "--pack", damaged.to_str().unwrap(), "--size", "32x18", "-o", image.to_str().unwrap()]);
        assert!(!o.status.success(), "a damaged pack rendered");
        let e = stderr(&o);
        assert!(e.contains("damaged.glb: not a kage pack"), "{e}");
        e
    };
    // The pack as written renders.
    let o = kage(&["render", "--pack", pack.to_str().unwrap(), "--size", "32x18", "-o", image.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    // A flipped exponent bit in the first transfer coefficient.
    let transfer = doc["meshes"]
        .as_array()
        .unwrap()
        .iter()
        .find_map(|m| m["primitives"][0]["extensions"]["KAGE_baked_shadows"]["prt"]["transfer"].as_u64())
        .unwrap();
    let at = doc["bufferViews"][transfer as usize]["byteOffset"].as_u64().unwrap_or(0) as usize;
    let mut flipped = bin.clone();
    flipped[at + 3] ^= 0x40;
    let mut bytes = std::fs::read(&pack).unwrap();
    let bin_start = bytes.len() - bin.len();
    bytes[bin_start..].copy_from_slice(&flipped);
    let e = render(bytes);
    assert!(e.contains("prt.transfer (buffer view") && e.contains("fails its checksum"), "{e}");
    let e = render(sealed_glb(doc.clone(), &flipped));
    assert!(e.contains("prt.transfer: vertex 0, coefficient 0"), "{e}");
    // A negative light in the bounces the pack carries (sealed anyway).
    let bounce = doc["meshes"][0]["primitives"][0]["extensions"]["KAGE_baked_shadows"]["bounce"].as_u64().unwrap();
    let at = doc["bufferViews"][bounce as usize]["byteOffset"].as_u64().unwrap_or(0) as usize;
    let mut negative = bin.clone();
    negative[at..at + 4].copy_from_slice(&(-1.0f32).to_le_bytes());
    let e = render(sealed_glb(doc.clone(), &negative));
    assert!(e.contains("bounce: not") && e.contains("≥ 0"), "{e}");
    // A light radiance beyond f32.
    let mut hot = doc.clone();
    let light = hot["meshes"]
        .as_array_mut()
        .unwrap()
        .iter_mut()
        .find_map(|m| m["primitives"][0]["extensions"]["KAGE_baked_shadows"].get_mut("lightRadiance"))
        .unwrap();
    *light = serde_json::json!([1e39, 1.0, 1.0]);
    let e = render(sealed_glb(hot.clone(), &bin));
    assert!(e.contains("light 0's lightRadiance") && e.contains("not a finite number"), "{e}");
    // The same edit without sealing: the JSON's checksum.
    let mut bytes = sealed_glb(doc.clone(), &bin);
    let key = b"\"previewExposure\":";
    let exposure = bytes.windows(key.len()).position(|w| w == key).unwrap() + key.len();
    bytes[exposure] = if bytes[exposure] == b'1' { b'2' } else { b'1' };
    let e = render(bytes);
    assert!(e.contains("the glTF JSON fails its checksum"), "{e}");
    // A newer kage's pack.
    let mut newer = doc.clone();
    newer["extensions"]["KAGE_baked_shadows"]["version"] = serde_json::json!(99);
    let e = render(sealed_glb(newer, &bin));
    assert!(e.contains("version 99 (this kage reads"), "{e}");
    std::fs::remove_dir_all(d).unwrap();
}

/// Overwrites the face lengths of the first BSPVT record in `pack` (a GLB), keeping its offsets.
fn damage_first_tree_record(pack: &Path) {
    use serde_json::Value;
    let mut bytes = std::fs::read(pack).unwrap();
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let doc: Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    fn records(v: &Value) -> Option<u64> {
        match v {
            Value::Object(m) => {
                m.get("bspvt").and_then(|b| b["records"].as_u64()).or_else(|| m.values().find_map(records))
            }
            Value::Array(a) => a.iter().find_map(records),
            _ => None,
        }
    }
    let view = &doc["bufferViews"][records(&doc).expect("a BSPVT record view") as usize];
    // The BIN chunk's data follows its 8-byte header.
    let at = 20 + json_len + 8 + view["byteOffset"].as_u64().unwrap() as usize;
    bytes[at..at + 2].copy_from_slice(&[0xFF, 0xFF]);
    std::fs::write(pack, bytes).unwrap();
}

#[test]
fn indirect_light_adds_to_per_vertex_methods() {
    let d = scratch("indirect");
    let scene = asset("scenes/cube_on_plane.gltf");
    let run = |extra: &[&str]| {
        let csv = d.join("v.csv");
        let mut args =
            vec!["render", &scene, "--method", "bspvt", "--face-res", "8", "--vertices-out", csv.to_str().unwrap()];
        args.extend_from_slice(extra);
        let o = kage(&args);
        assert!(o.status.success(), "{extra:?}: {}", stderr(&o));
        (String::from_utf8_lossy(&o.stdout).into_owned(), read_vertex_csv(&csv).unwrap())
    };
    let (_, direct) = run(&[]);
    for mode in ["cache", "gather", "reference"] {
        let (out, with) = run(&["--indirect", mode, "--spp", "64", "--cache-rays", "64"]);
        assert!(out.contains("indirect ("), "{out}");
        assert!(with.iter().zip(&direct).all(|(a, b)| a.radiance.cmpge(b.radiance).all()), "{mode} only adds light");
        assert!(with.iter().zip(&direct).any(|(a, b)| a.radiance != b.radiance), "{mode} adds something");
    }
    let o = kage(&["render", &scene, "--method", "reference", "--indirect", "cache"]);
    assert!(!o.status.success() && stderr(&o).contains("--bounces"), "{}", stderr(&o));
    // The cache chooses its bounces from the error budget and says so; --bounces fixes them,
    // and each bounce only adds light; --bounces 0 leaves the direct light.
    let (chosen, _) = run(&["--indirect", "cache", "--cache-rays", "64"]);
    assert!(chosen.contains("% budget)"), "{chosen}");
    let (one, single) = run(&["--indirect", "cache", "--cache-rays", "64", "--bounces", "1"]);
    let (three, triple) = run(&["--indirect", "cache", "--cache-rays", "64", "--bounces", "3"]);
    assert!(one.contains("1 bounce (given)") && three.contains("3 bounces (given)"), "{one}{three}");
    assert!(triple.iter().zip(&single).all(|(a, b)| a.radiance.cmpge(b.radiance).all()));
    assert!(triple.iter().zip(&single).any(|(a, b)| a.radiance != b.radiance));
    let (none, flat) = run(&["--indirect", "cache", "--bounces", "0"]);
    assert!(!none.contains("indirect (") && flat.iter().zip(&direct).all(|(a, b)| a.radiance == b.radiance), "{none}");
    // With a bake database the records persist: the second run reads them and shades the same.
    let db = d.join("bake.redb");
    let cached = ["--indirect", "cache", "--cache-rays", "64", "--db", db.to_str().unwrap()];
    let (first, a) = run(&cached);
    let (second, b) = run(&cached);
    assert!(!first.contains("from the bake database") && second.contains("from the bake database"), "{first}{second}");
    assert!(a.iter().zip(&b).all(|(x, y)| x.radiance == y.radiance));
    std::fs::remove_dir_all(d).unwrap();
}

/// `kage render` with no method renders the baked look: it plans and bakes into the database
/// on the first run (cached on the second), shades metal under the environment (the built-in
/// scene's gold torus is lit), and shows the environment where no geometry is.
#[test]
fn baked_is_the_default_and_shades_every_light() {
    let d = scratch("baked");
    let (exr, csv, db) = (d.join("a.exr"), d.join("v.csv"), d.join("bake.redb"));
    let run = || {
        let o = kage(&[
            "render",
            "--size",
            "64x36",
            "--spp",
            "1",
            "-o",
            exr.to_str().unwrap(),
            "--vertices-out",
            csv.to_str().unwrap(),
            "--db",
            db.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let first = run();
    let chunks = first.split("0 of ").nth(1).and_then(|r| r.split(' ').next()).unwrap_or("?").to_string();
    assert!(first.contains("plan for builtin:default") && first.contains(&format!("; {chunks} to bake")), "{first}");
    assert!(first.contains("indirect (Cache)"), "{first}");
    let second = run();
    assert!(second.contains(&format!("{chunks} of {chunks} chunks cached")), "{second}");
    let rows = read_vertex_csv(&csv).unwrap();
    let scene = kage_engine::scene::default_scene();
    let flat = kage_engine::scene::flatten(&scene);
    let k = flat.instances.iter().position(|i| i.material.metallic == 1.0).expect("the torus is metal");
    let eye = scene.first_camera().unwrap().eye();
    // A metal reflects only toward the side it faces: count the vertices facing the camera.
    let facing = |r: &&kage_engine::output::VertexRow| {
        r.node == flat.instances[k].id.node && {
            let (p, n) = flat.vertex(k, r.vertex as usize);
            n.dot((eye - p).normalize()) > 0.1
        }
    };
    let all = rows.iter().filter(facing).count();
    let lit = rows.iter().filter(facing).filter(|r| r.radiance.max_element() > 0.05).count();
    assert!(all > 500 && lit * 20 > all * 19, "the metal torus is lit: {lit} of {all} vertices facing the camera");
    let img = image::open(&exr).unwrap().into_rgb32f();
    assert!(img.get_pixel(0, 0).0.iter().all(|c| *c > 0.0), "the environment shows behind the geometry");
    std::fs::remove_dir_all(d).unwrap();
}

/// As shipped, every command refines receivers (at most 6000 added vertices per instance) and
/// says how many each instance got; `--refine-receivers 0` (or `KAGE_REFINE_RECEIVERS=0`)
/// turns it off.
#[test]
fn receivers_are_refined_by_default_and_say_by_how_much() {
    let d = scratch("default-refinement");
    let db = d.join("bake.redb");
    let text = |o: std::process::Output| {
        assert!(o.status.success(), "{}", stderr(&o));
        format!("{}{}", String::from_utf8_lossy(&o.stdout), stderr(&o))
    };
    let info = text(kage_as_shipped(&["info"]));
    let refined =
        info.lines().find_map(|l| l.strip_prefix("refined receivers: 4555 → ")).unwrap_or_else(|| panic!("{info}"));
    let (total, rest) = refined.split_once(" vertices").unwrap();
    // Measured: 6,570 (the ground's torus and sphere shadows, the torus's own).
    let total: usize = total.parse().unwrap();
    assert!((4555 + 1000..4555 + 4 * 6000).contains(&total) && rest.contains(" (at most 6000 more each"), "{info}");
    assert!(info.contains(&format!("totals: {total} vertices")), "{info}");
    let plan = text(kage_as_shipped(&["bake", "--dry-run", "--db", db.to_str().unwrap()]));
    assert!(plan.contains("instance   0: 1681 →") && plan.contains(&format!("{total} vertices")), "{plan}");
    let off = text(kage_as_shipped(&["info", "--refine-receivers", "0"]));
    assert!(!off.contains("refined receivers") && off.contains("totals: 4555 vertices"), "{off}");
    assert!(text(kage(&["info"])).contains("totals: 4555 vertices"), "the tests' helper turns it off");
    // The repository's coarse-receiver scene: its floor of two triangles gets the vertices.
    let floor = text(kage_as_shipped(&["info", &asset("scenes/two_triangle_floor.gltf")]));
    let added = floor.lines().find_map(|l| l.strip_prefix("  instance   0: 4 → ")).unwrap_or_else(|| panic!("{floor}"));
    let added: usize = added.split(' ').next().unwrap().parse().unwrap();
    // Measured: 1,588.
    assert!(floor.contains("refined receivers: 205 → ") && added > 1000, "{floor}");
    std::fs::remove_dir_all(d).unwrap();
}

/// The help says what kage and each command do today, and lists every method with what it
/// computes.
#[test]
fn help_describes_the_commands_and_every_method() {
    let o = kage(&["--help"]);
    let text = String::from_utf8(o.stdout).unwrap();
    assert!(text.contains("bakes and previews shadows"), "{text}");
    for command in ["info", "render", "bake", "db", "export", "report", "edit"] {
        assert!(text.lines().any(|l| l.trim_start().starts_with(command)), "{command} missing:\n{text}");
    }
    assert!(!text.contains("later"), "{text}");
    let o = kage(&["render", "--help"]);
    let text = String::from_utf8(o.stdout).unwrap();
    use kage_engine::named::Named;
    for &m in kage_engine::shading::Method::ALL {
        assert!(text.contains(&format!("{}:", m.name())) && text.contains(m.about()), "{} missing:\n{text}", m.name());
    }
    for &b in kage_engine::cache::Blend::ALL {
        assert!(text.contains(&format!("{}:", b.name())) && text.contains(b.about()), "{} missing:\n{text}", b.name());
    }
    let o = kage(&["render", "--method", "baked-look"]);
    assert!(!o.status.success() && stderr(&o).contains("ltc-exact-vis"), "{}", stderr(&o));
}

/// A model without a camera (most single-asset glTF files) is framed, not refused.
#[test]
fn a_scene_without_a_camera_is_framed() {
    let d = scratch("framed");
    let mut doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(asset("scenes/cube_on_plane.gltf")).unwrap()).unwrap();
    for node in doc["nodes"].as_array_mut().unwrap() {
        node.as_object_mut().unwrap().remove("camera");
    }
    doc.as_object_mut().unwrap().remove("cameras");
    let scene = d.join("no_camera.gltf");
    std::fs::write(&scene, serde_json::to_vec(&doc).unwrap()).unwrap();
    let png = d.join("framed.png");
    let (scene, out) = (scene.to_str().unwrap(), png.to_str().unwrap());
    let o = kage(&["render", scene, "--method", "ltc-unshadowed", "--size", "32x24", "--spp", "1", "-o", out]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("camera: the scene has none; framing it"));
    let img = image::open(&png).unwrap().to_rgb8();
    // The lit ground fills much of the frame; its bounding sphere stays inside the corners.
    let lit = img.pixels().filter(|p| p.0.iter().any(|c| *c > 0)).count();
    let corners = [(0, 0), (31, 0), (0, 23), (31, 23)].map(|(x, y)| img.get_pixel(x, y).0);
    assert!(lit > 32 * 24 / 10 && corners.iter().all(|c| *c == [0, 0, 0]), "{lit} lit pixels, corners {corners:?}");
    // The report shades toward the same framing.
    let out = d.join("report");
    let args = ["report", scene, "--only", "baked", "--reference-spp", "4", "--image-size", "16x12"];
    let o = kage(&[&args[..], &["--reference-image-spp", "4", "--out", out.to_str().unwrap()]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::read_to_string(out.join("report.md")).unwrap().contains("| baked-polygonal |"));
    std::fs::remove_dir_all(d).unwrap();
}

/// `kage info` says what varies a material: textures (size, UV set), a second UV set, vertex
/// colours.
#[test]
fn info_lists_materials_and_their_textures() {
    let o = kage(&["info", &asset("scenes/textured_materials.gltf")]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8(o.stdout).unwrap();
    for needle in [
        "material: base colour (1.000, 1.000, 1.000) × texture 0 (32×32, TEXCOORD_0), metallic 0.00, roughness 0.80",
        "roughness 1.00 × texture 1 (4×16, TEXCOORD_0; roughness G, metalness B)",
        "× texture 2 (16×16, TEXCOORD_1)",
        "24 vertices  12 triangles  area 2.9400  vertex colours",
        "TEXCOORD_1\n",
    ] {
        assert!(out.contains(needle), "missing '{needle}' in:\n{out}");
    }
}

/// `kage render --gpu --method baked` draws the look as the editor's viewport does, as linear
/// radiance (4×4 samples a pixel): against the CPU's image of the same bakes, per pixel.
/// Measured on `two_triangle_floor.gltf` under `city.hdr`: 7.7 % relative RMSE (surfaces
/// 7.8 %: the environment's diffuse light and the reflection's visibility come from the
/// vertices; background 0.07 %; drawn at one sample a pixel: 9.5 %, the aliased edges 26 % of
/// the background). On `cutout_lattice.gltf` under `sky.hdr`: 1.3 %, the sun's sharp shadow of
/// the lattice from the depth map (8.2 % with the sun's visibility interpolated from the
/// vertices).
#[test]
fn render_gpu_draws_the_baked_look_like_the_cpu_image() {
    for (scene, map, most) in [("two_triangle_floor", "city", 0.1), ("cutout_lattice", "sky", 0.1)] {
        let (error, surfaces, background) = gpu_against_cpu(scene, map);
        eprintln!(
            "{scene} under {map}: --gpu against the CPU image {error:.4} (surfaces {surfaces:.4}, background {background:.4})"
        );
        assert!(error < most, "{scene}: relative RMSE {error:.4}");
    }
}

/// The relative RMSE of `kage render --gpu`'s image of `scene` under `map` against the CPU's,
/// over the image, its surfaces and its background.
fn gpu_against_cpu(name: &str, map: &str) -> (f64, f64, f64) {
    let d = scratch(&format!("gpu-baked-{name}"));
    for ext in ["gltf", "bin"] {
        let _ = std::fs::copy(asset(&format!("scenes/{name}.{ext}")), d.join(format!("{name}.{ext}")));
    }
    let _ = std::fs::copy(asset("scenes/lattice.png"), d.join("lattice.png"));
    let (cpu, gpu, db) = (d.join("cpu.exr"), d.join("gpu.exr"), d.join("bake.redb"));
    let path = |p: &Path| p.to_str().unwrap().to_owned();
    let (scene, env) = (path(&d.join(format!("{name}.gltf"))), asset(&format!("envmaps/{map}.hdr")));
    for (out, gpu) in [(&cpu, false), (&gpu, true)] {
        let args = ["render", scene.as_str(), "--env", env.as_str(), "--size", "160x90", "--face-res", "16"];
        let extra: &[&str] = if gpu { &["--gpu"] } else { &[] };
        let o = kage(&[&args[..], &["-o", &path(out), "--db", &path(&db), "--indirect", "none"], extra].concat());
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(!stderr(&o).contains("draws per vertex"), "{}", stderr(&o));
    }
    let read = |p: &Path| -> Vec<glam::Vec3> {
        image::open(p).unwrap().into_rgb32f().pixels().map(|p| glam::Vec3::from(p.0)).collect()
    };
    let (a, b) = (read(&gpu), read(&cpu));
    let mut s = kage_engine::scene::import::import(Path::new(&scene), Default::default()).unwrap();
    s.set_environment(kage_engine::scene::EnvironmentLight::new(
        kage_engine::scene::EnvMap::load(Path::new(&env)).unwrap(),
    ));
    let renderer = kage_engine::reference::Renderer::new(&s);
    let surfaces = kage_engine::raster::surface_pixels(&renderer, &s.first_camera().unwrap(), 160, 90);
    let part = |v: &[glam::Vec3], on: bool| -> Vec<glam::Vec3> {
        v.iter().zip(&surfaces).filter(|(_, s)| **s == on).map(|(p, _)| *p).collect()
    };
    let error = kage_engine::math::relative_rmse(&a, &b);
    let on = kage_engine::math::relative_rmse(&part(&a, true), &part(&b, true));
    let off = kage_engine::math::relative_rmse(&part(&a, false), &part(&b, false));
    std::fs::remove_dir_all(d).unwrap();
    (error, on, off)
}
