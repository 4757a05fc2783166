//! How long a plan's misses will take to bake, measured rather than assumed: a deterministic
//! sample of the misses is baked (and thrown away: nothing is written) on this machine, for
//! this scene, and its seconds per unit of work ([`Plan::work`]: vertices, or for BSPVT under
//! a declared light reach the tiles the lights can see) scale to the whole plan.
//!
//! The sample is a few vertices from the middle of chunks spread evenly over the misses —
//! neighbouring vertices cost alike, distant ones do not — at most [`SAMPLE_SHARE`] of the
//! vertices to bake and [`SAMPLE_MAX`] per technique, so estimating costs a few percent of a
//! small bake and a second or two of a large one. Default rates ([`Plan::default_seconds_per_vertex`])
//! stay what shards deal by: shards must agree without timing anything.

use crate::plan::{Job, Kind, Plan};
use crate::run::{Tools, time_jobs};
use crate::store::{Result, Store};
use kage_engine::scene::{FlatScene, Scene};
use std::time::Instant;

/// Largest share of a technique's vertices to bake that the sample takes.
pub const SAMPLE_SHARE: f64 = 0.02;
/// Most vertices sampled per technique.
pub const SAMPLE_MAX: usize = 1024;
/// Fewest vertices sampled per technique (all of them when fewer are missing).
pub const SAMPLE_MIN: usize = 16;
/// Consecutive vertices taken from each sampled chunk.
const RUN: usize = 4;

/// A plan's estimated bake time, and what it was measured on.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Estimate {
    /// Per technique with misses: its name, work units to bake and seconds per unit on one worker.
    pub rates: Vec<(&'static str, f64, f64)>,
    /// Seconds to set up what baking needs (occluder BVHs, the PRT baker), once per bake.
    pub setup: f64,
    /// Vertices baked for the sample.
    pub sampled: usize,
    /// Wall-clock seconds the sample took, setup included.
    pub seconds: f64,
}

impl Estimate {
    /// Estimated wall-clock seconds of the whole bake on `threads` workers.
    pub fn total(&self, threads: usize) -> f64 {
        self.setup + self.rates.iter().map(|(_, work, rate)| work * rate).sum::<f64>() / threads as f64
    }

    /// Seconds per work unit on one worker for `kind` (0 when it has no misses).
    pub fn rate(&self, kind: Kind) -> f64 {
        self.rates.iter().find(|r| r.0 == kind.name()).map_or(0.0, |r| r.2)
    }
}

/// Measures the plan's bake time by baking a sample of its misses (see the module doc).
pub fn estimate(store: &Store, scene: &Scene, flat: &FlatScene, plan: &Plan) -> Result<Estimate> {
    let start = Instant::now();
    let kinds = [Kind::Bspvt, Kind::Prt];
    let samples: Vec<(Kind, Vec<Job>)> =
        kinds.into_iter().map(|k| (k, sample(plan, k))).filter(|(_, s)| !s.is_empty()).collect();
    let jobs: Vec<&Job> = samples.iter().flat_map(|(_, s)| s).collect();
    if jobs.is_empty() {
        return Ok(Estimate::default());
    }
    let tools = Tools::for_jobs(store, scene, flat, plan, &jobs)?;
    let setup = start.elapsed().as_secs_f64();
    let mut rates = Vec::new();
    for (kind, jobs) in &samples {
        let seconds = time_jobs(&tools.context(store, flat, plan), jobs)?;
        let sampled: f64 = jobs.iter().map(|j| plan.work(flat, j)).sum();
        let work: f64 = plan.misses().filter(|j| j.kind == *kind).map(|j| plan.work(flat, j)).sum();
        rates.push((kind.name(), work, seconds / sampled.max(f64::MIN_POSITIVE)));
    }
    let sampled = jobs.iter().map(|j| j.vertices.len()).sum();
    Ok(Estimate { rates, setup, sampled, seconds: start.elapsed().as_secs_f64() })
}

/// The sample of `kind`'s misses: runs of [`RUN`] vertices from the middle of chunks spread
/// evenly over them, as cold jobs.
pub fn sample(plan: &Plan, kind: Kind) -> Vec<Job> {
    let misses: Vec<&Job> = plan.misses().filter(|j| j.kind == kind).collect();
    let total: usize = misses.iter().map(|j| j.vertices.len()).sum();
    let budget = ((total as f64 * SAMPLE_SHARE).ceil() as usize).clamp(SAMPLE_MIN, SAMPLE_MAX).min(total);
    if budget == 0 {
        return Vec::new();
    }
    let chunks = misses.len().min(budget.div_ceil(RUN));
    let run = budget.div_ceil(chunks);
    (0..chunks)
        .map(|i| {
            let job = misses[i * misses.len() / chunks];
            let len = run.min(job.vertices.len());
            let start = job.vertices.start + (job.vertices.len() - len) / 2;
            Job { vertices: start..start + len, slot: None, cached: false, ..job.clone() }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::key::Key;

    fn plan_of(chunks: &[usize]) -> Plan {
        let jobs = chunks
            .iter()
            .enumerate()
            .map(|(i, &n)| Job {
                kind: Kind::Bspvt,
                instance: i,
                vertices: 0..n,
                key: Key::from_slice(&[i as u8; 32]),
                slot: None,
                cached: false,
            })
            .collect();
        let snapshot = crate::plan::Snapshot { occluders: Vec::new(), hash: Key::from_slice(&[0; 32]) };
        Plan { bspvt: None, prt: None, jobs, snapshot, reach: kage_engine::bspvt::reach::Reach::Anywhere }
    }

    /// The sample is spread over the misses, inside their chunks, and within its bounds.
    #[test]
    fn a_sample_is_spread_and_bounded() {
        let big = plan_of(&[256; 4000]);
        let s = sample(&big, Kind::Bspvt);
        assert_eq!(s.iter().map(|j| j.vertices.len()).sum::<usize>(), SAMPLE_MAX);
        assert_eq!(s.len(), SAMPLE_MAX / RUN);
        assert!(s.iter().all(|j| j.vertices == (126..130)));
        assert_eq!((s[0].instance, s.last().unwrap().instance), (0, 3984));
        let small = plan_of(&[5, 3]);
        let s = sample(&small, Kind::Bspvt);
        assert_eq!(s.iter().map(|j| j.vertices.len()).collect::<Vec<_>>(), [4, 3], "runs within their chunks");
        assert!(sample(&small, Kind::Prt).is_empty());
        let mut cached = plan_of(&[256; 10]);
        cached.jobs.iter_mut().for_each(|j| j.cached = true);
        assert!(sample(&cached, Kind::Bspvt).is_empty());
    }
}
