//! The editor's bake system: BSPVT and PRT bakes run in parallel on rayon (one `join`), off the
//! UI thread (on a thread pool of their own, so the UI's parallel shading never waits behind
//! them), through the bake database. Chunks stream to the editor as the database finds
//! them cached or commits them, so the preview refines batch by batch; each technique's
//! assembled bake lands when it finishes. A cancel stops starting new chunks and keeps every
//! committed batch for the next run.

use kage_bake_db::plan::Kind;
use kage_bake_db::{Chunk, DbError, Hooks, Plan, RunStats, Store, plan, run_cancellable};
use kage_engine::scene::{Scene, flatten};
use kage_engine::{bspvt, prt};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::time::Instant;

/// What a chunk holds for its vertices.
pub enum ChunkData {
    /// BSPVT vertex records.
    Trees(Vec<Vec<u8>>),
    /// PRT transfer, vertex-major.
    Transfer(Vec<f32>),
}

/// A streamed chunk, a finished bake, or why a bake stopped.
pub enum Landed {
    /// One chunk: its instance (snapshot order), first vertex and data.
    Chunk(usize, usize, ChunkData),
    /// BSPVT trees.
    Bspvt(Result<(bspvt::Bake, RunStats), DbError>),
    /// PRT transfer.
    Prt(Result<(prt::Bake, RunStats), DbError>),
}

/// Progress of one technique.
pub struct Track {
    /// Vertices to bake (the plan's misses).
    pub total: usize,
    /// Chunks already in the database.
    pub cached: usize,
    /// Vertices done so far.
    pub done: Arc<AtomicUsize>,
    /// Still running.
    pub running: bool,
}

/// A bake in the background.
pub struct BakeJob {
    /// BSPVT's progress (when planned).
    pub bspvt: Option<Track>,
    /// PRT's progress (when planned).
    pub prt: Option<Track>,
    /// When it started.
    pub started: Instant,
    cancel: Arc<AtomicBool>,
    rx: Receiver<Landed>,
}

fn track(p: &Plan) -> Track {
    let total = p.misses().map(|j| j.vertices.len()).sum();
    Track { total, cached: p.jobs.len() - p.misses().count(), done: Arc::default(), running: true }
}

impl BakeJob {
    /// Plans on the calling thread (cheap) and starts baking a snapshot of `scene`;
    /// `on_land` runs on the worker when a technique's bake ends (the editor asks for a
    /// repaint); chunks wait in [`BakeJob::landed`] for the next frame.
    pub fn start(
        store: Arc<Store>,
        scene: &Scene,
        bspvt_settings: Option<bspvt::Settings>,
        prt_settings: Option<prt::Settings>,
        on_land: impl Fn() + Send + Sync + 'static,
    ) -> Result<Self, DbError> {
        let snapshot = scene.duplicate();
        let flat = flatten(&snapshot);
        let bp = plan(&store, &snapshot, &flat, bspvt_settings, None)?;
        let pp = plan(&store, &snapshot, &flat, None, prt_settings)?;
        let (tx, rx) = channel();
        let cancel = Arc::new(AtomicBool::new(false));
        let (bt, pt) = ((bp.bspvt.is_some()).then(|| track(&bp)), (pp.prt.is_some()).then(|| track(&pp)));
        let done = [bt.as_ref().map(|t| t.done.clone()), pt.as_ref().map(|t| t.done.clone())];
        let stop = cancel.clone();
        // A pool of its own: on rayon's global pool the UI thread's parallel shading would queue
        // behind the bake's chunks and freeze the window until the bake ends.
        let pool = rayon::ThreadPoolBuilder::new().thread_name(|k| format!("kage-bake-{k}")).build().map_err(|e| {
            DbError::Storage { path: store.path().to_path_buf(), detail: format!("cannot start the bake threads: {e}") }
        })?;
        std::thread::spawn(move || {
            let land = &on_land;
            let run = |p: &Plan, done: &Option<Arc<AtomicUsize>>, tx: &Sender<Landed>| {
                let progress = |n: usize| {
                    if let Some(d) = done {
                        d.store(n, Ordering::Relaxed)
                    }
                };
                let chunk = |c: Chunk| {
                    let data = match c.job.kind {
                        Kind::Bspvt => c.bspvt_records().map(ChunkData::Trees),
                        Kind::Prt => c.prt_transfer().map(ChunkData::Transfer),
                    };
                    // A malformed chunk is reported by the assembly at the end of the run.
                    // No repaint for a chunk: the window's progress repaints pick it up
                    // (`Editor::progress_interval`), and a frame per chunk took a CPU device's
                    // time from the bake.
                    if let Some(data) = data {
                        let _ = tx.send(Landed::Chunk(c.job.instance, c.job.vertices.start, data));
                    }
                };
                let hooks = Hooks { progress: &progress, cancel: &stop, chunk: Some(&chunk) };
                run_cancellable(&store, &snapshot, &flat, p, hooks)
            };
            let (tx_b, tx_p) = (tx.clone(), tx);
            pool.install(|| {
                rayon::join(
                    || {
                        if bp.bspvt.is_some() {
                            let r = run(&bp, &done[0], &tx_b).map(|o| (o.bspvt.expect("BSPVT was planned"), o.stats));
                            let _ = tx_b.send(Landed::Bspvt(r));
                            land();
                        }
                    },
                    || {
                        if pp.prt.is_some() {
                            let r = run(&pp, &done[1], &tx_p).map(|o| (o.prt.expect("PRT was planned"), o.stats));
                            let _ = tx_p.send(Landed::Prt(r));
                            land();
                        }
                    },
                )
            });
            // Each run recorded only its own keys as the scene's; gc must keep both.
            let keys: Vec<_> = bp.keys().into_iter().chain(pp.keys()).collect();
            let _ = store.put_scene(&snapshot.source, &keys, &bp.snapshot.hash);
        });
        Ok(Self { bspvt: bt, prt: pt, started: Instant::now(), cancel, rx })
    }

    /// Results that landed since the last call.
    pub fn landed(&mut self) -> Vec<Landed> {
        let landed: Vec<Landed> = self.rx.try_iter().collect();
        for l in &landed {
            let t = match l {
                Landed::Chunk(..) => None,
                Landed::Bspvt(_) => self.bspvt.as_mut(),
                Landed::Prt(_) => self.prt.as_mut(),
            };
            if let Some(t) = t {
                t.running = false;
            }
        }
        landed
    }

    /// True while some technique is still baking.
    pub fn running(&self) -> bool {
        self.bspvt.iter().chain(&self.prt).any(|t| t.running)
    }

    /// Asks the workers to stop after the chunks in flight.
    pub fn cancel(&self) {
        self.cancel.store(true, Ordering::Relaxed);
    }
}
