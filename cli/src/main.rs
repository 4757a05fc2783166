//! `kage`: bake and preview shadows for real-time rendering.
//!
//! Subcommands: `info` (what a scene holds), `render` (images and per-vertex radiance with a
//! chosen method), `bake` and `db` (the bake database), `export` (asset packs), `report`
//! (speed against error), `edit` (the scene editor, from `kage-editor`). With no scene argument
//! every command uses the built-in default scene.

mod commands;
mod db_args;
mod exposure;
mod named_arg;
mod progress;
mod prt_args;
mod scene_args;
mod watch;

/// mimalloc rather than the system allocator: warm re-bakes allocate many small per-vertex
/// buffers, and took 8 % less CPU time with it (docs/bake-db.md).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// kage (影): bakes and previews shadows from area and environment lights.
#[derive(Parser)]
#[command(name = "kage", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Worker threads (default: all cores).
    #[arg(long, global = true)]
    threads: Option<usize>,
}

#[derive(Subcommand)]
enum Command {
    /// Meshes, vertices, triangles, lights, groups, cameras and content hashes of a scene.
    Info(commands::info::Args),
    /// Render an image and/or per-vertex radiance with a shading method (baking what it needs).
    Render(commands::render::Args),
    /// Plan and run the scene's bakes against the bake database (incremental, resumable).
    Bake(commands::bake::Args),
    /// Inspect, check or clean the bake database.
    Db(commands::db::Args),
    /// Write an asset pack: the scene, its baked data and an unlit preview, as glTF binary.
    Export(commands::export::Args),
    /// Speed against error of every method (polygonal lights, PRT, radiance cache) against the
    /// Monte Carlo reference: report.md, report.csv and plots.
    Report(commands::report::Args),
    /// Open the scene editor: live preview, outliner, inspector, background bakes, hot reload.
    Edit(commands::edit::Args),
}

/// Writes to stdout, ignoring a closed pipe (`kage info | head` is not an error).
pub fn emit(text: &str) {
    use std::io::Write;
    let _ = std::io::stdout().lock().write_all(text.as_bytes());
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Some(n) = cli.threads
        && let Err(e) = rayon::ThreadPoolBuilder::new().num_threads(n).build_global()
    {
        eprintln!("error: cannot start {n} threads: {e}");
        return ExitCode::FAILURE;
    }
    let result = match cli.command {
        Command::Info(a) => commands::info::run(&a),
        Command::Render(a) => commands::render::run(&a),
        Command::Report(a) => commands::report::run(&a),
        Command::Bake(a) => commands::bake::run(&a),
        Command::Db(a) => commands::db::run(&a),
        Command::Export(a) => commands::export::run(&a),
        Command::Edit(a) => commands::edit::run(&a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
