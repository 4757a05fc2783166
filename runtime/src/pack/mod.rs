//! Asset packs as a reader at run time sees them: the GLB container ([`glb`]), the
//! `KAGE_baked_shadows` extension's records ([`schema`], spec: `docs/KAGE_baked_shadows.md`),
//! their integrity ([`integrity`]: a blake3 digest per buffer view and of the JSON) and the
//! ranges every number must lie in ([`ranges`]); [`Pack::read`] reads all of it into plain
//! data. `kage-bake-db` writes packs and reads them into kage's scene through these.

pub mod glb;
pub mod integrity;
pub mod ranges;
mod read;
pub mod schema;

pub use read::{Checked, Environment, Group, Instance, Light, Mesh, Pack, Texture};

/// The extension's name.
pub const EXTENSION: &str = "KAGE_baked_shadows";
/// The extension's version this kage writes (6: with the vertices inside geometry).
pub const VERSION: u64 = 6;
/// The extension's versions this kage reads (2 differs from 1 in number formatting only; 1 and
/// 2 hold BSPVT record format 1, without depth: shaded as they were, lights in closed rooms
/// dark; 1 to 3 carry no checksums: read with their numbers range-checked only; 1 to 4 carry
/// no bounce; 1 to 5 do not name the vertices inside geometry).
pub const VERSIONS: std::ops::RangeInclusive<u64> = 1..=6;
/// The first version that carries the integrity record.
pub const SEALED: u64 = 4;
