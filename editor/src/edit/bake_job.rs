//! The editor's bake system: BSPVT and PRT bakes run in parallel on rayon (one `join`), off the
//! UI thread, through the bake database. Results land per technique as each finishes, so the
//! preview refines (PRT's fast bake first); a cancel stops starting new chunks and keeps every
//! committed batch for the next run.

use kage_bake_db::{DbError, Plan, RunStats, Store, plan, run_cancellable};
use kage_engine::scene::{Scene, flatten};
use kage_engine::{bspvt, prt};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, channel};
use std::time::Instant;

/// A finished bake (or why it stopped).
pub enum Landed {
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
    /// `on_land` runs on the worker after each result (the editor asks for a repaint).
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
        std::thread::spawn(move || {
            let run = |p: &Plan, done: &Option<Arc<AtomicUsize>>| {
                let progress = |n: usize| {
                    if let Some(d) = done {
                        d.store(n, Ordering::Relaxed)
                    }
                };
                run_cancellable(&store, &snapshot, &flat, p, &progress, &stop)
            };
            let (tx_b, tx_p) = (tx.clone(), tx);
            let land = &on_land;
            rayon::join(
                || {
                    if bp.bspvt.is_some() {
                        let r = run(&bp, &done[0]).map(|o| (o.bspvt.expect("BSPVT was planned"), o.stats));
                        let _ = tx_b.send(Landed::Bspvt(r));
                        land();
                    }
                },
                || {
                    if pp.prt.is_some() {
                        let r = run(&pp, &done[1]).map(|o| (o.prt.expect("PRT was planned"), o.stats));
                        let _ = tx_p.send(Landed::Prt(r));
                        land();
                    }
                },
            );
            // Each run recorded only its own keys as the scene's; gc must keep both.
            let keys: Vec<_> = bp.keys().into_iter().chain(pp.keys()).collect();
            let _ = store.put_scene(&snapshot.source, &keys);
        });
        Ok(Self { bspvt: bt, prt: pt, started: Instant::now(), cancel, rx })
    }

    /// Results that landed since the last call.
    pub fn landed(&mut self) -> Vec<Landed> {
        let landed: Vec<Landed> = self.rx.try_iter().collect();
        for l in &landed {
            let t = match l {
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
