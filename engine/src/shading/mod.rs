//! What every shading method shares: the material BSDF, and the ratio estimator that
//! `kage report` measures BSPVT against.

mod bsdf;
pub mod ratio;

pub use bsdf::Bsdf;
