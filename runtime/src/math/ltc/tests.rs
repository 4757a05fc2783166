//! LTC integral against Monte Carlo of the same distribution, and the hard cases.

use super::*;
use crate::math::{cubemap, rng, sampling};
use glam::Vec2;
use rand::Rng;

/// A parallelogram around `c`, wound so that its CCW normal faces the origin.
fn quad(c: DVec3, u: DVec3, v: DVec3) -> Vec<DVec3> {
    let q = vec![c - u - v, c + u - v, c + u + v, c - u + v];
    if newell_normal(&q).dot(c) > 0.0 { q.into_iter().rev().collect() } else { q }
}

/// Does the ray from the origin along `d` pass through convex planar polygon `poly`?
fn hits(poly: &[DVec3], d: DVec3) -> bool {
    let n = newell_normal(poly);
    let t = poly[0].dot(n) / d.dot(n);
    if t.is_nan() || t <= 0.0 {
        return false;
    }
    let p = d * t;
    let k = poly.len();
    let signs: Vec<f64> = (0..k).map(|i| (poly[(i + 1) % k] - poly[i]).cross(p - poly[i]).dot(n)).collect();
    signs.iter().all(|s| *s >= 0.0) || signs.iter().all(|s| *s <= 0.0)
}

#[test]
fn integral_equals_monte_carlo_of_the_same_ltc() {
    let t = table();
    let poly = quad(DVec3::new(0.4, 0.2, 1.0), DVec3::new(0.5, 0.1, 0.0), DVec3::new(0.0, 0.4, 0.2));
    let mut r = rng::seeded(21);
    for (roughness, cos_v) in [(1.0, 1.0), (0.5, 0.6), (0.3, 0.2)] {
        let lut = t.lookup(roughness, cos_v);
        let m = lut.inv.inverse();
        let exact = integrate(&poly.iter().map(|p| lut.inv * *p).collect::<Vec<_>>());
        let n = 200_000;
        let inside = (0..n)
            .filter(|_| {
                let c = sampling::cosine_hemisphere(Vec2::new(r.random(), r.random())).as_dvec3();
                hits(&poly, (m * c).normalize())
            })
            .count();
        let p = inside as f64 / n as f64;
        let se = (p * (1.0 - p) / n as f64).sqrt();
        assert!((p - exact).abs() < 4.0 * se + 1e-9, "r {roughness} cos {cos_v}: {exact} vs MC {p} ± {se}");
    }
}

#[test]
fn back_facing_polygons_give_nothing() {
    let front = quad(DVec3::new(0.1, 0.2, 1.0), DVec3::X * 0.3, DVec3::Y * 0.2);
    let back: Vec<DVec3> = front.iter().rev().copied().collect();
    assert!(integrate(&front) > 0.0);
    assert_eq!(integrate(&back), 0.0);
}

#[test]
fn form_factor_of_a_covering_polygon_is_one() {
    let big = quad(DVec3::new(0.0, 0.0, 1.0), DVec3::X * 1e7, DVec3::Y * 1e7);
    assert!((integrate(&big) - 1.0).abs() < 1e-6, "{}", integrate(&big));
}

#[test]
fn straddling_the_horizon_integrates_the_upper_part() {
    let poly = quad(DVec3::new(0.0, 1.0, 0.0), DVec3::X * 0.5, DVec3::Z * 0.5);
    let upper = polygon::clip_horizon(&poly);
    assert!((integrate(&poly) - integrate(&upper)).abs() < 1e-15);
    assert!(integrate(&poly) > 0.0);
}

#[test]
fn edge_passing_near_the_shading_point() {
    // The bottom edge passes ε above the point; the polygon's upper boundary lies on the great
    // circle y = z. As ε → 0⁺ the projection tends to the lune between the horizon and that
    // circle (dihedral angle 45°), whose form factor is (1 − cos 45°)/2. Exactly at ε = 0 the
    // point lies in the polygon's plane: edge-on, 0 (documented).
    let make = |eps: f64| {
        vec![
            DVec3::new(-1.0, eps, 0.0),
            DVec3::new(1.0, eps, 0.0),
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(-1.0, 1.0, 1.0),
        ]
    };
    let lune = (1.0 - std::f64::consts::FRAC_1_SQRT_2) / 2.0;
    let (near, through, farther) = (integrate(&make(1e-7)), integrate(&make(0.0)), integrate(&make(1e-3)));
    assert_eq!(through, 0.0);
    assert!((near - lune).abs() < 1e-6, "{near} vs {lune}");
    assert!((farther - lune).abs() < 1e-3, "{farther}");
    // After an LTC transform the value stays finite and continuous in ε.
    let lut = table().lookup(0.3, 0.5);
    let ltc = |eps: f64| integrate(&make(eps).iter().map(|p| lut.inv * *p).collect::<Vec<_>>());
    assert!((ltc(1e-7) - ltc(1e-9)).abs() < 1e-6, "{} {}", ltc(1e-7), ltc(1e-9));
}

#[test]
fn degenerate_polygons() {
    let p = DVec3::new(0.2, 0.1, 1.0);
    let tri = vec![p, DVec3::new(0.3, 0.5, 1.0), DVec3::new(0.6, 0.1, 1.0)];
    assert!(integrate(&tri) > 0.0, "faces the origin");
    let repeated = vec![tri[0], tri[0], tri[1], tri[2], tri[2]];
    assert!((integrate(&tri) - integrate(&repeated)).abs() < 1e-15, "zero-length edges add nothing");
    assert_eq!(integrate(&[p, p, p]), 0.0, "zero area");
    assert!(integrate(&[p, p * 2.0, p * 3.0]).abs() < 1e-15, "collinear");
    let sliver = integrate(&[p, DVec3::new(0.4, 0.1 + 1e-9, 1.0), DVec3::new(0.6, 0.1, 1.0)]);
    assert!(sliver > 0.0);
    assert!((0.0..1e-8).contains(&sliver));
    assert_eq!(integrate(&[p, DVec3::NAN, DVec3::Z]), 0.0, "non-finite input clamps to 0");
    assert_eq!(integrate(&[p, DVec3::X]), 0.0);
}

#[test]
fn pieces_across_cube_faces_and_corners_add_up() {
    // A polygon around the cube corner direction (1, 1, 1): it touches three faces.
    let c = DVec3::ONE.normalize() * 2.0;
    let u = c.any_orthonormal_vector();
    let poly = quad(c, u * 0.9, c.normalize().cross(u) * 0.9);
    let lut = table().lookup(0.4, 0.7);
    for m in [DMat3::IDENTITY, lut.inv] {
        let whole = integrate(&poly.iter().map(|p| m * *p).collect::<Vec<_>>());
        let mut sum = 0.0;
        let mut faces = 0;
        for f in 0..cubemap::FACES {
            let piece = cubemap::face_frustum(f).iter().fold(poly.clone(), |p, n| polygon::clip(&p, *n));
            if !piece.is_empty() {
                faces += 1;
                sum += integrate(&piece.iter().map(|p| m * *p).collect::<Vec<_>>());
            }
        }
        assert_eq!(faces, 3);
        assert!((sum - whole).abs() < 1e-12, "{sum} vs {whole}");
    }
}

#[test]
fn extreme_roughness_and_grazing_views_stay_finite_and_bounded() {
    let t = table();
    let light = quad(DVec3::new(0.0, 0.0, 3.0), DVec3::X, DVec3::Y);
    for roughness in [1e-3, 0.5, 1.0] {
        for cos_v in [1e-4f64, 0.5, 1.0] {
            let v = DVec3::new((1.0 - cos_v * cos_v).sqrt(), 0.0, cos_v);
            let surface = Surface { p: DVec3::ZERO, n: DVec3::Z, v, roughness, f0: Vec3::ONE, f90: Vec3::ONE };
            let s = shade_polygon(&t, &light, &surface);
            assert!(s.specular.is_finite() && s.form_factor.is_finite());
            assert!(s.specular.x >= 0.0 && s.specular.x <= 1.0 + 1e-6, "r {roughness} cos {cos_v}: {}", s.specular.x);
        }
    }
    let nan = t.lookup(f64::NAN, f64::NAN);
    assert!(nan.magnitude.is_finite());
}
