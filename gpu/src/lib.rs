//! GPU shading of kage's baked results with WGSL compute shaders on wgpu.
//!
//! - [`context`]: the device (any adapter, including Mesa's lavapipe CPU Vulkan device);
//! - [`shader`]: WGSL sources from `shaders/` (embedded in the binary, or read from a folder for
//!   hot reload), validated with naga first so a broken shader reports file, line and message
//!   and never reaches the device;
//! - [`bspvt`]: per-vertex BSPVT shading — tree descent and LTC integration per light;
//! - [`prt`]: per-vertex PRT shading — SH transfer against each group's posed lighting and the
//!   other groups' box-filtered silhouettes;
//! - [`viewport`]: the preview renderer the editor shows and `kage render --gpu` draws through
//!   (per-pixel lights and PRT, the base-colour texture's detail, the sky, the sun's shadow
//!   map), viewed through an [`camera::Orbit`]; it knows no GUI;
//! - [`reload`]: hot reload of shaders and scene files (notify).
//!
//! Both match the CPU path (`kage_engine::bspvt::shade`, `kage_engine::prt::Frame`) within
//! 1e-3 relative plus 1e-5 absolute (tests in `tests/tests/gpu.rs`): the GPU computes in f32
//! what the CPU computes in f64. Static data (trees, transfer) is uploaded once per bake; a
//! frame uploads only what the camera, lights and group poses change.

pub mod bspvt;
pub mod buffers;
pub mod camera;
pub mod context;
pub mod prt;
pub mod reload;
pub mod shader;
pub mod viewport;

pub use context::Gpu;
use kage_engine::scene::VertexValues;
pub use shader::{ShaderError, Shaders};

/// What can go wrong on the GPU side.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No adapter or device.
    #[error("no usable GPU device ({0}); without a GPU install Mesa's lavapipe (Debian: mesa-vulkan-drivers)")]
    NoDevice(String),
    /// A shader failed to parse or validate.
    #[error(transparent)]
    Shader(#[from] ShaderError),
    /// The scene exceeds what the shaders handle.
    #[error("{0}")]
    Unsupported(String),
    /// A result could not be read back.
    #[error("GPU read-back failed: {0}")]
    Readback(String),
}

/// Splits values over all vertices (instance order) into one list per instance.
fn per_instance(flat: &kage_engine::scene::FlatScene, values: Vec<glam::Vec3>) -> VertexValues {
    let mut rest = values.into_iter();
    flat.instances.iter().map(|i| rest.by_ref().take(flat.meshes[i.mesh as usize].positions.len()).collect()).collect()
}
