//! The material layer under the techniques: the glTF metallic-roughness BSDF ([`Bsdf`]), the
//! diffuse albedos that per-vertex light is weighed by ([`albedo`]), and the material's detail
//! between vertices ([`detail`]). BSPVT, PRT, the radiance cache and the reference read
//! materials only through it; [`crate::shading`] composes the techniques above it.
//!
//! One definition of "has a specular lobe": [`crate::scene::Material::has_specular`] (metallic,
//! or a dielectric with specularFactor > 0); [`Bsdf::has_specular`] reports the same. A black
//! metal has one: its F0 is black, but Schlick's F90 is 1, so it reflects at grazing angles.

pub mod albedo;
mod bsdf;
pub mod detail;

pub use bsdf::Bsdf;
