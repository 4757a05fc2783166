//! Occluders as one BVH per instance, queried together behind a bounds test.
//!
//! A ray's answer against one instance depends on that instance's triangles alone — never on
//! how a single scene-wide BVH happened to group them — so moving, adding or removing an
//! instance cannot change any ray's result against the others, even for rays that graze a
//! surface (where a BVH's box tests can go either way). Incremental BSPVT re-bakes rely on it
//! to reproduce a cold bake's bytes.

use super::SceneBvh;
use super::beam::{self, Beam};
use crate::scene::Holes;
use glam::Vec3;

/// One instance: its padded bounds and BVH.
struct Part {
    lo: Vec3,
    hi: Vec3,
    bvh: SceneBvh,
    /// Its triangles when there are few enough for a [`Beam`], else empty.
    few: Vec<[Vec3; 3]>,
}

/// A node of the top-level tree over the instances' bounds.
struct Node {
    /// Bounds holding the node's parts' (padded again: strictly larger, so a ray meeting a part's
    /// box always meets its ancestors' boxes, whatever the rounding).
    lo: Vec3,
    hi: Vec3,
    /// A leaf's parts are `order[start..start + count]`; an inner node (`count` 0) has its
    /// children at `start` and `start + 1`.
    start: u32,
    count: u32,
}

/// Instances per leaf of the top-level tree at most.
const LEAF: usize = 2;

/// Per-instance BVHs answering any-hit queries together, behind a top-level tree over their
/// bounds (a ray visits the instances whose boxes it meets, not every instance: the cost of a
/// ray grows with the log of the instance count).
pub struct Occluders {
    /// By instance; `None` for an instance with no triangles.
    parts: Vec<Option<Part>>,
    /// The top-level tree, root first (empty without parts).
    nodes: Vec<Node>,
    /// Part indices in the tree's leaf order.
    order: Vec<u32>,
    /// Parts as wide as the scene (a terrain), asked before the tree and kept out of it.
    wide: Vec<u32>,
}

impl Occluders {
    /// One BVH per triangle list, by instance index (all solid).
    pub fn new(instances: &[Vec<[Vec3; 3]>]) -> Self {
        Self::with(instances, &[], |_, t| SceneBvh::new(t))
    }

    /// [`Self::new`] with each non-empty list's BVH from `bvh(index, triangles)`: built, or
    /// restored from bytes a build wrote ([`SceneBvh::from_bytes`]), which answers alike; and
    /// cut by the list's holes (`holes[index]`; missing: solid).
    pub fn with(
        instances: &[Vec<[Vec3; 3]>],
        holes: &[Holes],
        mut bvh: impl FnMut(usize, &[[Vec3; 3]]) -> SceneBvh,
    ) -> Self {
        let parts = instances
            .iter()
            .enumerate()
            .map(|(i, t)| {
                (!t.is_empty()).then(|| {
                    let (lo, hi) =
                        t.iter().flatten().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
                    // Padding keeps the box test conservative for rays that graze it.
                    let pad = Vec3::splat(1e-4 * (hi - lo).length() + 1e-6);
                    let holes = holes.get(i).cloned().unwrap_or_default();
                    // A beam sees whole triangles: a cut-out instance is always asked ray by ray.
                    let few = if t.len() <= beam::MAX_TRIANGLES && holes.is_empty() { t.clone() } else { Vec::new() };
                    Part { lo: lo - pad, hi: hi + pad, bvh: bvh(i, t).cut(&holes), few }
                })
            })
            .collect::<Vec<_>>();
        let present: Vec<u32> = (0..parts.len() as u32).filter(|&i| parts[i as usize].is_some()).collect();
        let (wide, mut order) = split_wide(&parts, present);
        let mut nodes = Vec::new();
        if !order.is_empty() {
            nodes.push(Node { lo: Vec3::ZERO, hi: Vec3::ZERO, start: 0, count: 0 });
            top_level(&parts, &mut nodes, 0, &mut order, 0);
        }
        Self { parts, nodes, order, wide }
    }

    /// Whether instance `i`'s triangles alone block the segment as [`Self::occluded`] asks (any
    /// hit; an instance index out of range or with no triangles blocks nothing). With the other
    /// instances unchanged, it is how an edit to instance `i` changes [`Self::occluded`].
    pub fn occluded_by(&self, i: usize, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        let p = self.parts.get(i).and_then(Option::as_ref);
        p.is_some_and(|p| {
            slab_hits(origin, dir.recip(), tmax, p.lo, p.hi) && p.bvh.occluded_past_touching(origin, dir, tmax)
        })
    }

    /// A [`Beam`] over instance `i`'s triangles from `origin`, when it has a few (at most
    /// [`beam::MAX_TRIANGLES`]); where the beam answers, it answers as [`Self::occluded_by`].
    pub fn beam(&self, i: usize, origin: Vec3) -> Option<Beam> {
        let p = self.parts.get(i).and_then(Option::as_ref)?;
        (!p.few.is_empty()).then(|| Beam::new(origin, &p.few))
    }

    /// True when any instance blocks the segment from `origin` along unit `dir` within
    /// `[touching_distance(origin), tmax]` ([`super::touching_distance`]: what touches the ray's
    /// start does not block it).
    // Out of line: inlined into the cold bake's texel loop it ran 3–4 % slower (measured).
    #[inline(never)]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        let inv = dir.recip();
        let near = super::touching_distance(origin);
        let part = |&i: &u32| self.parts[i as usize].as_ref().expect("the tree holds parts only");
        let blocks =
            |p: &Part| slab_hits(origin, inv, tmax, p.lo, p.hi) && p.bvh.occluded_between(origin, dir, near, tmax);
        if self.wide.iter().map(part).any(blocks) {
            return true;
        }
        // A balanced tree over at most 2³² parts is at most 33 deep.
        let mut stack = [0u32; 64];
        let mut depth = usize::from(!self.nodes.is_empty());
        while depth > 0 {
            depth -= 1;
            let node = &self.nodes[stack[depth] as usize];
            if !slab_hits(origin, inv, tmax, node.lo, node.hi) {
                continue;
            }
            if node.count == 0 {
                stack[depth..depth + 2].copy_from_slice(&[node.start, node.start + 1]);
                depth += 2;
                continue;
            }
            let leaf = &self.order[node.start as usize..(node.start + node.count) as usize];
            if leaf.iter().map(part).any(blocks) {
                return true;
            }
        }
        false
    }
}

/// The parts whose box spans at least half the scene along two axes (a terrain), and the rest. A wide part in the tree would widen every node above it to the
/// whole scene, and every ray from inside it — from any receiver on a terrain — would descend
/// that whole path: asked apart, before the tree, they cost one box test and their own BVH.
fn split_wide(parts: &[Option<Part>], present: Vec<u32>) -> (Vec<u32>, Vec<u32>) {
    let part = |i: u32| parts[i as usize].as_ref().expect("only parts are listed");
    let (lo, hi) =
        present.iter().map(|&i| part(i)).fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| (lo.min(p.lo), hi.max(p.hi)));
    let (scene, many) = (hi - lo, present.len() > LEAF);
    let wide = |i: &u32| {
        let e = part(*i).hi - part(*i).lo;
        many && (0..3).filter(|&k| e[k] >= 0.5 * scene[k]).count() >= 2
    };
    present.into_iter().partition(wide)
}

/// Fills `nodes[at]` for the parts `order` (from `offset` in the whole order): bounds, then a
/// leaf, or a median split along the longest axis of the parts' centres (ties by index, so the
/// tree is deterministic) into two children appended to `nodes`.
fn top_level(parts: &[Option<Part>], nodes: &mut Vec<Node>, at: usize, order: &mut [u32], offset: usize) {
    let part = |i: u32| parts[i as usize].as_ref().expect("only parts are ordered");
    let (lo, hi) =
        order.iter().map(|&i| part(i)).fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| (lo.min(p.lo), hi.max(p.hi)));
    let pad = Vec3::splat(1e-4 * (hi - lo).length() + 1e-6);
    nodes[at] = Node { lo: lo - pad, hi: hi + pad, start: offset as u32, count: order.len() as u32 };
    if order.len() <= LEAF {
        return;
    }
    let centre = |i: u32| part(i).lo + part(i).hi;
    let (clo, chi) = order.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), &i| (lo.min(centre(i)), hi.max(centre(i))));
    let axis = (chi - clo).max_position();
    order.sort_unstable_by(|&a, &b| centre(a)[axis].total_cmp(&centre(b)[axis]).then(a.cmp(&b)));
    let mid = order.len() / 2;
    let left = nodes.len();
    nodes.extend([Node { lo, hi, start: 0, count: 0 }, Node { lo, hi, start: 0, count: 0 }]);
    (nodes[at].start, nodes[at].count) = (left as u32, 0);
    let (a, b) = order.split_at_mut(mid);
    top_level(parts, nodes, left, a, offset);
    top_level(parts, nodes, left + 1, b, offset + mid);
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
    }

    /// A floor point on the line where a box rests on the floor lies in the plane of the box's
    /// side: a ray leaving along that side, away from the box, is not blocked by it however the
    /// side rounds, and a ray into the box is (it meets the far side) — for BSPVT's occluders,
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
                let far = bvh.closest_hit_past_touching(p, into, f32::INFINITY).map(|h| h.t);
                assert!(far.is_some_and(|t| t > 0.5), "side at {x}: into along {into} meets {far:?}");
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
            let any = all.occluded(o, d, f32::INFINITY);
            hits += usize::from(any);
            assert_eq!(occ.occluded(o, d, f32::INFINITY), any, "{o} {d}");
            assert_eq!((0..parts.len()).any(|i| occ.occluded_by(i, o, d, f32::INFINITY)), any, "{o} {d}: by instance");
        }
        assert!(hits > 0 && hits < n, "{hits} of {n} rays blocked: the test tests nothing");
    }
}
