//! `cargo xtask`: developer tasks that regenerate the tables kage ships as source or bytes.
//!
//! They are not part of the user's `kage` binary: their output is committed, and a test beside
//! each table checks the committed data against its generator.

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use kage_engine::math::{ggx, ltc};
use std::path::{Path, PathBuf};
use std::time::Instant;

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
    /// Integrate the GGX directional-albedo tables and write them as little-endian f32.
    GgxAlbedo {
        /// Where to write the table bytes.
        #[arg(short, long, default_value = "engine/src/math/ggx_albedo.bin")]
        output: PathBuf,
    },
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
        Task::GgxAlbedo { output } => {
            write(&output, &ggx::albedo_table_bytes())?;
            (output, format!("{0}×{0} albedo entries per term", ggx::ALBEDO_N))
        }
    };
    println!("{what} in {:.1} s → {}", start.elapsed().as_secs_f64(), output.display());
    Ok(())
}

fn write(path: &Path, bytes: &[u8]) -> Result<()> {
    std::fs::write(path, bytes).with_context(|| format!("writing {}", path.display()))
}
