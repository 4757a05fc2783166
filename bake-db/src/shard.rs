//! Sharded bakes: a plan's missing chunks split into N shards that separate processes (or
//! machines) bake into databases of their own, to be merged afterwards ([`crate::merge`]).
//!
//! Every shard computes the same split from the same inputs, with no coordination: the misses
//! (against a shared base database, or all chunks), each with an estimated cost from the plan's
//! default rates and deterministic work counts — never from timings — are dealt, costliest
//! first, to the least loaded shard (ties: the lower key, the lower shard). Each chunk lands in
//! exactly one shard.

use crate::plan::{Job, Plan};
use kage_engine::scene::FlatScene;

/// Shard `index` of `count` (0-based), as `I/N` on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// This shard, `0..count`.
    pub index: usize,
    /// How many shards the bake is split into.
    pub count: usize,
}

impl std::str::FromStr for Shard {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let bad = || format!("'{s}' is not a shard I/N with 0 ≤ I < N (e.g. 0/4)");
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let (index, count): (usize, usize) =
            (i.trim().parse().map_err(|_| bad())?, n.trim().parse().map_err(|_| bad())?);
        if index >= count {
            return Err(bad());
        }
        Ok(Self { index, count })
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// The split of a plan's misses.
#[derive(Clone, Debug, PartialEq)]
pub struct Split {
    /// Per job of the plan: the shard that bakes it (`None`: cached, nobody bakes it).
    pub owner: Vec<Option<usize>>,
    /// Per shard: its estimated seconds on one worker.
    pub load: Vec<f64>,
}

/// Deals the misses of `plan` to `count` shards (see the module documentation).
pub fn split(plan: &Plan, flat: &FlatScene, count: usize) -> Split {
    let cost = |j: &Job| plan.default_seconds_per_vertex(j.kind) * plan.work(flat, j);
    let mut misses: Vec<(f64, usize)> =
        plan.jobs.iter().enumerate().filter(|(_, j)| !j.cached).map(|(i, j)| (cost(j), i)).collect();
    misses.sort_by(|a, b| b.0.total_cmp(&a.0).then_with(|| plan.jobs[a.1].key.cmp(&plan.jobs[b.1].key)));
    let mut owner = vec![None; plan.jobs.len()];
    let mut load = vec![0.0f64; count.max(1)];
    for (c, i) in misses {
        let lightest = (0..load.len()).min_by(|&a, &b| load[a].total_cmp(&load[b])).expect("at least one shard");
        load[lightest] += c;
        owner[i] = Some(lightest);
    }
    Split { owner, load }
}

impl Plan {
    /// This plan with only `shard`'s share of the misses left to bake (the others count as
    /// cached: another shard bakes them). Every key stays, so the shard records the scene's
    /// whole plan.
    pub fn shard(&self, split: &Split, shard: Shard) -> Plan {
        let mut plan = self.clone();
        for (job, owner) in plan.jobs.iter_mut().zip(&split.owner) {
            job.cached = *owner != Some(shard.index);
        }
        plan
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_parse_and_print_as_index_over_count() {
        assert_eq!("3/4".parse::<Shard>().unwrap(), Shard { index: 3, count: 4 });
        assert_eq!(Shard { index: 0, count: 1 }.to_string(), "0/1");
        for bad in ["4/4", "1", "a/2", "1/0", "-1/2"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
    }
}
