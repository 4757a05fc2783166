//! Diffuse albedos: what light proportional to the diffuse lobe (PRT's, the bounce's) is
//! weighed by, per vertex and per image sample.

use crate::material::Bsdf;
use crate::math::frame::Frame as ShadingFrame;
use crate::raster::SurfaceHit;
use crate::scene::{FlatScene, VertexValues};
use glam::Vec3;
use rayon::prelude::*;

/// Per instance and vertex: the diffuse albedo seen from `eye` (the BSDF's, view-dependent
/// through the specular layer's energy).
pub fn at_vertices(flat: &FlatScene, eye: Vec3) -> VertexValues {
    (0..flat.instances.len())
        .map(|i| {
            let count = flat.vertex_count(i);
            (0..count).into_par_iter().map(|v| at_vertex(flat, i, v, eye)).collect()
        })
        .collect()
}

/// Per instance, the diffuse albedo seen head-on (along the normal): what shading that must
/// serve every view (a bake plan's measurements) weights with.
pub(crate) fn head_on(flat: &FlatScene) -> Vec<Vec3> {
    flat.instances.iter().map(|i| Bsdf::new(&i.material, Vec3::Z).diffuse_albedo()).collect()
}

/// The diffuse albedo at vertex `v` of instance `i`, seen from `eye`.
pub fn at_vertex(flat: &FlatScene, i: usize, v: usize, eye: Vec3) -> Vec3 {
    let (p, normal) = flat.vertex(i, v);
    let wo = ShadingFrame::from_normal(normal).to_local((eye - p).normalize_or(normal));
    Bsdf::new(&flat.vertex_material(i, v), wo).diffuse_albedo()
}

/// The diffuse albedo of the material at `hit` (textures and vertex colours sampled there),
/// seen from `eye`.
pub fn at_hit(flat: &FlatScene, hit: &SurfaceHit, eye: Vec3) -> Vec3 {
    let n = (0..3).map(|c| flat.vertex(hit.instance, hit.corners[c]).1 * hit.weights[c]).sum::<Vec3>();
    let mu = n.normalize_or_zero().dot((eye - hit.position).normalize_or_zero());
    let material = flat.material_at(hit.instance, hit.corners, hit.weights);
    Bsdf::new(&material, Vec3::new(0.0, 0.0, mu)).diffuse_albedo()
}
