//! # kage-engine
//!
//! The engine behind `kage`: scene import (glTF → a [`hecs`] world of plain-data components),
//! ray casting (a CWBVH from `obvhs`), the math the shadow techniques share, the three
//! techniques — [`bspvt`] (polygonal-light shadows with BSP visibility trees and LTC), [`prt`]
//! (environment light with moving rigid groups) and [`cache`] (one bounce of indirect light
//! from HSH records) — and the Monte Carlo reference integrator that every approximation is
//! measured against.
//!
//! ## Design and guarantees
//! - **Data flows one way**: files → [`scene::import`] → [`scene::Scene`] (an ECS world) →
//!   [`scene::flatten`] (a world-space snapshot for a frame) → bakers ([`bspvt::bake`],
//!   [`prt::bake`]; stored by `kage-bake-db`) → per-frame shading ([`bspvt::shade_vertices`],
//!   [`prt::Frame`], [`cache`]) or the [`reference`](mod@crate::reference) integrator → [`raster`] / [`output`]
//!   (EXR/PNG/CSV).
//! - **Pure math apart from I/O**: [`math`] has no I/O and no global state.
//! - **Determinism**: every estimator seeds its random numbers from the pixel or vertex index
//!   (and the user's seed), never from time or thread; results are bit-identical on any
//!   number of threads.
//! - **Bad input never panics**: importers validate what they read and return
//!   [`Error`] values that name the file and the problem.
//! - **Conventions** (binding, `docs/conventions.md`): glTF frame (+Y up, right-handed), linear RGB
//!   radiance, GGX with α = roughness², one-sided lights emitting on the CCW side,
//!   equirectangular environments with `u = frac(atan2(d.x, −d.z)/2π)`, `v = acos(d.y)/π`.

pub mod accel;
pub mod bspvt;
pub mod cache;
pub mod error;
pub mod material;
pub mod named;
pub mod output;
pub mod prt;
pub mod raster;
pub mod receivers;
pub mod reference;
pub mod scene;
pub mod shading;

pub use error::{Error, Result};
pub use kage_runtime::math;
