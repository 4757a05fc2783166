//! What the `kage` binary's tests share: running it, scratch folders, the repository's assets.

#![allow(dead_code)] // each test binary uses its own subset

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs `kage` with `args`, without receiver refinement unless `args` ask for it: most tests
/// are about something else and bake the source meshes faster ([`kage_as_shipped`] does not).
pub fn kage(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_kage")).args(args).env("KAGE_REFINE_RECEIVERS", "0").output().expect("kage runs")
}

/// Runs `kage` with `args` and the defaults a user gets (receiver refinement on).
pub fn kage_as_shipped(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_kage")).args(args).env_remove("KAGE_REFINE_RECEIVERS").output().expect("kage runs")
}

/// A fresh folder for test `name` under Cargo's `target/tmp` (the next run replaces it; `cargo
/// clean` removes it).
pub fn scratch(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("kage-cli").join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The path of `rel` under the repository's `assets/`.
pub fn asset(rel: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets").join(rel).display().to_string()
}

/// What `o` wrote to stderr.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}
