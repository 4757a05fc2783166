//! `--watch`: re-runs a command when the scene file changes on disk, through the editor's
//! [`Watcher`](kage_gpu::reload::Watcher) (folder watched, so rename-replace and
//! delete-recreate saves are seen; only changed bytes count). A change that leaves the file
//! half-written fails to import, is reported, and the next change is waited for.

use anyhow::{Context, Result};
use kage_gpu::reload::Watcher;
use std::path::Path;

/// Calls `on_change` after every change to `scene` (or a file beside it with the same stem,
/// e.g. its `.bin`), until the process is stopped.
pub fn on_change(scene: Option<&Path>, mut on_change: impl FnMut() -> Result<()>) -> Result<()> {
    let scene = scene.context("--watch needs a scene file (the built-in scene never changes)")?;
    let mut watcher = Watcher::new(None, Some(scene), None, || {})?;
    crate::emit(&format!("watching {} (Ctrl-C to stop)\n", scene.display()));
    while let Some((changes, errors)) = watcher.wait() {
        errors.iter().for_each(|e| eprintln!("warning: {e}"));
        if !changes.is_empty()
            && let Err(e) = on_change()
        {
            eprintln!("error: {e:#}");
        }
    }
    Ok(())
}
