//! Occluders as one BVH per instance, queried together behind a bounds test.
//!
//! A ray's answer against one instance depends on that instance's triangles alone — never on
//! how a single scene-wide BVH happened to group them — so moving, adding or removing an
//! instance cannot change any ray's result against the others, even for rays that graze a
//! surface (where a BVH's box tests can go either way). Incremental BSPVT re-bakes rely on it
//! to reproduce a cold bake's bytes.
//!
//! An instance of many triangles (a terrain) is asked in pieces of nearby triangles, each a
//! pure function of the instance's triangles ([`PIECE`]), so the same holds. Many rays from one
//! point through one pyramid (a BSPVT tile's texels) first list the few pieces the pyramid can
//! meet ([`Occluders::view`], [`Frustum::narrow`]) and then ask only those, eight boxes at a time:
//! on a large level a ray no longer descends the whole terrain's BVH, nor the top-level tree.

use super::SceneBvh;
use super::beam::{self, Beam};
use super::top_level::{self, TopLevel};
use crate::math::sampling;
use crate::scene::Holes;
use glam::Vec3;
use std::ops::Range;
use wide::f32x8;

/// One instance: its pieces and, when it has few triangles, the triangles for a [`Beam`].
struct Part {
    /// Its pieces, `Occluders::pieces[pieces]`.
    pieces: Range<usize>,
    /// Its triangles when there are few enough for a [`Beam`], else empty.
    few: Vec<[Vec3; 3]>,
}

/// Nearby triangles of one instance behind their padded bounds: a BVH of their own.
struct Piece {
    lo: Vec3,
    hi: Vec3,
    bvh: SceneBvh,
    /// The instance it belongs to.
    owner: usize,
}

/// Triangles per piece at most. An instance with more (a terrain) is cut into pieces of nearby
/// triangles: a ray from a terrain vertex then descends a piece's shallow BVH near its start,
/// not the whole terrain's, and a pyramid of rays ([`Occluders::view`]) skips the pieces
/// it cannot meet. On the 1M-vertex level, 2048 baked 5 % faster than 1024 (which cut its
/// boulders in two) and as fast as 4096.
pub const PIECE: usize = 2048;

/// Per-instance BVHs answering any-hit queries together, behind a top-level tree over their
/// pieces' bounds (a ray visits the pieces whose boxes it meets, not every instance: the cost
/// of a ray grows with the log of the instance count).
pub struct Occluders {
    /// By instance; an instance with no triangles has no pieces.
    parts: Vec<Part>,
    /// Every instance's pieces, instance by instance.
    pieces: Vec<Piece>,
    /// The top-level tree over the pieces' boxes (all but the wide ones).
    tree: TopLevel,
    /// Pieces as wide as the scene, asked before the tree and kept out of it.
    wide: Vec<u32>,
}

impl Occluders {
    /// One BVH per triangle list, by instance index (all solid).
    pub fn new(instances: &[Vec<[Vec3; 3]>]) -> Self {
        Self::with(instances, &[], |_, t| SceneBvh::new(t))
    }

    /// [`Self::new`] with each piece's BVH from `bvh(index, triangles)` (an instance of at most
    /// [`PIECE`] triangles is one piece: its whole list): built, or restored from bytes a build
    /// wrote ([`SceneBvh::from_bytes`]), which answers alike; and cut by the list's holes
    /// (`holes[index]`; missing: solid).
    pub fn with(
        instances: &[Vec<[Vec3; 3]>],
        holes: &[Holes],
        bvh: impl Fn(usize, &[[Vec3; 3]]) -> SceneBvh + Sync,
    ) -> Self {
        use rayon::prelude::*;
        let solid = Holes::default();
        let holes = |i: usize| holes.get(i).unwrap_or(&solid);
        // Each instance's pieces, then their BVHs built in parallel (a terrain's many at once).
        let jobs: Vec<(usize, Option<Vec<u32>>)> =
            instances.iter().enumerate().flat_map(|(i, t)| pieces_of(t).into_iter().map(move |ids| (i, ids))).collect();
        let mut counts = vec![0; instances.len()];
        jobs.iter().for_each(|&(i, _)| counts[i] += 1);
        let pieces: Vec<Piece> = jobs
            .into_par_iter()
            .map(|(i, ids)| {
                let t = &instances[i];
                let (triangles, holes) = match ids {
                    None => (std::borrow::Cow::Borrowed(&t[..]), holes(i).clone()),
                    Some(ids) => {
                        let triangles = ids.iter().map(|&k| t[k as usize]).collect();
                        (triangles, holes(i).select(ids.iter().map(|&k| k as usize)))
                    }
                };
                let (lo, hi) = bounds(triangles.iter().flatten());
                // Padding keeps the box test conservative for rays that graze it.
                let pad = Vec3::splat(1e-4 * (hi - lo).length() + 1e-6);
                Piece { lo: lo - pad, hi: hi + pad, bvh: bvh(i, &triangles).cut(&holes), owner: i }
            })
            .collect();
        let mut first = 0;
        let parts = instances
            .iter()
            .zip(counts)
            .enumerate()
            .map(|(i, (t, count))| {
                first += count;
                // A beam sees whole triangles: a cut-out instance is always asked ray by ray.
                let few = if t.len() <= beam::MAX_TRIANGLES && holes(i).is_empty() { t.clone() } else { Vec::new() };
                Part { pieces: first - count..first, few }
            })
            .collect();
        let (wide, rest) = split_wide(&pieces);
        let tree = TopLevel::new(&pieces.iter().map(|p| (p.lo, p.hi)).collect::<Vec<_>>(), rest);
        Self { parts, pieces, tree, wide }
    }

    /// Whether instance `i`'s triangles alone block the segment as [`Self::occluded`] asks (any
    /// hit; an instance index out of range or with no triangles blocks nothing). With the other
    /// instances unchanged, it is how an edit to instance `i` changes [`Self::occluded`].
    pub fn occluded_by(&self, i: usize, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        let ray = self.ray(origin, dir, tmax);
        self.parts.get(i).is_some_and(|p| self.pieces[p.pieces.clone()].iter().any(|q| ray.blocked_by(q)))
    }

    /// A [`Beam`] over instance `i`'s triangles from `origin`, when it has a few (at most
    /// [`beam::MAX_TRIANGLES`]); where the beam answers, it answers as [`Self::occluded_by`].
    pub fn beam(&self, i: usize, origin: Vec3) -> Option<Beam> {
        let p = self.parts.get(i)?;
        (!p.few.is_empty()).then(|| Beam::new(origin, &p.few))
    }

    /// True when any instance blocks the segment from `origin` along unit `dir` within
    /// `[touching_distance(origin), tmax]` ([`super::touching_distance`]: what touches the ray's
    /// start does not block it).
    // Out of line: inlined into the cold bake's texel loop it ran 3–4 % slower (measured).
    #[inline(never)]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        self.occluded_if(origin, dir, tmax, |_| true)
    }

    /// [`Self::occluded`] by the instances `keep` accepts (by index) alone: as if the others
    /// were not there.
    #[inline]
    pub fn occluded_if(&self, origin: Vec3, dir: Vec3, tmax: f32, keep: impl Fn(usize) -> bool) -> bool {
        let ray = self.ray(origin, dir, tmax);
        let blocks = |i: u32| {
            let piece = &self.pieces[i as usize];
            keep(piece.owner) && ray.blocked_by(piece)
        };
        self.wide.iter().any(|&i| blocks(i)) || self.tree.any_along(origin, ray.inv, tmax, blocks)
    }

    /// The closest hit on the segment [`Self::occluded`] asks about. Of hits at the same
    /// distance on several pieces, the one on the piece the top-level walk lists first (wide
    /// pieces, then the tree's leaves in order), so the answer depends on the scene alone.
    pub fn closest(&self, origin: Vec3, dir: Vec3, tmax: f32) -> Option<super::PlaneHit> {
        self.closest_if(origin, dir, tmax, |_| true)
    }

    /// [`Self::closest`] among the instances `keep` accepts (by index). The pieces the segment
    /// meets are searched nearest entry first, and none entered past the best hit so far: in a
    /// room most walls' boxes meet a ray, and a far wall's BVH need not be searched once a near
    /// one has answered. A piece searched after the best hit looks up to it inclusive, so a tie
    /// goes to the piece listed first, whatever the search order.
    pub fn closest_if(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        keep: impl Fn(usize) -> bool,
    ) -> Option<super::PlaneHit> {
        let ray = self.ray(origin, dir, tmax);
        // (entry, place in the walk's list, piece)
        let mut met: Vec<(f32, u32, u32)> = Vec::with_capacity(8);
        let mut enter = |i: u32| {
            let piece = &self.pieces[i as usize];
            if keep(piece.owner) {
                self.enter(&ray, i, &mut met);
            }
            false
        };
        self.wide.iter().for_each(|&i| {
            enter(i);
        });
        self.tree.any_along(origin, ray.inv, tmax, &mut enter);
        self.nearest(&ray, met)
    }

    /// [`Self::closest`] for a ray from `view`'s apex whose direction lies inside the pyramid
    /// `view` was made for: the same answer, from the pieces `view` lists. They include every
    /// piece whose box the segment meets, and list them in the top-level walk's order, so ties
    /// go as [`Self::closest`] breaks them; no walk of the tree per ray.
    pub fn closest_among(&self, view: &Frustum, dir: Vec3, tmax: f32) -> Option<super::PlaneHit> {
        let ray = self.ray(view.apex, dir, tmax);
        let mut met: Vec<(f32, u32, u32)> = Vec::with_capacity(8);
        view.ids.iter().for_each(|&i| self.enter(&ray, i, &mut met));
        self.nearest(&ray, met)
    }

    /// Lists piece `i` in `met` as (entry, place in the list, piece) when `ray` meets its box.
    #[inline]
    fn enter(&self, ray: &Ray, i: u32, met: &mut Vec<(f32, u32, u32)>) {
        let piece = &self.pieces[i as usize];
        if let Some(t) = slab_entry(ray.origin, ray.inv, ray.tmax, piece.lo, piece.hi) {
            met.push((t, met.len() as u32, i));
        }
    }

    /// The closest hit of `ray` on the pieces `met` lists, searched nearest entry first (ties
    /// to the one listed first; see [`Self::closest_if`]).
    fn nearest(&self, ray: &Ray, mut met: Vec<(f32, u32, u32)>) -> Option<super::PlaneHit> {
        met.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut best = None::<(super::PlaneHit, u32)>;
        for (entry, listed, i) in met {
            let end = best.map_or(ray.tmax, |(b, _)| b.t);
            if entry > end {
                break;
            }
            let end = if best.is_some() { end.next_up() } else { end };
            if let Some(hit) = self.pieces[i as usize].bvh.closest_between(ray.origin, ray.dir, ray.near, end)
                && best.is_none_or(|(b, first)| (hit.t, listed) < (b.t, first))
            {
                best = Some((hit, listed));
            }
        }
        best.map(|(h, _)| h)
    }

    /// [`SceneBvh::inside`] among the instances `keep` accepts (by index): whether most of
    /// [`super::INSIDE_RAYS`] rays over `p`'s hemisphere first meet one of their triangles from
    /// behind.
    pub fn inside_if(&self, p: Vec3, n: Vec3, keep: impl Fn(usize) -> bool) -> bool {
        let frame = crate::math::frame::Frame::from_normal(n);
        let rays = super::INSIDE_RAYS;
        let behind = (0..rays)
            .filter(|&k| {
                let d = frame.to_world(sampling::cosine_hemisphere(sampling::hammersley(k, rays)));
                // `PlaneHit::normal` is obvhs' negated geometric normal: from behind, n · d < 0.
                self.closest_if(super::offset_ray_origin(p, n, d), d, f32::MAX, &keep)
                    .is_some_and(|hit| hit.normal.dot(d) < 0.0)
            })
            .count();
        2 * behind >= rays as usize
    }

    /// The pieces that a ray from `apex` may meet while its direction `d` stays inside the
    /// pyramid `planes · d ≥ −slack` (`planes` unit inward normals of planes through `apex`),
    /// found by one walk of the top-level tree: those whose boxes are not wholly outside one of
    /// the planes ([`outside_none`]). Narrower pyramids inside it cut their own lists from it
    /// ([`Frustum::narrow`]).
    pub fn view(&self, apex: Vec3, planes: &[Vec3], slack: f32) -> Frustum {
        let keeps = |i: &&u32| {
            let p = &self.pieces[**i as usize];
            outside_none(apex, planes, slack, p.lo, p.hi)
        };
        let mut ids: Vec<u32> = self.wide.iter().filter(keeps).copied().collect();
        self.tree.each_within(
            |lo, hi| outside_none(apex, planes, slack, lo, hi),
            |leaf| {
                ids.extend(leaf.iter().filter(keeps));
                false
            },
        );
        Frustum::new(apex, ids.iter().map(|&i| (i, &self.pieces[i as usize])))
    }

    /// [`Self::occluded`] for a ray from `view`'s apex that only the pieces `view` lists may
    /// block: its direction inside the pyramid `view` was made for.
    #[inline(never)]
    pub fn occluded_among(&self, view: &Frustum, dir: Vec3, tmax: f32) -> bool {
        let ray = self.ray(view.apex, dir, tmax);
        view.boxes.iter().zip(view.ids.chunks(LANES)).any(|(boxes, ids)| {
            let mut met = boxes.met_by(ray.inv, tmax);
            while met != 0 {
                let piece = &self.pieces[ids[met.trailing_zeros() as usize] as usize];
                if piece.bvh.occluded_between(ray.origin, ray.dir, ray.near, ray.tmax) {
                    return true;
                }
                met &= met - 1;
            }
            false
        })
    }

    /// A query's ray.
    fn ray(&self, origin: Vec3, dir: Vec3, tmax: f32) -> Ray {
        Ray { origin, dir, inv: dir.recip(), near: super::touching_distance(origin), tmax }
    }
}

/// Whether a box is not wholly outside one of the planes `m · (x − apex) ≥ −slack·|x − apex|`:
/// its corner farthest inside each plane is inside it, within `slack` times the box's farthest
/// distance from `apex` (a bound on every point's) and the rounding of the sum.
fn outside_none(apex: Vec3, planes: &[Vec3], slack: f32, lo: Vec3, hi: Vec3) -> bool {
    let (a, b) = (lo - apex, hi - apex);
    let reach = slack * a.abs().max(b.abs()).length();
    planes.iter().all(|&m| {
        let (x, y) = (a * m, b * m);
        x.max(y).element_sum() + reach >= -1e-5 * (x.abs().max(y.abs())).element_sum()
    })
}

/// The pieces rays from one apex inside one pyramid may meet ([`Occluders::view`]; for BSPVT, a
/// vertex's hemisphere, one cube face of it, one tile of a face), with their boxes relative to
/// the apex [`LANES`] at a time: a narrower pyramid's list is cut from it eight boxes per test,
/// and a ray tests eight boxes at once.
pub struct Frustum {
    apex: Vec3,
    /// The pieces, in the order the tree found them.
    ids: Vec<u32>,
    /// `ids[LANES·k..]`'s boxes less the apex, in `boxes[k]`.
    boxes: Vec<Boxes>,
}

impl Frustum {
    /// The view from `apex` of the `(index, piece)`s.
    fn new<'a>(apex: Vec3, pieces: impl Iterator<Item = (u32, &'a Piece)>) -> Self {
        let (ids, corners): (Vec<u32>, Vec<(Vec3, Vec3)>) =
            pieces.map(|(i, p)| (i, (p.lo - apex, p.hi - apex))).unzip();
        Self { apex, ids, boxes: corners.chunks(LANES).map(|c| Boxes::new(c.iter().copied())).collect() }
    }

    /// The pieces listed that a ray from the apex may meet while its direction `d` stays
    /// inside the pyramid `planes · d ≥ −slack` too: every piece [`outside_none`] keeps, and
    /// perhaps a few more.
    pub fn narrow(&self, planes: &[Vec3], slack: f32) -> Frustum {
        let mut kept = Vec::new();
        for (k, b) in self.boxes.iter().enumerate() {
            let mut lanes = b.inside(planes, slack);
            while lanes != 0 {
                kept.push(k * LANES + lanes.trailing_zeros() as usize);
                lanes &= lanes - 1;
            }
        }
        let corner = |v: usize| self.boxes[v / LANES].corners(v % LANES);
        Self {
            apex: self.apex,
            ids: kept.iter().map(|&v| self.ids[v]).collect(),
            boxes: kept.chunks(LANES).map(|c| Boxes::new(c.iter().map(|&v| corner(v)))).collect(),
        }
    }

    /// How many pieces it lists.
    pub fn len(&self) -> usize {
        self.ids.len()
    }

    /// Whether it lists none.
    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }
}

/// Boxes tested together (one AVX register of `f32`s per coordinate).
const LANES: usize = 8;

/// Up to [`LANES`] boxes, coordinate by coordinate, relative to a view's apex.
struct Boxes {
    lo: [f32x8; 3],
    hi: [f32x8; 3],
    /// Each box's farthest distance from the apex (a bound on every point's).
    reach: f32x8,
    /// Bit `l` set when lane `l` holds a box.
    used: u32,
}

impl Boxes {
    /// The boxes `(lo, hi)` (at most [`LANES`]).
    fn new(boxes: impl Iterator<Item = (Vec3, Vec3)>) -> Self {
        let (mut lo, mut hi, mut used) = ([[0.0; LANES]; 3], [[0.0; LANES]; 3], 0);
        for (l, (a, b)) in boxes.enumerate() {
            for k in 0..3 {
                (lo[k][l], hi[k][l]) = (a[k], b[k]);
            }
            used |= 1 << l;
        }
        let (lo, hi) = (lo.map(f32x8::new), hi.map(f32x8::new));
        let far = |k: usize| lo[k].abs().fast_max(hi[k].abs());
        let reach = (far(0) * far(0) + far(1) * far(1) + far(2) * far(2)).sqrt();
        Self { lo, hi, reach, used }
    }

    /// Lane `l`'s box.
    fn corners(&self, l: usize) -> (Vec3, Vec3) {
        let at = |v: &[f32x8; 3]| Vec3::from_array(v.map(|c| c.as_array()[l]));
        (at(&self.lo), at(&self.hi))
    }

    /// Bit `l` set when lane `l`'s box is not wholly outside one of the planes: [`outside_none`]
    /// in every lane at once, its rounding bound `1e-5·Σ|mₖ|·farₖ` replaced by the larger
    /// `2e-5·reach` (Cauchy–Schwarz), so that it keeps every box `outside_none` keeps.
    #[inline]
    fn inside(&self, planes: &[Vec3], slack: f32) -> u32 {
        let bound = self.reach * f32x8::splat(slack + 2e-5);
        planes.iter().fold(self.used, |kept, m| {
            let along = |k: usize| {
                let m = f32x8::splat(m[k]);
                (self.lo[k] * m).fast_max(self.hi[k] * m)
            };
            kept & (along(0) + along(1) + along(2) + bound).simd_ge(f32x8::ZERO).to_bitmask()
        })
    }

    /// Bit `l` set when the ray from the apex along the direction whose reciprocal is `inv`
    /// meets lane `l`'s box within `[0, tmax]`, as [`slab_hits`] says or more: where an axis's
    /// distances are NaN (0·∞) it is ignored, as `slab_hits` ignores it.
    #[inline]
    fn met_by(&self, inv: Vec3, tmax: f32) -> u32 {
        let (mut near, mut far) = (f32x8::ZERO, f32x8::splat(tmax));
        for k in 0..3 {
            let inv = f32x8::splat(inv[k]);
            let (t1, t2) = (self.lo[k] * inv, self.hi[k] * inv);
            // AVX's min and max return their second operand where either is NaN.
            (near, far) = (t1.fast_min(t2).fast_max(near), t1.fast_max(t2).fast_min(far));
        }
        near.simd_le(far).to_bitmask() & self.used
    }
}

/// A segment as the queries test it.
struct Ray {
    origin: Vec3,
    dir: Vec3,
    /// The reciprocal of `dir`.
    inv: Vec3,
    /// What is nearer does not block it ([`super::touching_distance`]).
    near: f32,
    tmax: f32,
}

impl Ray {
    /// Whether one of `piece`'s triangles blocks it.
    #[inline]
    fn blocked_by(&self, piece: &Piece) -> bool {
        slab_hits(self.origin, self.inv, self.tmax, piece.lo, piece.hi)
            && piece.bvh.occluded_between(self.origin, self.dir, self.near, self.tmax)
    }
}

/// The bounds of `points`.
fn bounds<'a>(points: impl Iterator<Item = &'a Vec3>) -> (Vec3, Vec3) {
    points.fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| (lo.min(*p), hi.max(*p)))
}

/// A triangle list's pieces ([`PIECE`]): `[None]` for a list of at most [`PIECE`] (one piece,
/// the whole list), else each piece's triangle indices, ascending. Pieces come from median
/// splits of the triangles' centroids along the longest axis of their bounds, ties by index:
/// a pure function of the triangles, so a warm bake's pieces are a cold one's.
fn pieces_of(triangles: &[[Vec3; 3]]) -> Vec<Option<Vec<u32>>> {
    if triangles.is_empty() {
        return Vec::new();
    }
    if triangles.len() <= PIECE {
        return vec![None];
    }
    let centre = |k: u32| triangles[k as usize].iter().sum::<Vec3>();
    let mut ids: Vec<u32> = (0..triangles.len() as u32).collect();
    let mut out = Vec::new();
    let mut todo = vec![&mut ids[..]];
    while let Some(ids) = todo.pop() {
        if ids.len() <= PIECE {
            let mut piece = ids.to_vec();
            piece.sort_unstable();
            out.push(Some(piece));
            continue;
        }
        let mid = top_level::halve(ids, centre);
        let (a, b) = ids.split_at_mut(mid);
        todo.extend([b, a]);
    }
    out
}

/// The pieces whose box spans at least half the scene along two axes (a terrain too small to
/// be cut into pieces, among more than a couple of others), and the rest. A wide piece in the
/// tree would widen every node above it to the whole scene, and every ray from inside it would
/// descend that whole path: asked apart, before the tree, it costs one box test and its own BVH.
fn split_wide(pieces: &[Piece]) -> (Vec<u32>, Vec<u32>) {
    let (lo, hi) = pieces.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| (lo.min(p.lo), hi.max(p.hi)));
    let (scene, many) = (hi - lo, pieces.len() > 2);
    let wide = |i: &u32| {
        let e = pieces[*i as usize].hi - pieces[*i as usize].lo;
        many && (0..3).filter(|&k| e[k] >= 0.5 * scene[k]).count() >= 2
    };
    (0..pieces.len() as u32).partition(wide)
}

/// Ray–box slab test for the segment from `o` within `[0, tmax]`, `inv` the reciprocal
/// direction (NaNs from 0·∞ are ignored by `max`/`min`).
pub(crate) fn slab_hits(o: Vec3, inv: Vec3, tmax: f32, lo: Vec3, hi: Vec3) -> bool {
    slab_entry(o, inv, tmax, lo, hi).is_some()
}

/// Where the segment of [`slab_hits`] enters the box (0 when it starts inside), if it meets it.
fn slab_entry(o: Vec3, inv: Vec3, tmax: f32, lo: Vec3, hi: Vec3) -> Option<f32> {
    let (t1, t2) = ((lo - o) * inv, (hi - o) * inv);
    let near = t1.min(t2).max_element().max(0.0);
    let far = t1.max(t2).min_element().min(tmax);
    (near <= far).then_some(near)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn answers_like_one_bvh_over_everything() {
        let quad = |c: Vec3| {
            let (a, b, d, e) = (
                c + Vec3::new(-0.5, 0.0, -0.5),
                c + Vec3::new(0.5, 0.0, -0.5),
                c + Vec3::new(0.5, 0.0, 0.5),
                c + Vec3::new(-0.5, 0.0, 0.5),
            );
            vec![[a, b, d], [a, d, e]]
        };
        answers_alike(&[quad(Vec3::new(0.0, 1.0, 0.0)), quad(Vec3::new(2.0, 2.0, 0.0)), Vec::new()]);
        // Enough instances for a deep top-level tree, some empty, on a field wider than tall.
        let mut r = crate::math::rng::seeded(7);
        let field: Vec<_> = (0..500)
            .map(|k| {
                use rand::Rng;
                let c = Vec3::new(r.random_range(-20.0..20.0), r.random_range(0.5..2.0), r.random_range(-20.0..20.0));
                if k % 17 == 0 { Vec::new() } else { quad(c) }
            })
            .collect();
        answers_alike(&field);
        // With a part as wide as the field (a sheet over most of it), asked apart from the tree.
        let mut covered = field.clone();
        let (a, b, c, d) = (
            Vec3::new(-20.0, 3.0, -20.0),
            Vec3::new(5.0, 2.5, -20.0),
            Vec3::new(5.0, 2.5, 20.0),
            Vec3::new(-20.0, 3.0, 20.0),
        );
        covered.push(vec![[a, b, c], [a, c, d]]);
        assert_eq!(Occluders::new(&covered).wide.len(), 1, "the sheet is wide, the quads are not");
        answers_alike(&covered);
        // With a terrain of two pieces under the quads.
        let quads = field.iter().filter(|p| !p.is_empty()).count();
        let mut hilly = field;
        hilly.push(terrain(-20.0, 40.0, 40));
        assert_eq!(Occluders::new(&hilly).pieces.len(), quads + 2, "the terrain's 3200 triangles are cut in two");
        answers_alike(&hilly);
    }

    /// An `n × n` grid of rolling ground from `(at, at)`, `side` wide, about 0.4 high.
    fn terrain(at: f32, side: f32, n: usize) -> Vec<[Vec3; 3]> {
        crate::accel::grid_triangles(n, |i, j| {
            let (x, z) = (at + side * i as f32 / n as f32, at + side * j as f32 / n as f32);
            Vec3::new(x, 0.2 * (0.7 * x).sin() * (0.5 * z).cos() - 0.1, z)
        })
    }

    /// Pieces hold every triangle once, at most [`PIECE`] each, in ascending order, as compact
    /// boxes (a quarter of the terrain's area each, not strips), and the same on every call.
    #[test]
    fn pieces_hold_every_triangle_once_and_lie_together() {
        let t = terrain(0.0, 40.0, 64);
        let pieces: Vec<Vec<u32>> = pieces_of(&t).into_iter().map(|p| p.expect("cut")).collect();
        assert_eq!(pieces.len(), 4, "8192 triangles in pieces of at most {PIECE}");
        let mut all: Vec<u32> = pieces.concat();
        all.sort_unstable();
        assert_eq!(all, (0..t.len() as u32).collect::<Vec<_>>());
        for p in &pieces {
            assert!(p.len() <= PIECE && p.is_sorted());
            let (lo, hi) = bounds(p.iter().flat_map(|&k| &t[k as usize]));
            let e = hi - lo;
            assert!(e.x <= 21.0 && e.z <= 21.0, "a quarter of 40 × 40: {e}");
        }
        assert_eq!(pieces_of(&t), pieces.into_iter().map(Some).collect::<Vec<_>>());
        assert_eq!(pieces_of(&t[..PIECE]), vec![None], "one piece: the whole list");
        assert!(pieces_of(&[]).is_empty());
    }

    /// Rays from one point inside a pyramid (or within its slack) get the same answers (any hit
    /// and closest hit) from the pieces its view lists as from every instance, whether the view is made for the pyramid
    /// ([`Occluders::view`]) or cut from a wider one ([`Frustum::narrow`]); the lists hold every
    /// piece the scalar test keeps and leave most pieces out.
    #[test]
    fn a_pyramid_of_rays_meets_only_what_it_sees() {
        use rand::Rng;
        let mut r = crate::math::rng::seeded(5);
        let mut parts: Vec<Vec<[Vec3; 3]>> = (0..300)
            .map(|_| {
                let c = Vec3::new(r.random_range(-20.0..20.0), r.random_range(0.0..1.0), r.random_range(-20.0..20.0));
                let s = r.random_range(0.2..1.0);
                vec![[c, c + Vec3::new(s, 0.5, 0.0), c + Vec3::new(0.0, s, s)]]
            })
            .collect();
        parts.push(terrain(-20.0, 40.0, 40));
        let occ = Occluders::new(&parts);
        let (mut listed, mut hits, mut n) = (0, 0, 0);
        for _ in 0..400 {
            let apex = Vec3::new(r.random_range(-18.0..18.0), 0.3, r.random_range(-18.0..18.0));
            let axis =
                Vec3::new(r.random_range(-1.0..1.0), r.random_range(-0.2..1.5), r.random_range(-1.0..1.0)).normalize();
            let (u, v) = axis.any_orthonormal_pair();
            let (w, slack) = (r.random_range(0.02..0.3), [0.0, 0.1][r.random_range(0..2)]);
            // Inward normals of the planes through the apex and the edges of the square of
            // half-width w around `axis`, a unit in front of it.
            let sides = [(u, v), (-u, v), (v, u), (-v, u)].map(|(m, along)| {
                let n = (axis + m * w).cross(along).normalize();
                if n.dot(axis) < 0.0 { -n } else { n }
            });
            let made = occ.view(apex, &sides, slack);
            let cut = occ.view(apex, &[axis], slack).narrow(&sides, slack);
            let all_planes = [sides[0], sides[1], sides[2], sides[3], axis];
            for (view, planes) in [(&made, &sides[..]), (&cut, &all_planes[..])] {
                let scalar = (0..occ.pieces.len() as u32).filter(|&i| {
                    outside_none(apex, planes, slack, occ.pieces[i as usize].lo, occ.pieces[i as usize].hi)
                });
                assert!(scalar.into_iter().all(|i| view.ids.contains(&i)), "{apex} {axis} {w} {slack}");
            }
            listed += made.len() + cut.len();
            for _ in 0..50 {
                let d =
                    (axis + u * r.random_range(-1.5 * w..1.5 * w) + v * r.random_range(-1.5 * w..1.5 * w)).normalize();
                if sides.iter().any(|m| m.dot(d) < -slack) {
                    continue;
                }
                let all = occ.occluded(apex, d, f32::INFINITY);
                assert_eq!(occ.occluded_among(&made, d, f32::INFINITY), all, "{apex} {d} {slack}");
                assert_eq!(occ.occluded_among(&cut, d, f32::INFINITY), all, "{apex} {d} {slack}: cut");
                let closest = occ.closest(apex, d, f32::INFINITY);
                assert_eq!(occ.closest_among(&made, d, f32::INFINITY), closest, "{apex} {d} {slack}: closest");
                assert_eq!(occ.closest_among(&cut, d, f32::INFINITY), closest, "{apex} {d} {slack}: closest, cut");
                (hits, n) = (hits + usize::from(all), n + 1);
            }
        }
        assert!(hits > n / 20 && hits < n, "{hits} of {n} rays blocked: the test tests nothing");
        assert!(listed < 2 * 400 * occ.pieces.len() / 10, "{listed} pieces listed");
    }

    /// Eight boxes at once meet every box the scalar slab test meets, and otherwise answer as it
    /// does but where a ray runs along a box's face through the apex (rays along an axis, boxes
    /// with a face on the apex's planes included).
    #[test]
    fn lanes_meet_what_the_slab_test_meets() {
        use rand::Rng;
        let mut r = crate::math::rng::seeded(9);
        let apex = Vec3::new(0.5, 0.25, -1.0);
        let (mut n, mut differ) = (0, 0);
        for _ in 0..2000 {
            let boxes: Vec<(Vec3, Vec3)> = (0..r.random_range(1..=LANES))
                .map(|_| {
                    let c = Vec3::new(r.random_range(-4.0..4.0), r.random_range(-4.0..4.0), r.random_range(-4.0..4.0));
                    let mut snap = |x: f32| if r.random_range(0..4) == 0 { x.round() } else { x };
                    let c = Vec3::new(snap(c.x), snap(c.y), snap(c.z));
                    (c, c + Vec3::new(r.random_range(0.0..2.0), r.random_range(0.0..2.0), r.random_range(0.0..2.0)))
                })
                .collect();
            let lanes = Boxes::new(boxes.iter().map(|&(lo, hi)| (lo - apex, hi - apex)));
            let mut d = Vec3::new(r.random_range(-1.0..1.0), r.random_range(-1.0..1.0), r.random_range(-1.0..1.0));
            d[r.random_range(0..3usize)] *= f32::from(r.random_range(0..3u8) != 0);
            let d = d.normalize_or(Vec3::X);
            let tmax = [f32::INFINITY, r.random_range(0.0..6.0)][r.random_range(0..2)];
            let met = lanes.met_by(d.recip(), tmax);
            for (l, &(lo, hi)) in boxes.iter().enumerate() {
                let (lane, scalar) = (met >> l & 1 == 1, slab_hits(apex, d.recip(), tmax, lo, hi));
                assert!(lane || !scalar, "{d} {tmax} {lo} {hi}: the slab test meets it");
                let on_face = (0..3).any(|k| d[k] == 0.0 && (lo[k] == apex[k] || hi[k] == apex[k]));
                assert!(lane == scalar || on_face, "{d} {tmax} {lo} {hi}");
                (n, differ) = (n + 1, differ + usize::from(lane != scalar));
            }
        }
        assert!(differ < n / 100, "{differ} of {n} boxes answered otherwise");
    }

    /// A floor point on the line where a box rests on the floor lies in the plane of the box's
    /// side: a ray leaving along that side, away from the box, is not blocked by it however the
    /// side rounds, and a ray into the box is — for BSPVT's occluders,
    /// and for a scene BVH's shadow rays and closest hits from surface points.
    #[test]
    fn what_touches_a_rays_start_does_not_block_it() {
        for x in [0.5f32, 0.5 + f32::EPSILON, 0.5 - f32::EPSILON / 2.0] {
            let (lo, hi) = (Vec3::new(-0.5, 0.0, -0.5), Vec3::new(x, 1.0, 0.5));
            let cuboid = crate::scene::shapes::cuboid(0.5 * (hi - lo));
            let corner = |i: u32| cuboid.positions[i as usize] + 0.5 * (lo + hi);
            let triangles: Vec<[Vec3; 3]> = cuboid.triangles.iter().map(|t| t.map(corner)).collect();
            let (bvh, occ) = (SceneBvh::new(&triangles), Occluders::new(&[triangles]));
            let p = super::super::offset_ray_origin(Vec3::new(0.5, 0.0, 0.1), Vec3::Y, Vec3::Y);
            for k in 1..16 {
                let up = k as f32 / 16.0;
                let away = Vec3::new(1.0, up, 0.2).normalize();
                assert!(!occ.occluded(p, away, f32::INFINITY), "side at {x}: away along {away}");
                assert!(!bvh.occluded_past_touching(p, away, f32::INFINITY), "side at {x}: away along {away}");
                assert!(bvh.closest_hit_past_touching(p, away, f32::INFINITY).is_none(), "side at {x}: {away}");
                let into = Vec3::new(-1.0, up, 0.2).normalize();
                assert!(occ.occluded(p, into, f32::INFINITY), "side at {x}: into the box along {into}");
                assert!(bvh.occluded_past_touching(p, into, f32::INFINITY), "side at {x}: into along {into}");
                // The side where the ray enters it (when the side rounds to the start's near
                // side), else the far side from inside.
                let met = bvh.closest_hit_past_touching(p, into, f32::INFINITY).map(|h| h.t);
                assert!(
                    met.is_some_and(|t| !(1e-3..=0.5).contains(&t)),
                    "side at {x}: into along {into} meets {met:?}"
                );
            }
        }
    }

    fn answers_alike(parts: &[Vec<[Vec3; 3]>]) {
        let occ = Occluders::new(parts);
        let all = SceneBvh::new(&parts.concat());
        let mut r = crate::math::rng::seeded(3);
        let (mut hits, n) = (0, 5000);
        for _ in 0..n {
            use rand::Rng;
            let o = Vec3::new(r.random_range(-20.0..20.0), 0.0, r.random_range(-20.0..20.0));
            let d =
                Vec3::new(r.random_range(-1.0..1.0), r.random_range(0.01..1.0), r.random_range(-1.0..1.0)).normalize();
            let any = all.occluded_past_touching(o, d, f32::INFINITY);
            hits += usize::from(any);
            assert_eq!(occ.occluded(o, d, f32::INFINITY), any, "{o} {d}");
            assert_eq!((0..parts.len()).any(|i| occ.occluded_by(i, o, d, f32::INFINITY)), any, "{o} {d}: by instance");
            // The closest hit, pieces searched nearest first, is the one BVH's.
            let near = super::super::touching_distance(o);
            let (ours, one) = (occ.closest(o, d, f32::INFINITY), all.closest_between(o, d, near, f32::INFINITY));
            assert_eq!(ours.is_some(), any, "{o} {d}: closest");
            if let (Some(a), Some(b)) = (ours, one) {
                assert!((a.t - b.t).abs() <= 1e-5 * b.t.max(1.0) && a.normal == b.normal, "{o} {d}: {a:?} vs {b:?}");
            }
        }
        assert!(hits > 0 && hits < n, "{hits} of {n} rays blocked: the test tests nothing");
    }
}
