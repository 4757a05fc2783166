//! The per-pixel draws' data: PRT's per-vertex terms for its shadows between groups, and the
//! polygonal lights' lobes, the environment's mip chain and the sun for the lights per pixel.

use super::*;

/// PRT per pixel: one unindexed draw of every instance's triangles.
pub(super) struct PrtDraw {
    pub(super) bind: wgpu::BindGroup,
    /// Per instance, its range of the unindexed draw (drawn with its base-colour texture).
    pub(super) ranges: Vec<std::ops::Range<u32>>,
}

/// `PrtParams` of preview.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(super) struct PrtParams {
    pub(super) regions: u32,
    pub(super) groups: u32,
    pub(super) pad: [u32; 2],
}

/// `PrtVertex` of preview.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(super) struct PrtVertex {
    pub(super) p: [f32; 4],
    pub(super) ls: [f32; 4],
    pub(super) albedo: [f32; 4],
    /// The base-colour UV, then the cut-out's factor and cutoff ([`Detail`]).
    pub(super) uv_cut: [f32; 4],
    /// The base-colour texture's value at the vertex.
    pub(super) at_vertex: [f32; 4],
}

/// The polygonal lights per pixel: one unindexed draw per instance (each with its base-colour
/// texture) of the triangles in storage.
pub(super) struct LitDraw {
    pub(super) bind: wgpu::BindGroup,
    /// Per vertex, the radiance of everything not drawn per pixel (rewritten with every
    /// [`Viewport::upload_radiance`]).
    pub(super) rest: wgpu::Buffer,
    /// The per-vertex radiance of what is drawn per pixel (the polygonal lights, the
    /// environment's specular term), which `rest` leaves out, flattened.
    pub(super) per_pixel: Vec<Vec3>,
    /// Per instance, its range of the unindexed draw.
    pub(super) ranges: Vec<std::ops::Range<u32>>,
}

/// What the viewport needs to draw the polygonal lights per pixel: the lobes' integrals at
/// every vertex toward the eye and the per-vertex radiance computed with them; and the
/// environment's specular term, where the look has one.
pub struct PixelLights {
    /// Per vertex and light, the shadowed and unshadowed integrals of both lobes.
    pub lobes: Lobes,
    /// The polygonal lights' radiance per vertex (part of what `upload_radiance` is given).
    pub values: VertexValues,
    /// The environment's specular term per vertex and the chain it reflects.
    pub environment: Option<PixelEnvironment>,
}

/// The environment's specular term, drawn per pixel: the reflection `R` by filtered importance
/// sampling of `prefiltered` at each pixel, times the weight interpolated from the vertices;
/// and the map's sun, its BSDF at each pixel times its visibility interpolated.
pub struct PixelEnvironment {
    /// Per vertex: the term (part of what `upload_radiance` is given) and its weight.
    pub specular: SpecularVertices,
    /// The environment's mip chain.
    pub prefiltered: Prefiltered,
    /// The map's sun, if it has one.
    pub sun: Option<PixelSun>,
}

impl PixelEnvironment {
    /// The environment's part of a frame just shaded through an environment memo
    /// (`specular`: [`kage_engine::shading::baked::EnvironmentMemo::specular`]), with the
    /// map's sun from `lighting` and its per-vertex visibility from `eye`'s frame.
    pub fn new(
        flat: &FlatScene,
        specular: &SpecularVertices,
        prefiltered: &Prefiltered,
        lighting: &prt::Lighting,
        eye: Vec3,
    ) -> Self {
        let sun = lighting.split_sun().0.map(|sun| {
            let values = kage_engine::shading::baked::sun_vertices(flat, &sun, eye).0;
            PixelSun { sun, values }
        });
        Self { specular: specular.clone(), prefiltered: prefiltered.clone(), sun }
    }
}

/// The sun per pixel — its BSDF at the pixel, its shadow from a depth map
/// (`sun_shadow.rs`) — and per vertex its light (part of what `upload_radiance` is
/// given: [`kage_engine::shading::baked::sun_vertices`]).
pub struct PixelSun {
    /// Direction, irradiance and size.
    pub sun: Sun,
    /// Per instance and vertex: the sun's light toward the eye.
    pub values: VertexValues,
}

/// The map's sun for the per-vertex draw: per vertex its light as the look adds it (shadowed)
/// and unshadowed ([`kage_engine::shading::baked::sun_vertices`]).
pub struct VertexSun {
    /// Direction, irradiance and size.
    pub sun: Sun,
    /// Per instance and vertex: the sun's light toward the eye where the vertex sees it.
    pub values: VertexValues,
    /// Per instance and vertex: the sun's light toward the eye were nothing in the way.
    pub open: VertexValues,
}

/// Most mip levels the shader reads.
pub(super) const MAX_LEVELS: usize = 12;

/// `LitParams` of preview.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(super) struct LitParams {
    pub(super) lights: u32,
    pub(super) levels: u32,
    pub(super) pad: [u32; 2],
    /// Rows of map-from-world; row 0's w the intensity, row 1's the solid angle of a level-0
    /// texel.
    pub(super) to_map: [[f32; 4]; 3],
    /// Per level: width, height, offset in the chain's texels.
    pub(super) level: [[u32; 4]; MAX_LEVELS],
    /// Toward the sun; w its least roughness (0: no sun).
    pub(super) sun_direction: [f32; 4],
    /// The sun's irradiance.
    pub(super) sun_irradiance: [f32; 4],
}

/// A mip chain on the device, and the chain it was uploaded from.
pub(super) struct Mips {
    pub(super) source: Prefiltered,
    pub(super) buffer: wgpu::Buffer,
}

/// `LitVertex` of preview.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(super) struct LitVertex {
    pub(super) p: [f32; 4],
    pub(super) n: [f32; 4],
    pub(super) base: [f32; 4],
    pub(super) surface: [f32; 4],
    pub(super) at_vertex: [f32; 4],
    pub(super) mr_uv: [f32; 4],
}

/// The per-pixel PRT draw of every receiver: its triangles, per-vertex terms and the shadow
/// arrays, bound to `layout`.
pub(super) fn prt_draw(gpu: &Gpu, layout: &wgpu::BindGroupLayout, flat: &FlatScene, frame: &prt::Frame) -> PrtDraw {
    let terms = frame.vertex_terms();
    let posed = frame.posed();
    let (mut vertices, mut indices, mut ranges) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..flat.instances.len() {
        let mesh = flat.mesh(i);
        let (base, start) = (vertices.len() as u32, indices.len() as u32);
        indices.extend(mesh.triangles.iter().flatten().map(|k| base + k));
        ranges.push(start..indices.len() as u32);
        let group = posed.group_of[i] as f32;
        vertices.extend(detail::vertices(flat, i).iter().enumerate().map(|(v, d)| {
            let p = flat.vertex(i, v).0;
            PrtVertex {
                p: [p.x, p.y, p.z, group],
                ls: terms.ls[i][v].extend(0.0).into(),
                albedo: terms.albedo[i][v].extend(0.0).into(),
                uv_cut: [d.uv[0], d.uv[1], d.cut[0], d.cut[1]],
                at_vertex: Vec3::from(d.at_vertex).extend(0.0).into(),
            }
        }));
    }
    let shadows = ShadowArrays::new(posed);
    let params = PrtParams { regions: posed.regions.len() as u32, groups: posed.silhouettes.len() as u32, pad: [0; 2] };
    let buffers = [
        uniform(gpu, "preview prt params", &params),
        storage(gpu, "preview indices", &indices),
        storage(gpu, "preview prt vertices", &vertices),
        storage(gpu, "preview shadow t", &terms.shadow_t.concat()),
        storage(gpu, "preview regions", &shadows.regions),
        storage(gpu, "preview silhouettes", &shadows.silhouettes),
        storage(gpu, "preview tables", &shadows.tables),
    ];
    PrtDraw { bind: bind_buffers(gpu, layout, &buffers), ranges }
}

/// A bind group of `buffers` at bindings 0, 1, … of `layout`.
pub(super) fn bind_buffers(gpu: &Gpu, layout: &wgpu::BindGroupLayout, buffers: &[wgpu::Buffer]) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = buffers
        .iter()
        .enumerate()
        .map(|(k, b)| wgpu::BindGroupEntry { binding: k as u32, resource: b.as_entire_binding() })
        .collect();
    gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("preview storage"),
        layout,
        entries: &entries,
    })
}

/// The per-pixel lights' draw of every instance, bound to `layout` with the environment's
/// chain `mips` (uploaded from `lights.environment`); `None` when a light is one the shader
/// does not take or the terms do not fit the snapshot.
pub(super) fn lit_draw(
    gpu: &Gpu,
    layout: &wgpu::BindGroupLayout,
    flat: &FlatScene,
    lights: &PixelLights,
    mips: Option<&wgpu::Buffer>,
) -> Option<LitDraw> {
    let gpu_lights = flat.lights.iter().map(crate::bspvt::gpu_light).collect::<Result<Vec<_>, _>>().ok()?;
    let environment = lights.environment.as_ref().filter(|_| mips.is_some());
    let specular = environment.map(|e| &e.specular);
    let counts = || (0..flat.instances.len()).map(|i| flat.vertex_count(i));
    let fits = |v: &VertexValues| v.iter().map(Vec::len).eq(counts());
    let shape = |v: &[Vec<f32>]| v.iter().map(Vec::len).eq(counts());
    let sun = environment.and_then(|e| e.sun.as_ref());
    let sun_fits = sun.is_none_or(|s| fits(&s.values));
    if !fits(&lights.values) || specular.is_some_and(|s| !fits(&s.values) || !shape(&s.weights)) || !sun_fits {
        return None;
    }
    let (mut vertices, mut indices, mut lobes, mut ranges) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for i in 0..flat.instances.len() {
        let mesh = flat.mesh(i);
        let base = vertices.len() as u32;
        let start = indices.len() as u32;
        indices.extend(mesh.triangles.iter().flatten().map(|k| base + k));
        ranges.push(start..indices.len() as u32);
        let detail = detail::vertices(flat, i);
        let weight = |v: usize| specular.map_or(0.0, |s| s.weights[i][v]);
        vertices.extend((0..mesh.positions.len()).zip(&detail).map(|(v, d)| lit_vertex(flat, i, v, d, weight(v))));
        for v in 0..mesh.positions.len() {
            lobes.extend(lights.lobes.vertex(i, v).iter().map(|[d, s]| [d[0], d[1], s[0], s[1]]));
        }
    }
    if lobes.len() != vertices.len() * flat.lights.len() {
        return None;
    }
    let mut per_pixel: Vec<Vec3> = lights.values.iter().flatten().copied().collect();
    for values in specular.map(|s| &s.values).into_iter().chain(sun.map(|s| &s.values)) {
        per_pixel.iter_mut().zip(values.iter().flatten()).for_each(|(p, s)| *p += *s);
    }
    let tables: Vec<f32> =
        ltc::table().entries().iter().flatten().chain(ggx::albedo_tables().concat().iter()).copied().collect();
    let params = lit_params(flat.lights.len(), environment.map(|e| &e.prefiltered), sun.map(|s| &s.sun));
    let rest = storage(gpu, "preview rest", &vec![[0.0f32; 4]; vertices.len()]);
    let mips = mips.cloned().unwrap_or_else(|| storage(gpu, "preview no mips", &[[0.0f32; 4]]));
    let buffers = [
        uniform(gpu, "preview lit params", &params),
        storage(gpu, "preview indices", &indices),
        storage(gpu, "preview lit vertices", &vertices),
        rest.clone(),
        storage(gpu, "preview lobes", &lobes),
        storage(gpu, "preview lights", &gpu_lights),
        storage(gpu, "preview ltc tables", &tables),
        mips,
    ];
    Some(LitDraw { bind: bind_buffers(gpu, layout, &buffers), rest, per_pixel, ranges })
}

/// The per-pixel lights' parameters: the light count and where the chain's levels are (none
/// without an environment).
pub(super) fn lit_params(lights: usize, chain: Option<&Prefiltered>, sun: Option<&Sun>) -> LitParams {
    let mut params = LitParams {
        lights: lights as u32,
        levels: 0,
        pad: [0; 2],
        to_map: [[0.0; 4]; 3],
        level: [[0; 4]; MAX_LEVELS],
        sun_direction: [0.0; 4],
        sun_irradiance: [0.0; 4],
    };
    if let Some(sun) = sun {
        let least = (SUN_ALPHA_FLOOR * sun.angular_radius).sqrt().max(1e-6);
        params.sun_direction = sun.direction.extend(least).into();
        params.sun_irradiance = sun.irradiance.extend(0.0).into();
    }
    let Some(chain) = chain else { return params };
    let (rotation, intensity) = chain.placement();
    let m = glam::Mat3::from_quat(rotation).transpose();
    let (mut offset, mut texel) = (0u32, 0.0f32);
    for (k, (w, h, texels)) in chain.levels().take(MAX_LEVELS).enumerate() {
        params.level[k] = [w as u32, h as u32, offset, 0];
        offset += texels.len() as u32;
        if k == 0 {
            texel = 4.0 * std::f32::consts::PI / (w * h) as f32;
        }
        params.levels = k as u32 + 1;
    }
    params.to_map = [m.x_axis.extend(intensity).into(), m.y_axis.extend(texel).into(), m.z_axis.extend(0.0).into()];
    params
}

/// The chain's levels, one after another, as a storage array.
pub(super) fn mip_buffer(gpu: &Gpu, chain: &Prefiltered) -> wgpu::Buffer {
    let texels: Vec<[f32; 4]> =
        chain.levels().take(MAX_LEVELS).flat_map(|(_, _, t)| t.iter().map(|c| c.extend(0.0).into())).collect();
    storage(gpu, "preview mips", &texels)
}

/// Vertex `v` of instance `i` as the per-pixel lights read it (`d`: its texture detail).
/// `weight`: the environment's specular weight there.
pub(super) fn lit_vertex(flat: &FlatScene, i: usize, v: usize, d: &Detail, weight: f32) -> LitVertex {
    let (p, n) = flat.vertex(i, v);
    // The metallic-roughness texture is read per pixel: its factors here, not its value.
    let (m, factors) = (flat.vertex_material(i, v), flat.instances[i].material);
    let mr = detail::metallic_roughness_uv(flat, i, v);
    LitVertex {
        p: p.extend(weight).into(),
        n: n.normalize_or_zero().extend(0.0).into(),
        base: m.base_color.extend(factors.metallic).into(),
        surface: [factors.roughness, m.specular, d.uv[0], d.uv[1]],
        at_vertex: Vec3::from(d.at_vertex).extend(0.0).into(),
        mr_uv: [mr[0], mr[1], d.cut[0], d.cut[1]],
    }
}
