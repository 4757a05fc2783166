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
use glam::{Affine3A, Vec3};
use kage_engine::accel::Occluders;
use kage_engine::scene::{FlatScene, Scene};
use kage_engine::{bspvt, prt};
use rayon::prelude::*;
use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Mutex, mpsc};
use std::time::{Duration, Instant};

/// Artefacts per write transaction at most.
const BATCH: usize = 32;
/// Finished artefacts queued for the writer at most (workers wait beyond it).
const IN_FLIGHT: usize = 2 * BATCH;
/// Longest a finished artefact waits before it is committed.
const FLUSH_EVERY: Duration = Duration::from_millis(250);

/// A slot's previous bake of each of a chunk's vertices (`None`: the vertex is new) and the
/// occluders that changed since.
type Lineage = (Vec<Option<bspvt::VertexBake>>, Vec<bspvt::Change>);

/// First bytes of a lineage entry (its layout's version): entries of an older layout (before
/// masks, or before vertices were kept) lack it, and their chunks bake cold once.
const LINEAGE_MAGIC: &[u8; 4] = b"kgl3";

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
    let misses: Vec<&Job> = plan.misses().collect();
    let tools = Tools::for_jobs(store, scene, flat, plan, &misses)?;
    let ctx = tools.context(store, flat, plan);
    let done = AtomicUsize::new(0);
    // Bounded, so that workers wait for the writer instead of piling artefacts up in memory.
    let (tx, rx) = mpsc::sync_channel::<Baked<'_>>(IN_FLIGHT);
    let mut fresh: HashMap<Key, Vec<u8>> = HashMap::new();
    let mut stats = RunStats { cached: plan.jobs.len() - misses.len(), ..RunStats::default() };
    let written = std::thread::scope(|scope| -> Result<()> {
        let writer = scope.spawn(|| write_batches(store, rx, chunk, keep));
        let baking = misses.par_iter().try_for_each_with(tx, |tx, job| -> Result<()> {
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
    stats.tiles_from_memo = tools.tiles.as_ref().map_or(0, |t| t.hits());
    store.put_scene(&scene.source, &plan.keys(), &plan.snapshot.hash)?;
    let meshes: Vec<([u8; 32], u32, u32)> =
        scene.meshes.iter().map(|m| (m.hash.0, m.positions.len() as u32, m.triangles.len() as u32)).collect();
    store.put_meshes(&meshes)?;
    Ok((stats, fresh))
}

/// Bakes `jobs` in parallel and throws the results away; returns the seconds they took summed
/// over the workers (what [`crate::estimate`] scales).
pub(crate) fn time_jobs(ctx: &Context<'_>, jobs: &[Job]) -> Result<f64> {
    let seconds = jobs
        .par_iter()
        .map(|job| {
            let t = Instant::now();
            ctx.bake(job).map(|_| t.elapsed().as_secs_f64())
        })
        .collect::<Result<Vec<f64>>>()?;
    Ok(seconds.iter().sum())
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

/// What baking jobs needs beyond the plan, set up only for the kinds a set of jobs has.
pub(crate) struct Tools {
    occluders: Option<Occluders>,
    /// Occluder BVHs built now, as memos to store.
    new_bvhs: Vec<(String, Vec<u8>)>,
    tiles: Option<bspvt::memo::SubtreeMemo>,
    transfer: Option<prt::Baker>,
    /// Re-refined curved occluders' triangles, as memos to store ([`crate::regions`]).
    new_triangles: Vec<(String, Vec<u8>)>,
    /// What changed in each re-refined occluder, by (old occluder hash, instance), worked out
    /// once for every chunk that asks.
    regions: Regions,
}

/// See [`Tools::regions`].
type Regions = Mutex<HashMap<([u8; 32], usize), Option<Vec<(Vec3, Vec3)>>>>;

impl Tools {
    pub(crate) fn for_jobs(store: &Store, scene: &Scene, flat: &FlatScene, plan: &Plan, jobs: &[&Job]) -> Result<Self> {
        let baking = |kind: Kind| jobs.iter().any(|j| j.kind == kind);
        let bspvt = plan.bspvt.filter(|_| baking(Kind::Bspvt));
        let (occluders, new_bvhs) = bspvt.map(|_| crate::bvhs::occluders(store, flat)).transpose()?.unzip();
        let new_triangles = if bspvt.is_some() { crate::regions::memos(store, flat)? } else { Vec::new() };
        Ok(Tools {
            occluders,
            new_bvhs: new_bvhs.unwrap_or_default(),
            new_triangles,
            regions: Mutex::default(),
            tiles: bspvt.map(|s| load_tiles(store, &s)).transpose()?,
            transfer: plan.prt.filter(|_| baking(Kind::Prt)).map(|s| prt::Baker::new(scene, flat, &s)),
        })
    }

    pub(crate) fn context<'a>(&'a self, store: &'a Store, flat: &'a FlatScene, plan: &'a Plan) -> Context<'a> {
        Context {
            flat,
            plan,
            store,
            occluders: self.occluders.as_ref(),
            tiles: self.tiles.as_ref(),
            transfer: self.transfer.as_ref(),
            regions: &self.regions,
        }
    }

    /// The memos worth storing: new occluder BVHs, re-refined occluders' triangles, and the
    /// subtree memo when it grew.
    fn memos(&self) -> Vec<(String, Vec<u8>)> {
        let tiles = self.tiles.as_ref().filter(|t| t.added() > 0).map(|t| (tiles_name(t.settings()), t.to_bytes()));
        self.new_bvhs.iter().chain(&self.new_triangles).cloned().chain(tiles).collect()
    }
}

pub(crate) struct Context<'a> {
    flat: &'a FlatScene,
    plan: &'a Plan,
    store: &'a Store,
    occluders: Option<&'a Occluders>,
    tiles: Option<&'a bspvt::memo::SubtreeMemo>,
    transfer: Option<&'a prt::Baker>,
    regions: &'a Regions,
}

impl Context<'_> {
    fn bake<'j>(&self, job: &'j Job) -> Result<Baked<'j>> {
        let t = Instant::now();
        let mut lineage = job.slot.map(|slot| {
            let mut v = LINEAGE_MAGIC.to_vec();
            v.extend_from_slice(job.key.as_bytes());
            let occluders = encode_occluders(&self.plan.snapshot.occluders);
            v.extend_from_slice(&(occluders.len() as u32).to_le_bytes());
            v.extend(occluders);
            (slot, v)
        });
        let (bytes, warm, vertices, rays, tiles) = match job.kind {
            Kind::Prt => {
                let s = self.plan.prt.expect("PRT job without PRT settings");
                let n = s.order * s.order;
                let mut out = vec![0.0f32; job.vertices.len() * n];
                let baker = self.transfer.expect("built for PRT misses");
                for (k, v) in job.vertices.clone().enumerate() {
                    baker.vertex(self.flat, job.instance, v, &mut out[k * n..(k + 1) * n]);
                }
                (bytemuck::cast_slice(&out).to_vec(), false, job.vertices.len(), 0, 0)
            }
            Kind::Bspvt => {
                let (baked, warm) = self.bake_bspvt(job)?;
                if let Some((_, v)) = &mut lineage {
                    v.extend_from_slice(&(job.vertices.len() as u32).to_le_bytes());
                    let bits = job.vertices.clone().map(|k| crate::plan::vertex_bits(self.flat, job.instance, k));
                    bits.for_each(|b| v.extend_from_slice(bytemuck::cast_slice(&b)));
                    baked.iter().for_each(|b| encode_masks(&b.masks, v));
                }
                let touched = baked.iter().filter(|b| b.rays > 0).count();
                let (rays, tiles) = baked.iter().fold((0, 0), |(r, t), b| (r + b.rays, t + b.built));
                let records: Vec<Vec<u8>> = baked.into_iter().map(|b| b.record).collect();
                (encode_records(&records), warm, touched, rays, tiles)
            }
        };
        let info = Info {
            kind: job.kind.name().into(),
            params: self.plan.params(job.kind),
            seconds: t.elapsed().as_secs_f64(),
            // Warm chunks are not representative of a bake's cost per vertex.
            vertices: if warm { 0 } else { job.vertices.len() },
            checksum: *blake3::hash(&bytes).as_bytes(),
        };
        Ok(Baked { job, key: job.key, bytes, info, lineage, warm, vertices, rays, tiles })
    }

    /// The chunk's vertex bakes, and whether they were re-baked warm from the slot's lineage.
    fn bake_bspvt(&self, job: &Job) -> Result<(Vec<bspvt::VertexBake>, bool)> {
        let (occ, tiles) =
            (self.occluders.expect("built for BSPVT misses"), self.tiles.expect("loaded for BSPVT misses"));
        let vertex = |v: usize| self.flat.vertex(job.instance, v);
        let (old, changed) = self.lineage_of(job)?.unwrap_or_else(|| (vec![None; job.vertices.len()], Vec::new()));
        let warm = old.iter().any(Option::is_some);
        let cold = bspvt::VertexBake::default();
        let baked = job
            .vertices
            .clone()
            .zip(&old)
            .map(|(v, old)| {
                let (p, n) = vertex(v);
                // A new vertex bakes cold: no change needs looking at.
                let (old, changed) = old.as_ref().map_or((&cold, &[][..]), |old| (old, &changed[..]));
                bspvt::rebake_vertex(occ, p, n, (tiles, &self.plan.reach), old, changed)
            })
            .collect();
        Ok((baked, warm))
    }

    /// The slot's previous bake of each of the chunk's vertices that it holds (matched by
    /// position and normal) and every occluder that changed since, when the lineage is usable.
    fn lineage_of(&self, job: &Job) -> Result<Option<Lineage>> {
        let Some(slot) = job.slot else { return Ok(None) };
        let Some(entry) = self.store.lineage(&slot)? else { return Ok(None) };
        let Some(Then { key, occluders, vertices, masks }) = decode_lineage(&entry) else { return Ok(None) };
        let Some(bytes) = self.store.get::<u8>(&key)? else { return Ok(None) };
        // The warm re-bake descends the old trees: a damaged chunk bakes cold instead.
        let usable = |r: &Vec<Vec<u8>>| {
            let res = self.plan.bspvt.map_or(0, |s| s.res);
            r.len() == vertices.len() && r.iter().all(|rec| bspvt::layout::check_record(rec, res).is_ok())
        };
        let Some(records) = decode_records(&bytes).filter(usable) else { return Ok(None) };
        let mut old: HashMap<[u32; 6], bspvt::VertexBake> = vertices
            .into_iter()
            .zip(records.into_iter().zip(masks))
            .map(|(bits, (record, masks))| (bits, bspvt::VertexBake { record, masks, ..Default::default() }))
            .collect();
        let now = job.vertices.clone().map(|v| old.remove(&crate::plan::vertex_bits(self.flat, job.instance, v)));
        Ok(Some((now.collect(), self.changes(&occluders)?)))
    }

    /// Every occluder that changed since the snapshot `then`, a re-refined curved one by the
    /// regions whose triangles changed where the store keeps its old triangles
    /// ([`crate::regions`]).
    fn changes(&self, then: &[Occluder]) -> Result<Vec<bspvt::Change>> {
        let now = &self.plan.snapshot.occluders;
        let old: HashMap<[u32; 3], &Occluder> = then.iter().map(|o| (o.id, o)).collect();
        let mut within: HashMap<[u32; 3], Vec<(Vec3, Vec3)>> = HashMap::new();
        for (i, n) in now.iter().enumerate() {
            let Some(o) = old.get(&n.id).filter(|o| o.world == n.world && o.mesh != n.mesh) else { continue };
            let known = self.regions.lock().expect("no worker panics holding it").get(&(o.mesh, i)).cloned();
            let boxes = match known {
                Some(boxes) => boxes,
                None => {
                    let world = Affine3A::from_cols_array(&n.world);
                    let boxes = crate::regions::changed(self.store, self.flat, (&o.mesh, i), &world, padding(n))?;
                    self.regions.lock().expect("no worker panics holding it").insert((o.mesh, i), boxes.clone());
                    boxes
                }
            };
            within.extend(boxes.map(|b| (n.id, b)));
        }
        Ok(changes(then, now, &within))
    }
}

/// The store's name for the subtree memo of `s`.
pub fn tiles_name(s: &bspvt::Settings) -> String {
    format!("bspvt tiles v{} res {} eps {}", bspvt::ALGORITHM_VERSION, s.res, s.epsilon)
}

/// The stored subtree memo for `s`, or an empty one (none stored, or damaged: it only costs time).
fn load_tiles(store: &Store, s: &bspvt::Settings) -> Result<bspvt::memo::SubtreeMemo> {
    let stored = store.memo(&tiles_name(s))?;
    Ok(stored
        .and_then(|b| bspvt::memo::SubtreeMemo::from_bytes(s, &b))
        .unwrap_or_else(|| bspvt::memo::SubtreeMemo::new(s)))
}

/// Every occluder added, removed or changed between two snapshots, with its old and new
/// bounds (padded: rays' offset origins differ from the vertex) and its index in `now` (the
/// flattened scene's instance order, as [`Occluders`] has it). An occluder listed in `within`
/// (changed in place) is instead each of its boxes there, before and after alike.
pub fn changes(
    then: &[Occluder],
    now: &[Occluder],
    within: &HashMap<[u32; 3], Vec<(Vec3, Vec3)>>,
) -> Vec<bspvt::Change> {
    let old: HashMap<[u32; 3], &Occluder> = then.iter().map(|o| (o.id, o)).collect();
    let new: HashMap<[u32; 3], (usize, &Occluder)> = now.iter().enumerate().map(|(i, o)| (o.id, (i, o))).collect();
    let bounds = |o: &Occluder| {
        let (lo, hi) = (Vec3::from_slice(&o.bounds[..3]), Vec3::from_slice(&o.bounds[3..]));
        (lo - padding(o), hi + padding(o))
    };
    let mut ids: Vec<[u32; 3]> = old.keys().chain(new.keys()).copied().collect();
    ids.sort_unstable();
    ids.dedup();
    ids.into_iter()
        .filter(|id| old.get(id).copied() != new.get(id).map(|n| n.1))
        .flat_map(|id| match (within.get(&id), new.get(&id)) {
            (Some(boxes), Some(&(i, _))) => {
                boxes.iter().map(|&b| bspvt::Change { before: Some(b), after: Some((b, i)) }).collect()
            }
            _ => vec![bspvt::Change {
                before: old.get(&id).map(|o| bounds(o)),
                after: new.get(&id).map(|&(i, o)| (bounds(o), i)),
            }],
        })
        .collect()
}

/// How far a changed occluder's boxes are grown: rays' offset origins differ from the vertex.
fn padding(o: &Occluder) -> Vec3 {
    let (lo, hi) = (Vec3::from_slice(&o.bounds[..3]), Vec3::from_slice(&o.bounds[3..]));
    Vec3::splat(1e-4 * (hi - lo).length() + 1e-5)
}

/// Appends a vertex's masks to a lineage entry: u32 count, then (u32 tile, u64 mask) pairs.
fn encode_masks(masks: &[(u32, u64)], out: &mut Vec<u8>) {
    out.extend_from_slice(&(masks.len() as u32).to_le_bytes());
    for (tile, mask) in masks {
        out.extend_from_slice(&tile.to_le_bytes());
        out.extend_from_slice(&mask.to_le_bytes());
    }
}

/// What a lineage entry remembers of a chunk's last bake.
struct Then {
    /// The artefact's key.
    key: Key,
    /// The occluder snapshot it saw.
    occluders: Vec<Occluder>,
    /// Its vertices' position and normal bits ([`crate::plan::vertex_bits`]).
    vertices: Vec<[u32; 6]>,
    /// Its vertices' visible-texel masks.
    masks: Vec<bspvt::tree::Masks>,
}

/// A lineage entry: magic, artefact key, occluder snapshot (u32 length, then its bytes),
/// u32 vertex count, each vertex's bits, then each vertex's masks (`None` when malformed or
/// of an older layout).
fn decode_lineage(entry: &[u8]) -> Option<Then> {
    let rest = entry.strip_prefix(LINEAGE_MAGIC)?;
    let key = Key::from_slice(rest.get(..32)?);
    let len = u32::from_le_bytes(rest.get(32..36)?.try_into().ok()?) as usize;
    let occluders = decode_occluders(rest.get(36..36usize.checked_add(len)?)?)?;
    let mut at = &rest[36 + len..];
    let mut take = |n: usize| -> Option<&[u8]> {
        let (head, tail) = at.split_at_checked(n)?;
        at = tail;
        Some(head)
    };
    let count = u32::from_le_bytes(take(4)?.try_into().ok()?) as usize;
    let bits = take(count.checked_mul(24)?)?;
    let vertices = bits.chunks_exact(24).map(bytemuck::pod_read_unaligned::<[u32; 6]>).collect();
    let mut masks = Vec::with_capacity(count);
    for _ in 0..count {
        let n = u32::from_le_bytes(take(4)?.try_into().ok()?) as usize;
        let pairs = take(n.checked_mul(12)?)?;
        masks.push(
            pairs
                .chunks_exact(12)
                .map(|c| {
                    (
                        u32::from_le_bytes(c[..4].try_into().expect("4")),
                        u64::from_le_bytes(c[4..].try_into().expect("8")),
                    )
                })
                .collect(),
        );
    }
    at.is_empty().then_some(Then { key, occluders, vertices, masks })
}

/// A BSPVT chunk: u32 count, count + 1 u32 offsets, then the records.
fn encode_records(records: &[Vec<u8>]) -> Vec<u8> {
    let mut offsets = vec![0u32];
    for r in records {
        offsets.push(offsets[offsets.len() - 1] + r.len() as u32);
    }
    let mut out = (records.len() as u32).to_le_bytes().to_vec();
    out.extend_from_slice(bytemuck::cast_slice(&offsets));
    records.iter().for_each(|r| out.extend_from_slice(r));
    out
}

/// The offsets and data of a BSPVT chunk (`None` when malformed).
fn chunk_parts(bytes: &[u8]) -> Option<(Vec<u32>, &[u8])> {
    let count = u32::from_le_bytes(bytes.get(..4)?.try_into().ok()?) as usize;
    let end = 4 + 4 * (count + 1);
    let offsets: Vec<u32> = bytemuck::pod_collect_to_vec(bytes.get(4..end)?);
    let data = bytes.get(end..)?;
    (offsets.windows(2).all(|w| w[0] <= w[1]) && *offsets.last()? as usize == data.len()).then_some((offsets, data))
}

fn decode_records(bytes: &[u8]) -> Option<Vec<Vec<u8>>> {
    let (offsets, data) = chunk_parts(bytes)?;
    Some(offsets.windows(2).map(|w| data[w[0] as usize..w[1] as usize].to_vec()).collect())
}

/// Builds the engine's bakes from the chunks, fresh or from the store (all read in one
/// transaction and borrowed, so each stored byte is copied once, into the bake).
fn assemble(
    store: &Store,
    flat: &FlatScene,
    plan: &Plan,
    fresh: &HashMap<Key, Vec<u8>>,
    stats: RunStats,
) -> Result<Assembled> {
    let stored: Vec<Key> = plan.jobs.iter().map(|j| j.key).filter(|k| !fresh.contains_key(k)).collect();
    let checked = store.with_checked_artefacts(&stored, |found| {
        let mut found = found.iter();
        let chunks: Vec<&[u8]> = plan
            .jobs
            .iter()
            .map(|j| {
                fresh.get(&j.key).map_or_else(|| found.next().copied().flatten().unwrap_or_default(), Vec::as_slice)
            })
            .collect();
        bakes(store, flat, plan, &chunks, stats)
    })?;
    Ok(match checked {
        Ok(outcome) => Assembled::Done(outcome),
        Err(damaged) => Assembled::Damaged(damaged),
    })
}

/// A plan's bakes, or the stored chunks that failed their checksum.
enum Assembled {
    Done(Outcome),
    Damaged(Vec<Key>),
}

/// A stored chunk, checked: a BSPVT chunk's offsets and records, or a PRT chunk's coefficients.
enum Part<'a> {
    Trees(Vec<u32>, &'a [u8]),
    Transfer(&'a [u8]),
}

/// Checks that a chunk holds what its job needs (every BSPVT tree is walked: a damaged one
/// would panic in the tree descent; a PRT chunk must hold `coeffs` floats per vertex; `res`
/// is BSPVT's face resolution).
fn part<'a>(store: &Store, job: &Job, bytes: &'a [u8], (coeffs, res): (usize, usize)) -> Result<Part<'a>> {
    let malformed = |why: String| {
        let kind = if job.kind == Kind::Bspvt { "BSPVT" } else { "PRT" };
        DbError::Corrupted {
            path: store.path().to_path_buf(),
            detail: format!("{kind} artefact {} is malformed{why} (run `kage db check`)", job.key.short()),
        }
    };
    if job.kind == Kind::Prt {
        let expected = 4 * coeffs * job.vertices.len();
        if bytes.len() != expected {
            let why = format!(": {} bytes where its {} vertices need {expected}", bytes.len(), job.vertices.len());
            return Err(malformed(why));
        }
        return Ok(Part::Transfer(bytes));
    }
    let (offsets, data) = chunk_parts(bytes)
        .filter(|(o, _)| o.len() == job.vertices.len() + 1)
        .ok_or_else(|| malformed(String::new()))?;
    for (v, w) in offsets.windows(2).enumerate() {
        bspvt::layout::check_record(&data[w[0] as usize..w[1] as usize], res)
            .map_err(|e| malformed(format!(": vertex {}: {e}", job.vertices.start + v)))?;
    }
    Ok(Part::Trees(offsets, data))
}

/// The engine's bakes from every job's chunk (in plan order); each instance's buffers are sized
/// once from its chunks' lengths.
fn bakes(store: &Store, flat: &FlatScene, plan: &Plan, chunks: &[&[u8]], stats: RunStats) -> Result<Outcome> {
    let per_instance = |kind: Kind| {
        let mut bytes = vec![0usize; flat.instances.len()];
        plan.jobs.iter().zip(chunks).filter(|(j, _)| j.kind == kind).for_each(|(j, c)| bytes[j.instance] += c.len());
        bytes
    };
    let mut bspvt_instances: Vec<bspvt::BakedInstance> = match plan.bspvt {
        Some(_) => per_instance(Kind::Bspvt)
            .into_iter()
            .map(|n| bspvt::BakedInstance { offsets: vec![0], data: Vec::with_capacity(n) })
            .collect(),
        None => Vec::new(),
    };
    let mut prt_instances: Vec<Vec<f32>> = match plan.prt {
        Some(_) => per_instance(Kind::Prt).into_iter().map(|n| Vec::with_capacity(n / 4)).collect(),
        None => Vec::new(),
    };
    // Checked chunk by chunk in parallel: walking the trees is most of loading's time.
    let sizes = (plan.prt.map_or(0, |s| s.order * s.order), plan.bspvt.map_or(0, |s| s.res));
    let parts: Vec<Part> =
        plan.jobs.par_iter().zip(chunks).map(|(job, &bytes)| part(store, job, bytes, sizes)).collect::<Result<_>>()?;
    let mut leaves_bytes = 0usize;
    for (job, part) in plan.jobs.iter().zip(parts) {
        match part {
            Part::Trees(offsets, data) => {
                let inst = &mut bspvt_instances[job.instance];
                let base = inst.data.len() as u32;
                inst.offsets.extend(offsets[1..].iter().map(|o| base + o));
                inst.data.extend_from_slice(data);
                leaves_bytes += data.len();
            }
            Part::Transfer(bytes) => {
                // One copy into aligned memory (redb's bytes are not aligned for f32).
                let t = &mut prt_instances[job.instance];
                let start = t.len();
                t.resize(start + bytes.len() / 4, 0.0);
                bytemuck::cast_slice_mut::<f32, u8>(&mut t[start..]).copy_from_slice(bytes);
            }
        }
    }
    let vertices: usize = (0..flat.instances.len()).map(|i| flat.vertex_count(i)).sum();
    let bspvt = plan.bspvt.map(|settings| bspvt::Bake {
        settings,
        instances: bspvt_instances,
        stats: bspvt::Stats { vertices, bytes: leaves_bytes, ..Default::default() },
    });
    let prt = plan.prt.map(|s| {
        let bytes = prt_instances.iter().map(|t| t.len() * 4).sum();
        prt::Bake { order: s.order, instances: prt_instances, stats: prt::Stats { vertices, bytes, seconds: 0.0 } }
    });
    Ok(Outcome { bspvt, prt, stats })
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
