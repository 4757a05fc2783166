//! Polygonal lights per pixel: LTC is evaluated at each pixel's own point, normal and view (so
//! highlights are as sharp as the lobe), and the trees' visibility is carried from the
//! triangle's vertices as, per light and lobe, the shadowed and the unshadowed integral. A
//! pixel's visible fraction of a lobe is the ratio of the two interpolated integrals — a
//! vertex whose lobe misses the light weighs nothing in it. Where all three corners' specular
//! lobes miss the light while the pixel's catches it, the diffuse lobe's fraction (the light's
//! visible fraction seen from the surface) stands in; where that is undefined too (the light
//! under every corner's horizon), the light is taken as unshadowed, never as black.

use super::shade::{PointShader, Visibility};
use super::{Bake, Shadows};
use crate::math::ltc;
use crate::raster::SurfaceHit;
use crate::scene::FlatScene;
use glam::Vec3;
use rayon::prelude::*;

/// Integrals below this count as "the lobe misses the light".
const MISSES: f64 = 1e-9;

/// Per instance, per vertex and light: (shadowed, unshadowed) integrals of the diffuse and the
/// specular lobe, toward one eye.
pub struct Lobes {
    lights: usize,
    /// `[instance][vertex · lights + light]` = `[[shadowed, unshadowed]; 2 lobes]`.
    integrals: Vec<Vec<[[f32; 2]; 2]>>,
}

impl Lobes {
    /// The integrals at every vertex toward `eye`, shadowed as `shadows` says.
    pub fn at_vertices(flat: &FlatScene, shadows: Shadows, eye: Vec3) -> Self {
        let table = ltc::table();
        let integrals = (0..flat.instances.len())
            .map(|i| {
                let material = flat.instances[i].material;
                (0..flat.vertex_count(i))
                    .into_par_iter()
                    .flat_map_iter(|v| {
                        let (p, n) = flat.vertex(i, v);
                        let shader = PointShader::new(&table, p, n, eye, &material);
                        let open = shader.lobe_integrals(&flat.lights, Visibility::Unshadowed);
                        let shut = match shadows {
                            Shadows::Trees(b) => shader.lobe_integrals(&flat.lights, vis(b, i, v)),
                            _ => open.clone(),
                        };
                        shut.into_iter()
                            .zip(open)
                            .map(|(s, o)| [[s[0] as f32, o[0] as f32], [s[1] as f32, o[1] as f32]])
                            .collect::<Vec<_>>()
                    })
                    .collect()
            })
            .collect();
        Self { lights: flat.lights.len(), integrals }
    }

    /// Radiance toward `eye` from the polygonal lights at a primary-ray `hit`.
    pub fn shade(&self, flat: &FlatScene, hit: &SurfaceHit, eye: Vec3) -> Vec3 {
        let i = hit.instance;
        let n = (0..3).map(|c| flat.vertex(i, hit.corners[c]).1 * hit.weights[c]).sum::<Vec3>().normalize_or_zero();
        let shader = PointShader::new(&ltc::table(), hit.position, n, eye, &flat.instances[i].material);
        shader.shade_scaled(&flat.lights, |l| {
            let lobe = |k: usize| {
                let (mut shut, mut open) = (0.0f64, 0.0f64);
                for c in 0..3 {
                    let [s, o] = self.integrals[i][hit.corners[c] * self.lights + l][k];
                    shut += (s * hit.weights[c]) as f64;
                    open += (o * hit.weights[c]) as f64;
                }
                (open > MISSES).then(|| (shut / open).clamp(0.0, 1.0))
            };
            let diffuse = lobe(0).unwrap_or(1.0);
            [diffuse, lobe(1).unwrap_or(diffuse)]
        })
    }
}

fn vis(bake: &Bake, i: usize, v: usize) -> Visibility<'_> {
    Visibility::Tree(bake.instances[i].record(v))
}
