//! Polygonal lights as the shading reads them: world-space polygons with their radiance.

use crate::texture::Texture;
use glam::{Vec2, Vec3};
use std::sync::Arc;

/// A light polygon in world space.
#[derive(Clone, Debug)]
pub struct FlatLight {
    /// Convex polygon, CCW about `normal`.
    pub points: Vec<Vec3>,
    /// Texture coordinates per point (empty when untextured).
    pub uvs: Vec<Vec2>,
    /// Unit emitting-side normal.
    pub normal: Vec3,
    /// Area.
    pub area: f32,
    /// Radiance (times the texture when present).
    pub radiance: Vec3,
    /// Emissive texture.
    pub texture: Option<Arc<Texture>>,
    /// The world-space box (min, max) the light promises to stay inside however it is moved,
    /// or `None`: it may go anywhere.
    pub reach: Option<[Vec3; 2]>,
}

impl FlatLight {
    /// Emitted radiance at barycentric position `b` (b1, b2) of fan triangle `tri`.
    pub fn radiance_at(&self, tri: usize, b: Vec2) -> Vec3 {
        match &self.texture {
            Some(t) if !self.uvs.is_empty() => {
                let uv = self.uvs[0] * (1.0 - b.x - b.y) + self.uvs[tri + 1] * b.x + self.uvs[tri + 2] * b.y;
                self.radiance * t.sample(uv)
            }
            _ => self.radiance,
        }
    }
}
