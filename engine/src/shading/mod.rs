//! Composition above the techniques: the methods' names ([`Method`]), the ratio estimator that
//! `kage report` measures BSPVT against, and the complete baked look ([`baked`]) that sums
//! the techniques. The BSDF and the albedos they share sit below them, in [`crate::material`].

pub mod baked;
mod method;
pub mod ratio;

pub use method::{Lights, Method};
