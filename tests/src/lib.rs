//! Shared helpers for kage's cross-crate integration tests (`tests/tests/*.rs`), and the
//! measurements `cargo xtask measure` runs.

pub mod floor;
pub mod measure;

use glam::Vec3;
use kage_engine::bspvt;
use kage_engine::prt::{self, prefilter::Prefiltered};
use kage_engine::scene::{FlatScene, PolygonLight, Scene, Transform, flatten};
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

/// A move of a light's corners (world space).
pub type LightMove = fn(&mut Vec<Vec3>);

/// Moves every polygonal light of `scene` by `mv`, applied to its corners in world space.
pub fn move_lights(scene: &mut Scene, mv: LightMove) {
    for (light, t) in scene.world.query_mut::<(&mut PolygonLight, &Transform)>() {
        let mut world: Vec<Vec3> = light.points.iter().map(|p| t.world.transform_point3(*p)).collect();
        mv(&mut world);
        light.points = world.iter().map(|p| t.world.inverse().transform_point3(*p)).collect();
    }
}

/// The Cornell box's light poses, from the light as built: moved 15 cm toward the red wall and
/// turned 20° about its normal (still in the ceiling's plane); lowered 15 cm and tilted 20°;
/// down behind the tall block, 5 cm from it, facing the camera (the block shadows the floor in
/// front).
pub const CORNELL_POSES: [LightMove; 3] = [
    |points| {
        let (c, turn) = (centre(points), glam::Quat::from_rotation_y(20f32.to_radians()));
        points.iter_mut().for_each(|p| *p = c + Vec3::new(0.15, 0.0, 0.0) + turn * (*p - c));
    },
    |points| {
        let (c, tilt) = (centre(points), glam::Quat::from_rotation_x(20f32.to_radians()));
        points.iter_mut().for_each(|p| *p = c - Vec3::new(0.0, 0.15, 0.0) + tilt * (*p - c));
    },
    |points| {
        let (c, face) = (centre(points), glam::Quat::from_rotation_x(90f32.to_radians()));
        points.iter_mut().for_each(|p| *p = Vec3::new(0.37, 0.15, 0.51) + face * (*p - c));
    },
];

/// The mean of `points`.
fn centre(points: &[Vec3]) -> Vec3 {
    points.iter().sum::<Vec3>() / points.len() as f32
}
