//! Polygonal lights per pixel: LTC is evaluated at each pixel's own point, normal and view (so
//! highlights are as sharp as the lobe), and the trees' visibility is carried from the
//! triangle's vertices as, per light and lobe, the shadowed and the unshadowed integral. A
//! pixel's visible fraction of a lobe is the ratio of the two interpolated integrals — a
//! vertex whose lobe misses the light weighs nothing in it. Where all three corners' specular
//! lobes miss the light while the pixel's catches it, the diffuse lobe's fraction (the light's
//! visible fraction seen from the surface) stands in; where that is undefined too (the light
//! under every corner's horizon), the light is taken as unshadowed, never as black.

use super::Bake;
use super::shade::{PointShader, Visibility};
use crate::math::ltc;
use crate::raster::SurfaceHit;
use crate::scene::{FlatScene, VertexValues};
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
    /// The integrals at every vertex toward `eye` with the trees of `bake` (`None`:
    /// unshadowed), and the vertices' radiance (as [`super::shade_vertices`] gives it) from the
    /// same pass.
    /// `inside`: per instance and vertex, whether it lies inside geometry ([`Inside`]).
    pub fn at_vertices(flat: &FlatScene, bake: Option<&Bake>, eye: Vec3, inside: &[Vec<bool>]) -> (Self, VertexValues) {
        let table = ltc::table();
        let lights = flat.lights.len();
        let (integrals, values) = (0..flat.instances.len())
            .map(|i| {
                let rows: Vec<(Vec3, Vec<[[f32; 2]; 2]>)> = (0..flat.vertex_count(i))
                    .into_par_iter()
                    .map(|v| {
                        let (p, n) = flat.vertex(i, v);
                        let shader = PointShader::new(&table, p, n, eye, &flat.vertex_material(i, v));
                        let vis = bake.map_or(Visibility::Unshadowed, |b| {
                            Visibility::Tree(b.instances[i].record(v), b.settings.res)
                        });
                        shader.vertex_lobe_pairs(&flat.lights, vis, inside[i][v])
                    })
                    .collect();
                let values: Vec<Vec3> = rows.iter().map(|r| r.0).collect();
                (rows.into_iter().flat_map(|r| r.1).collect::<Vec<_>>(), values)
            })
            .unzip();
        (Self { lights, integrals }, values)
    }

    /// Vertex `v` of instance `i`: per light, `[[shadowed, unshadowed]; 2 lobes]`.
    pub fn vertex(&self, i: usize, v: usize) -> &[[[f32; 2]; 2]] {
        &self.integrals[i][v * self.lights..(v + 1) * self.lights]
    }

    /// Radiance toward `eye` from the polygonal lights at a primary-ray `hit`.
    pub fn shade(&self, flat: &FlatScene, hit: &SurfaceHit, eye: Vec3) -> Vec3 {
        let i = hit.instance;
        let n = (0..3).map(|c| flat.vertex(i, hit.corners[c]).1 * hit.weights[c]).sum::<Vec3>().normalize_or_zero();
        let material = flat.material_at(i, hit.corners, hit.weights);
        let shader = PointShader::new(&ltc::table(), hit.position, n, eye, &material);
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

/// Which vertices lie inside geometry ([`crate::accel::SceneBvh::inside`] against every
/// instance, lights left out), kept while the instances stay as they are: a light or camera
/// move, which re-shades, does not cast its rays again.
#[derive(Default)]
pub struct Inside {
    key: Option<blake3::Hash>,
    flags: Vec<Vec<bool>>,
}

impl Inside {
    /// Per instance and vertex of `flat`, whether it lies inside geometry.
    pub fn flags(&mut self, flat: &FlatScene) -> &[Vec<bool>] {
        let mut h = blake3::Hasher::new();
        for (i, inst) in flat.instances.iter().enumerate() {
            h.update(&flat.occluder_hash(i));
            h.update(&flat.mesh(i).hash.0);
            h.update(bytemuck::cast_slice(&inst.world.to_cols_array()));
        }
        let key = h.finalize();
        if self.key != Some(key) {
            let (triangles, holes) = flat.select(|r| r.light == crate::scene::NO_LIGHT);
            let bvh = crate::accel::SceneBvh::quick(&triangles).cut(&holes);
            let inside = |i: usize| -> Vec<bool> {
                (0..flat.vertex_count(i))
                    .into_par_iter()
                    .map(|v| {
                        let (p, n) = flat.vertex(i, v);
                        bvh.inside(p, n)
                    })
                    .collect()
            };
            self.flags = (0..flat.instances.len()).map(inside).collect();
            self.key = Some(key);
        }
        &self.flags
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bspvt::{Settings, Shadows, shade_vertices};
    use crate::scene::{default_scene, flatten};

    /// The pass's values are `shade_vertices`' bit for bit, and a pixel on a vertex shades like
    /// the vertex (its lobes' fractions are the vertex's own) — but for a vertex inside
    /// geometry (the ground under the box), whose pixels are not shaded from it.
    #[test]
    fn vertices_match_and_pixels_on_vertices_shade_like_them() {
        let flat = flatten(&default_scene());
        let bake = crate::bspvt::bake(&flat, &Settings { res: 8, epsilon: 2.0 }, &|_| {});
        let eye = Vec3::new(0.0, 2.0, 5.0);
        let mut inside = Inside::default();
        let flags = inside.flags(&flat).to_vec();
        let (lobes, values) = Lobes::at_vertices(&flat, Some(&bake), eye, &flags);
        assert_eq!(values, shade_vertices(&flat, Shadows::Trees(&bake), eye));
        assert!(flags.iter().flatten().any(|&f| f), "the ground under the box");
        for (i, v) in flat.vertex_ids().step_by(37).filter(|&(i, v)| !flags[i][v]) {
            let (position, _) = flat.vertex(i, v);
            let hit = SurfaceHit { instance: i, corners: [v, v, v], weights: [1.0, 0.0, 0.0], position };
            let (pixel, vertex) = (lobes.shade(&flat, &hit, eye), values[i][v]);
            assert!(
                (pixel - vertex).abs().max_element() <= 1e-4 * vertex.max_element().max(1e-2),
                "{pixel} vs {vertex}"
            );
        }
    }
}
