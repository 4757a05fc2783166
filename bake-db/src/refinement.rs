//! Receiver refinement ([`receivers::refine`]) kept in the store's memos: a scene loaded again
//! with the same lights, geometry and settings reads its refined meshes instead of refining
//! (0.4 s on the built-in scene, over a minute at a million vertices). The memo's name is
//! [`receivers::key`], which hashes everything refinement reads, so a kept refinement is the
//! computed one byte for byte.
//!
//! Like every memo it costs only time: an entry checks its own hash and its meshes when read
//! (a damaged one is refined again), and `gc` drops it.

use crate::{DbError, Store};
use kage_engine::receivers::{self, Refinement, Report, Settings};
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
/// the refinement from `store` when it holds it and keeping it there otherwise (a read-only
/// store only reads). True when it was read.
pub fn refine(store: &Store, scene: &mut Scene, settings: &Settings) -> Result<(Report, bool), RefineError> {
    scene.restore_source_meshes();
    let name = format!("receiver refinement {}", &receivers::key(scene, settings).to_hex()[..32]);
    if let Some(kept) = store.memo(&name)?.and_then(|b| Refinement::from_bytes(&b)).filter(|k| k.fits(scene)) {
        return Ok((kept.apply(scene), true));
    }
    let refinement = Refinement::of(scene, settings)?;
    if !store.read_only() {
        store.put_memos(&[(name, refinement.to_bytes())])?;
    }
    Ok((refinement.apply(scene), false))
}
