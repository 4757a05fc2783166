//! BSPVT per-vertex shading on the GPU (`shaders/bspvt.wgsl`).

use crate::buffers::{dispatch, pipeline, storage, uniform};
use crate::{Gpu, GpuError, Shaders};
use glam::{DMat3, Vec3};
use kage_engine::bspvt::shade::PointShader;
use kage_engine::bspvt::{Bake, Shadows, layout};
use kage_engine::math::ltc;
use kage_engine::scene::VertexValues;
use kage_engine::scene::{FlatLight, FlatScene};

/// Most corners a light polygon may have on the GPU.
pub const MAX_LIGHT_POINTS: usize = 8;
/// Deepest tree the shader's stack holds.
pub const MAX_DEPTH: usize = 32;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    vertex_count: u32,
    light_count: u32,
    mode: u32,
    /// The bake's face resolution (its depth quadtrees' tiles).
    res: u32,
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct GpuVertex {
    p: [f32; 4],
    frame: [[f32; 4]; 3],
    spec_inv: [[f32; 4]; 3],
    diffuse: [f32; 4],
    spec: [f32; 4],
}

/// A light polygon as `ltc.wgsl`'s `Light` reads it.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuLight {
    points: [[f32; 4]; MAX_LIGHT_POINTS],
    normal: [f32; 3],
    count: u32,
    radiance: [f32; 3],
    pad: u32,
}

/// The BSPVT shading pipeline with a bake's trees resident on the device.
pub struct BspvtShader {
    pipeline: wgpu::ComputePipeline,
    trees: Trees,
}

/// A bake's vertex records on the device.
struct Trees {
    records: wgpu::Buffer,
    starts: wgpu::Buffer,
    /// Vertices with trees on the device.
    baked: usize,
    /// The bake's face resolution.
    res: u32,
}

impl Trees {
    /// Every instance's records of `bake`, in instance order (none for `None`).
    fn upload(gpu: &Gpu, bake: Option<&Bake>) -> Result<Self, GpuError> {
        let (mut bytes, mut starts) = (Vec::new(), Vec::new());
        for inst in bake.map_or(&[][..], |b| &b.instances[..]) {
            for v in 0..inst.offsets.len() - 1 {
                let record = inst.record(v);
                check_depth(record)?;
                starts.push(bytes.len() as u32);
                bytes.extend_from_slice(record);
            }
        }
        // One start past the last record: where a record ends tells whether depth follows its trees.
        let baked = starts.len();
        starts.push(bytes.len() as u32);
        bytes.resize(bytes.len().next_multiple_of(4), 0);
        Ok(Self {
            baked,
            res: bake.map_or(0, |b| b.settings.res as u32),
            records: storage(gpu, "bspvt records", &bytes),
            starts: storage(gpu, "bspvt record starts", &starts),
        })
    }
}

impl BspvtShader {
    /// Builds the pipeline from `shaders` and uploads the trees of `bake` (every instance's
    /// records, in instance order; `None` for unshadowed shading only).
    pub fn new(gpu: &Gpu, shaders: &Shaders, bake: Option<&Bake>) -> Result<Self, GpuError> {
        let module = shaders.module(&gpu.device, "bspvt.wgsl")?;
        let trees = Trees::upload(gpu, bake)?;
        Ok(Self { pipeline: pipeline(gpu, "bspvt", &module)?, trees })
    }

    /// Replaces the trees on the device with `bake`'s, keeping the pipeline: a bake streaming
    /// in chunks re-uploads its records many times, and building the pipeline again takes
    /// seconds on a CPU device.
    pub fn set_bake(&mut self, gpu: &Gpu, bake: Option<&Bake>) -> Result<(), GpuError> {
        self.trees = Trees::upload(gpu, bake)?;
        Ok(())
    }

    /// Rebuilds the pipeline from `shaders` (hot reload); on error the previous one stays.
    pub fn reload(&mut self, gpu: &Gpu, shaders: &Shaders) -> Result<(), GpuError> {
        let module = shaders.module(&gpu.device, "bspvt.wgsl")?;
        self.pipeline = pipeline(gpu, "bspvt", &module)?;
        Ok(())
    }

    /// Outgoing radiance at every vertex (`shaders`: the CPU's per-vertex LTC setup, in the
    /// bake's vertex order for trees) from `lights`, unshadowed or with the trees resident on
    /// the device, which must be `shadows`' (uploaded by [`Self::new`] or [`Self::set_bake`]).
    /// Exact visibility casts rays: the CPU's alone.
    pub fn shade(
        &self,
        gpu: &Gpu,
        shaders: &[PointShader],
        lights: &[FlatLight],
        shadows: Shadows,
    ) -> Result<Vec<Vec3>, GpuError> {
        let mode = match shadows {
            Shadows::Unshadowed => 0,
            Shadows::Trees(bake)
                if self.trees.baked == shaders.len()
                    && bake.instances.iter().map(|i| i.vertices()).sum::<usize>() == shaders.len() =>
            {
                1
            }
            Shadows::Trees(_) => {
                return Err(GpuError::Unsupported("BSPVT shading needs the resident bake of every vertex".into()));
            }
            Shadows::Exact { .. } => {
                return Err(GpuError::Unsupported(
                    "exact visibility casts rays on the CPU; the GPU shades trees".into(),
                ));
            }
        };
        let vertices: Vec<GpuVertex> = shaders.iter().map(gpu_vertex).collect();
        let lights = lights.iter().map(gpu_light).collect::<Result<Vec<_>, _>>()?;
        let params =
            Params { vertex_count: vertices.len() as u32, light_count: lights.len() as u32, mode, res: self.trees.res };
        let out = storage(gpu, "bspvt radiance", &vec![[0.0f32; 4]; vertices.len().max(1)]);
        let overflow = storage(gpu, "bspvt overflow", &[0u32]);
        let buffers = [
            &uniform(gpu, "bspvt params", &params),
            &storage(gpu, "bspvt vertices", &vertices),
            &storage(gpu, "bspvt lights", &lights),
            &self.trees.starts,
            &self.trees.records,
            &out,
            &overflow,
        ];
        let read = dispatch(gpu, &self.pipeline, &buffers, params.vertex_count, &[5, 6])?;
        let overflowed: u32 = bytemuck::pod_read_unaligned(&read[1][..4]);
        if overflowed > 0 {
            return Err(GpuError::Unsupported(format!(
                "{overflowed} light pieces outgrew the shader's 16-corner polygons or {MAX_DEPTH}-deep stack"
            )));
        }
        let values: &[[f32; 4]] = &bytemuck::cast_slice::<u8, [f32; 4]>(&read[0])[..shaders.len()];
        Ok(values.iter().map(|v| Vec3::new(v[0], v[1], v[2])).collect())
    }
}

/// Rejects a record whose trees are deeper than the shader's stack.
fn check_depth(record: &[u8]) -> Result<(), GpuError> {
    for face in layout::vertex_faces(record) {
        let (mut depth, mut pending) = (0usize, 0usize);
        let mut i = 0;
        while i < face.len() {
            if face[i] & 0x80 == 0 {
                pending = pending.saturating_sub(1);
                i += 1;
            } else {
                pending += 1;
                depth = depth.max(pending);
                i += 3;
            }
        }
        if depth > MAX_DEPTH {
            return Err(GpuError::Unsupported(format!("a visibility tree {depth} deep exceeds the GPU's {MAX_DEPTH}")));
        }
    }
    Ok(())
}

fn rows(m: &DMat3) -> [[f32; 4]; 3] {
    let t = m.transpose();
    [t.x_axis, t.y_axis, t.z_axis].map(|r| [r.x as f32, r.y as f32, r.z as f32, 0.0])
}

fn gpu_vertex(s: &PointShader) -> GpuVertex {
    let has_spec = if s.spec != glam::DVec3::ZERO { 1.0 } else { 0.0 };
    GpuVertex {
        p: [s.p.x as f32, s.p.y as f32, s.p.z as f32, 0.0],
        frame: rows(&s.frame),
        spec_inv: rows(&s.spec_inv),
        diffuse: [s.diffuse.x as f32, s.diffuse.y as f32, s.diffuse.z as f32, 0.0],
        spec: [s.spec.x as f32, s.spec.y as f32, s.spec.z as f32, has_spec],
    }
}

/// `l` as the shaders read it; an error for what they cannot shade (more than
/// [`MAX_LIGHT_POINTS`] corners, a texture).
pub fn gpu_light(l: &FlatLight) -> Result<GpuLight, GpuError> {
    if l.points.len() > MAX_LIGHT_POINTS {
        return Err(GpuError::Unsupported(format!(
            "a light polygon with {} corners (the GPU path takes at most {MAX_LIGHT_POINTS})",
            l.points.len()
        )));
    }
    if l.texture.is_some() {
        return Err(GpuError::Unsupported("textured polygonal lights are shaded on the CPU only".into()));
    }
    let mut points = [[0.0; 4]; MAX_LIGHT_POINTS];
    for (d, p) in points.iter_mut().zip(&l.points) {
        *d = [p.x, p.y, p.z, 0.0];
    }
    Ok(GpuLight {
        points,
        normal: l.normal.to_array(),
        count: l.points.len() as u32,
        radiance: l.radiance.to_array(),
        pad: 0,
    })
}

/// The CPU's per-vertex LTC setup for every vertex of every instance, seen from `eye`.
pub fn point_shaders(flat: &FlatScene, eye: Vec3) -> Vec<PointShader> {
    use rayon::prelude::*;
    let table = ltc::table();
    (0..flat.instances.len())
        .flat_map(|i| {
            let n = flat.vertex_count(i);
            let material = flat.instances[i].material;
            let table = &table;
            (0..n)
                .into_par_iter()
                .map(move |v| {
                    let (p, normal) = flat.vertex(i, v);
                    PointShader::new(table, p, normal, eye, &material)
                })
                .collect::<Vec<_>>()
        })
        .collect()
}

/// Per instance and vertex, the GPU counterpart of `kage_engine::bspvt::shade_vertices`.
pub fn shade_vertices(
    gpu: &Gpu,
    shader: &BspvtShader,
    flat: &FlatScene,
    shadows: Shadows,
    eye: Vec3,
) -> Result<VertexValues, GpuError> {
    let values = shader.shade(gpu, &point_shaders(flat, eye), &flat.lights, shadows)?;
    Ok(crate::per_instance(flat, values))
}
