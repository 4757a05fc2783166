//! The environment behind the geometry in the viewport, as `kage render`'s images show it: a
//! full-screen pass (`vs_sky`/`fs_sky` in preview.wgsl) that looks the view ray up in the
//! equirectangular map — filtered bilinearly (`EnvMap::bilinear`), the light's rotation and intensity applied, the
//! mapping of `kage_engine::scene::environment::dir_to_uv`.

use crate::Gpu;
use crate::buffers::texture_2d;
use bytemuck::{Pod, Zeroable};
use glam::Vec4;
use kage_engine::scene::{EnvMap, EnvironmentLight};
use std::sync::Arc;
use wgpu::util::DeviceExt;

/// `Sky` of preview.wgsl: cos and sin of the rotation about +Y, the intensity.
#[repr(C)]
#[derive(Clone, Copy, PartialEq, Pod, Zeroable)]
struct Params {
    rotation_intensity: [f32; 4],
}

/// An environment map on the device, with the light's rotation and intensity.
pub struct Sky {
    map: Arc<EnvMap>,
    params: wgpu::Buffer,
    /// What `params` holds.
    shown: Params,
    /// Group 1 of the sky pipeline.
    pub bind: wgpu::BindGroup,
}

impl Sky {
    /// `env` on the device, reusing `old`'s texture when it shows the same map.
    pub fn new(gpu: &Gpu, layout: &wgpu::BindGroupLayout, env: &EnvironmentLight, old: Option<Sky>) -> Self {
        let sky = match old.filter(|o| Arc::ptr_eq(&o.map, &env.map)) {
            Some(same) => same,
            None => upload(gpu, layout, &env.map),
        };
        let mut sky = sky;
        sky.shown = params(env);
        gpu.queue.write_buffer(&sky.params, 0, bytemuck::bytes_of(&sky.shown));
        sky
    }

    /// True when this shows `env` as it is (its map, rotation and intensity).
    pub fn shows(&self, env: &EnvironmentLight) -> bool {
        Arc::ptr_eq(&self.map, &env.map) && self.shown == params(env)
    }
}

fn params(env: &EnvironmentLight) -> Params {
    let (sin, cos) = env.rotation.sin_cos();
    Params { rotation_intensity: [cos, sin, env.intensity, 0.0] }
}

/// The map as an RGBA f32 texture read texel by texel, and its bind group.
fn upload(gpu: &Gpu, layout: &wgpu::BindGroupLayout, map: &Arc<EnvMap>) -> Sky {
    let texels: Vec<Vec4> = map.texels.iter().map(|t| t.extend(1.0)).collect();
    let size = [map.width as u32, map.height as u32];
    let view = texture_2d(gpu, "preview sky", size, wgpu::TextureFormat::Rgba32Float, bytemuck::cast_slice(&texels));
    let shown = Params { rotation_intensity: [1.0, 0.0, 1.0, 0.0] };
    let params = gpu.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("preview sky"),
        contents: bytemuck::bytes_of(&shown),
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
    });
    let bind = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("preview sky"),
        layout,
        entries: &[
            wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::TextureView(&view) },
            wgpu::BindGroupEntry { binding: 1, resource: params.as_entire_binding() },
        ],
    });
    Sky { map: map.clone(), params, shown, bind }
}

/// Group 1 of the sky pipeline: the map and its parameters.
pub fn layout(gpu: &Gpu) -> wgpu::BindGroupLayout {
    let texture = wgpu::BindingType::Texture {
        sample_type: wgpu::TextureSampleType::Float { filterable: false },
        view_dimension: wgpu::TextureViewDimension::D2,
        multisampled: false,
    };
    let params = wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Uniform,
        has_dynamic_offset: false,
        min_binding_size: None,
    };
    let entry =
        |binding, ty| wgpu::BindGroupLayoutEntry { binding, visibility: wgpu::ShaderStages::FRAGMENT, ty, count: None };
    gpu.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("preview sky"),
        entries: &[entry(0, texture), entry(1, params)],
    })
}
