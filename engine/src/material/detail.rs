//! The material's detail between vertices. Light shaded per vertex saw the material at the
//! vertices; an image sample between them rescales it by the diffuse albedo at the sample over
//! the albedo interpolated from the vertices, where the instance's material varies (textures,
//! vertex colours) — as engines show baked lighting, and as the editor's viewport does. Exact
//! for light proportional to the diffuse albedo (PRT's, the bounce's); elsewhere it keeps the
//! texture's pattern over per-vertex lighting.

use crate::material::albedo;
use crate::raster::SurfaceHit;
use crate::scene::{FlatScene, VertexValues};
use glam::Vec3;

/// What rescales per-vertex light at image samples of a snapshot seen from one eye.
pub struct Detail<'a> {
    flat: &'a FlatScene,
    eye: Vec3,
    /// The vertices' diffuse albedos toward the eye; `None` when no material varies.
    vertices: Option<VertexValues>,
}

impl<'a> Detail<'a> {
    /// The detail of `flat` seen from `eye` (the vertices' albedos computed only when some
    /// instance's material varies).
    pub fn new(flat: &'a FlatScene, eye: Vec3) -> Self {
        let varies = (0..flat.instances.len()).any(|i| flat.varies(i));
        Self { flat, eye, vertices: varies.then(|| albedo::at_vertices(flat, eye)) }
    }

    /// The factor for light interpolated from `hit`'s vertices.
    pub fn scale(&self, hit: &SurfaceHit) -> Vec3 {
        if !self.varies(hit) {
            return Vec3::ONE;
        }
        self.scale_for(hit, albedo::at_hit(self.flat, hit, self.eye))
    }

    /// [`Self::scale`] given the albedo at the sample, `at` (the caller's [`albedo::at_hit`]).
    pub fn scale_for(&self, hit: &SurfaceHit, at: Vec3) -> Vec3 {
        match &self.vertices {
            Some(v) if self.varies(hit) => ratio(at, hit.interpolate(&v[hit.instance])),
            _ => Vec3::ONE,
        }
    }

    fn varies(&self, hit: &SurfaceHit) -> bool {
        self.vertices.is_some() && self.flat.varies(hit.instance)
    }
}

/// `at` over `vertices` per channel; zero where the vertices' channel is black (it stays black).
fn ratio(at: Vec3, vertices: Vec3) -> Vec3 {
    Vec3::select(vertices.cmpgt(Vec3::splat(1e-6)), at / vertices.max(Vec3::splat(1e-6)), Vec3::ZERO)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_black_channel_at_the_vertices_stays_black() {
        let r = ratio(Vec3::new(0.5, 0.3, 0.2), Vec3::new(0.25, 0.0, 0.2));
        assert_eq!(r, Vec3::new(2.0, 0.0, 1.0));
    }
}
