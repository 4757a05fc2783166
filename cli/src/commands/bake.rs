//! `kage bake`: plan the scene's bakes against the database, print the plan, bake the misses
//! (progress, ETA), and with `--watch` do it again whenever the scene file changes. With
//! `--shard I/N`, bake one deterministic share of the misses into a database of its own (see
//! `docs/sharded-bakes.md`).

use crate::db_args::DbArgs;
use crate::progress::with_bar;
use crate::prt_args::PrtArgs;
use crate::scene_args::SceneArgs;
use anyhow::Result;
use kage_bake_db::plan::{Kind, Plan};
use kage_bake_db::shard::{self, Shard};
use kage_bake_db::{Store, plan};
use kage_engine::bspvt;
use kage_engine::scene::{FlatScene, Scene, flatten};
use std::collections::BTreeMap;
use std::path::PathBuf;
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
    #[arg(long, conflicts_with = "shard")]
    pub watch: bool,
    /// Bake only shard I of N (0-based, e.g. 2/8) of the missing chunks, into --db; merge the
    /// shards' databases with `kage db merge`.
    #[arg(long, value_name = "I/N", requires = "db")]
    pub shard: Option<Shard>,
    /// A database every shard reads, never writes: the parameter plan (`kage bake --dry-run
    /// --db BASE` makes it) and the chunks already baked, which no shard bakes again.
    #[arg(long, value_name = "BASE.redb", requires = "shard")]
    pub base: Option<PathBuf>,
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

    /// The plan a shard deals from: against `base` (every chunk missing without one), with the
    /// parameter plan `base` records — the shards never choose parameters themselves, so they
    /// all bake with the same ones.
    pub fn shard_plan(&self, own: &Store, base: Option<&Store>, scene: &Scene, flat: &FlatScene) -> Result<Plan> {
        let bspvt = bspvt::Settings { res: self.face_res, epsilon: self.epsilon };
        bspvt.check().map_err(|e| anyhow::anyhow!("--face-res/--epsilon: {e}"))?;
        let prt = match flat.environment {
            None => None,
            Some(_) => Some(self.prt.settings_recorded(base, scene, flat, self.error_budget)?),
        };
        let mut plan = plan(base.unwrap_or(own), scene, flat, Some(bspvt), prt)?;
        if base.is_none() {
            // Without a base nothing counts as cached, whatever the shard's own database holds.
            plan.jobs.iter_mut().for_each(|j| j.cached = false);
        }
        Ok(plan)
    }
}

/// Runs the command.
pub fn run(args: &Args) -> Result<()> {
    if let Some(shard) = args.shard {
        return bake_shard(args, shard);
    }
    let store = args.db.open(&args.scene)?;
    bake_once(args, &store)?;
    if args.watch {
        crate::watch::on_change(args.scene.scene.as_deref(), || bake_once(args, &store))?;
    }
    Ok(())
}

/// Bakes one shard: plans against the base (read-only) with the base's parameter plan, deals
/// the misses, and bakes this shard's share into its own database.
fn bake_shard(args: &Args, shard: Shard) -> Result<()> {
    let store = args.db.open(&args.scene)?;
    let base = args.base.as_deref().map(Store::open_read_only).transpose()?;
    let scene = args.scene.load_kept(Some(&store))?;
    let flat = flatten(&scene);
    let start = Instant::now();
    let plan = args.options.shard_plan(&store, base.as_ref(), &scene, &flat)?;
    let split = shard::split(&plan, &flat, shard.count);
    // Chunks this shard committed in an earlier, interrupted run are not baked again.
    let mut mine = plan.shard(&split, shard);
    let present = store.contains_all(&mine.keys())?;
    mine.jobs.iter_mut().zip(present).for_each(|(j, p)| j.cached |= p);
    print_plan(&store, &scene, &flat, &mine, start.elapsed().as_secs_f64())?;
    let taken = split.owner.iter().filter(|o| **o == Some(shard.index)).count();
    crate::emit(&format!(
        "shard {shard}: {taken} of {} missing chunks (estimated {:.1} s on one worker; the shards' range {:.1}–{:.1} s), {} already in {}\n",
        split.owner.iter().flatten().count(),
        split.load[shard.index],
        split.load.iter().copied().fold(f64::INFINITY, f64::min),
        split.load.iter().copied().fold(0.0, f64::max),
        taken - mine.misses().count(),
        store.path().display()
    ));
    if args.dry_run || mine.misses().next().is_none() {
        return Ok(());
    }
    let total: usize = mine.misses().map(|j| j.vertices.len()).sum();
    let s = with_bar(total, "baking", |p| kage_bake_db::bake(&store, &scene, &flat, &mine, p))?;
    crate::emit(&format!(
        "shard {shard}: baked {} chunks ({} vertices) in {:.2} s into {}\n",
        s.cold + s.warm,
        s.vertices_baked,
        s.seconds,
        store.path().display()
    ));
    Ok(())
}

/// Loads, plans, prints and (unless --dry-run) bakes.
fn bake_once(args: &Args, store: &Store) -> Result<()> {
    let scene = args.scene.load_kept(Some(store))?;
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

/// Rows of the plan listed one per line; the rest are counted.
const LISTED: usize = 32;

/// Per instance and technique: chunks, cached, vertices to bake, estimated seconds (from a
/// sample of the misses baked on this machine, see `kage_bake_db::estimate`).
pub fn print_plan(store: &Store, scene: &Scene, flat: &FlatScene, plan: &Plan, planning_s: f64) -> Result<()> {
    let threads = rayon::current_num_threads();
    let estimate = crate::progress::with_spinner("timing a sample of the bake", || {
        kage_bake_db::estimate::estimate(store, scene, flat, plan)
    })?;
    // (chunks, cached, vertices to bake, their seconds on one worker).
    let mut rows: BTreeMap<(usize, Kind), (usize, usize, usize, f64)> = BTreeMap::new();
    for j in &plan.jobs {
        let r = rows.entry((j.instance, j.kind)).or_default();
        r.0 += 1;
        r.1 += usize::from(j.cached);
        if !j.cached {
            r.2 += j.vertices.len();
            r.3 += estimate.rate(j) * plan.work(flat, j);
        }
    }
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
    for ((i, kind), (chunks, cached, vertices, seconds)) in rows.iter().take(LISTED) {
        let est = seconds / threads as f64;
        let kind = kind.name();
        out += &format!(
            "  instance {i:3} {kind:5}: {chunks:3} chunks, {cached:3} cached, {vertices:6} vertices to bake, ~{est:.1} s\n"
        );
    }
    if rows.len() > LISTED {
        out += &format!("  … {} more rows (instance and technique)\n", rows.len() - LISTED);
    }
    let misses = plan.misses().count();
    out += &format!(
        "  {} of {} chunks cached; {misses} to bake, estimated {:.1} s on {threads} threads (timed on a sample of {} vertices: {:.2} s)\n",
        plan.jobs.len() - misses,
        plan.jobs.len(),
        estimate.total(threads),
        estimate.sampled,
        estimate.seconds
    );
    crate::emit(&out);
    Ok(())
}
