//! BSP visibility trees: per cube face, a fixed grid of [`TILE`]-texel tiles, and inside each
//! mixed tile Algorithm 1 of the BSPVT paper with its two corrections (see [`super::split`]).
//!
//! Lines are `cos θ · s + sin θ · t = c` in face coordinates; the positive side
//! (`cos θ s + sin θ t − c > 0`) is the first child. Line parameters are quantised *before*
//! pixels are partitioned, so leaf means match the geometry the shader sees.

use super::Settings;
use super::memo::SubtreeMemo;
use super::node::{Node, TILE, TileKey, quantise_line};
use super::split::{Line, Pixels, bits, clusters};
use super::visibility::TileBits;
use crate::math::cubemap;
use std::ops::Range;

/// Visible-texel masks of mixed tiles: (tile index, mask) pairs by tile index (see
/// [`FaceTree::masks`]).
pub type Masks = Vec<(u32, u64)>;

/// A face's tree and what a later re-bake needs to know about its texels.
#[derive(Clone, Debug, PartialEq)]
pub struct FaceTree {
    /// The tree; `None` when no texel is above the horizon.
    pub nodes: Option<Vec<Node>>,
    /// The visible-texel masks of its mixed tiles (both visible and occluded texels above the
    /// horizon), by tile index (row-major within the face); bit `(j mod TILE)·TILE + i mod
    /// TILE` is texel (i, j). Uniform tiles need none: their subtree is a 0 or 1 leaf.
    pub masks: Masks,
    /// Mixed tiles whose subtrees were made anew, by Algorithm 1 or from the [`SubtreeMemo`]
    /// (the rest were kept or uniform).
    pub built: usize,
}

/// Builds the tree of one face from its texel states.
pub fn build(face: &[u8], res: usize, epsilon: f64) -> FaceTree {
    rebuild(&TileBits::from_face(face, res), &SubtreeMemo::new(&Settings { res, epsilon }), &[], &[])
}

/// [`build`] for a face given as tiles (see [`TileBits`]), some of whose texels were not cast
/// ([`SKIPPED`](super::visibility::SKIPPED)): their states are
/// those of `old`, the face's previous tree (a complete tree; a face that stored none was
/// entirely occluded: `[Leaf(0.0)]`), and `old_masks`, its masks. A tile whose states did not
/// change keeps its old subtree; the others come from `tiles` (whose settings apply) or are
/// built and added to it. Equal to [`build`] of the fully cast face when the skipped texels'
/// visibility did not change.
pub fn rebuild(face: &[TileBits], tiles: &SubtreeMemo, old: &[Node], old_masks: &[(u32, u64)]) -> FaceTree {
    let res = tiles.settings().res;
    let mut grid = Grid::new(face, tiles, old_masks);
    let mut nodes = Vec::new();
    let live = grid.region(Rect { i0: 0, j0: 0, i1: res, j1: res }, old, &mut nodes);
    grid.masks.sort_unstable_by_key(|m| m.0);
    FaceTree { nodes: live.then_some(nodes), masks: grid.masks, built: grid.built }
}

/// A rectangle of texels `[i0, i1) × [j0, j1)`.
#[derive(Clone, Copy)]
struct Rect {
    i0: usize,
    j0: usize,
    i1: usize,
    j1: usize,
}

impl Rect {
    /// The columns and rows of the tiles it covers.
    fn tile_ranges(self) -> (Range<usize>, Range<usize>) {
        (self.i0 / TILE..self.i1.div_ceil(TILE), self.j0 / TILE..self.j1.div_ceil(TILE))
    }

    /// Tiles across (s) and down (t): regions start on tile boundaries, the last tile of a
    /// face whose resolution is not a multiple of [`TILE`] is narrower.
    fn tiles(self) -> (usize, usize) {
        ((self.i1 - self.i0).div_ceil(TILE), (self.j1 - self.j0).div_ceil(TILE))
    }

    /// The grid split: the quantised line on the tile boundary that halves the tiles of the
    /// longer side, and the halves on its positive (larger s or t) and negative sides.
    fn halves(self, res: usize) -> ((u16, u16), Rect, Rect) {
        let edge = |k: usize| 2.0 * k as f64 / res as f64 - 1.0;
        let (across, down) = self.tiles();
        if across >= down {
            let m = self.i0 + across / 2 * TILE;
            (quantise_line(0.0, edge(m)), Rect { i0: m, ..self }, Rect { i1: m, ..self })
        } else {
            let m = self.j0 + down / 2 * TILE;
            (quantise_line(std::f64::consts::FRAC_PI_2, edge(m)), Rect { j0: m, ..self }, Rect { j1: m, ..self })
        }
    }
}

/// Whether `pick(tile index)` holds for a tile of region `r` (`k` tiles per side).
fn any_tile(r: Rect, k: usize, pick: impl Fn(usize) -> bool) -> bool {
    let (ti, tj) = r.tile_ranges();
    tj.flat_map(|j| ti.clone().map(move |i| (i, j))).any(|(i, j)| pick(j * k + i))
}

/// The previous subtrees of the two halves of a region whose previous subtree is `old`: a
/// merged uniform leaf covers both halves, and a half with no texel above the horizon left its
/// sibling's subtree in place of the split.
fn old_halves(old: &[Node], both_live: bool) -> (&[Node], &[Node]) {
    match old {
        [Node::Split { .. }, ..] if both_live => old[1..].split_at(skip(old, 1) - 1),
        _ => (old, old),
    }
}

/// A live tile's previous visible mask (to be masked by its live texels): its stored mask,
/// or, for a uniform tile (which stores none), all or nothing from its previous leaf `old`.
fn old_tile_visible(old_masks: &[(u32, u64)], tile: u32, old: &[Node]) -> u64 {
    match old_masks.binary_search_by_key(&tile, |m| m.0) {
        Ok(x) => old_masks[x].1,
        Err(_) if matches!(old, [Node::Leaf(v)] if *v >= 0.5) => u64::MAX,
        Err(_) => 0,
    }
}

/// Each tile's previous visible mask (row-major tiles: its stored mask, or all or nothing for a
/// uniform tile), from a face's previous tree `old` and masks, for the tiles `wanted` flags (0
/// for the others and for tiles with no texel above the horizon); `live` flags the tiles with
/// a texel above the horizon, which shaped that tree. Only the subtrees holding a wanted tile
/// are walked.
pub fn old_visibility(old: &[Node], old_masks: &[(u32, u64)], res: usize, live: &[bool], wanted: &[bool]) -> Vec<u64> {
    type Flags<'a> = (&'a [bool], &'a [bool]);
    fn walk(r: Rect, old: &[Node], res: usize, (live, wanted): Flags, old_masks: &[(u32, u64)], out: &mut [u64]) {
        let k = res.div_ceil(TILE);
        if !any_tile(r, k, |t| live[t] && wanted[t]) {
            return;
        }
        if r.tiles() == (1, 1) {
            let t = (r.j0 / TILE) * k + r.i0 / TILE;
            out[t] = old_tile_visible(old_masks, t as u32, old);
            return;
        }
        let (_, pos, neg) = r.halves(res);
        let both = any_tile(pos, k, |t| live[t]) && any_tile(neg, k, |t| live[t]);
        let (old_pos, old_neg) = old_halves(old, both);
        walk(pos, old_pos, res, (live, wanted), old_masks, out);
        walk(neg, old_neg, res, (live, wanted), old_masks, out);
    }
    let mut out = vec![0; live.len()];
    walk(Rect { i0: 0, j0: 0, i1: res, j1: res }, old, res, (live, wanted), old_masks, &mut out);
    out
}

/// One face's texel states, build parameters and the masks being gathered.
struct Grid<'a> {
    res: usize,
    memo: &'a SubtreeMemo,
    /// Tiles per side.
    k: usize,
    tiles: &'a [TileBits],
    old_masks: &'a [(u32, u64)],
    masks: Masks,
    built: usize,
}

impl<'a> Grid<'a> {
    fn new(tiles: &'a [TileBits], memo: &'a SubtreeMemo, old_masks: &'a [(u32, u64)]) -> Self {
        let res = memo.settings().res;
        Self { res, memo, k: res.div_ceil(TILE), tiles, old_masks, masks: Vec::new(), built: 0 }
    }

    /// Whether any texel of `r` is above the horizon.
    fn live(&self, r: Rect) -> bool {
        any_tile(r, self.k, |t| self.tiles[t].live != 0)
    }

    /// Whether no texel of `r` was cast: each keeps its old state.
    fn untouched(&self, r: Rect) -> bool {
        !any_tile(r, self.k, |t| self.tiles[t].skipped != self.tiles[t].live)
    }

    /// Appends the subtree of region `r` to `out` (`old` is its previous subtree): false, and
    /// nothing appended, when no texel of `r` is above the horizon. One buffer for the whole
    /// face, rather than a vector per region joined on the way up.
    fn region(&mut self, r: Rect, old: &[Node], out: &mut Vec<Node>) -> bool {
        if !self.live(r) {
            return false;
        }
        if !old.is_empty() && self.untouched(r) {
            // What the recursion would rebuild tile by tile (see `Self::tile`), in one copy.
            let ((ti, tj), k) = (r.tile_ranges(), self.k);
            let inside = |t: usize| ti.contains(&(t % k)) && tj.contains(&(t / k));
            self.masks.extend(self.old_masks.iter().filter(|m| inside(m.0 as usize)));
            out.extend_from_slice(old);
            return true;
        }
        if r.tiles() == (1, 1) {
            self.tile(r, old, out);
            return true;
        }
        let ((angle, offset), pos, neg) = r.halves(self.res);
        let (old_pos, old_neg) = old_halves(old, self.live(pos) && self.live(neg));
        let at = out.len();
        out.push(Node::Split { angle, offset });
        let positive = self.region(pos, old_pos, out);
        let middle = out.len();
        let negative = self.region(neg, old_neg, out);
        if !(positive && negative) {
            // One half has nothing above the horizon: the other stands for the region.
            out.remove(at);
        } else if out[at + 1..middle] == out[middle..]
            && matches!(out[middle..], [Node::Leaf(v)] if v == 0.0 || v == 1.0)
        {
            // Both halves uniformly visible, or both uniformly occluded: one leaf.
            let leaf = out[middle];
            out.truncate(at);
            out.push(leaf);
        }
        true
    }

    /// Appends the subtree of one tile with a texel above the horizon to `out`: its old
    /// subtree when its visibility did not change, else built by Algorithm 1. Skipped texels
    /// take their old state: from the tile's old mask, or (a uniform tile has none) from its
    /// old leaf.
    fn tile(&mut self, r: Rect, old: &[Node], out: &mut Vec<Node>) {
        let index = ((r.j0 / TILE) * self.k + r.i0 / TILE) as u32;
        let TileBits { live, visible, skipped } = self.tiles[index as usize];
        let old_visible = old_tile_visible(self.old_masks, index, old) & live;
        let visible = visible | (old_visible & skipped);
        if visible != 0 && visible != live {
            self.masks.push((index, visible));
        }
        if !old.is_empty() && visible == old_visible {
            out.extend_from_slice(old);
        } else if visible == 0 || visible == live {
            out.push(Node::Leaf(if visible == 0 { 0.0 } else { 1.0 }));
        } else {
            self.built += 1;
            memoised_subtree(self.memo, (index, live, visible), out);
        }
    }
}

/// Appends the subtree of mixed tile `key` to `out`: its orbit's subtree ([`build_tile`] of the
/// orbit's least key, memoised or built and memoised), mapped to the tile.
pub fn memoised_subtree(memo: &SubtreeMemo, key: TileKey, out: &mut Vec<Node>) {
    let (canonical, to) = memo.orbit(key);
    memo.with_subtree(canonical, || build_tile(canonical, memo), |nodes| to.extend(out, nodes));
}

/// The subtree Algorithm 1 builds for the mixed tile `key` (see [`TileKey`]) with the settings
/// and texel weights of `tiles` (whose entries it neither reads nor adds to).
pub fn build_tile((index, live, visible): TileKey, tiles: &SubtreeMemo) -> Vec<Node> {
    let Settings { res, epsilon } = *tiles.settings();
    let k = res.div_ceil(TILE);
    let (i0, j0) = (index as usize % k * TILE, index as usize / k * TILE);
    let r = Rect { i0, j0, i1: (i0 + TILE).min(res), j1: (j0 + TILE).min(res) };
    clusters(&tile_pixels(r, tiles, live, visible), res, epsilon)
}

/// The pixels of tile `r` above the horizon (`live`), visible where `visible` says.
fn tile_pixels(r: Rect, tiles: &SubtreeMemo, live: u64, visible: u64) -> Pixels {
    // Set bits lowest first: the texels in row-major order.
    Pixels::new(bits(live).map(|b| {
        let (i, j) = (r.i0 + b % TILE, r.j0 + b / TILE);
        let st = cubemap::texel_center(i, j, tiles.settings().res);
        (st.x, st.y, tiles.weight(i, j), visible >> b & 1 != 0)
    }))
}

/// Index (in `nodes`) of the leaf containing face point (s, t).
pub fn leaf_index(nodes: &[Node], s: f64, t: f64) -> usize {
    let mut i = 0;
    loop {
        match nodes[i] {
            Node::Leaf(_) => return i,
            Node::Split { angle, offset } => {
                let side = Line::dequantised(angle, offset).side(s, t);
                i = if side > 0.0 { i + 1 } else { skip(nodes, i + 1) };
            }
        }
    }
}

/// Index just past the subtree starting at `i`.
pub fn skip(nodes: &[Node], mut i: usize) -> usize {
    let mut pending = 1;
    while pending > 0 {
        pending -= 1;
        if let Node::Split { .. } = nodes[i] {
            pending += 2;
        }
        i += 1;
    }
    i
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bspvt::visibility::{BELOW, OCCLUDED, SKIPPED, VISIBLE};

    fn face_from(res: usize, f: impl Fn(f64, f64) -> u8) -> Vec<u8> {
        (0..res * res)
            .map(|k| {
                let st = cubemap::texel_center(k % res, k / res, res);
                f(st.x, st.y)
            })
            .collect()
    }

    /// Every valid pixel lands in exactly one leaf and each leaf holds its pixels' mean.
    fn check_invariants(face: &[u8], res: usize, nodes: &[Node]) {
        let mean_w = 4.0 * std::f64::consts::PI / (6 * res * res) as f64;
        let mut sums: std::collections::HashMap<usize, (f64, f64)> = Default::default();
        for (k, &state) in face.iter().enumerate() {
            if state == BELOW {
                continue;
            }
            let st = cubemap::texel_center(k % res, k / res, res);
            let leaf = leaf_index(nodes, st.x, st.y);
            let w = cubemap::texel_solid_angle(k % res, k / res, res) / mean_w;
            let e = sums.entry(leaf).or_default();
            e.0 += w;
            e.1 += w * if state == VISIBLE { 1.0 } else { 0.0 };
        }
        for (leaf, (w, v)) in sums {
            let Node::Leaf(stored) = nodes[leaf] else { panic!("not a leaf") };
            assert!((stored as f64 - v / w).abs() < 1e-6, "leaf {leaf}: {stored} vs {}", v / w);
        }
        let leaves = nodes.iter().filter(|n| matches!(n, Node::Leaf(_))).count();
        assert_eq!(nodes.len(), 2 * leaves - 1, "a full binary tree");
        assert_eq!(skip(nodes, 0), nodes.len());
    }

    #[test]
    fn uniform_faces_are_single_leaves() {
        let res = 16;
        assert_eq!(build(&vec![VISIBLE; res * res], res, 0.0).nodes, Some(vec![Node::Leaf(1.0)]));
        assert_eq!(build(&vec![OCCLUDED; res * res], res, 0.0).nodes, Some(vec![Node::Leaf(0.0)]));
        assert_eq!(build(&vec![BELOW; res * res], res, 0.0).nodes, None);
        assert!(build(&vec![VISIBLE; res * res], res, 0.0).masks.is_empty(), "uniform tiles need no mask");
    }

    #[test]
    fn a_straight_boundary_costs_a_split_per_tile_it_crosses() {
        let res = 32;
        let face = face_from(res, |s, t| if 0.6 * s + 0.8 * t > 0.1 { VISIBLE } else { OCCLUDED });
        let built = build(&face, res, 0.5);
        let nodes = built.nodes.unwrap();
        check_invariants(&face, res, &nodes);
        let k = res / TILE;
        let mixed = (0..k * k)
            .filter(|&tile| {
                let states: Vec<u8> = (0..res * res)
                    .filter(|&x| (x / res / TILE) * k + (x % res) / TILE == tile)
                    .map(|x| face[x])
                    .collect();
                states.contains(&VISIBLE) && states.contains(&OCCLUDED)
            })
            .count();
        let leaves = nodes.iter().filter(|n| matches!(n, Node::Leaf(_))).count();
        // Each crossed tile is one split; uniform tiles on either side merge into few leaves.
        assert!(leaves <= 2 * mixed + 2 * k, "{leaves} leaves for {mixed} crossed tiles");
        assert_eq!((built.masks.len(), built.built), (mixed, mixed), "a mask and a build per crossed tile");
        for (tile, mask) in built.masks {
            let (ti, tj) = (tile as usize % k, tile as usize / k);
            for b in 0..64 {
                let state = face[(tj * TILE + b / TILE) * res + ti * TILE + b % TILE];
                assert_eq!(mask >> b & 1 == 1, state == VISIBLE, "tile {tile} bit {b}");
            }
        }
    }

    /// A face whose visibility changed in some texels: casting only some texels around them
    /// (the others `SKIPPED`) and rebuilding from the old tree and masks gives the tree and
    /// masks built from scratch, and runs Algorithm 1 only in the tiles that changed.
    #[test]
    fn rebuilding_from_the_changed_texels_equals_building_from_scratch() {
        // 20: a face whose last tile is narrower.
        for res in [32, 20] {
            rebuild_equals_build(res);
        }
    }

    fn rebuild_equals_build(res: usize) {
        // One memo for every rebuild below, as a bake shares one among its vertices.
        let memo = SubtreeMemo::new(&Settings { res, epsilon: 1.0 });
        let horizon = |t: f64| t < -0.7;
        let scene = |cx: f64| {
            face_from(res, move |s, t| {
                if horizon(t) {
                    BELOW
                } else if (s - cx).powi(2) + t * t < 0.15 {
                    OCCLUDED
                } else {
                    VISIBLE
                }
            })
        };
        let tile_of = |x: usize| ((x / res) / TILE, (x % res) / TILE);
        let shut = face_from(res, |_, t| if horizon(t) { BELOW } else { OCCLUDED });
        let window = face_from(res, |s, t| {
            if horizon(t) {
                BELOW
            } else if s > 0.6 && t > 0.6 {
                VISIBLE
            } else {
                OCCLUDED
            }
        });
        for (before, after) in [(scene(-0.3), scene(0.1)), (shut, window)] {
            let old = build(&before, res, 1.0);
            // The old tree and masks tell every tile's old visibility.
            let before_bits = TileBits::from_face(&before, res);
            let live: Vec<bool> = before_bits.iter().map(|b| b.live != 0).collect();
            let old_visible = old_visibility(old.nodes.as_deref().unwrap(), &old.masks, res, &live, &live);
            for (b, v) in before_bits.iter().zip(&old_visible) {
                assert_eq!(v & b.live, b.visible);
            }
            // Asked for some tiles only, the walk gives those the same masks and the rest 0.
            let some: Vec<bool> = (0..live.len()).map(|t| t % 3 == 1).collect();
            let partial = old_visibility(old.nodes.as_deref().unwrap(), &old.masks, res, &live, &some);
            for (t, (p, v)) in partial.iter().zip(&old_visible).enumerate() {
                assert_eq!(*p, if some[t] { *v } else { 0 }, "tile {t}");
            }
            let fresh = build(&after, res, 1.0);
            let changed: Vec<(usize, usize)> = (0..res * res).filter(|&x| before[x] != after[x]).map(tile_of).collect();
            // Every changed texel and, in the tiles around them, every third other one is cast.
            let cast = |x: usize| before[x] != after[x] || (x.is_multiple_of(3) && changed.contains(&tile_of(x)));
            let partial: Vec<u8> =
                (0..res * res).map(|x| if after[x] == BELOW || cast(x) { after[x] } else { SKIPPED }).collect();
            assert!(partial.contains(&SKIPPED), "some texels are kept");
            let warm = rebuild(&TileBits::from_face(&partial, res), &memo, &old.nodes.clone().unwrap(), &old.masks);
            assert_eq!((&warm.nodes, &warm.masks), (&fresh.nodes, &fresh.masks));
            let mut crossed = changed.clone();
            crossed.sort_unstable();
            crossed.dedup();
            assert!(warm.built <= crossed.len(), "{} built for {} changed tiles", warm.built, crossed.len());
        }
        // Nothing changed: the old tree, whatever its grid merged, and nothing built.
        let face = scene(0.2);
        let old = build(&face, res, 1.0);
        let some: Vec<u8> = face
            .iter()
            .enumerate()
            .map(|(x, &s)| if s == BELOW || x.is_multiple_of(2) { s } else { SKIPPED })
            .collect();
        let none: Vec<u8> = face.iter().map(|&s| if s == BELOW { BELOW } else { SKIPPED }).collect();
        for partial in [some, none] {
            let warm = rebuild(&TileBits::from_face(&partial, res), &memo, &old.nodes.clone().unwrap(), &old.masks);
            assert_eq!((&warm.nodes, &warm.masks, warm.built), (&old.nodes, &old.masks, 0));
        }
    }

    /// A face built again through the memo that built it takes every subtree from the memo,
    /// and equals the first build. The face is its own mirror image in t, so the first build
    /// already shares the subtrees of mirrored tiles.
    #[test]
    fn memoised_subtrees_equal_built_ones() {
        let res = 32;
        let face = face_from(res, |s, t| if s * s + 2.0 * t * t < 0.4 || s > 0.7 { OCCLUDED } else { VISIBLE });
        let memo = SubtreeMemo::new(&Settings { res, epsilon: 0.5 });
        let face = TileBits::from_face(&face, res);
        let first = rebuild(&face, &memo, &[], &[]);
        assert!(first.built > 4 && memo.hits() > 0 && memo.hits() + memo.added() == first.built);
        let (hits, added) = (memo.hits(), memo.added());
        let again = rebuild(&face, &memo, &[], &[]);
        assert_eq!(again, first);
        assert_eq!((memo.hits(), memo.added()), (hits + first.built, added));
        // And through the memo's byte form, as a later bake loads it.
        let loaded = SubtreeMemo::from_bytes(memo.settings(), &memo.to_bytes()).expect("round trip");
        assert_eq!(rebuild(&face, &loaded, &[], &[]), first);
        assert_eq!((loaded.hits(), loaded.added()), (first.built, 0));
    }

    #[test]
    fn disk_and_checker_terminate_with_epsilon_zero() {
        let res = 24;
        let disk = face_from(res, |s, t| {
            if s * s + t * t < 0.3 {
                OCCLUDED
            } else if t < -0.8 {
                BELOW
            } else {
                VISIBLE
            }
        });
        let checker =
            face_from(
                res,
                |s, t| if ((s * 3.0).floor() + (t * 3.0).floor()) as i64 % 2 == 0 { VISIBLE } else { OCCLUDED },
            );
        for face in [&disk, &checker] {
            let exact = build(face, res, 0.0).nodes.unwrap();
            check_invariants(face, res, &exact);
            let coarse = build(face, res, 4.0).nodes.unwrap();
            check_invariants(face, res, &coarse);
            assert!(coarse.len() < exact.len());
        }
    }
}
