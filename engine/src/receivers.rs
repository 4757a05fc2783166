//! Receiver refinement driven by the polygonal lights' visibility: per-vertex bakes resolve a
//! shadow only as finely as its receiver is tessellated, and real assets have coarse receivers
//! (a floor of two triangles has no shadow at all between its four vertices).
//!
//! Every instance is refined on its own (an instanced mesh gets one refined copy per instance:
//! its instances receive different shadows), from its source mesh, in rounds:
//! 1. **Seed**: edges longer than the seed length are split, so that no shadow fits inside a
//!    triangle unseen. The seed length is chosen so that seeding all receivers costs a quarter
//!    of the vertex budget (spacing ∝ √(area / budget)).
//! 2. **Refine**: each edge's ends and midpoint are tested for the visibility `V` of every
//!    light — the share of a fixed set of points on the light (its centre and three rings
//!    through its corners and edge midpoints) that the point sees in front of both. An
//!    edge is split when, for some light, `|V(a) − V(b)|` or `|V(mid) − (V(a) + V(b)) / 2|`
//!    exceeds the tolerance: where linear interpolation along the edge misrepresents the
//!    shadow. The marks of a round are split largest error × world length first (an edge's
//!    error spreads over its length) until the budget is spent.
//!
//! Scope today: the lights as placed (a light moved far goes stale until refined again) and
//! polygonal lights only (the environment's PRT shadows do not drive it). Deterministic: the
//! same scene and settings give the same meshes on any thread count.

use crate::accel::SceneBvh;
use crate::scene::refine::Adaptive;
use crate::scene::{FlatLight, MeshRef, PrimitiveId, Scene, flatten};
use glam::Vec3;
use rayon::prelude::*;
use std::collections::HashMap;
use std::sync::Arc;

/// How far to refine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Vertices the refinement may add, over all receivers.
    pub budget: usize,
    /// Largest visibility error (0–1) linear interpolation may make along an edge.
    pub tolerance: f32,
    /// Rounds of marking and splitting after the seed.
    pub rounds: usize,
}

impl Default for Settings {
    fn default() -> Self {
        Self { budget: 10_000, tolerance: 0.1, rounds: 12 }
    }
}

/// What refinement did, per instance in snapshot order: (vertices before, after).
pub type Report = Vec<(usize, usize)>;

/// Refines every mesh instance of `scene` for its polygonal lights (nothing without any),
/// replacing each instance's mesh by its refined copy.
pub fn refine(scene: &mut Scene, settings: &Settings) -> crate::Result<Report> {
    let flat = flatten(scene);
    if flat.lights.is_empty() || settings.budget == 0 {
        let unchanged = |i: &crate::scene::Instance| flat.meshes[i.mesh as usize].positions.len();
        return Ok(flat.instances.iter().map(|i| (unchanged(i), unchanged(i))).collect());
    }
    let probe = Probe::new(&flat.triangles, &flat.lights);
    let mut meshes: Vec<Adaptive> =
        flat.instances.iter().map(|i| Adaptive::new(&flat.meshes[i.mesh as usize])).collect();
    let before: Vec<usize> = meshes.iter().map(Adaptive::vertices).collect();
    let total = before.iter().sum::<usize>() + settings.budget;
    let area: f32 = flat.instances.iter().enumerate().map(|(i, inst)| world_area(&meshes[i], &inst.world)).sum();
    // Bisection leaves right triangles whose legs are ~1/√2 of the longest edge allowed.
    let seed = (2.0 * area / (settings.budget as f32 / 4.0)).sqrt();
    for (mesh, inst) in meshes.iter_mut().zip(&flat.instances) {
        loop {
            let long: Vec<[u32; 2]> =
                mesh.edges().into_iter().filter(|e| world_length(mesh, &inst.world, e) > seed).collect();
            if long.is_empty() || mesh.split(&long, usize::MAX) == 0 {
                break;
            }
        }
    }
    // A vertex keeps its place and normal, and an edge its ends, from round to round: what
    // was probed once is looked up, so a round probes only what the last one added.
    let mut memos: Vec<Memo> = meshes.iter().map(|_| Memo::default()).collect();
    for _ in 0..settings.rounds {
        let used: usize = meshes.iter().map(Adaptive::vertices).sum();
        if used >= total {
            break;
        }
        let marks: Vec<Vec<(f32, [u32; 2])>> = meshes
            .iter()
            .zip(&flat.instances)
            .zip(&mut memos)
            .map(|((m, inst), memo)| marked(m, &inst.world, &probe, settings.tolerance, memo))
            .collect();
        if marks.iter().all(Vec::is_empty) {
            break;
        }
        split_worst(&mut meshes, marks, total - used);
    }
    replace_meshes(scene, &flat.instances, meshes, before)
}

/// Splits the marked edges of every instance, the largest errors first, within `budget` new
/// vertices (a split adds one vertex per side of a seam; counted as one, so the budget may be
/// exceeded by the seams' extra vertices).
fn split_worst(meshes: &mut [Adaptive], marks: Vec<Vec<(f32, [u32; 2])>>, budget: usize) {
    let mut all: Vec<(f32, usize, [u32; 2])> =
        marks.into_iter().enumerate().flat_map(|(i, m)| m.into_iter().map(move |(e, edge)| (e, i, edge))).collect();
    all.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    all.truncate(budget);
    let mut per: Vec<Vec<[u32; 2]>> = vec![Vec::new(); meshes.len()];
    for (_, i, e) in all {
        per[i].extend(meshes[i].longest_around(e));
    }
    for (mesh, edges) in meshes.iter_mut().zip(per) {
        mesh.split(&edges, usize::MAX);
    }
}

/// Puts each instance's refined mesh in place of its source mesh.
fn replace_meshes(
    scene: &mut Scene,
    instances: &[crate::scene::Instance],
    meshes: Vec<Adaptive>,
    before: Vec<usize>,
) -> crate::Result<Report> {
    let mut report = Vec::new();
    for ((inst, mesh), n) in instances.iter().zip(meshes).zip(before) {
        let after = mesh.vertices();
        report.push((n, after));
        if after == n {
            continue;
        }
        let mesh = mesh
            .finish()
            .map_err(|why| crate::Error::Invalid(format!("{}: refining a receiver: {why}", scene.source)))?;
        let entity =
            scene.world.query::<(hecs::Entity, &PrimitiveId)>().iter().find(|(_, id)| **id == inst.id).map(|(e, _)| e);
        let entity = entity.expect("the snapshot's instances are the world's");
        let index = scene.meshes.len() as u32;
        let hash = mesh.hash;
        scene.meshes.push(Arc::new(mesh));
        *scene.world.get::<&mut MeshRef>(entity).expect("an instance has a mesh") = MeshRef { index, hash };
    }
    Ok(report)
}

/// What earlier rounds probed on one mesh: per vertex its lights' visibility, per edge its
/// interpolation error.
#[derive(Default)]
struct Memo {
    vertex: Vec<Vec<f32>>,
    edge: HashMap<[u32; 2], f32>,
}

/// The edges of `mesh` whose visibility interpolates badly, with their error × world length;
/// probes only the vertices and edges `memo` lacks, and keeps them there.
fn marked(
    mesh: &Adaptive,
    world: &glam::Affine3A,
    probe: &Probe,
    tolerance: f32,
    memo: &mut Memo,
) -> Vec<(f32, [u32; 2])> {
    let (p, n) = (mesh.positions(), mesh.normals());
    let at = |a: Vec3, na: Vec3| {
        probe.visibility(world.transform_point3(a), world.transform_vector3(na).normalize_or_zero())
    };
    let new: Vec<Vec<f32>> = (memo.vertex.len()..p.len()).into_par_iter().map(|i| at(p[i], n[i])).collect();
    memo.vertex.extend(new);
    let vertex = &memo.vertex;
    let edges = mesh.edges();
    let fresh: Vec<([u32; 2], f32)> = edges
        .par_iter()
        .filter(|e| !memo.edge.contains_key(*e))
        .map(|&[a, b]| {
            let (va, vb) = (&vertex[a as usize], &vertex[b as usize]);
            let (a_, b_) = (a as usize, b as usize);
            let mid = at(0.5 * (p[a_] + p[b_]), (n[a_] + n[b_]).normalize_or_zero());
            let error = (0..va.len())
                .map(|l| (va[l] - vb[l]).abs().max((mid[l] - 0.5 * (va[l] + vb[l])).abs()))
                .fold(0.0, f32::max);
            ([a, b], error)
        })
        .collect();
    memo.edge.extend(fresh);
    let length = |a: u32, b: u32| world.transform_point3(p[a as usize]).distance(world.transform_point3(p[b as usize]));
    edges
        .into_iter()
        .filter_map(|[a, b]| {
            let error = memo.edge[&[a, b]];
            (error > tolerance).then(|| (error * length(a, b), [a, b]))
        })
        .collect()
}

/// Shadow rays from receiver points to fixed points on every light.
struct Probe {
    bvh: SceneBvh,
    /// Per light: its sample points and its emitting normal.
    lights: Vec<(Vec<Vec3>, Vec3)>,
}

impl Probe {
    fn new(triangles: &[[Vec3; 3]], lights: &[FlatLight]) -> Self {
        let lights = lights.iter().map(|l| (sample_points(&l.points), l.normal)).collect();
        Self { bvh: SceneBvh::new(triangles), lights }
    }

    /// Per light, the share of its points that `p` (normal `n`) sees, in front of both.
    fn visibility(&self, p: Vec3, n: Vec3) -> Vec<f32> {
        let origin = p + n * 1e-4 * (1.0 + p.abs().max_element());
        self.lights
            .iter()
            .map(|(points, normal)| {
                let seen = points
                    .iter()
                    .filter(|&&s| {
                        let d = s - origin;
                        let dist = d.length();
                        let dir = d / dist;
                        dir.dot(n) > 0.0
                            && dir.dot(*normal) < 0.0
                            && !self.bvh.occluded(origin, dir, dist * (1.0 - 1e-4))
                    })
                    .count();
                seen as f32 / points.len() as f32
            })
            .collect()
    }
}

/// A light polygon's probe points: its centre, and three rings (30, 60 and 90 % of the way
/// out) through its corners and edge midpoints — 25 points on a quad.
fn sample_points(polygon: &[Vec3]) -> Vec<Vec3> {
    let c = polygon.iter().copied().sum::<Vec3>() / polygon.len() as f32;
    let n = polygon.len();
    let mut out = vec![c];
    for t in [0.3, 0.6, 0.9] {
        for k in 0..n {
            out.push(c + t * (polygon[k] - c));
            out.push(c + t * (0.5 * (polygon[k] + polygon[(k + 1) % n]) - c));
        }
    }
    out
}

/// World-space area of a mesh under `world`.
fn world_area(mesh: &Adaptive, world: &glam::Affine3A) -> f32 {
    let p = mesh.positions();
    mesh.triangles()
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| world.transform_point3(p[i as usize]));
            0.5 * (b - a).cross(c - a).length()
        })
        .sum()
}

/// World-space length of edge `e` of `mesh`.
fn world_length(mesh: &Adaptive, world: &glam::Affine3A, e: &[u32; 2]) -> f32 {
    let p = mesh.positions();
    world.transform_point3(p[e[0] as usize]).distance(world.transform_point3(p[e[1] as usize]))
}
