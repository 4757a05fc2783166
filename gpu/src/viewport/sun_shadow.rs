//! The map's sun shadowed per pixel in the viewport (both draws): a depth map of the scene seen
//! from the sun (orthographic, over the scene's bounding sphere), looked up at each pixel with
//! a 3×3 percentage-closer filter — the directional-light shadow map of real-time engines, in
//! place of the sun's visibility interpolated from the vertices (which drew a lattice's sharp
//! sun shadow as blobs). A wide sun (`Sun::softness`, e.g. `studio.hdr`'s lamp) widens the
//! filter by the distance to the occluders found around the point (percentage-closer soft
//! shadows), as `kage render`'s CPU image spreads its shadow rays over the sun's disc. The
//! map is part of the view's bind group (bindings 1 and 2).

use crate::Gpu;
use glam::{Mat4, Vec3};
use kage_engine::prt::sun::Sun;

/// Texels per side.
pub const SIZE: u32 = 2048;
/// The depth format.
pub const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// The depth map, its comparison sampler, and where the last render put the sun.
pub struct SunShadow {
    /// The depth texture's view (sampled by `fs_main` and `fs_lit`, rendered by `vs_shadow`).
    pub view: wgpu::TextureView,
    /// A 1×1 depth texture bound in the map's place while the map is drawn.
    pub stand_in: wgpu::TextureView,
    /// A comparison sampler (less-equal, linear: each tap is itself 2×2 filtered).
    pub sampler: wgpu::Sampler,
    /// Clip from world of the last render (identity before any).
    pub clip: Mat4,
    /// World units per texel of the last render.
    pub texel: f32,
    /// Toward the sun of the last render; `None` when the map holds nothing to look up.
    toward: Option<Vec3>,
    /// The sun's [`Sun::softness`] of the last render (0: a hard shadow).
    softness: f32,
}

/// The view layout's bindings 1 and 2: the map and its comparison sampler.
pub fn layout_entries() -> [wgpu::BindGroupLayoutEntry; 2] {
    let entry =
        |binding, ty| wgpu::BindGroupLayoutEntry { binding, visibility: wgpu::ShaderStages::FRAGMENT, ty, count: None };
    let depth = wgpu::BindingType::Texture {
        sample_type: wgpu::TextureSampleType::Depth,
        view_dimension: wgpu::TextureViewDimension::D2,
        multisampled: false,
    };
    [entry(1, depth), entry(2, wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Comparison))]
}

/// A `size`² depth texture that can be drawn into and sampled.
fn depth_texture(gpu: &Gpu, size: u32) -> wgpu::TextureView {
    let texture = gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("sun shadow"),
        size: wgpu::Extent3d { width: size, height: size, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: FORMAT,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
        view_formats: &[],
    });
    texture.create_view(&Default::default())
}

impl SunShadow {
    /// An empty map.
    pub fn new(gpu: &Gpu) -> Self {
        let sampler = gpu.device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("sun shadow"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            compare: Some(wgpu::CompareFunction::LessEqual),
            ..Default::default()
        });
        Self {
            view: depth_texture(gpu, SIZE),
            stand_in: depth_texture(gpu, 1),
            sampler,
            clip: Mat4::IDENTITY,
            texel: 0.0,
            toward: None,
            softness: 0.0,
        }
    }

    /// Nothing to look up (or the geometry changed): the shaders leave the sun unshadowed by
    /// the map until it is rendered again.
    pub fn clear(&mut self) {
        self.toward = None;
    }

    /// True when the map holds the current geometry seen from `sun`.
    pub fn holds(&self, sun: &Sun) -> bool {
        self.toward == Some(sun.direction) && self.softness == sun.softness()
    }

    /// The view's `sun_direction`: toward the sun, w 1 when the map was rendered for it.
    pub fn direction(&self) -> [f32; 4] {
        self.toward.map_or([0.0; 4], |d| d.extend(1.0).into())
    }

    /// Aims the map at `sun` over the sphere (`centre`, `radius`) and returns the
    /// clip-from-world matrix the depth pass draws with.
    pub fn aim(&mut self, sun: &Sun, (centre, radius): (Vec3, f32)) -> Mat4 {
        let direction = sun.direction;
        let up = if direction.cross(Vec3::Y).length_squared() < 1e-6 { Vec3::Z } else { Vec3::Y };
        let eye = centre + direction * (2.0 * radius);
        let view = glam::camera::rh::view::look_at_mat4(eye, centre, up);
        // wgpu's depth runs 0 to 1: the sphere lies between radius and 3·radius from the eye.
        let proj =
            glam::camera::rh::proj::directx::orthographic(-radius, radius, -radius, radius, radius, 3.0 * radius);
        self.clip = proj * view;
        self.texel = 2.0 * radius / SIZE as f32;
        self.toward = Some(direction);
        self.softness = sun.softness();
        self.clip
    }

    /// The depth pass's attachment, cleared to the far plane.
    pub fn attachment(&self) -> wgpu::RenderPassDepthStencilAttachment<'_> {
        wgpu::RenderPassDepthStencilAttachment {
            view: &self.view,
            depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
            stencil_ops: None,
        }
    }

    /// The view's `sun_shadow`: the normal offset (world units, 1.5 texels), the depth bias (a
    /// texel's worth of depth: the depth range is the map's width), the texel size in map
    /// coordinates, and the sun's softness (map units of penumbra per unit of depth between
    /// occluder and receiver: both span the map's width).
    pub fn params(&self) -> [f32; 4] {
        let texel = 1.0 / SIZE as f32;
        [1.5 * self.texel, texel, texel, self.softness]
    }
}
