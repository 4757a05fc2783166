//! Watching a scene file (notify, debounced): the parent folder is watched, not the file, so
//! editors that save by writing a temporary file and renaming it over the scene, or by
//! deleting and re-creating it, are seen like in-place writes. A change that leaves the file
//! half-written fails to import, is reported, and the next change is waited for.

use anyhow::{Context, Result};
use notify_debouncer_mini::{DebounceEventResult, new_debouncer, notify::RecursiveMode};
use std::path::Path;
use std::time::Duration;

/// Calls `on_change` after every debounced change to `scene` (or a file beside it with the
/// same stem, e.g. its `.bin`), until the process is stopped.
pub fn on_change(scene: Option<&Path>, mut on_change: impl FnMut() -> Result<()>) -> Result<()> {
    let scene = scene.context("--watch needs a scene file (the built-in scene never changes)")?;
    let dir = scene.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let stem = scene.file_stem().map(|s| s.to_os_string());
    let (tx, rx) = std::sync::mpsc::channel::<DebounceEventResult>();
    let mut debouncer = new_debouncer(Duration::from_millis(300), tx).context("starting the file watcher")?;
    debouncer
        .watcher()
        .watch(dir, RecursiveMode::NonRecursive)
        .with_context(|| format!("watching {}", dir.display()))?;
    crate::emit(&format!("watching {} (Ctrl-C to stop)\n", scene.display()));
    for events in rx {
        let relevant = match events {
            Ok(events) => events.iter().any(|e| e.path.file_stem().map(|s| s.to_os_string()) == stem),
            Err(e) => {
                eprintln!("warning: file watcher: {e}");
                false
            }
        };
        if relevant && let Err(e) = on_change() {
            eprintln!("error: {e:#}");
        }
    }
    Ok(())
}
