//! Fitting LTCs to GGX, as in Heitz et al.'s `fitLTC.cpp` (published data in `assets/reference/ltc/`):
//! the fitted lobe is `D·G2/(4 cos θv)` (BRDF × cos θl, height-correlated Smith, no
//! Fresnel); the error is Σ |f − f_ltc|³ / (pdf_ltc + pdf_brdf) over 32×32 stratified samples
//! of each distribution; Nelder–Mead on (m11, m22, m13) with the lobe frame aligned to the
//! BRDF's average direction, isotropic at normal incidence, each fit starting from its
//! neighbour (roughness from high to low, view from normal to grazing).

use super::{Entry, TABLE_SIZE, entry_params};
use crate::math::{ggx, nelder_mead, sampling};
use glam::{DMat3, DVec3, Vec2};
use rayon::prelude::*;
use std::f64::consts::PI;

/// α floor of the fit (as in the published fit).
pub const MIN_ALPHA: f64 = 1e-5;

/// Samples per axis of the error estimator (as in the published fit).
const SAMPLES: usize = 32;

/// Samples per axis of the magnitude, Fresnel and average-direction integrals: 32² strata
/// leave ~5e-3 error in the magnitude at moderate roughness and grazing views; 128² bring it
/// below 1e-3 at little cost (they are computed once per entry, not per Nelder–Mead step).
const AVG_SAMPLES: usize = 128;

/// An LTC in parametric form: frame (x, y, z) and the matrix parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ltc {
    /// Lobe frame (columns x, y, z).
    pub frame: DMat3,
    /// Matrix parameters m11, m22, m13.
    pub m11: f64,
    /// m22.
    pub m22: f64,
    /// m13.
    pub m13: f64,
    /// ∫ f cos (the fitted magnitude).
    pub magnitude: f64,
}

impl Ltc {
    /// M = frame · [[m11, 0, m13], [0, m22, 0], [0, 0, 1]].
    pub fn matrix(&self) -> DMat3 {
        self.frame
            * DMat3::from_cols(
                DVec3::new(self.m11, 0.0, 0.0),
                DVec3::new(0.0, self.m22, 0.0),
                DVec3::new(self.m13, 0.0, 1.0),
            )
    }

    /// Density of the (unit-mass) LTC distribution at unit direction `l`, with M and M⁻¹ given.
    fn pdf(m: &DMat3, inv: &DMat3, det: f64, l: DVec3) -> f64 {
        let lo = (*inv * l).normalize();
        let len = (*m * lo).length();
        let jacobian = det / (len * len * len);
        lo.z.max(0.0) / PI / jacobian
    }
}

/// The fitted BRDF lobe: value (f·cos θl) and the pdf of our GGX sampler.
fn brdf(v: DVec3, l: DVec3, alpha: f64) -> (f64, f64) {
    let (vf, lf) = (v.as_vec3(), l.as_vec3());
    let f = ggx::eval(vf, lf, alpha as f32, glam::Vec3::ONE, glam::Vec3::ONE).x as f64 * l.z.max(0.0);
    (f, ggx::pdf(vf, lf, alpha as f32) as f64)
}

fn stratum(i: usize, j: usize) -> Vec2 {
    Vec2::new((i as f32 + 0.5) / SAMPLES as f32, (j as f32 + 0.5) / SAMPLES as f32)
}

/// (magnitude, Fresnel term, average direction) of the BRDF lobe for view `v`.
pub fn average_terms(v: DVec3, alpha: f64) -> (f64, f64, DVec3) {
    let (mut norm, mut fresnel, mut dir) = (0.0, 0.0, DVec3::ZERO);
    for j in 0..AVG_SAMPLES {
        for i in 0..AVG_SAMPLES {
            let u = Vec2::new((i as f32 + 0.5) / AVG_SAMPLES as f32, (j as f32 + 0.5) / AVG_SAMPLES as f32);
            let Some(l) = ggx::sample(v.as_vec3(), alpha as f32, u) else { continue };
            let l = l.as_dvec3();
            let (f, pdf) = brdf(v, l, alpha);
            if pdf > 0.0 {
                let w = f / pdf;
                let h = (v + l).normalize();
                norm += w;
                fresnel += w * (1.0 - v.dot(h).max(0.0)).powi(5);
                dir += w * l;
            }
        }
    }
    let n = (AVG_SAMPLES * AVG_SAMPLES) as f64;
    dir.y = 0.0;
    (norm / n, fresnel / n, dir.normalize_or(DVec3::Z))
}

/// The fit's error of `ltc` against the lobe for view `v`.
pub fn error(ltc: &Ltc, v: DVec3, alpha: f64) -> f64 {
    let m = ltc.matrix();
    let det = m.determinant().abs();
    if det.is_nan() || det <= 0.0 || det.is_infinite() {
        return f64::INFINITY;
    }
    let inv = m.inverse();
    let mut err = 0.0;
    let mut add = |l: DVec3| {
        let (f, pdf_brdf) = brdf(v, l, alpha);
        let pdf_ltc = Ltc::pdf(&m, &inv, det, l);
        let f_ltc = ltc.magnitude * pdf_ltc;
        let e = (f - f_ltc).abs().powi(3);
        if pdf_ltc + pdf_brdf > 0.0 {
            err += e / (pdf_ltc + pdf_brdf);
        }
    };
    for j in 0..SAMPLES {
        for i in 0..SAMPLES {
            let u = stratum(i, j);
            // Sample the LTC: a cosine direction through M.
            add((m * sampling::cosine_hemisphere(u).as_dvec3()).normalize());
            if let Some(l) = ggx::sample(v.as_vec3(), alpha as f32, u) {
                add(l.as_dvec3());
            }
        }
    }
    err / (SAMPLES * SAMPLES) as f64
}

/// Fits one entry from the starting guess `start`; `isotropic` ties m22 = m11, m13 = 0.
pub fn fit_one(start: &Ltc, v: DVec3, alpha: f64, isotropic: bool) -> Ltc {
    let make = |p: &[f64]| {
        let mut l = *start;
        if isotropic {
            l.m11 = p[0].max(1e-7);
            l.m22 = l.m11;
            l.m13 = 0.0;
        } else {
            l.m11 = p[0].max(1e-7);
            l.m22 = p[1].max(1e-7);
            l.m13 = p[2];
        }
        l
    };
    let opts = nelder_mead::Options { max_evals: 400, tolerance: 1e-7, restarts: 1 };
    let fit = |p: &[f64]| error(&make(p), v, alpha);
    if isotropic {
        make(&nelder_mead::minimize(|p| fit(p), [start.m11], [0.05], opts).x)
    } else {
        make(&nelder_mead::minimize(|p| fit(p), [start.m11, start.m22, start.m13], [0.05; 3], opts).x)
    }
}

/// Fits entry (a, t) given the previous fit along its chain.
fn fit_entry(prev: Option<&Ltc>, a: usize, t: usize) -> (Ltc, f64) {
    let (v, alpha) = entry_params(a, t);
    let (magnitude, fresnel, avg) = average_terms(v, alpha);
    let mut ltc = prev.copied().unwrap_or(Ltc { frame: DMat3::IDENTITY, m11: 1.0, m22: 1.0, m13: 0.0, magnitude });
    ltc.magnitude = magnitude;
    let isotropic = t == 0;
    ltc.frame =
        if isotropic { DMat3::IDENTITY } else { DMat3::from_cols(DVec3::new(avg.z, 0.0, -avg.x), DVec3::Y, avg) };
    if isotropic {
        ltc.m13 = 0.0;
    }
    (fit_one(&ltc, v, alpha, isotropic), fresnel)
}

/// The normalised table entry of a fitted LTC.
pub fn entry(ltc: &Ltc, fresnel: f64) -> Entry {
    let inv = ltc.matrix().inverse();
    let inv = inv / inv.y_axis.y;
    [inv.x_axis.x, inv.x_axis.z, inv.z_axis.x, inv.z_axis.z, ltc.magnitude, fresnel].map(|v| v as f32)
}

/// Fits the whole 64×64 table. The normal-incidence column is fitted first (from rough to
/// smooth, each from its neighbour); then every roughness row runs from normal to grazing in
/// parallel. `progress` is called with the number of finished rows.
pub fn fit_table(progress: &(dyn Fn(usize) + Sync)) -> Vec<Entry> {
    let mut column: Vec<(Ltc, f64)> = Vec::with_capacity(TABLE_SIZE);
    for a in (0..TABLE_SIZE).rev() {
        let prev = column.last().map(|c: &(Ltc, f64)| c.0);
        column.push(fit_entry(prev.as_ref(), a, 0));
    }
    column.reverse();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let rows: Vec<Vec<Entry>> = (0..TABLE_SIZE)
        .into_par_iter()
        .map(|a| {
            let mut row = vec![entry(&column[a].0, column[a].1)];
            let mut prev = column[a].0;
            for t in 1..TABLE_SIZE {
                let (ltc, fresnel) = fit_entry(Some(&prev), a, t);
                row.push(entry(&ltc, fresnel));
                prev = ltc;
            }
            progress(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1);
            row
        })
        .collect();
    let mut table = vec![[0.0f32; 6]; TABLE_SIZE * TABLE_SIZE];
    for (a, row) in rows.iter().enumerate() {
        for (t, e) in row.iter().enumerate() {
            table[a + t * TABLE_SIZE] = *e;
        }
    }
    table
}

/// Rust source of a table, for the committed `table.rs`.
pub fn table_source(table: &[Entry]) -> String {
    let mut s = String::from(
        "//! The fitted LTC table for GGX, generated by `cargo xtask fit-ltc` (do not edit).\n//! Entry `a + t·64`: see [`super::Entry`].\n\n#[rustfmt::skip]\npub static LTC_TABLE: [super::Entry; 4096] = [\n",
    );
    for e in table {
        s.push_str(&format!("    [{:e}, {:e}, {:e}, {:e}, {:e}, {:e}],\n", e[0], e[1], e[2], e[3], e[4], e[5]));
    }
    s.push_str("];\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_committed_table_is_what_the_fitter_produces() {
        // The first entries of the roughest row's chain, bit for bit.
        let (first, fresnel) = fit_entry(None, TABLE_SIZE - 1, 0);
        let mut got = vec![entry(&first, fresnel)];
        let mut prev = first;
        for t in 1..3 {
            let (ltc, fresnel) = fit_entry(Some(&prev), TABLE_SIZE - 1, t);
            got.push(entry(&ltc, fresnel));
            prev = ltc;
        }
        for (t, e) in got.iter().enumerate() {
            assert_eq!(*e, super::super::table::LTC_TABLE[TABLE_SIZE - 1 + t * TABLE_SIZE], "entry (63, {t})");
        }
    }

    #[test]
    fn table_source_round_trips_floats() {
        let e: Entry = [1.0, -0.25, 3.5e-7, 0.1, 0.999_999_9, 1e-44];
        let src = table_source(&[e]);
        let line = src.lines().find(|l| l.trim_start().starts_with('[')).unwrap();
        let parsed: Vec<f32> = line
            .trim()
            .trim_start_matches('[')
            .trim_end_matches("],")
            .split(", ")
            .map(|v| v.parse().unwrap())
            .collect();
        assert_eq!(parsed, e.to_vec());
    }
}
