//! Receiver refinement driven by the polygonal lights' visibility: per-vertex bakes resolve a
//! shadow only as finely as its receiver is tessellated, and real assets have coarse receivers
//! (a floor of two triangles has no shadow at all between its four vertices).
//!
//! Every instance is refined on its own (an instanced mesh gets one refined copy per instance:
//! its instances receive different shadows), from its source mesh, in rounds:
//! 1. **Seed**: edges longer than the seed length are split, so that no shadow fits inside a
//!    triangle unseen. The seed length is half the smallest footprint among what can shadow
//!    the instance (its shadows are about that size) and at most a sixteenth of its diagonal
//!    (the bounce across a plain wall needs vertices too) — a sixteenth no shorter than the
//!    scene's size over 32 away from other instances, as the bounce varies over the distances
//!    between surfaces, and no longer than the distance to them near them ([`Seed::at`]) —,
//!    but no shorter than seeding a quarter of the instance's cap would make it (spacing ∝
//!    √(area / cap)).
//! 2. **Refine**: each edge's ends and midpoint are tested for the visibility `V` of every
//!    view of what lights the scene ([`probe`]): a light where it is (the share of 49 fixed
//!    points spread over it that the point sees in front of both), every cell of a light's
//!    declared reach box, and the environment (the luminance-weighted share of fixed
//!    directions that the point sees past its own group). An edge is split when, for some view
//!    and side, what its pixels are shaded with misses the truth at its midpoint by more than
//!    the tolerance ([`marks`]), while it is longer than `√(2 · area / cap)` (the spacing at
//!    which the whole surface would cost the cap). Refinement stops when no such edge misses
//!    (the error and that spacing decide), after [`Settings::rounds`] rounds, or when the cap
//!    is spent: the marks of a round are then split largest error × world length first (in
//!    steps of 2^¼, by place within a step, see `split_worst`).
//!
//! **Local**: an instance's refinement is a pure function of its own mesh and placement, the
//! lights' views and the instances that can shadow it ([`probe::Near`]: those between it and
//! a light, and of its group nearby for the environment), probed against those alone, and the
//! bounds of the instances its seed is finer near. So an
//! edit re-refines only the receivers whose shadows it can change, each named by its own
//! [`keys`] entry, and the result is a cold refinement's, byte for byte, on any thread count.
//!
//! Lights without a declared reach are refined for where they are: moved, they are refined
//! again when the scene is next loaded (and the changed receivers re-baked). Lights with one
//! are refined for the whole box, so moving them inside it changes nothing. Groups are refined
//! as posed.

mod bytes;
mod marks;
mod probe;

use crate::scene::refine::Adaptive;
use crate::scene::{FlatScene, Mesh, PrimitiveId, Scene, flatten};
use glam::Vec3;
use marks::{Memo, Tier};
use probe::{Near, Probe, Scope, Sources};
use rayon::prelude::*;

/// How far to refine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Vertices the refinement may add to one instance (its cap).
    pub budget: usize,
    /// Largest visibility error (0–1, a share of the light) interpolation between an edge's
    /// ends may make at its midpoint.
    pub tolerance: f32,
    /// Rounds of marking and splitting after the seed.
    pub rounds: usize,
}

impl Default for Settings {
    fn default() -> Self {
        Self { budget: 6_000, tolerance: 0.03, rounds: 12 }
    }
}

/// Most vertices refinement may add to a whole scene: with each instance's cap, a file of
/// many instances would otherwise cost the cap times their count (10⁵ pebbles at 6,000 each).
pub const SCENE_ALLOWANCE: usize = 2_000_000;

impl Settings {
    /// These settings for a scene of `instances` instances: the cap halved until every
    /// instance at its cap stays within [`SCENE_ALLOWANCE`] (halved, not divided, so adding or
    /// deleting an object changes the cap, and every key, only when the count crosses a step).
    pub fn for_instances(self, instances: usize) -> Self {
        let mut budget = self.budget;
        while budget.saturating_mul(instances) > SCENE_ALLOWANCE {
            budget /= 2;
        }
        Self { budget, ..self }
    }
}

/// What refinement did, per instance in snapshot order: (vertices before, after).
pub type Report = Vec<(usize, usize)>;

/// Refines every mesh instance of `scene` for its polygonal lights and its environment (nothing
/// without either), replacing each instance's mesh by its refined copy. Starts from the source
/// meshes ([`crate::scene::SourceMesh`]), so refining a refined scene again equals refining it
/// once.
pub fn refine(scene: &mut Scene, settings: &Settings) -> crate::Result<Report> {
    refine_reporting(scene, settings, &|_| {})
}

/// [`refine`], calling `progress` with the number of instances refined so far.
pub fn refine_reporting(
    scene: &mut Scene,
    settings: &Settings,
    progress: &(dyn Fn(usize) + Sync),
) -> crate::Result<Report> {
    scene.restore_source_meshes();
    let refinement = Refinement::of(scene, settings, Vec::new(), progress)?;
    Ok(refinement.apply(scene))
}

/// Bumped whenever refinement would refine the same scene differently: it names kept
/// refinements ([`keys`]).
pub const VERSION: u32 = 10;

/// Per instance (snapshot order), what its refinement reads of `scene` (its source meshes, as
/// [`Scene::restore_source_meshes`] leaves it) and `settings`, hashed: the scene's size step,
/// its mesh and placement, the bounds of the instances its seed is finer near,
/// the occluding meshes and placements of the instances that can shadow it, and the views of
/// the lights and the environment it probes (a light moved within its reach box keeps its
/// views, so its keys). Equal keys refine to the same mesh.
pub fn keys(scene: &Scene, settings: &Settings) -> Vec<blake3::Hash> {
    let flat = flatten(scene);
    let settings = settings.for_instances(flat.instances.len());
    let scope = Scope::new(&flat);
    let mut common = blake3::Hasher::new();
    common.update(b"kage receiver refinement\0");
    common.update(&VERSION.to_le_bytes());
    common.update(&(settings.budget as u64).to_le_bytes());
    common.update(&settings.tolerance.to_le_bytes());
    common.update(&(settings.rounds as u64).to_le_bytes());
    common.update(&scope.size.to_le_bytes());
    hash_views(&mut common, &scope.views);
    (0..flat.instances.len())
        .into_par_iter()
        .map(|i| {
            let mut h = common.clone();
            let inst = &flat.instances[i];
            h.update(&flat.meshes[inst.mesh as usize].hash.0);
            h.update(bytemuck::cast_slice(&inst.world.to_cols_array()));
            let near = scope.near(i);
            for list in [&near.lights, &near.environment] {
                h.update(&(list.len() as u64).to_le_bytes());
                for &j in list {
                    h.update(&flat.occluder_hash(j as usize));
                    h.update(bytemuck::cast_slice(&flat.instances[j as usize].world.to_cols_array()));
                }
            }
            let close = seed(&scope, i, &near).close;
            h.update(&(close.len() as u64).to_le_bytes());
            for (lo, hi) in &close {
                h.update(bytemuck::cast_slice(&[lo.to_array(), hi.to_array()]));
            }
            h.finalize()
        })
        .collect()
}

/// Hashes what the probe looks at.
fn hash_views(h: &mut blake3::Hasher, views: &[Sources]) {
    for view in views {
        match view {
            Sources::Points { points, facing } => {
                h.update(&(points.len() as u64).to_le_bytes());
                h.update(bytemuck::cast_slice(points));
                h.update(bytemuck::bytes_of(&facing.unwrap_or(Vec3::ZERO)));
            }
            Sources::Directions(d) => {
                h.update(&(d.len() as u64).to_le_bytes());
                d.iter().for_each(|(dir, w)| {
                    h.update(bytemuck::bytes_of(dir));
                    h.update(&w.to_le_bytes());
                });
            }
        }
    }
}

/// One instance's refinement: its vertices before, and its refined mesh where refinement
/// changed it.
#[derive(Clone, Debug, PartialEq)]
pub struct Receiver {
    before: usize,
    refined: Option<Mesh>,
}

/// A refinement of a scene, not yet applied: one [`Receiver`] per instance (snapshot order).
#[derive(Clone, Debug, PartialEq)]
pub struct Refinement {
    receivers: Vec<Receiver>,
}

impl Refinement {
    /// Refines `scene` as it stands (call [`Scene::restore_source_meshes`] first to start from
    /// the source meshes), taking each instance's refinement from `kept` (by snapshot index)
    /// where it holds one for the instance's source mesh, and refining the others: with
    /// `kept` read under [`keys`], the same as refining all. Each instance's cap is
    /// [`Settings::for_instances`]'s; `progress` hears the instances done so far.
    pub fn of(
        scene: &Scene,
        settings: &Settings,
        mut kept: Vec<Option<Receiver>>,
        progress: &(dyn Fn(usize) + Sync),
    ) -> crate::Result<Self> {
        let flat = flatten(scene);
        let settings = &settings.for_instances(flat.instances.len());
        let sources: Vec<usize> = flat.instances.iter().map(|i| flat.meshes[i.mesh as usize].positions.len()).collect();
        kept.resize(sources.len(), None);
        let kept: Vec<Option<Receiver>> =
            kept.into_iter().zip(&sources).map(|(k, &n)| k.filter(|k| k.before == n)).collect();
        let scope = Scope::new(&flat);
        let idle = (flat.lights.is_empty() && flat.environment.is_none()) || settings.budget == 0;
        let probe = (!idle && kept.iter().any(Option::is_none)).then(|| Probe::new(&flat, &scope));
        let done = std::sync::atomic::AtomicUsize::new(0);
        let receivers = kept
            .into_par_iter()
            .enumerate()
            .map(|(i, k)| {
                let receiver = match (k, &probe) {
                    (Some(k), _) => Ok(k),
                    (None, None) => Ok(Receiver { before: sources[i], refined: None }),
                    (None, Some(probe)) => refined(&flat, i, probe, settings)
                        .map_err(|why| crate::Error::Invalid(format!("{}: refining a receiver: {why}", scene.source))),
                };
                progress(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1);
                receiver
            })
            .collect::<crate::Result<_>>()?;
        Ok(Self { receivers })
    }

    /// Each instance's refinement, in snapshot order.
    pub fn receivers(&self) -> &[Receiver] {
        &self.receivers
    }

    /// Puts each instance's refined mesh in place of its source mesh and says what changed.
    /// `scene` must be the one refined (with its source meshes).
    pub fn apply(self, scene: &mut Scene) -> Report {
        let flat = flatten(scene);
        let entities: std::collections::HashMap<PrimitiveId, hecs::Entity> =
            scene.world.query::<(hecs::Entity, &PrimitiveId)>().iter().map(|(e, id)| (*id, e)).collect();
        let mut report = Vec::new();
        for (inst, Receiver { before, refined }) in flat.instances.iter().zip(self.receivers) {
            let Some(mesh) = refined else {
                report.push((before, before));
                continue;
            };
            report.push((before, mesh.positions.len()));
            let entity = entities.get(&inst.id).expect("the snapshot's instances are the world's");
            scene.set_refined_mesh(*entity, mesh);
        }
        report
    }
}

/// Instance `i` of `flat` refined: seeded, then split where `probe` finds its visibility
/// interpolating badly, round by round, within its cap.
fn refined(
    flat: &FlatScene,
    i: usize,
    probe: &Probe,
    settings: &Settings,
) -> Result<Receiver, crate::scene::mesh::MeshProblem> {
    let inst = &flat.instances[i];
    let source = Adaptive::new(&flat.meshes[inst.mesh as usize]);
    let before = source.vertices();
    let near = probe.scope.near(i);
    let total = before + settings.budget;
    let mut mesh = seeded(&source, &inst.world, settings.budget / 4, &seed(probe.scope, i, &near));
    // A vertex keeps its place and normal, and an edge its ends, from round to round: what
    // was probed once is looked up, so a round probes only what the last one added.
    let mut memo = Memo::default();
    let shortest = (2.0 * world_area(&source, &inst.world) / settings.budget.max(1) as f32).sqrt();
    for _ in 0..settings.rounds {
        if mesh.vertices() >= total {
            break;
        }
        let criterion = (settings.tolerance, shortest);
        let mut marks = marks::marked(&mesh, (&inst.world, &near), probe, criterion, &mut memo);
        if marks.is_empty() {
            break;
        }
        if marks.iter().any(|m| m.0 == Tier::Lights) {
            marks.retain(|m| m.0 == Tier::Lights);
        }
        let left = total - mesh.vertices();
        split_worst(&mut mesh, marks, left);
    }
    let refined = (mesh.vertices() != before).then(|| mesh.finish()).transpose()?;
    Ok(Receiver { before, refined })
}

/// How long the seed's edges may be on one receiver (see [`seed`]).
#[derive(Debug)]
struct Seed {
    /// The shortest: the shadow cap, and a sixteenth of the receiver's diagonal.
    fine: f32,
    /// The longest: the shadow cap, and that sixteenth no shorter than the scene's size over
    /// [`SCENE_DIVISIONS`].
    coarse: f32,
    /// The bounds of the other instances within `coarse` of the receiver's, where `fine` is
    /// shorter than `coarse` and they are at most [`MOST_CLOSE`] (empty otherwise).
    close: Vec<(Vec3, Vec3)>,
}

impl Seed {
    /// The longest seed edge with its midpoint at `p`: `coarse`, but `d` (never below `fine`)
    /// at a distance `0 < d < coarse` from another instance's bounds — the bounce varies over
    /// the distance to the surfaces nearby, and falls off towards where two meet (a box's foot
    /// on a floor). A point on or inside another's bounds (a face resting on a floor, an
    /// object inside a room's bounds) keeps `coarse`: a resting face is hidden, and inside
    /// bounds the distance says nothing about the surfaces.
    fn at(&self, p: Vec3) -> f32 {
        let gap = |(lo, hi): &(Vec3, Vec3)| (*lo - p).max(p - *hi).max(Vec3::ZERO).length();
        let d = self.close.iter().map(gap).fold(f32::INFINITY, f32::min);
        if d > 0.0 && d < self.coarse { d.max(self.fine) } else { self.coarse }
    }
}

/// The seed of receiver `i`, shadowed by `near`. Its edges are at most half the smallest
/// footprint (the middle side of the bounds) of what can shadow it, itself included — its
/// shadows are about that size — and at most a sixteenth of its own diagonal, so that light
/// that varies over it without a shadow's edge (the bounce across a wall) has vertices to vary
/// between. Away from other instances that sixteenth is no shorter than the scene's size over
/// [`SCENE_DIVISIONS`], as the bounce varies over the distances between surfaces: an object
/// much smaller than the scene needs fewer, except near what it stands on ([`Seed::at`]).
fn seed(scope: &Scope, i: usize, near: &Near) -> Seed {
    let middle = |(lo, hi): (Vec3, Vec3)| {
        let mut s = (hi - lo).to_array();
        s.sort_by(f32::total_cmp);
        s[1]
    };
    let sides = near.lights.iter().chain(&near.environment).filter_map(|&j| scope.bounds[j as usize].map(middle));
    let cap = 0.5 * sides.fold(f32::INFINITY, f32::min);
    let own = scope.bounds[i].map_or(f32::INFINITY, |(lo, hi)| (hi - lo).length() / SEED_DIVISIONS);
    let (fine, coarse) = (cap.min(own), cap.min(own.max(scope.size / SCENE_DIVISIONS)));
    // Among a crowd (a heap of pebbles) the seed stays coarse: looking at every neighbour would
    // cost each member the crowd's size.
    let close = if fine < coarse { scope.close(i, coarse, MOST_CLOSE).unwrap_or_default() } else { Vec::new() };
    Seed { fine, coarse, close: close.iter().filter_map(|&j| scope.bounds[j as usize]).collect() }
}

/// Most other instances a seed is finer near: with more within its reach, it is coarse.
const MOST_CLOSE: usize = 16;

/// Seed edges across an instance's diagonal at least (see [`seed`]).
const SEED_DIVISIONS: f32 = 16.0;

/// Seed edges across the scene's size at most, away from other instances (see [`seed`]).
const SCENE_DIVISIONS: f32 = 32.0;

/// The mesh seeded: every edge longer than the seed allows at its midpoint split, so that no
/// shadow fits inside a triangle unseen by the midpoint test. The lengths are `seed`'s, or
/// where seeding costs about `share` vertices if that is longer, and grow by √2 until seeding
/// costs at most `share` (bisection halves a triangle's area per level, so the vertices a
/// length costs jump by about 2× between levels), so the rounds keep the rest of the cap.
fn seeded(source: &Adaptive, world: &glam::Affine3A, share: usize, seed: &Seed) -> Adaptive {
    // Bisection leaves right triangles whose legs are ~1/√2 of the longest edge allowed.
    let spread = (2.0 * world_area(source, world) / share.max(1) as f32).sqrt();
    let mut growth = 1.0;
    loop {
        let mut mesh = source.clone();
        loop {
            let p = mesh.positions();
            let long = |e: &[u32; 2]| {
                let (a, b) = (world.transform_point3(p[e[0] as usize]), world.transform_point3(p[e[1] as usize]));
                a.distance(b) > growth * spread.max(seed.at(0.5 * (a + b)))
            };
            // The longest edge of each triangle around a long one (Rivara's bisection): a
            // length that varies over the mesh would otherwise split short legs into slivers.
            let long: Vec<[u32; 2]> =
                mesh.edges().into_iter().filter(long).flat_map(|e| mesh.longest_around(e)).collect();
            if long.is_empty() || mesh.split(&long, usize::MAX) == 0 {
                break;
            }
        }
        if mesh.vertices() - source.vertices() <= share {
            return mesh;
        }
        growth *= std::f32::consts::SQRT_2;
    }
}

/// Splits the marked edges, the largest errors first, within `budget` new vertices (a split
/// adds one vertex per side of a seam; counted as one, so the budget may be exceeded by the
/// seams' extra vertices).
///
/// Errors are compared in steps of 2^¼ (19 %), and marks in one step go by place
/// ([`Adaptive::place`]). When the cap cuts a step, an edit that adds or drops marks in one
/// place (a moved box's shadow) moves the cut along one stretch of places, rather than among
/// near-equal marks all over the receiver, so the vertices, and the bakes, away from the edit
/// mostly stay as they were (`docs/receivers.md#edits`).
fn split_worst(mesh: &mut Adaptive, marks: Vec<marks::Mark>, budget: usize) {
    let step = |e: f32| (4.0 * e.log2()).floor() as i32;
    let mut all: Vec<(i32, u64, [u32; 2])> =
        marks.into_iter().map(|(_, e, edge)| (step(e), mesh.place(edge), edge)).collect();
    all.sort_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    all.truncate(budget);
    let edges: Vec<[u32; 2]> = all.into_iter().flat_map(|(_, _, e)| mesh.longest_around(e)).collect();
    mesh.split(&edges, usize::MAX);
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The cap stands while every instance at it fits the scene's allowance, and is halved
    /// (so it moves only when the count crosses a step) until they do; off stays off.
    #[test]
    fn the_cap_is_halved_until_the_scene_fits_its_allowance() {
        let cap = |budget, n| Settings { budget, ..Settings::default() }.for_instances(n).budget;
        assert_eq!(cap(6000, 333), 6000);
        assert_eq!(cap(6000, 334), 3000);
        assert_eq!(cap(6000, 100_001), 11);
        assert_eq!(cap(6000, 3_000_000), 0);
        assert_eq!(cap(0, 10), 0);
        for n in [1, 500, 10_000, 1_000_000] {
            assert!(cap(6000, n) * n <= SCENE_ALLOWANCE, "{n} instances");
            assert_eq!(Settings::default().for_instances(n).for_instances(n).budget, cap(6000, n), "idempotent");
        }
    }
}
