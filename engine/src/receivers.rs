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
//!    view of what lights the scene (see [`View`]): a light where it is (the share of 49 fixed
//!    points spread over it that the point sees in front of both), every cell of a light's
//!    declared reach box, and the environment (the luminance-weighted share of fixed directions
//!    that the point sees past its own group). An edge is split when, for some view and side,
//!    what its pixels are shaded with misses the truth at its midpoint by more than the
//!    tolerance: for a light, the visible fraction as pixels interpolate it (shadowed over
//!    unshadowed share; an end inside geometry takes no part) weighed by the unshadowed share;
//!    for the environment, `|V(a) − V(b)|` or `|V(mid) − (V(a) + V(b)) / 2|` (see `side_error`). The marks of a round are split
//!    largest error × world length first (an edge's error spreads over its length; in steps of
//!    2^¼, by place within a step, see `split_worst`) until the budget is spent.
//!
//! Lights without a declared reach are refined for where they are: moved, they are refined
//! again when the scene is next loaded (and the changed receivers re-baked). Lights with one
//! are refined for the whole box, so moving them inside it changes nothing. Groups are refined
//! as posed. Deterministic: the same scene and settings give the same meshes on any thread
//! count.

use crate::accel::SceneBvh;
use crate::math::color::luminance;
use crate::math::sampling::{hammersley, uniform_sphere, uniform_triangle};
use crate::scene::refine::{Adaptive, Refined};
use crate::scene::{EnvironmentLight, FlatLight, FlatScene, NO_LIGHT, PrimitiveId, Scene, flatten};
use glam::Vec3;
use rayon::prelude::*;
use std::collections::HashMap;

/// How far to refine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Vertices the refinement may add, over all receivers.
    pub budget: usize,
    /// Largest visibility error (0–1, a share of the light) interpolation between an edge's
    /// ends may make at its midpoint.
    pub tolerance: f32,
    /// Rounds of marking and splitting after the seed.
    pub rounds: usize,
}

impl Default for Settings {
    fn default() -> Self {
        Self { budget: 10_000, tolerance: 0.03, rounds: 12 }
    }
}

/// What refinement did, per instance in snapshot order: (vertices before, after).
pub type Report = Vec<(usize, usize)>;

/// Refines every mesh instance of `scene` for its polygonal lights and its environment (nothing
/// without either), replacing each instance's mesh by its refined copy. Starts from the source
/// meshes ([`crate::scene::SourceMesh`]), so refining a refined scene again equals refining it
/// once.
pub fn refine(scene: &mut Scene, settings: &Settings) -> crate::Result<Report> {
    scene.restore_source_meshes();
    let refinement = Refinement::of(scene, settings)?;
    Ok(refinement.apply(scene))
}

/// Bumped whenever refinement would refine the same scene differently: it names kept
/// refinements ([`key`]).
pub const VERSION: u32 = 6;

/// What refinement reads of `scene` (its source meshes, as [`Scene::restore_source_meshes`]
/// leaves it) and `settings`, hashed: the instances' meshes and placements, every occluding
/// triangle, and the views of the lights and the environment it probes (a light moved within
/// its reach box keeps its views, so its key). Equal keys refine to the same meshes.
pub fn key(scene: &Scene, settings: &Settings) -> blake3::Hash {
    let flat = flatten(scene);
    let mut h = blake3::Hasher::new();
    h.update(b"kage receiver refinement\0");
    h.update(&VERSION.to_le_bytes());
    h.update(&(settings.budget as u64).to_le_bytes());
    h.update(&settings.tolerance.to_le_bytes());
    h.update(&(settings.rounds as u64).to_le_bytes());
    for (i, inst) in flat.instances.iter().enumerate() {
        h.update(&flat.occluder_hash(i));
        h.update(bytemuck::cast_slice(&inst.world.to_cols_array()));
        h.update(&inst.group.to_bits().get().to_le_bytes());
    }
    for (t, r) in flat.triangles.iter().zip(&flat.refs).filter(|(_, r)| r.light == NO_LIGHT) {
        h.update(bytemuck::cast_slice(t));
        h.update(&r.owner.to_le_bytes());
    }
    let views = flat.lights.iter().flat_map(light_views).chain(flat.environment.as_ref().map(environment_view));
    for view in views {
        match view {
            View::Points { points, facing } => {
                h.update(&(points.len() as u64).to_le_bytes());
                h.update(bytemuck::cast_slice(&points));
                h.update(bytemuck::bytes_of(&facing.unwrap_or(Vec3::ZERO)));
            }
            View::Directions(d) => {
                h.update(&(d.len() as u64).to_le_bytes());
                d.iter().for_each(|(dir, w)| {
                    h.update(bytemuck::bytes_of(dir));
                    h.update(&w.to_le_bytes());
                });
            }
        }
    }
    h.finalize()
}

/// A refinement of a scene, not yet applied: per instance (snapshot order), its vertices
/// before, and its refined mesh where refinement changed it.
#[derive(Clone, Debug, PartialEq)]
pub struct Refinement {
    instances: Vec<(usize, Option<Refined>)>,
}

impl Refinement {
    /// Refines `scene` as it stands (call [`Scene::restore_source_meshes`] first to start from
    /// the source meshes).
    pub fn of(scene: &Scene, settings: &Settings) -> crate::Result<Self> {
        let flat = flatten(scene);
        let source_count = |i: &crate::scene::Instance| flat.meshes[i.mesh as usize].positions.len();
        if (flat.lights.is_empty() && flat.environment.is_none()) || settings.budget == 0 {
            return Ok(Self { instances: flat.instances.iter().map(|i| (source_count(i), None)).collect() });
        }
        let probe = Probe::new(&flat);
        let source: Vec<Adaptive> =
            flat.instances.iter().map(|i| Adaptive::new(&flat.meshes[i.mesh as usize])).collect();
        let before: Vec<usize> = source.iter().map(Adaptive::vertices).collect();
        let total = before.iter().sum::<usize>() + settings.budget;
        let mut meshes = seeded(&source, &flat.instances, settings.budget / 4);
        // A vertex keeps its place and normal, and an edge its ends, from round to round: what
        // was probed once is looked up, so a round probes only what the last one added.
        let mut memos: Vec<Memo> = meshes.iter().map(|_| Memo::default()).collect();
        for _ in 0..settings.rounds {
            let used: usize = meshes.iter().map(Adaptive::vertices).sum();
            if used >= total {
                break;
            }
            let mut marks: Vec<Vec<Mark>> = meshes
                .iter()
                .zip(&flat.instances)
                .zip(&mut memos)
                .enumerate()
                .map(|(i, ((m, inst), memo))| marked(m, (i, &inst.world), &probe, settings.tolerance, memo))
                .collect();
            if marks.iter().all(Vec::is_empty) {
                break;
            }
            if marks.iter().flatten().any(|m| m.0 == Tier::Lights) {
                marks.iter_mut().for_each(|m| m.retain(|m| m.0 == Tier::Lights));
            }
            split_worst(&mut meshes, marks, total - used);
        }
        let instances = meshes
            .into_iter()
            .zip(before)
            .map(|(mesh, n)| {
                let refined = (mesh.vertices() != n).then(|| mesh.finish()).transpose();
                refined
                    .map(|m| (n, m))
                    .map_err(|why| crate::Error::Invalid(format!("{}: refining a receiver: {why}", scene.source)))
            })
            .collect::<crate::Result<_>>()?;
        Ok(Self { instances })
    }

    /// True when this refinement is of `scene`'s instances as they stand: as many, with their
    /// vertex counts (a kept refinement read back is checked so before it is applied).
    pub fn fits(&self, scene: &Scene) -> bool {
        let flat = flatten(scene);
        let counts = flat.instances.iter().map(|i| flat.meshes[i.mesh as usize].positions.len());
        self.instances.len() == flat.instances.len() && self.instances.iter().map(|r| r.0).eq(counts)
    }

    /// Puts each instance's refined mesh in place of its source mesh and says what changed.
    /// `scene` must be the one refined (with its source meshes).
    pub fn apply(self, scene: &mut Scene) -> Report {
        let flat = flatten(scene);
        let mut report = Vec::new();
        for (inst, (before, mesh)) in flat.instances.iter().zip(self.instances) {
            let Some(Refined { mesh, flat }) = mesh else {
                report.push((before, before));
                continue;
            };
            report.push((before, mesh.positions.len()));
            let entity = scene
                .world
                .query::<(hecs::Entity, &PrimitiveId)>()
                .iter()
                .find(|(_, id)| **id == inst.id)
                .map(|(e, _)| e);
            scene.set_refined_mesh(entity.expect("the snapshot's instances are the world's"), mesh, flat);
        }
        report
    }

    /// The refinement as bytes (little-endian), ending in a blake3 hash of the rest.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        let word = |out: &mut Vec<u8>, n: usize| out.extend((n as u32).to_le_bytes());
        word(&mut out, self.instances.len());
        for (before, refined) in &self.instances {
            word(&mut out, *before);
            let Some(Refined { mesh: m, flat }) = refined else {
                word(&mut out, 0);
                continue;
            };
            // 1: refined, lifted off its source; 2: refined flat.
            word(&mut out, 1 + *flat as usize);
            for n in [m.positions.len(), m.uvs.len(), m.uvs1.len(), m.colors.len(), m.triangles.len()] {
                word(&mut out, n);
            }
            out.extend_from_slice(bytemuck::cast_slice(&m.positions));
            out.extend_from_slice(bytemuck::cast_slice(&m.normals));
            out.extend_from_slice(bytemuck::cast_slice(&m.uvs));
            out.extend_from_slice(bytemuck::cast_slice(&m.uvs1));
            out.extend_from_slice(bytemuck::cast_slice(&m.colors));
            out.extend_from_slice(bytemuck::cast_slice(&m.triangles));
        }
        let hash = *blake3::hash(&out).as_bytes();
        out.extend(hash);
        out
    }

    /// The refinement in `bytes` when its hash holds and its meshes are sound; `None` otherwise
    /// (a damaged entry is refined again).
    pub fn from_bytes(bytes: &[u8]) -> Option<Self> {
        let (body, hash) = bytes.split_at_checked(bytes.len().checked_sub(32)?)?;
        if blake3::hash(body).as_bytes() != hash {
            return None;
        }
        let mut r = Reader { body, at: 0 };
        let count = r.word()?;
        let mut instances = Vec::new();
        for _ in 0..count {
            let (before, refined) = (r.word()?, r.word()?);
            if refined == 0 {
                instances.push((before, None));
                continue;
            }
            if refined > 2 {
                return None;
            }
            let [p, uv, uv1, c, t] = [r.word()?, r.word()?, r.word()?, r.word()?, r.word()?];
            let mut mesh = crate::scene::Mesh {
                positions: r.pods(p)?,
                normals: r.pods(p)?,
                uvs: r.pods(uv)?,
                uvs1: r.pods(uv1)?,
                colors: r.pods(c)?,
                triangles: r.pods(t)?,
                hash: crate::scene::MeshHash([0; 32]),
            };
            if mesh.triangles.iter().flatten().any(|&i| i as usize >= p) {
                return None;
            }
            mesh.hash = mesh.compute_hash();
            instances.push((before, Some(Refined { mesh, flat: refined == 2 })));
        }
        (r.at == body.len()).then_some(Self { instances })
    }
}

/// Reads [`Refinement::to_bytes`]'s fields in order; `None` past the end.
struct Reader<'a> {
    body: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn bytes(&mut self, n: usize) -> Option<&[u8]> {
        let s = self.body.get(self.at..self.at.checked_add(n)?)?;
        self.at += n;
        Some(s)
    }

    fn word(&mut self) -> Option<usize> {
        self.bytes(4).map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]) as usize)
    }

    /// `n` values of `T`, copied (the bytes need not be aligned).
    fn pods<T: bytemuck::Pod>(&mut self, n: usize) -> Option<Vec<T>> {
        self.bytes(n.checked_mul(std::mem::size_of::<T>())?).map(bytemuck::pod_collect_to_vec)
    }
}

/// The meshes seeded: every edge longer than the seed length split, so that no shadow fits
/// inside a triangle unseen by the midpoint test. Bisection halves a triangle's area per
/// level, so the vertices a seed length costs jump by about 2× between levels: the length
/// starts where seeding costs about `share` vertices and grows by √2 until it costs at most
/// that (or no edge is split), so the rounds keep the rest of the budget.
fn seeded(source: &[Adaptive], instances: &[crate::scene::Instance], share: usize) -> Vec<Adaptive> {
    let area: f32 = source.iter().zip(instances).map(|(m, inst)| world_area(m, &inst.world)).sum();
    // Bisection leaves right triangles whose legs are ~1/√2 of the longest edge allowed.
    let mut seed = (2.0 * area / share.max(1) as f32).sqrt();
    let before: usize = source.iter().map(Adaptive::vertices).sum();
    loop {
        let mut meshes = source.to_vec();
        for (mesh, inst) in meshes.iter_mut().zip(instances) {
            loop {
                let long: Vec<[u32; 2]> =
                    mesh.edges().into_iter().filter(|e| world_length(mesh, &inst.world, e) > seed).collect();
                if long.is_empty() || mesh.split(&long, usize::MAX) == 0 {
                    break;
                }
            }
        }
        if meshes.iter().map(Adaptive::vertices).sum::<usize>() - before <= share {
            return meshes;
        }
        seed *= std::f32::consts::SQRT_2;
    }
}

/// Splits the marked edges of every instance, the largest errors first, within `budget` new
/// vertices (a split adds one vertex per side of a seam; counted as one, so the budget may be
/// exceeded by the seams' extra vertices).
///
/// Errors are compared in steps of 2^¼ (19 %), and marks in one step go by instance, then by
/// place ([`Adaptive::place`]). When the budget cuts a step, an edit that adds or drops marks
/// in one place (a moved box's shadow) moves the cut along one stretch of places, rather than
/// among near-equal marks all over the receiver, so the vertices, and the bakes, away from the
/// edit mostly stay as they were (`docs/receivers.md#edits`).
fn split_worst(meshes: &mut [Adaptive], marks: Vec<Vec<Mark>>, budget: usize) {
    let step = |e: f32| (4.0 * e.log2()).floor() as i32;
    let mut all: Vec<(i32, usize, u64, [u32; 2])> = marks
        .into_iter()
        .enumerate()
        .flat_map(|(i, m)| m.into_iter().map(move |(_, e, edge)| (e, i, edge)))
        .map(|(e, i, edge)| (step(e), i, meshes[i].place(edge), edge))
        .collect();
    all.sort_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)).then(a.3.cmp(&b.3)));
    all.truncate(budget);
    let mut per: Vec<Vec<[u32; 2]>> = vec![Vec::new(); meshes.len()];
    for (_, i, _, e) in all {
        per[i].extend(meshes[i].longest_around(e));
    }
    for (mesh, edges) in meshes.iter_mut().zip(per) {
        mesh.split(&edges, usize::MAX);
    }
}

/// What earlier rounds probed on one mesh: per vertex its lights' visibility, per edge its
/// interpolation error.
#[derive(Default)]
struct Memo {
    vertex: Vec<Vec<f32>>,
    /// The largest error over the lights' views, and over the environment's.
    edge: HashMap<[u32; 2], [f32; 2]>,
}

/// The edges of `mesh` (instance `index`, placed by `world`) whose visibility interpolates
/// badly, with their error × world length; probes only the vertices and edges `memo` lacks,
/// and keeps them there.
fn marked(
    mesh: &Adaptive,
    (index, world): (usize, &glam::Affine3A),
    probe: &Probe,
    tolerance: f32,
    memo: &mut Memo,
) -> Vec<Mark> {
    let (p, n) = (mesh.positions(), mesh.normals());
    let at = |a: Vec3, na: Vec3| {
        probe.visibility(world.transform_point3(a), world.transform_vector3(na).normalize_or_zero(), index)
    };
    let new: Vec<Vec<f32>> = (memo.vertex.len()..p.len()).into_par_iter().map(|i| at(p[i], n[i])).collect();
    memo.vertex.extend(new);
    let vertex = &memo.vertex;
    let edges = mesh.edges();
    let fresh: Vec<([u32; 2], [f32; 2])> = edges
        .par_iter()
        .filter(|e| !memo.edge.contains_key(*e))
        .map(|&e| {
            // Across a hard crease the named ends carry one side's normal each (a box's corner
            // would see the light on one face and not on the next): each side is judged on its
            // own vertices.
            let sides = mesh.sides(e).into_iter().map(|side| side_error(side, p, n, vertex, &at, probe.lights));
            (e, sides.fold([0.0f32; 2], |most, s| [most[0].max(s[0]), most[1].max(s[1])]))
        })
        .collect();
    memo.edge.extend(fresh);
    let length = |a: u32, b: u32| world.transform_point3(p[a as usize]).distance(world.transform_point3(p[b as usize]));
    edges
        .into_iter()
        .filter_map(|[a, b]| {
            let [lights, environment] = memo.edge[&[a, b]];
            let (tier, error) =
                if lights > tolerance { (Tier::Lights, lights) } else { (Tier::Environment, environment) };
            (error > tolerance).then(|| (tier, error * length(a, b), [a, b]))
        })
        .collect()
}

/// One side of an edge (`[a, b]`, the vertices one triangle uses): how far what the pixels
/// between its ends are shaded with misses the truth at its midpoint, over the lights' views
/// (the first `lights`) and over the environment's. A light's visible fraction is interpolated
/// as pixels interpolate it ([`crate::bspvt::pixel`]: the shadowed over the unshadowed share),
/// and its error weighed by the unshadowed share there and by how dark the truth is (a few
/// percent of the light show against an umbra, not in full light); a linear ramp across a
/// penumbra, or the light sinking below a curved receiver's horizon (which LTC takes per
/// pixel), is no error.
/// The environment's share is interpolated linearly, so its ends' difference counts too.
fn side_error(
    [a, b]: [u32; 2],
    p: &[Vec3],
    n: &[Vec3],
    vertex: &[Vec<f32>],
    at: &impl Fn(Vec3, Vec3) -> Vec<f32>,
    lights: usize,
) -> [f32; 2] {
    let (a, b) = (a as usize, b as usize);
    // An end inside geometry takes no part in its pixels' lights: they take the other end's.
    let ends: Vec<&Vec<f32>> = [&vertex[a], &vertex[b]].into_iter().filter(|v| !v.is_empty()).collect();
    if ends.is_empty() {
        return [0.0; 2];
    }
    let mid = at(0.5 * (p[a] + p[b]), (n[a] + n[b]).normalize_or_zero());
    let Some(m) = (!mid.is_empty()).then_some(&mid) else { return [0.0; 2] };
    let light = |l: usize| {
        let (s, o) = ends.iter().fold((0.0, 0.0), |(s, o), v| (s + v[2 * l], o + v[2 * l + 1]));
        let (sm, om) = (m[2 * l], m[2 * l + 1]);
        if om <= 0.0 {
            return 0.0;
        }
        // Where no end sees the light above its horizon, pixels take it as unshadowed.
        let shaded = if o > 0.0 { s / o } else { 1.0 };
        let f = sm / om;
        om * (shaded - f).abs() / (f + DARK)
    };
    // The environment's shading still interpolates an inside end's darkness
    // (`docs/receivers.md`): it is judged between two outside ends only.
    let environment = |k: usize| match ends[..] {
        [va, vb] => (va[k] - vb[k]).abs().max((m[k] - 0.5 * (va[k] + vb[k])).abs()),
        _ => 0.0,
    };
    let most = |e: &mut dyn Iterator<Item = f32>| e.fold(0.0, f32::max);
    [most(&mut (0..lights).map(light)), most(&mut (2 * lights..m.len()).map(environment))]
}

/// Points a light is probed at, where it is.
const LIGHT_POINTS: u32 = 49;

/// How much more a light's error counts where the truth is dark: it is divided by f + `DARK`,
/// f the visible fraction at the midpoint — ×4 in an umbra, ×0.8 in full light. Chosen on the
/// floor scene's ball, whose umbra otherwise showed long triangles' gradients of a few percent
/// of the light as light wedges (`docs/receivers.md`).
const DARK: f32 = 0.25;

/// Which views marked an edge. The environment's marks are split only once no light marks
/// any edge: measured, they lower the environment term's error by 1–2 % of itself, where the
/// lights' marks take shadows from 34 % to 3.5 % (`docs/receivers.md`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Tier {
    Lights,
    Environment,
}

/// An edge to split: its tier, its error × world length, and its ends.
type Mark = (Tier, f32, [u32; 2]);

/// What the probe measures the visibility of.
enum View {
    /// Points on a light, or in one cell of a light's reach box. A point counts only from in
    /// front of `facing` (a light that may move and turn within its box has none).
    Points { points: Vec<Vec3>, facing: Option<Vec3> },
    /// Directions towards the environment, each with its weight (the radiance's luminance),
    /// against the receiver's own group only (see [`Probe::groups`]).
    Directions(Vec<(Vec3, f32)>),
}

/// Most cells a light's reach box is split into, per axis.
const MAX_CELLS_PER_AXIS: f32 = 3.0;

/// Directions the environment is probed in (a Hammersley set on the sphere).
const ENVIRONMENT_DIRECTIONS: u32 = 64;

/// Shadow rays from receiver points to what lights them: fixed points on every light where it
/// is, or in every cell of its reach box, and fixed directions of the environment.
struct Probe {
    /// What casts the polygonal lights' shadows (as BSPVT bakes them), and what a point may be
    /// inside: every instance, no light.
    bvh: SceneBvh,
    /// Per group, its instances' triangles: per vertex, PRT bakes only the shadows a group casts
    /// on itself (other groups' shadows and the sun are shaded per pixel, `docs/baked.md`).
    groups: Vec<SceneBvh>,
    /// Per instance, its group's index in `groups`.
    group_of: Vec<usize>,
    /// The lights' views, then the environment's (if any).
    views: Vec<View>,
    /// How many of `views` are the lights'.
    lights: usize,
}

impl Probe {
    fn new(flat: &FlatScene) -> Self {
        let mut entities: Vec<hecs::Entity> = flat.instances.iter().map(|i| i.group).collect();
        entities.sort();
        entities.dedup();
        let group_of: Vec<usize> =
            flat.instances.iter().map(|i| entities.binary_search(&i.group).expect("listed")).collect();
        let mut views: Vec<View> = flat.lights.iter().flat_map(light_views).collect();
        let lights = views.len();
        views.extend(flat.environment.as_ref().map(environment_view));
        // The groups' BVHs only where the environment is probed.
        let cut = |keep: &dyn Fn(&crate::scene::TriangleRef) -> bool| {
            let (triangles, holes) = flat.select(|r| r.light == NO_LIGHT && keep(r));
            SceneBvh::new(&triangles).cut(&holes)
        };
        let bvh = cut(&|_| true);
        let groups = if views.len() > lights {
            (0..entities.len()).map(|g| cut(&|r| group_of[r.owner as usize] == g)).collect()
        } else {
            Vec::new()
        };
        Self { bvh, groups, group_of, views, lights }
    }

    /// What `p` (normal `n`) on instance `instance` sees: per light view, the share of its
    /// points seen and the share above the horizon (both in front of the light); then per
    /// environment view, the share seen. Empty for a point inside geometry
    /// ([`SceneBvh::inside`]), whose shading takes no part in what is seen (`bspvt::pixel`).
    fn visibility(&self, p: Vec3, n: Vec3, instance: usize) -> Vec<f32> {
        if self.bvh.inside(p, n) {
            return Vec::new();
        }
        let origin = p + n * 1e-4 * (1.0 + p.abs().max_element());
        // As BSPVT's rays, every ray here passes what touches the point (a box resting on the
        // floor): `occluded_past_touching`.
        let own = self.groups.get(self.group_of[instance]);
        let mut out = Vec::with_capacity(self.views.len() + self.lights);
        for view in &self.views {
            match view {
                View::Points { points, facing } => {
                    let (mut seen, mut above) = (0, 0);
                    for &s in points {
                        let d = s - origin;
                        let dist = d.length();
                        let dir = d / dist;
                        if dir.dot(n) > 0.0 && facing.is_none_or(|f| dir.dot(f) < 0.0) {
                            above += 1;
                            let blocked = self.bvh.occluded_past_touching(origin, dir, dist * (1.0 - 1e-4));
                            seen += usize::from(!blocked);
                        }
                    }
                    out.extend([seen as f32 / points.len() as f32, above as f32 / points.len() as f32]);
                }
                View::Directions(dirs) => {
                    let (mut lit, mut all) = (0.0, 0.0);
                    for &(dir, w) in dirs.iter().filter(|(d, _)| d.dot(n) > 0.0) {
                        let w = w * dir.dot(n);
                        all += w;
                        lit +=
                            if own.is_some_and(|g| g.occluded_past_touching(origin, dir, f32::MAX)) { 0.0 } else { w };
                    }
                    out.push(if all > 0.0 { lit / all } else { 1.0 });
                }
            }
        }
        out
    }
}

/// A light's views: where it is (49 points, seen from its front), or, with a declared reach,
/// each cell of its box (the box split into cells about the light's size, at most 3 per axis;
/// 9 points each, from any side). The cells depend on the box alone, so moving the light
/// inside it changes no refined mesh and no bake key.
fn light_views(light: &FlatLight) -> Vec<View> {
    let Some([lo, hi]) = light.reach else {
        return vec![View::Points { points: spread_points(&light.points, LIGHT_POINTS), facing: Some(light.normal) }];
    };
    // The box grown to hold the light where it is, as the bake's reach is (`bspvt::reach`).
    let (lo, hi) = light.points.iter().fold((lo, hi), |(a, b), p| (a.min(*p), b.max(*p)));
    let cells = ((hi - lo) / light.area.sqrt()).round().clamp(Vec3::ONE, Vec3::splat(MAX_CELLS_PER_AXIS));
    let (nx, ny, nz) = (cells.x as usize, cells.y as usize, cells.z as usize);
    let half = (hi - lo) / (2.0 * cells);
    let mut views = Vec::new();
    for (i, j, k) in (0..nx).flat_map(|i| (0..ny).flat_map(move |j| (0..nz).map(move |k| (i, j, k)))) {
        let centre = lo + half * (2.0 * Vec3::new(i as f32, j as f32, k as f32) + 1.0);
        let corners = (0..8).map(|c| {
            let sign = Vec3::new([-1.0, 1.0][c & 1], [-1.0, 1.0][(c >> 1) & 1], [-1.0, 1.0][c >> 2]);
            centre + 0.9 * half * sign
        });
        views.push(View::Points { points: std::iter::once(centre).chain(corners).collect(), facing: None });
    }
    views
}

/// The environment's view: fixed directions spread evenly over the sphere, weighted by the
/// radiance's luminance. A small bright source (a sun) is rarely among them: the look shades
/// it per pixel, not per vertex.
fn environment_view(env: &EnvironmentLight) -> View {
    let dirs = (0..ENVIRONMENT_DIRECTIONS)
        .map(|i| uniform_sphere(hammersley(i, ENVIRONMENT_DIRECTIONS)))
        .map(|d| (d, luminance(env.radiance(d))))
        .filter(|(_, w)| w.is_finite() && *w > 0.0)
        .collect();
    View::Directions(dirs)
}

/// Points spread evenly over a light polygon (area-uniform over its fan of triangles, from a
/// Hammersley set): no two share a row, so an occluder's straight edge sweeping over the light
/// hides them one at a time, and `V` steps by 1/`n` (rings through the corners and edge
/// midpoints lined up in rows of up to 13: their steps were edges refinement split without end).
fn spread_points(polygon: &[Vec3], n: u32) -> Vec<Vec3> {
    let fan: Vec<[Vec3; 3]> = (1..polygon.len() - 1).map(|k| [polygon[0], polygon[k], polygon[k + 1]]).collect();
    let areas: Vec<f32> = fan.iter().map(|[a, b, c]| 0.5 * (b - a).cross(c - a).length()).collect();
    let total: f32 = areas.iter().sum();
    (0..n)
        .map(|i| {
            let mut u = hammersley(i, n);
            // The first coordinate picks a triangle by area and is stretched over it.
            let mut k = 0;
            while k + 1 < fan.len() && u.x * total > areas[k] {
                u.x -= areas[k] / total;
                k += 1;
            }
            u.x = (u.x * total / areas[k].max(f32::MIN_POSITIVE)).min(1.0);
            let [a, b, c] = fan[k];
            let w = uniform_triangle(u);
            a + w.x * (b - a) + w.y * (c - a)
        })
        .collect()
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A light's probe points lie on it, and no straight edge parallel to one of its sides hides
    /// two of them at once: along each side's direction, the points' projections all differ.
    #[test]
    fn a_lights_points_are_spread_and_lie_on_it() {
        let quad = [
            Vec3::new(-0.5, 3.0, -0.5),
            Vec3::new(0.5, 3.0, -0.5),
            Vec3::new(0.5, 3.0, 0.5),
            Vec3::new(-0.5, 3.0, 0.5),
        ];
        let points = spread_points(&quad, LIGHT_POINTS);
        assert_eq!(points.len(), LIGHT_POINTS as usize);
        assert!(points.iter().all(|p| p.y == 3.0 && p.x.abs() <= 0.5 && p.z.abs() <= 0.5), "{points:?}");
        for axis in [Vec3::X, Vec3::Z] {
            let mut along: Vec<f32> = points.iter().map(|p| p.dot(axis)).collect();
            along.sort_by(f32::total_cmp);
            let gap = along.windows(2).map(|w| w[1] - w[0]).fold(f32::MAX, f32::min);
            assert!(gap > 1e-4, "two points in a row along {axis}: gap {gap}");
        }
        let triangle = [Vec3::ZERO, Vec3::X, Vec3::Z];
        let inside = spread_points(&triangle, 16);
        assert!(inside.iter().all(|p| p.x >= 0.0 && p.z >= 0.0 && p.x + p.z <= 1.0 + 1e-6), "{inside:?}");
    }

    /// An edge from a vertex inside geometry (no visibility) to one outside is held to the
    /// outside end's share, which its pixels show: a shadow between them is an error. With
    /// both ends, or the midpoint, inside there is nothing to judge.
    #[test]
    fn an_edge_with_one_end_inside_is_held_to_the_other_end() {
        let (p, n) = ([Vec3::ZERO, Vec3::X], [Vec3::Y, Vec3::Y]);
        let lit = vec![1.0, 1.0];
        let shadowed = |_: Vec3, _: Vec3| vec![0.2, 1.0];
        let error =
            |vertex: &[Vec<f32>], at: &dyn Fn(Vec3, Vec3) -> Vec<f32>| side_error([0, 1], &p, &n, vertex, &at, 1)[0];
        let expected = (1.0 - 0.2) / (0.2 + DARK);
        assert!((error(&[Vec::new(), lit.clone()], &shadowed) - expected).abs() < 1e-6);
        assert_eq!(error(&[Vec::new(), Vec::new()], &shadowed), 0.0);
        assert_eq!(error(&[Vec::new(), lit], &|_, _| Vec::new()), 0.0);
    }
}
