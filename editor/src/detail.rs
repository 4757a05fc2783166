//! Texture detail in the viewport, as engines show baked lighting: the lighting comes from the
//! vertices (their radiance, with the material at the vertex), the base-colour texture from
//! each pixel. A pixel's radiance is the interpolated vertex radiance times the texture there
//! over the texture's value interpolated from the vertices — exact for the diffuse part, which
//! is proportional to the base colour, and one where the material does not vary. The CPU
//! image (`Look::render`) shades the material per pixel; this is the preview's cheaper form.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use kage_engine::math::color::linear_to_srgb;
use kage_engine::scene::texture::{Texture, Wrap};
use kage_engine::scene::{FlatScene, TextureSlot};
use kage_gpu::Gpu;
use kage_gpu::buffers::texture_2d;

/// `detail` of preview.wgsl's vertex input: the base-colour UV and the texture's value there.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub struct Detail {
    /// The base-colour UV (the slot's texture transform applied).
    pub uv: [f32; 2],
    /// The texture's value at the vertex (linear RGB).
    pub at_vertex: [f32; 3],
}

/// A texture with nothing to modulate: one white texel, value one at every vertex.
pub const PLAIN: Detail = Detail { uv: [0.0; 2], at_vertex: [1.0; 3] };

/// Group 1 of the per-vertex pipeline: the base-colour texture and its sampler.
pub fn layout(gpu: &Gpu) -> wgpu::BindGroupLayout {
    let entry =
        |binding, ty| wgpu::BindGroupLayoutEntry { binding, visibility: wgpu::ShaderStages::FRAGMENT, ty, count: None };
    let texture = wgpu::BindingType::Texture {
        sample_type: wgpu::TextureSampleType::Float { filterable: true },
        view_dimension: wgpu::TextureViewDimension::D2,
        multisampled: false,
    };
    gpu.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("preview base colour"),
        entries: &[entry(0, texture), entry(1, wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering))],
    })
}

/// The base-colour slot of instance `i` (`None`: untextured).
pub fn slot(flat: &FlatScene, i: usize) -> Option<TextureSlot> {
    flat.instances[i].maps.base_color
}

/// Per vertex of instance `i`: the slot's UV and the texture's value there ([`PLAIN`] without
/// a slot).
pub fn vertices(flat: &FlatScene, i: usize) -> Vec<Detail> {
    let mesh = flat.mesh(i);
    let Some(s) = slot(flat, i) else { return vec![PLAIN; mesh.positions.len()] };
    let texture = &flat.textures[s.texture as usize];
    let uv = |set: &[glam::Vec2], v: usize| set.get(v).copied().unwrap_or_default();
    (0..mesh.positions.len())
        .map(|v| {
            let at = s.uv(uv(&mesh.uvs, v), uv(&mesh.uvs1, v));
            Detail { uv: at.into(), at_vertex: texture.sample(at).into() }
        })
        .collect()
}

/// The bind group of `texture` (`None`: one white texel) with its wrap modes and linear
/// filtering, as the CPU's bilinear lookup.
pub fn bind_group(gpu: &Gpu, layout: &wgpu::BindGroupLayout, texture: Option<&Texture>) -> wgpu::BindGroup {
    let white = Texture::new(1, 1, vec![Vec3::ONE], [Wrap::Repeat; 2]);
    let t = texture.unwrap_or(&white);
    let srgb: Vec<u8> = t
        .texels
        .iter()
        .flat_map(|c| {
            let [r, g, b] = c.to_array().map(|x| (linear_to_srgb(x.clamp(0.0, 1.0)) * 255.0).round() as u8);
            [r, g, b, 255]
        })
        .collect();
    let size = [t.width as u32, t.height as u32];
    let view = texture_2d(gpu, "preview base colour", size, wgpu::TextureFormat::Rgba8UnormSrgb, &srgb);
    let address = |w: Wrap| match w {
        Wrap::Clamp => wgpu::AddressMode::ClampToEdge,
        Wrap::Repeat => wgpu::AddressMode::Repeat,
        Wrap::Mirror => wgpu::AddressMode::MirrorRepeat,
    };
    let sampler = gpu.device.create_sampler(&wgpu::SamplerDescriptor {
        label: Some("preview base colour"),
        address_mode_u: address(t.wrap[0]),
        address_mode_v: address(t.wrap[1]),
        mag_filter: wgpu::FilterMode::Linear,
        min_filter: wgpu::FilterMode::Linear,
        ..Default::default()
    });
    gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("preview base colour"),
        layout,
        entries: &[
            wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::TextureView(&view) },
            wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::Sampler(&sampler) },
        ],
    })
}
