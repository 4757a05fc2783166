//! BSPVT: shadows from polygonal lights with BSP visibility trees (Okuno & Iwasaki, seed
//! `000_…txt`; summary in DESIGN.md).
//!
//! - [`visibility`]: per-vertex visibility cube maps (faces aligned to world axes), cast only
//!   above the horizon;
//! - [`tree`]: per face, a fixed grid of tiles and inside each the BSP tree of Algorithm 1 with
//!   the seed's two corrections (tiles make re-bakes local: [`rebake_vertex`]);
//! - [`cache`]: tile subtrees already built, shared by a bake's workers and kept between bakes;
//! - [`dirty`]: which tiles and texels an edit inside a box can change (warm re-bakes);
//! - [`reach`]: which tiles the lights can be seen through (the rest bake as occluded, uncast);
//! - [`layout`]: the compact versioned byte layout (≈2 bytes per node);
//! - [`shade`]: per vertex and light, the light polygon clipped by face frusta and tree planes
//!   (planes through the vertex) and integrated with LTC, weighted by the leaves' visibility;
//!   the same code runs `ltc-exact-vis` (per visible texel) and `ltc-unshadowed`.
//!
//! Baking depends only on the occluders' geometry (lights are not occluders: they move freely
//! at run time, within their declared [`reach::Reach`]), the face resolution and ε; it is
//! parallel over vertices and deterministic.

pub mod cache;
pub mod dirty;
pub mod grid;
pub mod layout;
pub mod plan;
pub mod reach;
pub mod shade;
pub mod split;
pub mod tree;
pub mod visibility;

use crate::accel::{self, Occluders};
use crate::scene::{FlatScene, NO_LIGHT, Scene};
use cache::TileCache;
use rayon::prelude::*;
use reach::Reach;
use std::ops::Range;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;
use visibility::Look;

/// Version of the bake algorithm, part of every bake key: bumped whenever the same inputs
/// would give different trees (2: trees start with the tile grid of [`tree::TILE`]; 3: the
/// split search's looser Nelder–Mead tolerance and fused sums, see [`split`]).
pub const ALGORITHM_VERSION: u32 = 3;

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

    /// Vertices held.
    pub fn vertices(&self) -> usize {
        self.offsets.len() - 1
    }

    /// An instance of `vertices` records that all see their whole hemisphere: what unshadowed
    /// LTC computes, the placeholder while the trees bake.
    pub fn unshadowed(vertices: usize) -> Self {
        let open = layout::encode_vertex(&std::array::from_fn(|_| Some(vec![tree::Node::Leaf(1.0)])));
        Self { offsets: (0..=vertices).map(|v| (v * open.len()) as u32).collect(), data: open.repeat(vertices) }
    }

    /// Replaces the records of vertices `first..first + records.len()` (which must exist).
    pub fn splice(&mut self, first: usize, records: &[Vec<u8>]) {
        let end = first + records.len();
        let (a, b) = (self.offsets[first] as usize, self.offsets[end] as usize);
        let fresh: Vec<u8> = records.concat();
        let shift = fresh.len() as i64 - (b - a) as i64;
        self.data.splice(a..b, fresh);
        let mut at = a as u32;
        for (k, r) in records.iter().enumerate() {
            self.offsets[first + k] = at;
            at += r.len() as u32;
        }
        self.offsets[end..].iter_mut().for_each(|o| *o = (*o as i64 + shift) as u32);
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

/// Everything that casts shadows on polygonal-light receivers (not the lights), one BVH per
/// instance (see [`Occluders`]: an edit cannot change rays against the other instances).
pub fn occluder_bvh(flat: &FlatScene) -> Occluders {
    let mut parts: Vec<Vec<[glam::Vec3; 3]>> = vec![Vec::new(); flat.instances.len()];
    for (t, r) in flat.triangles.iter().zip(&flat.refs) {
        if r.light == NO_LIGHT {
            parts[r.owner as usize].push(*t);
        }
    }
    Occluders::new(&parts)
}

/// One vertex's bake: its record and what a warm re-bake of it needs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VertexBake {
    /// The record (see [`layout`]).
    pub record: Vec<u8>,
    /// The visible-texel masks of its mixed tiles, by tile index `f · tiles_per_side² + tile`
    /// (see [`tree::FaceTree::masks`]).
    pub masks: tree::Masks,
    /// Rays cast.
    pub rays: usize,
    /// Mixed tiles whose subtrees were made anew (by Algorithm 1, or from the tile cache).
    pub built: usize,
}

/// Bakes one vertex with `tiles`' settings, its subtrees from (and added to) `tiles`, for
/// lights within `reach`. Faces entirely below the horizon, entirely occluded or out of reach
/// store no tree: they contribute nothing.
pub fn bake_vertex(
    occluders: &Occluders,
    p: glam::Vec3,
    n: glam::Vec3,
    tiles: &TileCache,
    reach: &Reach,
) -> VertexBake {
    rebake_vertex(occluders, p, n, (tiles, reach), &VertexBake::default(), &[])
}

/// Tiles per face side at face resolution `res` (see [`tree::TILE`]).
pub fn tiles_per_side(res: usize) -> usize {
    res.div_ceil(tree::TILE)
}

/// An occluder that changed since a vertex's previous bake (moved, added, removed or given
/// another mesh), as a warm re-bake needs it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Change {
    /// Its bounds before (padded for rays that graze them), when it existed.
    pub before: Option<(glam::Vec3, glam::Vec3)>,
    /// Its bounds now (padded) and its instance index in the occluders, when it exists.
    pub after: Option<((glam::Vec3, glam::Vec3), usize)>,
}

/// Re-bakes a vertex whose previous bake is `old` after the occluders in `changes` changed:
/// only texels whose rays can meet a changed occluder's old or new bounds are looked at, and
/// of those only the ones whose state can have changed are cast — a ray that was visible can
/// only be blocked now by a changed occluder (cast against those alone), a blocked one that
/// meets no old bounds stays blocked; only tiles whose visibility changed are built again.
/// A changed occluder with few triangles is tested without its BVH ([`accel::beam`]) where
/// the answer is certain, and neither tiles whose every ray certainly meets it nor the runs of
/// a row's texels that certainly do are visited texel by texel.
/// Identical to [`bake_vertex`] of the edited scene: a ray's result against an occluder
/// depends on that occluder alone (see [`Occluders`]). An empty `old` record bakes from
/// scratch. Settings, subtrees and reach as in [`bake_vertex`]; `old` must have been baked
/// for the same reach (tiles out of reach are never looked at again).
pub fn rebake_vertex(
    occluders: &Occluders,
    p: glam::Vec3,
    n: glam::Vec3,
    (tiles, reach): (&TileCache, &Reach),
    old: &VertexBake,
    changes: &[Change],
) -> VertexBake {
    let s = tiles.settings();
    let per_face = tiles_per_side(s.res).pow(2);
    let cold = old.record.is_empty();
    let edit = Edit::new(occluders, (p, n), changes, reach, s.res);
    let mut dirty = vec![cold; 6 * per_face];
    for cover in edit.before.iter().chain(&edit.after).map(|b| &b.cover) {
        dirty.iter_mut().zip(cover).for_each(|(a, c)| *a |= *c != dirty::Cover::None);
    }
    if let Some(reached) = &edit.reached {
        dirty.iter_mut().zip(reached).for_each(|(d, r)| *d &= r);
    }
    let kept = if cold { [&[][..]; 6] } else { layout::vertex_faces(&old.record) };
    let mut out = VertexBake::default();
    let faces: [Vec<u8>; 6] = std::array::from_fn(|f| {
        let range = (f * per_face) as u32..((f + 1) * per_face) as u32;
        let old_masks: tree::Masks =
            old.masks.iter().filter(|m| range.contains(&m.0)).map(|&(t, m)| (t - range.start, m)).collect();
        let dirty = &dirty[f * per_face..(f + 1) * per_face];
        if !dirty.contains(&true) {
            out.masks.extend(old_masks.iter().map(|&(t, m)| (t + range.start, m)));
            return kept[f].to_vec();
        }
        // A face that stored no tree was entirely occluded (or below the horizon: never read).
        let old_tree = match (cold, kept[f].is_empty()) {
            (true, _) => Vec::new(),
            (false, true) => vec![tree::Node::Leaf(0.0)],
            (false, false) => layout::decode_tree(kept[f]),
        };
        let bits = if cold {
            let reached = edit.reached.as_deref().map(|r| &r[f * per_face..(f + 1) * per_face]);
            let bits = visibility::cast_face_tiles(occluders, p, n, f, s.res, reached);
            out.rays += bits.iter().map(|b| b.live.count_ones() as usize).sum::<usize>();
            bits
        } else {
            edit.cast_face(f, s.res, dirty, (&old_tree, &old_masks), &mut out.rays)
        };
        let face = tree::rebuild(&bits, tiles, &old_tree, &old_masks);
        out.built += face.built;
        out.masks.extend(face.masks.iter().map(|&(t, m)| (t + range.start, m)));
        layout::encode_face(face.nodes.as_deref().filter(|t| *t != [tree::Node::Leaf(0.0)]))
    });
    out.record = layout::join_faces(faces.each_ref().map(Vec::as_slice));
    out
}

/// A warm re-bake's view of the changes from one vertex.
struct Edit<'a> {
    occluders: &'a Occluders,
    p: glam::Vec3,
    n: glam::Vec3,
    /// See [`visibility::horizon_origin`].
    origin: glam::Vec3,
    /// Old bounds.
    before: Vec<Seen>,
    /// New bounds.
    after: Vec<Seen>,
    /// Per tile (`6 · tiles_per_side²`): every ray through it certainly meets a changed
    /// occluder's triangles (see [`dirty::blocked_tiles`]).
    blocked: Vec<bool>,
    /// Per tile, whether a light can be seen through it (`None`: all can; see [`Reach::tiles`]).
    reached: Option<Vec<bool>>,
}

/// A changed occluder's old or new bounds from the vertex, and how each tile sees them.
struct Seen {
    bounds: dirty::SeenBox,
    /// Per tile (`6 · tiles_per_side²`).
    cover: Vec<dirty::Cover>,
    /// The occluder's instance index, for its new bounds.
    instance: Option<usize>,
    /// The occluder's triangles from the rays' origin, when it has few (for its new bounds).
    beam: Option<accel::beam::Beam>,
}

impl Seen {
    /// Whether the ray through tile `t` in direction `d` can meet the bounds.
    fn meets(&self, t: usize, d: glam::Vec3) -> bool {
        match self.cover[t] {
            dirty::Cover::None => false,
            dirty::Cover::Some => self.bounds.meets(d),
            dirty::Cover::All => true,
        }
    }
}

impl<'a> Edit<'a> {
    fn new(
        occluders: &'a Occluders,
        (p, n): (glam::Vec3, glam::Vec3),
        changes: &[Change],
        reach: &Reach,
        res: usize,
    ) -> Self {
        let origin = visibility::horizon_origin(p, n);
        let seen = |(lo, hi), instance: Option<usize>| {
            let bounds = dirty::SeenBox::new(p, n, lo, hi);
            let beam = instance.and_then(|i| occluders.beam(i, origin));
            Seen { cover: bounds.tiles(res), bounds, instance, beam }
        };
        let before = changes.iter().filter_map(|c| c.before).map(|b| seen(b, None)).collect();
        let after: Vec<Seen> = changes.iter().filter_map(|c| c.after).map(|(b, i)| seen(b, Some(i))).collect();
        let mut blocked = vec![false; 6 * tiles_per_side(res).pow(2)];
        for b in &after {
            let Some(beam) = &b.beam else { continue };
            let more = dirty::blocked_tiles(beam, &b.cover, n, res);
            blocked.iter_mut().zip(more).for_each(|(a, b)| *a |= b);
        }
        Self { occluders, p, n, origin, before, after, blocked, reached: reach.tiles(p, n, res) }
    }

    /// Face `f`'s tiles after the edit (see [`visibility::cast_tiles`]; `dirty` flags its tiles
    /// that can see a changed box, cast unless known blocked) from its previous tree and masks
    /// `old`; `rays` counts the rays cast.
    fn cast_face(
        &self,
        f: usize,
        res: usize,
        dirty: &[bool],
        old: (&[tree::Node], &[(u32, u64)]),
        rays: &mut usize,
    ) -> Vec<visibility::TileBits> {
        let first = f * dirty.len();
        let reached = |t: usize| self.reached.as_ref().is_none_or(|r| r[first + t]);
        // The tiles that shaped the old tree: above the horizon and in reach.
        let face = visibility::Horizon::new(self.n, f, res);
        let live: Vec<bool> = face.live().into_iter().enumerate().map(|(t, l)| l && reached(t)).collect();
        let was = tree::old_visibility(old.0, old.1, res, &live);
        let looks: Vec<Look> = (0..dirty.len())
            .map(|t| match (reached(t), dirty[t], self.blocked[first + t]) {
                (false, ..) => Look::Unreached,
                (true, false, _) => Look::Keep,
                (true, true, false) => Look::Cast,
                (true, true, true) => Look::Blocked,
            })
            .collect();
        let cast = |t: usize| matches!(looks[t], Look::Cast | Look::Blocked);
        // The rows of the tiles that may be cast: the only ones asked about.
        let span = tile_rows(res, cast);
        let tiles = first..first + dirty.len();
        let rows: Vec<Vec<Range<usize>>> = self
            .boxes()
            .map(|b| {
                let seen = b.cover[tiles.clone()].contains(&dirty::Cover::Some);
                if seen { b.bounds.columns(f, res, span.clone()) } else { Vec::new() }
            })
            .collect();
        let occluded = self.certain_runs(f, res, span.clone(), cast);
        let row = |t: usize, j: usize| visibility::Row {
            ask: self.columns(first + t, &rows, j - span.start),
            occluded: occluded[j - span.start].clone(),
        };
        let texel = |t: usize, bit, d| self.texel(first + t, d, was[t] & bit != 0, rays);
        visibility::cast_tiles(&face, &looks, row, texel)
    }

    /// Per texel row in `span` of face `f`, the longest run of columns whose rays certainly
    /// meet a changed occluder's triangles now (see [`dirty::certain_runs`]), looked for in the
    /// rows of the tiles `cast` picks that can see the occluder's bounds.
    fn certain_runs(
        &self,
        f: usize,
        res: usize,
        span: Range<usize>,
        cast: impl Fn(usize) -> bool,
    ) -> Vec<Range<usize>> {
        let first = f * tiles_per_side(res).pow(2);
        let mut out = vec![0..0; span.len()];
        for b in &self.after {
            let Some(beam) = &b.beam else { continue };
            let rows = tile_rows(res, |t| cast(t) && b.cover[first + t] != dirty::Cover::None);
            for (j, run) in rows.clone().zip(dirty::certain_runs(beam, self.n, f, res, rows)) {
                let longest = &mut out[j - span.start];
                if run.len() > longest.len() {
                    *longest = run;
                }
            }
        }
        out
    }

    /// Old bounds, then new.
    fn boxes(&self) -> impl Iterator<Item = &Seen> {
        self.before.iter().chain(&self.after)
    }

    /// The columns of a texel row through tile `t` (of all six faces) whose rays can meet a
    /// box: the hull over [`Self::boxes`] of their `rows[b][row]` ([`dirty::SeenBox::columns`]),
    /// all columns for a box covering the tile, none for one it cannot see.
    fn columns(&self, t: usize, rows: &[Vec<Range<usize>>], row: usize) -> Range<usize> {
        let all = 0..usize::MAX;
        let spans = self.boxes().zip(rows).filter_map(|(b, r)| match b.cover[t] {
            dirty::Cover::None => None,
            dirty::Cover::Some => Some(r[row].clone()),
            dirty::Cover::All => Some(all.clone()),
        });
        spans.filter(|r| !r.is_empty()).reduce(|a, b| a.start.min(b.start)..a.end.max(b.end)).unwrap_or(0..0)
    }

    /// The state of the texel cast through tile `t` (of all six faces) in direction `d` (unit,
    /// above the horizon), which was visible or not: [`visibility::SKIPPED`] when it cannot
    /// have changed; `rays` counts the rays cast.
    fn texel(&self, t: usize, d: glam::Vec3, was_visible: bool, rays: &mut usize) -> u8 {
        let mut after = self.after.iter().filter(|b| b.meets(t, d)).peekable();
        // Visible: only what is now inside a changed occluder's bounds could block it.
        // Blocked, by no changed occluder: what blocked it stayed put.
        let unchanged = if was_visible { after.peek().is_none() } else { !self.before.iter().any(|b| b.meets(t, d)) };
        if unchanged {
            return visibility::SKIPPED;
        }
        let o = visibility::ray_origin(self.origin, self.p, self.n, d);
        let mut cast = |i| {
            *rays += 1;
            self.occluders.occluded_by(i, o, d, f32::INFINITY)
        };
        // The beam's origin is `o` unless rounding put `d` below the horizon.
        let beam = |b: &Seen| b.beam.as_ref().filter(|_| o == self.origin).and_then(|beam| beam.hits(d));
        let blocks = |b: &Seen| b.instance.is_some_and(|i| beam(b).unwrap_or_else(|| cast(i)));
        match (after.any(blocks), was_visible) {
            (true, _) => visibility::OCCLUDED,
            (false, true) => visibility::VISIBLE,
            (false, false) => {
                *rays += 1;
                visibility::cast_ray(self.occluders, o, d)
            }
        }
    }
}

/// The texel rows of a face (resolution `res`) from the first to the last row of the tiles
/// `pick` picks.
fn tile_rows(res: usize, pick: impl Fn(usize) -> bool) -> Range<usize> {
    let k = tiles_per_side(res);
    let picked = || (0..k * k).filter(|&t| pick(t));
    match (picked().next(), picked().next_back()) {
        (Some(a), Some(b)) => a / k * tree::TILE..((b / k + 1) * tree::TILE).min(res),
        _ => 0..0,
    }
}

/// Bakes every receiver vertex, in parallel; `progress` gets the number of vertices done.
/// With no polygonal light in the scene nothing can be reached: every record is empty.
pub fn bake(scene: &Scene, flat: &FlatScene, s: &Settings, progress: &(dyn Fn(usize) + Sync)) -> Bake {
    let start = Instant::now();
    let occluders = occluder_bvh(flat);
    let tiles = TileCache::new(s);
    let reach = Reach::of(&flat.lights);
    let done = AtomicUsize::new(0);
    let mut stats = Stats::default();
    let instances = (0..flat.instances.len())
        .map(|i| {
            let n = scene.meshes[flat.instances[i].mesh as usize].positions.len();
            let records: Vec<Vec<u8>> = (0..n)
                .into_par_iter()
                .map(|v| {
                    let (p, normal) = flat.vertex(&scene.meshes, i, v);
                    let r = if flat.lights.is_empty() {
                        layout::encode_vertex(&Default::default())
                    } else {
                        bake_vertex(&occluders, p, normal, &tiles, &reach).record
                    };
                    progress(done.fetch_add(1, Ordering::Relaxed) + 1);
                    r
                })
                .collect();
            let mut offsets = vec![0u32];
            let mut data = Vec::new();
            for rec in records {
                data.extend_from_slice(&rec);
                offsets.push(data.len() as u32);
                let (leaves, nodes) = layout::tree_counts(&rec);
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
#[derive(Clone, Copy, Debug)]
pub enum Method<'a> {
    /// Baked BSP visibility trees.
    Bspvt(&'a Bake),
    /// The raw visibility cube map, cast at shading time (the tree's ground truth).
    ExactVis {
        /// Texels per cube-face side.
        res: usize,
    },
    /// No visibility.
    Unshadowed,
}

/// Outgoing radiance toward `eye` from the polygonal lights at every receiver vertex, per
/// instance in [`FlatScene::instances`] order.
pub fn shade_vertices(scene: &Scene, flat: &FlatScene, method: Method, eye: glam::Vec3) -> Vec<Vec<glam::Vec3>> {
    let exact = match method {
        Method::ExactVis { res } => Some((occluder_bvh(flat), res)),
        _ => None,
    };
    let trees = match method {
        Method::Bspvt(bake) => Some(bake),
        _ => None,
    };
    (0..flat.instances.len())
        .map(|i| {
            let n = scene.meshes[flat.instances[i].mesh as usize].positions.len();
            (0..n)
                .into_par_iter()
                .map(|v| match &exact {
                    Some((occluders, res)) => {
                        let (p, normal) = flat.vertex(&scene.meshes, i, v);
                        let cube = visibility::cast(occluders, p, normal, *res);
                        let table = crate::math::ltc::table();
                        shade::PointShader::new(&table, p, normal, eye, &flat.instances[i].material)
                            .shade(&flat.lights, shade::Visibility::Exact(&cube))
                    }
                    None => shade_vertex(scene, flat, trees, i, v, eye),
                })
                .collect()
        })
        .collect()
}

/// Outgoing radiance toward `eye` from the polygonal lights at the point of one of instance
/// `i`'s triangles (its `corners`) with barycentrics `bary`: LTC at that point and normal,
/// shadowed by the trees of the nearest corner (`None`: unshadowed). The indirect term lights
/// glossy hits so: the view-dependent lobe is evaluated where the ray hit; visibility, which
/// varies more slowly, is the nearest vertex's (as accurate as weighting all three corners' on
/// the test scene, in half the time).
pub fn shade_point(
    scene: &Scene,
    flat: &FlatScene,
    bake: Option<&Bake>,
    i: usize,
    corners: [usize; 3],
    bary: [f32; 3],
    eye: glam::Vec3,
) -> glam::Vec3 {
    let (mut p, mut n) = (glam::Vec3::ZERO, glam::Vec3::ZERO);
    for (&v, &b) in corners.iter().zip(&bary) {
        let (pv, nv) = flat.vertex(&scene.meshes, i, v);
        p += b * pv;
        n += b * nv;
    }
    let nearest = corners[(0..3).max_by(|&x, &y| bary[x].total_cmp(&bary[y])).unwrap_or(0)];
    shade_at(flat, bake.map(|b| b.instances[i].record(nearest)), i, p, n, eye)
}

/// Outgoing radiance toward `eye` from the polygonal lights at vertex `v` of instance `i`,
/// shadowed by `bake`'s trees (`None`: unshadowed LTC).
pub fn shade_vertex(
    scene: &Scene,
    flat: &FlatScene,
    bake: Option<&Bake>,
    i: usize,
    v: usize,
    eye: glam::Vec3,
) -> glam::Vec3 {
    let (p, n) = flat.vertex(&scene.meshes, i, v);
    shade_at(flat, bake.map(|b| b.instances[i].record(v)), i, p, n, eye)
}

/// LTC shading of instance `i`'s material at `p` (normal `n`) toward `eye`, shadowed by a
/// vertex record's trees (`None`: unshadowed).
fn shade_at(
    flat: &FlatScene,
    record: Option<&[u8]>,
    i: usize,
    p: glam::Vec3,
    n: glam::Vec3,
    eye: glam::Vec3,
) -> glam::Vec3 {
    let shader = shade::PointShader::new(&crate::math::ltc::table(), p, n, eye, &flat.instances[i].material);
    let vis = record.map_or(shade::Visibility::Unshadowed, shade::Visibility::Tree);
    shader.shade(&flat.lights, vis)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn from_records(records: &[Vec<u8>]) -> BakedInstance {
        let mut offsets = vec![0u32];
        records.iter().for_each(|r| offsets.push(offsets[offsets.len() - 1] + r.len() as u32));
        BakedInstance { offsets, data: records.concat() }
    }

    #[test]
    fn splicing_records_equals_building_from_them() {
        let records: Vec<Vec<u8>> = (0..7u8).map(|v| vec![v; 1 + (v as usize * 3) % 5]).collect();
        let mut inst = BakedInstance::unshadowed(7);
        assert_eq!(inst.vertices(), 7);
        inst.splice(4, &records[4..]);
        inst.splice(0, &records[..2]);
        inst.splice(2, &records[2..4]);
        assert_eq!(inst, from_records(&records));
        inst.splice(3, &[vec![9; 12]]);
        let mut edited = records.clone();
        edited[3] = vec![9; 12];
        assert_eq!(inst, from_records(&edited));
    }

    #[test]
    fn the_placeholder_shades_like_unshadowed_ltc() {
        let scene = crate::scene::default_scene();
        let flat = crate::scene::flatten(&scene);
        let s = Settings { res: 8, epsilon: 2.0 };
        let instances = (0..flat.instances.len())
            .map(|i| BakedInstance::unshadowed(scene.meshes[flat.instances[i].mesh as usize].positions.len()))
            .collect();
        let bake = Bake { settings: s, instances, stats: Stats::default() };
        let eye = glam::Vec3::new(0.0, 2.0, 5.0);
        let placeholder = shade_vertices(&scene, &flat, Method::Bspvt(&bake), eye);
        let open = shade_vertices(&scene, &flat, Method::Unshadowed, eye);
        for (a, b) in placeholder.iter().flatten().zip(open.iter().flatten()) {
            assert!((*a - *b).abs().max_element() <= 1e-4 * b.max_element().max(1.0), "{a} vs {b}");
        }
    }
}
