//! Texture detail in the viewport, as engines show baked lighting: the lighting comes from the
//! vertices (their radiance, with the material at the vertex), the base-colour texture from
//! each pixel. A pixel's radiance is the interpolated vertex radiance times the texture there
//! over the texture's value interpolated from the vertices — exact for the diffuse part, which
//! is proportional to the base colour, and one where the material does not vary. The CPU
//! image (`kage_engine::shading::baked::Look::render`) shades the material per pixel; this is the preview's cheaper form.

use crate::Gpu;
use crate::buffers::texture_2d;
use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use kage_engine::math::color::linear_to_srgb;
use kage_engine::scene::texture::{Texture, Wrap};
use kage_engine::scene::{FlatScene, TextureSlot};

/// `detail` of preview.wgsl's vertex input: the base-colour UV, the texture's value there, and
/// the cut-out's factor and cutoff.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub struct Detail {
    /// The base-colour UV (the slot's texture transform applied).
    pub uv: [f32; 2],
    /// The texture's value at the vertex (linear RGB).
    pub at_vertex: [f32; 3],
    /// A pixel is discarded where the texture's alpha × `cut[0]` < `cut[1]` ([`SOLID`]: never).
    pub cut: [f32; 2],
}

/// The `cut` of a solid surface.
pub const SOLID: [f32; 2] = [1.0, 0.0];

/// A texture with nothing to modulate: one white texel, value one at every vertex.
pub const PLAIN: Detail = Detail { uv: [0.0; 2], at_vertex: [1.0; 3], cut: SOLID };

/// Group 1 of the per-vertex pipeline (group 2 of the per-pixel lights): the base-colour
/// texture (alpha: the cut-out's mask) and its sampler, then the metallic-roughness texture and its sampler (read per pixel
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

/// Per vertex of instance `i`: the slot's UV, the texture's value there and the cut-out
/// ([`PLAIN`] without a slot or cut-out).
pub fn vertices(flat: &FlatScene, i: usize) -> Vec<Detail> {
    let mesh = flat.mesh(i);
    let cut = flat.instances[i].maps.cutout.map_or(SOLID, |c| [c.factor, c.cutoff]);
    let Some(s) = slot(flat, i) else { return vec![Detail { cut, ..PLAIN }; mesh.positions.len()] };
    let texture = &flat.textures[s.texture as usize];
    let uv = |set: &[glam::Vec2], v: usize| set.get(v).copied().unwrap_or_default();
    (0..mesh.positions.len())
        .map(|v| {
            let at = s.uv(uv(&mesh.uvs, v), uv(&mesh.uvs1, v));
            Detail { uv: at.into(), at_vertex: texture.sample(at).into(), cut }
        })
        .collect()
}

/// The textures an instance's bind group holds, by index into the scene's textures.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Textures {
    /// The base colour.
    pub base: Option<u32>,
    /// The cut-out's mask, put in the base colour's alpha (it reads the same UVs).
    pub alpha: Option<u32>,
    /// The metallic-roughness texture.
    pub metallic_roughness: Option<u32>,
}

impl Textures {
    /// Instance `i`'s.
    pub fn of(flat: &FlatScene, i: usize) -> Self {
        let maps = &flat.instances[i].maps;
        Self {
            base: maps.base_color.map(|s| s.texture),
            alpha: maps.cutout.and_then(|c| c.alpha).map(|s| s.texture),
            metallic_roughness: maps.metallic_roughness.map(|s| s.texture),
        }
    }
}

/// The bind group of the base-colour (with the mask in alpha) and metallic-roughness textures
/// (`None`: one white texel) with their wrap modes and linear filtering, as the CPU's bilinear
/// lookup.
pub fn bind_group(gpu: &Gpu, layout: &wgpu::BindGroupLayout, flat: &FlatScene, t: Textures) -> wgpu::BindGroup {
    let at = |k: Option<u32>| k.map(|k| &*flat.textures[k as usize]);
    let (base, base_sampler) = view(gpu, at(t.base), at(t.alpha), true);
    let (mr, mr_sampler) = view(gpu, at(t.metallic_roughness), None, false);
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
/// texture) or linear (data), its alpha from `alpha` (a mask of the same size; opaque without
/// one), with its sampler.
fn view(
    gpu: &Gpu,
    texture: Option<&Texture>,
    alpha: Option<&Texture>,
    srgb: bool,
) -> (wgpu::TextureView, wgpu::Sampler) {
    let white = Texture::new(1, 1, vec![Vec3::ONE], [Wrap::Repeat; 2]);
    let t = texture.or(alpha).unwrap_or(&white);
    let alpha = alpha.filter(|a| a.texels.len() == t.texels.len());
    let byte = |x: f32| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
    let encode = |x: f32| byte(if srgb { linear_to_srgb(x.clamp(0.0, 1.0)) } else { x });
    let colour = |k: usize| if texture.is_some() { t.texels[k] } else { Vec3::ONE };
    let bytes: Vec<u8> = (0..t.texels.len())
        .flat_map(|k| {
            let [r, g, b] = colour(k).to_array().map(encode);
            [r, g, b, alpha.map_or(255, |a| byte(a.texels[k].x))]
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
