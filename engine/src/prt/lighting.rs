//! Environment lighting in spherical harmonics: projection of an equirectangular map with exact
//! per-texel solid angles, windowing against ringing, and the rotation of the coefficients into
//! a rigid group's frame (the transfer never moves; the light does).

use crate::math::sh;
use crate::scene::EnvironmentLight;
use crate::scene::environment::uv_to_dir;
use glam::{DMat3, DVec3, Quat, Vec2};
use kage_runtime::pack::schema;
use rayon::prelude::*;
use std::f64::consts::PI;

/// RGB SH coefficients: `coeffs[k]` is the colour of basis function k.
pub type RgbCoeffs = Vec<DVec3>;

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

impl crate::named::Named for Window {
    const ALL: &'static [Window] = &[Window::None, Window::Hanning, Window::Lanczos];

    fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Hanning => "hanning",
            Self::Lanczos => "lanczos",
        }
    }

    fn about(self) -> &'static str {
        match self {
            Self::None => "no window",
            Self::Hanning => "Hanning window",
            Self::Lanczos => "Lanczos σ factors",
        }
    }
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

/// Direction and exact solid angle of every texel of an environment's map, in world space
/// (the light's rotation applied), with its radiance (intensity applied).
pub fn texels(env: &EnvironmentLight) -> Vec<(DVec3, f64, DVec3)> {
    let map = &env.map;
    let (w, h) = (map.width, map.height);
    let rot = Quat::from_rotation_y(env.rotation);
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let omega = crate::scene::environment::texel_solid_angle(y, w, h);
            let uv = Vec2::new((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
            let d = (rot * uv_to_dir(uv)).as_dvec3().normalize();
            (d, omega, (map.texels[i] * env.intensity).as_dvec3())
        })
        .collect()
}

/// SH coefficients (order `order`) of the environment's radiance, world frame.
pub fn project(env: &EnvironmentLight, order: usize) -> RgbCoeffs {
    let n = sh::num_coeffs(order);
    // Partial sums per fixed-size chunk, added in order: the same bits on any thread count.
    let partials: Vec<RgbCoeffs> = texels(env)
        .par_chunks(4096)
        .map(|chunk| {
            let mut y = vec![0.0; n];
            let mut acc = vec![DVec3::ZERO; n];
            for &(d, omega, l) in chunk {
                sh::eval_into(order, d, &mut y);
                acc.iter_mut().zip(&y).for_each(|(a, y)| *a += l * (omega * y));
            }
            acc
        })
        .collect();
    partials.iter().fold(vec![DVec3::ZERO; n], |a, b| a.iter().zip(b).map(|(a, b)| *a + *b).collect())
}

/// How far a (windowed) reconstruction of the lighting goes negative.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NegativeLobes {
    /// Most negative luminance over the sphere, relative to the mean luminance.
    pub min_relative: f64,
    /// Fraction of directions where the luminance is negative.
    pub fraction: f64,
}

/// Measures the negative lobes of `coeffs` windowed by `window`, on a 4096-direction spiral.
pub fn negative_lobes(coeffs: &[DVec3], window: Window) -> NegativeLobes {
    let order = (coeffs.len() as f64).sqrt() as usize;
    let h = window.per_coeff(order);
    let lum = |c: DVec3| 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
    let mean = lum(coeffs[0]) * sh::eval(1, DVec3::Z)[0];
    const N: usize = 4096;
    let mut y = vec![0.0; coeffs.len()];
    let (mut min, mut negative) = (f64::INFINITY, 0usize);
    for i in 0..N {
        sh::eval_into(order, fibonacci_direction(i, N), &mut y);
        let v: f64 = coeffs.iter().zip(&y).zip(&h).map(|((c, y), h)| lum(*c) * y * h).sum();
        min = min.min(v);
        negative += usize::from(v < 0.0);
    }
    let min_relative = if mean > 0.0 { min.min(0.0) / mean } else { 0.0 };
    NegativeLobes { min_relative, fraction: negative as f64 / N as f64 }
}

/// Point `i` of `n` on the Fibonacci spiral (well spread, deterministic).
pub fn fibonacci_direction(i: usize, n: usize) -> DVec3 {
    let z = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
    let phi = i as f64 * PI * (3.0 - 5f64.sqrt());
    let r = (1.0 - z * z).max(0.0).sqrt();
    DVec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Coefficients of `f(A d)` given those of `f`, for `A = rotation · mirror` (the world-from-
/// local linear part of a rigid group, scale removed): the lighting seen in the group's frame.
pub fn to_group_frame(coeffs: &[DVec3], rotation: DMat3, mirrored: bool) -> RgbCoeffs {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::EnvMap;
    use glam::Vec3;

    fn sky() -> EnvironmentLight {
        let mut env = EnvironmentLight::new(EnvMap::procedural_sky(128, 64, Vec3::new(0.4, 0.5, -0.3)));
        env.rotation = 0.6;
        env.intensity = 1.7;
        env
    }

    #[test]
    fn texel_solid_angles_sum_to_the_sphere() {
        let total: f64 = texels(&sky()).iter().map(|t| t.1).sum();
        assert!((total - 4.0 * PI).abs() < 1e-9, "{total}");
    }

    #[test]
    fn constant_environment_projects_to_band_zero_only() {
        let env = EnvironmentLight::new(EnvMap::new(256, 128, vec![Vec3::splat(2.0); 256 * 128], "c".into()).unwrap());
        let c = project(&env, 4);
        // ∫ 2 Y00 = 2 √(4π) exactly (solid angles are exact); higher bands vanish up to the
        // texel-centre rule's error, O(1/height²).
        assert!((c[0].x - 2.0 * (4.0 * PI).sqrt()).abs() < 1e-9);
        assert!(c[1..].iter().all(|v| v.length() < 1e-4 * c[0].x), "{c:?}");
    }

    #[test]
    fn projection_reconstructs_a_band_limited_map() {
        // L = 1 + 0.5 y + 0.3 x z lies in bands 0..2: order 3 holds it (up to the texel rule).
        let f = |d: Vec3| 1.0 + 0.5 * d.y + 0.3 * d.x * d.z;
        let (w, h) = (512, 256);
        let t = (0..w * h)
            .map(|i| {
                let uv = Vec2::new(((i % w) as f32 + 0.5) / w as f32, ((i / w) as f32 + 0.5) / h as f32);
                Vec3::splat(f(uv_to_dir(uv)))
            })
            .collect();
        let mut env = EnvironmentLight::new(EnvMap::new(w, h, t, "smooth".into()).unwrap());
        env.rotation = 0.9;
        let c = project(&env, 3);
        for i in 0..200 {
            let d = fibonacci_direction(i, 200);
            let got: f64 = sh::eval(3, d).iter().zip(&c).map(|(y, c)| y * c.y).sum();
            let want = f((glam::Quat::from_rotation_y(-0.9) * d.as_vec3()).normalize()) as f64;
            assert!((got - want).abs() < 2e-3, "{got} vs {want}");
        }
    }

    #[test]
    fn group_frame_rotation_matches_reprojection_with_and_without_mirror() {
        let env = sky();
        let order = 6;
        let world = project(&env, order);
        let q = glam::DQuat::from_euler(glam::EulerRot::YXZ, 0.7, -0.4, 1.9);
        let r = DMat3::from_quat(q);
        for mirrored in [false, true] {
            let got = to_group_frame(&world, r, mirrored);
            let a = if mirrored { r * DMat3::from_diagonal(DVec3::new(1.0, 1.0, -1.0)) } else { r };
            // Reference: reconstruct the world coefficients at A·d.
            let want =
                sh::project(order, 24, |d| sh::reconstruct(&world.iter().map(|c| c.x).collect::<Vec<_>>(), a * d));
            for (g, w) in got.iter().zip(&want) {
                assert!((g.x - w).abs() < 1e-9, "mirrored {mirrored}: {} vs {w}", g.x);
            }
        }
    }

    #[test]
    fn windows_damp_ringing_of_a_sun() {
        let mut texels = vec![Vec3::splat(0.1); 64 * 32];
        texels[10 * 64 + 20] = Vec3::splat(1e5);
        let env = EnvironmentLight::new(EnvMap::new(64, 32, texels, "sun".into()).unwrap());
        let c = project(&env, 8);
        let raw = negative_lobes(&c, Window::None);
        let hann = negative_lobes(&c, Window::Hanning);
        assert!(raw.min_relative < -0.1, "{raw:?}");
        assert!(hann.min_relative > raw.min_relative * 0.5, "{hann:?} vs {raw:?}");
        assert_eq!(Window::Hanning.factor(0, 8), 1.0);
        assert_eq!(Window::Lanczos.per_coeff(3).len(), 9);
    }
}
