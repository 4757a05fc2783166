//! What the store keeps beside the artefacts to save time or work: each entry costs only time
//! if lost — a damaged one is ignored and computed again, and `gc` drops what no scene uses.
//!
//! - [`bvhs`]: the BSPVT occluders' BVHs, so that an edit rebuilds only those it touched;
//! - [`pilot`]: the PRT budget's pilot transfer, read instead of baked after a rotation;
//! - [`refinement`]: each instance's receiver refinement, under its own key;
//! - [`records`]: radiance-cache records, keyed by geometry, materials, direct light and
//!   settings.
//!
//! Entries that carry their own checksum are written and read through [`codec`]: one checked
//! reader and writer, so a damaged or truncated entry reads as `None`, never as a panic.

pub mod bvhs;
pub mod codec;
pub mod pilot;
pub mod records;
pub mod refinement;
