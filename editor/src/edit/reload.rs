//! Hot reload: notify (debounced) on the shader folder and on the folders holding the scene and
//! environment files. Folders are watched rather than files, so saves by rename-replace or
//! delete-recreate are seen; a half-written file fails to load, is reported, and the next
//! change is waited for.

use anyhow::{Context, Result};
use notify_debouncer_mini::notify::{RecommendedWatcher, RecursiveMode};
use notify_debouncer_mini::{DebounceEventResult, Debouncer, new_debouncer};
use std::path::{Path, PathBuf};
use std::sync::mpsc::Receiver;
use std::time::Duration;

/// A change worth acting on.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Change {
    /// A WGSL file under the shader folder (its file name).
    Shader(String),
    /// The scene file (or a file beside it with its stem, e.g. its `.bin`).
    Scene,
    /// The environment map.
    Environment,
}

/// Watches the editor's inputs.
pub struct Watcher {
    _debouncer: Debouncer<RecommendedWatcher>,
    rx: Receiver<DebounceEventResult>,
    shaders: Option<PathBuf>,
    scene: Option<PathBuf>,
    env: Option<PathBuf>,
}

fn folder(p: &Path) -> PathBuf {
    let dir = p.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    dir.canonicalize().unwrap_or_else(|_| dir.to_path_buf())
}

fn canonical_file(p: &Path) -> PathBuf {
    folder(p).join(p.file_name().unwrap_or_default())
}

impl Watcher {
    /// Starts watching; `on_event` runs on the watcher's thread after each debounced batch
    /// (the editor asks for a repaint there).
    pub fn new(
        shaders: Option<&Path>,
        scene: Option<&Path>,
        env: Option<&Path>,
        on_event: impl Fn() + Send + 'static,
    ) -> Result<Self> {
        let (tx, rx) = std::sync::mpsc::channel();
        let mut debouncer = new_debouncer(Duration::from_millis(150), move |e: DebounceEventResult| {
            let _ = tx.send(e);
            on_event();
        })
        .context("starting the file watcher")?;
        let shaders = shaders.map(|d| d.canonicalize().unwrap_or_else(|_| d.to_path_buf()));
        let (scene, env) = (scene.map(canonical_file), env.map(canonical_file));
        let mut dirs: Vec<PathBuf> = shaders.iter().cloned().collect();
        dirs.extend(scene.iter().chain(&env).map(|f| folder(f)));
        dirs.sort();
        dirs.dedup();
        for d in &dirs {
            debouncer
                .watcher()
                .watch(d, RecursiveMode::NonRecursive)
                .with_context(|| format!("watching {}", d.display()))?;
        }
        Ok(Self { _debouncer: debouncer, rx, shaders, scene, env })
    }

    /// The changes since the last call (never blocks), without repeats; watcher errors are
    /// returned as messages.
    pub fn changes(&self) -> (Vec<Change>, Vec<String>) {
        let (mut changes, mut errors) = (Vec::new(), Vec::new());
        for batch in self.rx.try_iter() {
            match batch {
                Ok(events) => events.iter().filter_map(|e| self.classify(&e.path)).for_each(|c| {
                    if !changes.contains(&c) {
                        changes.push(c);
                    }
                }),
                Err(e) => errors.push(format!("file watcher: {e}")),
            }
        }
        (changes, errors)
    }

    fn classify(&self, path: &Path) -> Option<Change> {
        let path = canonical_file(path);
        let same_stem = |f: &PathBuf| folder(f) == folder(&path) && f.file_stem() == path.file_stem();
        if self.shaders.as_ref().is_some_and(|d| folder(&path) == *d) && path.extension().is_some_and(|e| e == "wgsl") {
            return Some(Change::Shader(path.file_name()?.to_string_lossy().into_owned()));
        }
        if self.env.as_ref().is_some_and(|f| *f == path) {
            return Some(Change::Environment);
        }
        self.scene.as_ref().filter(|f| same_stem(f)).map(|_| Change::Scene)
    }
}
