//! Shared helpers for kage's cross-crate integration tests (`tests/tests/*.rs`).

use kage_engine::bspvt;
use kage_engine::prt::{self, prefilter::Prefiltered};
use kage_engine::scene::{FlatScene, Scene, flatten};
use kage_engine::shading::baked::{Bakes, Look};
use std::path::{Path, PathBuf};

/// `scene`'s baked look seen from `eye`, for `f` to read: BSPVT trees (default settings) and
/// PRT transfer (order 4, 16 regions; the scene must have an environment) baked in memory.
pub fn with_baked_look<T>(scene: &Scene, eye: glam::Vec3, f: impl FnOnce(&Look, &FlatScene) -> T) -> T {
    let flat = flatten(scene);
    let trees = bspvt::bake(&flat, &bspvt::Settings::default(), &|_| {});
    let ps = prt::Settings { order: 4, regions: 16, ..prt::Settings::default() };
    let transfer = prt::bake(scene, &flat, &ps, &|_| {});
    let lighting = prt::Lighting::new(scene, &ps).expect("the scene has an environment");
    let pre = Prefiltered::new(flat.environment.as_ref().expect("the scene has an environment"));
    let bakes = Bakes {
        bspvt: Some(&trees),
        prt: Some(prt::Parts { bake: &transfer, lighting: &lighting, settings: &ps }),
        prefiltered: Some(&pre),
    };
    let look = Look::prepare(scene, &flat, bakes, eye, &mut prt::SilhouetteMemo::default());
    f(&look, &flat)
}

/// `assets/<rel>` in the repository (test scenes, models, environment maps, edge cases).
pub fn asset(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../assets").join(rel)
}

/// A fresh, empty folder for test `name` under Cargo's `target/tmp` (the next run replaces it;
/// `cargo clean` removes it). A macro: only an integration test knows that folder.
#[macro_export]
macro_rules! scratch {
    ($name:expr) => {
        $crate::fresh_dir(std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("kage-tests").join($name))
    };
}

/// `dir`, emptied or made.
pub fn fresh_dir(dir: PathBuf) -> PathBuf {
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir is writable");
    dir
}

/// A copy in `dir` of the self-contained `.gltf` asset `rel` with the extras of its node named
/// `node` set to `extras`.
pub fn with_node_extras(rel: &str, dir: &Path, node: &str, extras: serde_json::Value) -> PathBuf {
    let mut doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(asset(rel)).expect("asset exists")).expect("asset is JSON");
    let nodes = doc["nodes"].as_array_mut().expect("the asset has nodes");
    let target = nodes.iter_mut().find(|n| n["name"] == node).unwrap_or_else(|| panic!("{rel} has no node {node}"));
    target["extras"] = extras;
    let path = dir.join(Path::new(rel).file_name().expect("a file name"));
    std::fs::write(&path, serde_json::to_vec(&doc).expect("serialisable")).expect("scratch is writable");
    path
}
