//! Real orthonormal spherical harmonics.
//!
//! Convention (docs/conventions.md): index `k = l(l+1) + m`, **no Condon–Shortley phase**; "order n"
//! means bands l = 0..n−1 (n² coefficients). θ is measured from +Z of whatever frame the
//! direction is given in, φ = atan2(y, x):
//! `Y_lm = √2 K_lm P_l^m(cos θ) cos(mφ)` (m > 0), `√2 K_l|m| P_l^|m| sin(|m|φ)` (m < 0),
//! `K_l0 P_l^0` (m = 0), `K_lm = sqrt((2l+1)/(4π) · (l−m)!/(l+m)!)`.
//!
//! Evaluation is in Cartesian form, f64 inside: normalised associated Legendre recurrences on
//! z times Re/Im of (x + iy)^m, which carries the sin^m θ factor, so nothing divides by sin θ
//! and the poles are as accurate as anywhere else.

use crate::math::quadrature;
use glam::{DMat3, DVec3};
use std::f64::consts::PI;

/// Number of coefficients of order `n` (n²).
pub const fn num_coeffs(order: usize) -> usize {
    order * order
}

/// Index of (l, m).
pub const fn index(l: usize, m: i32) -> usize {
    ((l * (l + 1)) as isize + m as isize) as usize
}

/// Normalised polynomial parts `Q̄_lm(z)` (P̄_lm = Q̄_lm · sin^m θ, P̄ including K_lm),
/// indexed like the SH with m ≥ 0 only meaningful.
pub fn legendre_q(order: usize, z: f64, out: &mut [f64]) {
    debug_assert!(out.len() >= num_coeffs(order));
    if order == 0 {
        return;
    }
    out[0] = 0.5 / PI.sqrt();
    for m in 0..order {
        if m > 0 {
            // Q̄_mm = sqrt((2m+1)/(2m)) Q̄_{m−1,m−1}
            out[index(m, m as i32)] = ((2 * m + 1) as f64 / (2 * m) as f64).sqrt() * out[index(m - 1, m as i32 - 1)];
        }
        if m + 1 < order {
            out[index(m + 1, m as i32)] = ((2 * m + 3) as f64).sqrt() * z * out[index(m, m as i32)];
        }
        for l in m + 2..order {
            let (a, b) = recurrence(l, m);
            out[index(l, m as i32)] = a * (z * out[index(l - 1, m as i32)] - b * out[index(l - 2, m as i32)]);
        }
    }
}

/// Coefficients (a, b) of the normalised three-term recurrence
/// `Q̄_lm = a (z Q̄_{l−1,m} − b Q̄_{l−2,m})`.
pub(crate) fn recurrence(l: usize, m: usize) -> (f64, f64) {
    let (lf, mf) = (l as f64, m as f64);
    let a = ((4.0 * lf * lf - 1.0) / (lf * lf - mf * mf)).sqrt();
    let b = (((lf - 1.0) * (lf - 1.0) - mf * mf) / (4.0 * (lf - 1.0) * (lf - 1.0) - 1.0)).sqrt();
    (a, b)
}

/// Evaluates all n² basis functions at unit direction `d` into `out`; a non-finite `d`
/// evaluates at +Z (documented clamp: never NaN out).
pub fn eval_into(order: usize, d: DVec3, out: &mut [f64]) {
    let n = num_coeffs(order);
    let d = if d.is_finite() { d } else { DVec3::Z };
    legendre_q(order, d.z, out);
    // (x + iy)^m, built incrementally.
    let (mut re, mut im) = (1.0, 0.0);
    for m in 0..order {
        if m > 0 {
            (re, im) = (re * d.x - im * d.y, re * d.y + im * d.x);
        }
        for l in m..order {
            let q = out[index(l, m as i32)];
            if m == 0 {
                continue;
            }
            out[index(l, m as i32)] = std::f64::consts::SQRT_2 * q * re;
            out[index(l, -(m as i32))] = std::f64::consts::SQRT_2 * q * im;
        }
    }
    debug_assert!(out[..n].iter().all(|v| v.is_finite()));
}

/// Evaluates all n² basis functions at unit direction `d`.
pub fn eval(order: usize, d: DVec3) -> Vec<f64> {
    let mut out = vec![0.0; num_coeffs(order)];
    eval_into(order, d, &mut out);
    out
}

/// Projects `f` onto order `order` with an exact-for-polynomials quadrature of `nodes` nodes
/// in cos θ (≥ order for band-limited f; more for general f).
pub fn project(order: usize, nodes: usize, f: impl Fn(DVec3) -> f64) -> Vec<f64> {
    let mut c = vec![0.0; num_coeffs(order)];
    let mut y = vec![0.0; num_coeffs(order)];
    for (d, w) in quadrature::sphere_rule(nodes) {
        eval_into(order, d, &mut y);
        let fw = f(d) * w;
        c.iter_mut().zip(&y).for_each(|(c, y)| *c += fw * y);
    }
    c
}

/// Reconstructs Σ c_k Y_k(d).
pub fn reconstruct(coeffs: &[f64], d: DVec3) -> f64 {
    let order = (coeffs.len() as f64).sqrt() as usize;
    eval(order, d).iter().zip(coeffs).map(|(y, c)| y * c).sum()
}

/// Zonal coefficients `k_l` (of Y_l0) of the clamped cosine max(0, cos θ) about +Z.
pub fn clamped_cosine_zonal(order: usize) -> Vec<f64> {
    (0..order)
        .map(|l| {
            // k_l = 2π ∫₀¹ Q̄_l0(z) z dz: polynomial of degree l+1, exact with Gauss–Legendre.
            let mut q = vec![0.0; num_coeffs(l + 1)];
            quadrature::gauss_legendre(l / 2 + 2)
                .iter()
                .map(|&(x, w)| {
                    let z = 0.5 * (x + 1.0);
                    legendre_q(l + 1, z, &mut q);
                    0.5 * w * 2.0 * PI * q[index(l, 0)] * z
                })
                .sum()
        })
        .collect()
}

/// Convolves coefficients with a zonal kernel (given by its `k_l`):
/// `(k ∗ f)_lm = sqrt(4π/(2l+1)) k_l f_lm` (Funk–Hecke). With the clamped cosine this turns
/// radiance into irradiance.
pub fn convolve_zonal(coeffs: &mut [f64], kernel: &[f64]) {
    let order = (coeffs.len() as f64).sqrt() as usize;
    for l in 0..order.min(kernel.len()) {
        let s = (4.0 * PI / (2 * l + 1) as f64).sqrt() * kernel[l];
        for m in -(l as i32)..=l as i32 {
            coeffs[index(l, m)] *= s;
        }
    }
}

/// Block-diagonal SH rotation: one (2l+1)² matrix per band, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Rotation {
    bands: Vec<Vec<f64>>,
}

impl Rotation {
    /// The rotation of coefficient vectors that corresponds to rotating functions by `r`:
    /// if `g(d) = f(r⁻¹ d)` then `coeffs(g) = R · coeffs(f)`. Ivanic–Ruedenberg recurrences
    /// (J. Phys. Chem. 1996, with the 1998 erratum), for any order.
    pub fn new(order: usize, r: DMat3) -> Self {
        let mut bands: Vec<Vec<f64>> = Vec::with_capacity(order);
        if order == 0 {
            return Self { bands };
        }
        bands.push(vec![1.0]);
        if order == 1 {
            return Self { bands };
        }
        // Band 1 functions are ∝ (y, z, x) for m = −1, 0, 1.
        let p = [1usize, 2, 0];
        let mut b1 = vec![0.0; 9];
        for i in 0..3 {
            for j in 0..3 {
                b1[i * 3 + j] = r.col(p[j])[p[i]];
            }
        }
        bands.push(b1);
        for l in 2..order {
            let next = ir_band(l, &bands[1], &bands[l - 1]);
            bands.push(next);
        }
        Self { bands }
    }

    /// Order (number of bands).
    pub fn order(&self) -> usize {
        self.bands.len()
    }

    /// Applies the rotation to `coeffs` (n² entries, n ≤ order).
    pub fn apply(&self, coeffs: &[f64]) -> Vec<f64> {
        let order = (coeffs.len() as f64).sqrt() as usize;
        assert!(order <= self.order(), "rotation built for order {}, got {order}", self.order());
        let mut out = vec![0.0; coeffs.len()];
        for (l, band) in self.bands.iter().enumerate().take(order) {
            let (n, base) = (2 * l + 1, l * l);
            for i in 0..n {
                out[base + i] = (0..n).map(|j| band[i * n + j] * coeffs[base + j]).sum();
            }
        }
        out
    }
}

/// Band `l` of the rotation from band 1 and band l−1 (Ivanic–Ruedenberg).
fn ir_band(l: usize, r1: &[f64], prev: &[f64]) -> Vec<f64> {
    let li = l as i32;
    let n = 2 * l + 1;
    let r1 = |i: i32, j: i32| r1[((i + 1) * 3 + (j + 1)) as usize];
    let pw = 2 * l - 1;
    let rp = |a: i32, b: i32| prev[((a + li - 1) * pw as i32 + (b + li - 1)) as usize];
    let p = |i: i32, a: i32, b: i32| -> f64 {
        if b == li {
            r1(i, 1) * rp(a, li - 1) - r1(i, -1) * rp(a, -li + 1)
        } else if b == -li {
            r1(i, 1) * rp(a, -li + 1) + r1(i, -1) * rp(a, li - 1)
        } else {
            r1(i, 0) * rp(a, b)
        }
    };
    let mut out = vec![0.0; n * n];
    for m in -li..=li {
        for k in -li..=li {
            let d0 = (m == 0) as i32 as f64;
            let denom = if k.abs() == li { (2 * li * (2 * li - 1)) as f64 } else { ((li + k) * (li - k)) as f64 };
            let am = m.abs();
            let u = (((li + m) * (li - m)) as f64 / denom).sqrt();
            let v = 0.5 * ((1.0 + d0) * ((li + am - 1) * (li + am)) as f64 / denom).sqrt() * (1.0 - 2.0 * d0);
            let w = -0.5 * (((li - am - 1) * (li - am)) as f64 / denom).sqrt() * (1.0 - d0);
            let mut val = 0.0;
            if u != 0.0 {
                val += u * p(0, m, k);
            }
            if v != 0.0 {
                val += v * if m == 0 {
                    p(1, 1, k) + p(-1, -1, k)
                } else if m > 0 {
                    let d1 = (m == 1) as i32 as f64;
                    p(1, m - 1, k) * (1.0 + d1).sqrt() - p(-1, -m + 1, k) * (1.0 - d1)
                } else {
                    let d1 = (m == -1) as i32 as f64;
                    p(1, m + 1, k) * (1.0 - d1) + p(-1, -m - 1, k) * (1.0 + d1).sqrt()
                };
            }
            if w != 0.0 {
                val += w * if m > 0 { p(1, m + 1, k) + p(-1, -m - 1, k) } else { p(1, m - 1, k) - p(-1, -m + 1, k) };
            }
            out[((m + li) * n as i32 + (k + li)) as usize] = val;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    fn rotations() -> Vec<DMat3> {
        vec![
            DMat3::from_quat(DQuat::from_euler(glam::EulerRot::ZYZ, 0.3, 1.1, -0.7)),
            DMat3::from_quat(DQuat::from_axis_angle(DVec3::new(1.0, 2.0, -0.5).normalize(), 2.4)),
            DMat3::from_rotation_x(std::f64::consts::FRAC_PI_2),
        ]
    }

    #[test]
    fn orthonormal_to_order_16_by_quadrature() {
        let order = 16;
        let n = num_coeffs(order);
        let mut gram = vec![0.0; n * n];
        let mut y = vec![0.0; n];
        for (d, w) in quadrature::sphere_rule(order + 1) {
            eval_into(order, d, &mut y);
            for i in 0..n {
                for j in 0..n {
                    gram[i * n + j] += w * y[i] * y[j];
                }
            }
        }
        let worst = (0..n * n).map(|k| (gram[k] - if k / n == k % n { 1.0 } else { 0.0 }).abs()).fold(0.0, f64::max);
        assert!(worst < 1e-6, "max |G − I| = {worst:e}");
        assert!(worst < 1e-12, "in fact exact to rounding: {worst:e}");
    }

    #[test]
    fn low_bands_match_closed_forms_without_condon_shortley() {
        let d = DVec3::new(0.3, -0.5, 0.6).normalize();
        let y = eval(3, d);
        let c1 = (3.0 / (4.0 * PI)).sqrt();
        assert!((y[0] - 0.5 / PI.sqrt()).abs() < 1e-15);
        assert!((y[index(1, -1)] - c1 * d.y).abs() < 1e-15, "m = −1 ∝ +y");
        assert!((y[index(1, 0)] - c1 * d.z).abs() < 1e-15);
        assert!((y[index(1, 1)] - c1 * d.x).abs() < 1e-15, "m = +1 ∝ +x");
        let c2 = 0.5 * (15.0 / PI).sqrt();
        assert!((y[index(2, -2)] - c2 * d.x * d.y).abs() < 1e-14);
    }

    #[test]
    fn nan_input_is_clamped() {
        assert_eq!(eval(4, DVec3::NAN), eval(4, DVec3::Z));
    }

    #[test]
    fn poles_are_finite_and_zonal_only() {
        for d in [DVec3::Z, DVec3::NEG_Z] {
            let y = eval(16, d);
            for l in 0..16 {
                for m in -(l as i32)..=l as i32 {
                    let v = y[index(l, m)];
                    assert!(v.is_finite());
                    if m != 0 {
                        assert_eq!(v, 0.0, "only m = 0 is non-zero at the poles");
                    } else {
                        let expect = ((2 * l + 1) as f64 / (4.0 * PI)).sqrt() * d.z.powi(l as i32);
                        assert!((v - expect).abs() < 1e-12, "l {l}: {v} vs {expect}");
                    }
                }
            }
        }
    }

    fn test_function(d: DVec3) -> f64 {
        (3.0 * d.x - d.y * d.z + 0.5).exp() * (1.0 + d.z * d.z * d.x)
    }

    #[test]
    fn rotation_equals_reprojection_of_the_rotated_function() {
        let order = 8;
        for r in rotations() {
            let f = project(order, 24, test_function);
            let rotated = Rotation::new(order, r).apply(&f);
            let rinv = r.transpose();
            let expect = project(order, 24, |d| {
                // Band-limited f: re-project the reconstructed (band-limited) function.
                reconstruct(&f, rinv * d)
            });
            let worst = rotated.iter().zip(&expect).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            assert!(worst < 1e-10, "{worst:e}");
        }
    }

    #[test]
    fn rotations_compose_at_order_16() {
        let order = 16;
        let rs = rotations();
        let (a, b) = (rs[0], rs[1]);
        let f = project(order, 20, test_function);
        let ab = Rotation::new(order, a * b).apply(&f);
        let a_b = Rotation::new(order, a).apply(&Rotation::new(order, b).apply(&f));
        let worst = ab.iter().zip(&a_b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
        assert!(worst < 1e-9, "R(a)R(b) vs R(ab): {worst:e}");
        let back = Rotation::new(order, a.transpose()).apply(&Rotation::new(order, a).apply(&f));
        let worst = back.iter().zip(&f).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
        assert!(worst < 1e-9, "R⁻¹R = I: {worst:e}");
    }

    #[test]
    fn clamped_cosine_convolution_gives_irradiance() {
        let k = clamped_cosine_zonal(5);
        // Known values of sqrt(4π/(2l+1)) k_l: π, 2π/3, π/4, 0, −π/24.
        let a: Vec<f64> = (0..5).map(|l| (4.0 * PI / (2 * l + 1) as f64).sqrt() * k[l]).collect();
        for (got, want) in a.iter().zip([PI, 2.0 * PI / 3.0, PI / 4.0, 0.0, -PI / 24.0]) {
            assert!((got - want).abs() < 1e-12, "{got} vs {want}");
        }
        // A constant radiance 1 gives irradiance π everywhere.
        let mut c = project(5, 8, |_| 1.0);
        convolve_zonal(&mut c, &k);
        assert!((reconstruct(&c, DVec3::new(0.6, 0.0, 0.8)) - PI).abs() < 1e-12);
    }
}
