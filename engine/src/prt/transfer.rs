//! Diffuse self-transfer (the PRT paper's Eq. 2–5): per vertex, in its group's frame,
//! `T_k = ∫ V_self(ω) max(0, ω·n) / π · Y_k(ω) dω`, albedo left out (applied at shading), by
//! stratified directions shared by every vertex (one SH table, one deterministic set).

use crate::accel::{SceneBvh, offset_ray_origin};
use crate::math::{rng, sampling, sh};
use glam::{DVec3, Vec2, Vec3};
use rand::Rng;

/// A stratified set of sphere directions with their SH values.
#[derive(Clone, Debug)]
pub struct Directions {
    /// Order of [`Self::sh`].
    pub order: usize,
    /// Unit directions.
    pub dirs: Vec<Vec3>,
    /// `sh[j * n² + k]` = `Y_k(dirs[j])`.
    pub sh: Vec<f32>,
}

impl Directions {
    /// `side²` jittered-stratified directions (uniform over the sphere), seeded.
    pub fn stratified(side: usize, order: usize, seed: u64) -> Self {
        let mut r = rng::seeded(seed);
        let mut dirs = Vec::with_capacity(side * side);
        for j in 0..side {
            for i in 0..side {
                let u = Vec2::new(
                    (i as f32 + r.random::<f32>()) / side as f32,
                    (j as f32 + r.random::<f32>()) / side as f32,
                );
                dirs.push(sampling::uniform_sphere(u));
            }
        }
        let n = sh::num_coeffs(order);
        let mut y = vec![0.0; n];
        let mut table = Vec::with_capacity(dirs.len() * n);
        for d in &dirs {
            sh::eval_into(order, d.as_dvec3(), &mut y);
            table.extend(y.iter().map(|&v| v as f32));
        }
        Self { order, dirs, sh: table }
    }

    /// Solid angle each direction stands for.
    pub fn weight(&self) -> f32 {
        4.0 * std::f32::consts::PI / self.dirs.len() as f32
    }
}

/// The transfer coefficients of a point `p` with unit normal `n` (both in the group's frame)
/// against the group's own geometry; `out` gets n² values.
pub fn vertex_transfer(bvh: &SceneBvh, dirs: &Directions, p: Vec3, n: Vec3, out: &mut [f32]) {
    let k = sh::num_coeffs(dirs.order);
    let mut acc = vec![0.0f64; k];
    for (j, d) in dirs.dirs.iter().enumerate() {
        let cos = d.dot(n);
        if cos <= 0.0 || bvh.occluded_past_touching(offset_ray_origin(p, n, *d), *d, f32::INFINITY) {
            continue;
        }
        let y = &dirs.sh[j * k..(j + 1) * k];
        acc.iter_mut().zip(y).for_each(|(a, y)| *a += (cos * y) as f64);
    }
    let scale = (dirs.weight() / std::f32::consts::PI) as f64;
    out.iter_mut().zip(&acc).for_each(|(o, a)| *o = (a * scale) as f32);
}

/// Σ_k h_k T_k Y_k(d): the windowed transfer toward local direction `d`.
pub fn reconstruct(t: &[f32], window: &[f64], d: DVec3) -> f64 {
    let order = (t.len() as f64).sqrt() as usize;
    sh::eval(order, d).iter().zip(t).zip(window).map(|((y, t), h)| y * *t as f64 * h).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::shapes;

    #[test]
    fn unoccluded_transfer_is_the_clamped_cosine_over_pi() {
        let dirs = Directions::stratified(64, 4, 3);
        let empty = SceneBvh::new(&[]);
        let n = Vec3::new(0.3, 0.8, -0.52).normalize();
        let mut t = vec![0.0; 16];
        vertex_transfer(&empty, &dirs, Vec3::ZERO, n, &mut t);
        // Exact: the clamped cosine's zonal coefficients rotated to n, over π.
        let zonal = sh::clamped_cosine_zonal(4);
        let y = sh::eval(4, n.as_dvec3());
        for (l, z) in zonal.iter().enumerate() {
            let s = (4.0 * std::f64::consts::PI / (2 * l + 1) as f64).sqrt() * z / std::f64::consts::PI;
            for m in -(l as i32)..=l as i32 {
                let k = sh::index(l, m);
                assert!((t[k] as f64 - s * y[k]).abs() < 4e-3, "k {k}: {} vs {}", t[k], s * y[k]);
            }
        }
    }

    /// A floor vertex on the line where a box rests lies in the plane of the box's side: its
    /// rays leaving along that side pass it, so it receives what a point a hair away does
    /// (it read 0, dark, when the side rounded onto its rays).
    #[test]
    fn a_vertex_at_a_resting_boxs_foot_is_not_dark() {
        let m = shapes::cuboid(Vec3::splat(0.5));
        let centre = Vec3::new(-0.9, 0.5, 0.3);
        let mut tris: Vec<[Vec3; 3]> =
            m.triangles.iter().map(|t| t.map(|i| m.positions[i as usize] + centre)).collect();
        let h = 4.0;
        let [a, b, c, d] = [(-h, -h), (-h, h), (h, h), (h, -h)].map(|(x, z)| Vec3::new(x, 0.0, z));
        tris.extend([[a, b, c], [a, c, d]]);
        let (bvh, dirs) = (SceneBvh::new(&tris), Directions::stratified(64, 3, 1));
        let dc = |x: f32| {
            let mut t = vec![0.0; 9];
            vertex_transfer(&bvh, &dirs, Vec3::new(x, 0.0, 0.3), Vec3::Y, &mut t);
            t[0]
        };
        let (foot, beside) = (dc(-0.4), dc(-0.4 + 1e-5));
        assert!(beside > 0.1 && (foot - beside).abs() < 0.01 * beside, "foot {foot}, beside {beside}");
    }

    #[test]
    fn a_point_inside_a_closed_box_receives_nothing() {
        let m = shapes::cuboid(Vec3::ONE);
        let tris: Vec<[Vec3; 3]> = m.triangles.iter().map(|t| t.map(|i| m.positions[i as usize])).collect();
        let bvh = SceneBvh::new(&tris);
        let dirs = Directions::stratified(16, 3, 1);
        let mut t = vec![1.0; 9];
        vertex_transfer(&bvh, &dirs, Vec3::ZERO, Vec3::Y, &mut t);
        assert!(t.iter().all(|&v| v == 0.0), "{t:?}");
    }
}
