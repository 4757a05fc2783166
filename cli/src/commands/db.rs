//! `kage db`: inspect, check, list, clean and merge bake databases.

use crate::db_args::DbArgs;
use crate::scene_args::SceneArgs;
use anyhow::{Context, Result};
use kage_bake_db::Store;
use std::path::PathBuf;

/// Arguments of `kage db`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// What to do.
    #[command(subcommand)]
    action: Action,
}

#[derive(clap::Subcommand, Debug)]
enum Action {
    /// Counts and sizes.
    Info(Target),
    /// Verify the file's integrity and every artefact's checksum (exit 1 on damage).
    Check(Target),
    /// Drop artefacts that no baked scene references.
    Gc(Target),
    /// List every artefact: key, kind, bytes, checksum and parameters (no timings), by key.
    List(Target),
    /// Merge databases (e.g. the shards of a `kage bake --shard` run) into OUT, checking every
    /// artefact's checksum and version; OUT is created if missing.
    Merge {
        /// The database to merge into.
        out: PathBuf,
        /// The databases to merge (read-only).
        #[arg(required = true)]
        inputs: Vec<PathBuf>,
    },
}

#[derive(clap::Args, Debug)]
struct Target {
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    db: DbArgs,
}

/// Runs the command.
pub fn run(args: &Args) -> Result<()> {
    match &args.action {
        Action::Info(t) => {
            let store = open_existing(t)?;
            // Counting reads every artefact's bytes: its time is the load throughput.
            let start = std::time::Instant::now();
            let (artefacts, bytes, meshes, scenes) = store.counts()?;
            let secs = start.elapsed().as_secs_f64();
            crate::emit(&format!(
                "{}: schema {}, {artefacts} artefacts ({:.2} MB, read in {:.1} ms: {:.2} GB/s), {meshes} meshes, {scenes} scenes\n",
                store.path().display(),
                kage_bake_db::store::SCHEMA_VERSION,
                bytes as f64 / 1e6,
                secs * 1e3,
                bytes as f64 / secs.max(1e-9) / 1e9
            ));
            for (name, size) in store.memos()? {
                crate::emit(&format!("  memo \"{name}\": {:.2} MB\n", size as f64 / 1e6));
            }
        }
        Action::Check(t) => {
            let mut store = open_existing(t)?;
            let report = store.check()?;
            crate::emit(&format!(
                "{}: {} artefacts intact, {} damaged{}\n",
                store.path().display(),
                report.ok,
                report.bad.len(),
                if report.clean { "" } else { " (redb repaired the file)" }
            ));
            for k in &report.bad {
                crate::emit(&format!("  damaged: {}\n", k.short()));
            }
            anyhow::ensure!(report.bad.is_empty(), "{} damaged artefacts: re-bake to replace them", report.bad.len());
        }
        Action::Gc(t) => {
            let store = open_existing(t)?;
            let dropped = store.gc()?;
            crate::emit(&format!("{}: dropped {dropped} unreferenced artefacts\n", store.path().display()));
        }
        Action::List(t) => {
            let store = Store::open_read_only(&t.db.path(&t.scene))?;
            let mut out = String::new();
            for (key, info, bytes) in store.artefacts()? {
                let sum: String = info.checksum.iter().map(|b| format!("{b:02x}")).collect();
                out += &format!("{} {} {bytes} {sum} {}\n", key.hex(), info.kind, info.params);
            }
            crate::emit(&out);
        }
        Action::Merge { out, inputs } => merge(out, inputs)?,
    }
    Ok(())
}

/// Merges `inputs` into `out`, one after another, reporting each.
fn merge(out: &std::path::Path, inputs: &[PathBuf]) -> Result<()> {
    let target = Store::open(out)?;
    let canonical = |p: &std::path::Path| std::fs::canonicalize(p).ok();
    for input in inputs {
        anyhow::ensure!(canonical(input) != canonical(out), "{}: is the database being merged into", input.display());
        let start = std::time::Instant::now();
        let source = Store::open_read_only(input)?;
        let s = target
            .merge_from(&source)
            .with_context(|| format!("merging {} into {}", input.display(), out.display()))?;
        let secs = start.elapsed().as_secs_f64();
        crate::emit(&format!(
            "{}: {} artefacts merged ({:.2} MB, {:.0} MB/s), {} already in {}\n",
            input.display(),
            s.added,
            s.bytes as f64 / 1e6,
            s.bytes as f64 / 1e6 / secs.max(1e-9),
            s.present,
            out.display()
        ));
    }
    Ok(())
}

fn open_existing(t: &Target) -> Result<kage_bake_db::Store> {
    let path = t.db.path(&t.scene);
    anyhow::ensure!(path.exists(), "{}: no bake database here (run `kage bake` first)", path.display());
    Ok(kage_bake_db::Store::open(&path)?)
}
