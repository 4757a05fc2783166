//! Spawning a pack: one entity per rigid group (its pose), its mesh instances (real
//! materials) and lights as children, and the pack's camera. Rectangular lights become Bevy
//! `RectLight`s (local XY plane, emitting toward −Z), other polygons a [`KageLight`] with its
//! polygon; either way the plugin, not Bevy, lights with them ([`keep_baked_lights_out`]).

use crate::environment::{KageEnvironment, KageSun};
use crate::loader::KagePack;
use crate::material::{KageLights, KageMaterial, KageParams, Variant};
use crate::shade::{self, Shading};
use bevy::asset::{LoadState, RenderAssetUsages};
use bevy::camera::primitives::{Aabb, MeshAabb};
use bevy::camera::visibility::ViewVisibility;
use bevy::mesh::{Indices, PrimitiveTopology};
use bevy::prelude::*;
use bevy::render::storage::ShaderBuffer;
use bevy::world_serialization::{WorldAsset, WorldAssetRoot};
use kage_runtime::camera::{self, Camera};
use kage_runtime::pack::{self, Pack};

/// Spawns the pack `pack` as this entity's children once it has loaded; with `camera`, the
/// pack's camera too.
#[derive(Component, Clone)]
pub struct KageScene {
    /// The pack.
    pub pack: Handle<KagePack>,
    /// Whether to spawn the pack's camera.
    pub camera: bool,
}

impl KageScene {
    /// The pack `pack`, with its camera.
    pub fn new(pack: Handle<KagePack>) -> Self {
        Self { pack, camera: true }
    }
}

/// A rigid group of a spawned pack: its index in the pack.
#[derive(Component, Clone, Copy, Debug)]
pub struct KageGroup(pub usize);

/// A mesh instance of a spawned pack: its index in the pack.
#[derive(Component, Clone, Copy, Debug)]
pub struct KageInstance(pub usize);

/// A baked polygonal light: its index in the pack, and its shape. A rectangle's size and
/// radiance are its `RectLight`'s; any other polygon's are held here.
#[derive(Component, Clone, Debug)]
pub struct KageLight {
    /// The light's index in the pack.
    pub index: usize,
    /// The polygon in the entity's frame (empty for a `RectLight`).
    pub polygon: Vec<Vec3>,
    /// Linear radiance (for a `RectLight`, its colour and intensity give it).
    pub radiance: LinearRgba,
}

/// The camera a pack spawned.
#[derive(Component, Clone, Copy, Debug)]
pub struct KageCamera;

/// Marks a scene whose pack failed to load (the error was logged once; the file is shown as a
/// plain glTF instead).
#[derive(Component)]
pub(crate) struct Failed;

/// A kage `Affine3A` as a Bevy transform.
pub(crate) fn transform(a: &glam::Affine3A) -> Transform {
    Transform::from_matrix(Mat4::from_cols_array(&glam::Mat4::from(*a).to_cols_array()))
}

/// Spawns every [`KageScene`] whose pack has loaded.
pub(crate) fn spawn_scenes(
    mut commands: Commands,
    scenes: Query<(Entity, &KageScene), (Without<Shading>, Without<Failed>)>,
    packs: Res<Assets<KagePack>>,
    server: Res<AssetServer>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<KageMaterial>>,
    mut emitters: ResMut<Assets<StandardMaterial>>,
    mut buffers: ResMut<Assets<ShaderBuffer>>,
    mut images: ResMut<Assets<Image>>,
) {
    for (entity, scene) in &scenes {
        if let Some(LoadState::Failed(e)) = server.get_load_state(&scene.pack) {
            error!("{e}: shown as a plain glTF, without kage's shading");
            commands.entity(entity).insert(Failed);
            if let Some(path) = scene.pack.path() {
                let plain = server.load::<WorldAsset>(path.clone().with_label("Scene0"));
                commands.spawn((WorldAssetRoot(plain), ChildOf(entity)));
            }
            continue;
        }
        let Some(loaded) = packs.get(&scene.pack) else { continue };
        let pack = loaded.pack.clone();
        let environment = pack.environment.as_ref().map(|e| {
            KageEnvironment::new(images.add(crate::environment::skybox_image(e, crate::environment::SKYBOX_SIZE)))
        });
        let terms = shade::Terms::new(&pack, &mut buffers);
        let mut spawner = Spawner { commands: &mut commands, meshes: &mut meshes, emitters: &mut emitters };
        let groups: Vec<Entity> = pack
            .groups
            .iter()
            .enumerate()
            .map(|(g, group)| {
                let named =
                    (Name::new(group.name.clone()), KageGroup(g), transform(&group.pose), Visibility::default());
                spawner.commands.spawn(named).insert(ChildOf(entity)).id()
            })
            .collect();
        let instances = (0..pack.instances.len())
            .map(|i| {
                let material = materials.add(material(loaded, i, &terms));
                spawner.instance(&pack, i, groups[pack.instances[i].group], material)
            })
            .collect();
        let lights = (0..pack.lights.len()).map(|l| spawner.light(&pack, l, groups[pack.lights[l].group])).collect();
        if scene.camera
            && let Some(c) = &pack.camera
        {
            spawner.camera(c, pack.header.preview_exposure, entity, environment.as_ref());
        }
        let shading = Shading::new(pack.clone(), groups, instances, lights, terms);
        if let (Some(sun), Some(env)) = (shading.sun(), &environment) {
            let sun = KageSun(sun);
            let (light, place) = sun.light(env);
            commands.spawn((sun, light, place, sun_cascades(&pack), ChildOf(entity)));
        }
        commands.entity(entity).insert(shading);
        if let Some(e) = environment {
            commands.entity(entity).insert(e);
        }
    }
}

/// One shadow cascade over the whole pack, seen from its camera (or from anywhere near it):
/// a scene kage bakes is small enough for one map, and one map keeps shadows alike across
/// the view.
fn sun_cascades(pack: &Pack) -> bevy::light::CascadeShadowConfig {
    let points = pack.instances.iter().flat_map(|i| {
        let world = pack.groups[i.group].pose * i.local;
        i.mesh.positions.iter().map(move |p| world.transform_point3(*p))
    });
    let (lo, hi) = points.fold((glam::Vec3::MAX, glam::Vec3::MIN), |(lo, hi), p| (lo.min(p), hi.max(p)));
    // A pack without meshes casts nothing: any cascade will do.
    let (lo, hi) = if lo.cmple(hi).all() { (lo, hi) } else { (glam::Vec3::ZERO, glam::Vec3::ZERO) };
    let (centre, radius) = (0.5 * (lo + hi), (0.5 * (hi - lo).length()).max(1e-3));
    let eye = pack.camera.as_ref().map_or(centre, |c| c.world.translation.into());
    let reach = (eye - centre).length() + radius;
    bevy::light::CascadeShadowConfigBuilder {
        num_cascades: 1,
        minimum_distance: 0.01 * reach,
        maximum_distance: reach,
        ..default()
    }
    .build()
}

/// Instance `i`'s material: its real material's factors and textures, kage's lights added.
fn material(loaded: &KagePack, i: usize, terms: &shade::Terms) -> KageMaterial {
    let m = &loaded.pack.instances[i].material;
    let image = |s: &Option<pack::schema::TextureSlot>, space: usize| {
        s.as_ref().and_then(|s| loaded.images.get(s.index as usize)).and_then(|i| i[space].clone())
    };
    let channel = |s: &Option<pack::schema::TextureSlot>| match s {
        Some(s) if s.tex_coord == 1 => bevy::mesh::UvChannel::Uv1,
        _ => bevy::mesh::UvChannel::Uv0,
    };
    let uv_transform = m
        .base_color_texture
        .as_ref()
        .map_or(bevy::math::Affine2::IDENTITY, |s| bevy::math::Affine2::from_cols_array(&s.transform));
    let [r, g, b] = m.base_color;
    let mut base = StandardMaterial {
        base_color: Color::linear_rgb(r, g, b),
        base_color_texture: image(&m.base_color_texture, 0),
        base_color_channel: channel(&m.base_color_texture),
        metallic: m.metallic,
        perceptual_roughness: m.roughness,
        metallic_roughness_texture: image(&m.metallic_roughness_texture, 1),
        metallic_roughness_channel: channel(&m.metallic_roughness_texture),
        // F0 = 0.16 · reflectance² = 0.04 · specular.
        reflectance: 0.5 * m.specular.max(0.0).sqrt(),
        uv_transform,
        ..default()
    };
    if let Some(c) = &m.cutout {
        base.alpha_mode = AlphaMode::Mask(c.cutoff);
        base.base_color.set_alpha(c.factor);
    }
    let params = KageParams { first: terms.first[i], lights: 0, specular: m.specular, roughness: m.roughness };
    let extension = KageLights {
        params,
        vertices: terms.vertices.clone(),
        lights: terms.lights.clone(),
        tables: terms.tables.clone(),
        variant: Variant::default(),
    };
    KageMaterial { base, extension }
}

/// What spawning adds to.
struct Spawner<'a, 'w, 's> {
    commands: &'a mut Commands<'w, 's>,
    meshes: &'a mut Assets<Mesh>,
    emitters: &'a mut Assets<StandardMaterial>,
}

impl Spawner<'_, '_, '_> {
    /// Instance `i` under `group`.
    fn instance(&mut self, pack: &Pack, i: usize, group: Entity, material: Handle<KageMaterial>) -> Entity {
        let inst = &pack.instances[i];
        let (mesh, bounds) = self.add(mesh(&inst.mesh));
        let parts = (Name::new(inst.name.clone()), KageInstance(i), transform(&inst.local));
        self.commands.spawn((parts, Mesh3d(mesh), MeshMaterial3d(material), bounds)).insert(ChildOf(group)).id()
    }

    /// `mesh` added to the assets, with its box: its data lives in the render world only, where
    /// Bevy cannot measure it, and without a box a mesh casts no directional shadow.
    fn add(&mut self, mesh: Mesh) -> (Handle<Mesh>, Aabb) {
        let bounds = mesh.compute_aabb().unwrap_or_default();
        (self.meshes.add(mesh), bounds)
    }

    /// Light `l` under `group`: a `RectLight` when it is a rectangle, its polygon otherwise;
    /// either with its emitting polygon drawn, and its back black as kage draws it (a panel
    /// that also casts the sun's shadow, as kage's shadow rays meet either side).
    fn light(&mut self, pack: &Pack, l: usize, group: Entity) -> Entity {
        let light = &pack.lights[l];
        let radiance = LinearRgba::rgb(light.radiance.x, light.radiance.y, light.radiance.z);
        let emitter = self.emitters.add(StandardMaterial { base_color: Color::BLACK, emissive: radiance, ..default() });
        let back = self.emitters.add(StandardMaterial { base_color: Color::BLACK, unlit: true, ..default() });
        let name = Name::new(light.name.clone());
        match shade::rectangle(&light.polygon) {
            Some(r) => {
                let at = transform(&(light.local * r.frame));
                let luminance = kage_runtime::math::luminance(light.radiance);
                let rect = RectLight {
                    color: Color::LinearRgba(radiance * (1.0 / luminance.max(f32::MIN_POSITIVE))),
                    intensity: luminance * r.width * r.height * std::f32::consts::PI,
                    range: f32::MAX,
                    width: r.width,
                    height: r.height,
                };
                let marker = KageLight { index: l, polygon: Vec::new(), radiance };
                let quad = self.meshes.add(Rectangle::new(r.width, r.height));
                // Bevy's rectangle faces +Z; the light emits toward −Z.
                let face = Transform::from_rotation(Quat::from_rotation_y(std::f32::consts::PI));
                self.commands
                    .spawn((name, rect, marker, at))
                    .with_child((Mesh3d(quad.clone()), MeshMaterial3d(emitter), face))
                    .with_child((Mesh3d(quad), MeshMaterial3d(back), Transform::IDENTITY))
                    .insert(ChildOf(group))
                    .id()
            }
            None => {
                let polygon: Vec<Vec3> = light.polygon.iter().map(|p| Vec3::from_array(p.to_array())).collect();
                let (front, bounds) = self.add(fan(&polygon));
                let (behind, _) = self.add(fan(&polygon.iter().rev().copied().collect::<Vec<_>>()));
                let marker = KageLight { index: l, polygon, radiance };
                let parts = (name, marker, transform(&light.local), Visibility::default());
                self.commands
                    .spawn(parts)
                    .with_child((Mesh3d(front), MeshMaterial3d(emitter), Transform::IDENTITY, bounds))
                    .with_child((Mesh3d(behind), MeshMaterial3d(back), Transform::IDENTITY, bounds))
                    .insert(ChildOf(group))
                    .id()
            }
        }
    }

    /// The pack's camera, its exposure the preview's; tonemapped with ACES (which needs no
    /// lookup tables, so no Bevy feature beyond the plugin's).
    fn camera(&mut self, c: &Camera, exposure_stops: f32, parent: Entity, env: Option<&KageEnvironment>) {
        let exposure = bevy::camera::Exposure { ev100: exposure_ev100(exposure_stops) };
        let tonemapping = bevy::core_pipeline::tonemapping::Tonemapping::AcesFitted;
        let camera = (Camera3d::default(), camera_view(c), exposure, tonemapping, KageCamera, ChildOf(parent));
        let mut camera = self.commands.spawn(camera);
        if let Some(e) = env {
            camera.insert(e.skybox());
        }
    }
}

/// A pack camera's place and projection.
pub fn camera_view(c: &Camera) -> (Transform, Projection) {
    let projection = match c.projection {
        camera::Projection::Perspective { yfov } => {
            Projection::Perspective(PerspectiveProjection { fov: yfov, near: 0.01, ..default() })
        }
        camera::Projection::Orthographic { ymag } => Projection::Orthographic(OrthographicProjection {
            scaling_mode: bevy::camera::ScalingMode::FixedVertical { viewport_height: 2.0 * ymag },
            ..OrthographicProjection::default_3d()
        }),
    };
    (transform(&c.world), projection)
}

/// Bevy's EV100 that shows kage's radiance times 2^`stops` (Bevy's exposure is
/// 1 / (1.2 · 2^EV100)).
pub fn exposure_ev100(stops: f32) -> f32 {
    -stops - 1.2f32.log2()
}

/// A pack mesh as a Bevy mesh: positions, normals, UV sets, the source's vertex colours.
fn mesh(m: &pack::Mesh) -> Mesh {
    let v3 = |v: &[glam::Vec3]| v.iter().map(|p| p.to_array()).collect::<Vec<[f32; 3]>>();
    let v2 = |v: &[glam::Vec2]| v.iter().map(|p| p.to_array()).collect::<Vec<[f32; 2]>>();
    let mut mesh = Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::RENDER_WORLD)
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, v3(&m.positions))
        .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, v3(&m.normals))
        .with_inserted_indices(Indices::U32(m.triangles.iter().flatten().copied().collect()));
    if !m.uvs.is_empty() {
        mesh.insert_attribute(Mesh::ATTRIBUTE_UV_0, v2(&m.uvs));
    }
    if !m.uvs1.is_empty() {
        mesh.insert_attribute(Mesh::ATTRIBUTE_UV_1, v2(&m.uvs1));
    }
    if !m.colors.is_empty() {
        let colors: Vec<[f32; 4]> = m.colors.iter().map(|c| c.extend(1.0).to_array()).collect();
        mesh.insert_attribute(Mesh::ATTRIBUTE_COLOR, colors);
    }
    mesh
}

/// A convex polygon as a triangle fan (its emitting side counter-clockwise).
fn fan(points: &[Vec3]) -> Mesh {
    let normal = shade::bevy_vec(
        kage_runtime::light::normal_area(&points.iter().map(|p| shade::kage_vec(*p)).collect::<Vec<_>>()).0,
    );
    let indices = (1..points.len() as u32 - 1).flat_map(|i| [0, i, i + 1]).collect();
    Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::RENDER_WORLD)
        .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, points.iter().map(|p| p.to_array()).collect::<Vec<_>>())
        .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, vec![normal.to_array(); points.len()])
        .with_inserted_indices(Indices::U32(indices))
}

/// Keeps baked lights out of Bevy's own lighting: after visibility is computed, their
/// `RectLight`s are hidden from every view, so Bevy does not extract them (the plugin shades
/// them from the trees).
pub(crate) fn keep_baked_lights_out(mut lights: Query<&mut ViewVisibility, (With<KageLight>, With<RectLight>)>) {
    for mut v in &mut lights {
        *v = ViewVisibility::HIDDEN;
    }
}

/// Warns once that Bevy lights area lights the pack did not bake as usual: without kage's
/// shadows.
pub(crate) fn warn_unbaked_lights(
    added: Query<&Name, (Added<RectLight>, Without<KageLight>)>,
    scenes: Query<(), With<Shading>>,
    mut warned: Local<bool>,
) {
    if *warned || scenes.is_empty() {
        return;
    }
    if let Some(name) = added.iter().next() {
        warn!("{name}: a RectLight the pack did not bake is lit by Bevy as usual, without kage's shadows");
        *warned = true;
    }
}
