//! The ratio estimator of Heitz, Hill & McGuire 2018 ("Combining analytic direct illumination
//! and stochastic shadows"), without a denoiser: the analytic unshadowed LTC result times
//! the Monte Carlo ratio of shadowed to unshadowed direct light, both estimated from the same
//! N light samples per light (area sampling). A competitor to BSPVT at equal time.

use crate::bspvt::shade::{PointShader, Visibility};
use crate::material::Bsdf;
use crate::math::frame::Frame;
use crate::math::{ltc, rng, sampling};
use crate::reference::Renderer;
use crate::scene::VertexValues;
use glam::{DVec3, Vec2, Vec3};
use rand::Rng;
use rayon::prelude::*;

/// Per-vertex estimates toward `eye` with `n` shadow rays per light, seeded by `seed`. Points
/// are drawn uniformly over each fan triangle; the same samples (and weights) enter both sums,
/// so the sampling density cancels in the ratio.
pub fn shade_vertices(r: &Renderer, n: u32, seed: u64, eye: Vec3) -> VertexValues {
    let table = ltc::table();
    let mut first = 0u64;
    (0..r.flat.instances.len())
        .map(|i| {
            let count = r.mesh(i).positions.len();
            let base = first;
            first += count as u64;
            (0..count)
                .into_par_iter()
                .map(|v| {
                    let (p, normal) = r.vertex(i, v);
                    let material = r.flat.vertex_material(i, v);
                    let unshadowed = PointShader::new(&table, p, normal, eye, &material)
                        .shade(&r.flat.lights, Visibility::Unshadowed);
                    let frame = Frame::from_normal(normal);
                    let wo = frame.to_local((eye - p).normalize_or(normal));
                    let bsdf = Bsdf::new(&material, wo);
                    let mut rng = rng::stream(seed, base + v as u64);
                    let (mut shadowed, mut open) = (DVec3::ZERO, DVec3::ZERO);
                    for light in &r.flat.lights {
                        for _ in 0..n {
                            let k = ((rng.random::<f32>() * (light.points.len() - 2) as f32) as usize)
                                .min(light.points.len() - 3);
                            let b = sampling::uniform_triangle(Vec2::new(rng.random::<f32>(), rng.random::<f32>()));
                            let q = light.points[0] * (1.0 - b.x - b.y)
                                + light.points[k + 1] * b.x
                                + light.points[k + 2] * b.y;
                            let to = q - p;
                            let d2 = to.length_squared();
                            let wi = to / d2.sqrt();
                            let (cos_l, wi_l) = (-wi.dot(light.normal), frame.to_local(wi));
                            if cos_l <= 0.0 || wi_l.z <= 0.0 {
                                continue;
                            }
                            let contrib =
                                (bsdf.eval(wo, wi_l) * wi_l.z * light.radiance_at(k, b) * cos_l / d2).as_dvec3();
                            open += contrib;
                            if !r.bvh.occluded_to(p, normal, q) {
                                shadowed += contrib;
                            }
                        }
                    }
                    let ratio = DVec3::select(open.cmpgt(DVec3::ZERO), shadowed / open, DVec3::ZERO);
                    (unshadowed.as_dvec3() * ratio).as_vec3()
                })
                .collect()
        })
        .collect()
}
