//! Ray casting over triangles with a compressed wide BVH (`obvhs` CWBVH).
//!
//! [`SceneBvh`] answers closest-hit and any-hit queries; [`offset_ray_origin`] moves a ray's
//! origin off the surface it leaves by a few ULPs (Wächter & Binder, *Ray Tracing Gems* ch. 6),
//! which is robust at any distance from the origin without a scene-dependent epsilon.

pub mod beam;
mod instances;
mod stored;
pub(crate) mod top_level;

pub(crate) use instances::slab_hits;
pub use instances::{Frustum, Occluders};

use crate::math::sampling;
use crate::scene::{FlatScene, Holes};
use glam::{Vec2, Vec3, Vec3A};
use obvhs::{BvhBuildParams, cwbvh::CwBvh, ray::Ray, rt_triangle::RtTriangle, triangle::Triangle};
use std::time::Duration;

/// A closest hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Index of the triangle in the array the BVH was built from.
    pub triangle: u32,
    /// Distance along the (unit) ray direction.
    pub t: f32,
    /// Barycentrics (b1, b2) of the hit point; b0 = 1 − b1 − b2.
    pub bary: Vec2,
}

/// A BVH over a triangle soup.
pub struct SceneBvh {
    bvh: CwBvh,
    /// Triangles in BVH leaf order (avoids an indirection in the hot loop).
    tris: Vec<RtTriangle>,
    /// Their holes, in leaf order (empty: every triangle is solid).
    holes: Holes,
}

impl SceneBvh {
    /// Builds a BVH (deterministic: obvhs' single-threaded build). The slowest, best PLOC
    /// preset: 0.44 s for 165K triangles (4× the medium preset) buys ~7 % faster traversal.
    pub fn new(triangles: &[[Vec3; 3]]) -> Self {
        Self::build(triangles, BvhBuildParams::very_slow_build())
    }

    /// Builds a BVH quickly (obvhs' fastest preset) for a few rays, e.g. picking in the editor
    /// after every edit, where the slow build would cost more than the rays save.
    pub fn quick(triangles: &[[Vec3; 3]]) -> Self {
        Self::build(triangles, BvhBuildParams::fastest_build())
    }

    fn build(triangles: &[[Vec3; 3]], params: BvhBuildParams) -> Self {
        if triangles.is_empty() {
            return Self { bvh: CwBvh::default(), tris: Vec::new(), holes: Holes::default() };
        }
        let tris: Vec<Triangle> = triangles.iter().map(|&t| triangle(t)).collect();
        let bvh = obvhs::cwbvh::builder::build_cwbvh_from_tris(&tris, params, &mut Duration::default());
        Self::from_parts(bvh, triangles)
    }

    /// The BVH `bvh` built over `triangles`, its triangles laid out in leaf order.
    fn from_parts(bvh: CwBvh, triangles: &[[Vec3; 3]]) -> Self {
        let tris = bvh.primitive_indices.iter().map(|&i| RtTriangle::from(&triangle(triangles[i as usize]))).collect();
        Self { bvh, tris, holes: Holes::default() }
    }

    /// This BVH with `holes` (indexed as the triangles it was built from) open to every ray:
    /// cut-out surfaces ([`crate::scene::cutout`]).
    pub fn cut(mut self, holes: &Holes) -> Self {
        self.holes = holes.select(self.bvh.primitive_indices.iter().map(|&i| i as usize));
        self
    }

    /// Distance to leaf triangle `id` along `r`, or ∞ where it misses or is open.
    #[inline]
    fn intersect_cut(&self, r: &Ray, id: usize) -> f32 {
        let t = self.tris[id].intersect(r);
        if t < f32::INFINITY && self.holes.cuts(id) {
            let p = r.origin + r.direction * t;
            if self.holes.open(id, barycentrics(&self.tris[id], p)) {
                return f32::INFINITY;
            }
        }
        t
    }

    /// A BVH over a snapshot's triangles (lights' too) with its cut-outs' holes.
    pub fn over(flat: &FlatScene) -> Self {
        Self::new(&flat.triangles).cut(&flat.holes())
    }

    /// [`Self::over`], built quickly (see [`Self::quick`]).
    pub fn quick_over(flat: &FlatScene) -> Self {
        Self::quick(&flat.triangles).cut(&flat.holes())
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.tris.len()
    }

    /// True when the BVH holds no triangles.
    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }

    /// The closest hit along `dir` (unit) from `origin` within `(0, tmax)`.
    pub fn closest_hit(&self, origin: Vec3, dir: Vec3, tmax: f32) -> Option<Hit> {
        let (slot, t) = self.closest_slot(origin, dir, 0.0, tmax, |_, _| true)?;
        Some(self.hit(slot, origin, dir, t))
    }

    /// The closest hit within `[tmin, tmax]`, as the plane it lies in.
    pub fn closest_between(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<PlaneHit> {
        let (slot, t) = self.closest_slot(origin, dir, tmin, tmax, |_, _| true)?;
        let tri = &self.tris[slot];
        Some(PlaneHit { t, normal: Vec3::from(tri.ng).normalize_or(dir), corner: tri.v0.into() })
    }

    /// The hit on the triangle in leaf `slot` at `t` along the ray.
    fn hit(&self, slot: usize, origin: Vec3, dir: Vec3, t: f32) -> Hit {
        let p = Vec3A::from(origin) + Vec3A::from(dir) * t;
        Hit { triangle: self.bvh.primitive_indices[slot], t, bary: barycentrics(&self.tris[slot], p) }
    }

    /// The closest hit of a ray from `origin` (a surface point's offset origin) along `dir`
    /// (unit) within `tmax`, past what touches its start ([`touching_distance`]) unless the ray
    /// enters it through its front: a box's foot meets the floor it rests on at once.
    pub fn closest_hit_past_touching(&self, origin: Vec3, dir: Vec3, tmax: f32) -> Option<Hit> {
        let near = touching_distance(origin);
        let (slot, t) = self.closest_slot(origin - dir * near, dir, 0.0, tmax + near, |slot, t| {
            self.counts(slot, t - near, (origin, dir), near)
        })?;
        // A surface entered at the start is met there (its plane may round to either side).
        Some(self.hit(slot, origin, dir, (t - near).max(0.0)))
    }

    /// Whether a hit at `t` on the triangle in `slot` counts for a ray along `dir` from a
    /// surface point's offset origin: beyond `near` everything does; nearer, the surface
    /// touches the ray's start and counts only when the ray enters it through its front from a
    /// start on its plane, within the rounding of its coordinates, or before it. A floor vertex
    /// at the foot of a box lies in the plane of the box's side, which rounds to either side
    /// of it: a ray leaving away from the box meets the side from behind, if at all, and
    /// passes; a ray from the box's foot down into the floor meets the floor's front and stops
    /// there; a ray leaving a surface with a coincident back face (lifted past it by
    /// [`offset_ray_origin`], hundreds of ULPs) passes.
    ///
    /// Rays are cast from `near` before their start: obvhs ignores a box ending within 10⁻⁴ of
    /// a ray's origin, which would lose a flat floor's box under a foot on it.
    fn counts(&self, slot: usize, t: f32, (origin, dir): (Vec3, Vec3), near: f32) -> bool {
        if t >= near {
            return true;
        }
        // obvhs' `ng` is the negated geometric normal: a hit on the front has ng · d > 0, and
        // t (ng · d) / |ng| is the start's height above the plane.
        let ng = self.tris[slot].ng;
        let cos = ng.dot(Vec3A::from(dir));
        // Rounding a point of the plane moves it off the plane by at most ε Σ |n_i| |o_i|; the
        // start moved back by `near` and the hit's distance round by a few ε · near more.
        let scale = ng.abs().dot(Vec3A::from(origin.abs())) + near * ng.length();
        let rounding = ENTERING_ULPS * f32::EPSILON * scale;
        cos > 0.0 && t * cos >= -rounding
    }

    /// Whether a surface point `p` (unit normal `n`) lies inside closed geometry — a floor's
    /// vertex under a box resting on it — rather than merely in shadow: at least half of
    /// [`INSIDE_RAYS`] rays over its hemisphere (a fixed cosine-distributed Hammersley set)
    /// first meet a triangle from behind. Such a point's lighting means nothing for what is
    /// seen around it.
    pub fn inside(&self, p: Vec3, n: Vec3) -> bool {
        let frame = crate::math::frame::Frame::from_normal(n);
        let behind = (0..INSIDE_RAYS)
            .filter(|&k| {
                let d = frame.to_world(sampling::cosine_hemisphere(sampling::hammersley(k, INSIDE_RAYS)));
                // obvhs' `ng` is the negated geometric normal: a hit from behind has ng · d < 0.
                self.closest_slot(offset_ray_origin(p, n, d), d, 0.0, f32::INFINITY, |_, _| true)
                    .is_some_and(|(slot, _)| self.tris[slot].ng.dot(Vec3A::from(d)) < 0.0)
            })
            .count();
        2 * behind >= INSIDE_RAYS as usize
    }

    /// The leaf slot and distance of the closest hit that `counts` (slot, t) keeps.
    fn closest_slot(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
        counts: impl Fn(usize, f32) -> bool,
    ) -> Option<(usize, f32)> {
        if self.tris.is_empty() {
            return None;
        }
        let ray = ray(origin, dir, tmin, tmax);
        let mut hit = obvhs::ray::RayHit::none();
        let kept = |id: usize, t: f32| kept(t, || counts(id, t));
        // Two monomorphised traversals: the hole test stays out of the solid scene's loop
        // (in it, it cost 5–16 % of the any-hit rate; measured).
        let found = if self.holes.is_empty() {
            self.bvh.ray_traverse(ray, &mut hit, |r, id| kept(id, self.tris[id].intersect(r)))
        } else {
            self.bvh.ray_traverse(ray, &mut hit, |r, id| kept(id, self.intersect_cut(r, id)))
        };
        found.then_some((hit.primitive_id as usize, hit.t))
    }

    /// True when anything blocks the segment from `origin` along `dir` (unit) within `(0, tmax)`.
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        self.occluded_between(origin, dir, 0.0, tmax)
    }

    /// True when anything blocks the segment from surface point `p` (normal `n`) to `q`, a point
    /// on a light. The ray leaves the offset origin toward `q` itself: one parallel to `p → q`
    /// from the lifted origin meets the plane of a light close by, seen at a grazing angle,
    /// well before `q`, and the light would shadow itself.
    pub fn occluded_to(&self, p: Vec3, n: Vec3, q: Vec3) -> bool {
        let origin = offset_ray_origin(p, n, q - p);
        let to = q - origin;
        let dist = to.length();
        self.occluded(origin, to / dist, dist * (1.0 - 1e-4))
    }

    /// True when anything blocks a shadow ray from `origin` (a surface point's offset origin)
    /// along `dir` (unit) within `tmax`, past what touches its start ([`touching_distance`]).
    /// Unlike [`Self::closest_hit_past_touching`] it passes a touching surface it enters too:
    /// checking for one cost shadow rays 40–50 % (measured), and what lies beyond a surface
    /// touching a receiver — a light under the floor a box stands on — is rarely lit.
    pub fn occluded_past_touching(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        self.occluded_between(origin, dir, touching_distance(origin), tmax)
    }

    /// True when anything blocks the ray from `origin` along `dir` (unit) within `[tmin, tmax]`.
    pub fn occluded_between(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> bool {
        if self.tris.is_empty() {
            return false;
        }
        let ray = ray(origin, dir, tmin, tmax);
        if self.holes.is_empty() {
            !self.bvh.ray_traverse_miss(ray, |r, id| self.tris[id].intersect(r))
        } else {
            !self.bvh.ray_traverse_miss(ray, |r, id| self.intersect_cut(r, id))
        }
    }
}

/// The two triangles of each of the `n × n` cells of a grid whose corner (i, j) is at `p(i, j)`
/// (for tests: terrains of any size).
#[cfg(test)]
pub(crate) fn grid_triangles(n: usize, p: impl Fn(usize, usize) -> Vec3) -> Vec<[Vec3; 3]> {
    (0..n * n)
        .flat_map(|k| {
            let (i, j) = (k % n, k / n);
            [[p(i, j), p(i + 1, j), p(i + 1, j + 1)], [p(i, j), p(i + 1, j + 1), p(i, j + 1)]]
        })
        .collect()
}

/// Hit distance `t`, or a miss when `counts` drops the hit.
#[inline]
fn kept(t: f32, counts: impl FnOnce() -> bool) -> f32 {
    if t < f32::INFINITY && !counts() { f32::INFINITY } else { t }
}

/// A ray's hit as the plane of the triangle it met.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlaneHit {
    /// Distance along the (unit) ray direction.
    pub t: f32,
    /// The triangle's unit geometric normal (either side).
    pub normal: Vec3,
    /// One of the triangle's corners: with `normal`, its plane.
    pub corner: Vec3,
}

/// Rays [`SceneBvh::inside`] casts.
pub const INSIDE_RAYS: u32 = 32;

/// obvhs' triangle of three vertices.
fn triangle([v0, v1, v2]: [Vec3; 3]) -> Triangle {
    Triangle { v0: v0.into(), v1: v1.into(), v2: v2.into() }
}

/// Barycentrics (b1, b2) of point `p` on triangle `tri` (v1 = v0 − e1, v2 = v0 + e2 in obvhs).
fn barycentrics(tri: &RtTriangle, p: Vec3A) -> Vec2 {
    let (a, b, c) = (tri.v0, tri.v0 - tri.e1, tri.v0 + tri.e2);
    let (v0, v1, v2) = (b - a, c - a, p - a);
    let (d00, d01, d11) = (v0.dot(v0), v0.dot(v1), v1.dot(v1));
    let (d20, d21) = (v2.dot(v0), v2.dot(v1));
    let den = d00 * d11 - d01 * d01;
    if den == 0.0 {
        return Vec2::ZERO;
    }
    let b1 = (d11 * d20 - d01 * d21) / den;
    let b2 = (d00 * d21 - d01 * d20) / den;
    Vec2::new(b1, b2)
}

/// An obvhs ray. A direction component of −0.0 becomes +0.0: obvhs takes a component's sign
/// from `< 0.0` (false for −0.0) but its reciprocal from `signum` (−1 for −0.0), and a ray
/// straight down a flat box's axis then misses everything (a pick straight down at the ground).
fn ray(origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Ray {
    Ray::new(origin.into(), (dir + Vec3::ZERO).into(), tmin, tmax)
}

/// How far along a shadow ray from `origin` hits are ignored: a surface there is the one the
/// ray starts on or one touching it. A floor's vertex on the line where a box rests on it lies
/// in the plane of the box's side, and a ray leaving along that side meets it within a few
/// ULPs — or not — as the side happens to round, which darkened such vertices at random.
pub fn touching_distance(origin: Vec3) -> f32 {
    1e-4 * (1.0 + origin.abs().max_element())
}

/// How many ULPs of its coordinates behind a touching surface's plane a ray's start may lie
/// and still enter it: the rounding of a box's foot on a table top, not the hundreds by which
/// [`offset_ray_origin`] lifts a start past a coincident back face.
const ENTERING_ULPS: f32 = 8.0;

/// Moves `p` off a surface with geometric normal `n`, to the side `dir` leaves towards, by a
/// few ULPs of its coordinates (or a small absolute step near the world origin).
pub fn offset_ray_origin(p: Vec3, n: Vec3, dir: Vec3) -> Vec3 {
    const ORIGIN: f32 = 1.0 / 32.0;
    const FLOAT_SCALE: f32 = 1.0 / 65536.0;
    const INT_SCALE: f32 = 256.0;
    let n = if n.dot(dir) < 0.0 { -n } else { n };
    let of_i = (n * INT_SCALE).as_ivec3();
    let nudge = |x: f32, o: i32| f32::from_bits((x.to_bits() as i32 + if x < 0.0 { -o } else { o }) as u32);
    let p_i = Vec3::new(nudge(p.x, of_i.x), nudge(p.y, of_i.y), nudge(p.z, of_i.z));
    let pick = |x: f32, xi: f32, nx: f32| {
        if x.abs() < ORIGIN { x + FLOAT_SCALE * nx } else { xi }
    };
    Vec3::new(pick(p.x, p_i.x, n.x), pick(p.y, p_i.y, n.y), pick(p.z, p_i.z, n.z))
}

/// Reference Möller–Trumbore intersection (f64), for tests against the BVH.
pub fn intersect_triangle_f64(origin: Vec3, dir: Vec3, tri: &[Vec3; 3]) -> Option<f64> {
    let (o, d) = (origin.as_dvec3(), dir.as_dvec3());
    let [a, b, c] = tri.map(|v| v.as_dvec3());
    let (e1, e2) = (b - a, c - a);
    let pv = d.cross(e2);
    let det = e1.dot(pv);
    if det.abs() < 1e-14 {
        return None;
    }
    let tv = o - a;
    let u = tv.dot(pv) / det;
    let qv = tv.cross(e1);
    let v = d.dot(qv) / det;
    let t = e2.dot(qv) / det;
    (u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0).then_some(t)
}

/// Whether the ray `origin + t·dir` (t ≥ 0) meets the closed box `[lo, hi]` (f64).
///
/// The slab test without divisions (it runs for every texel a warm re-bake looks at): along
/// axis a the ray is inside the slab for t ∈ [E_a / D_a, X_a / D_a] with D_a = |dir_a|, so it
/// meets the box when every exit is ahead (X_b ≥ 0) and every entry precedes every exit
/// (E_a · D_b ≤ X_b · D_a); an axis with D_a = 0 then demands E_a ≤ 0 ≤ X_a, as it should.
pub fn ray_meets_box(origin: Vec3, dir: Vec3, lo: Vec3, hi: Vec3) -> bool {
    let (o, d, lo, hi) = (origin.as_dvec3(), dir.as_dvec3(), lo.as_dvec3(), hi.as_dvec3());
    let forward = d.cmpge(glam::DVec3::ZERO);
    let entry = glam::DVec3::select(forward, lo - o, o - hi);
    let exit = glam::DVec3::select(forward, hi - o, o - lo);
    let span = d.abs();
    if exit.min_element() < 0.0 {
        return false;
    }
    (0..3).all(|a| (0..3).all(|b| a == b || entry[a] * span[b] <= exit[b] * span[a]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ray meets a box exactly when some point along it lies inside: checked against points
    /// sampled densely along random rays (and axis-parallel ones, whose slab test divides by
    /// zero). Sampling can step over a corner the ray only grazes, so a hit without a sampled
    /// point inside must at least pass within a hair of the box.
    #[test]
    fn ray_box_test_agrees_with_points_along_the_ray() {
        use rand::Rng as _;
        let mut rng = crate::math::rng::seeded(7);
        let mut v = |scale: f32| (Vec3::new(rng.random(), rng.random(), rng.random()) - 0.5) * scale;
        let (lo, hi) = (Vec3::new(-0.5, -0.2, -0.3), Vec3::new(0.4, 0.3, 0.6));
        let near = |o: Vec3, d: Vec3, pad: f32| {
            (0..20000).map(|s| o + d * (s as f32 * 5e-4)).any(|q| (q.cmpge(lo - pad) & q.cmple(hi + pad)).all())
        };
        let (mut met, mut missed) = (0, 0);
        for k in 0..4000 {
            let o = v(4.0);
            // Axis-parallel, random, or aimed near the box (which grazes it often).
            let d = match k % 3 {
                0 => Vec3::new(-o.x.signum(), 0.0, 0.0),
                1 => v(2.0).normalize(),
                _ => (v(1.5) - o).normalize(),
            };
            let meets = ray_meets_box(o, d, lo, hi);
            assert!(meets || !near(o, d, 0.0), "o {o} d {d}: a point inside, yet no hit");
            assert!(!meets || near(o, d, 1e-3), "o {o} d {d}: a hit, yet no point near the box");
            met += usize::from(meets);
            missed += usize::from(!meets);
        }
        assert!(met > 200 && missed > 200, "{met} met, {missed} missed");
    }

    #[test]
    fn offset_leaves_the_surface_on_the_right_side() {
        for p in [Vec3::new(1000.0, -3.0, 0.01), Vec3::ZERO, Vec3::new(-1e5, 2e4, 7.0)] {
            let q = offset_ray_origin(p, Vec3::Y, Vec3::new(0.3, 0.9, 0.0));
            assert!(q.y > p.y);
            let q = offset_ray_origin(p, Vec3::Y, Vec3::NEG_Y);
            assert!(q.y < p.y);
            assert!((q - p).length() < 1e-2 * (1.0 + p.length() * 1e-3));
        }
    }

    #[test]
    fn hits_report_triangle_and_barycentrics() {
        let tris = [
            [Vec3::ZERO, Vec3::X, Vec3::Y],
            [Vec3::new(0.0, 0.0, -2.0), Vec3::new(1.0, 0.0, -2.0), Vec3::new(0.0, 1.0, -2.0)],
        ];
        for bvh in [SceneBvh::new(&tris), SceneBvh::quick(&tris)] {
            let h = bvh.closest_hit(Vec3::new(0.25, 0.5, 1.0), Vec3::NEG_Z, f32::INFINITY).unwrap();
            assert_eq!(h.triangle, 0);
            assert!((h.t - 1.0).abs() < 1e-6);
            assert!((h.bary - Vec2::new(0.25, 0.5)).length() < 1e-6);
            assert!(bvh.occluded(Vec3::new(0.25, 0.5, 1.0), Vec3::NEG_Z, 1.5));
            assert!(!bvh.occluded(Vec3::new(0.25, 0.5, 1.0), Vec3::NEG_Z, 0.5));
        }
        assert!(SceneBvh::new(&[]).closest_hit(Vec3::ZERO, Vec3::X, 1.0).is_none());
    }

    /// Points on a panel tilted 20°, 5–9 cm over a block's top (the Cornell box's light
    /// lowered and tilted): the segments from the top to them are clear, though a ray parallel
    /// to each from the lifted origin meets the panel's plane before its end.
    #[test]
    fn a_light_close_by_at_a_grazing_angle_does_not_shadow_itself() {
        let panel = [
            Vec3::new(0.343, 0.415_756_05, 0.230_166_14),
            Vec3::new(0.343, 0.379_843_95, 0.328_833_85),
            Vec3::new(0.213, 0.379_843_95, 0.328_833_85),
        ];
        let bvh = SceneBvh::new(&[panel]);
        let (mut clear, mut parallel_clear) = (0, 0);
        for p in [Vec3::new(0.283_375, 0.33, 0.356), Vec3::new(0.296_312_5, 0.33, 0.362_937_5)] {
            for k in 0..64 {
                let b = sampling::uniform_triangle(sampling::hammersley(k, 64));
                let q = panel[0] * (1.0 - b.x - b.y) + panel[1] * b.x + panel[2] * b.y;
                clear += usize::from(!bvh.occluded_to(p, Vec3::Y, q));
                let (d, o) = ((q - p).normalize(), offset_ray_origin(p, Vec3::Y, q - p));
                parallel_clear += usize::from(!bvh.occluded(o, d, (q - o).length() * (1.0 - 1e-4)));
            }
        }
        assert_eq!(clear, 128);
        assert!(parallel_clear < 64, "{parallel_clear}: the parallel ray no longer shadows itself");
    }

    /// A floor point under a box resting on it is inside; one beside it, or under a slab
    /// floating above (in shadow, not inside), is not.
    #[test]
    fn points_under_a_resting_box_are_inside_and_shadowed_points_are_not() {
        let world = |m: &crate::scene::Mesh, at: Vec3| -> Vec<[Vec3; 3]> {
            m.triangles.iter().map(|t| t.map(|i| m.positions[i as usize] + at)).collect()
        };
        let floor = world(&crate::scene::shapes::grid(8.0, 8), Vec3::ZERO);
        let box_ = world(&crate::scene::shapes::cuboid(Vec3::splat(0.5)), Vec3::new(0.0, 0.5, 0.0));
        let slab = world(&crate::scene::shapes::cuboid(Vec3::new(0.5, 0.05, 0.5)), Vec3::new(2.0, 1.0, 0.0));
        let bvh = SceneBvh::new(&[floor, box_, slab].concat());
        assert!(bvh.inside(Vec3::new(0.1, 0.0, -0.2), Vec3::Y), "under the box");
        assert!(!bvh.inside(Vec3::new(0.8, 0.0, 0.0), Vec3::Y), "beside it");
        assert!(!bvh.inside(Vec3::new(2.0, 0.0, 0.0), Vec3::Y), "under the floating slab");
        assert!(!SceneBvh::new(&[]).inside(Vec3::ZERO, Vec3::Y));
    }

    /// A gather ray from a box's foot down into the floor (or table top) it rests on meets the
    /// floor there, whichever side of the floor's plane the foot rounds to (a shadow ray passes
    /// it, see [`SceneBvh::occluded_past_touching`]); a ray from a surface with a coincident
    /// back face (a leaf's two sides) passes that back face.
    #[test]
    fn a_ray_entering_a_surface_at_its_start_meets_it() {
        for height in [0.0f32, 0.6, 0.6 + 1.2e-7, 0.6 - 6e-8, 17.3] {
            let floor = crate::scene::shapes::grid(80.0, 1);
            let floor: Vec<[Vec3; 3]> =
                floor.triangles.iter().map(|t| t.map(|i| floor.positions[i as usize] + height * Vec3::Y)).collect();
            let bvh = SceneBvh::new(&floor);
            // The +z side's foot: its height as the box's own transform rounds it.
            let foot = Vec3::new(0.1, 0.3 + (height - 0.3), 0.5);
            for k in 1..8 {
                let down = Vec3::new(0.1 * k as f32, -0.1 * k as f32, 1.0).normalize();
                let o = offset_ray_origin(foot, Vec3::Z, down);
                let hit = bvh.closest_hit_past_touching(o, down, f32::INFINITY);
                assert!(hit.is_some_and(|h| h.t < 1e-3), "floor at {height}: {down} meets {hit:?}");
                let up = Vec3::new(0.1 * k as f32, 0.1 * k as f32, 1.0).normalize();
                let o = offset_ray_origin(foot, Vec3::Z, up);
                assert!(bvh.closest_hit_past_touching(o, up, f32::INFINITY).is_none(), "floor at {height}: {up}");
            }
            // The floor's own rays pass its coincident back face.
            let back: Vec<[Vec3; 3]> = floor.iter().map(|&[a, b, c]| [a, c, b]).collect();
            let two_sided = SceneBvh::new(&[floor, back].concat());
            for k in 1..8 {
                let d = Vec3::new(0.1 * k as f32, 1.0, 0.3).normalize();
                for at in [Vec3::new(0.3, height, -0.2), Vec3::new(37.7, height, 39.1)] {
                    let o = offset_ray_origin(at, Vec3::Y, d);
                    assert!(two_sided.closest_hit_past_touching(o, d, f32::INFINITY).is_none(), "at {at}: {d}");
                }
            }
        }
    }

    #[test]
    fn rays_along_an_axis_with_negative_zero_components_still_hit() {
        let ground = [[Vec3::new(-1.0, 0.0, -1.0), Vec3::new(-1.0, 0.0, 1.0), Vec3::new(1.0, 0.0, -1.0)]];
        let bvh = SceneBvh::new(&ground);
        let down = -Vec3::Y * 1.0 - Vec3::ZERO; // (−0, −1, −0), as −n of an upward normal gives
        assert!(down.x.is_sign_negative());
        let hit = bvh.closest_hit(Vec3::new(-0.5, 1.0, -0.5), down, f32::INFINITY);
        assert_eq!(hit.map(|h| h.triangle), Some(0));
        assert!(bvh.occluded(Vec3::new(-0.5, 1.0, -0.5), down, 2.0));
    }
}
