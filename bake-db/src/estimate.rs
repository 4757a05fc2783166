//! How long a plan's misses will take to bake, measured rather than assumed: a deterministic
//! sample of the misses is baked (and thrown away: nothing is written) on this machine, for
//! this scene, and its seconds per unit of work ([`Plan::work`]: vertices, or for BSPVT under
//! a declared light reach the tiles the lights can see) scale to the whole plan.
//!
//! The sample is a few vertices from the middle of chunks spread evenly over the misses —
//! neighbouring vertices cost alike, distant ones do not — at most [`SAMPLE_SHARE`] of the
//! vertices to bake and [`SAMPLE_MAX`] per technique, so estimating costs a few percent of a
//! small bake and a second or two of a large one. BSPVT misses whose slot has lineage re-bake
//! warm after an edit, at a fraction of the cold cost: they are timed apart, on whole chunks
//! (a warm re-bake needs the chunk its lineage holds), at most [`WARM_CHUNKS`] of them. Default rates ([`Plan::default_seconds_per_vertex`])
//! stay what shards deal by: shards must agree without timing anything.

use crate::key::Key;
use crate::plan::{Job, Kind, Plan};
use crate::run::{Tools, time_jobs};
use crate::store::{Result, Store};
use kage_engine::scene::{FlatScene, Scene};
use std::collections::HashSet;
use std::time::Instant;

/// Largest share of a technique's vertices to bake that the sample takes.
pub const SAMPLE_SHARE: f64 = 0.02;
/// Most vertices sampled per technique.
pub const SAMPLE_MAX: usize = 1024;
/// Fewest vertices sampled per technique (all of them when fewer are missing).
pub const SAMPLE_MIN: usize = 16;
/// Consecutive vertices taken from each sampled chunk.
const RUN: usize = 4;
/// Most whole chunks sampled among the misses that re-bake warm.
pub const WARM_CHUNKS: usize = 8;
/// The name of the warm BSPVT misses' rate in [`Estimate::rates`].
const WARM: &str = "bspvt warm";

/// A plan's estimated bake time, and what it was measured on.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Estimate {
    /// Per technique with misses (and for BSPVT's warm re-bakes, "bspvt warm"): its name, work
    /// units to bake and seconds per unit on one worker.
    pub rates: Vec<(&'static str, f64, f64)>,
    /// The misses that re-bake warm, by key.
    pub warm: HashSet<Key>,
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

    /// Seconds per work unit on one worker for `job`, warm or cold (0 when none was timed).
    pub fn rate(&self, job: &Job) -> f64 {
        let name = if self.warm.contains(&job.key) { WARM } else { job.kind.name() };
        self.rates.iter().find(|r| r.0 == name).map_or(0.0, |r| r.2)
    }
}

/// Measures the plan's bake time by baking a sample of its misses (see the module doc).
pub fn estimate(store: &Store, scene: &Scene, flat: &FlatScene, plan: &Plan) -> Result<Estimate> {
    let start = Instant::now();
    let warm = warm_misses(store, plan)?;
    let of = |kind: Kind, is_warm: bool| -> Vec<&Job> {
        plan.misses().filter(|j| j.kind == kind && warm.contains(&j.key) == is_warm).collect()
    };
    let groups = [
        (Kind::Bspvt.name(), of(Kind::Bspvt, false), false),
        (WARM, of(Kind::Bspvt, true), true),
        (Kind::Prt.name(), of(Kind::Prt, false), false),
    ];
    let samples: Vec<(&'static str, Vec<&Job>, Vec<Job>)> = groups
        .into_iter()
        .map(|(name, misses, w)| {
            let s = if w { warm_sample(&misses) } else { sample(&misses) };
            (name, misses, s)
        })
        .filter(|(.., s)| !s.is_empty())
        .collect();
    let jobs: Vec<&Job> = samples.iter().flat_map(|(.., s)| s).collect();
    if jobs.is_empty() {
        return Ok(Estimate::default());
    }
    let tools = Tools::for_jobs(store, scene, flat, plan, &jobs)?;
    let setup = start.elapsed().as_secs_f64();
    let mut rates = Vec::new();
    for (name, misses, jobs) in &samples {
        let seconds = time_jobs(&tools.context(store, flat, plan), jobs)?;
        let sampled: f64 = jobs.iter().map(|j| plan.work(flat, j)).sum();
        let work: f64 = misses.iter().map(|j| plan.work(flat, j)).sum();
        rates.push((*name, work, seconds / sampled.max(f64::MIN_POSITIVE)));
    }
    let sampled = jobs.iter().map(|j| j.vertices.len()).sum();
    Ok(Estimate { rates, warm, setup, sampled, seconds: start.elapsed().as_secs_f64() })
}

/// The BSPVT misses whose slot has lineage: a run re-bakes them warm.
fn warm_misses(store: &Store, plan: &Plan) -> Result<HashSet<Key>> {
    let bspvt: Vec<&Job> = plan.misses().filter(|j| j.slot.is_some()).collect();
    let slots: Vec<Key> = bspvt.iter().filter_map(|j| j.slot).collect();
    let has = store.has_lineage(&slots)?;
    Ok(bspvt.iter().zip(has).filter(|(_, h)| *h).map(|(j, _)| j.key).collect())
}

/// Whole chunks spread evenly over `misses` (which re-bake warm), [`SAMPLE_SHARE`] of their
/// vertices' worth, at least one and at most [`WARM_CHUNKS`].
fn warm_sample(misses: &[&Job]) -> Vec<Job> {
    let vertices: usize = misses.iter().map(|j| j.vertices.len()).sum();
    let mean = vertices as f64 / misses.len().max(1) as f64;
    let n = ((vertices as f64 * SAMPLE_SHARE / mean.max(1.0)).ceil() as usize).clamp(1, WARM_CHUNKS).min(misses.len());
    (0..n).map(|i| misses[i * misses.len() / n].clone()).collect()
}

/// The sample of `misses` (of one technique, baked cold): runs of [`RUN`] vertices from the
/// middle of chunks spread evenly over them, as cold jobs.
pub fn sample(misses: &[&Job]) -> Vec<Job> {
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
        Plan {
            bspvt: None,
            prt: None,
            jobs,
            snapshot,
            reach: kage_engine::bspvt::reach::Reach::ANYWHERE,
            slot_lists: Vec::new(),
        }
    }

    /// The sample is spread over the misses, inside their chunks, and within its bounds.
    #[test]
    fn a_sample_is_spread_and_bounded() {
        let big = plan_of(&[256; 4000]);
        let misses = |p: &Plan, kind: Kind| -> Vec<Job> { p.misses().filter(|j| j.kind == kind).cloned().collect() };
        let s = sample(&misses(&big, Kind::Bspvt).iter().collect::<Vec<_>>());
        assert_eq!(s.iter().map(|j| j.vertices.len()).sum::<usize>(), SAMPLE_MAX);
        assert_eq!(s.len(), SAMPLE_MAX / RUN);
        assert!(s.iter().all(|j| j.vertices == (126..130)));
        assert_eq!((s[0].instance, s.last().unwrap().instance), (0, 3984));
        let small = plan_of(&[5, 3]);
        let s = sample(&misses(&small, Kind::Bspvt).iter().collect::<Vec<_>>());
        assert_eq!(s.iter().map(|j| j.vertices.len()).collect::<Vec<_>>(), [4, 3], "runs within their chunks");
        assert!(sample(&misses(&small, Kind::Prt).iter().collect::<Vec<_>>()).is_empty());
        let mut cached = plan_of(&[256; 10]);
        cached.jobs.iter_mut().for_each(|j| j.cached = true);
        assert!(sample(&misses(&cached, Kind::Bspvt).iter().collect::<Vec<_>>()).is_empty());
    }
}
