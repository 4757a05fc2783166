//! The `kage` binary: see the `kage_editor` library for the commands.

fn main() -> std::process::ExitCode {
    kage_editor::main()
}
