//! The BSPVT occluders' BVHs, kept between runs in the store's memos: a BVH is a pure
//! function of its instance's world-space triangles (obvhs' build is deterministic), so an edit
//! rebuilds only the BVHs of the instances it touched. On the slab scene, building the ground's
//! BVH (4608 triangles, obvhs' slowest preset) had been 3.6 % of a warm re-bake's CPU time.
//!
//! Like every memo it costs only time: an entry is named by a hash of the triangles and the
//! builder, restored exactly or not at all ([`SceneBvh::from_bytes`]), and `gc` drops them.

use crate::store::{Memo, Result, Store};
use glam::Vec3;
use kage_engine::accel::{Occluders, SceneBvh};
use kage_engine::bspvt;
use kage_engine::scene::FlatScene;
use std::sync::Mutex;

/// The builder whose output the entries hold: obvhs' version (as `Cargo.lock` pins it; a test
/// keeps the two in step, since another version may build other trees) and the preset
/// [`SceneBvh::new`] uses.
const BUILDER: &str = "obvhs 0.4.0 very_slow_build";

/// Instances with fewer triangles are built, not cached: their build takes less than looking
/// an entry up, and every move of such an instance would leave another entry behind.
const MIN_TRIANGLES: usize = 256;

/// The scene's BSPVT occluders, each piece's BVH ([`kage_engine::accel::instances::PIECE`])
/// restored from the store where it holds one for exactly its triangles, else built; also the
/// entries to store for the BVHs built.
pub fn occluders(store: &Store, flat: &FlatScene) -> Result<(Occluders, Vec<Memo>)> {
    let (built, failed) = (Mutex::new(Vec::new()), Mutex::new(None));
    let parts = bspvt::occluder_triangles(flat);
    let occluders = Occluders::with(&parts, &bspvt::occluder_holes(flat), |_, triangles| {
        let name = (triangles.len() >= MIN_TRIANGLES).then(|| name(triangles));
        let stored = name.as_deref().map_or(Ok(None), |n| store.memo(n)).unwrap_or_else(|e| {
            failed.lock().expect("not poisoned").get_or_insert(e);
            None
        });
        let restored = stored.as_deref().and_then(|b| SceneBvh::from_bytes(triangles, b));
        restored.unwrap_or_else(|| {
            let bvh = SceneBvh::new(triangles);
            if let Some(n) = name {
                built.lock().expect("not poisoned").push((n, bvh.to_bytes()));
            }
            bvh
        })
    });
    let mut built = built.into_inner().expect("not poisoned");
    // Built in parallel: stored in a fixed order.
    built.sort_unstable_by(|a, b| a.0.cmp(&b.0));
    failed.into_inner().expect("not poisoned").map_or(Ok((occluders, built)), Err)
}

/// The store's name for the BVH of `triangles`.
fn name(triangles: &[[Vec3; 3]]) -> String {
    let mut h = blake3::Hasher::new();
    h.update(BUILDER.as_bytes());
    h.update(bytemuck::cast_slice(triangles));
    format!("bvh {BUILDER} {}", h.finalize().to_hex())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The entries name the obvhs version the workspace builds with.
    #[test]
    fn the_builder_names_the_locked_obvhs() {
        let lock = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../Cargo.lock")).unwrap();
        let version = lock
            .split("[[package]]")
            .find_map(|p| p.contains("name = \"obvhs\"").then(|| p.split("version = \"").nth(1)?.split('"').next()))
            .flatten()
            .expect("obvhs is locked");
        assert!(BUILDER.starts_with(&format!("obvhs {version} ")), "{BUILDER} for obvhs {version}");
    }

    #[test]
    fn names_differ_with_the_triangles() {
        let a = [[Vec3::ZERO, Vec3::X, Vec3::Y]];
        let b = [[Vec3::ZERO, Vec3::X, Vec3::Z]];
        assert_eq!(name(&a), name(&a));
        assert_ne!(name(&a), name(&b));
    }
}
