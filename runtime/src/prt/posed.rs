//! The lighting posed into every rigid group for one frame, and a vertex's light from it.

use super::lighting::{Region, Window, to_group_frame};
use super::silhouette::{Openings, Silhouette};
use crate::math::{luminance, sh};
use glam::{DMat3, DVec3, Vec3};
use rayon::prelude::*;
use std::sync::Arc;

/// The lighting posed into every group for one frame: what per-vertex shading needs besides
/// the transfer and the albedo. CPU and GPU shading share it.
pub struct Posed {
    /// SH order used (the bake's, at most the lighting's).
    pub order: usize,
    /// Per group index: the windowed SH lighting in the group's frame (n² RGB coefficients).
    pub lighting: Vec<Vec<DVec3>>,
    /// Per group index: per region, the windowed SH basis at `w_i` in the group's frame
    /// (q × n², region-major).
    pub region_basis: Vec<Vec<f64>>,
    /// Group index of every instance.
    pub group_of: Vec<usize>,
    /// The environment's regions (empty without shadows between groups).
    pub regions: Vec<Region>,
    /// Angular width √spread of each region: the box filter's size per unit distance.
    pub widths: Vec<f32>,
    /// Per group index: one silhouette per region.
    pub silhouettes: Vec<Arc<Vec<Silhouette>>>,
    /// Per group index: the world-from-group rotation (scale removed) and mirror flag.
    pub frames: Vec<(DMat3, bool)>,
}

impl Posed {
    /// Poses world-frame lighting `coeffs` (windowed by `window`) into groups whose
    /// world-from-group rotations and mirror flags are `frames`, at order `order` (at most the
    /// lighting's). `regions` (world) and `silhouettes` (one list per group, one silhouette per
    /// region) are empty when no shadows fall between groups.
    pub fn new(
        order: usize,
        coeffs: &[DVec3],
        window: Window,
        regions: Vec<Region>,
        frames: Vec<(DMat3, bool)>,
        group_of: Vec<usize>,
        silhouettes: Vec<Arc<Vec<Silhouette>>>,
    ) -> Self {
        let order = order.min((coeffs.len() as f64).sqrt() as usize);
        let window = window.per_coeff(order);
        let (lighting, region_basis) = frames
            .iter()
            .map(|&(rot, mirrored)| {
                let local = to_group_frame(&coeffs[..sh::num_coeffs(order)], rot, mirrored);
                let lw = local.iter().zip(&window).map(|(c, h)| *c * *h).collect();
                let mirror = if mirrored { DVec3::new(1.0, 1.0, -1.0) } else { DVec3::ONE };
                let yh = regions
                    .iter()
                    .flat_map(|r| {
                        let d = mirror * (rot.transpose() * r.dir.as_dvec3());
                        sh::eval(order, d).into_iter().zip(&window).map(|(y, h)| y * h).collect::<Vec<_>>()
                    })
                    .collect();
                (lw, yh)
            })
            .unzip();
        let widths = regions.iter().map(|r| r.spread.sqrt() as f32).collect();
        Self { order, lighting, region_basis, group_of, regions, widths, silhouettes, frames }
    }

    /// `Ls`, the unshadowed-by-others diffuse light (albedo not applied, not clamped), of a
    /// vertex of instance `i` with transfer `t` (n² coefficients or more).
    pub fn diffuse(&self, i: usize, t: &[f32]) -> Vec3 {
        let lw = &self.lighting[self.group_of[i]];
        let l: DVec3 = t[..lw.len()].iter().zip(lw).map(|(t, c)| *c * *t as f64).sum();
        l.as_vec3()
    }

    /// `T(v, w_i)` of a vertex of instance `i` with transfer `t` toward region `r`, clamped at 0.
    pub fn toward_region(&self, i: usize, t: &[f32], r: usize) -> f32 {
        let n = sh::num_coeffs(self.order);
        let y = &self.region_basis[self.group_of[i]][r * n..(r + 1) * n];
        (t[..n].iter().zip(y).map(|(t, y)| *t as f64 * y).sum::<f64>()).max(0.0) as f32
    }

    /// `max(0, Ls − Σ_i B_i T_i V_o)` (the albedo multiplies it) at `p` from interpolated `ls`
    /// and `t`, with `V_o = 1 − Π (1 − V_g)` over the (region, group) `pairs` (sorted by
    /// region) that are not in group `own`; and the fraction of `Ls` (by luminance) the other
    /// groups leave, which the specular term is dimmed by.
    pub fn radiance(
        &self,
        own: usize,
        ls: Vec3,
        t: impl Fn(usize) -> f32,
        p: Vec3,
        pairs: &[(u16, u16)],
    ) -> (Vec3, f32) {
        let mut l = ls.as_dvec3();
        for run in pairs.chunk_by(|a, b| a.0 == b.0) {
            let r = run[0].0 as usize;
            let tr = t(r);
            if tr <= 0.0 {
                continue;
            }
            let width = self.widths[r];
            let open: f32 = run
                .iter()
                .filter(|(_, g)| *g as usize != own)
                .map(|&(_, g)| 1.0 - self.silhouettes[g as usize][r].occlusion(p, width))
                .product();
            if open < 1.0 {
                l -= self.regions[r].power * (tr * (1.0 - open)) as f64;
            }
        }
        let l = l.max(DVec3::ZERO).as_vec3();
        let lit = luminance(ls.max(Vec3::ZERO));
        let open = if lit > 0.0 { (luminance(l) / lit).clamp(0.0, 1.0) } else { 1.0 };
        (l, open)
    }

    /// Every (region, group) pair, sorted by region.
    pub fn all_pairs(&self) -> Vec<(u16, u16)> {
        (0..self.regions.len()).flat_map(|r| (0..self.silhouettes.len()).map(move |g| (r as u16, g as u16))).collect()
    }

    /// The pairs whose shadow can reach a sphere (a tile's or an instance's points).
    pub fn pairs_reaching(&self, centre: Vec3, radius: f32) -> Vec<(u16, u16)> {
        self.all_pairs()
            .into_iter()
            .filter(|&(r, g)| self.silhouettes[g as usize][r as usize].reaches(centre, radius, self.widths[r as usize]))
            .collect()
    }
}

/// One silhouette per region of a group's world triangles (open where `holes` says), at
/// `res` texels per side.
pub fn group_silhouettes(t: &[[Vec3; 3]], holes: &dyn Openings, regions: &[Region], res: usize) -> Vec<Silhouette> {
    let (lo, hi) = t.iter().flatten().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    let centre = 0.5 * (lo + hi);
    let radius = t.iter().flatten().map(|p| p.distance(centre)).fold(0.0f32, f32::max);
    regions.par_iter().map(|r| Silhouette::build(t, holes, centre, radius, r.dir, res)).collect()
}
