// The editor's viewport: meshes drawn with per-vertex radiance (the shading methods' results)
// and the base-colour texture's detail per pixel (editor/src/detail.rs), exposed and clamped
// like `kage render`'s PNGs (vs_main, fs_main); and PRT with the shadows between groups
// evaluated per pixel (vs_prt, fs_prt), as `kage render` images do; and the polygonal lights
// per pixel (vs_lit, fs_lit): LTC at each pixel's point, normal and view, the trees' visibility
// carried from the vertices, as engine/src/bspvt/pixel.rs does for `kage render`.

struct View {
    view_proj: mat4x4<f32>,
    // x: exposure multiplier 2^stops; y: 1 to show the error overlay's display colours as they are.
    exposure: vec4<f32>,
    // World from clip space, for the sky's view rays.
    inverse_view_proj: mat4x4<f32>,
    // xyz: the eye, for the per-pixel lights' view direction.
    eye: vec4<f32>,
    // The sun's depth map's clip from world (editor/src/sun_shadow.rs).
    sun_clip: mat4x4<f32>,
    // Toward the sun; w 1 when the depth map holds the scene.
    sun_direction: vec4<f32>,
    // The depth map's lookup: x the normal offset (world), y the depth bias, z a texel in map
    // coordinates, w the sun's softness (map units of penumbra per unit of depth from the
    // occluder; 0: a hard sun).
    sun_shadow: vec4<f32>,
}

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var sun_depth: texture_depth_2d;
@group(0) @binding(2) var sun_sampler: sampler_comparison;

// The base-colour texture (one white texel for untextured meshes); alpha is a cut-out's mask.
@group(1) @binding(0) var base_color: texture_2d<f32>;
@group(1) @binding(1) var base_sampler: sampler;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) radiance: vec3<f32>,
    // The base-colour UV (its texture transform applied) and the texture's value there.
    @location(2) uv: vec2<f32>,
    @location(3) at_vertex: vec3<f32>,
    // A cut-out's alpha factor and cutoff ((1, 0): solid).
    @location(4) cut: vec2<f32>,
    // The map's sun's unshadowed light, added per pixel where the depth map sees the sun
    // (zero: the sun, if any, is in `radiance`).
    @location(5) sun: vec3<f32>,
}

// Varyings are interpolated at the centroid of a pixel's covered samples: with several samples
// per pixel, an edge pixel's centre may lie outside the triangle, and values extrapolated there
// (normals past a silhouette, negative barycentrics) drew a dark rim round curved objects.
struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(perspective, centroid) radiance: vec3<f32>,
    @location(1) @interpolate(perspective, centroid) uv: vec2<f32>,
    @location(2) @interpolate(perspective, centroid) at_vertex: vec3<f32>,
    @location(3) @interpolate(flat) cut: vec2<f32>,
    @location(4) @interpolate(perspective, centroid) position: vec3<f32>,
    @location(5) @interpolate(perspective, centroid) sun: vec3<f32>,
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = view.view_proj * vec4<f32>(v.position, 1.0);
    out.radiance = v.radiance;
    out.uv = v.uv;
    out.at_vertex = v.at_vertex;
    out.cut = v.cut;
    out.position = v.position;
    out.sun = v.sun;
    return out;
}

// The sun's depth map (editor/src/sun_shadow.rs): every mesh's depth seen from the sun, cut-outs
// cut. Group 1 is the base-colour texture, as for fs_main.
struct ShadowOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) uv: vec2<f32>,
    @location(1) @interpolate(flat) cut: vec2<f32>,
}

@vertex
fn vs_shadow(v: VertexIn) -> ShadowOut {
    var out: ShadowOut;
    out.clip = view.sun_clip * vec4<f32>(v.position, 1.0);
    out.uv = v.uv;
    out.cut = v.cut;
    return out;
}

@fragment
fn fs_shadow(v: ShadowOut) {
    if (cut_away(textureSample(base_color, base_sampler, v.uv).a, v.cut)) {
        discard;
    }
}

// glTF alphaMode MASK (engine/src/scene/cutout.rs): the surface is absent where alpha × factor
// falls below the cutoff.
fn cut_away(alpha: f32, cut: vec2<f32>) -> bool {
    return alpha * cut.x < cut.y;
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
    // The face's normal, for the depth map's normal offset (derivatives want uniform control
    // flow: taken first).
    let face = normalize(cross(dpdx(v.position), dpdy(v.position)));
    if (view.exposure.y > 0.5) {
        return display(v.radiance); // the overlay's colours, as they are
    }
    let texel = textureSample(base_color, base_sampler, v.uv);
    if (cut_away(texel.a, v.cut)) {
        discard;
    }
    var radiance = v.radiance;
    if (view.sun_direction.w > 0.0 && any(v.sun > vec3<f32>(0.0))) {
        let n = select(-face, face, dot(face, view.sun_direction.xyz) >= 0.0);
        radiance = radiance + v.sun * sun_seen(v.position, n);
    }
    return display(radiance * detail(texel.rgb, v.at_vertex));
}

// The texture here over its value interpolated from the vertices, per channel (0 where that is 0).
fn detail(here: vec3<f32>, at_vertex: vec3<f32>) -> vec3<f32> {
    return select(vec3<f32>(0.0), here / max(at_vertex, vec3<f32>(1e-6)), at_vertex > vec3<f32>(1e-6));
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
    let t = bilinear_taps(uv, vec2<i32>(textureDimensions(sky_map)));
    let top = mix(textureLoad(sky_map, vec2<i32>(t.i.x, t.j.x), 0).rgb, textureLoad(sky_map, vec2<i32>(t.i.y, t.j.x), 0).rgb, t.f.x);
    let bottom = mix(textureLoad(sky_map, vec2<i32>(t.i.x, t.j.y), 0).rgb, textureLoad(sky_map, vec2<i32>(t.i.y, t.j.y), 0).rgb, t.f.x);
    return mix(top, bottom, t.f.y);
}

// environment::bilinear's four texels (columns i, rows j) and weights for `uv` on a map of
// `size`: between texel centres, wrapping in u, clamped at the poles.
struct Taps {
    i: vec2<i32>,
    j: vec2<i32>,
    f: vec2<f32>,
}

fn bilinear_taps(uv: vec2<f32>, size: vec2<i32>) -> Taps {
    let x = uv.x * f32(size.x) - 0.5;
    let y = clamp(uv.y * f32(size.y) - 0.5, 0.0, f32(size.y - 1));
    let x0 = floor(x);
    let y0 = floor(y);
    let i0 = ((i32(x0) % size.x) + size.x) % size.x;
    let j0 = i32(y0);
    return Taps(vec2<i32>(i0, (i0 + 1) % size.x), vec2<i32>(j0, min(j0 + 1, size.y - 1)), vec2<f32>(x - x0, y - y0));
}

// Per-pixel PRT (engine/src/prt/mod.rs, Frame::shade_hit):
//   L = ρ · max(0, Ls − Σ_i B_i T_i (1 − Π_o (1 − V_o(p, w_i))))
// with ρ, Ls and T_i interpolated across the triangle and V_o looked up at the pixel's point;
// ρ given the base-colour texture's detail (and a cut-out's mask) at the pixel as fs_main
// does, from the texture at group 2 as for fs_lit.
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
    // xy the base-colour UV; zw the cut-out's alpha factor and cutoff.
    uv_cut: vec4<f32>,
    // rgb the base-colour texture's value at the vertex.
    at_vertex: vec4<f32>,
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

// A corner of a triangle drawn unindexed from storage (vs_prt, vs_lit): the fragment gets the
// point, its barycentrics and the three corners' vertex indices.
struct CornerOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(perspective, centroid) position: vec3<f32>,
    @location(1) @interpolate(perspective, centroid) bary: vec3<f32>,
    @location(2) @interpolate(flat) corners: vec3<u32>,
}

// Draw vertex vi's triangle corners (from the indices at group 1, binding 1) and corner number.
fn triangle_of(vi: u32) -> vec4<u32> {
    let base = vi - vi % 3u;
    return vec4<u32>(indices[base], indices[base + 1u], indices[base + 2u], vi % 3u);
}

fn corner_out(t: vec4<u32>, p: vec3<f32>) -> CornerOut {
    let k = t.w;
    var out: CornerOut;
    out.clip = view.view_proj * vec4<f32>(p, 1.0);
    out.position = p;
    out.bary = vec3<f32>(select(0.0, 1.0, k == 0u), select(0.0, 1.0, k == 1u), select(0.0, 1.0, k == 2u));
    out.corners = t.xyz;
    return out;
}

@vertex
fn vs_prt(@builtin(vertex_index) vi: u32) -> CornerOut {
    let t = triangle_of(vi);
    return corner_out(t, prt_vertices[t[t.w]].p.xyz);
}

@fragment
fn fs_prt(v: CornerOut) -> @location(0) vec4<f32> {
    let a = prt_vertices[v.corners.x];
    let b = prt_vertices[v.corners.y];
    let c = prt_vertices[v.corners.z];
    let w = v.bary;
    let texel = textureSample(lit_texture, lit_sampler, a.uv_cut.xy * w.x + b.uv_cut.xy * w.y + c.uv_cut.xy * w.z);
    if (cut_away(texel.a, a.uv_cut.zw)) {
        discard;
    }
    let at_vertex = a.at_vertex.xyz * w.x + b.at_vertex.xyz * w.y + c.at_vertex.xyz * w.z;
    let albedo = (a.albedo.xyz * w.x + b.albedo.xyz * w.y + c.albedo.xyz * w.z) * detail(texel.rgb, at_vertex);
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
// #include "ltc.wgsl"
// #include "pixel_lights.wgsl"

// The polygonal lights per pixel (engine/src/bspvt/pixel.rs, Lobes::shade): at each pixel the
// LTC setup (shading frame, M⁻¹ and albedos from the tables) and every light's diffuse and
// specular integrals, each scaled by its visible fraction — the ratio of the shadowed to the
// unshadowed integral, both interpolated from the triangle's corners. Where the corners'
// specular lobes all miss the light, the diffuse fraction stands in; where that is undefined
// too, the light is unshadowed. Everything else (environment, bounce) comes from the vertices
// as `rest`. The material is interpolated from the vertices, its base colour given the
// texture's detail as fs_main does.

struct LitParams {
    lights: u32,
    // Levels of the environment's mip chain (0: no environment).
    levels: u32,
    pad: vec2<u32>,
    // Rows of map-from-world; row 0's w the intensity, row 1's the solid angle of a level-0
    // texel.
    to_map: array<vec4<f32>, 3>,
    // Per level: width, height, offset in `mips`.
    level: array<vec4<u32>, 12>,
    // Toward the map's sun; w its least roughness (0: no sun).
    sun_direction: vec4<f32>,
    // The sun's irradiance (rgb).
    sun_irradiance: vec4<f32>,
}

struct LitVertex {
    // xyz position; w the environment's specular weight V_lobe · O.
    p: vec4<f32>,
    // xyz unit normal.
    n: vec4<f32>,
    // rgb base colour at the vertex; w the metallic factor.
    base: vec4<f32>,
    // x the roughness factor, y specular factor, zw the base-colour UV.
    surface: vec4<f32>,
    // rgb the base-colour texture's value at the vertex.
    at_vertex: vec4<f32>,
    // xy the metallic-roughness texture's UV (read per pixel: G roughness, B metalness); zw the
    // cut-out's alpha factor and cutoff.
    mr_uv: vec4<f32>,
}

@group(1) @binding(0) var<uniform> lit: LitParams;
// Binding 1 is `indices`, as for PRT.
@group(1) @binding(2) var<storage, read> lit_vertices: array<LitVertex>;
// Per vertex: the radiance of everything but the polygonal lights (rgb).
@group(1) @binding(3) var<storage, read> rest: array<vec4<f32>>;
// Per vertex and light (vertex-major): diffuse shadowed, unshadowed; specular shadowed,
// unshadowed.
@group(1) @binding(4) var<storage, read> lobes: array<vec4<f32>>;
@group(1) @binding(5) var<storage, read> lights: array<Light>;
// The LTC table (64×64 entries of 6: a, b, c, d, magnitude, fresnel; index roughness row +
// 64 · view column), then the GGX directional albedo's A and B tables (32×32 each, index
// μ column + 32 · roughness row).
@group(1) @binding(6) var<storage, read> lit_tables: array<f32>;
// The environment's mip chain (prt::prefilter::Prefiltered), level after level.
@group(1) @binding(7) var<storage, read> mips: array<vec4<f32>>;
@group(2) @binding(0) var lit_texture: texture_2d<f32>;
@group(2) @binding(1) var lit_sampler: sampler;
@group(2) @binding(2) var mr_texture: texture_2d<f32>;
@group(2) @binding(3) var mr_sampler: sampler;

fn overflowed() {}

@vertex
fn vs_lit(@builtin(vertex_index) vi: u32) -> CornerOut {
    let t = triangle_of(vi);
    return corner_out(t, lit_vertices[t[t.w]].p.xyz);
}

// The LTC and GGX albedo tables for pixel_lights.wgsl.
fn table(i: u32) -> f32 {
    return lit_tables[i];
}

// The radiance from every polygonal light at a surface point, toward the eye.
fn lights_at(s: Surface, corners: vec3<u32>, w: vec3<f32>) -> vec3<f32> {
    let lobe = specular_lobe(s);
    var total = vec3<f32>(0.0);
    for (var l = 0u; l < lit.lights; l = l + 1u) {
        let a = lobes[corners.x * lit.lights + l];
        let b = lobes[corners.y * lit.lights + l];
        let c = lobes[corners.z * lit.lights + l];
        total = total + light_at(s, lobe, lights[l], a * w.x + b * w.y + c * w.z);
    }
    return total;
}

// GGX samples per reflection (prefilter::SAMPLES).
const FIS_SAMPLES: u32 = 32u;

// The environment's specular term at a surface point: the reflection R by filtered importance
// sampling (Prefiltered::reflect) times `weight`, the lobe's visible fraction and the other
// groups' open one interpolated from the vertices.
fn environment_at(s: Surface, weight: f32) -> vec3<f32> {
    if (lit.levels == 0u || weight <= 0.0 || !s.has_spec) {
        return vec3<f32>(0.0);
    }
    return reflect_environment(s.n, s.v, ggx_alpha(s.roughness), s.f0, s.f90) * weight;
}

// The sun's visibility at `p` (normal `n`) from its depth map: a hard sun's 3×3 taps each
// filtered 2×2, a wide sun's soft shadow (sun_seen_soft); outside the map (nothing there
// casts), seen.
fn sun_seen(p: vec3<f32>, n: vec3<f32>) -> f32 {
    let q = view.sun_clip * vec4<f32>(p + n * view.sun_shadow.x, 1.0);
    let uv = vec2<f32>(q.x * 0.5 + 0.5, 0.5 - q.y * 0.5);
    if (any(uv < vec2<f32>(0.0)) || any(uv > vec2<f32>(1.0)) || q.z > 1.0) {
        return 1.0;
    }
    if (view.sun_shadow.w > 0.0) {
        return sun_seen_soft(p, n, uv, q.z);
    }
    var seen = 0.0;
    for (var j = -1; j <= 1; j = j + 1) {
        for (var i = -1; i <= 1; i = i + 1) {
            let at = uv + vec2<f32>(f32(i), f32(j)) * view.sun_shadow.z;
            seen = seen + textureSampleCompareLevel(sun_depth, sun_sampler, at, q.z - view.sun_shadow.y);
        }
    }
    return seen / 9.0;
}

// Taps per search and per filter of a wide sun's shadow.
const SUN_TAPS: i32 = 16;

// A wide sun's visibility at map point `uv` (depth `z`) of `p` (normal `n`), percentage-closer
// soft shadows: the occluders' mean depth within the widest penumbra one could cast there, then
// a filter as wide as their penumbra (softness × the depth between), each over SUN_TAPS taps of
// a Vogel spiral turned per point (kage render turns its rays over the sun's disc per point
// too). Every tap's depth bias grows with its offset along the receiver's slope, so that a
// surface does not shadow itself.
fn sun_seen_soft(p: vec3<f32>, n: vec3<f32>, uv: vec2<f32>, z: f32) -> f32 {
    let softness = view.sun_shadow.w;
    let c = max(dot(n, view.sun_direction.xyz), 0.1);
    let slope = sqrt(max(1.0 - c * c, 0.0)) / c;
    let turn = fract(sin(dot(p, vec3<f32>(12.9898, 78.233, 37.719))) * 43758.547);
    let size = vec2<i32>(textureDimensions(sun_depth));
    let search = max(z * softness, view.sun_shadow.z);
    var blockers = 0.0;
    var depth = 0.0;
    for (var k = 0; k < SUN_TAPS; k = k + 1) {
        let o = vogel(k, turn) * search;
        let at = clamp(vec2<i32>((uv + o) * vec2<f32>(size)), vec2<i32>(0), size - vec2<i32>(1));
        let d = textureLoad(sun_depth, at, 0);
        if (d < z - view.sun_shadow.y - slope * length(o)) {
            blockers = blockers + 1.0;
            depth = depth + d;
        }
    }
    if (blockers == 0.0) {
        return 1.0;
    }
    let width = max((z - depth / blockers) * softness, view.sun_shadow.z);
    var seen = 0.0;
    for (var k = 0; k < SUN_TAPS; k = k + 1) {
        let o = vogel(k, turn + 0.5) * width;
        let reference = z - view.sun_shadow.y - slope * length(o);
        seen = seen + textureSampleCompareLevel(sun_depth, sun_sampler, uv + o, reference);
    }
    return seen / f32(SUN_TAPS);
}

// Point `k` of a SUN_TAPS-point Vogel spiral on the unit disc (equal areas), turned by `turn`
// turns (prt/sun.rs spreads kage render's shadow rays the same way).
fn vogel(k: i32, turn: f32) -> vec2<f32> {
    let r = sqrt((f32(k) + 0.5) / f32(SUN_TAPS));
    let a = f32(k) * 2.399963 + turn * 6.2831853;
    return r * vec2<f32>(cos(a), sin(a));
}

// The map's sun at a surface point (its roughness already floored for the sun: Look::sun_at):
// the BSDF times the sun's irradiance, times `seen`, its visibility from the depth map
// (Bsdf::eval: Lambertian plus GGX with Schlick Fresnel).
fn sun_at(s: Surface, seen: f32) -> vec3<f32> {
    let wi = lit.sun_direction.xyz;
    let cos_i = dot(s.n, wi);
    if (cos_i <= 0.0) {
        return vec3<f32>(0.0);
    }
    var f = s.diffuse / PI;
    if (s.has_spec) {
        let alpha = ggx_alpha(s.roughness);
        let h = normalize(s.v + wi);
        // The local frame's z is the normal: D and Λ read only cosines to it.
        let cos_h = dot(s.n, h);
        let hl = vec3<f32>(sqrt(max(1.0 - cos_h * cos_h, 0.0)), 0.0, cos_h);
        let lo = vec3<f32>(sqrt(max(1.0 - s.mu * s.mu, 0.0)), 0.0, s.mu);
        let li = vec3<f32>(sqrt(max(1.0 - cos_i * cos_i, 0.0)), 0.0, cos_i);
        let g2 = 1.0 / (1.0 + ggx_lambda(lo, alpha) + ggx_lambda(li, alpha));
        let fresnel = s.f0 + (s.f90 - s.f0) * pow(1.0 - clamp(dot(s.v, h), 0.0, 1.0), 5.0);
        f = f + fresnel * (ggx_d(hl, alpha) * g2 / (4.0 * s.mu * cos_i));
    }
    return f * cos_i * lit.sun_irradiance.xyz * seen;
}

fn ggx_alpha(roughness: f32) -> f32 {
    let r = clamp(roughness, 0.0, 1.0);
    return max(r * r, 1e-4);
}

fn ggx_d(h: vec3<f32>, alpha: f32) -> f32 {
    if (h.z <= 0.0) {
        return 0.0;
    }
    let a2 = alpha * alpha;
    let t = (h.x * h.x + h.y * h.y) + h.z * h.z * a2;
    return a2 / (PI * t * t);
}

fn ggx_lambda(w: vec3<f32>, alpha: f32) -> f32 {
    let cos2 = w.z * w.z;
    let tan2 = max((1.0 - cos2) / max(cos2, 1e-30), 0.0);
    return 0.5 * (sqrt(1.0 + alpha * alpha * tan2) - 1.0);
}

// ∫ L f cos over the GGX lobe (unshadowed): FIS_SAMPLES stratified visible normals (Heitz
// 2018), each weighted F · G2 / G1 and reading the mip of its solid angle.
fn reflect_environment(n: vec3<f32>, wo_world: vec3<f32>, alpha: f32, f0: vec3<f32>, f90: vec3<f32>) -> vec3<f32> {
    // Frame::from_normal (Duff et al. 2017).
    let sign = select(1.0, -1.0, n.z < 0.0);
    let fa = -1.0 / (sign + n.z);
    let fb = n.x * n.y * fa;
    let t = vec3<f32>(1.0 + sign * n.x * n.x * fa, sign * fb, -sign * n.x);
    let bt = vec3<f32>(fb, sign + n.y * n.y * fa, -n.y);
    let wo = vec3<f32>(dot(wo_world, t), dot(wo_world, bt), dot(wo_world, n));
    if (wo.z <= 0.0) {
        return vec3<f32>(0.0);
    }
    let g1 = 1.0 / (1.0 + ggx_lambda(wo, alpha));
    let vh = normalize(vec3<f32>(alpha * wo.x, alpha * wo.y, wo.z));
    let lensq = vh.x * vh.x + vh.y * vh.y;
    let t1 = select(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(-vh.y, vh.x, 0.0) / sqrt(lensq), lensq > 0.0);
    let t2 = cross(vh, t1);
    var sum = vec3<f32>(0.0);
    for (var k = 0u; k < FIS_SAMPLES; k = k + 1u) {
        // Hammersley: (k + ½)/N and the radical inverse of k.
        let r = sqrt((f32(k) + 0.5) / f32(FIS_SAMPLES));
        let phi = 2.0 * PI * f32(reverseBits(k)) * 2.3283064365386963e-10;
        let p1 = r * cos(phi);
        let sv = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - sv) * sqrt(max(1.0 - p1 * p1, 0.0)) + sv * r * sin(phi);
        let nh = t1 * p1 + t2 * p2 + vh * sqrt(max(1.0 - p1 * p1 - p2 * p2, 0.0));
        let h = normalize(vec3<f32>(alpha * nh.x, alpha * nh.y, max(nh.z, 1e-7)));
        let wi = 2.0 * dot(wo, h) * h - wo;
        if (wi.z <= 0.0) {
            continue;
        }
        let pdf = g1 * ggx_d(h, alpha) / (4.0 * wo.z);
        let lod = 0.5 * log2(1.0 / (f32(FIS_SAMPLES) * max(pdf, 1e-12) * lit.to_map[1].w)) + 1.0;
        let g2 = 1.0 / (1.0 + ggx_lambda(wo, alpha) + ggx_lambda(wi, alpha));
        let fresnel = f0 + (f90 - f0) * pow(1.0 - clamp(dot(wo, h), 0.0, 1.0), 5.0);
        let world = t * wi.x + bt * wi.y + n * wi.z;
        sum = sum + fresnel * (g2 / g1) * mip_lookup(world, lod);
    }
    return sum / f32(FIS_SAMPLES);
}

// Prefiltered::lookup: level `lod` (linear between levels) along world `dir`; level 0 by nearest
// texel as the reference reads the map, the others bilinearly.
fn mip_lookup(dir: vec3<f32>, lod_in: f32) -> vec3<f32> {
    let lod = clamp(lod_in, 0.0, f32(lit.levels - 1u));
    let k = min(u32(floor(lod)), lit.levels - 1u);
    let f = lod - f32(k);
    let d = vec3<f32>(dot(lit.to_map[0].xyz, dir), dot(lit.to_map[1].xyz, dir), dot(lit.to_map[2].xyz, dir));
    let uv = vec2<f32>(
        min(fract(atan2(d.x, -d.z) / (2.0 * PI)), 0.99999994),
        atan2(sqrt(d.x * d.x + d.z * d.z), d.y) / PI,
    );
    var value = mip_level(k, uv);
    if (f > 0.0) {
        value = mix(value, mip_level(k + 1u, uv), f);
    }
    return value * lit.to_map[0].w;
}

fn mip_level(k: u32, uv: vec2<f32>) -> vec3<f32> {
    let info = lit.level[k];
    let size = vec2<i32>(i32(info.x), i32(info.y));
    let at = i32(info.z);
    if (k == 0u) {
        let i = min(i32(uv.x * f32(size.x)), size.x - 1);
        let j = min(i32(uv.y * f32(size.y)), size.y - 1);
        return mips[at + j * size.x + i].xyz;
    }
    let t = bilinear_taps(uv, size);
    let top = mix(mips[at + t.j.x * size.x + t.i.x].xyz, mips[at + t.j.x * size.x + t.i.y].xyz, t.f.x);
    let bottom = mix(mips[at + t.j.y * size.x + t.i.x].xyz, mips[at + t.j.y * size.x + t.i.y].xyz, t.f.x);
    return mix(top, bottom, t.f.y);
}

@fragment
fn fs_lit(v: CornerOut) -> @location(0) vec4<f32> {
    let a = lit_vertices[v.corners.x];
    let b = lit_vertices[v.corners.y];
    let c = lit_vertices[v.corners.z];
    let w = v.bary;
    let uv = a.surface.zw * w.x + b.surface.zw * w.y + c.surface.zw * w.z;
    let at_vertex = a.at_vertex.xyz * w.x + b.at_vertex.xyz * w.y + c.at_vertex.xyz * w.z;
    let texel = textureSample(lit_texture, lit_sampler, uv);
    if (cut_away(texel.a, a.mr_uv.zw)) {
        discard;
    }
    let ratio = detail(texel.rgb, at_vertex);
    let others = (rest[v.corners.x].xyz * w.x + rest[v.corners.y].xyz * w.y + rest[v.corners.z].xyz * w.z) * ratio;
    let n = normalize(a.n.xyz * w.x + b.n.xyz * w.y + c.n.xyz * w.z);
    let base = (a.base.xyz * w.x + b.base.xyz * w.y + c.base.xyz * w.z) * ratio;
    let mr = textureSample(mr_texture, mr_sampler, a.mr_uv.xy * w.x + b.mr_uv.xy * w.y + c.mr_uv.xy * w.z).rgb;
    let metallic = (a.base.w * w.x + b.base.w * w.y + c.base.w * w.z) * mr.b;
    let roughness = (a.surface.x * w.x + b.surface.x * w.y + c.surface.x * w.z) * mr.g;
    let specular = a.surface.y * w.x + b.surface.y * w.y + c.surface.y * w.z;
    let s = surface_at(v.position, n, view.eye.xyz, base, metallic, roughness, specular);
    let weight = a.p.w * w.x + b.p.w * w.y + c.p.w * w.z;
    var sun = vec3<f32>(0.0);
    let seen = select(0.0, sun_seen(v.position, n), lit.sun_direction.w > 0.0 && view.sun_direction.w > 0.0);
    if (seen > 0.0) {
        let rough = surface_at(v.position, n, view.eye.xyz, base, metallic, max(roughness, lit.sun_direction.w), specular);
        sun = sun_at(rough, seen);
    }
    return display(others + lights_at(s, v.corners, w) + environment_at(s, weight) + sun);
}
