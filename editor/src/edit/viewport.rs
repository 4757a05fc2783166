//! The 3D view: the scene's meshes (and light polygons) drawn with per-vertex radiance by
//! `shaders/preview.wgsl` into an offscreen texture that egui shows as an image.

use super::camera::Orbit;
use bytemuck::{Pod, Zeroable};
use eframe::{egui, egui_wgpu};
use glam::Vec3;
use kage_engine::scene::{FlatScene, Scene};
use kage_gpu::{Gpu, Shaders};
use wgpu::util::DeviceExt;

const COLOR: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct View {
    view_proj: [[f32; 4]; 4],
    exposure: [f32; 4],
}

/// One drawable: world positions, radiance per vertex, triangle indices.
struct Mesh {
    positions: wgpu::Buffer,
    radiance: wgpu::Buffer,
    indices: wgpu::Buffer,
    count: u32,
    vertices: usize,
}

/// The offscreen target.
struct Target {
    size: [u32; 2],
    color: wgpu::TextureView,
    depth: wgpu::TextureView,
    id: Option<egui::TextureId>,
}

/// The viewport renderer.
pub struct Viewport {
    pipeline: wgpu::RenderPipeline,
    uniform: wgpu::Buffer,
    bind: wgpu::BindGroup,
    layout: wgpu::BindGroupLayout,
    meshes: Vec<Mesh>,
    /// Flat-coloured light polygons.
    lights: Vec<Mesh>,
    target: Option<Target>,
    /// The shader generation the pipeline was built from.
    pub generation: u64,
}

impl Viewport {
    /// Builds the pipeline from `shaders` (`preview.wgsl`).
    pub fn new(gpu: &Gpu, shaders: &Shaders) -> Result<Self, kage_gpu::ShaderError> {
        let layout = gpu.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("preview view"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            }],
        });
        let uniform = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("preview view"),
            size: std::mem::size_of::<View>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("preview view"),
            layout: &layout,
            entries: &[wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() }],
        });
        let pipeline = build_pipeline(gpu, shaders, &layout)?;
        Ok(Self {
            pipeline,
            uniform,
            bind,
            layout,
            meshes: Vec::new(),
            lights: Vec::new(),
            target: None,
            generation: 0,
        })
    }

    /// Rebuilds the pipeline (hot reload); on error the previous one stays.
    pub fn reload(&mut self, gpu: &Gpu, shaders: &Shaders, generation: u64) -> Result<(), kage_gpu::ShaderError> {
        self.generation = generation;
        self.pipeline = build_pipeline(gpu, shaders, &self.layout)?;
        Ok(())
    }

    /// Uploads every instance's world-space triangles and every light polygon.
    pub fn upload_geometry(&mut self, gpu: &Gpu, scene: &Scene, flat: &FlatScene) {
        self.meshes = (0..flat.instances.len())
            .map(|i| {
                let mesh = &scene.meshes[flat.instances[i].mesh as usize];
                let p: Vec<Vec3> = (0..mesh.positions.len()).map(|v| flat.vertex(&scene.meshes, i, v).0).collect();
                let idx: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
                mesh_buffers(gpu, &p, &vec![Vec3::ZERO; p.len()], &idx)
            })
            .collect();
        self.lights = flat
            .lights
            .iter()
            .map(|l| {
                let idx: Vec<u32> = (1..l.points.len() as u32 - 1).flat_map(|k| [0, k, k + 1]).collect();
                mesh_buffers(gpu, &l.points, &vec![l.radiance; l.points.len()], &idx)
            })
            .collect();
    }

    /// Uploads per-instance vertex radiance (ignored when the shapes disagree: a new snapshot
    /// is on its way).
    pub fn upload_radiance(&mut self, gpu: &Gpu, values: &[Vec<Vec3>]) {
        if values.len() != self.meshes.len() {
            return;
        }
        for (m, v) in self.meshes.iter().zip(values) {
            if v.len() == m.vertices {
                gpu.queue.write_buffer(&m.radiance, 0, bytemuck::cast_slice(v));
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
            let old = self.target.take().and_then(|t| t.id);
            self.target = Some(make_target(gpu, size, renderer, old));
        }
        let target = self.target.as_ref().expect("made above");
        let view = View {
            view_proj: orbit.view_proj(size[0] as f32 / size[1] as f32).to_cols_array_2d(),
            exposure: [exposure.exp2(), if raw { 1.0 } else { 0.0 }, 0.0, 0.0],
        };
        gpu.queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&view));
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("preview"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &target.color,
                    resolve_target: None,
                    depth_slice: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color { r: 0.02, g: 0.02, b: 0.025, a: 1.0 }),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &target.depth,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                    stencil_ops: None,
                }),
                ..Default::default()
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.bind, &[]);
            for m in self.meshes.iter().chain(&self.lights) {
                pass.set_vertex_buffer(0, m.positions.slice(..));
                pass.set_vertex_buffer(1, m.radiance.slice(..));
                pass.set_index_buffer(m.indices.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..m.count, 0, 0..1);
            }
        }
        gpu.queue.submit([encoder.finish()]);
        target.id.expect("registered with egui")
    }
}

fn build_pipeline(
    gpu: &Gpu,
    shaders: &Shaders,
    layout: &wgpu::BindGroupLayout,
) -> Result<wgpu::RenderPipeline, kage_gpu::ShaderError> {
    let module = shaders.module(&gpu.device, "preview.wgsl")?;
    let pipeline_layout = gpu.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("preview"),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    let attributes = [0, 1].map(|location| {
        [wgpu::VertexAttribute { format: wgpu::VertexFormat::Float32x3, offset: 0, shader_location: location }]
    });
    let layout_of =
        |a| wgpu::VertexBufferLayout { array_stride: 12, step_mode: wgpu::VertexStepMode::Vertex, attributes: a };
    let (positions, radiance) = (layout_of(&attributes[0]), layout_of(&attributes[1]));
    Ok(gpu.device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("preview"),
        layout: Some(&pipeline_layout),
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs_main"),
            buffers: &[Some(positions), Some(radiance)],
            compilation_options: Default::default(),
        },
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("fs_main"),
            targets: &[Some(COLOR.into())],
            compilation_options: Default::default(),
        }),
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DEPTH,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Less),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: Default::default(),
        multiview_mask: None,
        cache: None,
    }))
}

fn mesh_buffers(gpu: &Gpu, positions: &[Vec3], radiance: &[Vec3], indices: &[u32]) -> Mesh {
    let init = |label, contents: &[u8], usage| {
        gpu.device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
    };
    let v = wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST;
    Mesh {
        positions: init("positions", bytemuck::cast_slice(positions), v),
        radiance: init("radiance", bytemuck::cast_slice(radiance), v),
        indices: init("indices", bytemuck::cast_slice(indices), wgpu::BufferUsages::INDEX),
        count: indices.len() as u32,
        vertices: positions.len(),
    }
}

fn make_target(gpu: &Gpu, size: [u32; 2], renderer: &mut egui_wgpu::Renderer, old: Option<egui::TextureId>) -> Target {
    let texture = |format, usage| {
        gpu.device
            .create_texture(&wgpu::TextureDescriptor {
                label: Some("preview"),
                size: wgpu::Extent3d { width: size[0], height: size[1], depth_or_array_layers: 1 },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
            .create_view(&Default::default())
    };
    let color = texture(COLOR, wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING);
    let depth = texture(DEPTH, wgpu::TextureUsages::RENDER_ATTACHMENT);
    let id = match old {
        Some(id) => {
            renderer.update_egui_texture_from_wgpu_texture(&gpu.device, &color, wgpu::FilterMode::Linear, id);
            id
        }
        None => renderer.register_native_texture(&gpu.device, &color, wgpu::FilterMode::Linear),
    };
    Target { size, color, depth, id: Some(id) }
}
