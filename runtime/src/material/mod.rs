//! Materials as the shading reads them: glTF metallic-roughness factors ([`Material`]) and the
//! BSDF they make ([`Bsdf`]).
//!
//! One definition of "has a specular lobe": [`Material::has_specular`] (metallic, or a
//! dielectric with specularFactor > 0); [`Bsdf::has_specular`] reports the same. A black metal
//! has one: its F0 is black, but Schlick's F90 is 1, so it reflects at grazing angles.

use glam::Vec3;

mod bsdf;

pub use bsdf::Bsdf;

/// glTF metallic-roughness material (factors only; see `docs/conventions.md` for the BRDF).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Linear base colour.
    pub base_color: Vec3,
    /// Metalness in [0, 1].
    pub metallic: f32,
    /// Perceptual roughness in [0, 1] (α = roughness²).
    pub roughness: f32,
    /// `KHR_materials_specular` specularFactor (1 when absent).
    pub specular: f32,
}

impl Default for Material {
    /// glTF's default material: white, metallic 1, roughness 1.
    fn default() -> Self {
        Self { base_color: Vec3::ONE, metallic: 1.0, roughness: 1.0, specular: 1.0 }
    }
}

/// A pack's material's factors (its textures apart).
impl From<&crate::pack::schema::Material> for Material {
    fn from(m: &crate::pack::schema::Material) -> Self {
        Self {
            base_color: Vec3::from_array(m.base_color),
            metallic: m.metallic,
            roughness: m.roughness,
            specular: m.specular,
        }
    }
}

impl Material {
    /// A Lambertian material (dielectric with specularFactor 0).
    pub fn lambertian(albedo: Vec3) -> Self {
        Self { base_color: albedo, metallic: 0.0, roughness: 1.0, specular: 0.0 }
    }

    /// True when the material has a specular lobe (metallic, or a dielectric with specularFactor > 0).
    pub fn has_specular(&self) -> bool {
        self.metallic > 0.0 || self.specular > 0.0
    }
}
