//! One radiance-cache record: incoming radiance over the hemisphere above a surface point in
//! hemispherical harmonics (seed H4), its translational gradients (analytic form, H9–H18 with
//! the corrections in docs/references.md), and the harmonic mean distance R_i (H20).
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
use std::f64::consts::PI;

/// Smallest cos ξ the solid-angle gradient uses by default.
pub const MIN_COS_XI: f32 = 0.1;

/// Where gather rays find radiance: the scene, each instance's per-vertex direct radiance
/// (used for Lambertian hits, where it is view-independent), and how glossy hits are lit.
pub struct Source<'a> {
    /// The scene's BVH and snapshot.
    pub renderer: &'a Renderer,
    /// Per instance and vertex: radiance leaving the vertex from direct light.
    pub direct: &'a [Vec<Vec3>],
    /// How a glossy hit's radiance toward the record is found.
    pub glossy: Glossy<'a>,
}

/// The direct radiance leaving a point of one of instance `i`'s triangles toward another point:
/// `(i, the triangle's corner vertices, the point's barycentrics, toward)`.
pub type Toward<'a> = &'a (dyn Fn(usize, [usize; 3], [f32; 3], Vec3) -> Vec3 + Sync);

/// How a gather ray's glossy hit is lit: its direct light leaves it toward the record, not
/// toward the camera the per-vertex values were shaded for.
#[derive(Clone, Copy)]
pub enum Glossy<'a> {
    /// The reference's direct-light estimate toward the record with this many samples.
    Reference(u32),
    /// The direct method's own shading (e.g. BSPVT) of the hit point toward the record:
    /// consistent with the direct term, and noise-free.
    Toward(Toward<'a>),
    /// The per-vertex value: right only where the direct method is view-independent (PRT).
    PerVertex,
}

/// Samples per glossy hit when the reference lights them (CLI and report).
pub const GLOSSY_SPP: u32 = 4;

/// What a direct method offers for lighting glossy hits (the owned side of [`Glossy`]).
#[derive(Clone)]
pub enum GlossyDirect {
    /// Nothing of its own: the reference estimates them (the reference itself, and
    /// `ltc-exact-vis`, whose cube maps would be cast again per hit).
    Reference,
    /// Its per-vertex values are view-independent (PRT shades GGX surfaces' diffuse part).
    PerVertex,
    /// LTC at the hit toward the record, shadowed by these trees (`None`: unshadowed).
    Ltc(Option<std::sync::Arc<crate::bspvt::Bake>>),
}

impl GlossyDirect {
    /// Runs `f` with the [`Glossy`] this stands for in `scene` (snapshot `flat`).
    pub fn with<R>(&self, flat: &crate::scene::FlatScene, f: impl FnOnce(Glossy) -> R) -> R {
        let bake = if let Self::Ltc(b) = self { b.as_deref() } else { None };
        let toward = |i: usize, corners: [usize; 3], bary: [f32; 3], point: Vec3| {
            crate::bspvt::shade_point(flat, bake, i, corners, bary, point)
        };
        f(match self {
            Self::Reference => Glossy::Reference(GLOSSY_SPP),
            Self::PerVertex => Glossy::PerVertex,
            Self::Ltc(_) => Glossy::Toward(&toward),
        })
    }
}

/// What one gather ray found: radiance toward the record, distance, and the hit's normal
/// facing back along the ray.
struct Sample {
    radiance: Vec3,
    t: f32,
    normal: Vec3,
}

impl Source<'_> {
    /// What a gather ray from `o` along `d` finds; `stream` seeds glossy hits' estimates.
    fn trace(&self, o: Vec3, d: Vec3, stream: u64, outside: &mut Outside) -> Option<Sample> {
        let hit = self.renderer.bvh.closest_hit_past_touching(o, d, f32::INFINITY)?;
        Some(self.light(o, hit, d, stream, outside))
    }

    /// The radiance `hit` (of a ray from `o` along `d`) sends back along the ray; `outside`
    /// remembers the corners of triangles met at the start of the record's rays (see
    /// [`Self::diffuse_at`]).
    fn light(&self, o: Vec3, hit: Hit, d: Vec3, stream: u64, outside: &mut Outside) -> Sample {
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
        let m = r.flat.material_at(inst, self.corner_indices(hit), barycentrics(hit));
        let glossy = m.has_specular();
        let radiance = match self.glossy {
            Glossy::Reference(spp) if glossy => {
                let sp = r.surface_at(hit, inst, tref.local as usize, d);
                let s = crate::reference::Settings { spp, seed: 0x6105, ..Default::default() };
                r.estimate_point(&sp, -d, &s, stream).mean
            }
            Glossy::Toward(shade) if glossy => shade(inst, self.corner_indices(hit), barycentrics(hit), o),
            _ => self.diffuse_at(hit, inst, outside),
        };
        Sample { radiance, t: hit.t, normal }
    }

    /// The direct radiance at a Lambertian `hit` on instance `inst`, interpolated from its
    /// corners. A hit met at its ray's start (a gather from a box's foot down into the floor it
    /// stands on) lies on the line where an object rests: there, as in pixels
    /// ([`crate::bspvt::pixel`]), corners inside that object (under the box, dark) take no part,
    /// or the foot's records would read the floor's triangulation, a streak each.
    fn diffuse_at(&self, hit: Hit, inst: usize, memo: &mut Outside) -> Vec3 {
        let corners = self.corners(hit, self.direct);
        let mut weights = barycentrics(hit);
        if hit.t == 0.0 {
            let outside = match memo.0.iter().find(|(t, _)| *t == hit.triangle) {
                Some(&(_, outside)) => outside,
                None => {
                    let (flat, bvh) = (&self.renderer.flat, &self.renderer.bvh);
                    let outside = self.corner_indices(hit).map(|v| {
                        let (p, n) = flat.vertex(inst, v);
                        !bvh.inside(p, n)
                    });
                    memo.0.push((hit.triangle, outside));
                    outside
                }
            };
            let kept: [f32; 3] = std::array::from_fn(|k| if outside[k] { weights[k] } else { 0.0 });
            let (sum, count) = (kept.iter().sum::<f32>(), outside.iter().filter(|&&o| o).count());
            if sum > 1e-6 {
                weights = kept.map(|w| w / sum);
            } else if count > 0 {
                weights = outside.map(|o| if o { 1.0 / count as f32 } else { 0.0 });
            }
        }
        corners.iter().zip(weights).map(|(v, w)| *v * w).sum()
    }

    /// The direct radiance in `direct` at the corners of a receiver `hit`'s triangle, in the
    /// order of [`barycentrics`].
    fn corners(&self, hit: Hit, direct: &[Vec<Vec3>]) -> [Vec3; 3] {
        let inst = self.renderer.flat.refs[hit.triangle as usize].owner as usize;
        self.corner_indices(hit).map(|v| direct[inst][v])
    }

    /// The vertex indices of a receiver `hit`'s triangle corners, in [`barycentrics`] order.
    fn corner_indices(&self, hit: Hit) -> [usize; 3] {
        let r = self.renderer;
        let tref = r.flat.refs[hit.triangle as usize];
        let inst = tref.owner as usize;
        let idx = r.mesh(inst).triangles[tref.local as usize];
        let (i1, i2) = if r.flat.instances[inst].mirrored { (idx[2], idx[1]) } else { (idx[1], idx[2]) };
        [idx[0], i1, i2].map(|i| i as usize)
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

/// Which corners of the triangles met at a ray's start lie outside geometry: a record's
/// gathers from a box's foot meet the one or two floor triangles at that point, so their
/// corners are tested once per record, not once per ray.
#[derive(Default)]
struct Outside(Vec<(u32, [bool; 3])>);

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

/// How a gradient is computed (seed H6–H18).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GradientForm {
    /// The derivative of H4 in closed form (H9–H18, corrected).
    #[default]
    Analytic,
    /// Each ray's hit point held fixed while the record moves by a small step (H7–H8), as a
    /// central difference with a step of 10⁻³ of the ray's length.
    Numerical,
}

impl crate::named::Named for GradientForm {
    const ALL: &'static [GradientForm] = &[GradientForm::Analytic, GradientForm::Numerical];

    fn name(self) -> &'static str {
        match self {
            Self::Analytic => "analytic",
            Self::Numerical => "numerical",
        }
    }

    fn about(self) -> &'static str {
        match self {
            Self::Analytic => "closed form (H9–H18)",
            Self::Numerical => "hit points held fixed while the record moves a small step (H7–H8)",
        }
    }
}

/// What a gather computes: HSH order, `side²` rays, the clamp of R_i, the gradient form and
/// when a record's rays are too few.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Params {
    /// HSH order.
    pub order: usize,
    /// Side of the stratified ray grid.
    pub side: usize,
    /// Clamp of the harmonic mean distance R_i.
    pub bounds: (f32, f32),
    /// Gradient form.
    pub form: GradientForm,
    /// Smallest cos ξ the gradients use ([`MIN_COS_XI`]; 0 for the exact derivative).
    pub min_cos_xi: f32,
    /// Share of its light (irradiance over π) that a record's standard error may reach before
    /// it gathers again with a grid of twice the side ([`Hits`]); `f32::INFINITY`: never.
    pub noise: f32,
    /// Least light (as radiance) the share is taken of: where less arrives, noise shows less.
    pub noise_floor: f32,
}

/// What a record's rays hit, kept for [`relight`]: the `side²` grid every record casts, and,
/// for a record whose grid reads its light too noisily, the denser grid (`(2·side)²` rays) its
/// values come from. Its radius is always the first grid's: record places follow the
/// receivers' geometry alone, never the lighting.
#[derive(Clone, Debug, Default)]
pub struct Hits {
    /// The `side²` grid's hits.
    coarse: Vec<Option<Hit>>,
    /// The `(2·side)²` grid's hits once cast (kept when a later lighting needs them no more).
    dense: Vec<Option<Hit>>,
    /// The coarse grid's noise under the lighting it was last integrated with.
    noise: Noise,
    /// Whether the record's values come from the dense grid.
    uses_dense: bool,
}

/// A grid's irradiance over π (as radiance) and its standard error, estimated from the
/// differences between neighbouring strata: a horizon or a lit wall spanning many strata adds
/// little, a small bright patch that few rays meet adds much.
#[derive(Clone, Copy, Debug, Default)]
struct Noise {
    error: f32,
    light: f32,
}

impl Hits {
    /// Whether rays were kept (stored records have none).
    pub fn is_empty(&self) -> bool {
        self.coarse.is_empty()
    }

    /// Rays cast for the denser grid.
    pub fn dense_rays(&self) -> usize {
        self.dense.len()
    }
}

/// Gathers a record at `p` (unit normal `n`) with ray stream `index`.
pub fn gather(src: &Source, p: Vec3, n: Vec3, params: &Params, index: u64) -> Record {
    gather_with_hits(src, p, n, params, index).0
}

/// [`gather`], also returning what its rays hit (for [`relight`]).
pub fn gather_with_hits(src: &Source, p: Vec3, n: Vec3, params: &Params, index: u64) -> (Record, Hits) {
    let mut hits = Hits::default();
    let record = relight(src, p, n, params, index, &mut hits, &Change { old_direct: None, moved: &[] }).0;
    (record.expect("a record without rays is gathered"), hits)
}

/// The grids' stream keys: the coarse grid's is the one records have always used.
const GRID_STREAMS: [u64; 2] = [0xCAC4E, 0xDE45E];

/// A record's gather directions in its frame: `side²` rays stratified uniformly in solid angle,
/// jittered by stream `index` of the grid's `key`.
fn directions(side: usize, key: u64, index: u64) -> Vec<Vec3> {
    let mut r = rng::stream(key, index);
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

/// The harmonic mean distance of the receivers `hits` met, clamped to `bounds`. Lights move at
/// run time: record spacing follows the receivers' geometry alone, so a refresh after a light
/// moves keeps the places a cold placement would choose.
fn radius(src: &Source, hits: &[Option<Hit>], bounds: (f32, f32)) -> f32 {
    let receivers =
        hits.iter().flatten().filter(|h| src.renderer.flat.refs[h.triangle as usize].light == crate::scene::NO_LIGHT);
    let inverse_distance: f64 = receivers.map(|h| 1.0 / h.t.max(1e-6) as f64).sum();
    let harmonic = if inverse_distance > 0.0 { (hits.len() as f64 / inverse_distance) as f32 } else { f32::INFINITY };
    harmonic.clamp(bounds.0, bounds.1)
}

/// The record at `p` from its rays' local directions `dirs` and `hits`, with `radius`:
/// coefficients and gradients; and its [`Noise`].
fn integrate(
    src: &Source,
    p: Vec3,
    frame: Frame,
    params: &Params,
    (dirs, hits): (&[Vec3], &[Option<Hit>]),
    radius: f32,
    index: u64,
) -> (Record, Noise) {
    let omega = 2.0 * PI / dirs.len() as f64;
    let k = hsh::num_coeffs(params.order);
    let (mut c, mut gx, mut gy) = (vec![DVec3::ZERO; k], vec![DVec3::ZERO; k], vec![DVec3::ZERO; k]);
    let mut strata = vec![0.0f64; dirs.len()];
    let mut outside = Outside::default();
    for (j, (&local, hit)) in dirs.iter().zip(hits).enumerate() {
        let Some(hit) = hit else { continue };
        let d = frame.to_world(local);
        let hit = src.light(p, *hit, d, rng::mix64(index) ^ j as u64, &mut outside);
        if hit.radiance == Vec3::ZERO {
            continue;
        }
        let l = hit.radiance.as_dvec3();
        strata[j] = l.element_sum() / 3.0 * local.z as f64;
        let ray = Ray {
            min_cos_xi: params.min_cos_xi as f64,
            dir: local.as_dvec3(),
            t: hit.t.max(1e-6) as f64,
            q: frame.to_local(d * hit.t).as_dvec3(),
            normal: frame.to_local(hit.normal).as_dvec3(),
        };
        let h = hsh::eval(params.order, ray.dir);
        let (dx, dy) = match params.form {
            GradientForm::Analytic => ray.analytic(params.order, &h, omega),
            GradientForm::Numerical => ray.numerical(params.order, omega),
        };
        for i in 0..k {
            c[i] += l * (h[i] * omega);
            gx[i] += l * dx[i];
            gy[i] += l * dy[i];
        }
    }
    let noise = Noise {
        error: (omega * paired_spread(&strata) / PI) as f32,
        light: (omega * strata.iter().sum::<f64>() / PI) as f32,
    };
    (Record { p, frame, radius, coeffs: c, grad_x: gx, grad_y: gy }, noise)
}

/// √Σ (x_a − x_b)² over pairs of strata neighbouring in cos θ (row-major `side²` values, one
/// sample each): an estimate of the standard deviation of Σ x that stratification leaves, since
/// two strata of equal mean and variance v differ by 2v in square on average.
fn paired_spread(strata: &[f64]) -> f64 {
    let side = (strata.len() as f64).sqrt() as usize;
    let rows = strata.chunks_exact(side.max(1));
    rows.flat_map(|row| row.chunks_exact(2).map(|p| (p[0] - p[1]).powi(2))).sum::<f64>().sqrt()
}

/// One gather ray in the record's frame: direction, length, hit point and the hit's normal
/// (facing back along the ray).
struct Ray {
    min_cos_xi: f64,
    dir: DVec3,
    t: f64,
    q: DVec3,
    normal: DVec3,
}

impl Ray {
    /// cos ξ, the hit normal's angle to the ray, clamped (grazing hits would dominate).
    fn cos_xi(&self, dir: DVec3) -> f64 {
        self.normal.dot(-dir).max(self.min_cos_xi)
    }

    /// `∂(Ω H_k)/∂x` and `∂(Ω H_k)/∂y` in closed form (H9, H10 and the HSH derivatives).
    fn analytic(&self, order: usize, h: &[f64], omega: f64) -> (Vec<f64>, Vec<f64>) {
        let (tx, ty) = hsh::gradient_terms(order, self.dir);
        let (t, cos_xi) = (self.t, self.cos_xi(self.dir));
        let d_omega = |nx: f64, qx: f64| omega * (t * nx + 3.0 * qx * cos_xi) / (t * t * cos_xi);
        let (dox, doy) = (d_omega(self.normal.x, self.q.x), d_omega(self.normal.y, self.q.y));
        let along = |terms: &[f64], d_o: f64| terms.iter().zip(h).map(|(g, h)| g / t * omega + h * d_o).collect();
        (along(&tx, dox), along(&ty, doy))
    }

    /// The same by H7–H8: `Ω' H_k(ω')` with the hit point fixed and the record moved by ±δ
    /// along each axis, `Ω' = Ω (r/r')² cos ξ'/cos ξ`, as a central difference.
    fn numerical(&self, order: usize, omega: f64) -> (Vec<f64>, Vec<f64>) {
        let delta = 1e-3 * self.t;
        let moved = |offset: DVec3| {
            let q = self.q - offset;
            let r = q.length();
            let dir = q / r;
            let weight = omega * (self.t * self.t) / (r * r) * self.cos_xi(dir) / self.cos_xi(self.dir);
            let above = DVec3::new(dir.x, dir.y, dir.z.max(0.0)).normalize();
            hsh::eval(order, above).into_iter().map(move |h| weight * h)
        };
        let along = |axis: DVec3| {
            moved(axis * delta).zip(moved(-axis * delta)).map(|(plus, minus)| (plus - minus) / (2.0 * delta)).collect()
        };
        (along(DVec3::X), along(DVec3::Y))
    }
}

/// What changed since a record's rays were cast: the direct radiance they read before, and the
/// boxes (lo, hi) of geometry that moved (lights' old and new polygons; every light's when
/// lights were added or removed), which rays crossing them must be cast again. The receivers'
/// geometry is the same.
pub struct Change<'a> {
    /// Per instance and vertex: the direct radiance the record was gathered with; `None` when
    /// every hit's light may have changed (a further bounce, whose glossy hits are lit
    /// otherwise than the first's).
    pub old_direct: Option<&'a [Vec<Vec3>]>,
    /// Boxes of moved geometry, old and new places.
    pub moved: &'a [(Vec3, Vec3)],
}

/// What a re-light did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Relit {
    /// Rays cast again (they crossed moved geometry).
    pub recast: usize,
    /// Rays cast for a dense grid the record needs now and had not cast.
    pub densified: usize,
    /// The record's radiance may have changed, and it was integrated again.
    pub changed: bool,
}

/// Re-lights the record at `p` (normal `n`, stream `index`) whose rays found `hits` (none
/// yet: gathers it), after `change`: rays crossing moved geometry are cast again, and when any
/// ray's radiance may differ the record is integrated again. The coarse grid's noise under the
/// new lighting chooses the grid the values come from (the dense one cast when first needed),
/// so the result equals a fresh [`gather`] at the same place under the new lighting. `None`:
/// nothing it sees changed.
pub fn relight(
    src: &Source,
    p: Vec3,
    n: Vec3,
    params: &Params,
    index: u64,
    hits: &mut Hits,
    change: &Change,
) -> (Option<Record>, Relit) {
    let frame = Frame::from_normal(n);
    let mut relit = Relit::default();
    let coarse = directions(params.side, GRID_STREAMS[0], index);
    let mut changed = recast(src, p, n, frame, &coarse, &mut hits.coarse, change, &mut relit.recast);
    let r = radius(src, &hits.coarse, params.bounds);
    let mut record = None;
    if changed {
        let (fresh, noise) = integrate(src, p, frame, params, (&coarse, &hits.coarse), r, index);
        (record, hits.noise) = (Some(fresh), noise);
    }
    let dense = hits.noise.error > params.noise * hits.noise.light.max(params.noise_floor);
    if dense {
        let dirs = directions(2 * params.side, GRID_STREAMS[1], index);
        let cast = if hits.dense.is_empty() { &mut relit.densified } else { &mut relit.recast };
        // The coarse grid's change may be its radius's: integrate again whenever it changed.
        changed = recast(src, p, n, frame, &dirs, &mut hits.dense, change, cast) || !hits.uses_dense || changed;
        record = changed.then(|| integrate(src, p, frame, params, (&dirs, &hits.dense), r, index).0);
    } else if hits.uses_dense && record.is_none() {
        record = Some(integrate(src, p, frame, params, (&coarse, &hits.coarse), r, index).0);
    }
    hits.uses_dense = dense;
    relit.changed = record.is_some();
    (record, relit)
}

/// Brings `hits` of rays along local `dirs` up to date after `change` (all cast when there are
/// none yet; those crossing moved geometry cast again, counted in `cast`): whether any ray's
/// radiance may differ.
#[allow(clippy::too_many_arguments)]
fn recast(
    src: &Source,
    p: Vec3,
    n: Vec3,
    frame: Frame,
    dirs: &[Vec3],
    hits: &mut Vec<Option<Hit>>,
    change: &Change,
    cast: &mut usize,
) -> bool {
    let fresh = hits.is_empty();
    if fresh {
        hits.resize(dirs.len(), None);
    }
    let mut changed = fresh;
    for (local, hit) in dirs.iter().zip(hits.iter_mut()) {
        let d = frame.to_world(*local);
        let o = offset_ray_origin(p, n, d);
        let reach = hit.map_or(f32::INFINITY, |h| h.t);
        if fresh || change.moved.iter().any(|&(lo, hi)| slab_hits(o, d.recip(), reach, lo, hi)) {
            let again = src.renderer.bvh.closest_hit_past_touching(o, d, f32::INFINITY);
            *cast += 1;
            changed |= again != *hit;
            *hit = again;
        }
        changed |= hit.is_some_and(|h| change.old_direct.is_none_or(|old| src.changed(h, old)));
    }
    changed
}

/// Radiance leaving `p` toward local `wo` from one bounce, by `side²` BSDF-sampled gather rays
/// (the direct gather that glossy receivers fall back to).
pub fn gather_bsdf(
    src: &Source,
    p: Vec3,
    n: Vec3,
    bsdf: &crate::material::Bsdf,
    wo: Vec3,
    side: usize,
    index: u64,
) -> Vec3 {
    let frame = Frame::from_normal(n);
    let mut r = rng::stream(0x61055, index);
    let (mut sum, mut outside) = (Vec3::ZERO, Outside::default());
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
        let stream = rng::mix64(index ^ 0x61055) ^ j as u64;
        if let Some(hit) = src.trace(offset_ray_origin(p, n, d), d, stream, &mut outside) {
            sum += hit.radiance * bsdf.eval(wo, wi) * wi.z / pdf;
        }
    }
    sum / (side * side) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The strata's spread: nothing for a constant, little for a smooth ramp across the grid
    /// (what independent samples' variance would count in full), much for one bright stratum.
    #[test]
    fn the_paired_spread_sees_small_bright_patches_not_smooth_change() {
        let side = 16;
        assert_eq!(paired_spread(&[0.5; 256]), 0.0);
        let ramp: Vec<f64> = (0..side * side).map(|j| (j % side) as f64 / side as f64).collect();
        let patch: Vec<f64> = (0..side * side).map(|j| if j == 37 { 8.0 } else { 0.0 }).collect();
        let (sum, squares) = ramp.iter().fold((0.0, 0.0), |(a, b), x| (a + x, b + x * x));
        let independent = (squares - sum * sum / 256.0).sqrt();
        assert!(paired_spread(&ramp) < 0.25 * independent, "{} vs {independent}", paired_spread(&ramp));
        assert_eq!(paired_spread(&patch), 8.0);
    }

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
