//! The wgpu device kage shades on.

use crate::GpuError;

/// A device and its queue.
#[derive(Clone)]
pub struct Gpu {
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// What the adapter reported (name, backend, device type).
    pub info: wgpu::AdapterInfo,
}

impl Gpu {
    /// The first adapter wgpu offers (a hardware GPU when there is one, else lavapipe), with
    /// storage-buffer limits raised to what the adapter allows.
    pub fn new() -> Result<Self, GpuError> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions::default()))
            .map_err(|e| GpuError::NoDevice(e.to_string()))?;
        Self::from_adapter(&adapter)
    }

    /// Shares a device created elsewhere (the editor's window, created with [`Gpu::descriptor`]).
    pub fn from_parts(device: wgpu::Device, queue: wgpu::Queue, info: wgpu::AdapterInfo) -> Self {
        Self { device, queue, info }
    }

    /// A device on `adapter`.
    pub fn from_adapter(adapter: &wgpu::Adapter) -> Result<Self, GpuError> {
        let (device, queue) = pollster::block_on(adapter.request_device(&Self::descriptor(adapter)))
            .map_err(|e| GpuError::NoDevice(e.to_string()))?;
        Ok(Self { device, queue, info: adapter.get_info() })
    }

    /// The device descriptor kage needs on `adapter`: wgpu's default limits where the adapter
    /// has them (a GL adapter may have fewer; the shaders that need more then refuse to build
    /// with a message), its own buffer sizes, and 8192² textures for a window of any size.
    pub fn descriptor(adapter: &wgpu::Adapter) -> wgpu::DeviceDescriptor<'static> {
        let have = adapter.limits();
        let limits = wgpu::Limits {
            max_storage_buffer_binding_size: have.max_storage_buffer_binding_size,
            max_buffer_size: have.max_buffer_size,
            max_texture_dimension_2d: 8192,
            ..wgpu::Limits::default()
        }
        .or_worse_values_from(&have);
        wgpu::DeviceDescriptor { label: Some("kage"), required_limits: limits, ..Default::default() }
    }

    /// One line naming the device.
    pub fn describe(&self) -> String {
        format!("{} ({:?}, {:?})", self.info.name, self.info.backend, self.info.device_type)
    }
}
