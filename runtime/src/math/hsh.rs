//! Hemispherical harmonics (Gautron et al. 2004) over the upper (+Z) hemisphere.
//!
//! Convention (docs/conventions.md): `P̃_n^m(cos θ) = P_n^m(2 cos θ − 1)`,
//! `K̃_nm = sqrt((2n+1)/(2π) · (n−|m|)!/(n+|m|)!)`, `H_nm = √2 K̃ P̃^|m| cos(mφ)` (m > 0),
//! `√2 K̃ P̃^|m| sin(|m|φ)` (m < 0), `K̃ P̃^0` (m = 0); index and "order" as for SH.
//!
//! Since K̃ = √2 K, `H_nm(θ, φ) = √2 Y_nm(θ', φ)` with cos θ' = 2 cos θ − 1. In Cartesian
//! form sin θ' e^{iφ} = g(z) (x + iy) with `g(z) = 2 sqrt(z / (1 + z))`, so
//! `H_nm = √2 Q̄_nm(2z − 1) · g(z)^|m| · Re/Im((x + iy)^|m|)` — no division by sin θ anywhere.
//!
//! The translational gradient terms (seed H11–H18) are the derivatives of H along a fixed hit
//! point's direction when the record moves in its tangent plane: for a hit at distance r,
//! `∂H/∂x = −(1/r) [∇H − (d·∇H) d]_x` (tangential gradient on the unit sphere). The one
//! singular factor, dg^m/dz ∝ z^{m/2−1} at the horizon, only ever appears multiplied by
//! d_z, and `z · d(g^m)/dz = m g^m / (2(1 + z))` is evaluated in that product form.

use crate::math::{quadrature, sh};
use glam::{DMat3, DVec3};
use std::f64::consts::SQRT_2;

/// Number of coefficients of order `n` (n²).
pub use sh::{index, num_coeffs};

/// Per (l, m ≥ 0): Q̄_lm(2z − 1), its z-derivative, and g(z)^m and z·d(g^m)/dz.
struct Parts {
    q: Vec<f64>,
    dq: Vec<f64>,
}

fn parts(order: usize, z: f64) -> Parts {
    let n = num_coeffs(order);
    let (mut q, mut dq) = (vec![0.0; n], vec![0.0; n]);
    let x = 2.0 * z - 1.0;
    sh::legendre_q(order, x, &mut q);
    // dQ̄/dx by the same recurrence differentiated: Q̄'_lm = a (Q̄_{l−1} + x Q̄'_{l−1} − b Q̄'_{l−2}).
    for m in 0..order {
        let mi = m as i32;
        if m + 1 < order {
            dq[index(m + 1, mi)] = ((2 * m + 3) as f64).sqrt() * q[index(m, mi)];
        }
        for l in m + 2..order {
            let (a, b) = sh::recurrence(l, m);
            dq[index(l, mi)] = a * (q[index(l - 1, mi)] + x * dq[index(l - 1, mi)] - b * dq[index(l - 2, mi)]);
        }
    }
    // d/dz = 2 d/dx.
    dq.iter_mut().for_each(|v| *v *= 2.0);
    Parts { q, dq }
}

/// Clamps a direction into the closed upper hemisphere (z ≥ 0) and normalises it.
fn upper(d: DVec3) -> DVec3 {
    let d = DVec3::new(d.x, d.y, d.z.max(0.0));
    let len = d.length();
    if len > 0.0 && len.is_finite() { d / len } else { DVec3::Z }
}

/// Evaluates all n² HSH at direction `d` (local frame, +Z up). Directions below the horizon
/// are clamped onto it; non-finite input evaluates at the pole (documented clamp).
pub fn eval(order: usize, d: DVec3) -> Vec<f64> {
    let d = upper(d);
    let p = parts(order, d.z);
    let g = 2.0 * (d.z / (1.0 + d.z)).sqrt();
    let mut out = vec![0.0; num_coeffs(order)];
    let (mut re, mut im, mut gm) = (1.0, 0.0, 1.0);
    for m in 0..order {
        if m > 0 {
            (re, im) = (re * d.x - im * d.y, re * d.y + im * d.x);
            gm *= g;
        }
        for l in m..order {
            let q = p.q[index(l, m as i32)];
            if m == 0 {
                out[index(l, 0)] = SQRT_2 * q;
            } else {
                out[index(l, m as i32)] = 2.0 * q * gm * re;
                out[index(l, -(m as i32))] = 2.0 * q * gm * im;
            }
        }
    }
    out
}

/// Translational gradient terms `(r ∂H/∂x, r ∂H/∂y)` for a hit in direction `d` (local frame)
/// at distance r, when the record moves along its tangent x and y axes.
pub fn gradient_terms(order: usize, d: DVec3) -> (Vec<f64>, Vec<f64>) {
    let d = upper(d);
    let z = d.z;
    let p = parts(order, z);
    let g = 2.0 * (z / (1.0 + z)).sqrt();
    let n = num_coeffs(order);
    let (mut gx, mut gy) = (vec![0.0; n], vec![0.0; n]);
    // (x+iy)^m and m (x+iy)^(m−1), g^m and z·d(g^m)/dz.
    let (mut re, mut im) = (1.0, 0.0);
    let (mut re1, mut im1) = (0.0, 0.0);
    let mut gm = 1.0;
    for m in 0..order {
        if m > 0 {
            (re1, im1) = (re, im); // (x+iy)^(m−1)
            (re, im) = (re * d.x - im * d.y, re * d.y + im * d.x);
            gm *= g;
        }
        let mf = m as f64;
        let z_dgm = mf * gm / (2.0 * (1.0 + z));
        for l in m..order {
            let (q, dq) = (p.q[index(l, m as i32)], p.dq[index(l, m as i32)]);
            // H = c · q(z) · gm(z) · R(x, y) with R = Re or Im of (x+iy)^m.
            // ∇H = c [q gm ∂R/∂x, q gm ∂R/∂y, (dq gm + q gm') R];  d_z ∂H/∂z uses z gm' in product form.
            let c = if m == 0 { SQRT_2 } else { 2.0 };
            let mut emit = |k: usize, r: f64, drx: f64, dry: f64| {
                let hx = c * q * gm * drx;
                let hy = c * q * gm * dry;
                let z_hz = c * (z * dq * gm + q * z_dgm) * r;
                let radial = d.x * hx + d.y * hy + z_hz;
                gx[k] = -(hx - d.x * radial);
                gy[k] = -(hy - d.y * radial);
            };
            if m == 0 {
                emit(index(l, 0), 1.0, 0.0, 0.0);
            } else {
                // ∂/∂x (x+iy)^m = m (x+iy)^(m−1); ∂/∂y = i m (x+iy)^(m−1).
                emit(index(l, m as i32), re, mf * re1, -mf * im1);
                emit(index(l, -(m as i32)), im, mf * im1, mf * re1);
            }
        }
    }
    (gx, gy)
}

/// Projects a hemispherical function onto HSH with `nodes` Gauss–Legendre nodes in cos θ.
pub fn project(order: usize, nodes: usize, f: impl Fn(DVec3) -> f64) -> Vec<f64> {
    let mut c = vec![0.0; num_coeffs(order)];
    for (d, w) in quadrature::hemisphere_rule(nodes) {
        let h = eval(order, d);
        let fw = f(d) * w;
        c.iter_mut().zip(&h).for_each(|(c, h)| *c += fw * h);
    }
    c
}

/// Reconstructs Σ c_k H_k(d).
pub fn reconstruct(coeffs: &[f64], d: DVec3) -> f64 {
    let order = (coeffs.len() as f64).sqrt() as usize;
    eval(order, d).iter().zip(coeffs).map(|(h, c)| h * c).sum()
}

/// Conversion between HSH of order `n` and SH of order `l_order`, for rotation.
///
/// HSH → SH projects the **even extension** of the hemispherical function (mirrored through
/// the horizon plane, f(x, y, −z) = f(x, y, z)) rather than its zero extension: the mirrored
/// function is continuous at the horizon, so its SH series converges fast instead of ringing
/// (zero extension loses ~0.12 per coefficient at SH order 16; see the tests).
/// SH → HSH is the least-squares fit on the upper hemisphere, `∫_{H+} H_j Y_k`.
#[derive(Clone, Debug)]
pub struct Conversion {
    hsh_order: usize,
    sh_order: usize,
    /// `∫_{H+} Y_k H_j`, SH-count × HSH-count, row-major.
    overlap: Vec<f64>,
    /// Per SH band l, the clamped cosine's Funk–Hecke factor `sqrt(4π/(2l+1)) k_l`.
    cosine: Vec<f64>,
}

impl Conversion {
    /// Builds the overlap integrals by quadrature (odd-m integrands are not polynomial in
    /// cos θ, so a generous rule is used).
    pub fn new(hsh_order: usize, sh_order: usize) -> Self {
        let (nh, ns) = (num_coeffs(hsh_order), num_coeffs(sh_order));
        let mut overlap = vec![0.0; ns * nh];
        let mut y = vec![0.0; ns];
        for (d, w) in quadrature::hemisphere_rule(4 * (hsh_order + sh_order) + 32) {
            let h = eval(hsh_order, d);
            sh::eval_into(sh_order, d, &mut y);
            for k in 0..ns {
                for j in 0..nh {
                    overlap[k * nh + j] += w * y[k] * h[j];
                }
            }
        }
        let cosine = sh::clamped_cosine_zonal(sh_order)
            .iter()
            .enumerate()
            .map(|(l, k)| (4.0 * std::f64::consts::PI / (2 * l + 1) as f64).sqrt() * k)
            .collect();
        Self { hsh_order, sh_order, overlap, cosine }
    }

    /// The irradiance at unit normal `n` (in the coefficients' own frame) as a functional of
    /// HSH coefficients `c`: `g` with `Σ_j c_j g_j = ∫ f(ω) max(0, n·ω) dω`, f the SH of `c`'s
    /// even extension. The same as rotating `c` into a frame about `n` ([`Self::rotate`]) and
    /// integrating the cosine there, without building the rotation (Funk–Hecke).
    pub fn irradiance_functional(&self, n: DVec3) -> Vec<f64> {
        let (nh, ns) = (num_coeffs(self.hsh_order), num_coeffs(self.sh_order));
        let y = sh::eval(self.sh_order, n);
        let mut g = vec![0.0; nh];
        for (k, y) in y.iter().enumerate().take(ns) {
            let l = (k as f64).sqrt() as usize;
            // Odd l + m: zero in the even extension (see `hsh_to_sh`).
            if (k - l * l) % 2 == 1 {
                continue;
            }
            let z = 2.0 * y * self.cosine[l];
            g.iter_mut().zip(&self.overlap[k * nh..(k + 1) * nh]).for_each(|(g, o)| *g += o * z);
        }
        g
    }

    /// HSH coefficients → SH coefficients of the even extension: Y_lm is even in z when
    /// l + m is even, and then ∫_S Y f_even = 2 ∫_{H+} Y f; odd ones integrate to zero.
    pub fn hsh_to_sh(&self, c: &[f64]) -> Vec<f64> {
        let (nh, ns) = (num_coeffs(self.hsh_order), num_coeffs(self.sh_order));
        (0..ns)
            .map(|k| {
                let l = (k as f64).sqrt() as usize;
                let m = k as i64 - (l * (l + 1)) as i64;
                if (l as i64 + m).rem_euclid(2) == 1 {
                    return 0.0;
                }
                2.0 * (0..nh).map(|j| self.overlap[k * nh + j] * c[j]).sum::<f64>()
            })
            .collect()
    }

    /// SH coefficients → HSH coefficients (least squares on the upper hemisphere).
    pub fn sh_to_hsh(&self, c: &[f64]) -> Vec<f64> {
        let (nh, ns) = (num_coeffs(self.hsh_order), num_coeffs(self.sh_order));
        (0..nh).map(|j| (0..ns).map(|k| self.overlap[k * nh + j] * c[k]).sum()).collect()
    }

    /// Rotates HSH coefficients by `r` through SH: HSH → SH → rotate → HSH. Exact only in the
    /// limit of a high SH order (the zero-extended function is not band-limited).
    pub fn rotate(&self, c: &[f64], r: DMat3) -> Vec<f64> {
        self.rotate_by(&sh::Rotation::new(self.sh_order, r), c)
    }

    /// [`Self::rotate`] of each channel of RGB coefficients, building the rotation once.
    pub fn rotate_rgb(&self, c: &[DVec3], r: DMat3) -> Vec<DVec3> {
        let rot = sh::Rotation::new(self.sh_order, r);
        let mut out = vec![DVec3::ZERO; c.len()];
        for ch in 0..3 {
            let channel: Vec<f64> = c.iter().map(|v| v[ch]).collect();
            out.iter_mut().zip(self.rotate_by(&rot, &channel)).for_each(|(o, v)| o[ch] = v);
        }
        out
    }

    fn rotate_by(&self, rot: &sh::Rotation, c: &[f64]) -> Vec<f64> {
        self.sh_to_hsh(&rot.apply(&self.hsh_to_sh(c)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn orthonormal_over_the_hemisphere() {
        let order = 8;
        let n = num_coeffs(order);
        let mut gram = vec![0.0; n * n];
        // Odd m carries sqrt(z(1−z)) factors: use many nodes.
        for (d, w) in quadrature::hemisphere_rule(200) {
            let h = eval(order, d);
            for i in 0..n {
                for j in 0..n {
                    gram[i * n + j] += w * h[i] * h[j];
                }
            }
        }
        let worst = (0..n * n).map(|k| (gram[k] - if k / n == k % n { 1.0 } else { 0.0 }).abs()).fold(0.0, f64::max);
        assert!(worst < 1e-6, "max |G − I| = {worst:e}");
    }

    #[test]
    fn matches_the_design_formula() {
        // H_11 = √2 K̃_11 P_1^1(2c − 1) cos φ with P_1^1(x) = sqrt(1 − x²) (no Condon–Shortley).
        let (theta, phi) = (0.7f64, 2.1f64);
        let d = DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
        let x = 2.0 * theta.cos() - 1.0;
        let k11 = (3.0 / (2.0 * PI) / 2.0).sqrt();
        let h = eval(3, d);
        assert!((h[index(1, 1)] - SQRT_2 * k11 * (1.0 - x * x).sqrt() * phi.cos()).abs() < 1e-14);
        assert!((h[index(1, -1)] - SQRT_2 * k11 * (1.0 - x * x).sqrt() * phi.sin()).abs() < 1e-14);
        let k10 = (3.0 / (2.0 * PI)).sqrt();
        assert!((h[index(1, 0)] - k10 * x).abs() < 1e-14);
    }

    /// Central finite difference of H along the record's x / y motion, hit at unit distance.
    fn fd(order: usize, d: DVec3, axis: DVec3, h: f64) -> Vec<f64> {
        let plus = eval(order, (d - axis * h).normalize());
        let minus = eval(order, (d + axis * h).normalize());
        plus.iter().zip(&minus).map(|(a, b)| (a - b) / (2.0 * h)).collect()
    }

    #[test]
    fn gradient_terms_equal_finite_differences() {
        let order = 7;
        for (theta, phi) in [(0.3f64, 0.4f64), (1.0, 2.5), (1.4, -1.0), (0.05, 3.0)] {
            let d = DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
            let (gx, gy) = gradient_terms(order, d);
            for (g, axis) in [(&gx, DVec3::X), (&gy, DVec3::Y)] {
                let f = fd(order, d, axis, 1e-6);
                for k in 0..g.len() {
                    assert!((g[k] - f[k]).abs() < 1e-6 + 1e-5 * f[k].abs(), "θ {theta} k {k}: {} vs {}", g[k], f[k]);
                }
            }
        }
    }

    #[test]
    fn gradient_terms_near_pole_and_horizon() {
        let order = 8;
        for theta in [1e-6f64, std::f64::consts::FRAC_PI_2 - 1e-6] {
            let d = DVec3::new(theta.sin() * 0.6, theta.sin() * 0.8, theta.cos());
            let (gx, gy) = gradient_terms(order, d);
            assert!(gx.iter().chain(&gy).all(|v| v.is_finite()));
            // The finite difference must stay on the upper hemisphere: a step far below 1e-6.
            for (g, axis) in [(&gx, DVec3::X), (&gy, DVec3::Y)] {
                let f = fd(order, d, axis, 1e-9);
                for k in 0..g.len() {
                    assert!((g[k] - f[k]).abs() < 2e-4 + 1e-3 * f[k].abs(), "θ {theta:e} k {k}: {} vs {}", g[k], f[k]);
                }
            }
        }
    }

    #[test]
    fn bad_directions_are_clamped_not_nan() {
        for d in [DVec3::NAN, DVec3::new(0.0, 0.0, -1.0), DVec3::new(1.0, 0.0, -0.5), DVec3::ZERO] {
            assert!(eval(6, d).iter().all(|v| v.is_finite()));
            let (a, b) = gradient_terms(6, d);
            assert!(a.iter().chain(&b).all(|v| v.is_finite()));
        }
    }

    #[test]
    fn projection_round_trips_and_rotation_through_sh() {
        let order = 5;
        // Representable exactly: a quadratic in cos θ plus one m = 1 basis function.
        let f = |d: DVec3| 1.0 + 0.2 * d.z + 0.3 * d.z * d.z + 0.5 * eval(3, d)[index(2, 1)];
        let c = project(order, 40, f);
        for d in [DVec3::new(0.1, 0.2, 0.97).normalize(), DVec3::new(0.7, -0.6, 0.3).normalize()] {
            assert!((reconstruct(&c, d) - f(d)).abs() < 1e-12);
        }
        // The identity rotation through SH of order 16 reproduces the HSH coefficients.
        let conv = Conversion::new(order, 16);
        let back = conv.rotate(&c, DMat3::IDENTITY);
        let err = back.iter().zip(&c).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        eprintln!("HSH(5) → SH(16) → HSH: max coefficient error {err:e}");
        assert!(err < 1e-2, "HSH→SH(16)→HSH loses {err}");
        // RGB rotates each channel as `rotate` does, bit for bit, with one rotation.
        let turn = DMat3::from_axis_angle(DVec3::new(0.3, 0.4, 0.5).normalize(), 0.7);
        let rgb: Vec<DVec3> = c.iter().enumerate().map(|(k, &v)| DVec3::new(v, -v, k as f64)).collect();
        let by_channel: Vec<Vec<f64>> =
            (0..3).map(|ch| conv.rotate(&rgb.iter().map(|v| v[ch]).collect::<Vec<_>>(), turn)).collect();
        let together = conv.rotate_rgb(&rgb, turn);
        assert!(together.iter().enumerate().all(|(k, v)| (0..3).all(|ch| v[ch] == by_channel[ch][k])));
        assert!(together.iter().zip(&rgb).any(|(a, b)| (*a - *b).length() > 1e-3), "the turn changes them");
    }

    /// The irradiance functional at a normal equals rotating the coefficients into a frame about
    /// that normal and integrating the cosine there (HSH order 3 holds cos θ exactly), for
    /// normals near the frame's pole, tilted, grazing and below its horizon.
    #[test]
    fn irradiance_functional_equals_rotating_then_integrating() {
        let (order, conv) = (3, Conversion::new(3, 8));
        let cosine = project(order, 64, |d| d.z);
        let c: Vec<f64> =
            (0..num_coeffs(order)).map(|k| [1.0, -0.3, 0.5, 0.2, -0.1, 0.4, 0.05, -0.2, 0.1][k]).collect();
        for (axis, angle) in
            [(DVec3::X, 0.05), (DVec3::new(0.3, 0.4, 0.5), 0.7), (DVec3::Y, 1.5), (DVec3::new(1.0, -1.0, 0.2), 2.2)]
        {
            // Receiver-local from record-local, as the cache builds it: the receiver's normal
            // in the record's frame is its transpose applied to +Z.
            let r = DMat3::from_axis_angle(axis.normalize(), angle);
            let rotated: f64 = conv.rotate(&c, r).iter().zip(&cosine).map(|(a, h)| a * h).sum();
            let g = conv.irradiance_functional(r.transpose() * DVec3::Z);
            let direct: f64 = c.iter().zip(&g).map(|(a, g)| a * g).sum();
            assert!((direct - rotated).abs() < 1e-9 * (1.0 + rotated.abs()), "turn {angle}: {direct} vs {rotated}");
        }
    }
}
