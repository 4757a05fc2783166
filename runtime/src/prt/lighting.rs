//! The environment's lighting as PRT shades it: SH coefficients seen from a rigid group's
//! frame, the band window against ringing, and the regions that cast shadows between groups.

use crate::math::sh;
use crate::pack::schema;
use glam::{DMat3, DVec3, Vec3};
use std::f64::consts::PI;

/// A band-wise window `h_l` applied to reconstructions to tame Gibbs ringing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Window {
    /// No windowing (h_l = 1).
    None,
    /// Hanning: h_l = (1 + cos(π l / n)) / 2 for order n.
    Hanning,
    /// Lanczos σ factors: h_l = sinc(l / n).
    Lanczos,
}

impl Window {
    /// The factor of band `l` at order `order`.
    pub fn factor(self, l: usize, order: usize) -> f64 {
        let x = l as f64 / order as f64;
        match self {
            Window::None => 1.0,
            Window::Hanning => 0.5 * (1.0 + (PI * x).cos()),
            Window::Lanczos if l == 0 => 1.0,
            Window::Lanczos => (PI * x).sin() / (PI * x),
        }
    }

    /// One factor per coefficient (n² entries).
    pub fn per_coeff(self, order: usize) -> Vec<f64> {
        (0..order).flat_map(|l| std::iter::repeat_n(self.factor(l, order), 2 * l + 1)).collect()
    }
}

/// The window as a pack records it.
impl From<Window> for schema::Window {
    fn from(w: Window) -> Self {
        match w {
            Window::None => Self::None,
            Window::Hanning => Self::Hanning,
            Window::Lanczos => Self::Lanczos,
        }
    }
}

/// The window a pack records.
impl From<schema::Window> for Window {
    fn from(w: schema::Window) -> Self {
        match w {
            schema::Window::None => Self::None,
            schema::Window::Hanning => Self::Hanning,
            schema::Window::Lanczos => Self::Lanczos,
        }
    }
}

/// One region of the environment: an area light for shadows cast between groups.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Region {
    /// Power `B_i = ∫_{U_i} L dω` (RGB).
    pub power: DVec3,
    /// Power-weighted centroid direction `w_i` (world, unit).
    pub dir: Vec3,
    /// Solid angle `Ω_i` of the Voronoi region.
    pub solid_angle: f64,
    /// Angular extent of the region's power, `2π · E_power[|d − w_i|²]`, as a solid angle: the
    /// size of the area light it stands for (a sun inside a big sky region is still small).
    /// Equals the solid angle for a uniformly bright disc-shaped region.
    pub spread: f64,
}

/// A region as a pack records it.
impl From<&schema::Region> for Region {
    fn from(r: &schema::Region) -> Self {
        Self {
            power: DVec3::from_array(r.power),
            dir: Vec3::from_array(r.direction),
            solid_angle: r.solid_angle,
            spread: r.spread,
        }
    }
}

/// Coefficients of `f(A d)` given those of `f`, for `A = rotation · mirror` (the world-from-
/// local linear part of a rigid group, scale removed): the lighting seen in the group's frame.
pub fn to_group_frame(coeffs: &[DVec3], rotation: DMat3, mirrored: bool) -> Vec<DVec3> {
    let order = (coeffs.len() as f64).sqrt() as usize;
    // f(R d) has coefficients Rot(Rᵀ)·c (Rotation::new(r) maps f(d) to f(r⁻¹ d)).
    let rot = sh::Rotation::new(order, rotation.transpose());
    let mut out = vec![DVec3::ZERO; coeffs.len()];
    for c in 0..3 {
        let channel: Vec<f64> = coeffs.iter().map(|v| v[c]).collect();
        for (o, v) in out.iter_mut().zip(rot.apply(&channel)) {
            o[c] = v;
        }
    }
    if mirrored {
        // The mirror flips local z: Y_lm(x, y, −z) = (−1)^(l+|m|) Y_lm(x, y, z).
        for l in 0..order {
            for m in -(l as i32)..=l as i32 {
                if (l + m.unsigned_abs() as usize) % 2 == 1 {
                    out[sh::index(l, m)] = -out[sh::index(l, m)];
                }
            }
        }
    }
    out
}

/// Point `i` of `n` on the Fibonacci spiral (well spread, deterministic).
pub fn fibonacci_direction(i: usize, n: usize) -> DVec3 {
    let z = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
    let phi = i as f64 * PI * (3.0 - 5f64.sqrt());
    let r = (1.0 - z * z).max(0.0).sqrt();
    DVec3::new(r * phi.cos(), r * phi.sin(), z)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn group_frame_rotation_matches_reprojection_with_and_without_mirror() {
        let order = 6;
        // A smooth, asymmetric function in bands 0..5.
        let f = |d: DVec3| 1.0 + 0.5 * d.y + 0.3 * d.x * d.z + 0.2 * d.x.powi(3) - 0.1 * d.z * d.y * d.y;
        let world: Vec<DVec3> = sh::project(order, 24, f).into_iter().map(DVec3::splat).collect();
        let q = glam::DQuat::from_euler(glam::EulerRot::YXZ, 0.7, -0.4, 1.9);
        let r = DMat3::from_quat(q);
        for mirrored in [false, true] {
            let got = to_group_frame(&world, r, mirrored);
            let a = if mirrored { r * DMat3::from_diagonal(DVec3::new(1.0, 1.0, -1.0)) } else { r };
            let want = sh::project(order, 24, |d| f(a * d));
            for (g, w) in got.iter().zip(&want) {
                assert!((g.x - w).abs() < 1e-9, "mirrored {mirrored}: {} vs {w}", g.x);
            }
        }
    }

    #[test]
    fn windows_keep_band_zero_and_cover_every_coefficient() {
        for w in [Window::None, Window::Hanning, Window::Lanczos] {
            assert_eq!(w.factor(0, 8), 1.0);
            assert_eq!(w.per_coeff(3).len(), 9);
            assert!(w.per_coeff(8).windows(2).all(|p| p[1] <= p[0]), "{w:?} decreases with the band");
            assert_eq!(Window::from(schema::Window::from(w)), w);
        }
    }
}
