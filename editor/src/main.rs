//! The `kage` binary: see the `kage_editor` library for the commands.

/// mimalloc rather than the system allocator: warm re-bakes allocate many small per-vertex
/// buffers, and took 8 % less CPU time with it (docs/bake-db.md).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> std::process::ExitCode {
    kage_editor::main()
}
