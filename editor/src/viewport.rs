//! The 3D view: the scene's meshes (and light polygons) drawn with per-vertex radiance by
//! `shaders/preview.wgsl` into an offscreen texture that egui shows as an image, the base-colour
//! texture's detail added per pixel ([`crate::detail`]). PRT is drawn per pixel instead when a
//! frame's terms are given ([`Viewport::upload_prt`]): the shadows between groups are looked up
//! at every pixel, not interpolated between vertices. The polygonal lights are drawn per pixel
//! when their lobes are given ([`Viewport::upload_lights`]): LTC at every pixel, the trees'
//! visibility carried from the vertices, as `kage render` does.

use super::camera::Orbit;
use super::detail::{self, Detail};
use super::sky::{self, Sky};
use super::sun_shadow::{self, SunShadow};
use bytemuck::{Pod, Zeroable};
use eframe::{egui, egui_wgpu};
use glam::Vec3;
use kage_engine::bspvt::pixel::Lobes;
use kage_engine::math::{ggx, ltc};
use kage_engine::prt;
use kage_engine::prt::prefilter::Prefiltered;
use kage_engine::prt::sun::Sun;
use kage_engine::scene::{EnvironmentLight, FlatScene, VertexValues};
use kage_engine::shading::baked::{SUN_ALPHA_FLOOR, SpecularVertices};
use kage_gpu::buffers::{storage, uniform};
use kage_gpu::prt::ShadowArrays;
use kage_gpu::{Gpu, Shaders};
use wgpu::util::DeviceExt;

const COLOR: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
/// The target of [`Viewport::render_radiance`].
const RADIANCE: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;

/// What a frame's pixels hold.
#[derive(Clone, Copy, PartialEq)]
enum Output {
    /// Radiance × 2^stops, clamped and sRGB-encoded, over the environment.
    Display(f32),
    /// The error overlay's colours as they are, over a plain background.
    Overlay,
    /// Radiance as it is, over the environment.
    Radiance,
}
const DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Samples per pixel of the displayed view (WebGPU guarantees 4 for [`COLOR`] and [`DEPTH`]):
/// silhouettes and shadow-casting edges without stair steps. Linear radiance for
/// `kage render --gpu` stays at one sample, as the CPU renderer's pixel centres.
pub const SAMPLES: u32 = 4;

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct View {
    view_proj: [[f32; 4]; 4],
    exposure: [f32; 4],
    inverse_view_proj: [[f32; 4]; 4],
    eye: [f32; 4],
    sun_clip: [[f32; 4]; 4],
    sun_direction: [f32; 4],
    sun_shadow: [f32; 4],
}

/// One drawable: world positions, radiance and texture detail per vertex, triangle indices,
/// the base-colour texture.
struct Mesh {
    positions: wgpu::Buffer,
    radiance: wgpu::Buffer,
    detail: wgpu::Buffer,
    /// The sun's unshadowed light per vertex ([`Viewport::upload_sun`]; zero without).
    sun: wgpu::Buffer,
    indices: wgpu::Buffer,
    texture: wgpu::BindGroup,
    count: u32,
    vertices: usize,
}

impl Mesh {
    /// Draws it with its texture as group 1 and its vertex buffers 0–3.
    fn draw(&self, pass: &mut wgpu::RenderPass) {
        pass.set_bind_group(1, &self.texture, &[]);
        pass.set_vertex_buffer(0, self.positions.slice(..));
        pass.set_vertex_buffer(1, self.radiance.slice(..));
        pass.set_vertex_buffer(2, self.detail.slice(..));
        pass.set_vertex_buffer(3, self.sun.slice(..));
        pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(0..self.count, 0, 0..1);
    }
}

/// PRT per pixel: one unindexed draw of every instance's triangles.
struct PrtDraw {
    bind: wgpu::BindGroup,
    /// Per instance, its range of the unindexed draw (drawn with its base-colour texture).
    ranges: Vec<std::ops::Range<u32>>,
}

/// `PrtParams` of preview.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct PrtParams {
    regions: u32,
    groups: u32,
    pad: [u32; 2],
}

/// `PrtVertex` of preview.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct PrtVertex {
    p: [f32; 4],
    ls: [f32; 4],
    albedo: [f32; 4],
    /// The base-colour UV, then the cut-out's factor and cutoff ([`Detail`]).
    uv_cut: [f32; 4],
    /// The base-colour texture's value at the vertex.
    at_vertex: [f32; 4],
}

/// The polygonal lights per pixel: one unindexed draw per instance (each with its base-colour
/// texture) of the triangles in storage.
struct LitDraw {
    bind: wgpu::BindGroup,
    /// Per vertex, the radiance of everything not drawn per pixel (rewritten with every
    /// [`Viewport::upload_radiance`]).
    rest: wgpu::Buffer,
    /// The per-vertex radiance of what is drawn per pixel (the polygonal lights, the
    /// environment's specular term), which `rest` leaves out, flattened.
    per_pixel: Vec<Vec3>,
    /// Per instance, its range of the unindexed draw.
    ranges: Vec<std::ops::Range<u32>>,
}

/// What the viewport needs to draw the polygonal lights per pixel: the lobes' integrals at
/// every vertex toward the eye and the per-vertex radiance computed with them; and the
/// environment's specular term, where the look has one.
pub struct PixelLights {
    /// Per vertex and light, the shadowed and unshadowed integrals of both lobes.
    pub lobes: Lobes,
    /// The polygonal lights' radiance per vertex (part of what `upload_radiance` is given).
    pub values: VertexValues,
    /// The environment's specular term per vertex and the chain it reflects.
    pub environment: Option<PixelEnvironment>,
}

/// The environment's specular term, drawn per pixel: the reflection `R` by filtered importance
/// sampling of `prefiltered` at each pixel, times the weight interpolated from the vertices;
/// and the map's sun, its BSDF at each pixel times its visibility interpolated.
pub struct PixelEnvironment {
    /// Per vertex: the term (part of what `upload_radiance` is given) and its weight.
    pub specular: SpecularVertices,
    /// The environment's mip chain.
    pub prefiltered: Prefiltered,
    /// The map's sun, if it has one.
    pub sun: Option<PixelSun>,
}

impl PixelEnvironment {
    /// The environment's part of a frame just shaded through an environment memo
    /// (`specular`: [`kage_engine::shading::baked::EnvironmentMemo::specular`]), with the
    /// map's sun from `lighting` and its per-vertex visibility from `eye`'s frame.
    pub fn new(
        flat: &FlatScene,
        specular: &SpecularVertices,
        prefiltered: &Prefiltered,
        lighting: &prt::Lighting,
        eye: Vec3,
    ) -> Self {
        let sun = lighting.split_sun().0.map(|sun| {
            let values = kage_engine::shading::baked::sun_vertices(flat, &sun, eye).0;
            PixelSun { sun, values }
        });
        Self { specular: specular.clone(), prefiltered: prefiltered.clone(), sun }
    }
}

/// The sun per pixel — its BSDF at the pixel, its shadow from a depth map
/// (`sun_shadow.rs`) — and per vertex its light (part of what `upload_radiance` is
/// given: [`kage_engine::shading::baked::sun_vertices`]).
pub struct PixelSun {
    /// Direction, irradiance and size.
    pub sun: Sun,
    /// Per instance and vertex: the sun's light toward the eye.
    pub values: VertexValues,
}

/// The map's sun for the per-vertex draw: per vertex its light as the look adds it (shadowed)
/// and unshadowed ([`kage_engine::shading::baked::sun_vertices`]).
pub struct VertexSun {
    /// Direction, irradiance and size.
    pub sun: Sun,
    /// Per instance and vertex: the sun's light toward the eye where the vertex sees it.
    pub values: VertexValues,
    /// Per instance and vertex: the sun's light toward the eye were nothing in the way.
    pub open: VertexValues,
}

/// Most mip levels the shader reads.
const MAX_LEVELS: usize = 12;

/// `LitParams` of preview.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct LitParams {
    lights: u32,
    levels: u32,
    pad: [u32; 2],
    /// Rows of map-from-world; row 0's w the intensity, row 1's the solid angle of a level-0
    /// texel.
    to_map: [[f32; 4]; 3],
    /// Per level: width, height, offset in the chain's texels.
    level: [[u32; 4]; MAX_LEVELS],
    /// Toward the sun; w its least roughness (0: no sun).
    sun_direction: [f32; 4],
    /// The sun's irradiance.
    sun_irradiance: [f32; 4],
}

/// A mip chain on the device, and the chain it was uploaded from.
struct Mips {
    source: Prefiltered,
    buffer: wgpu::Buffer,
}

/// `LitVertex` of preview.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct LitVertex {
    p: [f32; 4],
    n: [f32; 4],
    base: [f32; 4],
    surface: [f32; 4],
    at_vertex: [f32; 4],
    mr_uv: [f32; 4],
}

/// The offscreen target: [`SAMPLES`] per pixel, resolved into the texture egui shows.
struct Target {
    size: [u32; 2],
    frame: Frame,
    id: Option<egui::TextureId>,
}

/// What one frame draws into: colour and depth of some samples per pixel, and the one-sample
/// colour they resolve into (the colour itself at one sample).
struct Frame {
    color: wgpu::TextureView,
    depth: wgpu::TextureView,
    resolved: Option<wgpu::TextureView>,
}

impl Frame {
    /// Views of `color` (a one-sample texture of `size`, read afterwards) with `samples`
    /// multisampled colour and depth textures in front of it when `samples` > 1.
    fn new(gpu: &Gpu, color: &wgpu::Texture, samples: u32) -> Self {
        let size = [color.width(), color.height()];
        let target = |format, usage| texture(gpu, size, format, usage, samples).create_view(&Default::default());
        let depth = target(DEPTH, wgpu::TextureUsages::RENDER_ATTACHMENT);
        let resolved = color.create_view(&Default::default());
        if samples == 1 {
            return Self { color: resolved, depth, resolved: None };
        }
        let color = target(color.format(), wgpu::TextureUsages::RENDER_ATTACHMENT);
        Self { color, depth, resolved: Some(resolved) }
    }

    /// The view to read or show: the resolved colour.
    fn shown(&self) -> &wgpu::TextureView {
        self.resolved.as_ref().unwrap_or(&self.color)
    }
}

/// The pipelines of preview.wgsl.
struct Pipelines {
    /// Per-vertex radiance with texture detail.
    main: wgpu::RenderPipeline,
    /// Per-pixel PRT; `None` where the device cannot bind its storage buffers in the fragment
    /// stage (e.g. a GL adapter), which then interpolates PRT per vertex.
    prt: Option<wgpu::RenderPipeline>,
    /// The polygonal lights per pixel; `None` as for `prt`.
    lit: Option<wgpu::RenderPipeline>,
    /// The environment behind the geometry.
    sky: wgpu::RenderPipeline,
    /// The sun's depth map.
    shadow: wgpu::RenderPipeline,
}

/// The viewport renderer.
pub struct Viewport {
    pipelines: Pipelines,
    uniform: wgpu::Buffer,
    bind: wgpu::BindGroup,
    layout: wgpu::BindGroupLayout,
    prt_layout: Option<wgpu::BindGroupLayout>,
    detail_layout: wgpu::BindGroupLayout,
    sky_layout: wgpu::BindGroupLayout,
    /// The environment map shown behind the geometry, if any.
    sky: Option<Sky>,
    meshes: Vec<Mesh>,
    prt: Option<PrtDraw>,
    lit: Option<LitDraw>,
    /// The environment's mip chain for the per-pixel lights, uploaded once per chain.
    mips: Option<Mips>,
    /// Group 1 of the per-pixel lights: the storage arrays, the mip chain and the sun's depth map.
    lit_layout: Option<wgpu::BindGroupLayout>,
    /// The map's sun's depth map.
    sun: SunShadow,
    /// The view's bind group with a stand-in for the map, for the pass that draws the map.
    bind_for_sun: wgpu::BindGroup,
    /// The sun's shadowed light per vertex, taken out of the radiance `fs_main` draws (it adds
    /// the sun per pixel), when [`Viewport::upload_sun`] was given one.
    vertex_sun: Option<VertexValues>,
    /// Flat-coloured light polygons, each with its emitting side.
    lights: Vec<(Mesh, LightSide)>,
    target: Option<Target>,
    /// Samples per pixel of what it draws for display ([`SAMPLES`] unless made otherwise).
    samples: u32,
    /// The shader generation the pipeline was built from.
    pub generation: u64,
    /// Bumped by every change to what a frame shows but the view.
    revision: u64,
    /// What the target's last frame was drawn from: a frame from the same is not drawn again
    /// (on a CPU device a frame of per-pixel lights costs a second of both cores).
    drawn: Option<Drawn>,
    /// Seconds the last drawn frame took to record and submit.
    draw_seconds: f64,
    /// Frames drawn for display so far.
    frames_drawn: u64,
}

/// The inputs of one drawn frame.
#[derive(PartialEq)]
struct Drawn {
    size: [u32; 2],
    view_proj: [f32; 16],
    eye: Vec3,
    output: Output,
    revision: u64,
}

/// Where a light polygon emits: its centre, the normal of its emitting side and its radiance.
struct LightSide {
    centre: Vec3,
    normal: Vec3,
    radiance: Vec3,
}

impl Viewport {
    /// Builds the pipeline from `shaders` (`preview.wgsl`), drawing [`SAMPLES`] per pixel.
    pub fn new(gpu: &Gpu, shaders: &Shaders) -> Result<Self, kage_gpu::ShaderError> {
        Self::with_samples(gpu, shaders, SAMPLES)
    }

    /// [`Self::new`] drawing `samples` per pixel (1: each pixel's centre alone, as a ray
    /// caster's image, which tests compare against).
    pub fn with_samples(gpu: &Gpu, shaders: &Shaders, samples: u32) -> Result<Self, kage_gpu::ShaderError> {
        let view_entry = wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let [depth, sampler] = sun_shadow::layout_entries();
        let layout = gpu.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("preview view"),
            entries: &[view_entry, depth, sampler],
        });
        let uniform = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("preview view"),
            size: std::mem::size_of::<View>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let sun = SunShadow::new(gpu);
        // The depth pass draws into the map, so it binds the view with a stand-in.
        let view_group = |map: &wgpu::TextureView| {
            gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("preview view"),
                layout: &layout,
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(map) },
                    wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::Sampler(&sun.sampler) },
                ],
            })
        };
        let (bind, bind_for_sun) = (view_group(&sun.view), view_group(&sun.stand_in));
        let prt_layout = storage_layout(gpu, 4);
        let lit_layout = storage_layout(gpu, 5);
        let (detail_layout, sky_layout) = (detail::layout(gpu), sky::layout(gpu));
        let layouts = Layouts {
            view: &layout,
            detail: &detail_layout,
            sky: &sky_layout,
            prt: prt_layout.as_ref(),
            lit: lit_layout.as_ref(),
        };
        let pipelines = build_pipelines(gpu, shaders, layouts, (COLOR, samples))?;
        Ok(Self {
            pipelines,
            uniform,
            bind,
            layout,
            prt_layout,
            detail_layout,
            sky_layout,
            sky: None,
            meshes: Vec::new(),
            prt: None,
            lit: None,
            mips: None,
            lit_layout,
            sun,
            bind_for_sun,
            vertex_sun: None,
            lights: Vec::new(),
            target: None,
            samples,
            generation: 0,
            revision: 0,
            drawn: None,
            draw_seconds: 0.0,
            frames_drawn: 0,
        })
    }

    /// Rebuilds the pipeline (hot reload); on error the previous one stays.
    pub fn reload(&mut self, gpu: &Gpu, shaders: &Shaders, generation: u64) -> Result<(), kage_gpu::ShaderError> {
        self.generation = generation;
        self.pipelines = self.build(gpu, shaders, (COLOR, self.samples))?;
        self.revision += 1;
        Ok(())
    }

    /// The pipelines of `shaders` over this viewport's layouts, drawing into `target` (format,
    /// samples per pixel).
    fn build(
        &self,
        gpu: &Gpu,
        shaders: &Shaders,
        target: (wgpu::TextureFormat, u32),
    ) -> Result<Pipelines, kage_gpu::ShaderError> {
        let layouts = Layouts {
            view: &self.layout,
            detail: &self.detail_layout,
            sky: &self.sky_layout,
            prt: self.prt_layout.as_ref(),
            lit: self.lit_layout.as_ref(),
        };
        build_pipelines(gpu, shaders, layouts, target)
    }

    /// Seconds the last drawn frame took to record and submit (a CPU device renders it then).
    pub fn draw_seconds(&self) -> f64 {
        self.draw_seconds
    }

    /// Frames drawn for display so far ([`Viewport::paint`] skips those whose inputs match the last).
    pub fn frames_drawn(&self) -> u64 {
        self.frames_drawn
    }

    /// Whether this device draws PRT per pixel.
    pub fn per_pixel_prt(&self) -> bool {
        self.pipelines.prt.is_some()
    }

    /// Whether this device draws the lights and the environment's reflection per pixel.
    pub fn per_pixel_lights(&self) -> bool {
        self.pipelines.lit.is_some()
    }

    /// Whether the next frame draws them per pixel: the device can, and the last
    /// [`Viewport::upload_lights`] was given lights it takes.
    pub fn drawing_lights(&self) -> bool {
        self.per_pixel_lights() && self.lit.is_some()
    }

    /// Shows `env` behind the geometry (`None`: the background colour); the map is uploaded
    /// again only when it changed, its rotation and intensity every call.
    pub fn set_environment(&mut self, gpu: &Gpu, env: Option<&EnvironmentLight>) {
        let same = match (&self.sky, env) {
            (Some(sky), Some(env)) => sky.shows(env),
            (None, None) => true,
            _ => false,
        };
        if same {
            return;
        }
        self.revision += 1;
        let old = self.sky.take();
        self.sky = env.map(|e| Sky::new(gpu, &self.sky_layout, e, old));
    }

    /// Draws the receivers with PRT per pixel from `frame`'s terms (`None`, or a device that
    /// cannot: per-vertex radiance).
    pub fn upload_prt(&mut self, gpu: &Gpu, flat: &FlatScene, frame: Option<&prt::Frame>) {
        self.revision += 1;
        self.prt = match (frame, &self.prt_layout) {
            (Some(f), Some(layout)) => Some(prt_draw(gpu, layout, flat, f)),
            _ => None,
        };
    }

    /// Draws the polygonal lights per pixel from `lights` (`None`, a device that cannot, or a
    /// light the shader does not take — textured, more than 8 corners: per-vertex radiance).
    /// Call after [`Viewport::upload_geometry`] of the same snapshot.
    pub fn upload_lights(&mut self, gpu: &Gpu, flat: &FlatScene, lights: Option<&PixelLights>) {
        self.revision += 1;
        let chain = lights.and_then(|l| l.environment.as_ref()).map(|e| &e.prefiltered);
        if let Some(chain) = chain.filter(|c| self.mips.as_ref().is_none_or(|m| !m.source.same_chain(c))) {
            self.mips = Some(Mips { source: chain.clone(), buffer: mip_buffer(gpu, chain) });
        }
        let fits = self.meshes.len() == flat.instances.len();
        let mips = chain.and(self.mips.as_ref()).map(|m| &m.buffer);
        self.lit = match (lights, &self.lit_layout) {
            (Some(l), Some(layout)) if fits => lit_draw(gpu, layout, flat, l, mips),
            _ => None,
        };
        let sun = lights.and_then(|l| l.environment.as_ref()).and_then(|e| e.sun.as_ref());
        if let Some(s) = sun.filter(|_| self.lit.is_some()) {
            self.render_sun(gpu, flat, &s.sun);
        }
    }

    /// Adds the map's sun per pixel to the per-vertex draw (`fs_main`): `sun`'s shadowed light
    /// per vertex is taken out of the radiance [`Viewport::upload_radiance`] is given, and its
    /// unshadowed light interpolated times the depth map's visibility put back at each pixel.
    /// `None`, or values that do not fit the snapshot: the sun stays in the vertices. Call
    /// after [`Viewport::upload_geometry`] and [`Viewport::upload_lights`] of the same snapshot.
    pub fn upload_sun(&mut self, gpu: &Gpu, flat: &FlatScene, sun: Option<&VertexSun>) {
        self.revision += 1;
        let counts = || (0..flat.instances.len()).map(|i| flat.vertex_count(i));
        let fits = |v: &VertexValues| v.iter().map(Vec::len).eq(counts());
        let sun = sun.filter(|s| self.meshes.len() == flat.instances.len() && fits(&s.values) && fits(&s.open));
        for (k, m) in self.meshes.iter().enumerate() {
            let open = sun.map_or_else(|| vec![Vec3::ZERO; m.vertices], |s| s.open[k].clone());
            gpu.queue.write_buffer(&m.sun, 0, bytemuck::cast_slice(&open));
        }
        self.vertex_sun = sun.map(|s| s.values.clone());
        if let Some(s) = sun {
            self.render_sun(gpu, flat, &s.sun);
        }
    }

    /// Renders the sun's depth map of every mesh and light polygon (the shadow rays of `kage
    /// render` see the lights too).
    fn render_sun(&mut self, gpu: &Gpu, flat: &FlatScene, sun: &kage_engine::prt::sun::Sun) {
        // The map depends on the geometry and the sun only: a camera or light move keeps it.
        if self.sun.holds(sun) {
            return;
        }
        let clip = self.sun.aim(sun, flat.bounding_sphere());
        let view = View { sun_clip: clip.to_cols_array_2d(), ..Zeroable::zeroed() };
        // The pass binds the view with a stand-in map: it draws into the real one.
        gpu.queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&view));
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("sun shadow"),
                color_attachments: &[],
                depth_stencil_attachment: Some(self.sun.attachment()),
                ..Default::default()
            });
            pass.set_pipeline(&self.pipelines.shadow);
            pass.set_bind_group(0, &self.bind_for_sun, &[]);
            for m in self.meshes.iter().chain(self.lights.iter().map(|(m, _)| m)) {
                m.draw(&mut pass);
            }
        }
        gpu.queue.submit([encoder.finish()]);
    }

    /// Uploads every instance's world-space triangles with its base-colour texture, and every
    /// light polygon.
    pub fn upload_geometry(&mut self, gpu: &Gpu, flat: &FlatScene) {
        self.revision += 1;
        self.sun.clear();
        let plain = detail::bind_group(gpu, &self.detail_layout, flat, detail::Textures::default());
        let mut textures = std::collections::HashMap::new();
        self.meshes = (0..flat.instances.len())
            .map(|i| {
                let mesh = flat.mesh(i);
                let p: Vec<Vec3> = (0..mesh.positions.len()).map(|v| flat.vertex(i, v).0).collect();
                let idx: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
                let t = detail::Textures::of(flat, i);
                let texture = if t == detail::Textures::default() {
                    plain.clone()
                } else {
                    let layout = &self.detail_layout;
                    textures.entry(t).or_insert_with(|| detail::bind_group(gpu, layout, flat, t)).clone()
                };
                let look = Look { radiance: &vec![Vec3::ZERO; p.len()], detail: &detail::vertices(flat, i), texture };
                mesh_buffers(gpu, &p, look, &idx)
            })
            .collect();
        self.lights = flat
            .lights
            .iter()
            .map(|l| {
                let idx: Vec<u32> = (1..l.points.len() as u32 - 1).flat_map(|k| [0, k, k + 1]).collect();
                let n = l.points.len();
                let look =
                    Look { radiance: &vec![l.radiance; n], detail: &vec![detail::PLAIN; n], texture: plain.clone() };
                let centre = l.points.iter().sum::<Vec3>() / n as f32;
                (mesh_buffers(gpu, &l.points, look, &idx), LightSide { centre, normal: l.normal, radiance: l.radiance })
            })
            .collect();
    }

    /// Uploads per-instance vertex radiance (ignored when the shapes disagree: a new snapshot
    /// is on its way).
    pub fn upload_radiance(&mut self, gpu: &Gpu, values: &[Vec<Vec3>]) {
        self.revision += 1;
        if values.len() != self.meshes.len() {
            return;
        }
        if let Some(lit) = &self.lit {
            let rest: Vec<[f32; 4]> =
                values.iter().flatten().zip(&lit.per_pixel).map(|(v, p)| (*v - *p).extend(0.0).into()).collect();
            if rest.len() == lit.per_pixel.len() {
                gpu.queue.write_buffer(&lit.rest, 0, bytemuck::cast_slice(&rest));
            }
        }
        for (k, (m, v)) in self.meshes.iter().zip(values).enumerate() {
            if v.len() != m.vertices {
                continue;
            }
            match self.vertex_sun.as_ref().map(|s| &s[k]).filter(|s| s.len() == v.len()) {
                Some(sun) => {
                    let rest: Vec<Vec3> = v.iter().zip(sun).map(|(v, s)| *v - *s).collect();
                    gpu.queue.write_buffer(&m.radiance, 0, bytemuck::cast_slice(&rest));
                }
                None => gpu.queue.write_buffer(&m.radiance, 0, bytemuck::cast_slice(v)),
            }
        }
    }

    /// Draws the scene from `orbit` into a `size` texture; returns its egui id.
    pub fn paint(
        &mut self,
        gpu: &Gpu,
        renderer: &mut egui_wgpu::Renderer,
        size: [u32; 2],
        orbit: &Orbit,
        exposure: f32,
        raw: bool,
    ) -> egui::TextureId {
        let size = [size[0].clamp(1, 4096), size[1].clamp(1, 4096)];
        if self.target.as_ref().is_none_or(|t| t.size != size) {
            self.drawn = None;
            let old = self.target.take().and_then(|t| t.id);
            self.target = Some(make_target(gpu, (size, self.samples), renderer, old));
        }
        let output = if raw { Output::Overlay } else { Output::Display(exposure) };
        let view_proj = orbit.view_proj(size[0] as f32 / size[1] as f32).to_cols_array();
        let drawn = Drawn { size, view_proj, eye: orbit.eye(), output, revision: self.revision };
        let target = self.target.as_ref().expect("made above");
        if self.drawn.as_ref() != Some(&drawn) {
            let start = std::time::Instant::now();
            let background = wgpu::Color { r: 0.02, g: 0.02, b: 0.025, a: 1.0 };
            self.draw(gpu, &self.pipelines, &target.frame, size, orbit, output, background);
            self.drawn = Some(drawn);
            self.draw_seconds = start.elapsed().as_secs_f64();
            self.frames_drawn += 1;
        }
        target.id.expect("registered with egui")
    }

    /// The view from `orbit` as an 8-bit sRGB image; misses show the environment when one is set
    /// ([`Viewport::set_environment`]), else black.
    pub fn render_image(
        &self,
        gpu: &Gpu,
        size: [u32; 2],
        orbit: &Orbit,
        exposure: f32,
    ) -> Result<image::RgbaImage, kage_gpu::GpuError> {
        let [w, h] = [size[0].clamp(1, 4096), size[1].clamp(1, 4096)];
        let usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC;
        let color = texture(gpu, [w, h], COLOR, usage, 1);
        let frame = Frame::new(gpu, &color, self.samples);
        self.draw(gpu, &self.pipelines, &frame, [w, h], orbit, Output::Display(exposure), wgpu::Color::BLACK);
        let data = read_back(gpu, &color, [w, h], 4)?;
        Ok(image::RgbaImage::from_raw(w, h, data).expect("w × h × 4 bytes"))
    }

    /// The view from `orbit` as linear radiance, row by row from the top (no exposure, no
    /// clamping: what `kage render --gpu` writes). Builds float-target pipelines from `shaders`
    /// for the one frame.
    pub fn render_radiance(
        &self,
        gpu: &Gpu,
        shaders: &Shaders,
        size: [u32; 2],
        orbit: &Orbit,
    ) -> Result<Vec<Vec3>, kage_gpu::GpuError> {
        let [w, h] = [size[0].clamp(1, 4096), size[1].clamp(1, 4096)];
        let pipelines = self.build(gpu, shaders, (RADIANCE, 1))?;
        let usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC;
        let color = texture(gpu, [w, h], RADIANCE, usage, 1);
        let frame = Frame::new(gpu, &color, 1);
        self.draw(gpu, &pipelines, &frame, [w, h], orbit, Output::Radiance, wgpu::Color::BLACK);
        let data = read_back(gpu, &color, [w, h], 16)?;
        Ok(bytemuck::cast_slice::<u8, [f32; 4]>(&data).iter().map(|p| Vec3::new(p[0], p[1], p[2])).collect())
    }

    /// One frame: per-pixel PRT (when uploaded) or per-vertex radiance, then the lights.
    #[allow(clippy::too_many_arguments)]
    fn draw(
        &self,
        gpu: &Gpu,
        pipelines: &Pipelines,
        frame: &Frame,
        size: [u32; 2],
        orbit: &Orbit,
        output: Output,
        background: wgpu::Color,
    ) {
        let (exposure, raw) = match output {
            Output::Display(stops) => (stops, false),
            Output::Overlay | Output::Radiance => (0.0, true),
        };
        let view_proj = orbit.view_proj(size[0] as f32 / size[1] as f32);
        let view = View {
            view_proj: view_proj.to_cols_array_2d(),
            exposure: [exposure.exp2(), if raw { 1.0 } else { 0.0 }, 0.0, 0.0],
            inverse_view_proj: view_proj.inverse().to_cols_array_2d(),
            eye: orbit.eye().extend(1.0).into(),
            sun_clip: self.sun.clip.to_cols_array_2d(),
            sun_direction: self.sun.direction(),
            sun_shadow: self.sun.params(),
        };
        gpu.queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&view));
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("preview"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &frame.color,
                    resolve_target: frame.resolved.as_ref(),
                    depth_slice: None,
                    ops: wgpu::Operations { load: wgpu::LoadOp::Clear(background), store: wgpu::StoreOp::Store },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &frame.depth,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                    stencil_ops: None,
                }),
                ..Default::default()
            });
            pass.set_bind_group(0, &self.bind, &[]);
            // The error overlay keeps a plain background: its colours are not radiance.
            if let Some(sky) = self.sky.as_ref().filter(|_| output != Output::Overlay) {
                pass.set_pipeline(&pipelines.sky);
                pass.set_bind_group(1, &sky.bind, &[]);
                pass.draw(0..3, 0..1);
            }
            let per_pixel = match (&self.lit, &pipelines.lit, &self.prt, &pipelines.prt) {
                (Some(lit), Some(pipeline), _, _) => Some((pipeline, &lit.bind, &lit.ranges)),
                (_, _, Some(prt), Some(pipeline)) => Some((pipeline, &prt.bind, &prt.ranges)),
                _ => None,
            };
            let per_vertex = match per_pixel {
                Some((pipeline, bind, ranges)) => {
                    pass.set_pipeline(pipeline);
                    pass.set_bind_group(1, bind, &[]);
                    for (range, mesh) in ranges.iter().zip(&self.meshes) {
                        pass.set_bind_group(2, &mesh.texture, &[]);
                        pass.draw(range.clone(), 0..1);
                    }
                    &self.meshes[..0]
                }
                None => &self.meshes[..],
            };
            pass.set_pipeline(&pipelines.main);
            // A light is one-sided: its back is dark, as in `kage render`'s images. The eye is on
            // one side of a flat polygon for all of it, so the side is chosen per light.
            let eye = orbit.eye();
            for (m, side) in &self.lights {
                let shown = if (eye - side.centre).dot(side.normal) > 0.0 { side.radiance } else { Vec3::ZERO };
                gpu.queue.write_buffer(&m.radiance, 0, bytemuck::cast_slice(&vec![shown; m.vertices]));
            }
            for m in per_vertex.iter().chain(self.lights.iter().map(|(m, _)| m)) {
                m.draw(&mut pass);
            }
        }
        gpu.queue.submit([encoder.finish()]);
    }
}

fn texture(
    gpu: &Gpu,
    [w, h]: [u32; 2],
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
    samples: u32,
) -> wgpu::Texture {
    gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("preview"),
        size: wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: samples,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    })
}

/// Copies a texture of `texel`-byte texels into rows of bytes (padded to wgpu's 256-byte
/// alignment on the way, unpadded on return).
fn read_back(gpu: &Gpu, color: &wgpu::Texture, [w, h]: [u32; 2], texel: u32) -> Result<Vec<u8>, kage_gpu::GpuError> {
    let row = (texel * w).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
    let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("preview read-back"),
        size: (row * h) as u64,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    encoder.copy_texture_to_buffer(
        color.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(row), rows_per_image: Some(h) },
        },
        wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
    );
    gpu.queue.submit([encoder.finish()]);
    let data = kage_gpu::buffers::map_read(gpu, &buffer)?;
    Ok((0..h as usize).flat_map(|y| data[y * row as usize..][..(texel * w) as usize].to_vec()).collect())
}

/// The per-pixel PRT draw of every receiver: its triangles, per-vertex terms and the shadow
/// arrays, bound to `layout`.
fn prt_draw(gpu: &Gpu, layout: &wgpu::BindGroupLayout, flat: &FlatScene, frame: &prt::Frame) -> PrtDraw {
    let terms = frame.vertex_terms();
    let posed = frame.posed();
    let (mut vertices, mut indices, mut ranges) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..flat.instances.len() {
        let mesh = flat.mesh(i);
        let (base, start) = (vertices.len() as u32, indices.len() as u32);
        indices.extend(mesh.triangles.iter().flatten().map(|k| base + k));
        ranges.push(start..indices.len() as u32);
        let group = posed.group_of[i] as f32;
        vertices.extend(detail::vertices(flat, i).iter().enumerate().map(|(v, d)| {
            let p = flat.vertex(i, v).0;
            PrtVertex {
                p: [p.x, p.y, p.z, group],
                ls: terms.ls[i][v].extend(0.0).into(),
                albedo: terms.albedo[i][v].extend(0.0).into(),
                uv_cut: [d.uv[0], d.uv[1], d.cut[0], d.cut[1]],
                at_vertex: Vec3::from(d.at_vertex).extend(0.0).into(),
            }
        }));
    }
    let shadows = ShadowArrays::new(posed);
    let params = PrtParams { regions: posed.regions.len() as u32, groups: posed.silhouettes.len() as u32, pad: [0; 2] };
    let buffers = [
        uniform(gpu, "preview prt params", &params),
        storage(gpu, "preview indices", &indices),
        storage(gpu, "preview prt vertices", &vertices),
        storage(gpu, "preview shadow t", &terms.shadow_t.concat()),
        storage(gpu, "preview regions", &shadows.regions),
        storage(gpu, "preview silhouettes", &shadows.silhouettes),
        storage(gpu, "preview tables", &shadows.tables),
    ];
    PrtDraw { bind: bind_buffers(gpu, layout, &buffers), ranges }
}

/// A bind group of `buffers` at bindings 0, 1, … of `layout`.
fn bind_buffers(gpu: &Gpu, layout: &wgpu::BindGroupLayout, buffers: &[wgpu::Buffer]) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = buffers
        .iter()
        .enumerate()
        .map(|(k, b)| wgpu::BindGroupEntry { binding: k as u32, resource: b.as_entire_binding() })
        .collect();
    gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("preview storage"),
        layout,
        entries: &entries,
    })
}

/// The per-pixel lights' draw of every instance, bound to `layout` with the environment's
/// chain `mips` (uploaded from `lights.environment`); `None` when a light is one the shader
/// does not take or the terms do not fit the snapshot.
fn lit_draw(
    gpu: &Gpu,
    layout: &wgpu::BindGroupLayout,
    flat: &FlatScene,
    lights: &PixelLights,
    mips: Option<&wgpu::Buffer>,
) -> Option<LitDraw> {
    let gpu_lights = flat.lights.iter().map(kage_gpu::bspvt::gpu_light).collect::<Result<Vec<_>, _>>().ok()?;
    let environment = lights.environment.as_ref().filter(|_| mips.is_some());
    let specular = environment.map(|e| &e.specular);
    let counts = || (0..flat.instances.len()).map(|i| flat.vertex_count(i));
    let fits = |v: &VertexValues| v.iter().map(Vec::len).eq(counts());
    let shape = |v: &[Vec<f32>]| v.iter().map(Vec::len).eq(counts());
    let sun = environment.and_then(|e| e.sun.as_ref());
    let sun_fits = sun.is_none_or(|s| fits(&s.values));
    if !fits(&lights.values) || specular.is_some_and(|s| !fits(&s.values) || !shape(&s.weights)) || !sun_fits {
        return None;
    }
    let (mut vertices, mut indices, mut lobes, mut ranges) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for i in 0..flat.instances.len() {
        let mesh = flat.mesh(i);
        let base = vertices.len() as u32;
        let start = indices.len() as u32;
        indices.extend(mesh.triangles.iter().flatten().map(|k| base + k));
        ranges.push(start..indices.len() as u32);
        let detail = detail::vertices(flat, i);
        let weight = |v: usize| specular.map_or(0.0, |s| s.weights[i][v]);
        vertices.extend((0..mesh.positions.len()).zip(&detail).map(|(v, d)| lit_vertex(flat, i, v, d, weight(v))));
        for v in 0..mesh.positions.len() {
            lobes.extend(lights.lobes.vertex(i, v).iter().map(|[d, s]| [d[0], d[1], s[0], s[1]]));
        }
    }
    if lobes.len() != vertices.len() * flat.lights.len() {
        return None;
    }
    let mut per_pixel: Vec<Vec3> = lights.values.iter().flatten().copied().collect();
    for values in specular.map(|s| &s.values).into_iter().chain(sun.map(|s| &s.values)) {
        per_pixel.iter_mut().zip(values.iter().flatten()).for_each(|(p, s)| *p += *s);
    }
    let tables: Vec<f32> =
        ltc::table().entries().iter().flatten().chain(ggx::albedo_tables().concat().iter()).copied().collect();
    let params = lit_params(flat.lights.len(), environment.map(|e| &e.prefiltered), sun.map(|s| &s.sun));
    let rest = storage(gpu, "preview rest", &vec![[0.0f32; 4]; vertices.len()]);
    let mips = mips.cloned().unwrap_or_else(|| storage(gpu, "preview no mips", &[[0.0f32; 4]]));
    let buffers = [
        uniform(gpu, "preview lit params", &params),
        storage(gpu, "preview indices", &indices),
        storage(gpu, "preview lit vertices", &vertices),
        rest.clone(),
        storage(gpu, "preview lobes", &lobes),
        storage(gpu, "preview lights", &gpu_lights),
        storage(gpu, "preview ltc tables", &tables),
        mips,
    ];
    Some(LitDraw { bind: bind_buffers(gpu, layout, &buffers), rest, per_pixel, ranges })
}

/// The per-pixel lights' parameters: the light count and where the chain's levels are (none
/// without an environment).
fn lit_params(lights: usize, chain: Option<&Prefiltered>, sun: Option<&Sun>) -> LitParams {
    let mut params = LitParams {
        lights: lights as u32,
        levels: 0,
        pad: [0; 2],
        to_map: [[0.0; 4]; 3],
        level: [[0; 4]; MAX_LEVELS],
        sun_direction: [0.0; 4],
        sun_irradiance: [0.0; 4],
    };
    if let Some(sun) = sun {
        let least = (SUN_ALPHA_FLOOR * sun.angular_radius).sqrt().max(1e-6);
        params.sun_direction = sun.direction.extend(least).into();
        params.sun_irradiance = sun.irradiance.extend(0.0).into();
    }
    let Some(chain) = chain else { return params };
    let (rotation, intensity) = chain.placement();
    let m = glam::Mat3::from_quat(rotation).transpose();
    let (mut offset, mut texel) = (0u32, 0.0f32);
    for (k, (w, h, texels)) in chain.levels().take(MAX_LEVELS).enumerate() {
        params.level[k] = [w as u32, h as u32, offset, 0];
        offset += texels.len() as u32;
        if k == 0 {
            texel = 4.0 * std::f32::consts::PI / (w * h) as f32;
        }
        params.levels = k as u32 + 1;
    }
    params.to_map = [m.x_axis.extend(intensity).into(), m.y_axis.extend(texel).into(), m.z_axis.extend(0.0).into()];
    params
}

/// The chain's levels, one after another, as a storage array.
fn mip_buffer(gpu: &Gpu, chain: &Prefiltered) -> wgpu::Buffer {
    let texels: Vec<[f32; 4]> =
        chain.levels().take(MAX_LEVELS).flat_map(|(_, _, t)| t.iter().map(|c| c.extend(0.0).into())).collect();
    storage(gpu, "preview mips", &texels)
}

/// Vertex `v` of instance `i` as the per-pixel lights read it (`d`: its texture detail).
/// `weight`: the environment's specular weight there.
fn lit_vertex(flat: &FlatScene, i: usize, v: usize, d: &Detail, weight: f32) -> LitVertex {
    let (p, n) = flat.vertex(i, v);
    // The metallic-roughness texture is read per pixel: its factors here, not its value.
    let (m, factors) = (flat.vertex_material(i, v), flat.instances[i].material);
    let mr = detail::metallic_roughness_uv(flat, i, v);
    LitVertex {
        p: p.extend(weight).into(),
        n: n.normalize_or_zero().extend(0.0).into(),
        base: m.base_color.extend(factors.metallic).into(),
        surface: [factors.roughness, m.specular, d.uv[0], d.uv[1]],
        at_vertex: Vec3::from(d.at_vertex).extend(0.0).into(),
        mr_uv: [mr[0], mr[1], d.cut[0], d.cut[1]],
    }
}

/// Group 1 of the per-pixel PRT and lights pipelines: parameters, then storage arrays —
/// indices read by the vertex stage, vertices by both, `fragment` more by the fragment (see
/// preview.wgsl); `None` when the device allows fewer storage buffers per stage than the
/// fragment stage binds.
fn storage_layout(gpu: &Gpu, fragment: usize) -> Option<wgpu::BindGroupLayout> {
    use wgpu::ShaderStages as S;
    if (gpu.device.limits().max_storage_buffers_per_shader_stage as usize) < fragment + 1 {
        return None;
    }
    let visibility =
        [S::FRAGMENT, S::VERTEX, S::VERTEX_FRAGMENT].into_iter().chain(std::iter::repeat_n(S::FRAGMENT, fragment));
    let entries: Vec<wgpu::BindGroupLayoutEntry> = visibility
        .enumerate()
        .map(|(k, visibility)| wgpu::BindGroupLayoutEntry {
            binding: k as u32,
            visibility,
            ty: wgpu::BindingType::Buffer {
                ty: if k == 0 {
                    wgpu::BufferBindingType::Uniform
                } else {
                    wgpu::BufferBindingType::Storage { read_only: true }
                },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        })
        .collect();
    Some(gpu.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("preview storage"),
        entries: &entries,
    }))
}

/// The bind group layouts the pipelines use: the view (group 0), then the base-colour texture
/// (per-vertex pipeline), the environment map (sky) or the storage arrays (per-pixel PRT and
/// lights, both with the base-colour texture as group 2) as group 1.
#[derive(Clone, Copy)]
struct Layouts<'a> {
    view: &'a wgpu::BindGroupLayout,
    detail: &'a wgpu::BindGroupLayout,
    sky: &'a wgpu::BindGroupLayout,
    prt: Option<&'a wgpu::BindGroupLayout>,
    lit: Option<&'a wgpu::BindGroupLayout>,
}

/// The pipelines of preview.wgsl.
fn build_pipelines(
    gpu: &Gpu,
    shaders: &Shaders,
    layouts: Layouts,
    target: (wgpu::TextureFormat, u32),
) -> Result<Pipelines, kage_gpu::ShaderError> {
    let module = shaders.module(&gpu.device, "preview.wgsl")?;
    let attribute = |location, format, offset| wgpu::VertexAttribute { format, offset, shader_location: location };
    let vec3 = wgpu::VertexFormat::Float32x3;
    let attributes = [
        vec![attribute(0, vec3, 0)],
        vec![attribute(1, vec3, 0)],
        vec![
            attribute(2, wgpu::VertexFormat::Float32x2, 0),
            attribute(3, vec3, 8),
            attribute(4, wgpu::VertexFormat::Float32x2, 20),
        ],
        vec![attribute(5, vec3, 0)],
    ];
    let strides = [12, 12, std::mem::size_of::<Detail>() as u64, 12];
    let per_vertex = [0, 1, 2, 3].map(|k| {
        Some(wgpu::VertexBufferLayout {
            array_stride: strides[k],
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &attributes[k],
        })
    });
    let view = Some(layouts.view);
    // The device may still refuse what naga accepted (e.g. storage buffers in the vertex stage).
    kage_gpu::buffers::checked(gpu, "preview pipelines", || {
        let pipeline = |groups: &[Option<&wgpu::BindGroupLayout>], stages, buffers, depth| {
            render_pipeline(gpu, &module, groups, (stages, target), buffers, depth)
        };
        let main = pipeline(&[view, Some(layouts.detail)], ("vs_main", "fs_main"), &per_vertex, Depth::Tested);
        let prt = layouts
            .prt
            .map(|prt| pipeline(&[view, Some(prt), Some(layouts.detail)], ("vs_prt", "fs_prt"), &[], Depth::Tested));
        let lit = layouts.lit.map(|storage| {
            pipeline(&[view, Some(storage), Some(layouts.detail)], ("vs_lit", "fs_lit"), &[], Depth::Tested)
        });
        let sky = pipeline(&[view, Some(layouts.sky)], ("vs_sky", "fs_sky"), &[], Depth::Behind);
        let shadow = pipeline(&[view, Some(layouts.detail)], ("vs_shadow", "fs_shadow"), &per_vertex, Depth::Shadow);
        Pipelines { main, prt, lit, sky, shadow }
    })
    .map_err(|e| kage_gpu::ShaderError {
        file: "preview.wgsl".into(),
        line: 0,
        message: e.to_string(),
        report: format!("preview.wgsl: {e}"),
    })
}

/// How a pipeline uses the depth buffer.
#[derive(Clone, Copy, PartialEq)]
enum Depth {
    /// Tested and written: geometry.
    Tested,
    /// Neither: the background, drawn first.
    Behind,
    /// Tested and written, with a slope bias, and nothing else: the sun's depth map.
    Shadow,
}

fn render_pipeline(
    gpu: &Gpu,
    module: &wgpu::ShaderModule,
    groups: &[Option<&wgpu::BindGroupLayout>],
    ((vs, fs), (target, samples)): ((&str, &str), (wgpu::TextureFormat, u32)),
    buffers: &[Option<wgpu::VertexBufferLayout>],
    depth: Depth,
) -> wgpu::RenderPipeline {
    let tested = depth != Depth::Behind;
    let shadow = depth == Depth::Shadow;
    let color = [Some(target.into())];
    let pipeline_layout = gpu.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("preview"),
        bind_group_layouts: groups,
        immediate_size: 0,
    });
    gpu.device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("preview"),
        layout: Some(&pipeline_layout),
        vertex: wgpu::VertexState { module, entry_point: Some(vs), buffers, compilation_options: Default::default() },
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some(fs),
            targets: if shadow { &[] } else { &color },
            compilation_options: Default::default(),
        }),
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: Some(wgpu::DepthStencilState {
            format: if shadow { sun_shadow::FORMAT } else { DEPTH },
            depth_write_enabled: Some(tested),
            depth_compare: Some(if tested { wgpu::CompareFunction::Less } else { wgpu::CompareFunction::Always }),
            stencil: Default::default(),
            // Slopes facing the sun at a grazing angle would shadow themselves.
            bias: if shadow {
                wgpu::DepthBiasState { constant: 0, slope_scale: 1.5, clamp: 0.0 }
            } else {
                Default::default()
            },
        }),
        // The sun's depth map has one sample, whatever the view's.
        multisample: wgpu::MultisampleState { count: if shadow { 1 } else { samples }, ..Default::default() },
        multiview_mask: None,
        cache: None,
    })
}

/// What a drawable shows: radiance and texture detail per vertex, and the texture.
struct Look<'a> {
    radiance: &'a [Vec3],
    detail: &'a [Detail],
    texture: wgpu::BindGroup,
}

fn mesh_buffers(gpu: &Gpu, positions: &[Vec3], look: Look, indices: &[u32]) -> Mesh {
    let init = |label, contents: &[u8], usage| {
        gpu.device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
    };
    let v = wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST;
    Mesh {
        positions: init("positions", bytemuck::cast_slice(positions), v),
        radiance: init("radiance", bytemuck::cast_slice(look.radiance), v),
        detail: init("detail", bytemuck::cast_slice(look.detail), wgpu::BufferUsages::VERTEX),
        sun: init("sun", bytemuck::cast_slice(&vec![Vec3::ZERO; positions.len()]), v),
        indices: init("indices", bytemuck::cast_slice(indices), wgpu::BufferUsages::INDEX),
        texture: look.texture,
        count: indices.len() as u32,
        vertices: positions.len(),
    }
}

fn make_target(
    gpu: &Gpu,
    (size, samples): ([u32; 2], u32),
    renderer: &mut egui_wgpu::Renderer,
    old: Option<egui::TextureId>,
) -> Target {
    let usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING;
    let frame = Frame::new(gpu, &texture(gpu, size, COLOR, usage, 1), samples);
    let shown = frame.shown();
    let id = match old {
        Some(id) => {
            renderer.update_egui_texture_from_wgpu_texture(&gpu.device, shown, wgpu::FilterMode::Linear, id);
            id
        }
        None => renderer.register_native_texture(&gpu.device, shown, wgpu::FilterMode::Linear),
    };
    Target { size, frame, id: Some(id) }
}
