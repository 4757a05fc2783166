//! PRT for dynamic scenes (Tamura, Johan & Nishita; `docs/references.md`, `docs/prt.md`):
//! diffuse surfaces under an environment light, the scene split into rigid groups.
//!
//! - [`transfer`]: per vertex, the self-shadowed diffuse transfer in SH, in its group's frame
//!   (albedo left out), so a bake depends on the group's own geometry alone and survives any
//!   move or rotation of the group;
//! - [`lighting`]: the environment's SH coefficients (exact texel solid angles), the window
//!   against ringing, and their rotation into each group's frame every frame;
//! - [`regions`]: the environment as q area lights (power `B_i`, direction `w_i`, `Ω_i`);
//! - [`silhouette`]: each other group's silhouette along `w_i`, box-filtered per receiver
//!   (the run time's, as is [`Posed`]: the lighting posed into the groups, and Eq. 15);
//! - [`budget`]: SH order, region count and window chosen from an error budget.
//!
//! Per frame ([`Frame::prepare`]): `L(p) = ρ · max(0, Ls(p) − Σ_i B_i T(p, w_i) V_o(p, w_i))`
//! (the PRT paper's Eq. 15), where `Ls` and `T(p, w_i)` are windowed SH reconstructions from the vertex
//! transfer, interpolated across triangles, and `V_o` combines the other groups as
//! `1 − Π_o (1 − V_o)`. Images evaluate `V_o` per pixel; `--vertices-out` per vertex.

pub mod budget;
pub mod glossy;
pub mod lighting;
pub mod prefilter;
pub mod regions;
pub mod sun;
pub mod transfer;

pub use kage_runtime::prt::{Posed, group_silhouettes, silhouette};

use crate::accel::SceneBvh;
use crate::material::albedo;
use crate::math::sh;
use crate::raster::{self, Primary, SurfaceHit};
use crate::scene::VertexValues;
use crate::scene::{FlatScene, Holes, InGroup, PrimitiveId, RigidGroup, Scene, Transform, group_triangles};
use glam::{Affine3A, DMat3, Vec3};
use lighting::{NegativeLobes, RgbCoeffs, Window};
use rayon::prelude::*;
use regions::Region;
use silhouette::Silhouette;
use std::collections::HashMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

/// Version of the transfer bake's algorithm: part of every bake key (2: what touches a ray's
/// start does not block it, see [`crate::accel::touching_distance`]).
pub const ALGORITHM_VERSION: u32 = 2;

/// Seed of the shared direction set (fixed: the bake depends on its parameters only).
const DIRECTION_SEED: u64 = 0x0050_5254;

/// PRT parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// SH order n (bands 0..n−1, n² coefficients).
    pub order: usize,
    /// Directions per vertex for the transfer (rounded down to a square, for stratification).
    pub directions: usize,
    /// Environment regions q for shadows between groups.
    pub regions: usize,
    /// Window applied to `Ls` and `T(p, w_i)` alike.
    pub window: Window,
    /// Silhouette resolution (texels per side).
    pub silhouette_res: usize,
}

impl Default for Settings {
    fn default() -> Self {
        Self { order: 4, directions: 1024, regions: 32, window: Window::Hanning, silhouette_res: 128 }
    }
}

pub use kage_runtime::pack::ranges::{DIRECTION_COUNTS, ORDERS, REGION_COUNTS, SILHOUETTE_RESOLUTIONS};

impl Settings {
    /// Checks every parameter against its documented range (a pack may declare any numbers;
    /// work and memory are sized by them).
    pub fn check(&self) -> Result<(), String> {
        kage_runtime::pack::ranges::prt_settings(self.order, self.regions, self.directions, self.silhouette_res)
    }

    /// Side of the stratified direction grid.
    pub fn direction_side(&self) -> usize {
        ((self.directions as f64).sqrt() as usize).max(1)
    }
}

/// Statistics of a transfer bake.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stats {
    /// Vertices baked.
    pub vertices: usize,
    /// Bytes of transfer data.
    pub bytes: usize,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// Self-transfer of every instance: vertex `v` of instance `i` is
/// `instances[i][v·n² .. (v+1)·n²]`, in its group's frame.
#[derive(Clone, Debug)]
pub struct Bake {
    /// SH order.
    pub order: usize,
    /// Per instance, in [`FlatScene::instances`] order.
    pub instances: Vec<Vec<f32>>,
    /// Statistics.
    pub stats: Stats,
}

impl Bake {
    /// The same bake cut to a lower order (SH projection is orthogonal: truncation is exact).
    pub fn truncated(&self, order: usize) -> Self {
        let (from, to) = (sh::num_coeffs(self.order), sh::num_coeffs(order.min(self.order)));
        let instances: Vec<Vec<f32>> =
            self.instances.iter().map(|t| t.chunks(from).flat_map(|c| c[..to].iter().copied()).collect()).collect();
        let bytes = instances.iter().map(|t| t.len() * 4).sum();
        Self { order: order.min(self.order), instances, stats: Stats { bytes, ..self.stats } }
    }

    /// Transfer coefficients of vertex `v` of instance `i`.
    pub fn vertex(&self, i: usize, v: usize) -> &[f32] {
        let n = sh::num_coeffs(self.order);
        &self.instances[i][v * n..(v + 1) * n]
    }
}

/// Group-from-local transform of every instance (exact, from the ECS: never through the
/// group's pose, so moving a group cannot change a bit of its bake).
pub fn local_transforms(scene: &Scene, flat: &FlatScene) -> Vec<Affine3A> {
    let by_id: HashMap<PrimitiveId, Affine3A> =
        scene.world.query::<(&PrimitiveId, &InGroup)>().iter().map(|(id, g)| (*id, g.local)).collect();
    flat.instances.iter().map(|i| by_id[&i.id]).collect()
}

/// What baking any vertex's transfer needs: the shared directions, each group's BVH in its own
/// frame, and each instance's group-from-local transform.
pub struct Baker {
    dirs: transfer::Directions,
    bvhs: HashMap<hecs::Entity, SceneBvh>,
    locals: Vec<Affine3A>,
}

impl Baker {
    /// Prepares the directions and the group BVHs of a snapshot.
    pub fn new(scene: &Scene, flat: &FlatScene, s: &Settings) -> Self {
        let dirs = transfer::Directions::stratified(s.direction_side(), s.order, DIRECTION_SEED);
        let mut bvhs: HashMap<hecs::Entity, SceneBvh> = HashMap::new();
        for inst in &flat.instances {
            bvhs.entry(inst.group).or_insert_with(|| {
                let (triangles, holes) = group_triangles(scene, inst.group);
                SceneBvh::new(&triangles).cut(&holes)
            });
        }
        Self { dirs, bvhs, locals: local_transforms(scene, flat) }
    }

    /// The transfer of vertex `v` of instance `i` into `out` (n² values).
    pub fn vertex(&self, flat: &FlatScene, i: usize, v: usize, out: &mut [f32]) {
        let inst = &flat.instances[i];
        let (local, mesh) = (&self.locals[i], &flat.meshes[inst.mesh as usize]);
        let p = local.transform_point3(mesh.positions[v]);
        let normal_matrix = local.matrix3.inverse().transpose();
        let normal = Vec3::from(normal_matrix * glam::Vec3A::from(mesh.normals[v])).normalize_or(Vec3::Y);
        transfer::vertex_transfer(&self.bvhs[&inst.group], &self.dirs, p, normal, out);
    }
}

/// Bakes the self-transfer of every instance against its own group, in parallel over vertices.
pub fn bake(scene: &Scene, flat: &FlatScene, s: &Settings, progress: &(dyn Fn(usize) + Sync)) -> Bake {
    let start = Instant::now();
    let baker = Baker::new(scene, flat, s);
    let n = sh::num_coeffs(s.order);
    let done = AtomicUsize::new(0);
    let mut stats = Stats::default();
    let instances: Vec<Vec<f32>> = (0..flat.instances.len())
        .map(|i| {
            let count = flat.vertex_count(i);
            let mut out = vec![0.0f32; count * n];
            out.par_chunks_mut(n).enumerate().for_each(|(v, t)| {
                baker.vertex(flat, i, v, t);
                progress(done.fetch_add(1, Ordering::Relaxed) + 1);
            });
            stats.vertices += count;
            stats.bytes += out.len() * 4;
            out
        })
        .collect();
    stats.seconds = start.elapsed().as_secs_f64();
    Bake { order: s.order, instances, stats }
}

/// The environment prepared for PRT: SH coefficients, regions and the ringing they show.
#[derive(Clone, Debug)]
pub struct Lighting {
    /// World-frame SH coefficients of the radiance.
    pub coeffs: RgbCoeffs,
    /// The environment's regions.
    pub regions: Vec<Region>,
    /// Window applied at reconstruction.
    pub window: Window,
    /// Negative lobes of the windowed reconstruction.
    pub lobes: NegativeLobes,
    /// Where the map has a sun: the sun and this lighting without it ([`sun`]), what the baked
    /// look shades with.
    pub sunless: Option<(sun::Sun, Box<Lighting>)>,
}

impl Lighting {
    /// Projects and decomposes the scene's environment (`None` without one), and the same
    /// without its sun when it has one.
    pub fn new(scene: &Scene, s: &Settings) -> Option<Self> {
        let env = scene.world.query::<&crate::scene::EnvironmentLight>().iter().next().cloned()?;
        Some(Self::of(&env, s).splitting_sun(&env, s))
    }

    /// This lighting (e.g. read from a pack) with the lighting of `env` without its sun
    /// beside it, when `env`'s map has one.
    pub fn splitting_sun(self, env: &crate::scene::EnvironmentLight, s: &Settings) -> Self {
        let sunless = sun::split_light(env).map(|(sun, rest)| (sun, Box::new(Self::of(&rest, s))));
        Self { sunless, ..self }
    }

    fn of(env: &crate::scene::EnvironmentLight, s: &Settings) -> Self {
        let coeffs = lighting::project(env, s.order);
        let lobes = lighting::negative_lobes(&coeffs, s.window);
        Self { coeffs, regions: regions::decompose(env, s.regions), window: s.window, lobes, sunless: None }
    }

    /// What the baked look shades the environment with: the sun apart (if the map has one)
    /// and the lighting of the rest.
    pub fn split_sun(&self) -> (Option<sun::Sun>, &Lighting) {
        match &self.sunless {
            Some((sun, rest)) => (Some(*sun), rest),
            None => (None, self),
        }
    }
}

/// Which PRT terms to shade.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shadows {
    /// Self-shadowing only (plain PRT).
    SelfOnly,
    /// Self-shadowing and shadows cast by other groups.
    WithOthers,
}

/// Poses `light` into every group of the snapshot; rasterises (or reuses from `memo`) the
/// silhouettes for [`Shadows::WithOthers`] in a scene with several groups.
pub fn pose(
    scene: &Scene,
    flat: &FlatScene,
    bake_order: usize,
    light: &Lighting,
    shadows: Shadows,
    s: &Settings,
    memo: &mut SilhouetteMemo,
) -> Posed {
    let (groups, frames) = group_poses(scene, flat);
    let group_of: Vec<usize> =
        flat.instances.iter().map(|i| groups.iter().position(|g| *g == i.group).expect("listed")).collect();
    let others = shadows == Shadows::WithOthers && groups.len() > 1;
    let regions = if others { light.regions.clone() } else { Vec::new() };
    let silhouettes = if others { memo.silhouettes(flat, &group_of, groups.len(), &regions, s) } else { Vec::new() };
    Posed::new(bake_order, &light.coeffs, light.window, regions, frames, group_of, silhouettes)
}

/// Per instance and vertex, the terms per-pixel PRT shading interpolates (see [`Frame::vertex_terms`]).
pub struct VertexTerms<'a> {
    /// `Ls` (RGB, albedo not applied).
    pub ls: &'a [Vec<Vec3>],
    /// The diffuse albedo toward the eye.
    pub albedo: &'a [Vec<Vec3>],
    /// `T(v, w_i)`, q per vertex, vertex-major.
    pub shadow_t: &'a [Vec<f32>],
}

/// Everything one frame's shading needs, after groups, lights and the camera are posed.
pub struct Frame {
    /// Per instance and vertex: unclamped `Ls` (RGB, albedo not applied).
    ls: VertexValues,
    /// Per instance and vertex: diffuse albedo toward the eye.
    albedo: VertexValues,
    /// Per instance: `T(v, w_i)` for every vertex, vertex-major (q per vertex).
    shadow_t: Vec<Vec<f32>>,
    posed: Posed,
}

/// World-from-group rotation (scale removed) and mirror flag of every group in the snapshot.
fn group_poses(scene: &Scene, flat: &FlatScene) -> (Vec<hecs::Entity>, Vec<(DMat3, bool)>) {
    let mut groups: Vec<(u32, hecs::Entity)> = flat
        .instances
        .iter()
        .map(|i| (scene.world.get::<&RigidGroup>(i.group).map_or(u32::MAX, |g| g.index), i.group))
        .collect();
    groups.sort();
    groups.dedup();
    let poses = groups
        .iter()
        .map(|&(_, g)| {
            let parts = scene.world.get::<&Transform>(g).ok().and_then(|t| t.rigid_parts().ok());
            parts.map_or((DMat3::IDENTITY, false), |p| (DMat3::from_quat(p.rotation.as_dquat()), p.mirrored))
        })
        .collect();
    (groups.into_iter().map(|(_, g)| g).collect(), poses)
}

/// A transfer bake with the lighting and settings it shades with: what a frame is posed from.
#[derive(Clone, Copy)]
pub struct Parts<'a> {
    /// The transfer.
    pub bake: &'a Bake,
    /// The environment projected for it.
    pub lighting: &'a Lighting,
    /// The settings both were made with.
    pub settings: &'a Settings,
}

impl Frame {
    /// Poses the lighting into every group, reconstructs `Ls` and `T(v, w_i)` per vertex, and
    /// (for [`Shadows::WithOthers`] in a scene with several groups) rasterises the silhouettes.
    pub fn prepare(scene: &Scene, flat: &FlatScene, parts: Parts, shadows: Shadows, eye: Vec3) -> Self {
        Self::prepare_cached(scene, flat, parts, shadows, eye, &mut SilhouetteMemo::default())
    }

    /// [`Frame::prepare`], reusing from `memo` the silhouettes of groups that did not move
    /// (after a move, only the moved group's are rasterised again).
    pub fn prepare_cached(
        scene: &Scene,
        flat: &FlatScene,
        parts: Parts,
        shadows: Shadows,
        eye: Vec3,
        memo: &mut SilhouetteMemo,
    ) -> Self {
        let Parts { bake, lighting, settings } = parts;
        let posed = pose(scene, flat, bake.order, lighting, shadows, settings, memo);
        Self::from_posed(flat, bake, posed, eye)
    }

    /// [`Frame::prepare`] with every albedo seen head-on instead of from an eye: shading that
    /// depends on no camera, which is what a bake plan measures (the bake serves every view).
    pub fn prepare_head_on(
        scene: &Scene,
        flat: &FlatScene,
        bake: &Bake,
        light: &Lighting,
        shadows: Shadows,
        s: &Settings,
    ) -> Self {
        let posed = pose(scene, flat, bake.order, light, shadows, s, &mut SilhouetteMemo::default());
        let albedo = albedo::head_on(flat);
        Self::from_posed_with(flat, bake, posed, &|i, _| albedo[i])
    }

    /// Reconstructs `Ls` and `T(v, w_i)` per vertex from `bake` under lighting already posed.
    pub fn from_posed(flat: &FlatScene, bake: &Bake, posed: Posed, eye: Vec3) -> Self {
        Self::from_posed_with(flat, bake, posed, &|i, v| albedo::at_vertex(flat, i, v, eye))
    }

    /// [`Frame::from_posed`] with `albedo(instance, vertex)`.
    fn from_posed_with(
        flat: &FlatScene,
        bake: &Bake,
        posed: Posed,
        albedo_of: &(dyn Fn(usize, usize) -> Vec3 + Sync),
    ) -> Self {
        let q = posed.regions.len();
        let (mut ls, mut albedo, mut shadow_t) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..flat.instances.len() {
            let count = flat.vertex_count(i);
            let rows: Vec<(Vec3, Vec3)> =
                (0..count).into_par_iter().map(|v| (posed.diffuse(i, bake.vertex(i, v)), albedo_of(i, v))).collect();
            ls.push(rows.iter().map(|r| r.0).collect());
            albedo.push(rows.iter().map(|r| r.1).collect());
            // Vertex-major, one element per (vertex, region): no allocation per vertex.
            let ts: Vec<f32> =
                (0..count * q).into_par_iter().map(|k| posed.toward_region(i, bake.vertex(i, k / q), k % q)).collect();
            shadow_t.push(ts);
        }
        Self { ls, albedo, shadow_t, posed }
    }

    /// The lighting this frame was posed with.
    pub fn posed(&self) -> &Posed {
        &self.posed
    }

    /// Per instance and vertex: `Ls` (RGB, albedo not applied), the diffuse albedo toward the
    /// eye, and `T(v, w_i)` (q per vertex, vertex-major) — what per-pixel shading interpolates.
    pub fn vertex_terms(&self) -> VertexTerms<'_> {
        VertexTerms { ls: &self.ls, albedo: &self.albedo, shadow_t: &self.shadow_t }
    }

    /// Per-vertex radiance toward the eye, per instance.
    pub fn vertex_values(&self, flat: &FlatScene) -> VertexValues {
        self.per_vertex(flat, |(radiance, _)| radiance)
    }

    /// Per instance and vertex: the radiance toward the eye and the fraction of the diffuse
    /// environment light the other groups' shadows leave (1 where none falls).
    pub fn vertex_values_open(&self, flat: &FlatScene) -> Vec<Vec<(Vec3, f32)>> {
        self.per_vertex(flat, |x| x)
    }

    /// [`Frame::radiance`] at every vertex, mapped by `pick`; each instance skips the pairs
    /// whose shadow cannot reach its vertices.
    fn per_vertex<T: Send>(&self, flat: &FlatScene, pick: impl Fn((Vec3, f32)) -> T + Sync) -> Vec<Vec<T>> {
        let q = self.posed.regions.len();
        (0..flat.instances.len())
            .map(|i| {
                let own = self.posed.group_of[i];
                let (lo, hi) = (0..flat.vertex_count(i))
                    .map(|v| flat.vertex(i, v).0)
                    .fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| (lo.min(p), hi.max(p)));
                let pairs = self.posed.pairs_reaching(0.5 * (lo + hi), 0.5 * (hi - lo).length());
                (0..self.ls[i].len())
                    .into_par_iter()
                    .map(|v| {
                        let (p, _) = flat.vertex(i, v);
                        let t = &self.shadow_t[i][v * q..(v + 1) * q];
                        let (l, open) = self.posed.radiance(own, self.ls[i][v], |r| t[r], p, &pairs);
                        pick((self.albedo[i][v] * l, open))
                    })
                    .collect()
            })
            .collect()
    }

    /// Radiance at one primary-ray hit, with the other groups' shadows evaluated there.
    pub fn shade_hit(&self, hit: &SurfaceHit) -> Vec3 {
        hit.interpolate(&self.albedo[hit.instance]) * self.shade_hit_with(hit, &self.posed.all_pairs()).0
    }

    /// Diffuse light at `hit` (albedo not applied) and the open fraction (see
    /// [`Frame::radiance`]).
    fn shade_hit_with(&self, hit: &SurfaceHit, pairs: &[(u16, u16)]) -> (Vec3, f32) {
        let i = hit.instance;
        let q = self.posed.regions.len();
        let t = |r: usize| (0..3).map(|c| self.shadow_t[i][hit.corners[c] * q + r] * hit.weights[c]).sum::<f32>();
        self.posed.radiance(self.posed.group_of[i], hit.interpolate(&self.ls[i]), t, hit.position, pairs)
    }

    /// A `width × height` image with `spp` samples per pixel, the other groups' shadows
    /// evaluated per sample (see [`Frame::shade_grid`]) and the diffuse albedo too where the
    /// material varies (textures, vertex colours: [`albedo::at_hit`]); misses show the environment.
    pub fn render(
        &self,
        r: &crate::reference::Renderer,
        camera: &crate::scene::Camera,
        width: usize,
        height: usize,
        spp: u32,
    ) -> Vec<Vec3> {
        let (grid, side) = raster::primary_grid(r, camera, width, height, spp);
        let (flat, eye) = (&r.flat, camera.eye());
        let albedo = |h: &SurfaceHit| {
            if flat.varies(h.instance) { albedo::at_hit(flat, h, eye) } else { h.interpolate(&self.albedo[h.instance]) }
        };
        raster::downsample(&self.shade_grid(&grid, width * side, &|h, l, _| albedo(h) * l), width, height, side)
    }

    /// Shades a grid of primary hits (`grid_width` columns, row-major): per sample,
    /// `shade(hit, diffuse light, open fraction)` with the light and fraction
    /// [`Frame::shade_hit`] reads (the albedo not applied: `shade` applies the one it has), but
    /// 8×8-sample tiles skip the (region, group) pairs whose shadow cannot reach them.
    pub fn shade_grid(
        &self,
        grid: &[Primary],
        grid_width: usize,
        shade: &(dyn Fn(&SurfaceHit, Vec3, f32) -> Vec3 + Sync),
    ) -> Vec<Vec3> {
        const TILE: usize = 8;
        let (gw, gh) = (grid_width, grid.len() / grid_width.max(1));
        let (tx, ty) = (gw.div_ceil(TILE), gh.div_ceil(TILE));
        let tiles: Vec<Vec<(usize, Vec3)>> = (0..tx * ty)
            .into_par_iter()
            .map(|t| {
                let (x0, y0) = ((t % tx) * TILE, (t / tx) * TILE);
                let cells: Vec<usize> = (y0..(y0 + TILE).min(gh))
                    .flat_map(|y| (x0..(x0 + TILE).min(gw)).map(move |x| y * gw + x))
                    .collect();
                let hits: Vec<&SurfaceHit> = cells
                    .iter()
                    .filter_map(|&k| if let Primary::Surface(h) = &grid[k] { Some(h) } else { None })
                    .collect();
                let (lo, hi) =
                    hits.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), h| (lo.min(h.position), hi.max(h.position)));
                let pairs = if hits.is_empty() {
                    Vec::new()
                } else {
                    self.posed.pairs_reaching(0.5 * (lo + hi), 0.5 * (hi - lo).length())
                };
                cells
                    .iter()
                    .map(|&k| {
                        let v = match &grid[k] {
                            Primary::Miss(l) | Primary::Emitter(l) => *l,
                            Primary::Surface(h) => {
                                let (light, open) = self.shade_hit_with(h, &pairs);
                                shade(h, light, open)
                            }
                        };
                        (k, v)
                    })
                    .collect()
            })
            .collect();
        let mut values = vec![Vec3::ZERO; gw * gh];
        for (k, v) in tiles.into_iter().flatten() {
            values[k] = v;
        }
        values
    }
}

/// Silhouettes kept between frames, per group, keyed by a hash of the group's world triangles,
/// the regions and the resolution: a group that did not move is not rasterised again.
/// A cut-out group's holes are compared as kept (its textures by identity): hashing their
/// texels every frame would cost more than the silhouettes.
#[derive(Default)]
pub struct SilhouetteMemo {
    entries: HashMap<usize, (blake3::Hash, Holes, Arc<Vec<Silhouette>>)>,
}

impl SilhouetteMemo {
    /// One silhouette list per group index, built or reused.
    pub fn silhouettes(
        &mut self,
        flat: &FlatScene,
        group_of: &[usize],
        groups: usize,
        regions: &[Region],
        s: &Settings,
    ) -> Vec<Arc<Vec<Silhouette>>> {
        let mut picked: Vec<Vec<usize>> = vec![Vec::new(); groups];
        for (t, r) in flat.refs.iter().enumerate() {
            if r.light == crate::scene::NO_LIGHT {
                picked[group_of[r.owner as usize]].push(t);
            }
        }
        let tris: Vec<Vec<[Vec3; 3]>> = picked.iter().map(|p| p.iter().map(|&t| flat.triangles[t]).collect()).collect();
        let all = flat.holes();
        let holes: Vec<Holes> = picked.iter().map(|p| all.select(p.iter().copied())).collect();
        let mut context = blake3::Hasher::new();
        context.update(&(s.silhouette_res as u64).to_le_bytes());
        for r in regions {
            context.update(bytemuck::cast_slice(&[r.dir.x, r.dir.y, r.dir.z, r.spread as f32]));
        }
        let keys: Vec<blake3::Hash> =
            tris.iter().map(|t| context.clone().update(bytemuck::cast_slice(t.as_slice())).finalize()).collect();
        let built: Vec<Arc<Vec<Silhouette>>> = (0..groups)
            .into_par_iter()
            .map(|g| match self.entries.get(&g) {
                Some((k, h, sil)) if *k == keys[g] && h.same(&holes[g]) => sil.clone(),
                _ => Arc::new(group_silhouettes(&tris[g], &holes[g], regions, s.silhouette_res)),
            })
            .collect();
        self.entries =
            built.iter().zip(holes).enumerate().map(|(g, (sil, h))| (g, (keys[g], h, sil.clone()))).collect();
        built
    }
}
