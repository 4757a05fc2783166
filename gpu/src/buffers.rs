//! Buffer helpers: uploads, a read-back, one compute dispatch.

use crate::{Gpu, GpuError};
use wgpu::util::DeviceExt;

/// A storage buffer holding `data`, padded to a multiple of 4 bytes and to at least 256 (an
/// empty array still binds: wgpu wants one element of the shader's type, at most 256 bytes here).
pub fn storage<T: bytemuck::Pod>(gpu: &Gpu, label: &str, data: &[T]) -> wgpu::Buffer {
    let bytes: &[u8] = bytemuck::cast_slice(data);
    let mut contents = bytes.to_vec();
    contents.resize(bytes.len().next_multiple_of(4).max(256), 0);
    gpu.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: &contents,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
    })
}

/// A uniform buffer holding `value`.
pub fn uniform<T: bytemuck::Pod>(gpu: &Gpu, label: &str, value: &T) -> wgpu::Buffer {
    gpu.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: bytemuck::bytes_of(value),
        usage: wgpu::BufferUsages::UNIFORM,
    })
}

/// A sampled 2D texture of `[width, height]` texels in `format`, one level, filled from `data`
/// (rows packed, top row first); its view.
pub fn texture_2d(
    gpu: &Gpu,
    label: &str,
    [width, height]: [u32; 2],
    format: wgpu::TextureFormat,
    data: &[u8],
) -> wgpu::TextureView {
    let descriptor = wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    };
    let order = wgpu::util::TextureDataOrder::LayerMajor;
    gpu.device.create_texture_with_data(&gpu.queue, &descriptor, order, data).create_view(&Default::default())
}

/// Runs `f` inside a validation error scope: what the device rejects becomes an error naming
/// `what` instead of wgpu's default panic.
pub fn checked<T>(gpu: &Gpu, what: &str, f: impl FnOnce() -> T) -> Result<T, GpuError> {
    let scope = gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
    let value = f();
    match pollster::block_on(scope.pop()) {
        None => Ok(value),
        Some(e) => Err(GpuError::Unsupported(format!("{what}: {e}"))),
    }
}

/// A compute pipeline over shader module `module`'s `main`, with an automatic layout.
pub fn pipeline(gpu: &Gpu, label: &str, module: &wgpu::ShaderModule) -> Result<wgpu::ComputePipeline, GpuError> {
    checked(gpu, label, || {
        gpu.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(label),
            layout: None,
            module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        })
    })
}

/// Runs `pipeline` with `buffers` bound in order at group 0 over `threads` invocations
/// (workgroups of 64; at most 65535 × 64 invocations), then reads back the buffers listed in `read` (indices into `buffers`).
pub fn dispatch(
    gpu: &Gpu,
    pipeline: &wgpu::ComputePipeline,
    buffers: &[&wgpu::Buffer],
    threads: u32,
    read: &[usize],
) -> Result<Vec<Vec<u8>>, GpuError> {
    let groups = threads.div_ceil(64).max(1);
    if groups > 65535 {
        return Err(GpuError::Unsupported(format!("{threads} invocations exceed one dispatch (65535 × 64)")));
    }
    let entries: Vec<wgpu::BindGroupEntry> = buffers
        .iter()
        .enumerate()
        .map(|(i, b)| wgpu::BindGroupEntry { binding: i as u32, resource: b.as_entire_binding() })
        .collect();
    // A shader edited to bind other buffers than the host provides fails here, not in a panic.
    let bind = checked(gpu, "binding the shader's buffers", || {
        gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &pipeline.get_bind_group_layout(0),
            entries: &entries,
        })
    })?;
    let staging: Vec<wgpu::Buffer> = read
        .iter()
        .map(|&i| {
            gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("read-back"),
                size: buffers[i].size(),
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        })
        .collect();
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(groups, 1, 1);
    }
    for (&i, s) in read.iter().zip(&staging) {
        encoder.copy_buffer_to_buffer(buffers[i], 0, s, 0, s.size());
    }
    gpu.queue.submit([encoder.finish()]);
    staging.iter().map(|s| map_read(gpu, s)).collect()
}

/// The bytes of a `MAP_READ` buffer, once the queue's work on it is done.
pub fn map_read(gpu: &Gpu, buffer: &wgpu::Buffer) -> Result<Vec<u8>, GpuError> {
    let slice = buffer.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    gpu.device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| GpuError::Readback(e.to_string()))?;
    rx.recv().map_err(|e| GpuError::Readback(e.to_string()))?.map_err(|e| GpuError::Readback(e.to_string()))?;
    let bytes = slice.get_mapped_range().map_err(|e| GpuError::Readback(e.to_string()))?.to_vec();
    buffer.unmap();
    Ok(bytes)
}
