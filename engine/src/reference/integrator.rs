//! The path loop, light sampling and the per-pixel / per-vertex drivers.

use super::{Accumulator, Estimate, Settings};
use crate::accel::{Hit, SceneBvh, offset_ray_origin};
use crate::material::Bsdf;
use crate::math::distribution::Distribution1D;
use crate::math::frame::Frame;
use crate::math::{rng, sampling};
use crate::scene::{Camera, FlatScene, Material, Mesh, NO_LIGHT, Scene, flatten};
use glam::{Vec2, Vec3};
use rand::Rng;
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

/// A shading point: position, normals facing the viewer, and material.
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint {
    /// World position.
    pub p: Vec3,
    /// Geometric normal (for ray offsets).
    pub ng: Vec3,
    /// Shading frame (+Z = shading normal).
    pub frame: Frame,
    /// Material.
    pub material: Material,
}

/// Everything a reference render needs: the world-space snapshot, its BVH and light tables.
pub struct Renderer {
    /// The snapshot being rendered.
    pub flat: FlatScene,
    /// BVH over `flat.triangles`.
    pub bvh: SceneBvh,
    /// Light choice by power.
    light_pick: Option<Distribution1D>,
    /// Per light: fan-triangle choice by area.
    fan_pick: Vec<Distribution1D>,
}

/// What a BSDF-sampled ray found.
enum Found {
    Surface(SurfacePoint),
    Emitter { radiance: Vec3, pdf_light: f32 },
    Environment,
    Nothing,
}

impl Renderer {
    /// Snapshots `scene` (transforms must be propagated) and builds the BVH.
    pub fn new(scene: &Scene) -> Self {
        let flat = flatten(scene);
        let bvh = SceneBvh::over(&flat);
        let powers: Vec<f32> = (0..flat.lights.len()).map(|l| flat.light_power(l)).collect();
        let light_pick = (!flat.lights.is_empty()).then(|| Distribution1D::new(&powers));
        let fan_pick = flat
            .lights
            .iter()
            .map(|l| {
                let areas: Vec<f32> = (1..l.points.len() - 1)
                    .map(|k| 0.5 * (l.points[k] - l.points[0]).cross(l.points[k + 1] - l.points[0]).length())
                    .collect();
                Distribution1D::new(&areas)
            })
            .collect();
        Self { flat, bvh, light_pick, fan_pick }
    }

    /// Radiance estimates for a `width × height` image seen through `camera` (row 0 at the top).
    pub fn render_image(
        &self,
        camera: &Camera,
        width: usize,
        height: usize,
        s: &Settings,
        progress: &(dyn Fn(usize) + Sync),
    ) -> Vec<Estimate> {
        let aspect = width as f32 / height as f32;
        let done = AtomicUsize::new(0);
        (0..height)
            .into_par_iter()
            .flat_map_iter(|y| {
                let row: Vec<Estimate> = (0..width)
                    .map(|x| {
                        let mut r = rng::stream(s.seed, (y * width + x) as u64);
                        let mut acc = Accumulator::default();
                        for _ in 0..s.spp {
                            let px = Vec2::new(x as f32 + r.random::<f32>(), y as f32 + r.random::<f32>());
                            let ndc = Vec2::new(2.0 * px.x / width as f32 - 1.0, 1.0 - 2.0 * px.y / height as f32);
                            let (o, d) = camera.ray(ndc, aspect);
                            acc.add(self.camera_path(o, d, (s.min_bounces, s.max_bounces), &mut r));
                        }
                        acc.estimate()
                    })
                    .collect();
                progress(done.fetch_add(1, Ordering::Relaxed) + 1);
                row
            })
            .collect()
    }

    /// Outgoing radiance toward `eye` at every receiver vertex, in [`FlatScene::instances`]
    /// order (vertex `v` of instance `i`), with the vertex's own shading normal.
    pub fn render_vertices(&self, eye: Vec3, s: &Settings, progress: &(dyn Fn(usize) + Sync)) -> Vec<Vec<Estimate>> {
        let done = AtomicUsize::new(0);
        let mut base = 0u64;
        let jobs: Vec<(usize, u64)> = self
            .flat
            .instances
            .iter()
            .enumerate()
            .map(|(i, inst)| {
                let b = base;
                base += self.flat.meshes[inst.mesh as usize].positions.len() as u64;
                (i, b)
            })
            .collect();
        jobs.iter()
            .map(|&(i, first)| {
                let n = self.flat.vertex_count(i);
                let out = (0..n)
                    .into_par_iter()
                    .map(|v| {
                        let (p, normal) = self.vertex(i, v);
                        let material = self.flat.vertex_material(i, v);
                        let sp = SurfacePoint { p, ng: normal, frame: Frame::from_normal(normal), material };
                        self.estimate_point(&sp, (eye - p).normalize_or(normal), s, first + v as u64)
                    })
                    .collect();
                progress(done.fetch_add(n, Ordering::Relaxed) + n);
                out
            })
            .collect()
    }

    /// Outgoing radiance at `sp` toward world direction `wo`, from stream `index`.
    pub fn estimate_point(&self, sp: &SurfacePoint, wo: Vec3, s: &Settings, index: u64) -> Estimate {
        let mut r = rng::stream(s.seed, index);
        let mut acc = Accumulator::default();
        for _ in 0..s.spp {
            acc.add(self.surface_path(*sp, wo, (s.min_bounces, s.max_bounces), &mut r));
        }
        acc.estimate()
    }

    /// World position and shading normal of vertex `v` of instance `i`.
    pub fn vertex(&self, i: usize, v: usize) -> (Vec3, Vec3) {
        self.flat.vertex(i, v)
    }

    /// The mesh of instance `i`.
    pub fn mesh(&self, i: usize) -> &Mesh {
        self.flat.mesh(i)
    }

    /// Number of receiver vertices.
    pub fn vertex_count(&self) -> usize {
        (0..self.flat.instances.len()).map(|i| self.flat.vertex_count(i)).sum()
    }

    /// Radiance along a camera ray: emitters and the environment are seen directly.
    fn camera_path(&self, o: Vec3, d: Vec3, bounces: (u32, u32), r: &mut rng::Rng) -> Vec3 {
        match self.trace(o, d) {
            Found::Surface(sp) => self.surface_path(sp, -d, bounces, r),
            Found::Emitter { radiance, .. } if bounces.0 == 0 => radiance,
            Found::Environment if bounces.0 == 0 => {
                self.flat.environment.as_ref().map_or(Vec3::ZERO, |e| e.background(d))
            }
            _ => Vec3::ZERO,
        }
    }

    /// Radiance leaving `sp` toward `wo` (world): the path loop with next-event estimation,
    /// counting light that arrives after `min..=max` bounces.
    fn surface_path(&self, mut sp: SurfacePoint, mut wo: Vec3, (min, bounces): (u32, u32), r: &mut rng::Rng) -> Vec3 {
        let mut radiance = Vec3::ZERO;
        let mut throughput = Vec3::ONE;
        for depth in 0..=bounces {
            // Light found at this depth has bounced `depth` times before reaching the point.
            let counted = if depth >= min { 1.0 } else { 0.0 };
            let wo_l = sp.frame.to_local(wo);
            let bsdf = Bsdf::new(&sp.material, wo_l);
            if bsdf.is_black() {
                break;
            }
            radiance += counted
                * throughput
                * (self.sample_polygon_light(&sp, &bsdf, wo_l, r) + self.sample_environment(&sp, &bsdf, wo_l, r));
            let Some(wi_l) = bsdf.sample(wo_l, r.random(), Vec2::new(r.random(), r.random())) else {
                break;
            };
            let pdf = bsdf.pdf(wo_l, wi_l);
            let wi = sp.frame.to_world(wi_l);
            if pdf <= 0.0 || wi.dot(sp.ng) <= 0.0 {
                break;
            }
            let weight = bsdf.eval(wo_l, wi_l) * wi_l.z / pdf;
            match self.trace(offset_ray_origin(sp.p, sp.ng, wi), wi) {
                Found::Emitter { radiance: le, pdf_light } => {
                    radiance += counted * throughput * weight * le * sampling::power_heuristic(pdf, pdf_light);
                    break;
                }
                Found::Environment => {
                    if let Some(env) = &self.flat.environment {
                        radiance += counted
                            * throughput
                            * weight
                            * env.radiance(wi)
                            * sampling::power_heuristic(pdf, env.pdf(wi));
                    }
                    break;
                }
                Found::Surface(next) if depth < bounces => {
                    throughput *= weight;
                    sp = next;
                    wo = -wi;
                }
                _ => break,
            }
        }
        radiance
    }

    /// One light sample (light by power, point by area), MIS-weighted against BSDF sampling.
    fn sample_polygon_light(&self, sp: &SurfacePoint, bsdf: &Bsdf, wo_l: Vec3, r: &mut rng::Rng) -> Vec3 {
        let Some(pick) = &self.light_pick else {
            return Vec3::ZERO;
        };
        let (_, p_light, l) = pick.sample(r.random());
        let light = &self.flat.lights[l];
        let (_, _, k) = self.fan_pick[l].sample(r.random());
        let b = sampling::uniform_triangle(Vec2::new(r.random(), r.random()));
        let q = light.points[0] * (1.0 - b.x - b.y) + light.points[k + 1] * b.x + light.points[k + 2] * b.y;
        let to = q - sp.p;
        let dist2 = to.length_squared();
        let wi = to / dist2.sqrt();
        let cos_l = -wi.dot(light.normal);
        let wi_l = sp.frame.to_local(wi);
        if cos_l <= 0.0 || wi.dot(sp.ng) <= 0.0 || wi_l.z <= 0.0 {
            return Vec3::ZERO;
        }
        let pdf = p_light / (pick.len() as f32) / light.area * dist2 / cos_l;
        let f = bsdf.eval(wo_l, wi_l) * wi_l.z;
        if f == Vec3::ZERO {
            return Vec3::ZERO;
        }
        if self.bvh.occluded_to(sp.p, sp.ng, q) {
            return Vec3::ZERO;
        }
        f * light.radiance_at(k, b) / pdf * sampling::power_heuristic(pdf, bsdf.pdf(wo_l, wi_l))
    }

    /// One environment sample by luminance, MIS-weighted against BSDF sampling.
    fn sample_environment(&self, sp: &SurfacePoint, bsdf: &Bsdf, wo_l: Vec3, r: &mut rng::Rng) -> Vec3 {
        let Some(env) = &self.flat.environment else {
            return Vec3::ZERO;
        };
        let Some(s) = env.sample(Vec2::new(r.random(), r.random())) else {
            return Vec3::ZERO;
        };
        let wi_l = sp.frame.to_local(s.dir);
        if s.dir.dot(sp.ng) <= 0.0 || wi_l.z <= 0.0 {
            return Vec3::ZERO;
        }
        let f = bsdf.eval(wo_l, wi_l) * wi_l.z;
        if f == Vec3::ZERO || self.bvh.occluded(offset_ray_origin(sp.p, sp.ng, s.dir), s.dir, f32::INFINITY) {
            return Vec3::ZERO;
        }
        f * s.radiance / s.pdf * sampling::power_heuristic(s.pdf, bsdf.pdf(wo_l, wi_l))
    }

    /// Area-to-solid-angle pdf (without the 1/cos at the light) of light sampling picking `hit` on light `l`.
    fn light_pdf(&self, l: usize, hit: &Hit) -> f32 {
        let pick = self.light_pick.as_ref().expect("a light was hit, so lights exist");
        pick.pdf_cell(l) / pick.len() as f32 / self.flat.lights[l].area * hit.t * hit.t
    }

    /// Closest hit along a ray, classified.
    fn trace(&self, o: Vec3, d: Vec3) -> Found {
        let Some(hit) = self.bvh.closest_hit(o, d, f32::INFINITY) else {
            return Found::Environment;
        };
        let tref = self.flat.refs[hit.triangle as usize];
        if tref.light != NO_LIGHT {
            let light = &self.flat.lights[tref.light as usize];
            let cos_l = -d.dot(light.normal);
            if cos_l <= 0.0 {
                return Found::Nothing; // the dark back of a one-sided light
            }
            let radiance = light.radiance_at(tref.local as usize, hit.bary);
            return Found::Emitter { radiance, pdf_light: self.light_pdf(tref.light as usize, &hit) / cos_l };
        }
        Found::Surface(self.surface_at(hit, tref.owner as usize, tref.local as usize, d))
    }

    /// Builds the shading point of a hit, with both normals facing the incoming ray.
    /// The shading point of a hit on triangle `local_tri` of instance `inst` by a ray along `d`
    /// (normals facing the ray's origin).
    pub fn surface_at(&self, hit: Hit, inst: usize, local_tri: usize, d: Vec3) -> SurfacePoint {
        let instance = &self.flat.instances[inst];
        let mesh = self.flat.mesh(inst);
        let t = self.flat.triangles[hit.triangle as usize];
        let p = t[0] * (1.0 - hit.bary.x - hit.bary.y) + t[1] * hit.bary.x + t[2] * hit.bary.y;
        let mut ng = (t[1] - t[0]).cross(t[2] - t[0]).normalize_or(Vec3::Y);
        let idx = mesh.triangles[local_tri];
        // The flat triangle's corners 1 and 2 are swapped for mirrored instances.
        let (i1, i2) = if instance.mirrored { (idx[2], idx[1]) } else { (idx[1], idx[2]) };
        let n_local = mesh.normals[idx[0] as usize] * (1.0 - hit.bary.x - hit.bary.y)
            + mesh.normals[i1 as usize] * hit.bary.x
            + mesh.normals[i2 as usize] * hit.bary.y;
        let mut ns: Vec3 = (instance.normal_matrix * glam::Vec3A::from(n_local)).normalize_or(ng.into()).into();
        if ng.dot(d) > 0.0 {
            ng = -ng;
        }
        if ns.dot(ng) < 0.0 {
            ns = -ns;
        }
        let corners = [idx[0] as usize, i1 as usize, i2 as usize];
        let material = self.flat.material_at(inst, corners, [1.0 - hit.bary.x - hit.bary.y, hit.bary.x, hit.bary.y]);
        SurfacePoint { p, ng, frame: Frame::from_normal(ns), material }
    }
}
