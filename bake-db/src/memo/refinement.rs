//! Receiver refinement ([`receivers::refine`]) kept in the store's memos, one per instance: a
//! scene loaded again reads the refined meshes of the instances whose shadows did not change
//! instead of refining them (0.4 s on the built-in scene, over a minute at a million
//! vertices). A memo's name is the instance's [`receivers::keys`] entry, which hashes
//! everything its refinement reads, so a kept refinement is the computed one byte for byte.
//!
//! Like every memo it costs only time: an entry checks its own hash and its meshes when read
//! (a damaged one is refined again), and `gc` drops it.

use crate::{DbError, Store};
use kage_engine::receivers::{self, Receiver, Refinement, Report, Settings};
use kage_engine::scene::Scene;

/// Why a scene could not be refined through the store.
#[derive(Debug, thiserror::Error)]
pub enum RefineError {
    /// Reading or keeping the memo failed.
    #[error(transparent)]
    Db(#[from] DbError),
    /// Refinement itself failed.
    #[error(transparent)]
    Scene(#[from] kage_engine::Error),
}

/// Refines `scene`'s receivers from their source meshes as [`receivers::refine`] does, reading
/// each instance's refinement from `store` when it holds it (named by its [`receivers::keys`]
/// entry) and keeping the others there (a read-only store only reads). Also says how many
/// instances were read. `progress` hears the instances done so far.
pub fn refine(
    store: &Store,
    scene: &mut Scene,
    settings: &Settings,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<(Report, usize), RefineError> {
    scene.restore_source_meshes();
    let names: Vec<String> =
        receivers::keys(scene, settings).iter().map(|k| format!("receiver {}", &k.to_hex()[..32])).collect();
    let kept = names
        .iter()
        .map(|name| Ok(store.memo(name)?.and_then(|b| Receiver::from_bytes(&b))))
        .collect::<Result<Vec<_>, DbError>>()?;
    let read: Vec<bool> = kept.iter().map(Option::is_some).collect();
    let refinement = Refinement::of(scene, settings, kept, progress)?;
    if !store.read_only() {
        let fresh = names.into_iter().zip(refinement.receivers()).zip(&read).filter(|(_, read)| !**read);
        store.put_memos(&fresh.map(|((name, r), _)| (name, r.to_bytes())).collect::<Vec<_>>())?;
    }
    Ok((refinement.apply(scene), read.iter().filter(|r| **r).count()))
}

/// What [`refine`] read, for a front end's refinement line: empty when nothing was read,
/// else ", K of N instances kept in the bake database".
pub fn kept_note(kept: usize, instances: usize) -> String {
    match kept {
        0 => String::new(),
        k if k == instances => format!(", all {k} instances kept in the bake database"),
        k => format!(", {k} of {instances} instances kept in the bake database"),
    }
}
