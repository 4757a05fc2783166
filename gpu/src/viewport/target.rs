//! What a frame draws into: the offscreen target a GUI shows, its multisampled colour and
//! depth, and reading an image back.

use super::*;

/// The offscreen target: [`SAMPLES`] per pixel, resolved into the texture a GUI shows.
pub(super) struct Target {
    pub(super) size: [u32; 2],
    pub(super) frame: Attachments,
}

/// The texture a [`Viewport::paint`] drew into.
pub struct Shown<'a> {
    /// Its view, one sample per pixel, for a GUI to show.
    pub view: &'a wgpu::TextureView,
    /// The texture was made by this call (the view size changed): a GUI showing the last one
    /// must take this one instead.
    pub new: bool,
}

/// What one frame draws into: colour and depth of some samples per pixel, and the one-sample
/// colour they resolve into (the colour itself at one sample).
pub(super) struct Attachments {
    pub(super) color: wgpu::TextureView,
    pub(super) depth: wgpu::TextureView,
    pub(super) resolved: Option<wgpu::TextureView>,
}

impl Attachments {
    /// Views of `color` (a one-sample texture of `size`, read afterwards) with `samples`
    /// multisampled colour and depth textures in front of it when `samples` > 1.
    pub(super) fn new(gpu: &Gpu, color: &wgpu::Texture, samples: u32) -> Self {
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
    pub(super) fn shown(&self) -> &wgpu::TextureView {
        self.resolved.as_ref().unwrap_or(&self.color)
    }
}

pub(super) fn texture(
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
pub(super) fn read_back(
    gpu: &Gpu,
    color: &wgpu::Texture,
    [w, h]: [u32; 2],
    texel: u32,
) -> Result<Vec<u8>, crate::GpuError> {
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
    let data = crate::buffers::map_read(gpu, &buffer)?;
    Ok((0..h as usize).flat_map(|y| data[y * row as usize..][..(texel * w) as usize].to_vec()).collect())
}

pub(super) fn make_target(gpu: &Gpu, (size, samples): ([u32; 2], u32)) -> Target {
    let usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING;
    Target { size, frame: Attachments::new(gpu, &texture(gpu, size, COLOR, usage, 1), samples) }
}
