//! The pack's environment light at run time: PRT's diffuse term per vertex, with the
//! self-shadowing its transfer holds and the shadows that rigid groups cast on each other
//! (`kage_runtime::prt`, the code `kage render` runs). Each frame the environment's SH
//! lighting is rotated into every group's frame as the group entity is posed now, and the
//! other groups' silhouettes are rasterised along the environment's regions again for the
//! groups that moved; a vertex's light is the PRT paper's Eq. 15 at its current position.
//! The albedo is applied per pixel (textures and the view's Fresnel as the pixel sees them).

use bevy::asset::RenderAssetUsages;
use bevy::light::Skybox;
use bevy::prelude::*;
use bevy::render::render_resource::{
    Extent3d, TextureDimension, TextureFormat, TextureViewDescriptor, TextureViewDimension,
};
use glam::{DMat3, DVec3, Vec3 as KVec3};
use kage_runtime::pack::Pack;
use kage_runtime::prt::silhouette::{Silhouette, Solid};
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

/// Texels per side of a skybox face.
pub const SKYBOX_SIZE: u32 = 256;

/// `env` as a cube map for Bevy's `Skybox` (linear RGB radiance, half floats), `size` texels
/// per face side.
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
        let c = env.background(KVec3::new(r.x, r.y, -r.z).normalize()) / env.intensity.max(f32::MIN_POSITIVE);
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
    /// The inputs of [`Self::light`], and per instance and vertex its diffuse light.
    last: Option<(Vec<u32>, Vec<Vec<KVec3>>)>,
}

impl EnvironmentShading {
    /// The environment of `pack`, if it has one with a transfer.
    pub(crate) fn new(pack: &Pack) -> Option<Self> {
        let h = pack.header.prt.as_ref()?;
        if pack.instances.iter().any(|i| i.transfer.is_none()) {
            return None;
        }
        let mut triangles = vec![Vec::new(); pack.groups.len()];
        for inst in &pack.instances {
            let at = |k: u32| inst.local.transform_point3(inst.mesh.positions[k as usize]);
            triangles[inst.group].extend(inst.mesh.triangles.iter().map(|t| t.map(at)));
        }
        let regions = if pack.groups.len() > 1 { h.regions.iter().map(Region::from).collect() } else { Vec::new() };
        Some(Self {
            order: h.order as usize,
            coeffs: h.lighting.iter().map(|c| DVec3::from_array(*c)).collect(),
            window: h.window.into(),
            regions,
            resolution: h.silhouette_resolution as usize,
            silhouettes: vec![None; triangles.len()],
            triangles,
            last: None,
        })
    }

    /// Per instance and vertex, the diffuse environment light (albedo not applied) with the
    /// groups posed at `poses` (world from group) and the environment turned by `rotation` and
    /// scaled by `intensity` from where it was baked.
    pub(crate) fn light(
        &mut self,
        pack: &Pack,
        poses: &[glam::Affine3A],
        rotation: Quat,
        intensity: f32,
    ) -> &[Vec<KVec3>] {
        let env = Placement { rotation, intensity };
        let key = key(poses, env);
        if self.last.as_ref().is_none_or(|(k, _)| *k != key) {
            let posed = self.pose(pack, poses, env);
            let light = pack
                .instances
                .iter()
                .enumerate()
                .map(|(i, inst)| instance_light(&posed, i, inst, &(poses[inst.group] * inst.local)))
                .collect();
            self.last = Some((key, light));
        }
        &self.last.as_ref().expect("just computed").1
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
/// from instance).
fn instance_light(posed: &Posed, i: usize, inst: &kage_runtime::pack::Instance, world: &glam::Affine3A) -> Vec<KVec3> {
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
            posed.radiance(own, ls, |r| posed.toward_region(i, t, r), *p, &pairs).0
        })
        .collect()
}

/// The rotation (scale removed) and mirror flag of a world-from-group linear map, as kage's
/// groups are posed: a mirror flips the group's local z.
fn rigid_frame(m: glam::Mat3) -> (DMat3, bool) {
    let mirrored = m.determinant() < 0.0;
    let z = if mirrored { -1.0 } else { 1.0 };
    let cols = [m.x_axis.normalize(), m.y_axis.normalize(), m.z_axis.normalize() * z];
    (DMat3::from_cols(cols[0].as_dvec3(), cols[1].as_dvec3(), cols[2].as_dvec3()), mirrored)
}
