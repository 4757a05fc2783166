//! The 3D view: the scene's meshes (and light polygons) drawn with per-vertex radiance by
//! `shaders/preview.wgsl` into an offscreen texture that a GUI shows as an image (the editor,
//! through egui), the base-colour texture's detail added per pixel (`detail.rs`). PRT is drawn per pixel instead when a
//! frame's terms are given ([`Viewport::upload_prt`]): the shadows between groups are looked up
//! at every pixel, not interpolated between vertices. The polygonal lights are drawn per pixel
//! when their lobes are given ([`Viewport::upload_lights`]): LTC at every pixel, the trees'
//! visibility carried from the vertices, as `kage render` does.

mod detail;
mod mesh;
mod per_pixel;
mod pipelines;
mod sky;
mod sun_shadow;
mod target;

use crate::buffers::{storage, uniform};
use crate::camera::Orbit;
use crate::prt::ShadowArrays;
use crate::{Gpu, Shaders};
use bytemuck::{Pod, Zeroable};
use detail::Detail;
use glam::Vec3;
use kage_engine::bspvt::pixel::Lobes;
use kage_engine::math::{ggx, ltc};
use kage_engine::prt;
use kage_engine::prt::prefilter::Prefiltered;
use kage_engine::prt::sun::Sun;
use kage_engine::scene::{EnvironmentLight, FlatScene, VertexValues};
use kage_engine::shading::baked::{SUN_ALPHA_FLOOR, SpecularVertices};
use mesh::*;
use per_pixel::*;
pub use per_pixel::{PixelEnvironment, PixelLights, PixelSun, VertexSun};
use pipelines::*;
use sky::Sky;
use sun_shadow::SunShadow;
pub use target::Shown;
use target::*;
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
struct ViewUniform {
    view_proj: [[f32; 4]; 4],
    exposure: [f32; 4],
    inverse_view_proj: [[f32; 4]; 4],
    eye: [f32; 4],
    sun_clip: [[f32; 4]; 4],
    sun_direction: [f32; 4],
    sun_shadow: [f32; 4],
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
    pub fn new(gpu: &Gpu, shaders: &Shaders) -> Result<Self, crate::ShaderError> {
        Self::with_samples(gpu, shaders, SAMPLES)
    }

    /// [`Self::new`] drawing `samples` per pixel (1: each pixel's centre alone, as a ray
    /// caster's image, which tests compare against).
    pub fn with_samples(gpu: &Gpu, shaders: &Shaders, samples: u32) -> Result<Self, crate::ShaderError> {
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
            size: std::mem::size_of::<ViewUniform>() as u64,
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
    pub fn reload(&mut self, gpu: &Gpu, shaders: &Shaders, generation: u64) -> Result<(), crate::ShaderError> {
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
    ) -> Result<Pipelines, crate::ShaderError> {
        let layouts = Layouts {
            view: &self.layout,
            detail: &self.detail_layout,
            sky: &self.sky_layout,
            prt: self.prt_layout.as_ref(),
            lit: self.lit_layout.as_ref(),
        };
        build_pipelines(gpu, shaders, layouts, target)
    }

    /// Seconds the last drawn frame took to record, submit and finish on the device.
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
        let view = ViewUniform { sun_clip: clip.to_cols_array_2d(), ..Zeroable::zeroed() };
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
                let look =
                    VertexData { radiance: &vec![Vec3::ZERO; p.len()], detail: &detail::vertices(flat, i), texture };
                mesh_buffers(gpu, &p, look, &idx)
            })
            .collect();
        self.lights = flat
            .lights
            .iter()
            .map(|l| {
                let idx: Vec<u32> = (1..l.points.len() as u32 - 1).flat_map(|k| [0, k, k + 1]).collect();
                let n = l.points.len();
                let look = VertexData {
                    radiance: &vec![l.radiance; n],
                    detail: &vec![detail::PLAIN; n],
                    texture: plain.clone(),
                };
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

    /// Draws the scene from `orbit` into a `size` texture (unless it already shows just that)
    /// and returns it.
    pub fn paint(&mut self, gpu: &Gpu, size: [u32; 2], orbit: &Orbit, exposure: f32, raw: bool) -> Shown<'_> {
        let size = [size[0].clamp(1, 4096), size[1].clamp(1, 4096)];
        let new = self.target.as_ref().is_none_or(|t| t.size != size);
        if new {
            self.drawn = None;
            self.target = Some(make_target(gpu, (size, self.samples)));
        }
        let output = if raw { Output::Overlay } else { Output::Display(exposure) };
        let view_proj = orbit.view_proj(size[0] as f32 / size[1] as f32).to_cols_array();
        let drawn = Drawn { size, view_proj, eye: orbit.eye(), output, revision: self.revision };
        let target = self.target.as_ref().expect("made above");
        if self.drawn.as_ref() != Some(&drawn) {
            let start = std::time::Instant::now();
            let background = wgpu::Color { r: 0.02, g: 0.02, b: 0.025, a: 1.0 };
            self.draw(gpu, &self.pipelines, &target.frame, size, orbit, output, background);
            // Wait for the device: a CPU device (lavapipe) renders on its own threads after the
            // submit, and the editor paces its previews by what a frame really costs. The
            // window's next present waits for this frame anyway; a lost device shows at the
            // next submit.
            let _ = gpu.device.poll(wgpu::PollType::wait_indefinitely());
            self.drawn = Some(drawn);
            self.draw_seconds = start.elapsed().as_secs_f64();
            self.frames_drawn += 1;
        }
        Shown { view: target.frame.shown(), new }
    }

    /// The view from `orbit` as an 8-bit sRGB image; misses show the environment when one is set
    /// ([`Viewport::set_environment`]), else black.
    pub fn render_image(
        &self,
        gpu: &Gpu,
        size: [u32; 2],
        orbit: &Orbit,
        exposure: f32,
    ) -> Result<image::RgbaImage, crate::GpuError> {
        let [w, h] = [size[0].clamp(1, 4096), size[1].clamp(1, 4096)];
        let usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC;
        let color = texture(gpu, [w, h], COLOR, usage, 1);
        let frame = Attachments::new(gpu, &color, self.samples);
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
    ) -> Result<Vec<Vec3>, crate::GpuError> {
        let [w, h] = [size[0].clamp(1, 4096), size[1].clamp(1, 4096)];
        let pipelines = self.build(gpu, shaders, (RADIANCE, 1))?;
        let usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC;
        let color = texture(gpu, [w, h], RADIANCE, usage, 1);
        let frame = Attachments::new(gpu, &color, 1);
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
        frame: &Attachments,
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
        let view = ViewUniform {
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
