//! # kage-bake-db
//!
//! The bake database: every baker's results, content-addressed in one redb file per project.
//!
//! - [`store`]: the file (schema version; tables for meshes, artefacts, metadata, scenes,
//!   lineage and bakers' memos), batched writes, read-only opens, integrity check, garbage
//!   collection and merging;
//! - [`memo`]: what the store keeps to save time — occluder BVHs, re-refined occluders'
//!   triangles, the PRT pilot, receiver refinements, radiance-cache records — each entry
//!   checked when read, through one codec;
//! - [`key`]: bake keys, blake3 of everything a result depends on;
//! - [`plan`](mod@plan): which artefacts a scene needs (chunks of about [`plan::CHUNK`] vertices,
//!   cut by content, per instance and technique), which are cached;
//! - [`run`](mod@run): bakes the misses on rayon while one writer commits batches, re-bakes BSPVT warm
//!   from lineage after edits (with the BSPVT subtree memo kept between runs), and assembles the
//!   engine's bakes ([`bake`]: the same without assembling, reading no cached chunk);
//! - [`estimate`]: a plan's bake time, measured by baking a sample of its misses;
//! - [`prt_budget`]: PRT's order, window and region count chosen from an error budget and kept
//!   in `meta`, so that `kage bake`, `kage render` and the editor bake with the same parameters;
//! - [`pack`]: asset packs (glTF binary + the `KAGE_baked_shadows` extension) written and read;
//! - [`shard`]: a plan's misses dealt to N shards for farms; [`Store::merge_from`] merges
//!   their databases (`docs/sharded-bakes.md`).
//!
//! ## Guarantees
//! - **Same inputs, same bytes**: a key covers the chunk's vertices, parameters, algorithm version
//!   and (BSPVT) the occluder snapshot or (PRT) the group's own geometry; artefacts are
//!   bit-identical on any thread count, and a warm re-bake gives the cold bake's bytes.
//! - **Crash safety**: each batch is one transaction; a process killed at any moment loses at
//!   most the batch in flight, and the next run bakes only what is missing.
//! - **Memos cost only time**: a baker's memo (BSPVT tile subtrees, occluder BVHs) returns
//!   exactly what a build would; a damaged one is ignored and rebuilt, `gc` drops them all.
//! - **Clear errors**: a locked, corrupted or incompatible file is an error naming the file.

pub mod estimate;
pub mod key;
pub mod memo;
pub mod pack;
pub mod plan;
pub mod prt_budget;
pub mod run;
pub mod shard;
pub mod store;

pub use key::Key;
pub use plan::{Plan, plan};
pub use run::{Chunk, Hooks, Outcome, RunStats, bake, load, run, run_cancellable};
pub use store::{DbError, Store};
