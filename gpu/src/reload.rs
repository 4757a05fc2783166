//! Hot reload: notify (debounced) on the shader folder and on the folders holding the scene and
//! environment files. Folders are watched rather than files, so saves by rename-replace or
//! delete-recreate are seen; a half-written file fails to load, is reported, and the next
//! change is waited for. A change is reported only when the file's bytes differ from the last
//! seen (blake3): notify also reports reads (loading a file would otherwise re-trigger its own
//! reload) and editors often write a file more than once per save.

use anyhow::{Context, Result};
use notify_debouncer_mini::notify::{RecommendedWatcher, RecursiveMode};
use notify_debouncer_mini::{DebounceEventResult, Debouncer, new_debouncer};
use std::collections::HashMap;
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
    /// The content hash of every relevant file as last seen (`None`: absent).
    seen: HashMap<PathBuf, Option<blake3::Hash>>,
}

fn content(path: &Path) -> Option<blake3::Hash> {
    std::fs::read(path).ok().map(|b| blake3::hash(&b))
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
        let mut w = Self { _debouncer: debouncer, rx, shaders, scene, env, seen: HashMap::new() };
        for d in &dirs {
            for entry in std::fs::read_dir(d).into_iter().flatten().flatten() {
                let path = canonical_file(&entry.path());
                if w.classify(&path).is_some() {
                    w.seen.insert(path.clone(), content(&path));
                }
            }
        }
        Ok(w)
    }

    /// Records `path`'s bytes as seen: the editor's own save is not a change to act on.
    pub fn note_write(&mut self, path: &Path) {
        let path = canonical_file(path);
        if self.classify(&path).is_some() {
            let now = content(&path);
            self.seen.insert(path, now);
        }
    }

    /// The changes since the last call (never blocks), without repeats; watcher errors are
    /// returned as messages.
    pub fn changes(&mut self) -> (Vec<Change>, Vec<String>) {
        let batches: Vec<DebounceEventResult> = self.rx.try_iter().collect();
        self.sort(batches)
    }

    /// Waits for the next batch of events and sorts it like [`Self::changes`] (for `--watch`).
    pub fn wait(&mut self) -> Option<(Vec<Change>, Vec<String>)> {
        let first = self.rx.recv().ok()?;
        let batches: Vec<DebounceEventResult> = std::iter::once(first).chain(self.rx.try_iter()).collect();
        Some(self.sort(batches))
    }

    fn sort(&mut self, batches: Vec<DebounceEventResult>) -> (Vec<Change>, Vec<String>) {
        let (mut changes, mut errors) = (Vec::new(), Vec::new());
        for batch in batches {
            match batch {
                Ok(events) => {
                    for e in events {
                        let path = canonical_file(&e.path);
                        let Some(c) = self.classify(&path) else { continue };
                        let now = content(&path);
                        if self.seen.insert(path, now) != Some(now) && !changes.contains(&c) {
                            changes.push(c);
                        }
                    }
                }
                Err(e) => errors.push(format!("file watcher: {e}")),
            }
        }
        (changes, errors)
    }

    fn classify(&self, path: &Path) -> Option<Change> {
        let same_stem = |f: &PathBuf| folder(f) == folder(path) && f.file_stem() == path.file_stem();
        if self.shaders.as_ref().is_some_and(|d| folder(path) == *d) && path.extension().is_some_and(|e| e == "wgsl") {
            return Some(Change::Shader(path.file_name()?.to_string_lossy().into_owned()));
        }
        if self.env.as_deref() == Some(path) {
            return Some(Change::Environment);
        }
        self.scene.as_ref().filter(|f| same_stem(f)).map(|_| Change::Scene)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::{Duration, Instant};

    fn wait_changes(w: &mut Watcher, quiet: Duration) -> Vec<Change> {
        let start = Instant::now();
        let mut all = Vec::new();
        while start.elapsed() < quiet {
            all.extend(w.changes().0);
            std::thread::sleep(Duration::from_millis(20));
        }
        all
    }

    #[test]
    fn reads_are_not_changes_and_writes_are() {
        let scratch = tempfile::tempdir().unwrap();
        let dir = scratch.path();
        std::fs::write(dir.join("a.wgsl"), "// one").unwrap();
        std::fs::write(dir.join("scene.gltf"), "{}").unwrap();
        let mut w = Watcher::new(Some(dir), Some(&dir.join("scene.gltf")), None, || {}).unwrap();
        // Loading files (what a reload does) is not a change.
        let _ = std::fs::read(dir.join("a.wgsl")).unwrap();
        let _ = std::fs::read(dir.join("scene.gltf")).unwrap();
        assert_eq!(wait_changes(&mut w, Duration::from_millis(600)), vec![]);
        // Re-writing the same bytes is not either; new bytes are.
        std::fs::write(dir.join("scene.gltf"), "{}").unwrap();
        std::fs::write(dir.join("a.wgsl"), "// two").unwrap();
        std::fs::write(dir.join("scene.bin"), "new").unwrap();
        let got = wait_changes(&mut w, Duration::from_millis(800));
        assert!(got.contains(&Change::Shader("a.wgsl".into())) && got.contains(&Change::Scene), "{got:?}");
        assert_eq!(got.len(), 2, "{got:?}");
    }
}
