//! `kage bake`: plan the scene's bakes against the database, print the plan, bake the misses
//! (progress, ETA), and with `--watch` do it again whenever the scene file changes.

use crate::db_args::DbArgs;
use crate::progress::with_bar;
use crate::prt_args::PrtArgs;
use crate::scene_args::SceneArgs;
use anyhow::Result;
use kage_bake_db::plan::{Job, Kind, Plan};
use kage_bake_db::{Store, plan};
use kage_engine::bspvt;
use kage_engine::scene::{FlatScene, Scene, flatten};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::time::Instant;

/// Arguments of `kage bake`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub(crate) scene: SceneArgs,
    #[command(flatten)]
    pub(crate) db: DbArgs,
    /// Print the plan and stop.
    #[arg(long)]
    pub dry_run: bool,
    /// Re-plan and re-bake whenever the scene file changes on disk.
    #[arg(long)]
    pub watch: bool,
    #[command(flatten)]
    pub(crate) options: BakeOptions,
}

/// Bake parameters shared by `bake` and `export`.
#[derive(clap::Args, Debug)]
pub struct BakeOptions {
    /// BSPVT cube-face resolution.
    #[arg(long, default_value_t = 64)]
    pub face_res: usize,
    /// BSPVT split threshold ε.
    #[arg(long, default_value_t = 2.0)]
    pub epsilon: f64,
    /// Error budget PRT chooses its parameters with.
    #[arg(long)]
    pub error_budget: Option<f64>,
    #[command(flatten)]
    pub(crate) prt: PrtArgs,
}

impl BakeOptions {
    /// The plan for a snapshot: BSPVT with polygonal lights, PRT (parameters planned or given)
    /// with an environment.
    pub fn plan(&self, store: &Store, scene: &Scene, flat: &FlatScene) -> Result<Plan> {
        let bspvt = bspvt::Settings { res: self.face_res, epsilon: self.epsilon };
        bspvt.check().map_err(|e| anyhow::anyhow!("--face-res/--epsilon: {e}"))?;
        let bspvt = Some(bspvt);
        let prt = flat
            .environment
            .is_some()
            .then(|| self.prt.settings_cached(store, scene, flat, self.error_budget))
            .transpose()?;
        Ok(plan(store, scene, flat, bspvt, prt)?)
    }
}

/// Runs the command.
pub fn run(args: &Args) -> Result<()> {
    let store = args.db.open(&args.scene)?;
    bake_once(args, &store)?;
    if args.watch {
        crate::watch::on_change(args.scene.scene.as_deref(), || bake_once(args, &store))?;
    }
    Ok(())
}

/// Loads, plans, prints and (unless --dry-run) bakes.
fn bake_once(args: &Args, store: &Store) -> Result<()> {
    let scene = args.scene.load()?;
    let flat = flatten(&scene);
    let start = Instant::now();
    let plan = args.options.plan(store, &scene, &flat)?;
    print_plan(store, &scene, &flat, &plan, start.elapsed().as_secs_f64())?;
    if args.dry_run || plan.misses().next().is_none() {
        return Ok(());
    }
    let total: usize = plan.misses().map(|j| j.vertices.len()).sum();
    // Only the misses: the assembled bakes (every chunk read and checked) are not needed here.
    let s = with_bar(total, "baking", |p| kage_bake_db::bake(store, &scene, &flat, &plan, p))?;
    crate::emit(&format!(
        "baked {} chunks cold and {} warm ({} vertices, {} rays, {} tiles built, {} from the subtree memo) in {:.2} s; {} cached; {}\n",
        s.cold,
        s.warm,
        s.vertices_baked,
        s.rays_cast,
        s.tiles_built,
        s.tiles_from_memo,
        s.seconds,
        s.cached,
        store.path().display()
    ));
    Ok(())
}

/// Per instance and technique: chunks, cached, vertices to bake, estimated seconds.
pub fn print_plan(store: &Store, scene: &Scene, flat: &FlatScene, plan: &Plan, planning_s: f64) -> Result<()> {
    let threads = rayon::current_num_threads() as f64;
    // (chunks, cached, vertices to bake, their work in full-vertex units).
    let mut rows: BTreeMap<(usize, &str), (usize, usize, usize, f64)> = BTreeMap::new();
    for j in &plan.jobs {
        let r = rows.entry((j.instance, j.kind.name())).or_default();
        r.0 += 1;
        r.1 += usize::from(j.cached);
        if !j.cached {
            r.2 += j.vertices.len();
            r.3 += work(flat, plan, j);
        }
    }
    // Seconds per vertex on one worker: measured by earlier bakes with the same parameters in
    // this database, else the default rates of docs/bake-db.md (BSPVT ≈ 10 ms per vertex at 64², ∝ res²; PRT
    // ≈ 80 µs per vertex at 1024 directions, ∝ directions).
    let mut rate = std::collections::HashMap::new();
    for kind in [Kind::Bspvt, Kind::Prt] {
        let measured = store.seconds_per_vertex(kind.name(), &plan.params(kind))?;
        let default = match kind {
            Kind::Bspvt => plan.bspvt.map_or(0.0, |s| 1e-2 * (s.res as f64 / 64.0).powi(2)),
            Kind::Prt => plan.prt.map_or(0.0, |s| 8e-5 * s.direction_side().pow(2) as f64 / 1024.0),
        };
        rate.insert(kind.name(), (measured.unwrap_or(default), measured.is_some()));
    }
    // Measured rates already hold the reach's savings (the same parameters, reach included).
    let cost = |kind: &str, vertices: usize, work: f64| {
        let (rate, measured) = rate[kind];
        rate * if measured { vertices as f64 } else { work }
    };
    let mut out = format!("plan for {} ({:.0} ms):\n", scene.source, planning_s * 1e3);
    if let Some(s) = plan.bspvt {
        out += &format!("  bspvt: {}² faces, ε {}, {} (polygonal lights present)\n", s.res, s.epsilon, plan.reach);
    }
    if let Some(s) = plan.prt {
        out += &format!(
            "  prt: order {}, {} directions, {} regions, {:?} window (environment present)\n",
            s.order,
            s.direction_side().pow(2),
            s.regions,
            s.window
        );
    }
    if plan.jobs.is_empty() {
        out += "  nothing to bake: no polygonal light and no environment\n";
    }
    let mut total = 0.0;
    for ((i, kind), (chunks, cached, vertices, work)) in &rows {
        let est = cost(kind, *vertices, *work) / threads;
        total += est;
        out += &format!(
            "  instance {i:3} {kind:5}: {chunks:3} chunks, {cached:3} cached, {vertices:6} vertices to bake, ~{est:.1} s\n"
        );
    }
    let misses = plan.misses().count();
    let basis = if rate.values().any(|r| r.1) { "rates measured by earlier bakes" } else { "default rates" };
    out += &format!(
        "  {} of {} chunks cached; {misses} to bake, estimated {total:.1} s on {threads} threads ({basis})\n",
        plan.jobs.len() - misses,
        plan.jobs.len()
    );
    crate::emit(&out);
    Ok(())
}

/// The work of a job in full-vertex units: a BSPVT vertex casts only the share of its tiles
/// the lights can reach.
fn work(flat: &FlatScene, plan: &Plan, job: &Job) -> f64 {
    match (job.kind, plan.bspvt, &plan.reach) {
        (Kind::Bspvt, Some(s), reach @ bspvt::reach::Reach::Within(_)) => job
            .vertices
            .clone()
            .into_par_iter()
            .map(|v| {
                let (p, n) = flat.vertex(job.instance, v);
                reach.share(p, n, s.res)
            })
            .sum(),
        _ => job.vertices.len() as f64,
    }
}
