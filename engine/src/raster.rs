//! Images from per-vertex results: each pixel's primary ray hits a triangle and a shading
//! function sees the hit (instance, corner vertices, barycentrics, position) — for per-vertex
//! methods it interpolates the three vertex values (as a GPU would with per-vertex colours);
//! per-pixel methods add their own terms. Lights seen directly show their radiance; misses
//! show the snapshot's environment (black without one).

use crate::reference::Renderer;
use crate::scene::{Camera, NO_LIGHT};
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// A primary-ray hit on a receiver triangle.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceHit {
    /// Instance index in [`crate::scene::FlatScene::instances`].
    pub instance: usize,
    /// The triangle's vertex indices, in the order the weights refer to.
    pub corners: [usize; 3],
    /// Barycentric weights (sum to 1).
    pub weights: [f32; 3],
    /// World position.
    pub position: Vec3,
}

impl SurfaceHit {
    /// Barycentric interpolation of per-vertex `values` of this hit's instance.
    pub fn interpolate<T: Copy + std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T>>(&self, values: &[T]) -> T {
        values[self.corners[0]] * self.weights[0]
            + values[self.corners[1]] * self.weights[1]
            + values[self.corners[2]] * self.weights[2]
    }
}

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
    shade_image(r, camera, width, height, spp, &|hit| hit.interpolate(&values[hit.instance]))
}

/// What a primary ray saw.
#[derive(Clone, Copy, Debug)]
pub enum Primary {
    /// No geometry: the environment's radiance along the ray (zero without one).
    Miss(Vec3),
    /// A light's emitting side, with its radiance.
    Emitter(Vec3),
    /// A receiver triangle.
    Surface(SurfaceHit),
}

/// Primary rays on a `(width · side) × (height · side)` grid of stratified subpixel samples
/// (`side = ⌈√spp⌉`), row-major; returns the grid and `side`.
pub fn primary_grid(r: &Renderer, camera: &Camera, width: usize, height: usize, spp: u32) -> (Vec<Primary>, usize) {
    let aspect = width as f32 / height as f32;
    let side = (spp.max(1) as f32).sqrt().ceil() as usize;
    let gw = width * side;
    let grid = (0..gw * height * side)
        .into_par_iter()
        .map(|k| {
            let px = Vec2::new((k % gw) as f32 + 0.5, (k / gw) as f32 + 0.5) / side as f32;
            let ndc = Vec2::new(2.0 * px.x / width as f32 - 1.0, 1.0 - 2.0 * px.y / height as f32);
            let (o, d) = camera.ray(ndc, aspect);
            primary(r, o, d)
        })
        .collect();
    (grid, side)
}

/// Per pixel of a `width × height` image: whether the ray through its centre meets a receiver
/// (not the environment, nor a light) — the pixels an exposure is metered on.
pub fn surface_pixels(r: &Renderer, camera: &Camera, width: usize, height: usize) -> Vec<bool> {
    primary_grid(r, camera, width, height, 1).0.iter().map(|p| matches!(p, Primary::Surface(_))).collect()
}

/// Averages `side × side` blocks of a grid of `width · side` columns into pixels.
pub fn downsample(grid: &[Vec3], width: usize, height: usize, side: usize) -> Vec<Vec3> {
    let gw = width * side;
    (0..width * height)
        .into_par_iter()
        .map(|k| {
            let (x, y) = (k % width, k / width);
            let mut sum = Vec3::ZERO;
            for sy in 0..side {
                for sx in 0..side {
                    sum += grid[(y * side + sy) * gw + x * side + sx];
                }
            }
            sum / (side * side) as f32
        })
        .collect()
}

/// A `width × height` image through `camera`, `spp` stratified samples per pixel, each receiver
/// hit shaded by `shade`.
pub fn shade_image(
    r: &Renderer,
    camera: &Camera,
    width: usize,
    height: usize,
    spp: u32,
    shade: &(dyn Fn(&SurfaceHit) -> Vec3 + Sync),
) -> Vec<Vec3> {
    let (grid, side) = primary_grid(r, camera, width, height, spp);
    let values: Vec<Vec3> = grid
        .par_iter()
        .map(|p| match p {
            Primary::Miss(l) | Primary::Emitter(l) => *l,
            Primary::Surface(hit) => shade(hit),
        })
        .collect();
    downsample(&values, width, height, side)
}

fn primary(r: &Renderer, o: Vec3, d: Vec3) -> Primary {
    let Some(hit) = r.bvh.closest_hit(o, d, f32::INFINITY) else {
        return Primary::Miss(r.flat.environment.as_ref().map_or(Vec3::ZERO, |e| e.background(d)));
    };
    let tref = r.flat.refs[hit.triangle as usize];
    if tref.light != NO_LIGHT {
        let light = &r.flat.lights[tref.light as usize];
        return if d.dot(light.normal) < 0.0 {
            Primary::Emitter(light.radiance_at(tref.local as usize, hit.bary))
        } else {
            Primary::Miss(Vec3::ZERO) // a one-sided light's dark back hides what is behind it
        };
    }
    let instance = tref.owner as usize;
    let idx = r.mesh(instance).triangles[tref.local as usize];
    // The flat triangle's corners 1 and 2 are swapped for mirrored instances.
    let (i1, i2) = if r.flat.instances[instance].mirrored { (idx[2], idx[1]) } else { (idx[1], idx[2]) };
    Primary::Surface(SurfaceHit {
        instance,
        corners: [idx[0] as usize, i1 as usize, i2 as usize],
        weights: [1.0 - hit.bary.x - hit.bary.y, hit.bary.x, hit.bary.y],
        position: o + d * hit.t,
    })
}
