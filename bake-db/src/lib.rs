//! # kage-bake-db
//!
//! The content-addressed store of baked artefacts (redb), the bake planner with incremental
//! re-bake, and asset-pack export — issue #7. The crate exists so that the workspace layout is
//! the final one; it has no code yet: bakes currently run in memory on every
//! `kage render --method bspvt` (see the README's BSPVT section).
