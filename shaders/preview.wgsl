// The editor's viewport: meshes drawn with per-vertex radiance (the shading methods' results)
// and the base-colour texture's detail per pixel (editor/src/detail.rs), exposed and clamped
// like `kage render`'s PNGs (vs_main, fs_main); and PRT with the shadows between groups
// evaluated per pixel (vs_prt, fs_prt), as `kage render` images do.

struct View {
    view_proj: mat4x4<f32>,
    // x: exposure multiplier 2^stops; y: 1 to show the error overlay's display colours as they are.
    exposure: vec4<f32>,
    // World from clip space, for the sky's view rays.
    inverse_view_proj: mat4x4<f32>,
}

@group(0) @binding(0) var<uniform> view: View;

// The base-colour texture (one white texel for untextured meshes).
@group(1) @binding(0) var base_color: texture_2d<f32>;
@group(1) @binding(1) var base_sampler: sampler;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) radiance: vec3<f32>,
    // The base-colour UV (its texture transform applied) and the texture's value there.
    @location(2) uv: vec2<f32>,
    @location(3) at_vertex: vec3<f32>,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) radiance: vec3<f32>,
    @location(1) uv: vec2<f32>,
    @location(2) at_vertex: vec3<f32>,
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = view.view_proj * vec4<f32>(v.position, 1.0);
    out.radiance = v.radiance;
    out.uv = v.uv;
    out.at_vertex = v.at_vertex;
    return out;
}

// The target is plain Rgba8Unorm (what egui shows as an image): encode sRGB here.
fn srgb(c: vec3<f32>) -> vec3<f32> {
    return select(1.055 * pow(c, vec3<f32>(1.0 / 2.4)) - 0.055, 12.92 * c, c <= vec3<f32>(0.0031308));
}

// Radiance as shown: exposed, clamped like the PNGs and sRGB-encoded, or as it is (overlay).
fn display(radiance: vec3<f32>) -> vec4<f32> {
    if (view.exposure.y > 0.5) {
        return vec4<f32>(radiance, 1.0);
    }
    return vec4<f32>(srgb(clamp(radiance * view.exposure.x, vec3<f32>(0.0), vec3<f32>(1.0))), 1.0);
}

// Lighting from the vertices, texture from the pixel: the radiance times the texture here over
// its value interpolated from the vertices (a channel black at the vertices stays black).
@fragment
fn fs_main(v: VertexOut) -> @location(0) vec4<f32> {
    if (view.exposure.y > 0.5) {
        return display(v.radiance); // the overlay's colours, as they are
    }
    let here = textureSample(base_color, base_sampler, v.uv).rgb;
    let lit = v.at_vertex > vec3<f32>(1e-6);
    let ratio = select(vec3<f32>(0.0), here / max(v.at_vertex, vec3<f32>(1e-6)), lit);
    return display(v.radiance * ratio);
}

// The environment behind the geometry (editor/src/sky.rs): one full-screen triangle, each pixel
// the map filtered bilinearly along its view ray (dir_to_uv's mapping: u = atan2(x, −z)/2π,
// v = acos(y)/π in the map's frame, the light's rotation about +Y undone first).

struct Sky {
    // x, y: cos and sin of the rotation about +Y; z: intensity.
    rotation_intensity: vec4<f32>,
}

@group(1) @binding(0) var sky_map: texture_2d<f32>;
@group(1) @binding(1) var<uniform> sky: Sky;

struct SkyOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) ndc: vec2<f32>,
}

@vertex
fn vs_sky(@builtin(vertex_index) vi: u32) -> SkyOut {
    let p = vec2<f32>(f32((vi << 1u) & 2u), f32(vi & 2u)) * 2.0 - 1.0;
    var out: SkyOut;
    out.clip = vec4<f32>(p, 1.0, 1.0);
    out.ndc = p;
    return out;
}

@fragment
fn fs_sky(v: SkyOut) -> @location(0) vec4<f32> {
    let near = view.inverse_view_proj * vec4<f32>(v.ndc, 0.0, 1.0);
    let far = view.inverse_view_proj * vec4<f32>(v.ndc, 1.0, 1.0);
    let d = normalize(far.xyz / far.w - near.xyz / near.w);
    let c = sky.rotation_intensity.x;
    let s = sky.rotation_intensity.y;
    let m = vec3<f32>(c * d.x - s * d.z, d.y, s * d.x + c * d.z);
    let pi = 3.14159265358979;
    let u = fract(atan2(m.x, -m.z) / (2.0 * pi));
    let w = acos(clamp(m.y, -1.0, 1.0)) / pi;
    return display(sky_bilinear(vec2<f32>(u, w)) * sky.rotation_intensity.z);
}

// EnvMap::bilinear: between texel centres, wrapping in u and clamped at the poles (the map is
// unfilterable 32-bit float, so the four texels are loaded and blended here).
fn sky_bilinear(uv: vec2<f32>) -> vec3<f32> {
    let size = vec2<i32>(textureDimensions(sky_map));
    let x = uv.x * f32(size.x) - 0.5;
    let y = clamp(uv.y * f32(size.y) - 0.5, 0.0, f32(size.y - 1));
    let x0 = floor(x);
    let y0 = floor(y);
    let f = vec2<f32>(x - x0, y - y0);
    let i0 = ((i32(x0) % size.x) + size.x) % size.x;
    let i1 = (i0 + 1) % size.x;
    let j0 = i32(y0);
    let j1 = min(j0 + 1, size.y - 1);
    let top = mix(textureLoad(sky_map, vec2<i32>(i0, j0), 0).rgb, textureLoad(sky_map, vec2<i32>(i1, j0), 0).rgb, f.x);
    let bottom = mix(textureLoad(sky_map, vec2<i32>(i0, j1), 0).rgb, textureLoad(sky_map, vec2<i32>(i1, j1), 0).rgb, f.x);
    return mix(top, bottom, f.y);
}

// Per-pixel PRT (engine/src/prt/mod.rs, Frame::shade_hit):
//   L = ρ · max(0, Ls − Σ_i B_i T_i (1 − Π_o (1 − V_o(p, w_i))))
// with ρ, Ls and T_i interpolated across the triangle and V_o looked up at the pixel's point.
// Triangles are drawn unindexed: each vertex reads its triangle's corners, so the fragment can
// interpolate any number of T_i from storage.

struct PrtParams {
    regions: u32,
    groups: u32,
}

struct PrtVertex {
    // xyz world position; w = group index.
    p: vec4<f32>,
    // rgb Ls (albedo not applied).
    ls: vec4<f32>,
    // rgb diffuse albedo toward the eye.
    albedo: vec4<f32>,
}

@group(1) @binding(0) var<uniform> prt: PrtParams;
@group(1) @binding(1) var<storage, read> indices: array<u32>;
@group(1) @binding(2) var<storage, read> prt_vertices: array<PrtVertex>;
// T_i per vertex, vertex-major.
@group(1) @binding(3) var<storage, read> shadow_t: array<f32>;
@group(1) @binding(4) var<storage, read> regions: array<Region>;
// Per group and region.
@group(1) @binding(5) var<storage, read> silhouettes: array<Silhouette>;
@group(1) @binding(6) var<storage, read> tables: array<f32>;

struct PrtOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) position: vec3<f32>,
    @location(1) bary: vec3<f32>,
    @location(2) @interpolate(flat) corners: vec3<u32>,
}

@vertex
fn vs_prt(@builtin(vertex_index) vi: u32) -> PrtOut {
    let base = vi - vi % 3u;
    let corners = vec3<u32>(indices[base], indices[base + 1u], indices[base + 2u]);
    let k = vi % 3u;
    let p = prt_vertices[corners[k]].p.xyz;
    var out: PrtOut;
    out.clip = view.view_proj * vec4<f32>(p, 1.0);
    out.position = p;
    out.bary = vec3<f32>(select(0.0, 1.0, k == 0u), select(0.0, 1.0, k == 1u), select(0.0, 1.0, k == 2u));
    out.corners = corners;
    return out;
}

@fragment
fn fs_prt(v: PrtOut) -> @location(0) vec4<f32> {
    let a = prt_vertices[v.corners.x];
    let b = prt_vertices[v.corners.y];
    let c = prt_vertices[v.corners.z];
    let w = v.bary;
    let albedo = a.albedo.xyz * w.x + b.albedo.xyz * w.y + c.albedo.xyz * w.z;
    var l = a.ls.xyz * w.x + b.ls.xyz * w.y + c.ls.xyz * w.z;
    let own = u32(a.p.w);
    let q = prt.regions;
    for (var r = 0u; r < q; r = r + 1u) {
        let t = shadow_t[v.corners.x * q + r] * w.x + shadow_t[v.corners.y * q + r] * w.y
            + shadow_t[v.corners.z * q + r] * w.z;
        if (t <= 0.0) {
            continue;
        }
        let open = open_fraction(own, r, prt.groups, q, v.position, regions[r].power.w);
        if (open < 1.0) {
            l = l - regions[r].power.xyz * (t * (1.0 - open));
        }
    }
    return display(albedo * max(l, vec3<f32>(0.0)));
}

// #include "silhouette.wgsl"
