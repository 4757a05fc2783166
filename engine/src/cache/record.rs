//! One radiance-cache record: incoming radiance over the hemisphere above a surface point in
//! hemispherical harmonics (seed H4), its translational gradients (analytic form, H9–H18 with
//! the corrections in DESIGN.md), and the harmonic mean distance R_i (H20).
//!
//! Gather rays are stratified uniformly in solid angle (each stands for Ω = 2π/N). A ray that
//! hits a receiver sees the radiance leaving the hit toward the record: the hit triangle's
//! per-vertex diffuse direct radiance, interpolated (one BVH query per ray). Emitters and the
//! environment are direct light, not one bounce of indirect, and back faces are the insides of
//! closed objects: they contribute nothing here.
//!
//! Gradient of `c_k = Σ_j L_j H_k(ω_j) Ω_j` when the record moves along its tangent x (fixed
//! hit points): `∂c_k/∂x = Σ_j L_j [∂H_k/∂x Ω_j + H_k ∂Ω_j/∂x]` with
//! `∂H_k/∂x = gradient_terms(ω_j)/r_j` and `∂Ω_j/∂x = Ω_j (r_j n_x + 3 q_x cos ξ_j)/(r_j² cos ξ_j)`
//! (q = hit − record, n the hit's normal facing the record, ξ its angle to −ω_j), cos ξ clamped
//! at [`MIN_COS_XI`]: grazing hits would otherwise dominate (Křivánek et al. note the same).

use crate::accel::{Hit, offset_ray_origin, slab_hits};
use crate::math::frame::Frame;
use crate::math::{hsh, rng};
use crate::reference::Renderer;
use glam::{DVec3, Vec3};
use rand::Rng;

/// Smallest cos ξ the solid-angle gradient uses.
pub const MIN_COS_XI: f32 = 0.1;

/// Where gather rays find radiance: the scene, each instance's per-vertex direct radiance
/// (used for Lambertian hits, where it is view-independent), and for glossy hits the reference's
/// direct-light estimate toward the record with `glossy_spp` samples (0: use the per-vertex
/// value there too, right only if it is view-independent).
pub struct Source<'a> {
    /// The scene's BVH and snapshot.
    pub renderer: &'a Renderer,
    /// Per instance and vertex: radiance leaving the vertex from direct light.
    pub direct: &'a [Vec<Vec3>],
    /// Direct-light samples per glossy hit, evaluated toward the record.
    pub glossy_spp: u32,
}

/// Samples per glossy hit used by the CLI and the report.
pub const GLOSSY_SPP: u32 = 4;

/// What one gather ray found: radiance toward the record, distance, and the hit's normal
/// facing back along the ray.
struct Sample {
    radiance: Vec3,
    t: f32,
    normal: Vec3,
}

impl Source<'_> {
    /// What a gather ray from `o` along `d` finds; `stream` seeds glossy hits' estimates.
    fn trace(&self, o: Vec3, d: Vec3, stream: u64) -> Option<Sample> {
        let hit = self.renderer.bvh.closest_hit(o, d, f32::INFINITY)?;
        Some(self.light(hit, d, stream))
    }

    /// The radiance `hit` (of a ray along `d`) sends back along the ray.
    fn light(&self, hit: Hit, d: Vec3, stream: u64) -> Sample {
        let r = self.renderer;
        let tri = r.flat.triangles[hit.triangle as usize];
        let normal = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize_or_zero();
        let tref = r.flat.refs[hit.triangle as usize];
        // Emitters are direct light; a back face is the inside of a closed object (a ray that
        // started in contact geometry): neither reflects one bounce toward the record.
        if tref.light != crate::scene::NO_LIGHT || normal.dot(d) > 0.0 {
            return Sample { radiance: Vec3::ZERO, t: hit.t, normal };
        }
        let inst = tref.owner as usize;
        let m = r.flat.instances[inst].material;
        if self.glossy_spp > 0 && (m.metallic > 0.0 || m.specular > 0.0) {
            // A glossy hit reflects direct light toward the record, not toward the camera.
            let sp = r.surface_at(hit, inst, tref.local as usize, d);
            let s = crate::reference::Settings { spp: self.glossy_spp, seed: 0x6105, ..Default::default() };
            let radiance = r.estimate_point(&sp, -d, &s, stream).mean;
            return Sample { radiance, t: hit.t, normal };
        }
        let radiance = self.corners(hit, self.direct).iter().zip(barycentrics(hit)).map(|(v, b)| *v * b).sum();
        Sample { radiance, t: hit.t, normal }
    }

    /// The direct radiance in `direct` at the corners of a receiver `hit`'s triangle, in the
    /// order of [`barycentrics`].
    fn corners(&self, hit: Hit, direct: &[Vec<Vec3>]) -> [Vec3; 3] {
        let r = self.renderer;
        let tref = r.flat.refs[hit.triangle as usize];
        let inst = tref.owner as usize;
        let idx = r.mesh(inst).triangles[tref.local as usize];
        let (i1, i2) = if r.flat.instances[inst].mirrored { (idx[2], idx[1]) } else { (idx[1], idx[2]) };
        [idx[0], i1, i2].map(|i| direct[inst][i as usize])
    }

    /// Whether the radiance `hit` sends may differ from what it sent under direct radiance
    /// `old`: a receiver whose corners' direct radiance changed (for a glossy hit, whose
    /// estimate toward the record reads the lights themselves, the corners' camera-facing values
    /// stand in: light that changes it changes them). A light's triangle sends nothing either way.
    fn changed(&self, hit: Hit, old: &[Vec<Vec3>]) -> bool {
        self.renderer.flat.refs[hit.triangle as usize].light == crate::scene::NO_LIGHT
            && self.corners(hit, old) != self.corners(hit, self.direct)
    }
}

/// Weights of a hit's triangle corners (b0, b1, b2).
fn barycentrics(hit: Hit) -> [f32; 3] {
    [1.0 - hit.bary.x - hit.bary.y, hit.bary.x, hit.bary.y]
}

/// A record.
#[derive(Clone, Debug, PartialEq)]
pub struct Record {
    /// Position.
    pub p: Vec3,
    /// Tangent frame (+Z = normal); gradients are along its t and b axes.
    pub frame: Frame,
    /// Harmonic mean distance of the gathered hits, clamped.
    pub radius: f32,
    /// HSH coefficients of the incoming radiance (RGB), in the record's frame.
    pub coeffs: Vec<DVec3>,
    /// ∂coeffs/∂x along `frame.t`.
    pub grad_x: Vec<DVec3>,
    /// ∂coeffs/∂y along `frame.b`.
    pub grad_y: Vec<DVec3>,
}

impl Record {
    /// The record as little-endian f64s: p, frame (t, b, n), radius, then coefficients and both
    /// gradients (RGB each) — the bake database's artefact layout.
    pub fn to_f64s(&self) -> Vec<f64> {
        let mut out: Vec<f64> =
            [self.p, self.frame.t, self.frame.b, self.frame.n].iter().flat_map(|v| v.as_dvec3().to_array()).collect();
        out.push(self.radius as f64);
        for list in [&self.coeffs, &self.grad_x, &self.grad_y] {
            out.extend(list.iter().flat_map(|c| c.to_array()));
        }
        out
    }

    /// Records of HSH order `order` from [`Record::to_f64s`] data (`None` if malformed).
    pub fn from_f64s(data: &[f64], order: usize) -> Option<Vec<Record>> {
        let k = hsh::num_coeffs(order);
        let size = 13 + 9 * k;
        if !data.len().is_multiple_of(size) {
            return None;
        }
        data.chunks_exact(size)
            .map(|c| {
                let v = |i: usize| Vec3::new(c[i] as f32, c[i + 1] as f32, c[i + 2] as f32);
                let list =
                    |from: usize| (0..k).map(|j| DVec3::from_slice(&c[from + 3 * j..from + 3 * j + 3])).collect();
                let frame = Frame { t: v(3), b: v(6), n: v(9) };
                let ok = c.iter().all(|x| x.is_finite()) && c[12] > 0.0;
                ok.then(|| Record {
                    p: v(0),
                    frame,
                    radius: c[12] as f32,
                    coeffs: list(13),
                    grad_x: list(13 + 3 * k),
                    grad_y: list(13 + 6 * k),
                })
            })
            .collect()
    }
}

/// Gathers a record at `p` (unit normal `n`) with `side²` stratified rays of stream `index`,
/// HSH `order`, the harmonic mean distance clamped to `[r_min, r_max]`.
pub fn gather(src: &Source, p: Vec3, n: Vec3, order: usize, side: usize, index: u64, bounds: (f32, f32)) -> Record {
    gather_with_hits(src, p, n, order, side, index, bounds).0
}

/// [`gather`], also returning what each ray hit (for [`relight`]).
pub fn gather_with_hits(
    src: &Source,
    p: Vec3,
    n: Vec3,
    order: usize,
    side: usize,
    index: u64,
    bounds: (f32, f32),
) -> (Record, Vec<Option<Hit>>) {
    let frame = Frame::from_normal(n);
    let dirs = directions(side, index);
    let hits: Vec<Option<Hit>> = dirs
        .iter()
        .map(|l| {
            let d = frame.to_world(*l);
            src.renderer.bvh.closest_hit(offset_ray_origin(p, n, d), d, f32::INFINITY)
        })
        .collect();
    (integrate(src, p, frame, order, &dirs, &hits, index, bounds), hits)
}

/// A record's gather directions in its frame: `side²` rays stratified uniformly in solid angle,
/// jittered by stream `index`.
fn directions(side: usize, index: u64) -> Vec<Vec3> {
    let mut r = rng::stream(0xCAC4E, index);
    (0..side * side)
        .map(|j| {
            let (u, v) = (
                ((j % side) as f32 + r.random::<f32>()) / side as f32,
                ((j / side) as f32 + r.random::<f32>()) / side as f32,
            );
            let (z, phi) = (u, 2.0 * std::f32::consts::PI * v);
            let s = (1.0 - z * z).max(0.0).sqrt();
            Vec3::new(s * phi.cos(), s * phi.sin(), z)
        })
        .collect()
}

/// The record at `p` from its rays' local directions `dirs` and `hits`: coefficients, analytic
/// gradients and the clamped harmonic mean distance.
#[allow(clippy::too_many_arguments)]
fn integrate(
    src: &Source,
    p: Vec3,
    frame: Frame,
    order: usize,
    dirs: &[Vec3],
    hits: &[Option<Hit>],
    index: u64,
    (r_min, r_max): (f32, f32),
) -> Record {
    let omega = 2.0 * std::f64::consts::PI / dirs.len() as f64;
    let k = hsh::num_coeffs(order);
    let (mut c, mut gx, mut gy) = (vec![DVec3::ZERO; k], vec![DVec3::ZERO; k], vec![DVec3::ZERO; k]);
    let mut inverse_distance = 0.0f64;
    for (j, (&local, hit)) in dirs.iter().zip(hits).enumerate() {
        let Some(hit) = hit else { continue };
        let d = frame.to_world(local);
        let hit = src.light(*hit, d, rng::mix64(index) ^ j as u64);
        inverse_distance += 1.0 / hit.t.max(1e-6) as f64;
        if hit.radiance == Vec3::ZERO {
            continue;
        }
        let l = hit.radiance.as_dvec3();
        let dl = local.as_dvec3();
        let h = hsh::eval(order, dl);
        let (tx, ty) = hsh::gradient_terms(order, dl);
        let t = hit.t.max(1e-6) as f64;
        let q = frame.to_local(d * hit.t).as_dvec3();
        let nk = frame.to_local(hit.normal).as_dvec3();
        let cos_xi = (nk.dot(-dl)).max(MIN_COS_XI as f64);
        let d_omega = |nx: f64, qx: f64| omega * (t * nx + 3.0 * qx * cos_xi) / (t * t * cos_xi);
        let (dox, doy) = (d_omega(nk.x, q.x), d_omega(nk.y, q.y));
        for i in 0..k {
            c[i] += l * (h[i] * omega);
            gx[i] += l * (tx[i] / t * omega + h[i] * dox);
            gy[i] += l * (ty[i] / t * omega + h[i] * doy);
        }
    }
    let harmonic = if inverse_distance > 0.0 { (dirs.len() as f64 / inverse_distance) as f32 } else { f32::INFINITY };
    Record { p, frame, radius: harmonic.clamp(r_min, r_max), coeffs: c, grad_x: gx, grad_y: gy }
}

/// What changed since a record's rays were cast: the direct radiance they read before, and the
/// boxes (lo, hi) of geometry that moved (lights' old and new polygons; every light's when
/// lights were added or removed), which rays crossing them must be cast again. The receivers'
/// geometry is the same.
pub struct Change<'a> {
    /// Per instance and vertex: the direct radiance the record was gathered with.
    pub old_direct: &'a [Vec<Vec3>],
    /// Boxes of moved geometry, old and new places.
    pub moved: &'a [(Vec3, Vec3)],
}

/// What a re-light did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Relit {
    /// Rays cast again (they crossed moved geometry).
    pub recast: usize,
    /// The record's radiance may have changed, and it was integrated again.
    pub changed: bool,
}

/// Re-lights the record at `p` (normal `n`, stream `index`) whose rays found `hits`, after
/// `change`: rays crossing moved geometry are cast again, and when any
/// ray's radiance may differ the record is integrated again — equal to a fresh
/// [`gather`] at the same place under the new lighting. `None`: nothing it sees changed.
#[allow(clippy::too_many_arguments)]
pub fn relight(
    src: &Source,
    p: Vec3,
    n: Vec3,
    order: usize,
    index: u64,
    bounds: (f32, f32),
    hits: &mut [Option<Hit>],
    change: &Change,
) -> (Option<Record>, Relit) {
    let frame = Frame::from_normal(n);
    let side = (hits.len() as f64).sqrt() as usize;
    let dirs = directions(side, index);
    let mut relit = Relit::default();
    for (local, hit) in dirs.iter().zip(hits.iter_mut()) {
        let d = frame.to_world(*local);
        let o = offset_ray_origin(p, n, d);
        let reach = hit.map_or(f32::INFINITY, |h| h.t);
        let crosses = change.moved.iter().any(|&(lo, hi)| slab_hits(o, d.recip(), reach, lo, hi));
        if crosses {
            let again = src.renderer.bvh.closest_hit(o, d, f32::INFINITY);
            relit.recast += 1;
            relit.changed |= again != *hit;
            *hit = again;
        }
        relit.changed |= hit.is_some_and(|h| src.changed(h, change.old_direct));
    }
    let record = relit.changed.then(|| integrate(src, p, frame, order, &dirs, hits, index, bounds));
    (record, relit)
}

/// Radiance leaving `p` toward local `wo` from one bounce, by `side²` BSDF-sampled gather rays
/// (the direct gather that glossy receivers fall back to).
pub fn gather_bsdf(
    src: &Source,
    p: Vec3,
    n: Vec3,
    bsdf: &crate::reference::Bsdf,
    wo: Vec3,
    side: usize,
    index: u64,
) -> Vec3 {
    let frame = Frame::from_normal(n);
    let mut r = rng::stream(0x61055, index);
    let mut sum = Vec3::ZERO;
    for j in 0..side * side {
        let u = glam::Vec2::new(
            ((j % side) as f32 + r.random::<f32>()) / side as f32,
            ((j / side) as f32 + r.random::<f32>()) / side as f32,
        );
        let Some(wi) = bsdf.sample(wo, r.random(), u) else { continue };
        let pdf = bsdf.pdf(wo, wi);
        if pdf <= 0.0 {
            continue;
        }
        let d = frame.to_world(wi);
        if let Some(hit) = src.trace(offset_ray_origin(p, n, d), d, rng::mix64(index ^ 0x61055) ^ j as u64) {
            sum += hit.radiance * bsdf.eval(wo, wi) * wi.z / pdf;
        }
    }
    sum / (side * side) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_round_trip_through_f64s_bit_for_bit() {
        let r = Record {
            p: Vec3::new(0.1, -2.0, 3.3),
            frame: Frame::from_normal(Vec3::new(0.3, 0.9, 0.1).normalize()),
            radius: 0.37,
            coeffs: (0..9).map(|i| DVec3::new(i as f64, 0.5, -1.0 / (i + 1) as f64)).collect(),
            grad_x: (0..9).map(|i| DVec3::splat(i as f64 * 0.1)).collect(),
            grad_y: (0..9).map(|i| DVec3::splat(-(i as f64))).collect(),
        };
        let data = [r.to_f64s(), r.to_f64s()].concat();
        assert_eq!(Record::from_f64s(&data, 3).unwrap(), vec![r.clone(), r]);
        assert!(Record::from_f64s(&data[1..], 3).is_none(), "a cut record is malformed");
    }
}
