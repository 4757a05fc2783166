//! Images from per-vertex results: each pixel's primary ray hits a triangle and the three
//! vertex values are interpolated barycentrically (as a GPU would with per-vertex colours).
//! Lights seen directly show their radiance; misses are black.

use crate::reference::Renderer;
use crate::scene::{Camera, NO_LIGHT};
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// A `width × height` image (row 0 at the top) of `values[instance][vertex]` through `camera`,
/// with `spp` stratified samples per pixel.
pub fn vertex_image(
    r: &Renderer,
    camera: &Camera,
    width: usize,
    height: usize,
    spp: u32,
    values: &[Vec<Vec3>],
) -> Vec<Vec3> {
    let aspect = width as f32 / height as f32;
    let side = (spp.max(1) as f32).sqrt().ceil() as usize;
    (0..width * height)
        .into_par_iter()
        .map(|k| {
            let (x, y) = (k % width, k / width);
            let mut sum = Vec3::ZERO;
            for sy in 0..side {
                for sx in 0..side {
                    let px = Vec2::new(
                        x as f32 + (sx as f32 + 0.5) / side as f32,
                        y as f32 + (sy as f32 + 0.5) / side as f32,
                    );
                    let ndc = Vec2::new(2.0 * px.x / width as f32 - 1.0, 1.0 - 2.0 * px.y / height as f32);
                    let (o, d) = camera.ray(ndc, aspect);
                    sum += sample(r, o, d, values);
                }
            }
            sum / (side * side) as f32
        })
        .collect()
}

fn sample(r: &Renderer, o: Vec3, d: Vec3, values: &[Vec<Vec3>]) -> Vec3 {
    let Some(hit) = r.bvh.closest_hit(o, d, f32::INFINITY) else { return Vec3::ZERO };
    let tref = r.flat.refs[hit.triangle as usize];
    if tref.light != NO_LIGHT {
        let light = &r.flat.lights[tref.light as usize];
        return if d.dot(light.normal) < 0.0 { light.radiance_at(tref.local as usize, hit.bary) } else { Vec3::ZERO };
    }
    let inst = tref.owner as usize;
    let idx = r.mesh(inst).triangles[tref.local as usize];
    // The flat triangle's corners 1 and 2 are swapped for mirrored instances.
    let (i1, i2) = if r.flat.instances[inst].mirrored { (idx[2], idx[1]) } else { (idx[1], idx[2]) };
    let vals = &values[inst];
    vals[idx[0] as usize] * (1.0 - hit.bary.x - hit.bary.y)
        + vals[i1 as usize] * hit.bary.x
        + vals[i2 as usize] * hit.bary.y
}
