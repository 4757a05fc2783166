//! The pipelines of `preview.wgsl` over the viewport's bind-group layouts: the sky, the
//! per-vertex meshes, PRT and the polygonal lights per pixel, the sun's depth map.

use super::*;

/// The pipelines of preview.wgsl.
pub(super) struct Pipelines {
    /// Per-vertex radiance with texture detail.
    pub(super) main: wgpu::RenderPipeline,
    /// Per-pixel PRT; `None` where the device cannot bind its storage buffers in the fragment
    /// stage (e.g. a GL adapter), which then interpolates PRT per vertex.
    pub(super) prt: Option<wgpu::RenderPipeline>,
    /// The polygonal lights per pixel; `None` as for `prt`.
    pub(super) lit: Option<wgpu::RenderPipeline>,
    /// The environment behind the geometry.
    pub(super) sky: wgpu::RenderPipeline,
    /// The sun's depth map.
    pub(super) shadow: wgpu::RenderPipeline,
}

/// Group 1 of the per-pixel PRT and lights pipelines: parameters, then storage arrays —
/// indices read by the vertex stage, vertices by both, `fragment` more by the fragment (see
/// preview.wgsl); `None` when the device allows fewer storage buffers per stage than the
/// fragment stage binds.
pub(super) fn storage_layout(gpu: &Gpu, fragment: usize) -> Option<wgpu::BindGroupLayout> {
    use wgpu::ShaderStages as S;
    if (gpu.device.limits().max_storage_buffers_per_shader_stage as usize) < fragment + 1 {
        return None;
    }
    let visibility =
        [S::FRAGMENT, S::VERTEX, S::VERTEX_FRAGMENT].into_iter().chain(std::iter::repeat_n(S::FRAGMENT, fragment));
    let entries: Vec<wgpu::BindGroupLayoutEntry> = visibility
        .enumerate()
        .map(|(k, visibility)| wgpu::BindGroupLayoutEntry {
            binding: k as u32,
            visibility,
            ty: wgpu::BindingType::Buffer {
                ty: if k == 0 {
                    wgpu::BufferBindingType::Uniform
                } else {
                    wgpu::BufferBindingType::Storage { read_only: true }
                },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        })
        .collect();
    Some(gpu.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("preview storage"),
        entries: &entries,
    }))
}

/// The bind group layouts the pipelines use: the view (group 0), then the base-colour texture
/// (per-vertex pipeline), the environment map (sky) or the storage arrays (per-pixel PRT and
/// lights, both with the base-colour texture as group 2) as group 1.
#[derive(Clone, Copy)]
pub(super) struct Layouts<'a> {
    pub(super) view: &'a wgpu::BindGroupLayout,
    pub(super) detail: &'a wgpu::BindGroupLayout,
    pub(super) sky: &'a wgpu::BindGroupLayout,
    pub(super) prt: Option<&'a wgpu::BindGroupLayout>,
    pub(super) lit: Option<&'a wgpu::BindGroupLayout>,
}

/// The pipelines of preview.wgsl.
pub(super) fn build_pipelines(
    gpu: &Gpu,
    shaders: &Shaders,
    layouts: Layouts,
    target: (wgpu::TextureFormat, u32),
) -> Result<Pipelines, crate::ShaderError> {
    let module = shaders.module(&gpu.device, "preview.wgsl")?;
    let attribute = |location, format, offset| wgpu::VertexAttribute { format, offset, shader_location: location };
    let vec3 = wgpu::VertexFormat::Float32x3;
    let attributes = [
        vec![attribute(0, vec3, 0)],
        vec![attribute(1, vec3, 0)],
        vec![
            attribute(2, wgpu::VertexFormat::Float32x2, 0),
            attribute(3, vec3, 8),
            attribute(4, wgpu::VertexFormat::Float32x2, 20),
        ],
        vec![attribute(5, vec3, 0)],
    ];
    let strides = [12, 12, std::mem::size_of::<Detail>() as u64, 12];
    let per_vertex = [0, 1, 2, 3].map(|k| {
        Some(wgpu::VertexBufferLayout {
            array_stride: strides[k],
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &attributes[k],
        })
    });
    let view = Some(layouts.view);
    // The device may still refuse what naga accepted (e.g. storage buffers in the vertex stage).
    crate::buffers::checked(gpu, "preview pipelines", || {
        let pipeline = |groups: &[Option<&wgpu::BindGroupLayout>], stages, buffers, depth| {
            render_pipeline(gpu, &module, groups, (stages, target), buffers, depth)
        };
        let main = pipeline(&[view, Some(layouts.detail)], ("vs_main", "fs_main"), &per_vertex, Depth::Tested);
        let prt = layouts
            .prt
            .map(|prt| pipeline(&[view, Some(prt), Some(layouts.detail)], ("vs_prt", "fs_prt"), &[], Depth::Tested));
        let lit = layouts.lit.map(|storage| {
            pipeline(&[view, Some(storage), Some(layouts.detail)], ("vs_lit", "fs_lit"), &[], Depth::Tested)
        });
        let sky = pipeline(&[view, Some(layouts.sky)], ("vs_sky", "fs_sky"), &[], Depth::Behind);
        let shadow = pipeline(&[view, Some(layouts.detail)], ("vs_shadow", "fs_shadow"), &per_vertex, Depth::Shadow);
        Pipelines { main, prt, lit, sky, shadow }
    })
    .map_err(|e| crate::ShaderError {
        file: "preview.wgsl".into(),
        line: 0,
        message: e.to_string(),
        report: format!("preview.wgsl: {e}"),
    })
}

/// How a pipeline uses the depth buffer.
#[derive(Clone, Copy, PartialEq)]
pub(super) enum Depth {
    /// Tested and written: geometry.
    Tested,
    /// Neither: the background, drawn first.
    Behind,
    /// Tested and written, with a slope bias, and nothing else: the sun's depth map.
    Shadow,
}

pub(super) fn render_pipeline(
    gpu: &Gpu,
    module: &wgpu::ShaderModule,
    groups: &[Option<&wgpu::BindGroupLayout>],
    ((vs, fs), (target, samples)): ((&str, &str), (wgpu::TextureFormat, u32)),
    buffers: &[Option<wgpu::VertexBufferLayout>],
    depth: Depth,
) -> wgpu::RenderPipeline {
    let tested = depth != Depth::Behind;
    let shadow = depth == Depth::Shadow;
    let color = [Some(target.into())];
    let pipeline_layout = gpu.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("preview"),
        bind_group_layouts: groups,
        immediate_size: 0,
    });
    gpu.device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("preview"),
        layout: Some(&pipeline_layout),
        vertex: wgpu::VertexState { module, entry_point: Some(vs), buffers, compilation_options: Default::default() },
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some(fs),
            targets: if shadow { &[] } else { &color },
            compilation_options: Default::default(),
        }),
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: Some(wgpu::DepthStencilState {
            format: if shadow { sun_shadow::FORMAT } else { DEPTH },
            depth_write_enabled: Some(tested),
            depth_compare: Some(if tested { wgpu::CompareFunction::Less } else { wgpu::CompareFunction::Always }),
            stencil: Default::default(),
            // Slopes facing the sun at a grazing angle would shadow themselves.
            bias: if shadow {
                wgpu::DepthBiasState { constant: 0, slope_scale: 1.5, clamp: 0.0 }
            } else {
                Default::default()
            },
        }),
        // The sun's depth map has one sample, whatever the view's.
        multisample: wgpu::MultisampleState { count: if shadow { 1 } else { samples }, ..Default::default() },
        multiview_mask: None,
        cache: None,
    })
}
