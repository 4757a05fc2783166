//! Per-frame shading of a spawned pack's lights on the CPU, from the baked BSPVT trees.
//!
//! At every vertex and for each of the first [`PIXEL_LIGHTS`] lights, the diffuse and the
//! specular lobe's (shadowed, unshadowed) LTC integrals; for any further light, its specular
//! radiance and its diffuse light (the pixel's own albedo multiplies it). Each instance is
//! shaded in its group's baked frame (the lights and the eye carried there from where its
//! group is now): the trees hold directions in that frame, so a moved group keeps its own
//! shadows exactly, and what other groups cast stays where it was baked. Recomputed only when
//! the eye, a group or a light moved; the environment's terms (the `diffuse_light` slot and
//! the specular term added to the per-vertex specular radiance) come from
//! [`crate::environment`]. The pack's bounces, frozen where its lights and groups were baked,
//! start the `diffuse_light` slot: they move with their vertices and nothing relights them.

use crate::environment::{EnvironmentShading, KageEnvironment};
use crate::material::{KageMaterial, tables};
use crate::spawn::KageLight;
use bevy::asset::RenderAssetUsages;
use bevy::prelude::*;
use bevy::render::renderer::RenderAdapterInfo;
use bevy::render::storage::ShaderBuffer;
use kage_runtime::bspvt::shade::{PointShader, Visibility};
use kage_runtime::light::FlatLight;
use kage_runtime::material::Material;
use kage_runtime::math::ltc;
use kage_runtime::pack::Pack;
use rayon::prelude::*;
use std::collections::HashSet;
use std::sync::Arc;

/// Lights shaded per pixel at most (the shader's `PIXEL_LIGHTS`); any further light is shaded
/// per vertex.
pub const PIXEL_LIGHTS: usize = 4;

/// 4-float slots per vertex: the per-vertex lights' and the environment's specular radiance,
/// the diffuse light of the per-vertex lights, the environment and the pack's bounces (albedo
/// not applied), then one per pixel light.
const SLOTS: usize = 2 + PIXEL_LIGHTS;

/// A Bevy vector as kage's.
pub fn kage_vec(v: Vec3) -> glam::Vec3 {
    glam::Vec3::from_array(v.to_array())
}

/// A kage vector as Bevy's.
pub fn bevy_vec(v: glam::Vec3) -> Vec3 {
    Vec3::from_array(v.to_array())
}

/// A Bevy global transform as kage's affine map.
fn kage_affine(t: &GlobalTransform) -> glam::Affine3A {
    glam::Affine3A::from_mat4(glam::Mat4::from_cols_array(&t.to_matrix().to_cols_array()))
}

/// A rectangle's frame and size: the frame maps the local XY plane (centre at the origin,
/// emitting toward −Z, as `RectLight`) onto the polygon's plane.
pub struct Rectangle {
    /// Polygon frame from rectangle frame.
    pub frame: glam::Affine3A,
    /// Extent along the frame's X.
    pub width: f32,
    /// Extent along the frame's Y.
    pub height: f32,
}

/// `polygon` as a rectangle, if it is one (four corners, opposite sides equal and parallel,
/// a right angle, to a part in 10⁴).
pub fn rectangle(polygon: &[glam::Vec3]) -> Option<Rectangle> {
    let [a, b, c, d] = polygon else { return None };
    let (e0, e1) = (*b - *a, *c - *b);
    let size = e0.length().max(e1.length());
    let tol = 1e-4 * size;
    let square = (e0 + (*d - *c)).length() <= tol && (e1 + (*a - *d)).length() <= tol;
    if size <= 0.0 || !square || e0.dot(e1).abs() > tol * size {
        return None;
    }
    let (normal, _) = kage_runtime::light::normal_area(polygon);
    let x = e0.normalize();
    let z = -normal;
    let frame = glam::Affine3A::from_cols(x.into(), z.cross(x).into(), z.into(), ((*a + *c) * 0.5).into());
    Some(Rectangle { frame, width: e0.length(), height: e1.length() })
}

/// The corners of a `RectLight` of `width` × `height` in its own frame, counter-clockwise
/// about its emitting side (−Z).
fn rect_corners(width: f32, height: f32) -> [glam::Vec3; 4] {
    let (w, h) = (width * 0.5, height * 0.5);
    [glam::Vec3::new(-w, -h, 0.0), glam::Vec3::new(-w, h, 0.0), glam::Vec3::new(w, h, 0.0), glam::Vec3::new(w, -h, 0.0)]
}

/// The buffers a spawned pack's materials read.
pub struct Terms {
    /// Per instance: its first vertex in `vertices`.
    pub first: Vec<u32>,
    /// Per vertex: [`SLOTS`] × 4 floats.
    pub vertices: Handle<ShaderBuffer>,
    /// The per-pixel lights.
    pub lights: Handle<ShaderBuffer>,
    /// The LTC and albedo tables.
    pub tables: Handle<ShaderBuffer>,
}

impl Terms {
    /// Zeroed terms for every vertex of `pack`, no lights, and the tables.
    pub fn new(pack: &Pack, buffers: &mut Assets<ShaderBuffer>) -> Self {
        let mut first = Vec::new();
        let mut total = 0u32;
        for i in &pack.instances {
            first.push(total);
            total += i.mesh.positions.len() as u32;
        }
        let zeros = vec![0.0f32; (total as usize).max(1) * SLOTS * 4];
        Self {
            first,
            vertices: buffers.add(buffer("kage vertices", &zeros)),
            lights: buffers.add(buffer("kage lights", &[0u32; LIGHT_WORDS])),
            tables: buffers.add(buffer("kage tables", &tables())),
        }
    }
}

/// A storage buffer named `label` holding `data`.
fn buffer<T: bytemuck::Pod>(label: &'static str, data: &[T]) -> ShaderBuffer {
    let mut b = ShaderBuffer::new(bytemuck::cast_slice(data), RenderAssetUsages::default());
    b.buffer_description.label = Some(label);
    b
}

/// 4-byte words of `ltc.wgsl`'s `Light`: eight corners (vec4), normal and corner count,
/// radiance and padding.
const LIGHT_WORDS: usize = 40;

/// `light` as `ltc.wgsl`'s `Light` (at most eight corners).
fn light_words(light: &FlatLight) -> [u32; LIGHT_WORDS] {
    let mut w = [0u32; LIGHT_WORDS];
    for (k, p) in light.points.iter().take(8).enumerate() {
        w[4 * k..4 * k + 3].copy_from_slice(&p.to_array().map(f32::to_bits));
    }
    w[32..35].copy_from_slice(&light.normal.to_array().map(f32::to_bits));
    w[35] = light.points.len().min(8) as u32;
    w[36..39].copy_from_slice(&light.radiance.to_array().map(f32::to_bits));
    w
}

/// A spawned pack's entities and what its shading last saw.
#[derive(Component)]
pub struct Shading {
    pack: Arc<Pack>,
    groups: Vec<Entity>,
    instances: Vec<Entity>,
    lights: Vec<Entity>,
    terms: Terms,
    /// Per instance and vertex: position and unit normal in the baked world.
    baked: Vec<Vec<(glam::Vec3, glam::Vec3)>>,
    /// What the terms were last computed for.
    last: Option<Vec<u32>>,
    /// Lights already warned about leaving their declared reach.
    warned: HashSet<usize>,
    /// The environment's shading, when the pack has an environment.
    environment: Option<EnvironmentShading>,
}

impl Shading {
    /// The state of a pack just spawned as these entities.
    pub(crate) fn new(
        pack: Arc<Pack>,
        groups: Vec<Entity>,
        instances: Vec<Entity>,
        lights: Vec<Entity>,
        terms: Terms,
    ) -> Self {
        let baked = pack
            .instances
            .iter()
            .map(|inst| {
                let world = pack.groups[inst.group].pose * inst.local;
                let normals = world.matrix3.inverse().transpose();
                let at = |(p, n): (&glam::Vec3, &glam::Vec3)| {
                    (world.transform_point3(*p), (normals * glam::Vec3A::from(*n)).normalize_or_zero().into())
                };
                inst.mesh.positions.iter().zip(&inst.mesh.normals).map(at).collect()
            })
            .collect();
        let environment = EnvironmentShading::new(&pack);
        Self { pack, groups, instances, lights, terms, baked, last: None, warned: HashSet::new(), environment }
    }

    /// The environment's sun where it was baked, when the pack shades it apart.
    pub(crate) fn sun(&self) -> Option<kage_runtime::prt::sun::Sun> {
        self.environment.as_ref().and_then(|e| e.sun)
    }
}

/// The lights as their entities place them now (hidden lights are off).
fn placed_lights(
    s: &mut Shading,
    lights: &Query<(&KageLight, &GlobalTransform, Option<&RectLight>, &InheritedVisibility)>,
) -> Vec<FlatLight> {
    let mut out = Vec::new();
    for &e in &s.lights {
        let Ok((light, at, rect, visible)) = lights.get(e) else { continue };
        if !visible.get() {
            continue;
        }
        let to = kage_affine(at);
        let placed = match rect {
            Some(r) => {
                let corners = rect_corners(r.width, r.height);
                let (w, h) = (r.width * to.matrix3.x_axis.length(), r.height * to.matrix3.y_axis.length());
                let c = r.color.to_linear();
                let radiance = glam::Vec3::new(c.red, c.green, c.blue) * (r.intensity / (w * h * std::f32::consts::PI));
                FlatLight::placed(&corners, &[], &to, radiance)
            }
            None => {
                let points: Vec<glam::Vec3> = light.polygon.iter().map(|p| kage_vec(*p)).collect();
                let c = light.radiance;
                FlatLight::placed(&points, &[], &to, glam::Vec3::new(c.red, c.green, c.blue))
            }
        };
        let Some(mut placed) = placed else { continue };
        placed.reach = s.pack.lights[light.index].reach;
        if let Some([lo, hi]) = placed.reach
            && placed.points.iter().any(|p| p.cmplt(lo).any() || p.cmpgt(hi).any())
            && s.warned.insert(light.index)
        {
            warn!("light {} left the box it was baked to stay in: its shadows there are guesses", light.index);
        }
        out.push(placed);
    }
    out
}

/// Where the baked lights are shaded: their LTC per pixel (highlights as sharp as the lobe),
/// or per vertex (cheaper where the GPU is emulated on the CPU).
#[derive(Resource, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ShadeOn {
    /// Per pixel, unless the device is a CPU emulation (Mesa's lavapipe): per vertex there.
    #[default]
    Auto,
    /// Per pixel (the first [`PIXEL_LIGHTS`] lights; any further one per vertex).
    Pixel,
    /// Per vertex.
    Vertex,
}

/// What the last shading cost: for frame-time reports.
#[derive(Resource, Clone, Copy, Debug, Default)]
pub struct KageStats {
    /// Wall time of the last per-vertex shading (all packs).
    pub shade: std::time::Duration,
    /// Vertices it shaded.
    pub vertices: usize,
    /// Frames whose shading was recomputed.
    pub shaded_frames: u64,
}

/// The bits of everything the terms depend on.
fn key(eye: glam::Vec3, poses: &[glam::Affine3A], lights: &[FlatLight], env: Option<&KageEnvironment>) -> Vec<u32> {
    let mut k: Vec<u32> = eye.to_array().map(f32::to_bits).to_vec();
    if let Some(e) = env {
        k.extend(e.rotation.to_array().into_iter().chain([e.intensity]).map(f32::to_bits));
    }
    k.extend(poses.iter().flat_map(|p| p.to_cols_array()).map(f32::to_bits));
    for l in lights {
        k.extend(l.points.iter().flat_map(|p| p.to_array()).chain(l.radiance.to_array()).map(f32::to_bits));
    }
    k
}

/// Shades every spawned pack whose eye, groups or lights moved: its per-vertex terms and its
/// per-pixel lights, into the buffers its materials read.
pub(crate) fn shade_lights(
    mut scenes: Query<(&mut Shading, Option<&KageEnvironment>)>,
    globals: Query<&GlobalTransform>,
    lights: Query<(&KageLight, &GlobalTransform, Option<&RectLight>, &InheritedVisibility)>,
    cameras: Query<(&Camera, &GlobalTransform), With<Camera3d>>,
    handles: Query<&MeshMaterial3d<KageMaterial>>,
    mut buffers: ResMut<Assets<ShaderBuffer>>,
    mut materials: ResMut<Assets<KageMaterial>>,
    mut stats: ResMut<KageStats>,
    shade_on: Res<ShadeOn>,
    adapter: Option<Res<RenderAdapterInfo>>,
) {
    let per_pixel = crate::material::per_pixel(*shade_on, adapter.as_deref());
    let start = std::time::Instant::now();
    let mut vertices = 0;
    let mut active: Vec<(isize, glam::Vec3)> =
        cameras.iter().filter(|(c, _)| c.is_active).map(|(c, t)| (c.order, kage_vec(t.translation()))).collect();
    active.sort_by_key(|c| c.0);
    let Some(&(_, eye)) = active.last() else { return };
    for (mut s, env) in &mut scenes {
        let poses: Vec<glam::Affine3A> =
            s.groups.iter().map(|g| globals.get(*g).map_or(glam::Affine3A::IDENTITY, kage_affine)).collect();
        let placed = placed_lights(&mut s, &lights);
        let key = key(eye, &poses, &placed, env);
        if s.last.as_ref() == Some(&key) {
            continue;
        }
        let pixel_lights = if per_pixel { placed.len().min(PIXEL_LIGHTS) } else { 0 };
        let mut terms = vertex_terms(&s, &poses, &placed, pixel_lights, eye);
        let s = &mut *s;
        if let Some(e) = s.environment.as_mut() {
            let (rotation, intensity) = env.map_or((Quat::IDENTITY, 1.0), |e| (e.rotation, e.intensity));
            let light = e.light(&s.pack, &poses, eye, rotation, intensity);
            for (row, (diffuse, specular)) in terms.chunks_exact_mut(SLOTS * 4).zip(light.iter().flatten()) {
                for c in 0..3 {
                    row[c] += specular[c];
                    row[4 + c] += diffuse[c];
                }
            }
        }
        vertices += terms.len() / (SLOTS * 4);
        let _ = buffers.insert(s.terms.vertices.id(), buffer("kage vertices", &terms));
        let pixel: Vec<u32> = placed.iter().take(pixel_lights).flat_map(light_words).collect();
        let pixel = if pixel.is_empty() { vec![0; LIGHT_WORDS] } else { pixel };
        let _ = buffers.insert(s.terms.lights.id(), buffer("kage lights", &pixel));
        // Touching every material re-binds its buffers.
        for h in s.instances.iter().filter_map(|e| handles.get(*e).ok()) {
            if let Some(mut m) = materials.get_mut(&h.0) {
                m.extension.params.lights = pixel_lights as u32;
            }
        }
        s.last = Some(key);
    }
    if vertices > 0 {
        *stats = KageStats { shade: start.elapsed(), vertices, shaded_frames: stats.shaded_frames + 1 };
    }
}

/// Every vertex's [`SLOTS`] × 4 floats, instance after instance.
/// `pixel_lights`: how many of `lights` (the first) are shaded per pixel.
fn vertex_terms(
    s: &Shading,
    poses: &[glam::Affine3A],
    lights: &[FlatLight],
    pixel_lights: usize,
    eye: glam::Vec3,
) -> Vec<f32> {
    let table = ltc::table();
    let res = s.pack.header.bspvt.as_ref().map_or(0, |h| h.face_resolution as usize);
    let mut out = Vec::new();
    for (i, inst) in s.pack.instances.iter().enumerate() {
        // The lights and the eye in the instance's baked frame.
        let to_baked = s.pack.groups[inst.group].pose * poses[inst.group].inverse();
        let baked: Vec<FlatLight> =
            lights.iter().filter_map(|l| FlatLight::placed(&l.points, &l.uvs, &to_baked, l.radiance)).collect();
        let (per_pixel, per_vertex) = baked.split_at(pixel_lights);
        let eye = to_baked.transform_point3(eye);
        let material = Material::from(&inst.material);
        let rows: Vec<[f32; SLOTS * 4]> = s.baked[i]
            .par_iter()
            .enumerate()
            .map(|(v, &(p, n))| {
                let shader = PointShader::new(&table, p, n, eye, &material);
                let vis = inst.bspvt.as_ref().map_or(Visibility::Unshadowed, |b| Visibility::Tree(b.record(v), res));
                let mut row = [0.0; SLOTS * 4];
                // The diffuse light meets each pixel's own albedo (its texture, its vertex
                // colour): the vertex's, here, would spread it over the triangles around.
                let (diffuse, specular) = shader.shade_parts(per_vertex, vis);
                let bounce = inst.bounce.as_ref().map_or(glam::Vec3::ZERO, |b| b[v]);
                row[..3].copy_from_slice(&specular.to_array());
                row[4..7].copy_from_slice(&(diffuse + bounce).to_array());
                let (_, pairs) = shader.vertex_lobe_pairs(per_pixel, vis, inst.inside[v]);
                for (k, [d, sp]) in pairs.iter().enumerate() {
                    row[4 * (k + 2)..4 * (k + 3)].copy_from_slice(&[d[0], d[1], sp[0], sp[1]]);
                }
                row
            })
            .collect();
        out.extend(rows.iter().flatten());
    }
    if out.is_empty() {
        out.resize(SLOTS * 4, 0.0);
    }
    out
}
