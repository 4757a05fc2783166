//! What every shading method shares: the methods' names ([`Method`]), the material BSDF, the
//! ratio estimator that `kage report` measures BSPVT against, and the complete baked look
//! ([`baked`]) that sums the techniques.

pub mod baked;
mod bsdf;
pub mod detail;
mod method;
pub mod ratio;

pub use bsdf::Bsdf;
pub use method::{Lights, Method};
