//! The per-vertex draw: an instance's (or a light polygon's) triangles with their radiance and
//! base-colour detail.

use super::*;

/// One drawable: world positions, radiance and texture detail per vertex, triangle indices,
/// the base-colour texture.
pub(super) struct Mesh {
    pub(super) positions: wgpu::Buffer,
    pub(super) radiance: wgpu::Buffer,
    pub(super) detail: wgpu::Buffer,
    /// The sun's unshadowed light per vertex ([`Viewport::upload_sun`]; zero without).
    pub(super) sun: wgpu::Buffer,
    pub(super) indices: wgpu::Buffer,
    pub(super) texture: wgpu::BindGroup,
    pub(super) count: u32,
    pub(super) vertices: usize,
}

impl Mesh {
    /// Draws it with its texture as group 1 and its vertex buffers 0–3.
    pub(super) fn draw(&self, pass: &mut wgpu::RenderPass) {
        pass.set_bind_group(1, &self.texture, &[]);
        pass.set_vertex_buffer(0, self.positions.slice(..));
        pass.set_vertex_buffer(1, self.radiance.slice(..));
        pass.set_vertex_buffer(2, self.detail.slice(..));
        pass.set_vertex_buffer(3, self.sun.slice(..));
        pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(0..self.count, 0, 0..1);
    }
}

/// What a drawable shows: radiance and texture detail per vertex, and the texture.
pub(super) struct VertexData<'a> {
    pub(super) radiance: &'a [Vec3],
    pub(super) detail: &'a [Detail],
    pub(super) texture: wgpu::BindGroup,
}

pub(super) fn mesh_buffers(gpu: &Gpu, positions: &[Vec3], look: VertexData, indices: &[u32]) -> Mesh {
    let init = |label, contents: &[u8], usage| {
        gpu.device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
    };
    let v = wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST;
    Mesh {
        positions: init("positions", bytemuck::cast_slice(positions), v),
        radiance: init("radiance", bytemuck::cast_slice(look.radiance), v),
        detail: init("detail", bytemuck::cast_slice(look.detail), wgpu::BufferUsages::VERTEX),
        sun: init("sun", bytemuck::cast_slice(&vec![Vec3::ZERO; positions.len()]), v),
        indices: init("indices", bytemuck::cast_slice(indices), wgpu::BufferUsages::INDEX),
        texture: look.texture,
        count: indices.len() as u32,
        vertices: positions.len(),
    }
}
