//! The material: Bevy's `StandardMaterial` extended with kage's per-pixel polygonal lights
//! (`shaders/bevy_kage.wgsl`, which includes kage's `ltc.wgsl` and `pixel_lights.wgsl`: the
//! WGSL text is shared with kage's viewport, not copied).

use bevy::asset::uuid_handle;
use bevy::pbr::{ExtendedMaterial, MaterialExtension};
use bevy::prelude::*;
use bevy::render::render_resource::{AsBindGroup, ShaderType};
use bevy::render::storage::ShaderBuffer;
use bevy::shader::ShaderRef;

/// A pack instance's material: its real material as a `StandardMaterial`, kage's lights added.
pub type KageMaterial = ExtendedMaterial<StandardMaterial, KageLights>;

/// The extension's bindings: this instance's place in the scene's per-vertex terms, the lights
/// shaded per pixel and the LTC tables.
#[derive(Asset, AsBindGroup, Reflect, Debug, Clone)]
pub struct KageLights {
    /// Where the instance's terms start, how many lights are per pixel, the specular factor.
    #[uniform(100)]
    pub params: KageParams,
    /// Per vertex of every instance: the per-vertex lights' radiance and the per-pixel lights'
    /// lobe integrals ([`crate::shade`]).
    #[storage(101, read_only)]
    pub vertices: Handle<ShaderBuffer>,
    /// The lights shaded per pixel, as `ltc.wgsl`'s `Light`.
    #[storage(102, read_only)]
    pub lights: Handle<ShaderBuffer>,
    /// The LTC table, then the GGX directional albedo's tables.
    #[storage(103, read_only)]
    pub tables: Handle<ShaderBuffer>,
}

/// `KageParams` in `bevy_kage.wgsl`.
#[derive(Clone, Copy, Debug, Default, Reflect, ShaderType)]
pub struct KageParams {
    /// The instance's first vertex in the per-vertex terms.
    pub first: u32,
    /// Lights shaded per pixel.
    pub lights: u32,
    /// `KHR_materials_specular`'s factor.
    pub specular: f32,
    /// Padding to 16 bytes.
    pub pad: f32,
}

impl MaterialExtension for KageLights {
    fn vertex_shader() -> ShaderRef {
        SHADER.into()
    }

    fn fragment_shader() -> ShaderRef {
        SHADER.into()
    }
}

/// The material's shader, registered by [`register_shader`].
const SHADER: Handle<Shader> = uuid_handle!("4b0e3f61-8d7c-4c52-9a55-6e1f0c2d7a11");

/// `bevy_kage.wgsl` with kage's shared files in place of its include lines.
pub fn shader_source() -> String {
    include_str!("../../shaders/bevy_kage.wgsl")
        .replace("// #include \"ltc.wgsl\"", include_str!("../../shaders/ltc.wgsl"))
        .replace("// #include \"pixel_lights.wgsl\"", include_str!("../../shaders/pixel_lights.wgsl"))
}

/// Puts the material's shader into `Assets<Shader>` under its fixed handle.
pub(crate) fn register_shader(app: &mut App) {
    let shader = Shader::from_wgsl(shader_source(), "bevy_kage/bevy_kage.wgsl");
    let mut shaders = app.world_mut().resource_mut::<Assets<Shader>>();
    shaders.insert(SHADER.id(), shader).expect("a UUID handle always inserts");
}

/// The LTC table and the GGX directional albedo's A and B tables, as `pixel_lights.wgsl`
/// indexes them.
pub fn tables() -> Vec<f32> {
    use kage_runtime::math::{ggx, ltc};
    ltc::table().entries().iter().flatten().chain(ggx::albedo_tables().concat().iter()).copied().collect()
}
