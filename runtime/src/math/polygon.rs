//! Polygons seen from the origin: clipping by planes through the origin (cube-face frusta,
//! BSP lines, the horizon) and by planes in front of it (occluders' depth), and solid angles
//! of spherical polygons.
//!
//! Vertices within a relative tolerance of a plane are treated as lying on it: they are kept
//! and never produce a second, nearly identical intersection point, so repeated clipping by a
//! plane and its opposite partitions a polygon without slivers or gaps.

use glam::DVec3;

/// Relative distance below which a vertex counts as on a plane.
pub const ON_PLANE: f64 = 1e-12;

/// Keeps the part of convex polygon `poly` where `n · p ≥ 0` (Sutherland–Hodgman).
pub fn clip(poly: &[DVec3], n: DVec3) -> Vec<DVec3> {
    keep(poly, |p| {
        let d = n.dot(p);
        if d.abs() <= ON_PLANE * n.length() * p.length() { 0.0 } else { d }
    })
}

/// Keeps the part of convex polygon `poly` where `n · p ≤ c`: what lies in front of the plane
/// `n · p = c` (not through the origin) seen from the origin, for `c > 0`.
pub fn clip_below(poly: &[DVec3], n: DVec3, c: f64) -> Vec<DVec3> {
    keep(poly, |p| {
        let d = c - n.dot(p);
        if d.abs() <= ON_PLANE * (c.abs() + n.length() * p.length()) { 0.0 } else { d }
    })
}

/// The part of convex polygon `poly` where `side(p) ≥ 0`, `side` affine and exactly 0 on the
/// boundary (Sutherland–Hodgman); empty when fewer than three vertices remain.
fn keep(poly: &[DVec3], side: impl Fn(DVec3) -> f64) -> Vec<DVec3> {
    let mut out = Vec::with_capacity(poly.len() + 2);
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        let (da, db) = (side(a), side(b));
        if da >= 0.0 {
            out.push(a);
        }
        if (da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0) {
            out.push(a + (b - a) * (da / (da - db)));
        }
    }
    if out.len() < 3 { Vec::new() } else { out }
}

/// Both parts of convex polygon `poly` cut by the plane through the origin with normal `n`:
/// exactly `(clip(poly, n), clip(poly, −n))`, without clipping a polygon that lies strictly on
/// one side (the common case when descending a BSP tree).
pub fn split(poly: Vec<DVec3>, n: DVec3) -> (Vec<DVec3>, Vec<DVec3>) {
    let scale = ON_PLANE * n.length();
    let beyond = |sign: f64| poly.len() >= 3 && poly.iter().all(|p| sign * n.dot(*p) > scale * p.length());
    if beyond(1.0) {
        (poly, Vec::new())
    } else if beyond(-1.0) {
        (Vec::new(), poly)
    } else {
        (clip(&poly, n), clip(&poly, -n))
    }
}

/// Keeps the part above the local horizon (z ≥ 0).
pub fn clip_horizon(poly: &[DVec3]) -> Vec<DVec3> {
    clip(poly, DVec3::Z)
}

/// Signed solid angle of the spherical polygon whose vertices are the directions of `poly`:
/// positive when the vertices wind counter-clockwise seen from outside the sphere, in
/// (−2π, 2π] (a polygon larger than a hemisphere wraps by 4π; see
/// [`enclosed_solid_angle`]). Fan of Van Oosterom–Strackee triangles; degenerate triangles
/// contribute exactly zero.
pub fn solid_angle(poly: &[DVec3]) -> f64 {
    if poly.len() < 3 {
        return 0.0;
    }
    let u: Vec<DVec3> = poly.iter().map(|p| p.normalize_or_zero()).collect();
    (1..u.len() - 1)
        .map(|k| {
            let (a, b, c) = (u[0], u[k], u[k + 1]);
            let num = a.dot(b.cross(c));
            let den = 1.0 + a.dot(b) + b.dot(c) + c.dot(a);
            2.0 * num.atan2(den)
        })
        .sum()
}

/// Solid angle of the region to the left of the polygon's path (seen from outside), in
/// [0, 4π): unambiguous for polygons larger than a hemisphere.
pub fn enclosed_solid_angle(poly: &[DVec3]) -> f64 {
    solid_angle(poly).rem_euclid(4.0 * std::f64::consts::PI)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Clipping below a plane keeps what is in front of it: the parts on both sides add up
    /// to the whole polygon's solid angle, and every kept vertex is in front.
    #[test]
    fn clipping_below_a_plane_partitions_the_polygon() {
        let poly = vec![DVec3::new(-1.0, 2.0, -1.0), DVec3::new(1.0, 2.0, -1.0), DVec3::new(1.0, 3.0, 1.0)];
        let (n, c) = (DVec3::new(0.2, 1.0, 0.1).normalize(), 2.3);
        let front = clip_below(&poly, n, c);
        let back = clip_below(&poly, -n, -c);
        assert!(front.iter().all(|p| n.dot(*p) <= c + 1e-12) && !front.is_empty() && !back.is_empty());
        let whole = solid_angle(&poly);
        assert!((solid_angle(&front) + solid_angle(&back) - whole).abs() < 1e-12 * whole.abs(), "{front:?}");
        assert_eq!(clip_below(&poly, n, 10.0), poly);
        assert!(clip_below(&poly, n, 0.5).is_empty());
    }
    use std::f64::consts::PI;

    fn square(z: f64, h: f64) -> Vec<DVec3> {
        vec![DVec3::new(-h, -h, z), DVec3::new(h, -h, z), DVec3::new(h, h, z), DVec3::new(-h, h, z)]
    }

    #[test]
    fn split_is_both_clips() {
        let planes = [DVec3::X, DVec3::new(0.3, -0.2, 0.9), DVec3::new(1.0, 1.0, 0.0), DVec3::new(0.0, 0.0, -1.0)];
        for poly in [square(1.0, 0.5), square(1.0, 2.0), square(-0.5, 0.3), square(0.0, 1.0)] {
            for n in planes {
                assert_eq!(split(poly.clone(), n), (clip(&poly, n), clip(&poly, -n)), "{poly:?} by {n}");
            }
        }
        // A vertex on the plane is not strictly on one side: the clipping path, same answer.
        let touching = vec![DVec3::new(0.0, 0.0, 1.0), DVec3::new(1.0, 0.0, 1.0), DVec3::new(1.0, 1.0, 1.0)];
        let (pos, neg) = split(touching.clone(), DVec3::X);
        assert_eq!((pos, neg.len()), (touching, 0));
    }

    #[test]
    fn solid_angle_of_a_cube_face_is_four_pi_over_six() {
        assert!((solid_angle(&square(1.0, 1.0)) - 4.0 * PI / 6.0).abs() < 1e-12);
        assert!(
            (solid_angle(&square(-1.0, 1.0)) + 4.0 * PI / 6.0).abs() < 1e-12,
            "opposite winding seen from the origin"
        );
    }

    #[test]
    fn straddling_the_horizon() {
        let tilted: Vec<DVec3> = square(0.0, 1.0).iter().map(|p| DVec3::new(p.x, 2.0, p.y)).collect();
        let clipped = clip_horizon(&tilted);
        assert_eq!(clipped.len(), 4);
        assert!(clipped.iter().all(|p| p.z >= 0.0));
        let below = clip(&tilted, DVec3::NEG_Z);
        let total = solid_angle(&tilted);
        assert!((solid_angle(&clipped) + solid_angle(&below) - total).abs() < 1e-12);
    }

    #[test]
    fn clip_and_opposite_clip_keep_the_solid_angle() {
        let poly = vec![
            DVec3::new(0.3, -0.2, 1.0),
            DVec3::new(1.2, 0.1, 0.9),
            DVec3::new(0.4, 1.1, 1.1),
            DVec3::new(-0.5, 0.6, 1.0),
        ];
        for n in [DVec3::new(1.0, 0.3, -0.5), DVec3::new(-0.2, 1.0, 0.1), DVec3::new(0.0, 0.0, 1.0)] {
            let (a, b) = (clip(&poly, n), clip(&poly, -n));
            let sum = solid_angle(&a) + solid_angle(&b);
            assert!((sum - solid_angle(&poly)).abs() < 1e-12, "{sum}");
        }
    }

    #[test]
    fn vertex_exactly_on_the_clip_plane() {
        let tri = vec![DVec3::new(0.0, 0.0, 1.0), DVec3::new(1.0, 0.0, 1.0), DVec3::new(0.0, 1.0, 1.0)];
        // The plane x = 0 passes through two vertices: keep the whole triangle on one side,
        // nothing on the other, and no duplicated points.
        assert_eq!(clip(&tri, DVec3::X).len(), 3);
        assert!(clip(&tri, DVec3::NEG_X).is_empty());
        // Through one vertex and across the opposite edge: two triangles, no extra vertex.
        let n = DVec3::new(1.0, -1.0, 0.0);
        let (a, b) = (clip(&tri, n), clip(&tri, -n));
        assert_eq!((a.len(), b.len()), (3, 3));
        assert!((solid_angle(&a) + solid_angle(&b) - solid_angle(&tri)).abs() < 1e-12);
    }

    #[test]
    fn degenerate_polygons_have_zero_solid_angle() {
        let p = DVec3::new(0.1, 0.2, 1.0);
        let collinear = vec![p, p * 2.0 + DVec3::X * 0.0, DVec3::new(0.3, 0.6, 3.0)];
        assert_eq!(solid_angle(&collinear), 0.0, "all on one ray");
        let repeated = vec![p, p, DVec3::new(0.5, 0.2, 1.0), DVec3::new(0.5, 0.2, 1.0)];
        assert!(solid_angle(&repeated).abs() < 1e-15);
        let zero_area = vec![DVec3::Z, DVec3::Z, DVec3::Z];
        assert_eq!(solid_angle(&zero_area), 0.0);
        let sliver = vec![DVec3::new(0.0, 0.0, 1.0), DVec3::new(1.0, 0.0, 1.0), DVec3::new(0.5, 1e-9, 1.0)];
        let s = solid_angle(&sliver);
        assert!(s > 0.0 && s < 1e-9);
        assert!(clip(&[DVec3::Z, DVec3::X], DVec3::Z).is_empty(), "fewer than 3 vertices");
    }

    #[test]
    fn nan_vertices_never_produce_nan() {
        let poly = vec![DVec3::new(0.0, 0.0, 1.0), DVec3::NAN, DVec3::new(1.0, 0.0, 1.0), DVec3::new(0.0, 1.0, 1.0)];
        assert!(clip(&poly, DVec3::X).iter().all(|p| p.is_finite()));
        assert!(solid_angle(&poly).is_finite());
    }

    #[test]
    fn a_polygon_covering_more_than_a_hemisphere() {
        // Four directions just below the equator, counter-clockwise seen from +Z: the region
        // to their left is the big cap containing +Z.
        let ring: Vec<DVec3> = (0..4)
            .map(|k| {
                let phi = PI / 2.0 * k as f64;
                DVec3::new(phi.cos(), phi.sin(), -0.2)
            })
            .collect();
        let s = enclosed_solid_angle(&ring);
        assert!(s > 2.0 * PI, "{s}");
        // Its complement is the small square around −Z; fan it from −Z independently.
        let reversed: Vec<DVec3> = ring.iter().rev().copied().collect();
        let small: f64 = (0..4).map(|k| solid_angle(&[DVec3::NEG_Z, reversed[k], reversed[(k + 1) % 4]])).sum();
        assert!((enclosed_solid_angle(&reversed) - small).abs() < 1e-12);
        assert!((s + small - 4.0 * PI).abs() < 1e-12, "{s} + {small}");
    }
}
