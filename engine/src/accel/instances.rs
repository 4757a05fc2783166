//! Occluders as one BVH per instance, queried together behind a bounds test.
//!
//! A ray's answer against one instance depends on that instance's triangles alone — never on
//! how a single scene-wide BVH happened to group them — so moving, adding or removing an
//! instance cannot change any ray's result against the others, even for rays that graze a
//! surface (where a BVH's box tests can go either way). Incremental BSPVT re-bakes rely on it
//! to reproduce a cold bake's bytes.

use super::SceneBvh;
use super::beam::{self, Beam};
use glam::Vec3;

/// One instance: its padded bounds and BVH.
struct Part {
    lo: Vec3,
    hi: Vec3,
    bvh: SceneBvh,
    /// Its triangles when there are few enough for a [`Beam`], else empty.
    few: Vec<[Vec3; 3]>,
}

/// Per-instance BVHs answering any-hit queries together.
pub struct Occluders {
    /// By instance; `None` for an instance with no triangles.
    parts: Vec<Option<Part>>,
}

impl Occluders {
    /// One BVH per triangle list, by instance index.
    pub fn new(instances: &[Vec<[Vec3; 3]>]) -> Self {
        Self::with(instances, |_, t| SceneBvh::new(t))
    }

    /// [`Self::new`] with each non-empty list's BVH from `bvh(index, triangles)`: built, or
    /// restored from bytes a build wrote ([`SceneBvh::from_bytes`]), which answers alike.
    pub fn with(instances: &[Vec<[Vec3; 3]>], mut bvh: impl FnMut(usize, &[[Vec3; 3]]) -> SceneBvh) -> Self {
        let parts = instances
            .iter()
            .enumerate()
            .map(|(i, t)| {
                (!t.is_empty()).then(|| {
                    let (lo, hi) =
                        t.iter().flatten().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
                    // Padding keeps the box test conservative for rays that graze it.
                    let pad = Vec3::splat(1e-4 * (hi - lo).length() + 1e-6);
                    let few = if t.len() <= beam::MAX_TRIANGLES { t.clone() } else { Vec::new() };
                    Part { lo: lo - pad, hi: hi + pad, bvh: bvh(i, t), few }
                })
            })
            .collect();
        Self { parts }
    }

    /// Whether instance `i`'s triangles alone block the segment (any hit; an instance index
    /// out of range or with no triangles blocks nothing). With the other instances unchanged,
    /// it is how an edit to instance `i` changes [`Self::occluded`].
    pub fn occluded_by(&self, i: usize, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        let p = self.parts.get(i).and_then(Option::as_ref);
        p.is_some_and(|p| slab_hits(origin, dir.recip(), tmax, p.lo, p.hi) && p.bvh.occluded(origin, dir, tmax))
    }

    /// A [`Beam`] over instance `i`'s triangles from `origin`, when it has a few (at most
    /// [`beam::MAX_TRIANGLES`]); where the beam answers, it answers as [`Self::occluded_by`].
    pub fn beam(&self, i: usize, origin: Vec3) -> Option<Beam> {
        let p = self.parts.get(i).and_then(Option::as_ref)?;
        (!p.few.is_empty()).then(|| Beam::new(origin, &p.few))
    }

    /// True when any instance blocks the segment from `origin` along unit `dir` within `(0, tmax)`.
    // Out of line: inlined into the cold bake's texel loop it ran 3–4 % slower (measured).
    #[inline(never)]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        let inv = dir.recip();
        self.parts
            .iter()
            .flatten()
            .any(|p| slab_hits(origin, inv, tmax, p.lo, p.hi) && p.bvh.occluded(origin, dir, tmax))
    }
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
        let parts = vec![quad(Vec3::new(0.0, 1.0, 0.0)), quad(Vec3::new(2.0, 2.0, 0.0)), Vec::new()];
        let occ = Occluders::new(&parts);
        let all = SceneBvh::new(&parts.concat());
        let mut r = crate::math::rng::seeded(3);
        for _ in 0..5000 {
            use rand::Rng;
            let o = Vec3::new(r.random_range(-1.0..3.0), 0.0, r.random_range(-1.0..1.0));
            let d =
                Vec3::new(r.random_range(-1.0..1.0), r.random_range(0.1..1.0), r.random_range(-1.0..1.0)).normalize();
            let any = all.occluded(o, d, f32::INFINITY);
            assert_eq!(occ.occluded(o, d, f32::INFINITY), any, "{o} {d}");
            assert_eq!((0..4).any(|i| occ.occluded_by(i, o, d, f32::INFINITY)), any, "{o} {d}: by instance");
        }
    }
}
