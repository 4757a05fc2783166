//! `kage fit-ltc`: fits the GGX LTC table and writes it as Rust source (the committed
//! `engine/src/math/ltc/table.rs`).

use crate::progress::bar;
use anyhow::{Context, Result};
use kage_engine::math::ltc::{TABLE_SIZE, fit};
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `kage fit-ltc`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Where to write the table source.
    #[arg(short, long, default_value = "engine/src/math/ltc/table.rs")]
    output: PathBuf,
}

/// Fits all 64×64 entries (parallel over roughness rows) and writes the source file.
pub fn run(args: &Args) -> Result<()> {
    let pb = bar(TABLE_SIZE as u64, "rows");
    let start = Instant::now();
    let table = fit::fit_table(&|rows| pb.set_position(rows as u64));
    pb.finish_and_clear();
    std::fs::write(&args.output, fit::table_source(&table))
        .with_context(|| format!("writing {}", args.output.display()))?;
    crate::emit(&format!(
        "fitted {} entries in {:.1} s → {}\n",
        table.len(),
        start.elapsed().as_secs_f64(),
        args.output.display()
    ));
    Ok(())
}
