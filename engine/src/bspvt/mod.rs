//! BSPVT: shadows from polygonal lights with BSP visibility trees (Okuno & Iwasaki, seed
//! `000_…txt`; summary in DESIGN.md).
//!
//! - [`visibility`]: per-vertex visibility cube maps (faces aligned to world axes), cast only
//!   above the horizon;
//! - [`tree`]: per face, the BSP tree of Algorithm 1 with the seed's two corrections;
//! - [`layout`]: the compact versioned byte layout (≈2 bytes per node);
//! - [`shade`]: per vertex and light, the light polygon clipped by face frusta and tree planes
//!   (planes through the vertex) and integrated with LTC, weighted by the leaves' visibility;
//!   the same code runs `ltc-exact-vis` (per visible texel) and `ltc-unshadowed`.
//!
//! Baking depends only on the occluders' geometry (lights are not occluders: they move freely
//! at run time), the face resolution and ε; it is parallel over vertices and deterministic.

pub mod layout;
pub mod plan;
pub mod shade;
pub mod tree;
pub mod visibility;

use crate::accel::SceneBvh;
use crate::scene::{FlatScene, NO_LIGHT, Scene};
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

/// Bake parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Cube-face resolution (texels per side).
    pub res: usize,
    /// Split clusters while their error (in mean-texel units) exceeds this.
    pub epsilon: f64,
}

impl Default for Settings {
    fn default() -> Self {
        Self { res: 64, epsilon: 2.0 }
    }
}

/// Baked trees of one mesh instance: vertex `v`'s record is `data[offsets[v]..offsets[v + 1]]`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BakedInstance {
    /// Record offsets (one more than vertices).
    pub offsets: Vec<u32>,
    /// Concatenated vertex records (see [`layout`]).
    pub data: Vec<u8>,
}

impl BakedInstance {
    /// The record of vertex `v`.
    pub fn record(&self, v: usize) -> &[u8] {
        &self.data[self.offsets[v] as usize..self.offsets[v + 1] as usize]
    }
}

/// Statistics of a bake.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stats {
    /// Vertices baked.
    pub vertices: usize,
    /// Leaves over all faces and vertices.
    pub leaves: usize,
    /// Nodes (leaves + splits).
    pub nodes: usize,
    /// Bytes of all records.
    pub bytes: usize,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// A bake of every receiver instance of a scene snapshot.
#[derive(Clone, Debug)]
pub struct Bake {
    /// Parameters used.
    pub settings: Settings,
    /// Per instance, in [`FlatScene::instances`] order.
    pub instances: Vec<BakedInstance>,
    /// Statistics.
    pub stats: Stats,
}

/// The BVH of everything that casts shadows on polygonal-light receivers (not the lights).
pub fn occluder_bvh(flat: &FlatScene) -> SceneBvh {
    let tris: Vec<_> =
        flat.triangles.iter().zip(&flat.refs).filter(|(_, r)| r.light == NO_LIGHT).map(|(t, _)| *t).collect();
    SceneBvh::new(&tris)
}

/// Bakes one vertex: its record and (leaves, nodes). Faces entirely below the horizon or
/// entirely occluded store no tree: both contribute nothing.
pub fn bake_vertex(occluders: &SceneBvh, p: glam::Vec3, n: glam::Vec3, s: &Settings) -> (Vec<u8>, usize, usize) {
    let vis = visibility::cast(occluders, p, n, s.res);
    let faces: [Option<Vec<tree::Node>>; 6] = std::array::from_fn(|f| {
        tree::build(vis.face(f), s.res, s.epsilon).filter(|t| t.as_slice() != [tree::Node::Leaf(0.0)])
    });
    let nodes: usize = faces.iter().flatten().map(Vec::len).sum();
    let leaves = faces.iter().flatten().flatten().filter(|n| matches!(n, tree::Node::Leaf(_))).count();
    (layout::encode_vertex(&faces), leaves, nodes)
}

/// Bakes every receiver vertex, in parallel; `progress` gets the number of vertices done.
/// With no polygonal light in the scene nothing can be reached: every record is empty.
pub fn bake(scene: &Scene, flat: &FlatScene, s: &Settings, progress: &(dyn Fn(usize) + Sync)) -> Bake {
    let start = Instant::now();
    let occluders = occluder_bvh(flat);
    let done = AtomicUsize::new(0);
    let mut stats = Stats::default();
    let instances = (0..flat.instances.len())
        .map(|i| {
            let n = scene.meshes[flat.instances[i].mesh as usize].positions.len();
            let records: Vec<(Vec<u8>, usize, usize)> = (0..n)
                .into_par_iter()
                .map(|v| {
                    let (p, normal) = flat.vertex(&scene.meshes, i, v);
                    let r = if flat.lights.is_empty() {
                        (layout::encode_vertex(&Default::default()), 0, 0)
                    } else {
                        bake_vertex(&occluders, p, normal, s)
                    };
                    progress(done.fetch_add(1, Ordering::Relaxed) + 1);
                    r
                })
                .collect();
            let mut offsets = vec![0u32];
            let mut data = Vec::new();
            for (rec, leaves, nodes) in records {
                data.extend_from_slice(&rec);
                offsets.push(data.len() as u32);
                stats.leaves += leaves;
                stats.nodes += nodes;
            }
            stats.vertices += n;
            stats.bytes += data.len();
            BakedInstance { offsets, data }
        })
        .collect();
    stats.seconds = start.elapsed().as_secs_f64();
    Bake { settings: *s, instances, stats }
}

/// Which visibility the per-vertex shading uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Baked BSP visibility trees.
    Bspvt,
    /// The raw visibility cube map, cast at shading time (the tree's ground truth).
    ExactVis,
    /// No visibility.
    Unshadowed,
}

/// Outgoing radiance toward `eye` from the polygonal lights at every receiver vertex, per
/// instance in [`FlatScene::instances`] order. `bake` is required for [`Method::Bspvt`].
pub fn shade_vertices(
    scene: &Scene,
    flat: &FlatScene,
    method: Method,
    bake: Option<&Bake>,
    s: &Settings,
    eye: glam::Vec3,
) -> Vec<Vec<glam::Vec3>> {
    let table = crate::math::ltc::table();
    let occluders = (method == Method::ExactVis).then(|| occluder_bvh(flat));
    (0..flat.instances.len())
        .map(|i| {
            let n = scene.meshes[flat.instances[i].mesh as usize].positions.len();
            let material = flat.instances[i].material;
            (0..n)
                .into_par_iter()
                .map(|v| {
                    let (p, normal) = flat.vertex(&scene.meshes, i, v);
                    let shader = shade::PointShader::new(&table, p, normal, eye, &material);
                    match method {
                        Method::Bspvt => {
                            let rec = bake.expect("bspvt shading needs a bake").instances[i].record(v);
                            shader.shade(&flat.lights, shade::Visibility::Tree(rec))
                        }
                        Method::ExactVis => {
                            let cube = visibility::cast(occluders.as_ref().expect("built above"), p, normal, s.res);
                            shader.shade(&flat.lights, shade::Visibility::Exact(&cube))
                        }
                        Method::Unshadowed => shader.shade(&flat.lights, shade::Visibility::Unshadowed),
                    }
                })
                .collect()
        })
        .collect()
}
