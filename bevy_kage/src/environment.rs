//! The pack's environment light at run time, per vertex (`kage_runtime::prt`, the code
//! `kage render` runs):
//! - the diffuse term: the environment's SH lighting rotated into every group's frame as the
//!   group entity is posed now, less what the other groups' silhouettes along the
//!   environment's regions take (the PRT paper's Eq. 15); silhouettes are rasterised again for
//!   the groups that moved, and the albedo is applied per pixel;
//! - the specular term on glossy and metal surfaces: the map's reflection in the GGX lobe
//!   (filtered importance sampling of its mip chain) times the lobe's visible fraction from
//!   the vertex's transfer and the share of the diffuse light the other groups leave;
//! - a map's sun apart, as kage's look shades it: both terms above then carry the rest of the
//!   sky (the pack's `sunless` lighting and regions, the map without the sun's texels), and
//!   the sun is a `DirectionalLight` with shadow maps ([`KageSun`], turned and scaled with the
//!   environment by [`sync_suns`]).

use bevy::asset::RenderAssetUsages;
use bevy::light::Skybox;
use bevy::prelude::*;
use bevy::render::render_resource::{
    Extent3d, TextureDimension, TextureFormat, TextureViewDescriptor, TextureViewDimension,
};
use glam::{DMat3, DVec3, Vec3 as KVec3};
use kage_runtime::material::{Bsdf, Material};
use kage_runtime::math::ggx;
use kage_runtime::pack::Pack;
use kage_runtime::prt::glossy::{Lobe, dominant_direction};
use kage_runtime::prt::prefilter::Prefiltered;
use kage_runtime::prt::silhouette::{Silhouette, Solid};
use kage_runtime::prt::sun::Sun;
use kage_runtime::prt::{Posed, Region, Window, group_silhouettes, to_group_frame};
use rayon::prelude::*;
use std::sync::Arc;

/// The pack's environment light as the scene shows it: put on the [`crate::KageScene`] entity
/// when its pack has one. Identity and 1 show the environment as baked.
#[derive(Component, Clone, Debug, PartialEq)]
pub struct KageEnvironment {
    /// Turns the environment (and the light and shadows it casts) from where it was baked.
    pub rotation: Quat,
    /// Multiplies the environment's radiance.
    pub intensity: f32,
    /// The environment as a cube map, for a camera's `Skybox` (the pack's camera has one;
    /// [`sync_skyboxes`] turns and scales every skybox showing it as the light is).
    pub skybox: Handle<Image>,
}

impl KageEnvironment {
    /// The environment as baked, shown by `skybox`.
    pub fn new(skybox: Handle<Image>) -> Self {
        Self { rotation: Quat::IDENTITY, intensity: 1.0, skybox }
    }

    /// A camera's skybox showing this environment.
    pub fn skybox(&self) -> Skybox {
        Skybox { image: Some(self.skybox.clone()), brightness: self.intensity, rotation: self.rotation }
    }
}

/// A pack environment's sun, lit by Bevy as a `DirectionalLight` (with shadow maps) on this
/// entity, a child of the scene entity: where the environment was baked, in the pack's world.
#[derive(Component, Clone, Copy, Debug)]
pub struct KageSun(pub Sun);

impl KageSun {
    /// The light and its orientation as the scene's environment (`env`) turns and scales it.
    pub fn light(&self, env: &KageEnvironment) -> (DirectionalLight, Transform) {
        let sun = self.0.placed(glam::Quat::from_array(env.rotation.normalize().to_array()), env.intensity);
        let lux = kage_runtime::math::color::luminance(sun.irradiance);
        let c = sun.irradiance / lux.max(f32::MIN_POSITIVE);
        let light = DirectionalLight {
            color: Color::linear_rgb(c.x, c.y, c.z),
            illuminance: lux,
            shadow_maps_enabled: true,
            ..default()
        };
        let toward = crate::shade::bevy_vec(sun.direction);
        let up = if toward.y.abs() > 0.99 { Vec3::Z } else { Vec3::Y };
        (light, Transform::default().looking_to(-toward, up))
    }
}

/// Turns and scales every scene's sun with its environment.
pub(crate) fn sync_suns(
    scenes: Query<(Entity, &KageEnvironment), Changed<KageEnvironment>>,
    mut suns: Query<(&KageSun, &ChildOf, &mut DirectionalLight, &mut Transform)>,
) {
    for (scene, env) in &scenes {
        for (sun, _, mut light, mut place) in suns.iter_mut().filter(|s| s.1.parent() == scene) {
            (*light, *place) = sun.light(env);
        }
    }
}

/// Texels per side of a skybox face.
pub const SKYBOX_SIZE: u32 = 256;

/// `env` as a cube map for Bevy's `Skybox` (linear RGB radiance, its intensity and rotation
/// applied, half floats), `size` texels per face side.
pub fn skybox_image(env: &kage_runtime::pack::Environment, size: u32) -> Image {
    let n = size as usize;
    let texel = |face: usize, k: usize| {
        let (sc, tc) = (2.0 * ((k % n) as f32 + 0.5) / n as f32 - 1.0, 2.0 * ((k / n) as f32 + 0.5) / n as f32 - 1.0);
        // The cube map's direction of the texel (Vulkan's face order and orientation), and the
        // world's: Bevy samples a skybox with z negated (cube maps are left-handed).
        let r = match face {
            0 => KVec3::new(1.0, -tc, -sc),
            1 => KVec3::new(-1.0, -tc, sc),
            2 => KVec3::new(sc, 1.0, tc),
            3 => KVec3::new(sc, -1.0, -tc),
            4 => KVec3::new(sc, -tc, 1.0),
            _ => KVec3::new(-sc, -tc, -1.0),
        };
        let c = env.background(KVec3::new(r.x, r.y, -r.z).normalize());
        [c.x, c.y, c.z, 1.0].map(half::f16::from_f32)
    };
    let halves: Vec<half::f16> =
        (0..6 * n * n).into_par_iter().flat_map_iter(|k| texel(k / (n * n), k % (n * n))).collect();
    let bytes: Vec<u8> = halves.iter().flat_map(|h| h.to_le_bytes()).collect();
    let extent = Extent3d { width: size, height: size, depth_or_array_layers: 6 };
    let mut image =
        Image::new(extent, TextureDimension::D2, bytes, TextureFormat::Rgba16Float, RenderAssetUsages::RENDER_WORLD);
    image.texture_view_descriptor =
        Some(TextureViewDescriptor { dimension: Some(TextureViewDimension::Cube), ..default() });
    image
}

/// Turns and scales every camera's skybox that shows a scene's environment as the
/// environment's [`KageEnvironment`] says.
pub(crate) fn sync_skyboxes(
    scenes: Query<&KageEnvironment, Changed<KageEnvironment>>,
    mut skyboxes: Query<&mut Skybox>,
) {
    for env in &scenes {
        for mut s in skyboxes.iter_mut().filter(|s| s.image.as_ref() == Some(&env.skybox)) {
            s.rotation = env.rotation;
            s.brightness = env.intensity;
        }
    }
}

/// How the environment is turned and scaled from where it was baked.
#[derive(Clone, Copy)]
struct Placement {
    rotation: Quat,
    intensity: f32,
}

/// What shading a pack's environment needs besides the pack, and what it last computed.
pub(crate) struct EnvironmentShading {
    /// SH order of the transfer.
    order: usize,
    /// The baked world lighting (n² RGB coefficients).
    coeffs: Vec<DVec3>,
    window: Window,
    /// The regions as baked (empty when shadows between groups are off: one group).
    regions: Vec<Region>,
    /// Silhouette texels per side.
    resolution: usize,
    /// Per group: its instances' triangles in the group's frame.
    triangles: Vec<Vec<[KVec3; 3]>>,
    /// Per group: the pose and environment its silhouettes were rasterised for, and them.
    silhouettes: Vec<Option<(Vec<u32>, Arc<Vec<Silhouette>>)>>,
    /// The map's mip chain as baked (placed at baked rotation and intensity).
    chain: Prefiltered,
    /// The lobe's visible fraction at the transfer's order.
    lobe: Lobe,
    /// The map's sun where it was baked, when the pack shades it apart.
    pub(crate) sun: Option<Sun>,
    /// The groups' and the environment's placement the diffuse light was computed for, and it.
    last: Option<(Vec<u32>, Lit)>,
    /// The same and the eye the specular term was computed for, and the light toward it.
    shaded: Option<(Vec<u32>, Vec<Vec<(KVec3, KVec3)>>)>,
}

/// The diffuse environment light of the groups as last posed.
struct Lit {
    /// Per instance and vertex: the diffuse light (albedo not applied) and the share of it
    /// the other groups leave.
    vertices: Vec<Vec<(KVec3, f32)>>,
    /// Per group: world-from-group rotation and mirror flag.
    frames: Vec<(DMat3, bool)>,
}

impl EnvironmentShading {
    /// The environment of `pack`, if it has one with a transfer.
    pub(crate) fn new(pack: &Pack) -> Option<Self> {
        let (h, env) = (pack.header.prt.as_ref()?, pack.environment.as_ref()?);
        if pack.instances.iter().any(|i| i.transfer.is_none()) {
            return None;
        }
        let mut triangles = vec![Vec::new(); pack.groups.len()];
        for inst in &pack.instances {
            let at = |k: u32| inst.local.transform_point3(inst.mesh.positions[k as usize]);
            triangles[inst.group].extend(inst.mesh.triangles.iter().map(|t| t.map(at)));
        }
        // A pack that records the sky without its sun has it split off as kage's look does.
        let split = h.sunless.as_ref().and_then(|_| kage_runtime::prt::sun::split(env.width, env.height, &env.texels));
        let (lighting, regions) = match (&h.sunless, &split) {
            (Some(rest), Some(_)) => (&rest.lighting, &rest.regions),
            _ => (&h.lighting, &h.regions),
        };
        let regions = if pack.groups.len() > 1 { regions.iter().map(Region::from).collect() } else { Vec::new() };
        let texels = split.as_ref().map_or_else(|| env.texels.clone(), |(_, rest)| rest.clone());
        let chain = Prefiltered::new(env.width, env.height, texels, env.intensity, env.rotation);
        let baked = glam::Quat::from_rotation_y(env.rotation);
        Some(Self {
            lobe: Lobe::new(h.order as usize, h.window.into()),
            chain,
            sun: split.map(|(sun, _)| sun.placed(baked, env.intensity)),
            order: h.order as usize,
            coeffs: lighting.iter().map(|c| DVec3::from_array(*c)).collect(),
            window: h.window.into(),
            regions,
            resolution: h.silhouette_resolution as usize,
            silhouettes: vec![None; triangles.len()],
            triangles,
            last: None,
            shaded: None,
        })
    }

    /// Per instance and vertex, the environment's light toward `eye`: the diffuse light
    /// (albedo not applied: the pixel's multiplies it) and the specular term (radiance), with
    /// the groups posed at `poses` (world from group) and the environment turned by `rotation`
    /// and scaled by `intensity` from where it was baked.
    pub(crate) fn light(
        &mut self,
        pack: &Pack,
        poses: &[glam::Affine3A],
        eye: KVec3,
        rotation: Quat,
        intensity: f32,
    ) -> &[Vec<(KVec3, KVec3)>] {
        let env = Placement { rotation, intensity };
        let key = key(poses, env);
        let toward: Vec<u32> = key.iter().copied().chain(eye.to_array().map(f32::to_bits)).collect();
        if self.shaded.as_ref().is_some_and(|(k, _)| *k == toward) {
            return &self.shaded.as_ref().expect("just checked").1;
        }
        if self.last.as_ref().is_none_or(|(k, _)| *k != key) {
            let posed = self.pose(pack, poses, env);
            let vertices = pack
                .instances
                .iter()
                .enumerate()
                .map(|(i, inst)| instance_light(&posed, i, inst, &(poses[inst.group] * inst.local)))
                .collect();
            self.last = Some((key, Lit { vertices, frames: posed.frames }));
        }
        let lit = &self.last.as_ref().expect("just computed").1;
        let (to_map, baked) = self.chain.placement();
        let turn = glam::Quat::from_array(rotation.normalize().to_array());
        let chain = self.chain.placed(to_map * turn.inverse(), baked * intensity);
        let specular = Specular { chain: &chain, lobe: &self.lobe, eye };
        let shaded = pack
            .instances
            .iter()
            .zip(&lit.vertices)
            .map(|(inst, diffuse)| {
                let frame = lit.frames[inst.group];
                specular.instance(inst, &(poses[inst.group] * inst.local), frame, diffuse)
            })
            .collect();
        &self.shaded.insert((toward, shaded)).1
    }

    /// The lighting posed into every group, the silhouettes of the groups that moved
    /// rasterised again.
    fn pose(&mut self, pack: &Pack, poses: &[glam::Affine3A], env: Placement) -> Posed {
        let turn = glam::DQuat::from_array(env.rotation.normalize().to_array().map(f64::from));
        let coeffs: Vec<DVec3> = to_group_frame(&self.coeffs, DMat3::from_quat(turn.inverse()), false)
            .into_iter()
            .map(|c| c * env.intensity as f64)
            .collect();
        let regions: Vec<Region> = self
            .regions
            .iter()
            .map(|r| Region {
                power: r.power * env.intensity as f64,
                dir: (turn * r.dir.as_dvec3()).as_vec3().normalize(),
                ..*r
            })
            .collect();
        let silhouettes = if regions.is_empty() { Vec::new() } else { self.silhouettes(poses, env, &regions) };
        let frames = poses.iter().map(|p| rigid_frame(p.matrix3.into())).collect();
        let group_of = pack.instances.iter().map(|i| i.group).collect();
        Posed::new(self.order, &coeffs, self.window, regions, frames, group_of, silhouettes)
    }

    /// One silhouette list per group, rasterised again where the group or the environment
    /// turned or moved.
    fn silhouettes(
        &mut self,
        poses: &[glam::Affine3A],
        env: Placement,
        regions: &[Region],
    ) -> Vec<Arc<Vec<Silhouette>>> {
        let (triangles, res) = (&self.triangles, self.resolution);
        self.silhouettes
            .par_iter_mut()
            .enumerate()
            .map(|(g, kept)| {
                let key = key(&poses[g..=g], env);
                match kept {
                    Some((k, s)) if *k == key => s.clone(),
                    _ => {
                        let world: Vec<[KVec3; 3]> =
                            triangles[g].iter().map(|t| t.map(|p| poses[g].transform_point3(p))).collect();
                        let s = Arc::new(group_silhouettes(&world, &Solid, regions, res));
                        *kept = Some((key, s.clone()));
                        s
                    }
                }
            })
            .collect()
    }
}

/// The bits of the poses and the environment.
fn key(poses: &[glam::Affine3A], env: Placement) -> Vec<u32> {
    let mut k: Vec<u32> = poses.iter().flat_map(|p| p.to_cols_array()).map(f32::to_bits).collect();
    k.extend(env.rotation.to_array().into_iter().chain([env.intensity]).map(f32::to_bits));
    k
}

/// The diffuse environment light at every vertex of instance `i`, placed at `world` (world
/// from instance), and the share of it the other groups leave.
fn instance_light(
    posed: &Posed,
    i: usize,
    inst: &kage_runtime::pack::Instance,
    world: &glam::Affine3A,
) -> Vec<(KVec3, f32)> {
    let transfer = inst.transfer.as_deref().expect("checked when the shading was made");
    let n2 = transfer.len() / inst.mesh.positions.len().max(1);
    let points: Vec<KVec3> = inst.mesh.positions.iter().map(|p| world.transform_point3(*p)).collect();
    let (lo, hi) = points.iter().fold((KVec3::MAX, KVec3::MIN), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    let pairs = posed.pairs_reaching(0.5 * (lo + hi), 0.5 * (hi - lo).length());
    let own = posed.group_of[i];
    points
        .par_iter()
        .enumerate()
        .map(|(v, p)| {
            let t = &transfer[v * n2..(v + 1) * n2];
            let ls = posed.diffuse(i, t);
            posed.radiance(own, ls, |r| posed.toward_region(i, t, r), *p, &pairs)
        })
        .collect()
}

/// The environment's specular term toward an eye.
struct Specular<'a> {
    /// The map's chain, placed as the environment is now.
    chain: &'a Prefiltered,
    lobe: &'a Lobe,
    eye: KVec3,
}

impl Specular<'_> {
    /// Every vertex of `inst` placed at `world`, its group's frame `frame`: its `diffuse`
    /// light and that light's radiance toward the eye with the specular term added.
    fn instance(
        &self,
        inst: &kage_runtime::pack::Instance,
        world: &glam::Affine3A,
        (rot, mirrored): (DMat3, bool),
        diffuse: &[(KVec3, f32)],
    ) -> Vec<(KVec3, KVec3)> {
        let material = Material::from(&inst.material);
        let alpha = ggx::alpha_from_roughness(material.roughness);
        let normals = world.matrix3.inverse().transpose();
        let transfer = inst.transfer.as_deref().expect("checked when the shading was made");
        let n2 = transfer.len() / inst.mesh.positions.len().max(1);
        let local = |w: KVec3| {
            let g = rot.transpose() * w.as_dvec3();
            if mirrored { DVec3::new(g.x, g.y, -g.z) } else { g }
        };
        (0..inst.mesh.positions.len())
            .into_par_iter()
            .map(|v| {
                let (light, open) = diffuse[v];
                let p = world.transform_point3(inst.mesh.positions[v]);
                let n = KVec3::from(normals * glam::Vec3A::from(inst.mesh.normals[v])).normalize_or_zero();
                let wo = (self.eye - p).normalize_or_zero();
                let mu = n.dot(wo);
                let bsdf = Bsdf::new(&material, KVec3::new(0.0, 0.0, mu));
                if mu <= 0.0 || !bsdf.has_specular() {
                    return (light, KVec3::ZERO);
                }
                let d = dominant_direction(n, 2.0 * mu * n - wo, alpha);
                let t: Vec<f64> = transfer[v * n2..][..self.lobe.coeffs()].iter().map(|c| *c as f64).collect();
                let visible = self.lobe.visible_fraction(&t, local(n), local(d), alpha);
                (light, self.chain.reflect(n, wo, alpha, bsdf.f0(), bsdf.f90()) * visible * open)
            })
            .collect()
    }
}

/// The rotation (scale removed) and mirror flag of a world-from-group linear map, as kage's
/// groups are posed: a mirror flips the group's local z.
fn rigid_frame(m: glam::Mat3) -> (DMat3, bool) {
    let mirrored = m.determinant() < 0.0;
    let z = if mirrored { -1.0 } else { 1.0 };
    let cols = [m.x_axis.normalize(), m.y_axis.normalize(), m.z_axis.normalize() * z];
    (DMat3::from_cols(cols[0].as_dvec3(), cols[1].as_dvec3(), cols[2].as_dvec3()), mirrored)
}
