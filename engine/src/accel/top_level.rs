//! A tree over boxes (the occluders' pieces): for rays that must ask many of them, and for
//! listing the pieces a pyramid of rays may meet ([`super::Occluders::view`]).
//!
//! Median splits along the longest axis of the boxes' centres (deterministic: ties by index).
//! Every node's box is padded around what it holds, so a ray meeting an item's box always meets
//! its ancestors' boxes, whatever the rounding: the tree finds every item whose box a ray meets.
//! (An 8-wide tree with one SIMD slab test per node measured no faster on the 1M-vertex level;
//! opening the child nearer along a ray first measured no faster or slower, and sorting a
//! vertex's view of the pieces nearest or farthest first made its bake 10–20 % slower.)

use super::instances::slab_hits;
use glam::Vec3;

/// Items per leaf at most (4 measured 3 % faster than 2 on the 1M-vertex level's terrain).
const LEAF: usize = 4;

/// A node: a leaf's items are `TopLevel::order[start..start + count]`; an inner node (`count`
/// 0) has its children at `start` and `start + 1`.
struct Node {
    lo: Vec3,
    hi: Vec3,
    start: u32,
    count: u32,
}

/// A tree over some of a list of boxes.
pub struct TopLevel {
    /// Root first; empty without items.
    nodes: Vec<Node>,
    /// Item indices in leaf order.
    order: Vec<u32>,
}

impl TopLevel {
    /// The tree over the boxes `boxes[i]` (`(lo, hi)`) of the items `ids`.
    pub fn new(boxes: &[(Vec3, Vec3)], mut ids: Vec<u32>) -> Self {
        let mut nodes = Vec::new();
        if !ids.is_empty() {
            nodes.push(Node { lo: Vec3::ZERO, hi: Vec3::ZERO, start: 0, count: 0 });
            split(boxes, &mut nodes, 0, &mut ids, 0);
        }
        Self { nodes, order: ids }
    }

    /// Whether `hit` is true for an item in a leaf whose box the segment from `o` (`inv` its
    /// reciprocal direction) within `[0, tmax]` meets, asking leaf by leaf until one is.
    #[inline]
    pub fn any_along(&self, o: Vec3, inv: Vec3, tmax: f32, mut hit: impl FnMut(u32) -> bool) -> bool {
        let mut found = false;
        self.each_within(
            |lo, hi| slab_hits(o, inv, tmax, lo, hi),
            |leaf| {
                found = leaf.iter().any(|&i| hit(i));
                found
            },
        );
        found
    }

    /// Hands `found` the items of the leaves reached by descending only into the boxes `keep`
    /// accepts, leaf by leaf, until it returns `true`; `false` when stopped so.
    #[inline]
    pub fn each_within(&self, keep: impl Fn(Vec3, Vec3) -> bool, mut found: impl FnMut(&[u32]) -> bool) -> bool {
        // A balanced tree over at most 2³² items is at most 33 deep.
        let mut stack = [0u32; 64];
        let mut depth = usize::from(!self.nodes.is_empty());
        while depth > 0 {
            depth -= 1;
            let node = &self.nodes[stack[depth] as usize];
            if !keep(node.lo, node.hi) {
                continue;
            }
            if node.count == 0 {
                stack[depth..depth + 2].copy_from_slice(&[node.start, node.start + 1]);
                depth += 2;
            } else if found(&self.order[node.start as usize..(node.start + node.count) as usize]) {
                return false;
            }
        }
        true
    }
}

/// Splits `ids` at its median along the longest axis of the bounds of their `centre`s: the
/// first half (returned: its length) holds the lower ones. Ties go by index, so the order is
/// strict and the halves are the same sets on every run.
pub(super) fn halve(ids: &mut [u32], centre: impl Fn(u32) -> Vec3) -> usize {
    let (lo, hi) = ids.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), &i| (lo.min(centre(i)), hi.max(centre(i))));
    let axis = (hi - lo).max_position();
    let mid = ids.len() / 2;
    ids.select_nth_unstable_by(mid, |&a, &b| centre(a)[axis].total_cmp(&centre(b)[axis]).then(a.cmp(&b)));
    mid
}

/// Fills `nodes[at]` for the items `order` (from `offset` in the whole order): padded bounds,
/// then a leaf, or a median split into two children appended to `nodes`.
fn split(boxes: &[(Vec3, Vec3)], nodes: &mut Vec<Node>, at: usize, order: &mut [u32], offset: usize) {
    let (lo, hi) = order.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), &i| {
        let (l, h) = boxes[i as usize];
        (lo.min(l), hi.max(h))
    });
    let pad = Vec3::splat(1e-4 * (hi - lo).length() + 1e-6);
    nodes[at] = Node { lo: lo - pad, hi: hi + pad, start: offset as u32, count: order.len() as u32 };
    if order.len() <= LEAF {
        return;
    }
    let mid = halve(order, |i| boxes[i as usize].0 + boxes[i as usize].1);
    let left = nodes.len();
    nodes.extend([0, 1].map(|_| Node { lo, hi, start: 0, count: 0 }));
    (nodes[at].start, nodes[at].count) = (left as u32, 0);
    let (a, b) = order.split_at_mut(mid);
    split(boxes, nodes, left, a, offset);
    split(boxes, nodes, left + 1, b, offset + mid);
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::Rng;

    /// The tree finds exactly the items whose boxes a ray meets (by the scalar slab test),
    /// and every item inside a region (by a box test on the way down).
    #[test]
    fn finds_every_box_a_ray_meets() {
        let mut r = crate::math::rng::seeded(11);
        for n in [1, 2, 3, 9, 17, 300] {
            let boxes: Vec<(Vec3, Vec3)> = (0..n)
                .map(|_| {
                    let c =
                        Vec3::new(r.random_range(-20.0..20.0), r.random_range(0.0..3.0), r.random_range(-20.0..20.0));
                    let e = Vec3::new(r.random_range(0.1..2.0), r.random_range(0.1..2.0), r.random_range(0.1..2.0));
                    (c - e, c + e)
                })
                .collect();
            let tree = TopLevel::new(&boxes, (0..n as u32).collect());
            for _ in 0..2000 {
                let o = Vec3::new(r.random_range(-25.0..25.0), r.random_range(-1.0..4.0), r.random_range(-25.0..25.0));
                let mut d = Vec3::new(r.random_range(-1.0..1.0), r.random_range(-1.0..1.0), r.random_range(-1.0..1.0));
                // Some rays parallel to an axis plane.
                d[r.random_range(0..6usize) % 4 % 3] *= f32::from(r.random_range(0..3u8) != 0);
                let d = d.normalize_or(Vec3::X);
                let inv = d.recip();
                let mut met = Vec::new();
                tree.any_along(o, inv, f32::INFINITY, |i| {
                    met.push(i);
                    false
                });
                met.sort_unstable();
                let expected: Vec<u32> = (0..n as u32)
                    .filter(|&i| {
                        crate::accel::instances::slab_hits(
                            o,
                            inv,
                            f32::INFINITY,
                            boxes[i as usize].0,
                            boxes[i as usize].1,
                        )
                    })
                    .collect();
                // Every box the ray meets, in leaves the ray meets: at most a leaf's worth more.
                assert!(expected.iter().all(|i| met.contains(i)), "{o} {d}: {expected:?} ⊄ {met:?}");
            }
            let region = |lo: Vec3, hi: Vec3| lo.x <= 0.0 && hi.x >= -10.0;
            let mut within = Vec::new();
            assert!(tree.each_within(region, |leaf| {
                within.extend(leaf.iter().copied().filter(|&i| region(boxes[i as usize].0, boxes[i as usize].1)));
                false
            }));
            within.sort_unstable();
            let expected: Vec<u32> =
                (0..n as u32).filter(|&i| region(boxes[i as usize].0, boxes[i as usize].1)).collect();
            assert_eq!(within, expected, "{n} boxes");
        }
    }
}
