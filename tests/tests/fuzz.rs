//! Fuzzing on stable Rust, with a fixed budget: structure-aware mutants of the repository's own
//! inputs — glTF JSON fields, GLB chunks and headers, buffer and image URIs, HDR and EXR maps,
//! packs and bake databases — each loaded as kage loads it. Every run must end in a result or a
//! clean error:
//! - no panic (a panic hook counts them), and none even contained as an error
//!   (`kage_engine::error::contain`) except inside the storage library on a damaged database
//!   page, which the store turns into an error by design;
//! - no run longer than 10 s plus 4 µs per input byte ([`time_bound`]);
//! - no run allocating more than 64 MiB plus 64 bytes per input byte above what was live before
//!   it ([`MEMORY_ALLOWANCE`]; the allocator is instrumented);
//! - no file outside the scene's folder read: a URI that leads outside (in any spelling) or to a
//!   special file must fail the import.
//!
//! The mutants are seeded (a failure reproduces); one that breaks a rule is written to
//! `target/fuzz-failures/` to become a regression test. `KAGE_FUZZ_MUTANTS` sets the total
//! (default 10,000, split across the kinds as [`KINDS`] says).
//!
//! Besides the mutants, files the harness writes that hold many of one thing ([`COUNTS`]:
//! 10⁵–10⁶ nodes, lights, primitives, instances, materials) are loaded as `kage info` loads
//! them — imported and their receivers refined — under the same rules: each costs what it
//! holds, or is refused with an error naming its count and kage's limit.

use kage_bake_db::pack::{self, Export};
use kage_bake_db::{Store, plan};
use kage_engine::error::contained_panics;
use kage_engine::scene::import::{ImportOptions, import};
use kage_engine::scene::{EnvMap, EnvironmentLight, flatten};
use kage_engine::{bspvt, prt};
use kage_tests::{asset, scratch};
use peakmem_alloc::{INSTRUMENTED_SYSTEM, PeakMemAlloc, PeakMemAllocTrait};
use rand::{Rng, RngCore, SeedableRng};
use rand_pcg::Pcg64;
use serde_json::{Value, json};
use std::alloc::System;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

#[global_allocator]
static GLOBAL: &PeakMemAlloc<System> = &INSTRUMENTED_SYSTEM;

/// Longest a run on `bytes` of input may take: 10 s, plus 4 µs per byte (a 5 MB file of 10⁵
/// instances is imported and refined in about 12 s on two cores).
fn time_bound(bytes: usize) -> Duration {
    Duration::from_secs(10) + Duration::from_micros(4 * bytes as u64)
}
/// Most a run may allocate above what was live before it: proportional to the input, a fixed
/// allowance plus [`MEMORY_PER_BYTE`] per byte of it.
const MEMORY_ALLOWANCE: usize = 64 << 20;
/// See [`MEMORY_ALLOWANCE`]: 64 bytes per input byte (decoded float textures and meshes stay
/// well under it).
const MEMORY_PER_BYTE: usize = 64;

static PANICS: AtomicUsize = AtomicUsize::new(0);

/// Held by each test while it measures: the allocator's peak is the process's.
static MEASURING: Mutex<()> = Mutex::new(());

/// Installs the hook that counts panics, once, before any test loads a file: kage's
/// `error::contain` wraps the hook it finds on first use (keeping contained panics apart), so
/// a hook set after it would count those too.
fn count_panics() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        std::panic::set_hook(Box::new(|info| {
            PANICS.fetch_add(1, Ordering::SeqCst);
            eprintln!("PANIC: {info}");
        }))
    });
}

/// The kinds of input and their shares of the budget (per ten thousand).
const KINDS: [(Kind, usize); 7] = [
    (Kind::GltfJson, 3000),
    (Kind::Glb, 1500),
    (Kind::Uri, 1200),
    (Kind::Hdr, 700),
    (Kind::Exr, 600),
    (Kind::Pack, 2000),
    (Kind::Database, 1000),
];

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    GltfJson,
    Glb,
    Uri,
    Hdr,
    Exr,
    Pack,
    Database,
}

/// The seeds, made once: files in a folder of their own, with a canary file outside it.
struct Seeds {
    dir: PathBuf,
    gltf: Vec<u8>,
    glb: Vec<u8>,
    hdr: Vec<u8>,
    exr: Vec<u8>,
    pack: Vec<u8>,
    db: Vec<u8>,
}

impl Seeds {
    fn new() -> Self {
        let root = scratch!("fuzz");
        let dir = root.join("scene");
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(root.join("canary.bin"), vec![7u8; 4096]).unwrap();
        for f in ["textured_light.bin", "stained_glass.png"] {
            std::fs::copy(asset(&format!("scenes/{f}")), dir.join(f)).unwrap();
        }
        let status = std::process::Command::new("mkfifo").arg(dir.join("fifo.bin")).status();
        assert!(status.is_ok_and(|s| s.success()), "mkfifo makes a FIFO in the scene folder");
        let (pack, db) = baked(&dir);
        Self {
            gltf: std::fs::read(asset("scenes/textured_light.gltf")).unwrap(),
            glb: std::fs::read(asset("models/teapot_npm.glb")).unwrap(),
            hdr: std::fs::read(asset("envmaps/sky.hdr")).unwrap(),
            exr: std::fs::read(asset("envmaps/sky.exr")).unwrap(),
            pack,
            db,
            dir,
        }
    }
}

/// A pack and a database holding real BSPVT (with depth: a light in a closed room) and PRT
/// bakes of a small scene.
fn baked(dir: &Path) -> (Vec<u8>, Vec<u8>) {
    let mut scene = import(&asset("scenes/cornell_box.gltf"), ImportOptions::default()).unwrap();
    scene.set_environment(EnvironmentLight::new(EnvMap::load(&asset("envmaps/sky.hdr")).unwrap()));
    let flat = flatten(&scene);
    let b = bspvt::Settings { res: 8, epsilon: 2.0 };
    let p = prt::Settings { order: 3, directions: 64, regions: 4, ..prt::Settings::default() };
    let db = dir.join("seed.redb");
    {
        let store = Store::open(&db).unwrap();
        let plan = plan(&store, &scene, &flat, Some(b), Some(p)).unwrap();
        kage_bake_db::bake(&store, &scene, &flat, &plan, &|_| {}).unwrap();
    }
    let (trees, transfer) = (bspvt::bake(&flat, &b, &|_| {}), prt::bake(&scene, &flat, &p, &|_| {}));
    let lighting = prt::Lighting::new(&scene, &p).unwrap();
    let export = Export {
        scene: &scene,
        flat: &flat,
        bspvt: Some(&trees),
        prt: Some(prt::Parts { bake: &transfer, lighting: &lighting, settings: &p }),
        radiance: &flat.zeros(),
        bounce: Some(&flat.zeros()),
        exposure: 0.0,
    };
    let path = dir.join("seed.pack.glb");
    pack::write(&path, &export).unwrap();
    let out = (std::fs::read(&path).unwrap(), std::fs::read(&db).unwrap());
    std::fs::remove_file(path).unwrap();
    std::fs::remove_file(db).unwrap();
    out
}

/// Numbers and values that break assumptions.
fn interesting(rng: &mut Pcg64) -> Value {
    let pick = [
        json!(0),
        json!(-1),
        json!(1),
        json!(2147483648u64),
        json!(4294967299u64),
        json!(u64::MAX),
        json!(1e38),
        json!(-1e38),
        json!(1e-45),
        json!(0.5),
        json!(1e20),
        json!(null),
        json!(true),
        json!("x"),
        json!([]),
        json!({}),
        json!([1e30, -1e30, 0.0]),
        json!(4096),
        json!(100000000),
    ];
    pick[rng.random_range(0..pick.len())].clone()
}

/// Every path to a value in `v` (object keys and array indices).
fn paths(v: &Value, at: &mut Vec<Value>, out: &mut Vec<Vec<Value>>) {
    out.push(at.clone());
    match v {
        Value::Object(m) => m.iter().for_each(|(k, c)| {
            at.push(json!(k));
            paths(c, at, out);
            at.pop();
        }),
        Value::Array(a) => a.iter().enumerate().for_each(|(i, c)| {
            at.push(json!(i));
            paths(c, at, out);
            at.pop();
        }),
        _ => {}
    }
}

fn at_mut<'a>(v: &'a mut Value, path: &[Value]) -> &'a mut Value {
    path.iter().fold(v, |v, k| match k {
        Value::String(s) => &mut v[s.as_str()],
        Value::Number(n) => &mut v[n.as_u64().unwrap() as usize],
        _ => unreachable!(),
    })
}

/// One to three structural edits: a value replaced by an interesting one, a key or element
/// removed, an element duplicated, an array of numbers scaled by 1e20.
fn mutate_json(doc: &mut Value, rng: &mut Pcg64) {
    for _ in 0..rng.random_range(1..=3) {
        let mut all = Vec::new();
        paths(doc, &mut Vec::new(), &mut all);
        if all.len() < 2 {
            return;
        }
        // The data URIs of buffers are long; edit the structure, not base64 text.
        let path = &all[rng.random_range(1..all.len())];
        let (parent, last) = path.split_at(path.len() - 1);
        match rng.random_range(0..5) {
            0 | 1 => *at_mut(doc, path) = interesting(rng),
            2 => match (at_mut(doc, parent), &last[0]) {
                (Value::Object(m), Value::String(k)) => {
                    m.remove(k);
                }
                (Value::Array(a), Value::Number(i)) => {
                    a.remove(i.as_u64().unwrap() as usize);
                }
                _ => {}
            },
            3 => {
                if let (Value::Array(a), Value::Number(i)) = (at_mut(doc, parent), &last[0]) {
                    let copy = a[i.as_u64().unwrap() as usize].clone();
                    a.push(copy);
                }
            }
            _ => {
                if let Value::Array(a) = at_mut(doc, path) {
                    a.iter_mut().filter_map(|x| x.as_f64().map(|f| (x, f))).for_each(|(x, f)| *x = json!(f * 1e20));
                }
            }
        }
    }
}

/// Flips, zeroes or randomises a few bytes (within `range`), or truncates.
fn mutate_bytes(bytes: &mut Vec<u8>, range: std::ops::Range<usize>, rng: &mut Pcg64) {
    let range = range.start.min(bytes.len())..range.end.min(bytes.len());
    if range.is_empty() {
        return;
    }
    match rng.random_range(0..6) {
        0 => bytes.truncate(rng.random_range(0..bytes.len())),
        1 => {
            let at = rng.random_range(range.clone());
            let end = (at + rng.random_range(1..4096)).min(bytes.len());
            bytes[at..end].fill(0);
        }
        _ => {
            for _ in 0..rng.random_range(1..8) {
                let at = rng.random_range(range.clone());
                bytes[at] = match rng.random_range(0..3) {
                    0 => bytes[at] ^ (1 << rng.random_range(0..8)),
                    1 => 0xff,
                    _ => rng.next_u32() as u8,
                };
            }
        }
    }
}

/// A GLB with `json` as its JSON chunk and `bin` as its binary chunk.
fn glb(json: &[u8], bin: &[u8]) -> Vec<u8> {
    let pad = |n: usize| n.next_multiple_of(4);
    let mut out = Vec::new();
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend(((12 + 8 + pad(json.len()) + 8 + pad(bin.len())) as u32).to_le_bytes());
    for (kind, data, fill) in [(b"JSON", json, b' '), (b"BIN\0", bin, 0u8)] {
        out.extend((pad(data.len()) as u32).to_le_bytes());
        out.extend(kind);
        out.extend(data);
        out.resize(out.len().next_multiple_of(4), fill);
    }
    out
}

/// The JSON and binary chunks of a GLB.
fn chunks(bytes: &[u8]) -> (Value, Vec<u8>) {
    let g = gltf::binary::Glb::from_slice(bytes).unwrap();
    (serde_json::from_slice(&g.json).unwrap(), g.bin.map(|b| b.into_owned()).unwrap_or_default())
}

/// A GLB mutant: its JSON edited (re-chunked with right lengths), or its bytes edited.
fn mutate_glb(seed: &[u8], rng: &mut Pcg64) -> Vec<u8> {
    if rng.random_bool(0.6) {
        let (mut doc, bin) = chunks(seed);
        mutate_json(&mut doc, rng);
        let bytes = glb(&serde_json::to_vec(&doc).unwrap(), &bin);
        // Sealed again half of the time, as a writer that got the data wrong would: past the
        // checksums, into the parser and the range checks.
        match rng.random_bool(0.5) {
            true => pack::reseal(&bytes).unwrap_or(bytes),
            false => bytes,
        }
    } else {
        let mut bytes = seed.to_vec();
        // Headers and chunk headers half of the time.
        let end = if rng.random_bool(0.5) { 32 } else { bytes.len() };
        mutate_bytes(&mut bytes, 0..end, rng);
        bytes
    }
}

/// URIs that lead outside the scene folder or to something that is not a regular file.
fn hostile_uri(dir: &Path, rng: &mut Pcg64) -> String {
    let canary = dir.parent().unwrap().join("canary.bin").display().to_string();
    let forms = [
        "../canary.bin".to_string(),
        "%2e%2e/canary.bin".to_string(),
        "%2E%2E%2Fcanary.bin".to_string(),
        "..%2fcanary.bin".to_string(),
        "sub/../../canary.bin".to_string(),
        "./../canary.bin".to_string(),
        canary.clone(),
        format!("file://{canary}"),
        format!("file:{canary}"),
        "/dev/zero".to_string(),
        "/dev/urandom".to_string(),
        "/proc/self/mem".to_string(),
        "/proc/self/environ".to_string(),
        "fifo.bin".to_string(),
        ".".to_string(),
        "".to_string(),
        "http://example.invalid/x.bin".to_string(),
        format!("..{}canary.bin", '\\'),
        "%00".to_string(),
    ];
    forms[rng.random_range(0..forms.len())].clone()
}

/// What one mutant is: its file, and whether it must fail (a hostile URI).
struct Mutant {
    path: PathBuf,
    bytes: usize,
    must_fail: bool,
}

fn make(kind: Kind, seeds: &Seeds, n: usize, rng: &mut Pcg64) -> Mutant {
    let file = |ext: &str| seeds.dir.join(format!("m{n}.{ext}"));
    let (path, bytes, must_fail) = match kind {
        Kind::GltfJson => {
            let mut doc: Value = serde_json::from_slice(&seeds.gltf).unwrap();
            mutate_json(&mut doc, rng);
            (file("gltf"), serde_json::to_vec(&doc).unwrap(), false)
        }
        Kind::Glb => (file("glb"), mutate_glb(&seeds.glb, rng), false),
        Kind::Uri => {
            let mut doc: Value = serde_json::from_slice(&seeds.gltf).unwrap();
            let uri = hostile_uri(&seeds.dir, rng);
            let target = if rng.random_bool(0.5) { "buffers" } else { "images" };
            doc[target][0]["uri"] = json!(uri);
            (file("gltf"), serde_json::to_vec(&doc).unwrap(), true)
        }
        Kind::Hdr | Kind::Exr => {
            let (seed, ext) = if kind == Kind::Hdr { (&seeds.hdr, "hdr") } else { (&seeds.exr, "exr") };
            let mut bytes = seed.clone();
            let end = if rng.random_bool(0.6) { 512 } else { bytes.len() };
            mutate_bytes(&mut bytes, 0..end, rng);
            (file(ext), bytes, false)
        }
        Kind::Pack => (file("glb"), mutate_glb(&seeds.pack, rng), false),
        Kind::Database => {
            let mut bytes = seeds.db.clone();
            let page = rng.random_range(0..bytes.len().div_ceil(4096));
            mutate_bytes(&mut bytes, page * 4096..(page + 1) * 4096, rng);
            (file("redb"), bytes, false)
        }
    };
    std::fs::write(&path, &bytes).unwrap();
    Mutant { path, bytes: bytes.len(), must_fail }
}

/// Loads a mutant as kage would; `Ok(true)` when it loaded, `Ok(false)` on a clean error.
fn load(kind: Kind, path: &Path) -> Result<bool, String> {
    Ok(match kind {
        Kind::GltfJson | Kind::Glb | Kind::Uri => import(path, ImportOptions::default()).is_ok(),
        Kind::Hdr | Kind::Exr => EnvMap::load(path).is_ok(),
        Kind::Pack => pack::read(path).is_ok(),
        Kind::Database => match Store::open(path) {
            Ok(mut store) => {
                let checked = store.check().is_ok();
                checked && store.artefacts().is_ok()
            }
            Err(_) => false,
        },
    })
}

/// Keeps a mutant that broke a rule, for a regression test.
fn keep(path: &Path, why: &str) -> String {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/fuzz-failures");
    std::fs::create_dir_all(&dir).unwrap();
    let kept = dir.join(path.file_name().unwrap());
    std::fs::copy(path, &kept).unwrap();
    format!("{}: {why}", kept.display())
}

#[derive(Default, Debug)]
struct Tally {
    runs: usize,
    loaded: usize,
    contained: usize,
    slowest: Duration,
    most_memory: usize,
}

/// Which rule a run of `took` allocating `used` on `bytes` of input broke, if one.
fn over_bounds(took: Duration, used: usize, bytes: usize) -> Option<String> {
    if took > time_bound(bytes) {
        return Some(format!("took {took:?} on {bytes} bytes (bound {:?})", time_bound(bytes)));
    }
    (used > MEMORY_ALLOWANCE + MEMORY_PER_BYTE * bytes)
        .then(|| format!("allocated {} MB from {bytes} bytes", used >> 20))
}

#[test]
fn mutants_load_or_fail_cleanly_within_time_and_memory_and_never_read_outside_the_scene() {
    let _measuring = MEASURING.lock().unwrap_or_else(|e| e.into_inner());
    count_panics();
    let total: usize = std::env::var("KAGE_FUZZ_MUTANTS").ok().and_then(|v| v.parse().ok()).unwrap_or(10_000);
    let seeds = Seeds::new();
    let mut failures = Vec::new();
    for (k, (kind, share)) in KINDS.into_iter().enumerate() {
        let mut rng = Pcg64::seed_from_u64(0x6b616765 + k as u64);
        let mut tally = Tally::default();
        for n in 0..(total * share).div_ceil(10_000) {
            let mutant = make(kind, &seeds, n, &mut rng);
            let (panics, contained) = (PANICS.load(Ordering::SeqCst), contained_panics());
            // From here the allocator's peak counts what this run allocates net.
            GLOBAL.reset_peak_memory();
            let start = Instant::now();
            let loaded = std::panic::catch_unwind(|| load(kind, &mutant.path)).unwrap_or(Err("panicked".into()));
            let (took, used) = (start.elapsed(), GLOBAL.get_peak_memory());
            let caught = contained_panics() - contained;
            tally.contained += caught;
            let broke = match &loaded {
                _ if PANICS.load(Ordering::SeqCst) != panics => Some("a panic".to_string()),
                // The storage library may assert on a damaged page: contained at the store's
                // boundary as an error. Anywhere else kage validates what its parsers assert.
                _ if caught > 0 && kind != Kind::Database => Some("a panic inside a parser (contained)".into()),
                Err(e) => Some(e.clone()),
                Ok(true) if mutant.must_fail => Some("a URI outside the scene folder was read".into()),
                _ => over_bounds(took, used, mutant.bytes),
            };
            if let Some(why) = broke {
                failures.push(keep(&mutant.path, &format!("{kind:?}: {why}")));
            }
            tally.runs += 1;
            tally.loaded += usize::from(loaded == Ok(true));
            tally.slowest = tally.slowest.max(took);
            tally.most_memory = tally.most_memory.max(used);
            let _ = std::fs::remove_file(&mutant.path);
        }
        eprintln!(
            "fuzz {kind:?}: {} mutants, {} loaded, the rest refused cleanly ({} by a contained panic); slowest {:.0} ms, most memory {:.1} MB",
            tally.runs,
            tally.loaded,
            tally.contained,
            tally.slowest.as_secs_f64() * 1e3,
            tally.most_memory as f64 / (1 << 20) as f64
        );
    }
    assert!(failures.is_empty(), "{} mutants broke a rule:\n{}", failures.len(), failures.join("\n"));
}

/// What a count-heavy file holds many of.
#[derive(Clone, Copy, Debug)]
enum Count {
    /// Empty nodes, children of one node.
    Nodes,
    /// Nodes placing a quad light (kage refuses more than `MAX_LIGHTS`).
    Lights,
    /// Primitives of one mesh placed once.
    Primitives,
    /// Nodes placing one small quad each, on a grid above a ground.
    Instances,
    /// Materials, each on a primitive of one mesh.
    Materials,
}

/// The count-heavy files and how many each holds.
const COUNTS: [(Count, usize); 5] = [
    (Count::Nodes, 1_000_000),
    (Count::Lights, 1_000_000),
    (Count::Primitives, 100_000),
    (Count::Instances, 100_000),
    (Count::Materials, 100_000),
];

/// A `.gltf` in `dir` (its buffer beside it) holding a 10 m ground, a 1 m quad light 3 m above
/// it facing down, and `n` of `count`, made of 2 cm quads.
fn count_heavy(count: Count, n: usize, dir: &Path) -> PathBuf {
    let quad = |h: f32| [[-h, 0.0, -h], [h, 0.0, -h], [h, 0.0, h], [-h, 0.0, h]];
    let mut bin: Vec<u8> =
        [quad(0.01), quad(5.0), quad(0.5)].iter().flatten().flatten().flat_map(|c| c.to_le_bytes()).collect();
    // Upward (+Y) and downward triangles over the four corners.
    bin.extend([0u16, 2, 1, 0, 3, 2, 0, 1, 2, 0, 2, 3].iter().flat_map(|i| i.to_le_bytes()));
    std::fs::write(dir.join("counts.bin"), &bin).unwrap();
    let view = |offset: usize, length: usize| json!({"buffer": 0, "byteOffset": offset, "byteLength": length});
    let points = |view: usize, h: f32| json!({"bufferView": view, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-h, 0, -h], "max": [h, 0, h]});
    let up = |material: usize| json!({"attributes": {"POSITION": 0}, "indices": 3, "material": material});
    // Nodes are written as text: a million `serde_json::Value`s take seconds to build.
    let mut nodes: Vec<String> = vec![r#"{"mesh":1}"#.into(), r#"{"mesh":2,"translation":[0,3,0]}"#.into()];
    let mut meshes = vec![
        json!({"primitives": [up(1)]}),
        json!({"primitives": [{"attributes": {"POSITION": 1}, "indices": 3, "material": 1}]}),
        json!({"primitives": [{"attributes": {"POSITION": 2}, "indices": 4, "material": 0}]}),
    ];
    let mut materials = vec![
        json!({"emissiveFactor": [1, 1, 1]}),
        json!({"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1]}}),
    ];
    let side = (n as f32).sqrt().ceil() as usize;
    let grid = |i: usize| format!("[{},0.5,{}]", (i % side) as f32 * 0.05 - 2.5, (i / side) as f32 * 0.05 - 2.5);
    let placed = r#"{"mesh":0,"translation":[0,0.5,0]}"#.to_string();
    match count {
        Count::Nodes => {
            let children: Vec<String> = (3..3 + n).map(|c| c.to_string()).collect();
            nodes.push(format!(r#"{{"children":[{}]}}"#, children.join(",")));
            nodes.extend((0..n).map(|_| "{}".to_string()));
        }
        // All in one place: the count is refused before any mesh is read.
        Count::Lights => nodes.extend((0..n).map(|_| r#"{"mesh":2}"#.to_string())),
        Count::Primitives => {
            meshes[0] = json!({"primitives": vec![up(1); n]});
            nodes.push(placed);
        }
        Count::Instances => nodes.extend((0..n).map(|i| format!(r#"{{"mesh":0,"translation":{}}}"#, grid(i)))),
        Count::Materials => {
            materials.extend((0..n).map(|_| json!({"pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1]}})));
            meshes[0] = json!({"primitives": (0..n).map(|i| up(2 + i)).collect::<Vec<_>>()});
            nodes.push(placed);
        }
    }
    let roots: Vec<usize> = match count {
        Count::Nodes | Count::Primitives | Count::Materials => vec![0, 1, 2],
        Count::Lights | Count::Instances => (0..nodes.len()).collect(),
    };
    let doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": roots}],
        "nodes": [],
        "meshes": meshes,
        "materials": materials,
        "buffers": [{"byteLength": bin.len(), "uri": "counts.bin"}],
        "bufferViews": [view(0, 48), view(48, 48), view(96, 48), view(144, 12), view(156, 12)],
        "accessors": [points(0, 0.01), points(1, 5.0), points(2, 0.5),
            {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"},
            {"bufferView": 4, "componentType": 5123, "count": 6, "type": "SCALAR"}],
    });
    let text =
        serde_json::to_string(&doc).unwrap().replacen(r#""nodes":[]"#, &format!(r#""nodes":[{}]"#, nodes.join(",")), 1);
    let path = dir.join(format!("{count:?}.gltf").to_lowercase());
    std::fs::write(&path, text).unwrap();
    path
}

/// Loads a file as `kage info` does: imported, then its receivers refined by default.
fn import_and_refine(path: &Path) -> Result<kage_engine::scene::Scene, String> {
    let mut scene = import(path, ImportOptions::default()).map_err(|e| e.to_string())?;
    kage_engine::receivers::refine(&mut scene, &Default::default()).map_err(|e| e.to_string())?;
    Ok(scene)
}

#[test]
fn files_of_many_nodes_lights_primitives_instances_and_materials_cost_what_they_hold() {
    let _measuring = MEASURING.lock().unwrap_or_else(|e| e.into_inner());
    count_panics();
    let panics = PANICS.load(Ordering::SeqCst);
    let dir = scratch!("fuzz-counts");
    let mut failures = Vec::new();
    for (count, n) in COUNTS {
        let path = count_heavy(count, n, &dir);
        let bytes = std::fs::metadata(&path).unwrap().len() as usize;
        GLOBAL.reset_peak_memory();
        let start = Instant::now();
        let loaded = import_and_refine(&path);
        let (took, used) = (start.elapsed(), GLOBAL.get_peak_memory());
        eprintln!(
            "{count:?} ×{n}: {} in {:.2} s, {} MB allocated, from {:.1} MB",
            loaded
                .as_ref()
                .map_or_else(|e| format!("refused ({e})"), |s| format!("{} instances", flatten(s).instances.len())),
            took.as_secs_f64(),
            used >> 20,
            bytes as f64 / 1e6
        );
        let refused = matches!(count, Count::Lights);
        let broke = match &loaded {
            Ok(_) if refused => Some("loaded past kage's light limit".to_string()),
            Err(e) if refused && !(e.contains(&(n + 1).to_string()) && e.contains("4096")) => {
                Some(format!("refused without naming the count and the limit: {e}"))
            }
            Err(e) if !refused => Some(e.clone()),
            _ if PANICS.load(Ordering::SeqCst) != panics => Some("a panic".into()),
            _ => over_bounds(took, used, bytes),
        };
        if let Some(why) = broke {
            failures.push(keep(&path, &format!("{count:?}: {why}")));
        }
        let _ = std::fs::remove_file(path);
    }
    assert!(failures.is_empty(), "{} count-heavy files broke a rule:\n{}", failures.len(), failures.join("\n"));
}
