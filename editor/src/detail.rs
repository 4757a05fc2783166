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

/// Group 1 of the per-vertex pipeline (group 2 of the per-pixel lights): the base-colour
/// texture and its sampler, then the metallic-roughness texture and its sampler (read per pixel
/// by the per-pixel lights only).
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
        entries: &[
            entry(0, texture),
            entry(1, wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering)),
            entry(2, texture),
            entry(3, wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering)),
        ],
    })
}

/// The base-colour slot of instance `i` (`None`: untextured).
pub fn slot(flat: &FlatScene, i: usize) -> Option<TextureSlot> {
    flat.instances[i].maps.base_color
}

/// The metallic-roughness texture's UV at vertex `v` of instance `i` (zero without one).
pub fn metallic_roughness_uv(flat: &FlatScene, i: usize, v: usize) -> [f32; 2] {
    let (mesh, slot) = (flat.mesh(i), flat.instances[i].maps.metallic_roughness);
    let uv = |set: &[glam::Vec2]| set.get(v).copied().unwrap_or_default();
    slot.map_or([0.0; 2], |s| s.uv(uv(&mesh.uvs), uv(&mesh.uvs1)).into())
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

/// The bind group of the base-colour and metallic-roughness textures (`None`: one white texel)
/// with their wrap modes and linear filtering, as the CPU's bilinear lookup.
pub fn bind_group(
    gpu: &Gpu,
    layout: &wgpu::BindGroupLayout,
    base: Option<&Texture>,
    metallic_roughness: Option<&Texture>,
) -> wgpu::BindGroup {
    let (base, base_sampler) = view(gpu, base, true);
    let (mr, mr_sampler) = view(gpu, metallic_roughness, false);
    gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("preview textures"),
        layout,
        entries: &[
            wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::TextureView(&base) },
            wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::Sampler(&base_sampler) },
            wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(&mr) },
            wgpu::BindGroupEntry { binding: 3, resource: wgpu::BindingResource::Sampler(&mr_sampler) },
        ],
    })
}

/// `texture` (one white texel without one) on the device, sRGB-encoded (`srgb`: a colour
/// texture) or linear (data), with its sampler.
fn view(gpu: &Gpu, texture: Option<&Texture>, srgb: bool) -> (wgpu::TextureView, wgpu::Sampler) {
    let white = Texture::new(1, 1, vec![Vec3::ONE], [Wrap::Repeat; 2]);
    let t = texture.unwrap_or(&white);
    let encode = |x: f32| if srgb { linear_to_srgb(x.clamp(0.0, 1.0)) } else { x.clamp(0.0, 1.0) };
    let bytes: Vec<u8> = t
        .texels
        .iter()
        .flat_map(|c| {
            let [r, g, b] = c.to_array().map(|x| (encode(x) * 255.0).round() as u8);
            [r, g, b, 255]
        })
        .collect();
    let size = [t.width as u32, t.height as u32];
    let format = if srgb { wgpu::TextureFormat::Rgba8UnormSrgb } else { wgpu::TextureFormat::Rgba8Unorm };
    let view = texture_2d(gpu, "preview texture", size, format, &bytes);
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
    (view, sampler)
}
