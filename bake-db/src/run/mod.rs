//! Running a plan: rayon workers bake the missing chunks while one writer thread commits them
//! in batches, then every chunk (baked now or cached) is assembled into the engine's bakes.
//!
//! A BSPVT chunk whose slot has lineage is re-baked *warm* (`bspvt::rebake_vertex`): only the
//! texels of its vertices whose rays meet the old or new bounds of an occluder that changed
//! are looked at, and of those only the rays whose result can have changed are cast (a ray
//! that was visible only against the changed occluders); only the cube-face tiles whose
//! visibility changed are built again, most of them found in the subtree memo the store keeps
//! between runs; the other tiles' subtrees are kept. The lineage keeps, beside the previous
//! artefact's key and the occluders it saw, the visible-texel masks of every vertex's mixed
//! tiles (uniform tiles need none), so the texels not cast again keep their exact old state,
//! and the vertices' positions and normals: a chunk whose vertices changed (a receiver refined
//! again) re-bakes warm each vertex its lineage holds, and cold only the new ones.
//! The result is byte-identical to a cold bake, because a ray's result against an occluder
//! depends on that occluder alone and a face's tree is its tiles' subtrees joined by a fixed
//! grid (`bspvt::node::TILE`).

use crate::key::Key;
use crate::plan::{Job, Kind, Occluder, Plan, decode_occluders, encode_occluders};
use crate::store::{DbError, Info, Result, Store};
use glam::Vec3;
use kage_engine::accel::Occluders;
use kage_engine::scene::{FlatScene, Scene};
use kage_engine::{bspvt, prt};
use rayon::prelude::*;
use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Mutex, mpsc};
use std::time::{Duration, Instant};

mod assemble;
mod lineage;
mod tools;

use assemble::*;
pub use lineage::changes;
use lineage::*;
pub use tools::tiles_name;
pub(crate) use tools::*;

/// Artefacts per write transaction at most.
const BATCH: usize = 32;
/// Finished artefacts queued for the writer at most (workers wait beyond it).
const IN_FLIGHT: usize = 2 * BATCH;
/// Longest a finished artefact waits before it is committed.
const FLUSH_EVERY: Duration = Duration::from_millis(250);

/// What a run did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RunStats {
    /// Chunks found in the store.
    pub cached: usize,
    /// Chunks baked from scratch.
    pub cold: usize,
    /// BSPVT chunks re-baked from their lineage.
    pub warm: usize,
    /// Vertices whose data was computed (all of a cold chunk, the touched ones of a warm one).
    pub vertices_baked: usize,
    /// BSPVT visibility rays cast (all above the horizon cold; only those meeting a changed
    /// occluder's bounds warm).
    pub rays_cast: usize,
    /// BSPVT mixed cube-face tiles whose subtrees were made anew (all cold; only those whose
    /// visibility changed warm), by Algorithm 1 or from the subtree memo.
    pub tiles_built: usize,
    /// Of those, the ones the subtree memo had (shared by the run's workers and kept in the
    /// database between runs; see `bspvt::memo`). Depends on timing: two workers can build
    /// the same new tile at once.
    pub tiles_from_memo: usize,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// The assembled bakes and what it took.
pub struct Outcome {
    /// BSPVT trees, when planned.
    pub bspvt: Option<bspvt::Bake>,
    /// PRT transfer, when planned.
    pub prt: Option<prt::Bake>,
    /// Statistics.
    pub stats: RunStats,
}

/// One finished artefact on its way to the writer.
struct Baked<'a> {
    job: &'a Job,
    key: Key,
    bytes: Vec<u8>,
    info: Info,
    lineage: Option<(Key, Vec<u8>)>,
    warm: bool,
    vertices: usize,
    rays: usize,
    tiles: usize,
}

/// Bakes the plan's misses (committing as they finish), then assembles every chunk.
/// `progress` gets the number of vertices done among the misses.
pub fn run(
    store: &Store,
    scene: &Scene,
    flat: &FlatScene,
    plan: &Plan,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<Outcome> {
    run_cancellable(store, scene, flat, plan, Hooks { progress, cancel: &AtomicBool::new(false), chunk: None })
}

/// How a caller follows and steers a run.
#[derive(Clone, Copy)]
pub struct Hooks<'a> {
    /// Gets the number of vertices done among the misses.
    pub progress: &'a (dyn Fn(usize) + Sync),
    /// Once set, no further job starts.
    pub cancel: &'a AtomicBool,
    /// Gets every chunk of the plan: the cached ones before baking starts, then each baked one
    /// right after the batch holding it is committed (so a preview can refine batch by batch).
    pub chunk: Option<&'a (dyn Fn(Chunk<'_>) + Sync)>,
}

/// A chunk's artefact, as [`Hooks::chunk`] sees it.
#[derive(Clone, Copy)]
pub struct Chunk<'a> {
    /// The job (technique, instance, vertex range).
    pub job: &'a Job,
    /// The artefact's bytes.
    pub bytes: &'a [u8],
}

impl Chunk<'_> {
    /// A BSPVT chunk's vertex records (`None` when malformed or not BSPVT).
    pub fn bspvt_records(&self) -> Option<Vec<Vec<u8>>> {
        (self.job.kind == Kind::Bspvt).then(|| decode_records(self.bytes)).flatten()
    }

    /// A PRT chunk's transfer coefficients, vertex-major (`None` when not PRT).
    pub fn prt_transfer(&self) -> Option<Vec<f32>> {
        (self.job.kind == Kind::Prt).then(|| bytemuck::pod_collect_to_vec(self.bytes))
    }
}

/// [`run`] steered by `hooks`: once `hooks.cancel` is set no job starts; the jobs in flight
/// finish and are committed with the rest of their batch, then [`DbError::Cancelled`] is
/// returned, and the next run finds their results cached.
///
/// A stored chunk whose bytes no longer match their checksum is baked again (cold: its
/// lineage is not trusted either) and replaced, so a run never shades damaged data.
pub fn run_cancellable(store: &Store, scene: &Scene, flat: &FlatScene, plan: &Plan, hooks: Hooks) -> Result<Outcome> {
    let start = Instant::now();
    let (stats, mut fresh) = bake_misses(store, scene, flat, plan, hooks, true)?;
    let outcome = match assemble(store, flat, plan, &fresh, stats)? {
        Assembled::Done(outcome) => outcome,
        Assembled::Damaged(damaged) => {
            let again = Plan {
                jobs: plan
                    .jobs
                    .iter()
                    .map(|j| Job { cached: !damaged.contains(&j.key), slot: None, ..j.clone() })
                    .collect(),
                ..plan.clone()
            };
            let (rebaked, more) = bake_misses(store, scene, flat, &again, hooks, true)?;
            fresh.extend(more);
            let stats = RunStats {
                cached: stats.cached - damaged.len(),
                cold: stats.cold + rebaked.cold,
                vertices_baked: stats.vertices_baked + rebaked.vertices_baked,
                rays_cast: stats.rays_cast + rebaked.rays_cast,
                tiles_built: stats.tiles_built + rebaked.tiles_built,
                tiles_from_memo: stats.tiles_from_memo + rebaked.tiles_from_memo,
                ..stats
            };
            match assemble(store, flat, plan, &fresh, stats)? {
                Assembled::Done(outcome) => outcome,
                Assembled::Damaged(keys) => return Err(damaged_error(store, &keys)),
            }
        }
    };
    Ok(Outcome { stats: RunStats { seconds: start.elapsed().as_secs_f64(), ..outcome.stats }, ..outcome })
}

/// What a damaged artefact that baking again did not replace is reported as.
fn damaged_error(store: &Store, keys: &[Key]) -> DbError {
    let first = keys.first().map_or_else(String::new, Key::short);
    DbError::Corrupted {
        path: store.path().to_path_buf(),
        detail: format!("{} artefacts (first {first}) fail their checksum (run `kage db check`)", keys.len()),
    }
}

/// The bakes of a fully cached `plan`, read from the store without writing anything (not even
/// the scene's references); `None` when any chunk is missing.
pub fn load(store: &Store, flat: &FlatScene, plan: &Plan) -> Result<Option<Outcome>> {
    if plan.misses().next().is_some() {
        return Ok(None);
    }
    // A damaged chunk counts as missing: a run bakes it again.
    Ok(match assemble(store, flat, plan, &HashMap::new(), RunStats::default())? {
        Assembled::Done(outcome) => Some(outcome),
        Assembled::Damaged(_) => None,
    })
}

/// [`run`] without assembling the bakes: the plan's misses are baked and committed, and no
/// cached chunk is read (what `kage bake` needs, whatever the database's size).
pub fn bake(
    store: &Store,
    scene: &Scene,
    flat: &FlatScene,
    plan: &Plan,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<RunStats> {
    let start = Instant::now();
    let hooks = Hooks { progress, cancel: &AtomicBool::new(false), chunk: None };
    let (stats, _) = bake_misses(store, scene, flat, plan, hooks, false)?;
    Ok(RunStats { seconds: start.elapsed().as_secs_f64(), ..stats })
}

/// Bakes and commits the plan's misses (see [`run_cancellable`]); returns what it did and, with
/// `keep`, the fresh artefacts by key. Without `keep` the run streams: memory holds only the
/// artefacts in flight (a bounded queue to the writer, one batch being committed), whatever
/// the scene's total bake size.
fn bake_misses(
    store: &Store,
    scene: &Scene,
    flat: &FlatScene,
    plan: &Plan,
    hooks: Hooks,
    keep: bool,
) -> Result<(RunStats, HashMap<Key, Vec<u8>>)> {
    let Hooks { progress, cancel, chunk } = hooks;
    if let Some(f) = chunk {
        for job in plan.jobs.iter().filter(|j| j.cached) {
            f(Chunk { job, bytes: &store.get::<u8>(&job.key)?.unwrap_or_default() });
        }
    }
    let mut misses: Vec<&Job> = plan.misses().collect();
    // Largest first, each worker taking the next as it frees (greedy list scheduling): a
    // large chunk started last would leave the other cores idle while one bakes it.
    misses.sort_by_key(|j| std::cmp::Reverse(j.vertices.len()));
    let tools = Tools::for_jobs(store, scene, flat, plan, &misses)?;
    let ctx = tools.context(store, flat, plan);
    let done = AtomicUsize::new(0);
    // Bounded, so that workers wait for the writer instead of piling artefacts up in memory.
    let (tx, rx) = mpsc::sync_channel::<Baked<'_>>(IN_FLIGHT);
    let mut fresh: HashMap<Key, Vec<u8>> = HashMap::new();
    let mut stats = RunStats { cached: plan.jobs.len() - misses.len(), ..RunStats::default() };
    let written = std::thread::scope(|scope| -> Result<()> {
        let writer = scope.spawn(|| write_batches(store, rx, chunk, keep));
        let baking = misses.iter().par_bridge().try_for_each_with(tx, |tx, job| -> Result<()> {
            if cancel.load(Ordering::Relaxed) {
                return Err(DbError::Cancelled { done: 0 });
            }
            let baked = ctx.bake(job)?;
            progress(done.fetch_add(job.vertices.len(), Ordering::Relaxed) + job.vertices.len());
            // A closed channel means the writer failed; its error is reported below.
            let _ = tx.send(baked);
            Ok(())
        });
        // The channel is closed either way: the writer commits what arrived before returning.
        let results = writer.join().expect("the writer thread does not panic")?;
        if let Err(e) = baking {
            let done = results.iter().map(|b| b.vertices).sum();
            return Err(match e {
                DbError::Cancelled { .. } => DbError::Cancelled { done },
                e => e,
            });
        }
        for b in results {
            if b.warm {
                stats.warm += 1
            } else {
                stats.cold += 1
            }
            stats.vertices_baked += b.vertices;
            stats.rays_cast += b.rays;
            stats.tiles_built += b.tiles;
            if keep {
                fresh.insert(b.key, b.bytes);
            }
        }
        Ok(())
    });
    // Kept even when the run failed or was cancelled: what was built stays useful.
    let saved = store.put_memos(&tools.memos());
    written?;
    saved?;
    stats.tiles_from_memo = tools.bspvt.as_ref().map_or(0, |b| b.tiles.hits());
    store.put_scene(&scene.source, &plan.keys(), &plan.snapshot.hash)?;
    if stats.cold + stats.warm > 0 {
        store.put_batch(&[], &slot_lists(plan))?;
    }
    let meshes: Vec<([u8; 32], u32, u32)> =
        scene.meshes.iter().map(|m| (m.hash.0, m.positions.len() as u32, m.triangles.len() as u32)).collect();
    store.put_meshes(&meshes)?;
    Ok((stats, fresh))
}

/// Each instance's slot list ([`Plan::slot_lists`]): its BSPVT chunks' slots, for the next
/// warm re-bake. Written once a run has baked and committed every chunk (a cached run writes
/// nothing); a run cancelled before keeps the last list, whose slots hold either their old
/// bake or a newer one, both usable.
fn slot_lists(plan: &Plan) -> Vec<(Key, Vec<u8>)> {
    let slots =
        |i: usize| -> Vec<Key> { plan.jobs.iter().filter(|j| j.instance == i).filter_map(|j| j.slot).collect() };
    plan.slot_lists.iter().enumerate().filter_map(|(i, list)| Some(((*list)?, encode_slot_list(&slots(i))))).collect()
}

/// Bakes `jobs` in parallel and throws the results away; returns the workers' seconds they
/// took (what [`crate::estimate`] scales): their wall time times the threads, since a job's
/// vertices bake in parallel too and its own wall time is not its work.
pub(crate) fn time_jobs(ctx: &Context<'_>, jobs: &[Job]) -> Result<f64> {
    let t = Instant::now();
    jobs.par_iter().try_for_each(|job| ctx.bake(job).map(drop))?;
    Ok(t.elapsed().as_secs_f64() * rayon::current_num_threads() as f64)
}

/// Receives finished artefacts and commits them in batches; returns them all, their bytes and
/// lineage dropped once committed unless `keep`.
fn write_batches<'a>(
    store: &Store,
    rx: mpsc::Receiver<Baked<'a>>,
    chunk: Option<&(dyn Fn(Chunk<'_>) + Sync)>,
    keep: bool,
) -> Result<Vec<Baked<'a>>> {
    let mut all: Vec<Baked> = Vec::new();
    let mut pending = 0usize;
    let mut last = Instant::now();
    loop {
        let next = rx.recv_timeout(FLUSH_EVERY);
        let closed = matches!(next, Err(mpsc::RecvTimeoutError::Disconnected));
        if let Ok(b) = next {
            all.push(b);
            pending += 1;
        }
        if pending > 0 && (pending >= BATCH || closed || last.elapsed() >= FLUSH_EVERY) {
            let batch = &all[all.len() - pending..];
            let arts: Vec<(Key, Vec<u8>, Info)> =
                batch.iter().map(|b| (b.key, b.bytes.clone(), b.info.clone())).collect();
            let lineage: Vec<(Key, Vec<u8>)> = batch.iter().filter_map(|b| b.lineage.clone()).collect();
            store.put_batch(&arts, &lineage)?;
            if let Some(f) = chunk {
                batch.iter().for_each(|b| f(Chunk { job: b.job, bytes: &b.bytes }));
            }
            if !keep {
                let at = all.len() - pending;
                all[at..].iter_mut().for_each(|b| (b.bytes, b.lineage) = (Vec::new(), None));
            }
            pending = 0;
            last = Instant::now();
        }
        if closed {
            return Ok(all);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Streaming: every artefact is committed, and once committed its bytes are not held
    /// (without `keep`), so a bake's memory does not grow with its size; with `keep` they are.
    #[test]
    fn the_writer_commits_everything_and_holds_bytes_only_when_asked() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(&dir.path().join("bake.redb")).unwrap();
        let jobs: Vec<Job> = (0..100u8)
            .map(|i| Job {
                kind: Kind::Prt,
                instance: 0,
                vertices: 0..1,
                key: Key::from_slice(&[i; 32]),
                slot: None,
                cached: false,
            })
            .collect();
        for keep in [false, true] {
            let (tx, rx) = mpsc::sync_channel(IN_FLIGHT);
            let held = std::thread::scope(|s| {
                let writer = s.spawn(|| write_batches(&store, rx, None, keep));
                for job in &jobs {
                    let bytes = vec![job.key.as_bytes()[0]; 4096];
                    let info = Info {
                        kind: "prt".into(),
                        params: String::new(),
                        seconds: 0.0,
                        vertices: 1,
                        checksum: *blake3::hash(&bytes).as_bytes(),
                    };
                    let baked = Baked {
                        job,
                        key: job.key,
                        bytes,
                        info,
                        lineage: None,
                        warm: false,
                        vertices: 1,
                        rays: 0,
                        tiles: 0,
                    };
                    tx.send(baked).unwrap();
                }
                drop(tx);
                writer.join().unwrap().unwrap()
            });
            assert_eq!(held.len(), jobs.len());
            let bytes: usize = held.iter().map(|b| b.bytes.len()).sum();
            assert_eq!(bytes, if keep { 4096 * jobs.len() } else { 0 }, "keep {keep}");
            let keys: Vec<Key> = jobs.iter().map(|j| j.key).collect();
            assert!(store.contains_all(&keys).unwrap().iter().all(|&c| c));
            assert_eq!(store.get::<u8>(&keys[7]).unwrap().unwrap(), vec![7u8; 4096]);
        }
    }
}
