//! The environment's specular term on GGX surfaces (glossy dielectrics and metals), which the
//! diffuse transfer leaves out: the lobe's unshadowed reflection times its visible fraction
//! (`docs/baked.md`):
//!
//! `L_s = R(n, ωo; α, F0, F90) · V_lobe · O`
//!
//! - `R`: the environment reflected by the specular lobe, by filtered importance sampling of
//!   its mip chain ([`super::prefilter`]);
//! - `V_lobe`: the visible fraction of the lobe around its dominant direction `d` (Lagarde & de
//!   Rousiers 2014: the reflection direction bent toward the normal as roughness grows), from
//!   the vertex's own transfer: the transfer
//!   and the unoccluded clamped cosine, both reconstructed at `d` with the same window and a
//!   lobe-width kernel `g_l = exp(−l(l+1) α²)`, divided and clamped to [0, 1]. Both are the
//!   same band-limited function of a cosine-weighted visibility, so an open sky gives exactly 1;
//!   as the lobe widens only band 0 survives and the ratio becomes the diffuse visible
//!   fraction (the fallback wherever the unoccluded reconstruction is too small to divide by);
//! - `O`: the fraction of the diffuse environment light that other groups' shadows leave at
//!   the point (1 without other groups). Transfer is rigid in its group's frame, so groups
//!   move and rotate without a re-bake, as for the diffuse term.

use super::prefilter::Prefiltered;
use super::{Bake, Posed};
use crate::material::Bsdf;
use crate::math::ggx;
use crate::scene::FlatScene;
use glam::{DVec3, Vec3};
use kage_runtime::prt::glossy::MAX_COEFFS;
pub use kage_runtime::prt::glossy::{Lobe, dominant_direction};

/// Shades the environment's specular term of one frame's posed lighting.
pub struct Specular<'a> {
    env: &'a Prefiltered,
    bake: &'a Bake,
    posed: &'a Posed,
    flat: &'a FlatScene,
    lobe: &'a Lobe,
}

impl<'a> Specular<'a> {
    /// The specular term for `posed` lighting, the transfer `bake`, `env` prefiltered, and
    /// `lobe` at the posed order.
    pub fn new(env: &'a Prefiltered, bake: &'a Bake, posed: &'a Posed, lobe: &'a Lobe, flat: &'a FlatScene) -> Self {
        Self { env, bake, posed, flat, lobe }
    }

    /// Radiance the specular lobe of instance `i`'s surface at `p` (barycentrics `weights` of
    /// the triangle `corners`) reflects toward `toward`, times the other groups' `open` fraction.
    pub fn at(&self, i: usize, corners: [usize; 3], weights: [f32; 3], p: Vec3, toward: Vec3, open: f32) -> Vec3 {
        let (reflected, weight) = self.parts(i, corners, weights, p, toward, open);
        reflected * weight
    }

    /// [`Self::at`] as its two factors: the unshadowed reflection `R` and the weight
    /// `V_lobe · O` (0 where the lobe reflects nothing) — what the editor's viewport carries
    /// from the vertices to evaluate `R` per pixel.
    pub fn parts(
        &self,
        i: usize,
        corners: [usize; 3],
        weights: [f32; 3],
        p: Vec3,
        toward: Vec3,
        open: f32,
    ) -> (Vec3, f32) {
        let n = (0..3).map(|c| self.flat.vertex(i, corners[c]).1 * weights[c]).sum::<Vec3>().normalize_or_zero();
        let wo = (toward - p).normalize_or_zero();
        let mu = n.dot(wo);
        let m = &self.flat.material_at(i, corners, weights);
        let bsdf = Bsdf::new(m, Vec3::new(0.0, 0.0, mu));
        if mu <= 0.0 || !bsdf.has_specular() {
            return (Vec3::ZERO, 0.0);
        }
        let alpha = ggx::alpha_from_roughness(m.roughness);
        let d = dominant_direction(n, 2.0 * mu * n - wo, alpha);
        let nc = self.lobe.coeffs();
        let mut buffer = [0.0f64; MAX_COEFFS];
        let t = &mut buffer[..nc];
        for c in 0..3 {
            for (t, v) in t.iter_mut().zip(&self.bake.vertex(i, corners[c])[..nc]) {
                *t += (*v * weights[c]) as f64;
            }
        }
        let (rot, mirrored) = self.posed.frames[self.posed.group_of[i]];
        let local = |w: Vec3| {
            let g = rot.transpose() * w.as_dvec3();
            if mirrored { DVec3::new(g.x, g.y, -g.z) } else { g }
        };
        let vis = self.lobe.visible_fraction(t, local(n), local(d), alpha);
        (self.env.reflect(n, wo, alpha, bsdf.f0(), bsdf.f90()), vis * open)
    }
}
