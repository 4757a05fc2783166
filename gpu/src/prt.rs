//! PRT per-vertex shading on the GPU (`shaders/prt.wgsl`).

use crate::buffers::{dispatch, pipeline, storage, uniform};
use crate::{Gpu, GpuError, Shaders};
use glam::Vec3;
use kage_engine::math::sh;
use kage_engine::prt::{Bake, Posed};
use kage_engine::scene::FlatScene;
use kage_engine::scene::VertexValues;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    vertex_count: u32,
    coeffs: u32,
    regions: u32,
    groups: u32,
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct GpuVertex {
    p: [f32; 4],
    albedo: [f32; 3],
    group: u32,
}

/// One silhouette's parameters as `silhouette.wgsl` reads them.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuSilhouette {
    w: [f32; 3],
    plane: f32,
    u_axis: [f32; 3],
    texels_per_unit: f32,
    v_axis: [f32; 3],
    res: u32,
    offset: [f32; 2],
    lo: [f32; 2],
    hi: [f32; 2],
    sat_base: u32,
    far_base: u32,
}

/// The PRT shading pipeline with a bake's transfer resident on the device.
pub struct PrtShader {
    pipeline: wgpu::ComputePipeline,
    transfer: wgpu::Buffer,
    order: usize,
    vertices: usize,
    /// Vertices of every instance.
    sizes: Vec<usize>,
}

impl PrtShader {
    /// Builds the pipeline from `shaders` and uploads the transfer of `bake` cut to `order`.
    pub fn new(gpu: &Gpu, shaders: &Shaders, bake: &Bake, order: usize) -> Result<Self, GpuError> {
        let module = shaders.module(&gpu.device, "prt.wgsl")?;
        let bake = bake.truncated(order);
        let transfer: Vec<f32> = bake.instances.concat();
        let n = sh::num_coeffs(bake.order);
        let sizes: Vec<usize> = bake.instances.iter().map(|t| t.len() / n).collect();
        Ok(Self {
            pipeline: pipeline(gpu, "prt", &module)?,
            transfer: storage(gpu, "prt transfer", &transfer),
            order: bake.order,
            vertices: sizes.iter().sum(),
            sizes,
        })
    }

    /// Rebuilds the pipeline from `shaders` (hot reload); on error the previous one stays.
    pub fn reload(&mut self, gpu: &Gpu, shaders: &Shaders) -> Result<(), GpuError> {
        let module = shaders.module(&gpu.device, "prt.wgsl")?;
        self.pipeline = pipeline(gpu, "prt", &module)?;
        Ok(())
    }

    /// Radiance at every vertex (instance order) for lighting `posed` (at this shader's order),
    /// vertex `positions` and `albedo` (flattened over instances, as the bake).
    pub fn shade(&self, gpu: &Gpu, posed: &Posed, positions: &[Vec3], albedo: &[Vec3]) -> Result<Vec<Vec3>, GpuError> {
        if posed.order != self.order || positions.len() != self.vertices || albedo.len() != self.vertices {
            return Err(GpuError::Unsupported(format!(
                "PRT shading set up for order {} and {} vertices, given order {} and {} vertices",
                self.order,
                self.vertices,
                posed.order,
                positions.len()
            )));
        }
        let group_of = self.sizes.iter().zip(&posed.group_of).flat_map(|(&n, &g)| std::iter::repeat_n(g as u32, n));
        let vertices: Vec<GpuVertex> = positions
            .iter()
            .zip(albedo)
            .zip(group_of)
            .map(|((p, a), g)| GpuVertex { p: [p.x, p.y, p.z, 0.0], albedo: a.to_array(), group: g })
            .collect();
        let lighting: Vec<[f32; 4]> =
            posed.lighting.iter().flatten().map(|c| [c.x as f32, c.y as f32, c.z as f32, 0.0]).collect();
        let basis: Vec<f32> = posed.region_basis.iter().flatten().map(|&y| y as f32).collect();
        let shadows = ShadowArrays::new(posed);
        let params = Params {
            vertex_count: vertices.len() as u32,
            coeffs: sh::num_coeffs(self.order) as u32,
            regions: posed.regions.len() as u32,
            groups: posed.silhouettes.len() as u32,
        };
        let out = storage(gpu, "prt radiance", &vec![[0.0f32; 4]; vertices.len().max(1)]);
        let buffers = [
            &uniform(gpu, "prt params", &params),
            &storage(gpu, "prt vertices", &vertices),
            &self.transfer,
            &storage(gpu, "prt lighting", &lighting),
            &storage(gpu, "prt region basis", &basis),
            &storage(gpu, "prt regions", &shadows.regions),
            &storage(gpu, "prt silhouettes", &shadows.silhouettes),
            &storage(gpu, "prt tables", &shadows.tables),
            &out,
        ];
        let read = dispatch(gpu, &self.pipeline, &buffers, params.vertex_count, &[8])?;
        let values: &[[f32; 4]] = &bytemuck::cast_slice::<u8, [f32; 4]>(&read[0])[..vertices.len()];
        Ok(values.iter().map(|v| Vec3::new(v[0], v[1], v[2])).collect())
    }
}

/// The shadows between groups of a posed frame, as `silhouette.wgsl` reads them.
pub struct ShadowArrays {
    /// Per region: RGB power B_i and the box filter's angular width.
    pub regions: Vec<[f32; 4]>,
    /// Per group and region: the silhouette's parameters.
    pub silhouettes: Vec<GpuSilhouette>,
    /// Every silhouette's summed-area table, then its far depths, concatenated.
    pub tables: Vec<f32>,
}

impl ShadowArrays {
    /// The arrays of `posed` (empty without shadows between groups).
    pub fn new(posed: &Posed) -> Self {
        let regions = posed
            .regions
            .iter()
            .zip(&posed.widths)
            .map(|(r, w)| [r.power.x as f32, r.power.y as f32, r.power.z as f32, *w])
            .collect();
        let (mut silhouettes, mut tables) = (Vec::new(), Vec::new());
        for s in posed.silhouettes.iter().flat_map(|g| g.iter()) {
            let p = s.params();
            silhouettes.push(GpuSilhouette {
                w: p.w.to_array(),
                plane: p.plane,
                u_axis: p.u_axis.to_array(),
                texels_per_unit: p.texels_per_unit,
                v_axis: p.v_axis.to_array(),
                res: p.res,
                offset: p.offset.to_array(),
                lo: p.covered.0.to_array(),
                hi: p.covered.1.to_array(),
                sat_base: tables.len() as u32,
                far_base: (tables.len() + s.sat().len()) as u32,
            });
            tables.extend_from_slice(s.sat());
            tables.extend_from_slice(s.far());
        }
        Self { regions, silhouettes, tables }
    }
}

/// Per instance and vertex, the GPU counterpart of `kage_engine::prt::Frame::vertex_values`.
pub fn shade_vertices(
    gpu: &Gpu,
    shader: &PrtShader,
    flat: &FlatScene,
    posed: &Posed,
    eye: Vec3,
) -> Result<VertexValues, GpuError> {
    let positions: Vec<Vec3> = (0..flat.instances.len())
        .flat_map(|i| {
            let n = flat.vertex_count(i);
            (0..n).map(move |v| flat.vertex(i, v).0)
        })
        .collect();
    let albedo: Vec<Vec3> = kage_engine::material::albedo::at_vertices(flat, eye).concat();
    let values = shader.shade(gpu, posed, &positions, &albedo)?;
    Ok(crate::per_instance(flat, values))
}
