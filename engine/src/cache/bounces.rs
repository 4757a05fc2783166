//! More bounces from the radiance cache. Bounce k + 1 is the cache's records re-lit from their
//! kept hits (no new rays; [`Cache::refresh`]) with bounce k's per-vertex radiance standing in
//! for the direct light at the hits, then shaded at the vertices as the first bounce is.
//!
//! How many: a fixed count, or as many as an error budget asks for. After bounce k the budget
//! gathers bounce k + 1 at a sample of vertices, takes its ratio ρ to bounce k there, and
//! estimates the light all the bounces left out would add as the geometric series' tail,
//! `next / (1 − ρ)`; it stops when that tail's RMS over the sample is below the budget's share
//! of the look's (direct plus the bounces so far).
//!
//! Bounces after the first light glossy gather hits by their per-vertex value (toward the eye),
//! not toward the record: the first bounce carries the view-dependent highlights, the later
//! ones are mostly diffuse interreflection.

use super::record::{Change, Glossy, Source};
use super::{Cache, gather_one, light_vertices, shade_vertices, vertices};
use crate::scene::VertexValues;
use glam::Vec3;

/// Most bounces an error budget may choose.
pub const MAX_BOUNCES: usize = 32;
/// Default share of the look the bounces left out may add.
pub const DEFAULT_BUDGET: f64 = 0.02;
/// Vertices the budget's estimate gathers at (evenly spaced in vertex order).
const SAMPLE: usize = 256;
/// Largest bounce-to-bounce ratio the estimate assumes: a room of white walls approaches 1,
/// where the series' tail has no bound.
const MAX_RATIO: f64 = 0.95;

/// How many bounces of indirect light to add.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Bounces {
    /// Exactly this many (at least one).
    Fixed(usize),
    /// Until the bounces left out would add less than this share of the look.
    Budget(f64),
}

impl Default for Bounces {
    fn default() -> Self {
        Self::Budget(DEFAULT_BUDGET)
    }
}

/// Why [`bounce`] stopped where it did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Stop {
    /// The count was given.
    Fixed,
    /// The estimated rest fell below the budget.
    Budget {
        /// The share of the look the bounces left out would add, estimated.
        rest: f64,
        /// The share allowed.
        budget: f64,
    },
    /// [`MAX_BOUNCES`] reached.
    Capped {
        /// The share of the look the bounces left out would still add, estimated.
        rest: f64,
    },
}

/// What [`bounce`] added.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounced {
    /// Bounces in the result.
    pub count: usize,
    /// Why no more.
    pub stop: Stop,
}

impl std::fmt::Display for Bounced {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        let n = self.count;
        let s = if n == 1 { "" } else { "s" };
        match self.stop {
            Stop::Fixed => write!(f, "{n} bounce{s} (given)"),
            Stop::Budget { rest, budget } => write!(
                f,
                "{n} bounce{s} (more would add {:.1} % of the light, under the {:.1} % budget)",
                100.0 * rest,
                100.0 * budget
            ),
            Stop::Capped { rest } => {
                write!(f, "{n} bounce{s}, the most allowed (more would still add {:.1} % of the light)", 100.0 * rest)
            }
        }
    }
}

/// The indirect light toward `eye` at every receiver vertex over `bounces` bounces: the first
/// from `cache` (placed and gathered under `src`), each further one from a copy of its records
/// re-lit by the previous bounce. `cache` itself is left as it was.
pub fn bounce(src: &Source, cache: &Cache, eye: Vec3, bounces: Bounces) -> (VertexValues, Bounced) {
    bounce_each(src, cache, (eye, bounces), &|| false, |_, _| {}).expect("never stopped")
}

/// [`bounce`], and the light the same bounces bring to every receiver vertex: irradiance over
/// π ([`light_vertices`]), view-independent — what an asset pack carries to run time. `None`
/// once `stopped()` answers true, which it is asked before each bounce.
pub fn bounce_with_light(
    src: &Source,
    cache: &Cache,
    (eye, bounces): (Vec3, Bounces),
    stopped: &dyn Fn() -> bool,
) -> Option<(VertexValues, VertexValues, Bounced)> {
    let mut light = src.renderer.flat.zeros();
    let (values, bounced) = bounce_each(src, cache, (eye, bounces), stopped, |src, records| {
        let more = light_vertices(src, records);
        light.iter_mut().flatten().zip(more.iter().flatten()).for_each(|(t, m)| *t += *m);
    })?;
    Some((values, light, bounced))
}

/// [`bounce`], calling `each(source, records)` with every bounce's lighting and records; `None`
/// once `stopped()` answers true before a bounce.
fn bounce_each(
    src: &Source,
    cache: &Cache,
    (eye, bounces): (Vec3, Bounces),
    stopped: &dyn Fn() -> bool,
    mut each: impl FnMut(&Source, &Cache),
) -> Option<(VertexValues, Bounced)> {
    each(src, cache);
    let mut last = shade_vertices(src, cache, eye);
    let mut total = last.clone();
    let mut relit: Option<Cache> = None;
    let mut count = 1;
    let stop = loop {
        if stopped() {
            return None;
        }
        match bounces {
            Bounces::Fixed(n) if count >= n => break Stop::Fixed,
            Bounces::Fixed(_) => {}
            Bounces::Budget(budget) => {
                let rest = rest(src, &total, &last, cache, eye);
                if rest < budget {
                    break Stop::Budget { rest, budget };
                }
                if count >= MAX_BOUNCES {
                    break Stop::Capped { rest };
                }
            }
        }
        let next_src = Source { renderer: src.renderer, direct: &last, glossy: Glossy::PerVertex };
        let records = relit.get_or_insert_with(|| cache.clone());
        // Every record is integrated again (no ray is cast): the first bounce lit glossy hits
        // toward the record, the next ones by their per-vertex value, so an unchanged corner
        // does not mean an unchanged hit.
        records.refresh(&next_src, &Change { old_direct: None, moved: &[] });
        each(&next_src, records);
        let next = shade_vertices(&next_src, records, eye);
        total.iter_mut().flatten().zip(next.iter().flatten()).for_each(|(t, n)| *t += *n);
        last = next;
        count += 1;
    };
    Some((total, Bounced { count, stop }))
}

/// The estimated share of the look the bounces after `last` would add, over a sample of
/// vertices: the next bounce gathered there (hits lit by `last`) over one minus its ratio to
/// `last`, in RMS against the look (`src.direct` plus `total`).
fn rest(src: &Source, total: &VertexValues, last: &VertexValues, cache: &Cache, eye: Vec3) -> f64 {
    use rayon::prelude::*;
    let all = vertices(src);
    let sample: Vec<_> = all.iter().enumerate().step_by((all.len() / SAMPLE).max(1)).collect();
    let next_src = Source { renderer: src.renderer, direct: last, glossy: Glossy::PerVertex };
    let side = cache.settings().side();
    let next: Vec<Vec3> =
        sample.par_iter().map(|&(k, &(i, v, p, n))| gather_one(&next_src, (i, v, p, n), eye, side, k as u64)).collect();
    let at = |values: &[Vec<Vec3>]| sample.iter().map(|&(_, &(i, v, ..))| values[i][v]).collect::<Vec<_>>();
    let sum = |values: &[Vec3]| values.iter().map(|c| c.element_sum() as f64).sum::<f64>();
    let ratio = (sum(&next) / sum(&at(last)).max(1e-30)).clamp(0.0, MAX_RATIO);
    let look: Vec<Vec3> = at(total).iter().zip(at(src.direct)).map(|(t, d)| *t + d).collect();
    let squares = |values: &[Vec3]| values.iter().map(|c| c.as_dvec3().length_squared()).sum::<f64>();
    let whole = squares(&look);
    if whole <= 0.0 {
        return 0.0;
    }
    (squares(&next) / whole).sqrt() / (1.0 - ratio)
}
