//! The glTF metallic-roughness BSDF (`docs/conventions.md`) in the local shading frame (+Z = shading normal):
//! `f = diffuse · (1 − E_dielectric(μo)) / π + GGX specular with Schlick(F0, F90)`.
//!
//! The diffuse lobe is evaluated whenever ωi is above the surface, whatever the side of ωo
//! (a vertex seen from behind still reports its Lambertian radiance); the specular lobe needs
//! both above.

use super::Material;
use crate::math::{ggx, luminance, sampling};
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// A material's BSDF at one shading point, for one outgoing direction.
#[derive(Clone, Copy, Debug)]
pub struct Bsdf {
    diffuse: Vec3,
    f0: Vec3,
    f90: Vec3,
    alpha: f32,
    /// Probability of sampling the specular lobe.
    p_spec: f32,
    /// [`Material::has_specular`] of the material.
    specular: bool,
}

impl Bsdf {
    /// The BSDF of `m` seen from local direction `wo`.
    pub fn new(m: &Material, wo: Vec3) -> Self {
        let metallic = m.metallic.clamp(0.0, 1.0);
        let s = m.specular.max(0.0);
        let dielectric_f0 = Vec3::splat(0.04 * s);
        let f0 = dielectric_f0.lerp(m.base_color, metallic);
        let f90 = Vec3::splat(s).lerp(Vec3::ONE, metallic);
        let mu = wo.z.abs();
        let e_dielectric = ggx::directional_albedo(mu, m.roughness, dielectric_f0, Vec3::splat(s));
        let diffuse = m.base_color * (1.0 - metallic) * (Vec3::ONE - e_dielectric).max(Vec3::ZERO) / PI;
        let specular = m.has_specular();
        let spec_albedo =
            if wo.z > 0.0 && specular { luminance(ggx::directional_albedo(mu, m.roughness, f0, f90)) } else { 0.0 };
        let diffuse_albedo = luminance(diffuse) * PI;
        let total = spec_albedo + diffuse_albedo;
        let p_spec = if total > 0.0 { spec_albedo / total } else { 0.0 };
        Self { diffuse, f0, f90, alpha: ggx::alpha_from_roughness(m.roughness), p_spec, specular }
    }

    /// Diffuse albedo (base colour × (1 − metallic) × (1 − dielectric albedo)).
    pub fn diffuse_albedo(&self) -> Vec3 {
        self.diffuse * PI
    }

    /// Fresnel reflectance at normal incidence.
    pub fn f0(&self) -> Vec3 {
        self.f0
    }

    /// Fresnel reflectance at grazing incidence.
    pub fn f90(&self) -> Vec3 {
        self.f90
    }

    /// True when the material has a specular lobe ([`Material::has_specular`]).
    pub fn has_specular(&self) -> bool {
        self.specular
    }

    /// True when the BSDF reflects nothing (e.g. a black emitter's back).
    pub fn is_black(&self) -> bool {
        self.diffuse == Vec3::ZERO && self.p_spec == 0.0
    }

    /// f(ωo, ωi) without the cosine.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        let spec = if self.p_spec > 0.0 { ggx::eval(wo, wi, self.alpha, self.f0, self.f90) } else { Vec3::ZERO };
        self.diffuse + spec
    }

    /// Solid-angle pdf of [`Self::sample`] producing ωi.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wi.z <= 0.0 {
            return 0.0;
        }
        let spec = if self.p_spec > 0.0 { ggx::pdf(wo, wi, self.alpha) } else { 0.0 };
        self.p_spec * spec + (1.0 - self.p_spec) * sampling::cosine_hemisphere_pdf(wi)
    }

    /// Samples ωi: picks a lobe with `u_lobe`, then a direction with `u`.
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<Vec3> {
        if self.is_black() {
            return None;
        }
        if u_lobe < self.p_spec { ggx::sample(wo, self.alpha, u) } else { Some(sampling::cosine_hemisphere(u)) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng;
    use rand::Rng;

    /// One definition: the BSDF has a specular lobe exactly when its material says so, and a
    /// black metal has one (F0 black, F90 1: it reflects at grazing angles).
    #[test]
    fn the_bsdf_and_its_material_agree_on_the_specular_lobe() {
        for metallic in [0.0, 1e-6, 0.5, 1.0] {
            for specular in [0.0, 1e-6, 1.0] {
                for base_color in [Vec3::ZERO, Vec3::splat(0.5)] {
                    let m = Material { base_color, metallic, roughness: 0.4, specular };
                    let wo = Vec3::new(0.6, 0.0, 0.8);
                    let b = Bsdf::new(&m, wo);
                    assert_eq!(b.has_specular(), m.has_specular(), "{m:?}");
                    let grazing = Vec3::new(-0.95, 0.0, 0.05).normalize();
                    let lobe = b.eval(Vec3::new(0.95, 0.0, 0.05).normalize(), grazing) - b.diffuse;
                    assert_eq!(lobe.max_element() > 0.0, m.has_specular(), "{m:?}: {lobe}");
                }
            }
        }
        let black_metal = Material { base_color: Vec3::ZERO, metallic: 1.0, roughness: 0.4, specular: 0.0 };
        assert!(black_metal.has_specular());
    }

    #[test]
    fn lambertian_material_is_exactly_lambertian() {
        let b = Bsdf::new(&Material::lambertian(Vec3::splat(0.5)), Vec3::new(0.6, 0.0, 0.8));
        let f = b.eval(Vec3::new(0.6, 0.0, 0.8), Vec3::new(-0.3, 0.1, 0.9).normalize());
        assert!((f - Vec3::splat(0.5 / PI)).abs().max_element() < 1e-7);
    }

    #[test]
    fn albedo_never_exceeds_one_white_furnace() {
        let mut r = rng::seeded(9);
        for m in [
            Material { base_color: Vec3::ONE, metallic: 0.0, roughness: 0.5, specular: 1.0 },
            Material { base_color: Vec3::ONE, metallic: 1.0, roughness: 0.3, specular: 1.0 },
            Material { base_color: Vec3::ONE, metallic: 0.0, roughness: 1.0, specular: 1.0 },
        ] {
            for mu in [0.1f32, 0.5, 1.0] {
                let wo = Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
                let b = Bsdf::new(&m, wo);
                let n = 200_000;
                let mut s = 0.0f64;
                for _ in 0..n {
                    if let Some(wi) = b.sample(wo, r.random(), Vec2::new(r.random(), r.random())) {
                        let p = b.pdf(wo, wi);
                        if p > 0.0 {
                            s += (b.eval(wo, wi).x * wi.z / p) as f64;
                        }
                    }
                }
                let albedo = s / n as f64;
                assert!(albedo <= 1.01, "{m:?} mu {mu}: {albedo}");
                assert!(albedo > 0.6, "{m:?} mu {mu}: {albedo}");
            }
        }
    }
}
