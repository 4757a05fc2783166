//! `cargo xtask`: developer tasks that regenerate the tables kage ships as source or bytes,
//! generate the large benchmark scene, and run the measurements that take too long for the
//! suite (`measure`).
//!
//! They are not part of the user's `kage` binary. The tables' output is committed, and a test
//! beside each table checks the committed data against its generator; the level is generated
//! where a benchmark needs it (`docs/benchmarks.md#a-million-vertices`), never committed.

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use kage_engine::math::{ggx, ltc};
use std::path::{Path, PathBuf};
use std::time::Instant;

mod level;

/// Developer tasks for the kage workspace.
#[derive(Parser)]
#[command(name = "cargo xtask")]
struct Cli {
    #[command(subcommand)]
    task: Task,
}

#[derive(Subcommand)]
enum Task {
    /// Fit the GGX LTC table (Heitz et al. 2016) and write it as Rust source (~70 s on 2 cores).
    FitLtc {
        /// Where to write the table source.
        #[arg(short, long, default_value = "engine/src/math/ltc/table.rs")]
        output: PathBuf,
    },
    /// Generate the scaling benchmark's level: a terrain with instanced rocks and four quad
    /// lights, of about VERTICES receiver vertices (glTF and a .bin).
    Level {
        /// Receiver vertices to aim for (the level's area grows with them).
        #[arg(long, default_value_t = 1_000_000)]
        vertices: usize,
        /// Where to write the .gltf (the .bin goes beside it).
        #[arg(short, long, default_value = "target/level/level.gltf")]
        output: PathBuf,
        /// Each light declares it stays within this many metres of where it is (without: the
        /// lights may go anywhere, and BSPVT bakes every direction).
        #[arg(long, value_name = "METRES")]
        light_reach: Option<f32>,
    },
    /// Integrate the GGX directional-albedo tables and write them as little-endian f32.
    GgxAlbedo {
        /// Where to write the table bytes.
        #[arg(short, long, default_value = "engine/src/math/ggx_albedo.bin")]
        output: PathBuf,
    },
    /// Run one of receiver refinement's measurements on the two-triangle floor (minutes each),
    /// printing what `docs/receivers.md` and `docs/benchmarks.md` report.
    Measure {
        #[command(subcommand)]
        what: Measure,
    },
}

#[derive(Subcommand)]
enum Measure {
    /// Per-pixel error against vertices, adaptive against uniform refinement (4096-spp reference).
    ErrorCurve {
        /// Budgets to refine at (comma-separated).
        #[arg(long, value_delimiter = ',', default_values_t = kage_tests::measure::CURVE_BUDGETS)]
        budgets: Vec<usize>,
    },
    /// BSPVT's own error at the refined floor's penumbra vertices, at 64² and 128² faces.
    BspvtAtVertices,
    /// Refinement for a light that may go anywhere above the floor against for where it is.
    Anywhere,
    /// The environment's part of refinement, under each of the repository's maps.
    Environment,
}

/// Runs a measurement; it prints its own lines.
fn measure(what: Measure) {
    use kage_tests::measure::*;
    match what {
        Measure::ErrorCurve { budgets } => error_curve(&budgets),
        Measure::BspvtAtVertices => bspvt_at_refined_vertices(),
        Measure::Anywhere => anywhere_against_where_it_is(),
        Measure::Environment => environment_refinement(),
    }
}

fn main() -> Result<()> {
    // Paths are relative to the workspace root, wherever cargo was started.
    std::env::set_current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))?;
    let start = Instant::now();
    let (output, what) = match Cli::parse().task {
        Task::FitLtc { output } => {
            let pb = ProgressBar::new(ltc::TABLE_SIZE as u64)
                .with_style(ProgressStyle::with_template("{bar:40} {pos}/{len} rows, {eta} left")?);
            let table = ltc::fit::fit_table(&|rows| pb.set_position(rows as u64));
            pb.finish_and_clear();
            write(&output, ltc::fit::table_source(&table).as_bytes())?;
            (output, format!("{} LTC entries", table.len()))
        }
        Task::Level { vertices, output, light_reach } => {
            let made = level::write(&output, vertices, light_reach)?;
            let what = format!(
                "a {:.0} m level of {} receiver vertices ({} terrain, {} instances)",
                made.side, made.vertices, made.terrain, made.instances
            );
            (output, what)
        }
        Task::GgxAlbedo { output } => {
            write(&output, &ggx::albedo_table_bytes())?;
            (output, format!("{0}×{0} albedo entries per term", ggx::ALBEDO_N))
        }
        Task::Measure { what } => {
            measure(what);
            println!("measured in {:.1} s", start.elapsed().as_secs_f64());
            return Ok(());
        }
    };
    println!("{what} in {:.1} s → {}", start.elapsed().as_secs_f64(), output.display());
    Ok(())
}

fn write(path: &Path, bytes: &[u8]) -> Result<()> {
    std::fs::write(path, bytes).with_context(|| format!("writing {}", path.display()))
}
