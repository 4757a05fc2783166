//! Hemispherical-harmonic radiance caching (Gautron et al. 2004, Křivánek et al.
//! 2005; equations H1–H23 as labelled in the article of `docs/references.md`): indirect light
//! from sparse records.
//!
//! - [`bounces`]: the bounces after the first, from the records re-lit, and how many a budget
//!   chooses;
//! - [`record`]: gathering a record (HSH coefficients, analytic translational gradients,
//!   harmonic mean distance);
//! - this module: placement by the Ward/Křivánek criterion (a new record where no existing one
//!   has weight above 1/a), lookup with the weights of H19 (clamped at a record's own
//!   position), gradient extrapolation (H23), rotation of each record into the receiver's
//!   frame, normalised blending, and the diffuse outgoing radiance `ρ/π Σ c_k h_k` with
//!   `h_k = ∫ H_k cos θ dω` (H5 with its missing cos θ restored).
//!
//! Rotation goes through SH (`hsh::Conversion`, order [`ROTATION_SH_ORDER`]); when the
//! receiver's normal is within [`SMALL_ANGLE`] of the record's the rotation is skipped (the
//! small-angle case, measured in the tests). A Lambertian receiver needs only irradiance, so it
//! integrates each record's SH against the cosine about its normal in the record's own frame
//! (Funk–Hecke) instead of rotating the record ([`Cache::irradiance_at`]; equal to rotating to
//! 1e-9).

pub mod bounces;
pub mod record;

pub use bounces::{Bounced, Bounces, bounce, bounce_with_light};

use crate::math::hsh;
use crate::named::Named;
use crate::scene::VertexValues;
use glam::{DMat3, DVec3, Vec3};
use record::{Change, Record, Source};
use std::collections::HashMap;

/// SH order of the rotation between record and receiver frames.
pub const ROTATION_SH_ORDER: usize = 8;
/// Normals closer than this angle (radians) skip the rotation.
pub const SMALL_ANGLE: f64 = 0.02;
/// Default roughness below which glossy receivers gather directly (measured: docs/radiance-cache.md).
pub const GLOSSY_FALLBACK_ROUGHNESS: f32 = 0.6;
/// Gauss–Legendre nodes in cos θ of the BRDF projection (twice as many in φ).
const BRDF_NODES: usize = 32;
/// Default [`Settings::noise`].
pub const DEFAULT_NOISE: f32 = 0.06;
/// Share of the RMS direct radiance over the receivers below which a record's light counts
/// as that much in [`Settings::noise`]: dim places show noise less in the image.
pub const NOISE_FLOOR: f32 = 0.25;

/// How a lookup blends the records around a point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Blend {
    /// H19 as written: the records whose weight w exceeds 1/a, weighted by w. A point at a
    /// record (records sit at vertices) takes that record alone, noise and all.
    Ward,
    /// The records whose weight exceeds 1/(2a) — twice Ward's reach —, each weight capped at
    /// 1/a, so a point blends its neighbourhood's records instead of copying the nearest one:
    /// records of few rays average out their noise (measured: docs/radiance-cache.md).
    Wide,
}

impl Named for Blend {
    const ALL: &'static [Blend] = &[Blend::Ward, Blend::Wide];

    fn name(self) -> &'static str {
        match self {
            Self::Ward => "ward",
            Self::Wide => "wide",
        }
    }

    fn about(self) -> &'static str {
        match self {
            Self::Ward => "H19 as written: records with weight above 1/a, weighted by it",
            Self::Wide => {
                "twice Ward's reach, weights capped at 1/a: for dense records of few rays (e.g. --cache-accuracy 0.2 --cache-rays 64)"
            }
        }
    }
}

impl Blend {
    /// The weight below which a record is not used, and the most any record weighs.
    fn limits(self, accuracy: f32) -> (f32, f32) {
        match self {
            Self::Ward => (1.0 / accuracy, f32::INFINITY),
            Self::Wide => (0.5 / accuracy, 1.0 / accuracy),
        }
    }
}

/// Cache parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// HSH order (bands 0..order−1).
    pub order: usize,
    /// Rays per record (rounded down to a square).
    pub rays: usize,
    /// Accuracy a: a record serves points where its weight exceeds 1/a.
    pub accuracy: f32,
    /// Use the translational gradients.
    pub gradients: bool,
    /// How gradients are computed.
    pub gradient_form: record::GradientForm,
    /// Bounds of the record radius R_i, as fractions of the scene's bounding diagonal.
    pub radius_bounds: (f32, f32),
    /// Glossy receivers smoother than this gather directly (BSDF-sampled, `rays` rays)
    /// instead of reading the cache, whose low-order HSH cannot hold their lobe.
    pub glossy_fallback: f32,
    /// How lookups blend records (placement always uses Ward's 1/a).
    pub blend: Blend,
    /// A record whose irradiance's standard error exceeds this share of its irradiance (of at
    /// least [`NOISE_FLOOR`] of the direct light's RMS) gathers again with twice the side (4× the
    /// rays): records that read a small bright patch through few rays (`f32::INFINITY`: never).
    pub noise: f32,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            order: 3,
            rays: 256,
            accuracy: 0.3,
            gradients: true,
            gradient_form: record::GradientForm::Analytic,
            radius_bounds: (0.01, 0.2),
            glossy_fallback: GLOSSY_FALLBACK_ROUGHNESS,
            blend: Blend::Ward,
            noise: DEFAULT_NOISE,
        }
    }
}

impl Settings {
    /// Side of the stratified ray grid.
    pub fn side(&self) -> usize {
        ((self.rays as f64).sqrt() as usize).max(1)
    }
}

/// What [`Cache::refresh`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Refresh {
    /// Records looked at so far (all of them once the refresh is complete).
    pub visited: usize,
    /// Records integrated again from their kept (and re-cast) hits.
    pub relit: usize,
    /// Records gathered anew (stored records have no hits).
    pub gathered: usize,
    /// Rays cast again because they crossed moved geometry.
    pub recast: usize,
    /// Rays cast for dense grids that records kept but now need ([`Settings::noise`]).
    pub densified: usize,
}

/// Records with a uniform grid over their areas of influence.
#[derive(Clone)]
pub struct Cache {
    /// The records, in creation order (record `i` gathered with ray stream `i`).
    pub records: Vec<Record>,
    /// What each record's rays hit, for [`Cache::refresh`] (empty for stored records).
    hits: Vec<record::Hits>,
    settings: Settings,
    /// [`record::Params::noise_floor`] for the lighting last placed or refreshed under.
    noise_floor: f32,
    bounds: (f32, f32),
    cell: f32,
    grid: HashMap<[i32; 3], Vec<u32>>,
    cosine: Vec<f64>,
    conversion: hsh::Conversion,
    /// Quadrature directions and weights for BRDF projections, with their HSH values.
    rule: Vec<(Vec3, f64)>,
    rule_h: Vec<f64>,
}

/// The H19 weight of a record at `p` with normal `n` (infinite at the record itself: clamped).
pub fn weight(r: &Record, p: Vec3, n: Vec3) -> f32 {
    let d = p.distance(r.p) / r.radius + (1.0 - n.dot(r.frame.n)).max(0.0).sqrt();
    1.0 / d.max(1e-6)
}

impl Cache {
    /// An empty cache for a scene whose bounding diagonal is `diagonal`.
    pub fn new(settings: Settings, diagonal: f32) -> Self {
        let bounds = (settings.radius_bounds.0 * diagonal, settings.radius_bounds.1 * diagonal);
        Self {
            records: Vec::new(),
            hits: Vec::new(),
            settings,
            noise_floor: 0.0,
            bounds,
            cell: (settings.accuracy * bounds.1).max(1e-6),
            grid: HashMap::new(),
            cosine: hsh::project(settings.order, 64, |d| d.z),
            conversion: hsh::Conversion::new(settings.order, ROTATION_SH_ORDER),
            rule: crate::math::quadrature::hemisphere_rule(BRDF_NODES)
                .into_iter()
                .map(|(d, w)| (d.as_vec3(), w))
                .collect(),
            rule_h: crate::math::quadrature::hemisphere_rule(BRDF_NODES)
                .into_iter()
                .flat_map(|(d, _)| hsh::eval(settings.order, d))
                .collect(),
        }
    }

    fn cell_of(&self, p: Vec3) -> [i32; 3] {
        (p / self.cell).floor().as_ivec3().to_array()
    }

    fn insert(&mut self, r: Record, hits: record::Hits) {
        self.records.push(r);
        self.hits.push(hits);
        self.index(self.records.len() - 1);
    }

    /// Enters record `id` in the grid cells its area of influence overlaps.
    fn index(&mut self, id: usize) {
        let r = &self.records[id];
        // w > least reaches R_i / least: a·R_i for Ward's blend and placement, 2a·R_i wide.
        let least = self.settings.blend.limits(self.settings.accuracy).0;
        let reach = Vec3::splat(r.radius / least);
        let (lo, hi) = (self.cell_of(r.p - reach), self.cell_of(r.p + reach));
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    self.grid.entry([x, y, z]).or_default().push(id as u32);
                }
            }
        }
    }

    /// Records usable at `p` (normal `n`) with their weights: weight above 1/a, and not in
    /// front of the point (Ward's test: a record ahead of the tangent plane sees other light).
    pub fn usable(&self, p: Vec3, n: Vec3) -> Vec<(u32, f32)> {
        self.usable_above(p, n, 1.0 / self.settings.accuracy)
    }

    /// [`Cache::usable`] with weights above `least`.
    fn usable_above(&self, p: Vec3, n: Vec3, least: f32) -> Vec<(u32, f32)> {
        let Some(ids) = self.grid.get(&self.cell_of(p)) else { return Vec::new() };
        ids.iter()
            .filter_map(|&i| {
                let r = &self.records[i as usize];
                let w = weight(r, p, n);
                let ahead = (p - r.p).dot(n + r.frame.n) * 0.5;
                (w > least && ahead > -0.05 * r.radius).then_some((i, w))
            })
            .collect()
    }

    /// Places records at `points` (in order): a new record wherever no usable one exists, its
    /// radius and its neighbours' clamped at contacts ([`Self::clamp_neighbours`]); passes repeat until
    /// every point has a usable record (a clamp can uncover a point placed before it). Returns
    /// the number of records made.
    pub fn place(&mut self, src: &Source, points: &[(Vec3, Vec3)]) -> usize {
        self.place_unless(src, points, &|| false).expect("never stopped")
    }

    /// [`Self::place`], giving up (`None`, the records made so far kept) once `stopped()`
    /// answers true, which it is asked before each record: an editor drops a gather the scene
    /// has outgrown instead of letting it take the cores its next bake needs.
    pub fn place_unless(&mut self, src: &Source, points: &[(Vec3, Vec3)], stopped: &dyn Fn() -> bool) -> Option<usize> {
        let before = self.records.len();
        self.noise_floor = noise_floor(src);
        loop {
            let made = self.records.len();
            for &(p, n) in points {
                if self.usable(p, n).is_empty() {
                    if stopped() {
                        return None;
                    }
                    let index = self.records.len() as u64;
                    let (r, hits) = record::gather_with_hits(src, p, n, &self.params(), index);
                    self.insert(r, hits);
                    self.clamp_neighbours(self.records.len() - 1);
                }
            }
            if self.records.len() == made {
                return Some(self.records.len() - before);
            }
        }
    }

    /// Neighbour clamping at contacts (after Křivánek et al. 2006): a record whose radius is at
    /// its lower bound (gathered at a contact or in a corner, whose rays meet geometry at once)
    /// bounds its neighbours' radii by its own plus their distance, so records from farther
    /// away do not serve across it with light they did not see. Between record `id` and the
    /// records indexed where it lies (those whose reach it is in), in both directions; radii
    /// stay within the bounds. Open surfaces, where no record is at the bound, are left as
    /// Ward placed them (docs/radiance-cache.md).
    fn clamp_neighbours(&mut self, id: usize) {
        let Some(ids) = self.grid.get(&self.cell_of(self.records[id].p)).cloned() else { return };
        let (p, mut radius, least) = (self.records[id].p, self.records[id].radius, self.bounds.0);
        for j in ids.into_iter().map(|j| j as usize).filter(|&j| j != id) {
            let d = self.records[j].p.distance(p);
            if self.records[j].radius <= least {
                radius = radius.min(self.records[j].radius + d).max(least);
            }
            if radius <= least {
                let r = &mut self.records[j];
                r.radius = r.radius.min(radius + d).max(least);
            }
        }
        self.records[id].radius = radius;
    }

    /// Re-lights the records after `change` (in parallel; each as [`record::relight`]): only
    /// records whose rays see changed radiance are integrated again, only rays crossing moved
    /// geometry are cast again, and records without their hits (stored ones) are gathered anew.
    /// The records keep their places; each equals a fresh gather there under the new lighting.
    pub fn refresh(&mut self, src: &Source, change: &Change) -> Refresh {
        self.refresh_progressively(src, change, usize::MAX, &mut |_, _| true)
    }

    /// [`Cache::refresh`] in batches of `batch` records, so a preview can show the re-lit
    /// records as they land: after each batch `landed(cache, so_far)` sees the cache with the
    /// batches so far re-lit and the rest as before, and returns whether to go on. A refresh
    /// stopped early leaves records of both lightings: discard the cache (or refresh it again
    /// from the same old lighting). The result does not depend on `batch`.
    pub fn refresh_progressively(
        &mut self,
        src: &Source,
        change: &Change,
        batch: usize,
        landed: &mut dyn FnMut(&Cache, &Refresh) -> bool,
    ) -> Refresh {
        let mut out = Refresh::default();
        if change.old_direct.is_some() {
            self.noise_floor = noise_floor(src);
        }
        let mut start = 0;
        while start < self.records.len() {
            let end = start.saturating_add(batch.max(1)).min(self.records.len());
            self.refresh_range(src, change, start..end, &mut out);
            out.visited = end;
            // Radii may have changed with what the rays hit.
            self.grid.clear();
            (0..self.records.len()).for_each(|i| self.index(i));
            if !landed(self, &out) {
                break;
            }
            start = end;
        }
        out
    }

    fn refresh_range(&mut self, src: &Source, change: &Change, range: std::ops::Range<usize>, out: &mut Refresh) {
        use rayon::prelude::*;
        let params = self.params();
        let first = range.start;
        let outcomes: Vec<(Option<Record>, record::Relit, bool)> = self.records[range.clone()]
            .par_iter()
            .zip(self.hits[range.clone()].par_iter_mut())
            .enumerate()
            .map(|(k, (r, hits))| {
                let gathered = hits.is_empty();
                let (fresh, relit) = record::relight(src, r.p, r.frame.n, &params, (first + k) as u64, hits, change);
                (fresh, relit, gathered)
            })
            .collect();
        for (r, (fresh, relit, gathered)) in self.records[range].iter_mut().zip(outcomes) {
            if !gathered {
                out.recast += relit.recast;
                out.densified += relit.densified;
            }
            out.gathered += usize::from(gathered);
            out.relit += usize::from(fresh.is_some() && !gathered);
            // A record keeps its place and its radius as placed (neighbour-clamped): a
            // refreshed cache is the cold placement under the new lighting.
            if let Some(mut fresh) = fresh {
                fresh.radius = fresh.radius.min(r.radius);
                *r = fresh;
            }
        }
    }

    /// The settings the cache was placed with.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// What this cache's gathers compute.
    pub fn params(&self) -> record::Params {
        let s = &self.settings;
        let form = s.gradient_form;
        let (side, bounds, noise, noise_floor) = (s.side(), self.bounds, s.noise, self.noise_floor);
        record::Params { order: s.order, side, bounds, form, min_cos_xi: record::MIN_COS_XI, noise, noise_floor }
    }

    /// Rays cast so far (a stored record counts as its grid).
    pub fn rays(&self) -> usize {
        self.records.len() * self.settings.side().pow(2) + self.hits.iter().map(record::Hits::dense_rays).sum::<usize>()
    }

    /// Records that have cast the denser grid ([`Settings::noise`]), used now or not.
    pub fn dense_records(&self) -> usize {
        self.hits.iter().filter(|h| h.dense_rays() > 0).count()
    }

    /// Incoming radiance at `p` (normal `n`) as HSH coefficients in the frame of
    /// `Frame::from_normal(n)`: the records the [`Blend`] takes, extrapolated, rotated and
    /// blended. `None` when there are none.
    pub fn incoming(&self, p: Vec3, n: Vec3) -> Option<Vec<DVec3>> {
        let frame = crate::math::frame::Frame::from_normal(n);
        let k = self.cosine.len();
        self.blend(p, n, vec![DVec3::ZERO; k], |sum, r, c, w| {
            sum.iter_mut().zip(self.rotate(&c, r, &frame)).for_each(|(s, c)| *s += c * w);
        })
        .map(|(sum, total)| sum.into_iter().map(|s| s / total).collect())
    }

    /// Irradiance at `p` (normal `n`): [`Self::irradiance`] of [`Self::incoming`], each record
    /// integrated against the cosine about `n` in its own frame instead of rotated into the
    /// receiver's (what a Lambertian receiver needs; [`hsh::Conversion::irradiance_functional`]).
    pub fn irradiance_at(&self, p: Vec3, n: Vec3) -> Option<Vec3> {
        let (sum, total) = self.blend(p, n, DVec3::ZERO, |sum, r, c, w| {
            let g = if self.unrotated(r, n) {
                std::borrow::Cow::Borrowed(&self.cosine)
            } else {
                std::borrow::Cow::Owned(
                    self.conversion.irradiance_functional(r.frame.to_local(n).as_dvec3().normalize()),
                )
            };
            *sum += c.iter().zip(g.iter()).map(|(c, g)| *c * *g).sum::<DVec3>() * w;
        })?;
        Some((sum / total).max(DVec3::ZERO).as_vec3())
    }

    /// Folds `add(sum, record, its coefficients extrapolated to p, weight)` over the records the
    /// [`Blend`] takes at `p` (normal `n`), from `sum`; with the weights' total, or `None`
    /// when there are none.
    fn blend<T>(
        &self,
        p: Vec3,
        n: Vec3,
        mut sum: T,
        add: impl Fn(&mut T, &Record, Vec<DVec3>, f64),
    ) -> Option<(T, f64)> {
        let (least, most) = self.settings.blend.limits(self.settings.accuracy);
        let usable = self.usable_above(p, n, least);
        if usable.is_empty() {
            return None;
        }
        let mut total = 0.0f64;
        for (i, w) in usable {
            let r = &self.records[i as usize];
            let mut c = r.coeffs.clone();
            if self.settings.gradients {
                extrapolate(&mut c, r, r.frame.to_local(p - r.p).as_dvec3());
            }
            let w = w.min(most) as f64;
            add(&mut sum, r, c, w);
            total += w;
        }
        Some((sum, total))
    }

    /// Whether record `r` is used as it is at a receiver with normal `n` (the small-angle case).
    fn unrotated(&self, r: &Record, n: Vec3) -> bool {
        r.frame.n.dot(n) as f64 >= SMALL_ANGLE.cos()
    }

    /// A record's coefficients in the receiver's frame.
    fn rotate(&self, c: &[DVec3], r: &Record, to: &crate::math::frame::Frame) -> Vec<DVec3> {
        if self.unrotated(r, to.n) {
            return c.to_vec();
        }
        let basis = |f: &crate::math::frame::Frame| DMat3::from_cols(f.t.as_dvec3(), f.b.as_dvec3(), f.n.as_dvec3());
        // Receiver-local from record-local: g(d_recv) = f(d_rec), d_rec = Bᵢᵀ B_r d_recv.
        self.conversion.rotate_rgb(c, basis(to).transpose() * basis(&r.frame))
    }

    /// Radiance leaving toward local `wo` for a BSDF, from incoming-radiance coefficients in the
    /// same frame: `Σ c_k b_k` with `b_k = ∫ f(ωi, wo) cos θi H_k(ωi) dωi` (H5 with cos θ).
    pub fn outgoing(&self, c: &[DVec3], bsdf: &crate::material::Bsdf, wo: Vec3) -> Vec3 {
        if !bsdf.has_specular() {
            return bsdf.diffuse_albedo() * self.irradiance(c) / std::f32::consts::PI;
        }
        let k = c.len();
        let mut out = DVec3::ZERO;
        for (j, (d, w)) in self.rule.iter().enumerate() {
            let f = (bsdf.eval(wo, *d) * d.z).as_dvec3() * *w;
            let h = &self.rule_h[j * k..(j + 1) * k];
            let l: DVec3 = c.iter().zip(h).map(|(c, h)| *c * *h).sum();
            out += f * l;
        }
        out.max(DVec3::ZERO).as_vec3()
    }

    /// Irradiance from incoming-radiance coefficients: Σ c_k h_k.
    pub fn irradiance(&self, c: &[DVec3]) -> Vec3 {
        c.iter().zip(&self.cosine).map(|(c, h)| *c * *h).sum::<DVec3>().max(DVec3::ZERO).as_vec3()
    }
}

/// Every receiver vertex (instance, vertex) with its world position and normal, in instance order.
fn vertices(src: &Source) -> Vec<(usize, usize, Vec3, Vec3)> {
    let r = src.renderer;
    (0..r.flat.instances.len())
        .flat_map(|i| (0..r.mesh(i).positions.len()).map(move |v| (i, v)))
        .map(|(i, v)| {
            let (p, n) = r.vertex(i, v);
            (i, v, p, n)
        })
        .collect()
}

/// The boxes a re-light must re-cast through when the lights went from `old` to `new`: the old
/// and new bounds of every light that moved, turned or resized (of every light when lights
/// were added or removed), padded so that grazing rays count.
pub fn moved_lights(old: &[crate::scene::FlatLight], new: &[crate::scene::FlatLight]) -> Vec<(Vec3, Vec3)> {
    let bounds = |l: &crate::scene::FlatLight| {
        let (lo, hi) = l.points.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
        let pad = Vec3::splat(1e-4 * (hi - lo).length() + 1e-5);
        (lo - pad, hi + pad)
    };
    if old.len() != new.len() {
        return old.iter().chain(new).map(bounds).collect();
    }
    old.iter().zip(new).filter(|(a, b)| a.points != b.points).flat_map(|(a, b)| [bounds(a), bounds(b)]).collect()
}

/// At most this fraction of a record's own (DC) radiance may its gradients add or remove.
const GRADIENT_LIMIT: f64 = 0.25;

/// Extrapolates record `r`'s coefficients `c` by its gradients over the tangent-frame offset
/// `d` (H23), per channel limited so the DC term moves by at most [`GRADIENT_LIMIT`] of itself:
/// sparse records are looked up far from where they were gathered, and a gradient steep near
/// contact (small R_i) would otherwise swing the extrapolation far past anything gathered.
fn extrapolate(c: &mut [DVec3], r: &Record, d: DVec3) {
    let delta: Vec<DVec3> = r.grad_x.iter().zip(&r.grad_y).map(|(gx, gy)| *gx * d.x + *gy * d.y).collect();
    let (c0, d0) = (c[0].abs() * GRADIENT_LIMIT, delta[0].abs());
    let scale = DVec3::select(d0.cmpgt(c0), c0 / d0, DVec3::ONE);
    c.iter_mut().zip(&delta).for_each(|(c, d)| *c += *d * scale);
}

/// [`NOISE_FLOOR`] of the RMS over the receivers' vertices of their direct radiance (mean of
/// the channels) under `src`'s lighting.
fn noise_floor(src: &Source) -> f32 {
    let vertices = src.direct.iter().flatten();
    let (sum, count) = vertices.fold((0.0f64, 0usize), |(a, n), v| (a + (v.element_sum() as f64 / 3.0).powi(2), n + 1));
    NOISE_FLOOR * (sum / count.max(1) as f64).sqrt() as f32
}

/// The receivers' bounding diagonal.
fn diagonal(src: &Source) -> f32 {
    let flat = &src.renderer.flat;
    // The receivers' extent: lights move at run time and must not move the radius bounds.
    let (lo, hi) = flat
        .triangles
        .iter()
        .zip(&flat.refs)
        .filter(|(_, r)| r.light == crate::scene::NO_LIGHT)
        .flat_map(|(t, _)| t)
        .fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    (hi - lo).length().max(1e-6)
}

/// True when instance `i` of `renderer`'s scene is a glossy receiver smoother somewhere than
/// the cache can serve — at its smoothest vertex, where a roughness texture varies it (it
/// gathers directly; no records are placed on it).
pub fn falls_back(renderer: &crate::reference::Renderer, s: &Settings, i: usize) -> bool {
    let flat = &renderer.flat;
    let m = &flat.instances[i].material;
    let vertices = (0..flat.vertex_count(i)).filter(|_| flat.varies(i));
    let smoothest = vertices.map(|v| flat.vertex_material(i, v).roughness).fold(m.roughness, f32::min);
    crate::material::Bsdf::new(m, Vec3::Z).has_specular() && smoothest < s.glossy_fallback
}

/// [`falls_back`] for every instance.
fn fallbacks(renderer: &crate::reference::Renderer, s: &Settings) -> Vec<bool> {
    (0..renderer.flat.instances.len()).map(|i| falls_back(renderer, s, i)).collect()
}

/// A cache with records placed at the receiver vertices (in order) that read it (not the
/// glossy receivers that gather directly).
pub fn place_at_vertices(src: &Source, s: &Settings) -> Cache {
    place_at_vertices_unless(src, s, &|| false).expect("never stopped")
}

/// [`place_at_vertices`], `None` once `stopped()` answers true (see [`Cache::place_unless`]).
pub fn place_at_vertices_unless(src: &Source, s: &Settings, stopped: &dyn Fn() -> bool) -> Option<Cache> {
    let mut cache = Cache::new(*s, diagonal(src));
    let back = fallbacks(src.renderer, s);
    let points: Vec<(Vec3, Vec3)> = vertices(src).iter().filter(|v| !back[v.0]).map(|&(_, _, p, n)| (p, n)).collect();
    cache.place_unless(src, &points, stopped)?;
    Some(cache)
}

/// A cache from stored records (e.g. the bake database's), as [`place_at_vertices`] made them.
pub fn from_records(src: &Source, s: &Settings, records: Vec<Record>) -> Cache {
    let mut cache = Cache::new(*s, diagonal(src));
    cache.noise_floor = noise_floor(src);
    records.into_iter().for_each(|r| cache.insert(r, record::Hits::default()));
    cache
}

/// One bounce of indirect light toward `eye` at every receiver vertex from `cache`, or by a
/// direct BSDF-sampled gather for glossy receivers smoother than [`Settings::glossy_fallback`].
pub fn shade_vertices(src: &Source, cache: &Cache, eye: Vec3) -> VertexValues {
    shade_as(src, cache, Some(eye), &|i, v| src.renderer.flat.vertex_material(i, v))
}

/// The light one bounce brings to every receiver vertex from `cache`: irradiance over π, the
/// radiance a white Lambertian surface there would reflect (view-independent; where
/// [`shade_vertices`] gathers directly, so does this).
pub fn light_vertices(src: &Source, cache: &Cache) -> VertexValues {
    let white = crate::scene::Material::lambertian(Vec3::ONE);
    shade_as(src, cache, None, &|_, _| white)
}

/// [`shade_vertices`] with `material(instance, vertex)` at the receivers in place of theirs,
/// toward `eye` (`None`: along each vertex's normal).
fn shade_as(
    src: &Source,
    cache: &Cache,
    eye: Option<Vec3>,
    material: &(dyn Fn(usize, usize) -> crate::scene::Material + Sync),
) -> VertexValues {
    use rayon::prelude::*;
    let s = &cache.settings;
    let back = fallbacks(src.renderer, s);
    let values: Vec<Vec3> = vertices(src)
        .par_iter()
        .enumerate()
        .map(|(k, &(i, v, p, n))| {
            let frame = crate::math::frame::Frame::from_normal(n);
            let wo = eye.map_or(Vec3::Z, |eye| frame.to_local((eye - p).normalize_or(n)));
            let bsdf = crate::material::Bsdf::new(&material(i, v), wo);
            if back[i] {
                return record::gather_bsdf(src, p, n, &bsdf, wo, s.side(), k as u64);
            }
            if !bsdf.has_specular() {
                let e = cache.irradiance_at(p, n).unwrap_or(Vec3::ZERO);
                return bsdf.diffuse_albedo() * e / std::f32::consts::PI;
            }
            cache.incoming(p, n).map_or(Vec3::ZERO, |c| cache.outgoing(&c, &bsdf, wo))
        })
        .collect();
    split(src, values)
}

/// [`place_at_vertices`] then [`shade_vertices`]: per instance, and the cache.
pub fn indirect_vertices(src: &Source, s: &Settings, eye: Vec3) -> (VertexValues, Cache) {
    let cache = place_at_vertices(src, s);
    (shade_vertices(src, &cache, eye), cache)
}

/// Brute-force gathering: `rays` BSDF-sampled rays at every vertex toward `eye`, no cache (the
/// baseline the cache is measured against), per instance.
pub fn gather_vertices(src: &Source, rays: usize, eye: Vec3) -> VertexValues {
    use rayon::prelude::*;
    let side = ((rays as f64).sqrt() as usize).max(1);
    let values: Vec<Vec3> = vertices(src)
        .par_iter()
        .enumerate()
        .map(|(k, &(i, v, p, n))| gather_one(src, (i, v, p, n), eye, side, k as u64))
        .collect();
    split(src, values)
}

/// Brute-force gathering at vertex `v` of instance `i` (at `p`, normal `n`) toward `eye`:
/// `side²` BSDF-sampled rays from ray stream `index`.
fn gather_one(src: &Source, (i, v, p, n): (usize, usize, Vec3, Vec3), eye: Vec3, side: usize, index: u64) -> Vec3 {
    let wo = crate::math::frame::Frame::from_normal(n).to_local((eye - p).normalize_or(n));
    let bsdf = crate::material::Bsdf::new(&src.renderer.flat.vertex_material(i, v), wo);
    record::gather_bsdf(src, p, n, &bsdf, wo, side, index)
}

/// Per-instance vectors from a flat list in vertex order.
fn split(src: &Source, mut values: Vec<Vec3>) -> VertexValues {
    let r = src.renderer;
    let mut out = Vec::new();
    for i in 0..r.flat.instances.len() {
        let rest = values.split_off(r.mesh(i).positions.len());
        out.push(std::mem::replace(&mut values, rest));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(c0: f64, grad: f64) -> Record {
        Record {
            p: Vec3::ZERO,
            frame: crate::math::frame::Frame::from_normal(Vec3::Z),
            radius: 0.1,
            coeffs: vec![DVec3::new(c0, 2.0 * c0, 0.0), DVec3::splat(0.3)],
            grad_x: vec![DVec3::splat(grad), DVec3::splat(grad)],
            grad_y: vec![DVec3::ZERO; 2],
        }
    }

    /// A Lambertian receiver's irradiance from the records ([`Cache::irradiance_at`]) equals
    /// the irradiance of their coefficients extrapolated, rotated into its frame and blended,
    /// where its normal is within the small angle of a record's and where it is tilted away.
    #[test]
    fn irradiance_at_equals_the_irradiance_of_the_rotated_blend() {
        let mut cache = Cache::new(Settings::default(), 10.0);
        let normals = [Vec3::Z, Vec3::new(0.3, 0.1, 1.0).normalize(), Vec3::new(-0.4, 0.2, 1.0).normalize()];
        for (i, n) in normals.into_iter().enumerate() {
            let k = |j: usize| j as f64;
            let record = Record {
                p: Vec3::new(0.2 * i as f32, 0.0, 0.1 * i as f32),
                frame: crate::math::frame::Frame::from_normal(n),
                radius: 1.0,
                coeffs: (0..9).map(|j| DVec3::new(1.0 - 0.1 * k(j), 0.5 + 0.05 * k(j), 0.3 * k(j).cos())).collect(),
                grad_x: vec![DVec3::splat(0.1); 9],
                grad_y: vec![DVec3::splat(-0.05); 9],
            };
            cache.insert(record, record::Hits::default());
        }
        let mut compared = 0;
        for (a, b) in (0..6).flat_map(|a| (0..6).map(move |b| (a, b))) {
            let p = Vec3::new(0.05 * a as f32, 0.0, 0.04 * b as f32);
            let n = Vec3::new(0.06 * (a as f32 - 2.5), 0.05 * (b as f32 - 2.5), 1.0).normalize();
            for n in [n, normals[a % 3]] {
                let (fast, c) = (cache.irradiance_at(p, n), cache.incoming(p, n));
                assert_eq!(fast.is_some(), c.is_some(), "the same records at {p}");
                let (Some(fast), Some(c)) = (fast, c) else { continue };
                let rotated = cache.irradiance(&c);
                assert!(
                    (fast - rotated).abs().max_element() < 1e-5 * (1.0 + rotated.max_element()),
                    "{fast} vs {rotated}"
                );
                compared += 1;
            }
        }
        assert!(compared > 50, "{compared} receivers with records");
    }

    #[test]
    fn gradients_extrapolate_as_is_until_they_would_move_the_record_past_its_limit() {
        let gentle = record(1.0, 0.5);
        let mut c = gentle.coeffs.clone();
        extrapolate(&mut c, &gentle, DVec3::new(0.2, 0.0, 0.0));
        // (The blue channel has no radiance at the record: its DC term may not move at all.)
        assert_eq!(c, vec![DVec3::new(1.1, 2.1, 0.0), DVec3::new(0.4, 0.4, 0.3)]);
        // A steep gradient far out: the DC term moves by at most the limit, per channel, and
        // the other coefficients by the same factor; a channel with no radiance does not move.
        let steep = record(1.0, 50.0);
        let mut c = steep.coeffs.clone();
        extrapolate(&mut c, &steep, DVec3::new(-0.2, 0.0, 0.0));
        let moved = c[0] - steep.coeffs[0];
        assert!((moved - DVec3::new(-GRADIENT_LIMIT, -2.0 * GRADIENT_LIMIT, 0.0)).abs().max_element() < 1e-12);
        // Coefficient 1's gradient equals the DC term's here, so it moves by the same amount.
        assert!((c[1] - (steep.coeffs[1] + moved)).abs().max_element() < 1e-12, "{c:?}");
    }
}
