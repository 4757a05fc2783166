//! What every shading method shares: the methods' names ([`Method`]), the material BSDF, and
//! the ratio estimator that `kage report` measures BSPVT against.

mod bsdf;
mod method;
pub mod ratio;

pub use bsdf::Bsdf;
pub use method::{Lights, Method};
