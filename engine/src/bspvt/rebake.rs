//! Warm re-bakes: a vertex's trees after some occluders changed, from its previous bake —
//! only the texels whose rays can meet a changed occluder's old or new bounds are looked at,
//! only the rays whose answer can have changed are cast, and only the tiles whose visibility
//! changed are built again (see [`rebake_vertex`]).

use super::memo::SubtreeMemo;
use super::reach::Reach;
use super::visibility::{self, Look};
use super::{VertexBake, depth, dirty, layout, node, tiles_per_side, tree};
use crate::accel::{self, Occluders};
use std::ops::Range;

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
/// Identical to [`super::bake_vertex`] of the edited scene: a ray's result against an occluder
/// depends on that occluder alone (see [`Occluders`]). An empty `old` record bakes from
/// scratch. Settings, subtrees and reach as in [`super::bake_vertex`]; `old` must have been baked
/// for the same reach (tiles out of reach are never looked at again).
pub fn rebake_vertex(
    occluders: &Occluders,
    p: glam::Vec3,
    n: glam::Vec3,
    (tiles, reach): (&SubtreeMemo, &Reach),
    old: &VertexBake,
    changes: &[Change],
) -> VertexBake {
    let s = tiles.settings();
    let per_face = tiles_per_side(s.res).pow(2);
    let cold = old.record.is_empty();
    let edit = Edit::new(occluders, (p, n), changes, reach, s.res);
    let mut dirty = vec![cold; 6 * per_face];
    for cover in edit.boxes().map(|b| &b.cover) {
        dirty.iter_mut().zip(cover).for_each(|(a, c)| *a |= *c != dirty::Cover::None);
    }
    if let Some(reached) = &edit.reached {
        dirty.iter_mut().zip(reached).for_each(|(d, r)| *d &= r);
    }
    debug_assert!(old.masks.is_sorted_by_key(|m| m.0), "a bake's masks are by tile index");
    let kept = if cold { [&[][..]; 6] } else { layout::vertex_faces(&old.record) };
    let kept_depths = if cold { [&[][..]; 6] } else { layout::vertex_depths(&old.record) };
    let mut out = VertexBake::default();
    let hemisphere = std::cell::OnceCell::new();
    let view = || hemisphere.get_or_init(|| visibility::hemisphere(occluders, p, n, s.res));
    let faces: [(Vec<u8>, Vec<u8>); 6] = std::array::from_fn(|f| {
        let range = (f * per_face) as u32..((f + 1) * per_face) as u32;
        // The masks are by tile index: the face's are one run of them.
        let run = old.masks.partition_point(|m| m.0 < range.start)..old.masks.partition_point(|m| m.0 < range.end);
        let old_masks: tree::Masks = old.masks[run].iter().map(|&(t, m)| (t - range.start, m)).collect();
        let dirty = &dirty[f * per_face..(f + 1) * per_face];
        if !dirty.contains(&true) {
            out.masks.extend(old_masks.iter().map(|&(t, m)| (t + range.start, m)));
            return (kept[f].to_vec(), kept_depths[f].to_vec());
        }
        // A face that stored no tree was entirely occluded (or below the horizon: never read).
        let old_tree = match (cold, kept[f].is_empty()) {
            (true, _) => Vec::new(),
            (false, true) => vec![node::Node::Leaf(0.0)],
            (false, false) => layout::decode_tree(kept[f]),
        };
        let reached = edit.reached.as_deref().map(|r| &r[f * per_face..(f + 1) * per_face]);
        let bits = if cold {
            let bits = visibility::cast_face_tiles(occluders, view(), (p, n), f, s.res, (reached, reach));
            out.rays += bits.iter().map(|b| b.live.count_ones() as usize).sum::<usize>();
            bits
        } else {
            edit.cast_face(f, s.res, dirty, (&old_tree, &old_masks), &mut out.rays)
        };
        let face = tree::rebuild(&bits, tiles, &old_tree, &old_masks);
        out.built += face.built;
        out.masks.extend(face.masks.iter().map(|&(t, m)| (t + range.start, m)));
        let recast: Vec<bool> = (0..per_face).map(|t| dirty[t] && reached.is_none_or(|r| r[t])).collect();
        let depth = face.nodes.as_ref().filter(|_| reach.depth).map_or_else(Vec::new, |nodes| {
            let occluded = occluded_texels((nodes, &face.masks), &bits, (n, f, s.res), (&recast, reached));
            let new = visibility::cast_depth(occluders, (view(), p, n), f, s.res, (&occluded, reach));
            out.rays += occluded.iter().map(|m| m.count_ones() as usize).sum::<usize>();
            let old = depth::split_tiles(kept_depths[f], s.res);
            let tiles: Vec<Option<&[u8]>> =
                (0..per_face).map(|t| if recast[t] { new[t].as_deref() } else { old[t].as_deref() }).collect();
            depth::join_tiles(&tiles, s.res)
        });
        let tree = layout::encode_face(face.nodes.as_deref().filter(|t| *t != [node::Node::Leaf(0.0)]));
        (tree, depth)
    });
    out.record = layout::with_depths(
        layout::join_faces(faces.each_ref().map(|f| f.0.as_slice())),
        faces.each_ref().map(|f| f.1.as_slice()),
    );
    out
}

/// Per tile of a face (row-major), the occluded texels after a (re-)bake of the tiles
/// `recast` flags (0 for the others): above the horizon in `bits` and not visible in the
/// face's new tree and masks `tree`. `reached` flags the tiles in reach (`None`: all).
fn occluded_texels(
    tree: (&[node::Node], &[(u32, u64)]),
    bits: &[visibility::TileBits],
    (n, f, res): (glam::Vec3, usize, usize),
    (recast, reached): (&[bool], Option<&[bool]>),
) -> Vec<u64> {
    let live: Vec<bool> = visibility::live_tiles(n, f, res)
        .into_iter()
        .enumerate()
        .map(|(t, l)| l && reached.is_none_or(|r| r[t]))
        .collect();
    let visible = tree::old_visibility(tree.0, tree.1, res, &live, recast);
    (0..recast.len()).map(|t| if recast[t] { bits[t].live & !visible[t] } else { 0 }).collect()
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
    /// Where each ray ends ([`Reach::ray_end`]).
    reach: &'a Reach,
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
        reach: &'a Reach,
        res: usize,
    ) -> Self {
        let origin = visibility::horizon_origin(p, n);
        let seen = |(lo, hi), instance: Option<usize>| {
            let bounds = dirty::SeenBox::new(p, n, lo, hi);
            // A beam answers for whole rays: where reach ends rays, each ray is cast.
            let beam = instance.filter(|_| !reach.bounds_rays()).and_then(|i| occluders.beam(i, origin));
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
        Self { occluders, p, n, origin, before, after, blocked, reached: reach.tiles(p, n, res), reach }
    }

    /// Face `f`'s tiles after the edit (see [`visibility::cast_tiles`]; `dirty` flags its tiles
    /// that can see a changed box, cast unless known blocked) from its previous tree and masks
    /// `old`; `rays` counts the rays cast.
    fn cast_face(
        &self,
        f: usize,
        res: usize,
        dirty: &[bool],
        old: (&[node::Node], &[(u32, u64)]),
        rays: &mut usize,
    ) -> Vec<visibility::TileBits> {
        let first = f * dirty.len();
        let reached = |t: usize| self.reached.as_ref().is_none_or(|r| r[first + t]);
        // The tiles that shaped the old tree: above the horizon and in reach.
        let face = visibility::Horizon::new(self.n, f, res);
        let live: Vec<bool> = face.live().into_iter().enumerate().map(|(t, l)| l && reached(t)).collect();
        let looks: Vec<Look> = (0..dirty.len())
            .map(|t| match (reached(t), dirty[t], self.blocked[first + t]) {
                (false, ..) => Look::Unreached,
                (true, false, _) => Look::Keep,
                (true, true, false) => Look::Cast,
                (true, true, true) => Look::Blocked,
            })
            .collect();
        let cast = |t: usize| matches!(looks[t], Look::Cast | Look::Blocked);
        // Only the tiles that may be cast ask what their texels were.
        let was = tree::old_visibility(old.0, old.1, res, &live, &(0..dirty.len()).map(cast).collect::<Vec<_>>());
        // The rows of the tiles that may be cast: the only ones asked about.
        let span = tile_rows(res, cast);
        let [before, after] = [&self.before, &self.after].map(|boxes| self.seen(boxes, f, res, span.clone()));
        let occluded = visibility::tile_masks(res, self.certain_runs(f, res, cast));
        // A texel that was visible can only change inside a new box, one that was not only
        // inside an old one (see `Self::texel`).
        let asks =
            |t: usize| visibility::Ask { ask: (was[t] & after[t]) | (!was[t] & before[t]), occluded: occluded[t] };
        // A texel centre outside every new box's columns meets none of them (the columns hold
        // every centre that can; a direction lifted above the horizon is not a centre).
        let texel = |t: usize, bit, d, centred: bool| {
            self.texel(first + t, d, (was[t] & bit != 0, !centred || after[t] & bit != 0), rays)
        };
        visibility::cast_tiles(&face, &looks, asks, texel)
    }

    /// Per tile of face `f` (row-major), the texels of rows `span` whose rays can meet one of
    /// `boxes` (see [`dirty::SeenBox::columns`]; all of a tile a box covers).
    fn seen(&self, boxes: &[Seen], f: usize, res: usize, span: Range<usize>) -> Vec<u64> {
        let per_face = tiles_per_side(res).pow(2);
        let mut masks = vec![0; per_face];
        for b in boxes {
            let cover = &b.cover[f * per_face..(f + 1) * per_face];
            // Only the tiles the box covers in part use their rows' columns.
            let some = tile_rows(res, |t| cover[t] == dirty::Cover::Some);
            let rows = some.start.max(span.start)..some.end.min(span.end);
            let seen = visibility::tile_masks(res, rows.clone().zip(b.bounds.columns(f, res, rows)));
            for ((m, c), s) in masks.iter_mut().zip(cover).zip(seen) {
                *m |= match c {
                    dirty::Cover::None => 0,
                    dirty::Cover::Some => s,
                    dirty::Cover::All => u64::MAX,
                };
            }
        }
        masks
    }

    /// The runs of columns (`(row, columns)` pairs) of face `f` whose rays certainly meet a
    /// changed occluder's triangles now (see [`dirty::certain_runs`]), looked for in the rows of
    /// the tiles `cast` picks that can see the occluder's bounds.
    fn certain_runs(&self, f: usize, res: usize, cast: impl Fn(usize) -> bool) -> Vec<(usize, Range<usize>)> {
        let first = f * tiles_per_side(res).pow(2);
        let mut out = Vec::new();
        for b in &self.after {
            let Some(beam) = &b.beam else { continue };
            let rows = tile_rows(res, |t| cast(t) && b.cover[first + t] != dirty::Cover::None);
            out.extend(dirty::certain_runs(beam, self.n, f, res, rows));
        }
        out
    }

    /// Old bounds, then new.
    fn boxes(&self) -> impl Iterator<Item = &Seen> {
        self.before.iter().chain(&self.after)
    }

    /// The state of the texel cast through tile `t` (of all six faces) in direction `d` (unit,
    /// above the horizon), which was visible or not, and whose ray may meet a new box or
    /// certainly meets none: [`visibility::SKIPPED`] when it cannot have changed; `rays` counts
    /// the rays cast.
    fn texel(&self, t: usize, d: glam::Vec3, (was_visible, may_meet): (bool, bool), rays: &mut usize) -> u8 {
        let mut after = self.after.iter().filter(|b| may_meet && b.meets(t, d)).peekable();
        // Visible: only what is now inside a changed occluder's bounds could block it.
        // Blocked, by no changed occluder: what blocked it stayed put.
        let unchanged = if was_visible { after.peek().is_none() } else { !self.before.iter().any(|b| b.meets(t, d)) };
        if unchanged {
            return visibility::SKIPPED;
        }
        let o = visibility::ray_origin(self.origin, self.p, self.n, d);
        let end = self.reach.ray_end(o, d);
        let mut cast = |i| {
            *rays += 1;
            self.occluders.occluded_by(i, o, d, end)
        };
        // The beam's origin is `o` unless rounding put `d` below the horizon.
        let beam = |b: &Seen| b.beam.as_ref().filter(|_| o == self.origin).and_then(|beam| beam.hits(d));
        let blocks = |b: &Seen| b.instance.is_some_and(|i| beam(b).unwrap_or_else(|| cast(i)));
        match (after.any(blocks), was_visible) {
            (true, _) => visibility::OCCLUDED,
            (false, true) => visibility::VISIBLE,
            (false, false) => {
                *rays += 1;
                visibility::cast_ray(self.occluders, o, d, end)
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
        (Some(a), Some(b)) => a / k * node::TILE..((b / k + 1) * node::TILE).min(res),
        _ => 0..0,
    }
}
