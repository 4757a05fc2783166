//! The material layer under the techniques: the glTF metallic-roughness BSDF ([`Bsdf`], from
//! `kage_runtime::material`, where "has a specular lobe" is defined once), the diffuse albedos
//! that per-vertex light is weighed by ([`albedo`]), and the material's detail between vertices
//! ([`detail`]). BSPVT, PRT, the radiance cache and the reference read materials only through
//! it; [`crate::shading`] composes the techniques above it.

pub mod albedo;
pub mod detail;

pub use kage_runtime::material::Bsdf;
