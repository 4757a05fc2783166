//! Shared helpers for kage's cross-crate integration tests (`tests/tests/*.rs`).

use std::path::{Path, PathBuf};

/// `assets/<rel>` in the repository (test scenes, models, environment maps, edge cases).
pub fn asset(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../assets").join(rel)
}

/// A fresh, empty scratch directory for one test.
pub fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("kage-test-{}-{name}", std::process::id()));
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
