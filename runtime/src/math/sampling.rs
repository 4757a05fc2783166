//! Sampling routines, each paired with its pdf and its inverse (tested by round trips).

use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};

/// Concentric mapping of the unit square onto the unit disk (Shirley–Chiu).
pub fn square_to_disk(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    let (r, theta) =
        if o.x.abs() > o.y.abs() { (o.x, FRAC_PI_4 * (o.y / o.x)) } else { (o.y, FRAC_PI_2 - FRAC_PI_4 * (o.x / o.y)) };
    r * Vec2::new(theta.cos(), theta.sin())
}

/// Inverse of [`square_to_disk`].
pub fn disk_to_square(p: Vec2) -> Vec2 {
    let r = p.length();
    if r == 0.0 {
        return Vec2::splat(0.5);
    }
    let mut phi = p.y.atan2(p.x);
    if phi < -FRAC_PI_4 {
        phi += 2.0 * PI;
    }
    let (a, b) = if phi < FRAC_PI_4 {
        (r, phi * r / FRAC_PI_4)
    } else if phi < 3.0 * FRAC_PI_4 {
        (-(phi - FRAC_PI_2) * r / FRAC_PI_4, r)
    } else if phi < 5.0 * FRAC_PI_4 {
        (-r, -(phi - PI) * r / FRAC_PI_4)
    } else {
        ((phi - 3.0 * FRAC_PI_2) * r / FRAC_PI_4, -r)
    };
    Vec2::new((a + 1.0) * 0.5, (b + 1.0) * 0.5)
}

/// Cosine-weighted direction on the +Z hemisphere.
pub fn cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = square_to_disk(u);
    Vec3::new(d.x, d.y, (1.0 - d.length_squared()).max(0.0).sqrt())
}

/// Pdf (solid angle) of [`cosine_hemisphere`].
pub fn cosine_hemisphere_pdf(w: Vec3) -> f32 {
    w.z.max(0.0) / PI
}

/// Inverse of [`cosine_hemisphere`].
pub fn cosine_hemisphere_inverse(w: Vec3) -> Vec2 {
    disk_to_square(Vec2::new(w.x, w.y))
}

/// Uniform barycentrics `(b1, b2)` on a triangle (b0 = 1 − b1 − b2), by the square-root map.
pub fn uniform_triangle(u: Vec2) -> Vec2 {
    let s = u.x.sqrt();
    Vec2::new(s * (1.0 - u.y), s * u.y)
}

/// Inverse of [`uniform_triangle`].
pub fn uniform_triangle_inverse(b: Vec2) -> Vec2 {
    let s = b.x + b.y;
    let uy = if s > 0.0 { b.y / s } else { 0.0 };
    Vec2::new(s * s, uy)
}

/// Uniform direction on the unit sphere.
pub fn uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Inverse of [`uniform_sphere`].
pub fn uniform_sphere_inverse(w: Vec3) -> Vec2 {
    let phi = w.y.atan2(w.x);
    let phi = if phi < 0.0 { phi + 2.0 * PI } else { phi };
    Vec2::new((1.0 - w.z) * 0.5, phi / (2.0 * PI))
}

/// Van der Corput's radical inverse of `i` in base 2.
pub fn radical_inverse(i: u32) -> f32 {
    (i.reverse_bits() as f64 / 4_294_967_296.0) as f32
}

/// Point `i` of the `n`-point Hammersley set in the unit square: `((i + ½) / n, radical_inverse(i))`.
pub fn hammersley(i: u32, n: u32) -> Vec2 {
    Vec2::new((i as f32 + 0.5) / n as f32, radical_inverse(i))
}

/// Veach's power heuristic (β = 2) for one sample of strategy `a` against strategy `b`.
pub fn power_heuristic(pdf_a: f32, pdf_b: f32) -> f32 {
    let (a, b) = (pdf_a * pdf_a, pdf_b * pdf_b);
    if a + b > 0.0 && a.is_finite() {
        a / (a + b)
    } else if a.is_infinite() {
        1.0
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng;
    use rand::Rng;

    #[test]
    fn radical_inverse_is_van_der_corput() {
        assert_eq!([0, 1, 2, 3].map(radical_inverse), [0.0, 0.5, 0.25, 0.75]);
        assert_eq!(hammersley(1, 4), Vec2::new(0.375, 0.5));
    }

    fn points(n: usize) -> Vec<Vec2> {
        let mut r = rng::seeded(7);
        (0..n).map(|_| Vec2::new(r.random(), r.random())).collect()
    }

    #[test]
    fn disk_round_trip() {
        for u in points(2000) {
            let back = disk_to_square(square_to_disk(u));
            assert!((back - u).abs().max_element() < 1e-5, "{u} -> {back}");
        }
    }

    #[test]
    fn cosine_round_trip_and_pdf_integrates_to_one() {
        for u in points(2000) {
            let w = cosine_hemisphere(u);
            assert!((w.length() - 1.0).abs() < 1e-5);
            assert!((cosine_hemisphere_inverse(w) - u).abs().max_element() < 1e-4);
        }
        // ∫ pdf dω over the hemisphere by uniform sphere sampling.
        let pts = points(200_000);
        let s: f64 = pts.iter().map(|&u| cosine_hemisphere_pdf(uniform_sphere(u)) as f64).sum();
        let integral = s / pts.len() as f64 * 4.0 * std::f64::consts::PI;
        assert!((integral - 1.0).abs() < 0.01, "{integral}");
    }

    #[test]
    fn triangle_and_sphere_round_trip() {
        for u in points(2000) {
            let b = uniform_triangle(u);
            assert!(b.x >= 0.0 && b.y >= 0.0 && b.x + b.y <= 1.0 + 1e-6);
            assert!((uniform_triangle_inverse(b) - u).abs().max_element() < 1e-4);
            let w = uniform_sphere(u);
            assert!((uniform_sphere_inverse(w) - u).abs().max_element() < 1e-3);
        }
    }

    #[test]
    fn power_heuristic_is_a_partition_of_unity() {
        for (a, b) in [(1.0, 2.0), (0.0, 3.0), (5.0, 0.0), (0.0, 0.0)] {
            let s = power_heuristic(a, b) + power_heuristic(b, a);
            assert!(s == 0.0 && a + b == 0.0 || (s - 1.0).abs() < 1e-6);
        }
        assert_eq!(power_heuristic(f32::INFINITY, 1.0), 1.0);
    }
}
