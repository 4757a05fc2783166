//! Many rays from one origin against a few triangles, answered without a BVH.
//!
//! From a fixed origin `o`, a ray in direction `d` meets a triangle exactly when `d` lies inside
//! the three planes through `o` and the triangle's edges. A [`Beam`] keeps those planes per
//! triangle and answers only when `d` clears them by [`MARGIN`] — far more than the rounding of
//! the f32 Möller–Trumbore test the BVH runs — and otherwise says it does not know, so a caller
//! that falls back to the BVH then gets exactly the BVH's answer, bit for bit. Warm BSPVT
//! re-bakes use it to test the few triangles of a moved object against millions of texel rays.

use crate::math::planes::Planes;
use glam::{DVec3, Vec3};

/// Instances with more triangles than this are left to their BVH.
pub const MAX_TRIANGLES: usize = 32;

/// How far inside (or outside) a triangle's edge planes a unit direction must lie, in cosines,
/// for the beam to answer: far above the f32 rounding of the BVH's test at the distances a beam
/// accepts (see [`Beam::new`]; checked against the BVH in the tests), and a small fraction of a
/// 64² texel (0.025 rad), so few texel rays are left open.
pub const MARGIN: f32 = 2e-3;

/// The edge planes of a few triangles as seen from one origin.
pub struct Beam {
    /// Per triangle whose plane is far enough from the origin: unit normals of its three edge
    /// planes, the triangle on their positive side.
    planes: Vec<[Vec3; 3]>,
    /// The same edge planes all at once, triangle `b`'s at bits 3b, 3b + 1 and 3b + 2.
    edges: Planes,
    /// Bit 3b set for each triangle b.
    firsts: u128,
    /// Bit `b` set when triangle `b` of `planes` turns its front (counter-clockwise) side to
    /// the origin.
    front: u32,
    /// Whether some triangle's plane passes too close to the origin to rule out a hit.
    near: bool,
}

impl Beam {
    /// The beam of `triangles` from `origin`; a triangle whose plane passes within
    /// 1e-2 · (|origin|∞ + 1) of the origin (seen edge-on, or degenerate) can only leave a
    /// ray's answer open.
    pub fn new(origin: Vec3, triangles: &[[Vec3; 3]]) -> Self {
        let o = origin.as_dvec3();
        let close = 1e-2 * (o.abs().max_element() + 1.0);
        let mut near = false;
        let mut planes = Vec::with_capacity(triangles.len());
        for t in triangles {
            let v = t.map(|v| v.as_dvec3() - o);
            let normal = (v[1] - v[0]).cross(v[2] - v[0]);
            let length = normal.length();
            if length == 0.0 || normal.dot(v[0]).abs() < close * length {
                near = true;
                continue;
            }
            // Oriented so that the triangle's own vertices are on the positive side.
            let side = normal.dot(v[0]).signum();
            let edge = |a: DVec3, b: DVec3| (a.cross(b) * side).normalize_or_zero().as_vec3();
            // The numerator of the triangle's solid angle (Van Oosterom & Strackee) over its
            // vertices' distances: larger for triangles covering more directions.
            let size = normal.dot(v[0]).abs() / (v[0].length() * v[1].length() * v[2].length());
            planes.push((size, side < 0.0, [edge(v[1], v[2]), edge(v[2], v[0]), edge(v[0], v[1])]));
        }
        // Hits are found sooner in the triangles that cover more directions (the answer does
        // not depend on the order).
        planes.sort_by(|a, b| b.0.total_cmp(&a.0));
        let front = planes.iter().enumerate().fold(0, |m, (b, p)| m | (p.1 as u32) << b);
        let planes: Vec<[Vec3; 3]> = planes.into_iter().map(|(.., p)| p).collect();
        let firsts = (0..planes.len()).fold(0, |m, b| m | 1 << (3 * b));
        Self { edges: Planes::new(planes.as_flattened()), planes, firsts, front, near }
    }

    /// The edge planes (see [`Self::inside`]) of the triangles that turn their front to the
    /// origin: a ray into a closed mesh enters through one of them, so a search for certain hits
    /// can skip the others (they would add only rays near the front triangles' edges, or, on an
    /// open mesh, rays that meet back faces alone; a caller asks [`Self::hits`] about those).
    pub fn front_edge_planes(&self) -> impl Iterator<Item = &[Vec3; 3]> {
        self.planes.iter().enumerate().filter(|(b, _)| self.front >> b & 1 == 1).map(|(_, p)| p)
    }

    /// The triangles the ray from the origin along unit `d` certainly meets, as bits (in the
    /// beam's own order; at most [`MAX_TRIANGLES`]). A direction every bit of which is set in
    /// the masks of some unit directions, positively combined from them, meets that triangle too:
    /// each edge plane's dot grows no slower than the combination's length.
    pub fn inside(&self, d: Vec3) -> u32 {
        let hit = |planes: &[Vec3; 3]| planes.iter().all(|m| m.dot(d) > MARGIN);
        self.planes.iter().enumerate().fold(0, |mask, (b, planes)| mask | (hit(planes) as u32) << b)
    }

    /// Whether the ray from the origin along unit `d` meets a triangle: `Some` when certain,
    /// `None` when `d` passes within [`MARGIN`] of an edge plane that matters, or near a
    /// triangle whose plane passes close to the origin.
    pub fn hits(&self, d: Vec3) -> Option<bool> {
        let (beyond, behind) = self.edges.sides(d, MARGIN);
        // Certainly inside a triangle: beyond its three edge planes.
        if beyond & beyond >> 1 & beyond >> 2 & self.firsts != 0 {
            return Some(true);
        }
        // Certainly outside every triangle: behind one of each one's edge planes.
        let missed = (behind | behind >> 1 | behind >> 2) & self.firsts;
        (!self.near && missed == self.firsts).then_some(false)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::SceneBvh;
    use rand::Rng;

    /// Wherever the beam answers, it agrees with the BVH's any-hit test from the same origin —
    /// on random rays and on rays aimed just inside and outside edges and vertices — and it
    /// answers for most random rays.
    #[test]
    fn answers_agree_with_the_bvh() {
        let mut r = crate::math::rng::seeded(11);
        let (mut answered, mut asked) = (0, 0);
        for _ in 0..200 {
            let count = r.random_range(1..12);
            let mut point =
                || Vec3::new(r.random_range(-2.0..2.0), r.random_range(0.5..3.0), r.random_range(-2.0..2.0));
            let triangles: Vec<[Vec3; 3]> = (0..count).map(|_| [point(), point(), point()]).collect();
            let origin = Vec3::new(r.random_range(-3.0..3.0), r.random_range(-0.5..0.5), r.random_range(-3.0..3.0));
            let beam = Beam::new(origin, &triangles);
            let bvh = SceneBvh::new(&triangles);
            let aimed = triangles.iter().flat_map(|t| {
                let c = (t[0] + t[1] + t[2]) / 3.0;
                t.iter().chain(&[(t[0] + t[1]) / 2.0, (t[1] + t[2]) / 2.0]).map(move |v| (*v, c)).collect::<Vec<_>>()
            });
            let mut rays: Vec<Vec3> = aimed
                .flat_map(|(v, c)| [-1e-3, -1e-5, 0.0, 1e-5, 1e-3].map(|s| (v + (c - v) * s - origin).normalize()))
                .collect();
            let aimed = rays.len();
            rays.extend((0..200).map(|_| {
                Vec3::new(r.random_range(-1.0..1.0), r.random_range(-1.0..1.0), r.random_range(-1.0..1.0)).normalize()
            }));
            for (k, d) in rays.into_iter().enumerate() {
                let answer = beam.hits(d);
                if let Some(hit) = answer {
                    assert_eq!(hit, bvh.occluded(origin, d, f32::INFINITY), "origin {origin}, d {d}");
                }
                if k >= aimed {
                    (asked, answered) = (asked + 1, answered + answer.is_some() as usize);
                }
            }
        }
        assert!(answered * 10 > asked * 9, "answered {answered} of {asked}");
    }

    /// A cone spanned by directions certainly inside one triangle is: every positive
    /// combination of them is answered as a hit.
    #[test]
    fn cones_inside_a_triangle_hit() {
        let roof = [[Vec3::new(-1.0, 1.0, -1.0), Vec3::new(2.0, 1.0, -1.0), Vec3::new(-1.0, 1.0, 2.0)]];
        let beam = Beam::new(Vec3::ZERO, &roof);
        let corners =
            [Vec3::new(-0.5, 1.0, -0.5), Vec3::new(0.5, 1.0, -0.5), Vec3::new(-0.5, 1.0, 0.5)].map(Vec3::normalize);
        assert_eq!(corners.map(|c| beam.inside(c)), [1; 3]);
        let mut r = crate::math::rng::seeded(2);
        for _ in 0..1000 {
            let w = Vec3::new(r.random(), r.random(), r.random());
            let d = (corners[0] * w.x + corners[1] * w.y + corners[2] * w.z).normalize();
            assert_eq!((beam.inside(d), beam.hits(d)), (1, Some(true)), "{d}");
        }
        assert_eq!(beam.inside(Vec3::new(1.0, 1.0, 1.0).normalize()), 0);
    }

    /// Of a closed box (counter-clockwise seen from outside), the front triangles are those of
    /// the faces the origin sees: two from straight above, six from off a corner; a triangle
    /// wound the other way is not front.
    #[test]
    fn front_triangles_are_the_faces_seen() {
        let cuboid = crate::scene::shapes::cuboid(Vec3::splat(0.5));
        let triangles: Vec<[Vec3; 3]> =
            cuboid.triangles.iter().map(|t| t.map(|v| cuboid.positions[v as usize])).collect();
        for (origin, seen) in [(Vec3::new(0.0, 3.0, 0.0), 2), (Vec3::new(2.0, 3.0, -4.0), 6)] {
            assert_eq!(Beam::new(origin, &triangles).front_edge_planes().count(), seen, "{origin}");
        }
        let roof = [Vec3::new(-1.0, 1.0, -1.0), Vec3::new(-1.0, 1.0, 1.0), Vec3::new(1.0, 1.0, 0.0)];
        let flipped = [roof[0], roof[2], roof[1]];
        let count = |t: [Vec3; 3]| Beam::new(Vec3::ZERO, &[t]).front_edge_planes().count();
        assert_eq!(count(roof) + count(flipped), 1);
    }

    /// A triangle whose plane passes through the origin never gives a certain miss.
    #[test]
    fn a_plane_through_the_origin_leaves_misses_open() {
        let floor = [[Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 0.0, -1.0), Vec3::new(0.0, 0.0, 1.0)]];
        let beam = Beam::new(Vec3::new(3.0, 0.0, 0.0), &floor);
        assert_eq!(beam.hits(Vec3::Y), None);
        let roof = [floor[0].map(|v| v + Vec3::Y)];
        let beam = Beam::new(Vec3::ZERO, &roof);
        assert_eq!((beam.hits(Vec3::Y), beam.hits(Vec3::NEG_Y)), (Some(true), Some(false)));
    }
}
