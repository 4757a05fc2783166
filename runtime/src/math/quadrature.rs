//! Gauss–Legendre quadrature, and the product rule on the sphere / hemisphere built from it.
//!
//! With `n` nodes in cos θ and `2n` uniform nodes in φ the sphere rule integrates every
//! spherical polynomial of degree < 2n exactly, so products of SH up to order n are exact.

use glam::DVec3;
use std::f64::consts::PI;

/// Nodes and weights of the `n`-point Gauss–Legendre rule on [−1, 1] (Newton on P_n).
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            // Tricomi's initial guess, then Newton.
            let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let mut dp = 1.0;
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                    p0 = p1;
                    p1 = p2;
                }
                let p = if n == 0 { 1.0 } else { p1 };
                dp = n as f64 * (x * p - p0) / (x * x - 1.0);
                let dx = p / dp;
                x -= dx;
                if dx.abs() < 1e-16 {
                    break;
                }
            }
            (x, 2.0 / ((1.0 - x * x) * dp * dp))
        })
        .collect()
}

/// Directions and weights integrating over the whole sphere (`n` nodes in cos θ, `2n` in φ).
pub fn sphere_rule(n: usize) -> Vec<(DVec3, f64)> {
    product_rule(n, -1.0, 1.0)
}

/// Directions and weights integrating over the upper (+Z) hemisphere.
pub fn hemisphere_rule(n: usize) -> Vec<(DVec3, f64)> {
    product_rule(n, 0.0, 1.0)
}

fn product_rule(n: usize, z0: f64, z1: f64) -> Vec<(DVec3, f64)> {
    let nphi = 2 * n.max(1);
    let half = 0.5 * (z1 - z0);
    let mut out = Vec::with_capacity(n * nphi);
    for (x, w) in gauss_legendre(n) {
        let z = z0 + (x + 1.0) * half;
        let s = (1.0 - z * z).max(0.0).sqrt();
        for j in 0..nphi {
            let phi = 2.0 * PI * (j as f64 + 0.5) / nphi as f64;
            out.push((DVec3::new(s * phi.cos(), s * phi.sin(), z), w * half * 2.0 * PI / nphi as f64));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_legendre_is_exact_for_polynomials() {
        let rule = gauss_legendre(8);
        for k in 0..16 {
            let got: f64 = rule.iter().map(|(x, w)| w * x.powi(k)).sum();
            let exact = if k % 2 == 1 { 0.0 } else { 2.0 / (k as f64 + 1.0) };
            assert!((got - exact).abs() < 1e-14, "x^{k}: {got} vs {exact}");
        }
    }

    #[test]
    fn sphere_and_hemisphere_areas() {
        let s: f64 = sphere_rule(10).iter().map(|(_, w)| w).sum();
        let h: f64 = hemisphere_rule(10).iter().map(|(_, w)| w).sum();
        assert!((s - 4.0 * PI).abs() < 1e-12 && (h - 2.0 * PI).abs() < 1e-12);
    }
}
