//! Pure math shared by the bakers, the shading code and the reference integrator.
//!
//! No I/O and no global mutable state live here; lazily built tables are immutable once made.

pub mod color;
pub mod cubemap;
pub mod distribution;
pub mod equirect;
pub mod frame;
pub mod ggx;
pub mod hsh;
pub mod ltc;
pub mod morton;
pub mod nelder_mead;
pub mod planes;
pub mod polygon;
pub mod quadrature;
pub mod rng;
pub mod sampling;
pub mod sh;
pub mod trig;

pub use color::luminance;

/// Relative RMSE `√(Σ|x − r|² / Σ|r|²)` of colours against a reference (0 for a black one).
pub fn relative_rmse(x: &[glam::Vec3], r: &[glam::Vec3]) -> f64 {
    let num: f64 = x.iter().zip(r).map(|(a, b)| (*a - *b).as_dvec3().length_squared()).sum();
    let den: f64 = r.iter().map(|b| b.as_dvec3().length_squared()).sum();
    if den > 0.0 { (num / den).sqrt() } else { 0.0 }
}
