//! The material: Bevy's `StandardMaterial` extended with kage's per-pixel polygonal lights
//! (`shaders/bevy_kage.wgsl`, which includes kage's `ltc.wgsl` and `pixel_lights.wgsl`: the
//! WGSL text is shared with kage's viewport, not copied).
//!
//! The pipeline is specialised ([`Variant`]): the per-pixel light code is compiled in only
//! where lights are shaded per pixel, and Bevy's own lighting only where Bevy has light of
//! its own to add. On a CPU device (Mesa's lavapipe) a fragment stage pays for code its
//! uniform branches skip: the two together were most of the frame there.

use bevy::asset::uuid_handle;
use bevy::light::{AmbientLight, EnvironmentMapLight, LightProbe};
use bevy::mesh::MeshVertexBufferLayoutRef;
use bevy::pbr::{ExtendedMaterial, MaterialExtension, MaterialExtensionKey, MaterialExtensionPipeline};
use bevy::prelude::*;
use bevy::render::render_resource::{AsBindGroup, RenderPipelineDescriptor, ShaderType, SpecializedMeshPipelineError};
use bevy::render::renderer::RenderAdapterInfo;
use bevy::render::storage::ShaderBuffer;
use bevy::shader::ShaderRef;

use crate::shade::ShadeOn;
use crate::spawn::KageLight;

/// A pack instance's material: its real material as a `StandardMaterial`, kage's lights added.
pub type KageMaterial = ExtendedMaterial<StandardMaterial, KageLights>;

/// The extension's bindings: this instance's place in the scene's per-vertex terms, the lights
/// shaded per pixel and the LTC tables; which pipeline variant draws it.
#[derive(Asset, AsBindGroup, Reflect, Debug, Clone)]
#[bind_group_data(Variant)]
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
    /// The pipeline variant: the plugin keeps it to what the app needs (`choose_variant`).
    pub variant: Variant,
}

/// Which code the material's pipeline holds.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Reflect)]
pub struct Variant {
    /// The lights are shaded per pixel (`KAGE_PIXEL_LIGHTS`).
    pub pixel: bool,
    /// Bevy has light of its own to add (`KAGE_BEVY_LIGHTING`): its lights, ambient light,
    /// environment maps or light probes.
    pub bevy_lighting: bool,
}

impl From<&KageLights> for Variant {
    fn from(m: &KageLights) -> Self {
        m.variant
    }
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
    /// The material's perceptual roughness factor.
    pub roughness: f32,
}

impl MaterialExtension for KageLights {
    fn vertex_shader() -> ShaderRef {
        SHADER.into()
    }

    fn fragment_shader() -> ShaderRef {
        SHADER.into()
    }

    fn specialize(
        _pipeline: &MaterialExtensionPipeline,
        descriptor: &mut RenderPipelineDescriptor,
        _layout: &MeshVertexBufferLayoutRef,
        key: MaterialExtensionKey<Self>,
    ) -> Result<(), SpecializedMeshPipelineError> {
        let Variant { pixel, bevy_lighting } = key.bind_group_data;
        let defs = [("KAGE_PIXEL_LIGHTS", pixel), ("KAGE_BEVY_LIGHTING", bevy_lighting)];
        let defs = defs.into_iter().filter(|d| d.1).map(|d| d.0.into());
        descriptor.vertex.shader_defs.extend(defs.clone());
        if let Some(f) = descriptor.fragment.as_mut() {
            f.shader_defs.extend(defs);
        }
        Ok(())
    }
}

/// Whether the lights are shaded per pixel on this device, as `shade_on` asks.
pub(crate) fn per_pixel(shade_on: ShadeOn, adapter: Option<&RenderAdapterInfo>) -> bool {
    match shade_on {
        ShadeOn::Pixel => true,
        ShadeOn::Vertex => false,
        ShadeOn::Auto => adapter.is_none_or(|a| a.device_type != wgpu_types::DeviceType::Cpu),
    }
}

/// Puts every kage material on the variant the app needs now: per-pixel lights as
/// [`ShadeOn`] and the device say, and Bevy's lighting while Bevy has anything to light with
/// (a visible light the pack did not bake — the pack's sun is Bevy's —, ambient light, an
/// environment map or a light probe). A change re-specialises the pipeline: Bevy compiles it
/// before it draws with it.
pub(crate) fn choose_variant(
    lights: Query<
        &InheritedVisibility,
        Or<(With<PointLight>, With<SpotLight>, With<DirectionalLight>, (With<RectLight>, Without<KageLight>))>,
    >,
    global_ambient: Option<Res<GlobalAmbientLight>>,
    ambient: Query<&AmbientLight>,
    probes: Query<(), Or<(With<EnvironmentMapLight>, With<LightProbe>)>>,
    shade_on: Res<ShadeOn>,
    adapter: Option<Res<RenderAdapterInfo>>,
    mut materials: ResMut<Assets<KageMaterial>>,
) {
    let bevy_lighting = lights.iter().any(|v| v.get())
        || global_ambient.is_some_and(|a| a.brightness > 0.0)
        || ambient.iter().any(|a| a.brightness > 0.0)
        || !probes.is_empty();
    let wanted = Variant { pixel: per_pixel(*shade_on, adapter.as_deref()), bevy_lighting };
    let stale: Vec<AssetId<KageMaterial>> =
        materials.iter().filter(|(_, m)| m.extension.variant != wanted).map(|(id, _)| id).collect();
    for id in stale {
        if let Some(mut m) = materials.get_mut(id) {
            m.extension.variant = wanted;
        }
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
