//! Polygonal lights as the shading reads them: world-space polygons with their radiance.

use crate::texture::Texture;
use glam::{Affine3A, DVec3, Vec2, Vec3};
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
    /// The light polygon `points` (in its node's frame) placed in the world by `to`, or `None`
    /// when it has no area. A mirroring `to` reverses the loop (and its UVs), so the light
    /// keeps emitting on its CCW side.
    pub fn placed(points: &[Vec3], uvs: &[Vec2], to: &Affine3A, radiance: Vec3) -> Option<Self> {
        let mut points: Vec<Vec3> = points.iter().map(|p| to.transform_point3(*p)).collect();
        let mut uvs = uvs.to_vec();
        if to.matrix3.determinant() < 0.0 {
            points.reverse();
            uvs.reverse();
        }
        let (normal, area) = normal_area(&points);
        (area > 0.0).then_some(Self { points, uvs, normal, area, radiance, texture: None, reach: None })
    }

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

/// Unit normal (Newell's method) and area of a planar polygon.
pub fn normal_area(points: &[Vec3]) -> (Vec3, f32) {
    let mut n = DVec3::ZERO;
    for i in 0..points.len() {
        let (a, b) = (points[i].as_dvec3(), points[(i + 1) % points.len()].as_dvec3());
        n += a.cross(b);
    }
    let area = 0.5 * n.length();
    (n.normalize_or_zero().as_vec3(), area as f32)
}
