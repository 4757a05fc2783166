// BSPVT per-vertex shading (engine/src/bspvt/shade.rs on the GPU): every light polygon, taken
// relative to the vertex, is clipped by each cube face's frustum and then down the face's BSP
// visibility tree (planes through the vertex); each piece at a leaf with v > 0 is integrated
// with LTC (diffuse + GGX specular) and weighted by v. Mode 0 integrates the whole polygon with
// no visibility (`ltc-unshadowed`).
//
// The per-vertex LTC setup (shading frame, M⁻¹, albedos — view-dependent table lookups) comes
// from the CPU; this shader does the clipping, descent and integration, in f32 (the polygon
// code shared with the viewport's per-pixel lights is in ltc.wgsl).

// #include "ltc.wgsl"

const MAX_DEPTH: u32 = 32u;
const SQRT_2: f32 = 1.41421356237310;

struct Params {
    vertex_count: u32,
    light_count: u32,
    // 0: unshadowed, 1: visibility trees.
    mode: u32,
    pad: u32,
}

struct Vertex {
    p: vec4<f32>,
    // Rows of world → diffuse space (row 2 is the normal).
    frame0: vec4<f32>,
    frame1: vec4<f32>,
    frame2: vec4<f32>,
    // Rows of world → specular LTC space.
    spec0: vec4<f32>,
    spec1: vec4<f32>,
    spec2: vec4<f32>,
    diffuse: vec4<f32>,
    // rgb weight; w = 1 when there is a specular lobe.
    spec: vec4<f32>,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> vertices: array<Vertex>;
@group(0) @binding(2) var<storage, read> lights: array<Light>;
@group(0) @binding(3) var<storage, read> record_start: array<u32>;
@group(0) @binding(4) var<storage, read> records: array<u32>;
@group(0) @binding(5) var<storage, read_write> radiance: array<vec4<f32>>;
// Polygons that outgrew MAX_VERTS or trees deeper than MAX_DEPTH: the host reports them.
@group(0) @binding(6) var<storage, read_write> overflow: atomic<u32>;

fn overflowed() {
    atomicAdd(&overflow, 1u);
}

fn byte_at(i: u32) -> u32 {
    return (records[i >> 2u] >> (8u * (i & 3u))) & 0xffu;
}

// (C, S, T) of cube face f: the point (s, t) is the direction C + s S + t T.
fn face_basis(f: u32) -> mat3x3<f32> {
    switch f {
        case 0u: { return mat3x3<f32>(vec3(1.0, 0.0, 0.0), vec3(0.0, 0.0, -1.0), vec3(0.0, -1.0, 0.0)); }
        case 1u: { return mat3x3<f32>(vec3(-1.0, 0.0, 0.0), vec3(0.0, 0.0, 1.0), vec3(0.0, -1.0, 0.0)); }
        case 2u: { return mat3x3<f32>(vec3(0.0, 1.0, 0.0), vec3(1.0, 0.0, 0.0), vec3(0.0, 0.0, 1.0)); }
        case 3u: { return mat3x3<f32>(vec3(0.0, -1.0, 0.0), vec3(1.0, 0.0, 0.0), vec3(0.0, 0.0, -1.0)); }
        case 4u: { return mat3x3<f32>(vec3(0.0, 0.0, 1.0), vec3(1.0, 0.0, 0.0), vec3(0.0, -1.0, 0.0)); }
        default: { return mat3x3<f32>(vec3(0.0, 0.0, -1.0), vec3(-1.0, 0.0, 0.0), vec3(0.0, -1.0, 0.0)); }
    }
}

// Normal of the plane through the origin that the face line a s + b t + c = 0 stands for.
fn line_plane(f: u32, a: f32, b: f32, c: f32) -> vec3<f32> {
    let m = face_basis(f);
    return m[0] * c + m[1] * a + m[2] * b;
}

fn clip_frustum(src: ptr<function, Poly>, f: u32) -> Poly {
    var p = clip(src, line_plane(f, -1.0, 0.0, 1.0));
    p = clip(&p, line_plane(f, 1.0, 0.0, 1.0));
    p = clip(&p, line_plane(f, 0.0, -1.0, 1.0));
    return clip(&p, line_plane(f, 0.0, 1.0, 1.0));
}

// Outgoing radiance per unit light radiance from one piece of a light.
fn piece(p: ptr<function, Poly>, vx: Vertex) -> vec3<f32> {
    var d = transformed(p, vx.frame0.xyz, vx.frame1.xyz, vx.frame2.xyz);
    var out = vx.diffuse.xyz * cosine_integral(&d);
    if (vx.spec.w > 0.0) {
        var s = transformed(p, vx.spec0.xyz, vx.spec1.xyz, vx.spec2.xyz);
        out = out + vx.spec.xyz * cosine_integral(&s);
    }
    return out;
}

// Descends face f's pre-order tree starting at byte `at`: the byte index only grows, so the
// stack holds just the polygons of the negative sides still to visit.
fn walk(at: u32, f: u32, start: ptr<function, Poly>, vx: Vertex) -> vec3<f32> {
    var acc = vec3<f32>(0.0);
    var stack: array<Poly, 32>;
    var sp = 0u;
    var cur = *start;
    var i = at;
    loop {
        let b = byte_at(i);
        if ((b & 0x80u) == 0u) {
            let v = f32(b) / 127.0;
            if (v > 0.0 && cur.n > 0u) {
                acc = acc + v * piece(&cur, vx);
            }
            i = i + 1u;
            if (sp == 0u) {
                break;
            }
            sp = sp - 1u;
            cur = stack[sp];
        } else {
            if (sp >= MAX_DEPTH) {
                overflowed();
                break;
            }
            let bits = (b << 16u) | (byte_at(i + 1u) << 8u) | byte_at(i + 2u);
            let theta = f32((bits >> 12u) & 0x7ffu) / 2048.0 * (2.0 * PI);
            let c = (f32(bits & 0xfffu) - 2047.0) / 2047.0 * SQRT_2;
            let pl = line_plane(f, cos(theta), sin(theta), -c);
            if (cur.n > 0u) {
                stack[sp] = clip(&cur, -pl);
                cur = clip(&cur, pl);
            } else {
                stack[sp].n = 0u;
            }
            sp = sp + 1u;
            i = i + 3u;
        }
    }
    return acc;
}

fn u16_at(i: u32) -> u32 {
    return byte_at(i) | (byte_at(i + 1u) << 8u);
}

fn through_trees(vi: u32, rel: ptr<function, Poly>, vx: Vertex) -> vec3<f32> {
    let start = record_start[vi];
    var acc = vec3<f32>(0.0);
    var at = start + 12u;
    for (var f = 0u; f < 6u; f = f + 1u) {
        let len = u16_at(start + 2u * f);
        if (len > 0u) {
            var p = clip_frustum(rel, f);
            if (p.n > 0u) {
                acc = acc + walk(at, f, &p, vx);
            }
        }
        at = at + len;
    }
    return acc;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let vi = id.x;
    if (vi >= params.vertex_count) {
        return;
    }
    let vx = vertices[vi];
    var total = vec3<f32>(0.0);
    for (var l = 0u; l < params.light_count; l = l + 1u) {
        let light = lights[l];
        var rel = relative(light, vx.p.xyz, vx.frame2.xyz);
        if (rel.n == 0u) {
            continue;
        }
        var w: vec3<f32>;
        if (params.mode == 0u) {
            w = piece(&rel, vx);
        } else {
            w = through_trees(vi, &rel, vx);
        }
        total = total + light.radiance * w;
    }
    radiance[vi] = vec4<f32>(total, 1.0);
}
