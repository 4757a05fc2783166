//! Environment lighting in spherical harmonics: projection of an equirectangular map with exact
//! per-texel solid angles and the ringing a window leaves. The window and the rotation of the
//! coefficients into a rigid group's frame (the transfer never moves; the light does) are the
//! run time's ([`kage_runtime::prt`]), re-exported here.

use crate::math::sh;
use crate::scene::EnvironmentLight;
use crate::scene::environment::uv_to_dir;
use glam::{DVec3, Quat, Vec2};
pub use kage_runtime::prt::{Window, fibonacci_direction, to_group_frame};
use rayon::prelude::*;

/// RGB SH coefficients: `coeffs[k]` is the colour of basis function k.
pub type RgbCoeffs = Vec<DVec3>;

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::EnvMap;
    use glam::Vec3;
    use std::f64::consts::PI;

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
