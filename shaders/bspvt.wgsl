// BSPVT per-vertex shading (engine/src/bspvt/shade.rs on the GPU): every light polygon, taken
// relative to the vertex, is clipped by each cube face's frustum and then down the face's BSP
// visibility tree (planes through the vertex); each piece at a leaf with v > 0 is integrated
// with LTC (diffuse + GGX specular) and weighted by v; the occluded share 1 − v sees the parts
// of the piece in front of its occluders' depth planes (engine/src/bspvt/depth.rs). Mode 0
// integrates the whole polygon with no visibility (`ltc-unshadowed`).
//
// The per-vertex LTC setup (shading frame, M⁻¹, albedos — view-dependent table lookups) comes
// from the CPU; this shader does the clipping, descent and integration, in f32 (the polygon
// code shared with the viewport's per-pixel lights is in ltc.wgsl).

// #include "ltc.wgsl"

const MAX_DEPTH: u32 = 32u;
const SQRT_2: f32 = 1.41421356237310;
// Texels per side of a tile of the coverage grid (the depth quadtrees split on its boundaries).
const TILE: u32 = 8u;

struct Params {
    vertex_count: u32,
    light_count: u32,
    // 0: unshadowed, 1: visibility trees.
    mode: u32,
    // Cube-face resolution of the bake.
    res: u32,
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

// The bounding plane stored at byte i: (unit normal, distance) from its octahedral codes and
// the top three bytes of the distance's f32 bits.
fn plane_at(i: u32) -> vec4<f32> {
    let a = f32(u16_at(i)) / 65534.0 * 2.0 - 1.0;
    let b = f32(u16_at(i + 2u)) / 65534.0 * 2.0 - 1.0;
    var n = vec3<f32>(a, b, 1.0 - abs(a) - abs(b));
    let t = max(-n.z, 0.0);
    n.x = n.x + select(t, -t, n.x >= 0.0);
    n.y = n.y + select(t, -t, n.y >= 0.0);
    let c = bitcast<f32>((byte_at(i + 4u) << 24u) | (byte_at(i + 5u) << 16u) | (byte_at(i + 6u) << 8u));
    return vec4<f32>(normalize(n), c);
}

fn edge(k: u32) -> f32 {
    return 2.0 * f32(k) / f32(params.res) - 1.0;
}

// The polygon clipped to the texels [r.x, r.y) × [r.z, r.w) of face f.
fn clip_cell(src: ptr<function, Poly>, f: u32, r: vec4<u32>) -> Poly {
    var p = clip(src, line_plane(f, 1.0, 0.0, -edge(r.x)));
    p = clip(&p, line_plane(f, -1.0, 0.0, edge(r.y)));
    p = clip(&p, line_plane(f, 0.0, 1.0, -edge(r.z)));
    return clip(&p, line_plane(f, 0.0, -1.0, edge(r.w)));
}

// The children of the texel cell r = [r.x, r.y) × [r.z, r.w) (engine/src/bspvt/depth.rs,
// `children`): a cell of more than one tile halves each axis spanning more than one on a tile
// boundary, a cell inside a tile halves both; the lower half first, then the upper, s before t.
fn half(a: u32, b: u32, inside: bool) -> u32 {
    let n = (b + TILE - 1u) / TILE - a / TILE;
    if (inside) {
        return (a + b) / 2u;
    }
    if (n == 1u) {
        return b;
    }
    return (a / TILE + n / 2u) * TILE;
}

fn spans_one_tile(a: u32, b: u32) -> bool {
    return (b + TILE - 1u) / TILE - a / TILE == 1u;
}

// The light of the parts of `src` (inside face f's frustum) in front of the planes of the
// face's depth quadtree at byte `at`; cells outside the texels [lo, hi] the piece covers are
// walked past.
fn front(at: u32, f: u32, src: ptr<function, Poly>, vx: Vertex) -> vec3<f32> {
    let res = params.res;
    let m = face_basis(f);
    var lo_st = vec2<f32>(1e30);
    var hi_st = vec2<f32>(-1e30);
    for (var q = 0u; q < (*src).n; q = q + 1u) {
        let v = (*src).v[q];
        let st = vec2<f32>(dot(v, m[1]), dot(v, m[2])) / dot(v, m[0]);
        lo_st = min(lo_st, st);
        hi_st = max(hi_st, st);
    }
    let lo = texel_of(lo_st);
    let hi = texel_of(hi_st);
    var cells: array<vec4<u32>, 32>;
    cells[0] = vec4<u32>(0u, res, 0u, res);
    var sp = 1u;
    var i = at;
    var acc = vec3<f32>(0.0);
    loop {
        if (sp == 0u) {
            break;
        }
        sp = sp - 1u;
        let r = cells[sp];
        let meets = r.x <= hi.x && lo.x < r.y && r.z <= hi.y && lo.y < r.w;
        let tag = byte_at(i);
        if (tag == 0u) {
            i = i + 1u;
        } else if (tag == 1u) {
            let pl = plane_at(i + 1u);
            if (meets && pl.w > 0.0) {
                var cell = clip_cell(src, f, r);
                if (cell.n > 0u) {
                    var ahead = clip_plane(&cell, vec4<f32>(-pl.xyz, -pl.w));
                    if (ahead.n > 0u) {
                        acc = acc + piece(&ahead, vx);
                    }
                }
            }
            i = i + 8u;
        } else {
            // The children, the last pushed first so that they pop in the stored order.
            let inside = spans_one_tile(r.x, r.y) && spans_one_tile(r.z, r.w);
            let im = half(r.x, r.y, inside);
            let jm = half(r.z, r.w, inside);
            var kids = array<vec4<u32>, 4>(
                vec4<u32>(im, r.y, jm, r.w),
                vec4<u32>(r.x, im, jm, r.w),
                vec4<u32>(im, r.y, r.z, jm),
                vec4<u32>(r.x, im, r.z, jm),
            );
            for (var c = 0u; c < 4u; c = c + 1u) {
                let k = kids[c];
                if (k.x < k.y && k.z < k.w) {
                    if (sp >= 32u) {
                        overflowed();
                        return acc;
                    }
                    cells[sp] = k;
                    sp = sp + 1u;
                }
            }
            i = i + 1u;
        }
    }
    return acc;
}

fn texel_of(st: vec2<f32>) -> vec2<u32> {
    let k = vec2<f32>(f32(params.res - 1u));
    return vec2<u32>(clamp((st + 1.0) * 0.5 * f32(params.res), vec2<f32>(0.0), k));
}

// A piece at a leaf of visibility v: the share v sees it whole, the occluded rest the parts in
// front of its occluders (`depth`: the face's depth bytes, 0xffffffff: none).
fn leaf(v: f32, depth: u32, f: u32, p: ptr<function, Poly>, vx: Vertex) -> vec3<f32> {
    var out = vec3<f32>(0.0);
    if (v > 0.0) {
        out = v * piece(p, vx);
    }
    if (v < 1.0 && depth != NO_DEPTH) {
        out = out + (1.0 - v) * front(depth, f, p, vx);
    }
    return out;
}

const NO_DEPTH: u32 = 0xffffffffu;

// Descends face f's pre-order tree starting at byte `at`: the byte index only grows, so the
// stack holds just the polygons of the negative sides still to visit.
fn walk(at: u32, depth: u32, f: u32, start: ptr<function, Poly>, vx: Vertex) -> vec3<f32> {
    var acc = vec3<f32>(0.0);
    var stack: array<Poly, 32>;
    var sp = 0u;
    var cur = *start;
    var i = at;
    loop {
        let b = byte_at(i);
        if ((b & 0x80u) == 0u) {
            if (cur.n > 0u) {
                acc = acc + leaf(f32(b) / 127.0, depth, f, &cur, vx);
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
    // The depth header follows the trees when the record goes on past them.
    var trees_end = start + 12u;
    for (var f = 0u; f < 6u; f = f + 1u) {
        trees_end = trees_end + u16_at(start + 2u * f);
    }
    let deep = record_start[vi + 1u] >= trees_end + 12u;
    var acc = vec3<f32>(0.0);
    var at = start + 12u;
    var depth_at = trees_end + 12u;
    for (var f = 0u; f < 6u; f = f + 1u) {
        let len = u16_at(start + 2u * f);
        var depth_len = 0u;
        if (deep) {
            depth_len = u16_at(trees_end + 2u * f);
        }
        let depth = select(NO_DEPTH, depth_at, depth_len > 0u);
        if (len > 0u || depth_len > 0u) {
            var p = clip_frustum(rel, f);
            if (p.n > 0u) {
                if (len > 0u) {
                    acc = acc + walk(at, depth, f, &p, vx);
                } else {
                    // No tree: every texel above the horizon is occluded.
                    acc = acc + leaf(0.0, depth, f, &p, vx);
                }
            }
        }
        at = at + len;
        depth_at = depth_at + depth_len;
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
