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
//! meet ([`Occluders::seen_from`]) and then ask only those: on a large level a ray no longer
//! descends the whole terrain's BVH and the top-level tree near its start.

use super::SceneBvh;
use super::beam::{self, Beam};
use super::top_level::{self, TopLevel};
use crate::scene::Holes;
use glam::Vec3;
use std::ops::Range;

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
}

/// Triangles per piece at most. An instance with more (a terrain) is cut into pieces of nearby
/// triangles: a ray from a terrain vertex then descends a piece's shallow BVH near its start,
/// not the whole terrain's, and a pyramid of rays ([`Occluders::seen_from`]) skips the pieces
/// it cannot meet. On the 1M-vertex level, 2048 baked 5 % faster than 1024 (which cut its
/// boulders in two) and as fast as 4096.
pub const PIECE: usize = 2048;

/// Pieces [`Occluders::seen_from`] returns at most: past them, asking the top-level tree ray
/// by ray costs less than asking every piece (8 and 32, with 32 and 128 visits, baked the
/// 1M-vertex level's eighth 8 % and 4 % slower).
pub const MAX_SEEN: usize = 16;

/// Nodes of the top-level tree [`Occluders::seen_from`] visits at most.
pub const MAX_VISITS: usize = 64;

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
                Piece { lo: lo - pad, hi: hi + pad, bvh: bvh(i, &triangles).cut(&holes) }
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
        let ray = self.ray(origin, dir, tmax);
        let blocks = |i: u32| ray.blocked_by(&self.pieces[i as usize]);
        self.wide.iter().any(|&i| blocks(i)) || self.tree.any_along(origin, ray.inv, tmax, blocks)
    }

    /// The pieces that a ray from `apex` may meet while its direction `d` stays inside the
    /// pyramid `sides · d ≥ −slack` (`sides` unit inward normals of planes through `apex`):
    /// those whose boxes are not wholly outside one of the planes. `None` when there are more
    /// than [`MAX_SEEN`], or finding them would visit more than [`MAX_VISITS`] nodes of the
    /// top-level tree: then asking the tree ray by ray costs less.
    pub fn seen_from(&self, apex: Vec3, sides: &[Vec3; 4], slack: f32) -> Option<Seen> {
        // A box is outside a plane when its corner farthest inside is outside by more than
        // `slack` times the box's farthest distance (a bound on every point's), and by more
        // than the rounding of the sum.
        let inside = |lo: Vec3, hi: Vec3| {
            let (a, b) = (lo - apex, hi - apex);
            let reach = slack * a.abs().max(b.abs()).length();
            sides.iter().all(|&m| {
                let (x, y) = (a * m, b * m);
                x.max(y).element_sum() + reach >= -1e-5 * (x.abs().max(y.abs())).element_sum()
            })
        };
        let piece = |&i: &u32| inside(self.pieces[i as usize].lo, self.pieces[i as usize].hi);
        let mut seen: Vec<u32> = self.wide.iter().copied().filter(piece).collect();
        let all = self.tree.each_within(inside, MAX_VISITS, |leaf| {
            seen.extend(leaf.iter().copied().filter(piece));
            seen.len() > MAX_SEEN
        });
        all.then_some(Seen(seen))
    }

    /// [`Self::occluded`] for a ray that only the pieces `seen` lists may block (see
    /// [`Self::seen_from`]).
    #[inline(never)]
    pub fn occluded_among(&self, seen: &Seen, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        let ray = self.ray(origin, dir, tmax);
        seen.0.iter().any(|&i| ray.blocked_by(&self.pieces[i as usize]))
    }

    /// A query's ray.
    fn ray(&self, origin: Vec3, dir: Vec3, tmax: f32) -> Ray {
        Ray { origin, dir, inv: dir.recip(), near: super::touching_distance(origin), tmax }
    }
}

/// The pieces rays from one apex within one pyramid may meet (see [`Occluders::seen_from`]).
pub struct Seen(Vec<u32>);

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
    let (t1, t2) = ((lo - o) * inv, (hi - o) * inv);
    let near = t1.min(t2).max_element().max(0.0);
    let far = t1.max(t2).min_element().min(tmax);
    near <= far
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

    /// Rays from one point inside a pyramid (or within its slack) get the same answers from the
    /// pieces [`Occluders::seen_from`] lists as from every instance; the list leaves most pieces
    /// out, and a pyramid that sees too many gets none.
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
        let (mut listed, mut too_many, mut hits, mut n) = (0, 0, 0, 0);
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
            let Some(seen) = occ.seen_from(apex, &sides, slack) else {
                too_many += 1;
                continue;
            };
            listed += seen.0.len();
            for _ in 0..50 {
                let d =
                    (axis + u * r.random_range(-1.5 * w..1.5 * w) + v * r.random_range(-1.5 * w..1.5 * w)).normalize();
                if sides.iter().any(|m| m.dot(d) < -slack) {
                    continue;
                }
                let all = occ.occluded(apex, d, f32::INFINITY);
                assert_eq!(occ.occluded_among(&seen, apex, d, f32::INFINITY), all, "{apex} {d} {slack}");
                (hits, n) = (hits + usize::from(all), n + 1);
            }
        }
        assert!(hits > n / 20 && hits < n, "{hits} of {n} rays blocked: the test tests nothing");
        assert!(too_many > 0 && too_many < 200, "{too_many} of 400 pyramids saw too many pieces");
        assert!(listed < (400 - too_many) * occ.pieces.len() / 20, "{listed} pieces listed");
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
        }
        assert!(hits > 0 && hits < n, "{hits} of {n} rays blocked: the test tests nothing");
    }
}
