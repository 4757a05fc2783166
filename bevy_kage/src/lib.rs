//! # bevy_kage
//!
//! kage's baked shadows in Bevy 0.19: a pack (`kage export SCENE -o PACK.glb`) loads as an
//! asset ([`KagePack`]), and a [`KageScene`] entity spawns it — its rigid groups, mesh instances
//! with their real materials, lights, camera and environment. Every frame the plugin shades
//! the pack's polygonal lights from the baked BSPVT visibility trees wherever the light
//! entities are now, and its environment from the baked PRT transfer wherever the groups are
//! and however the environment is turned: moving or resizing a light moves its shadows,
//! moving a group moves the environment's shadows it casts, with no bake.
//!
//! ## Design
//! - **Reading** is `kage-runtime`'s ([`kage_runtime::pack::Pack::read`]): integrity verified,
//!   every number range-checked; a pack that fails is logged and spawns nothing.
//! - **Per vertex, on the CPU** ([`shade`]): at every vertex and for every light, the diffuse
//!   and specular lobes' shadowed and unshadowed LTC integrals through the trees
//!   (`kage_runtime::bspvt::shade`, the code `kage render` runs), in the group's baked frame so
//!   that a moved group keeps its own shadows. Recomputed only when a light, a group or the
//!   camera moved.
//! - **Per pixel, on the GPU** ([`material`]): a `StandardMaterial` extension evaluates each
//!   light's LTC at the pixel and scales it by the visible fraction interpolated from the
//!   vertices — the WGSL is kage's viewport's (`shaders/pixel_lights.wgsl`, `ltc.wgsl`), so
//!   highlights are as sharp as the lobe. Bevy's own lights, ambient light and environment
//!   maps light the same materials as usual.
//! - **The environment** ([`environment`]): PRT's diffuse light with the shadows groups cast
//!   on each other, and the reflection on glossy and metal surfaces, per vertex
//!   (`kage_runtime::prt`, the code `kage render` runs); a map's sun split off and lit by Bevy
//!   as a shadowed `DirectionalLight` ([`KageSun`]); the map as the camera's skybox.
//! - **The bounce** is the pack's, frozen where the lights and groups were baked: its light
//!   per vertex times the pixel's diffuse albedo.
//!
//! ## Guarantees
//! - A baked light is lit once, by the plugin: its `RectLight` is kept out of Bevy's
//!   lighting (hidden from every view after visibility is computed), so Bevy's area-light
//!   LTC does not add it again.
//! - Units: kage's radiance is Bevy's luminance (cd/m²) one to one; a `RectLight`'s
//!   `intensity` is its luminous power, `radiance · width · height · π`, as Bevy defines it.
//! - The per-vertex work is deterministic (the same inputs, the same buffers, on any thread
//!   count).

// Bevy systems take their queries and resources as arguments: long signatures are the idiom.
#![allow(clippy::type_complexity, clippy::too_many_arguments)]

pub mod environment;
pub mod headless;
pub mod loader;
pub mod material;
pub mod shade;
pub mod spawn;

pub use environment::{KageEnvironment, KageSun};
pub use loader::{KagePack, KagePackLoader};
pub use material::KageMaterial;
pub use shade::{KageStats, ShadeOn};
pub use spawn::{KageGroup, KageInstance, KageLight, KageScene};

use bevy::camera::visibility::VisibilitySystems;
use bevy::prelude::*;
use bevy::transform::TransformSystems;

/// The plugin: the pack asset and its loader, the material, spawning and per-frame shading.
#[derive(Default)]
pub struct KagePlugin {
    /// Where the baked lights are shaded (also a resource, changeable at run time).
    pub shade_on: ShadeOn,
}

impl Plugin for KagePlugin {
    fn build(&self, app: &mut App) {
        app.init_asset::<KagePack>()
            .insert_resource(self.shade_on)
            .init_resource::<shade::KageStats>()
            .init_asset_loader::<KagePackLoader>()
            .add_plugins(MaterialPlugin::<KageMaterial>::default())
            .add_systems(
                Update,
                (spawn::spawn_scenes, spawn::warn_unbaked_lights, environment::sync_skyboxes, environment::sync_suns),
            )
            .add_systems(PostUpdate, shade::shade_lights.after(TransformSystems::Propagate))
            .add_systems(PostUpdate, material::choose_variant.after(VisibilitySystems::VisibilityPropagate))
            .add_systems(
                PostUpdate,
                spawn::keep_baked_lights_out.after(VisibilitySystems::MarkNewlyHiddenEntitiesInvisible),
            );
        material::register_shader(app);
    }
}
