// PRT per-vertex shading (engine/src/prt/mod.rs, Frame::vertex_values, on the GPU):
//   L = ρ · max(0, Ls − Σ_i B_i T(w_i) (1 − Π_o (1 − V_o(p, w_i))))
// with Ls = Σ_k t_k l_k (the vertex transfer against the group's windowed lighting) and
// T(w_i) = max(0, Σ_k t_k y_ik) (against the windowed basis at the region direction), and V_o
// each other group's box-filtered silhouette (prt/silhouette.rs, Silhouette::occlusion).

struct Params {
    vertex_count: u32,
    // n² SH coefficients per vertex.
    coeffs: u32,
    regions: u32,
    groups: u32,
}

struct Vertex {
    // xyz position; w unused.
    p: vec4<f32>,
    // rgb diffuse albedo toward the eye.
    albedo: vec3<f32>,
    group: u32,
}

struct Region {
    // rgb power B_i; w = the box filter's angular width.
    power: vec4<f32>,
}

struct Silhouette {
    w: vec3<f32>,
    plane: f32,
    u_axis: vec3<f32>,
    texels_per_unit: f32,
    v_axis: vec3<f32>,
    res: u32,
    offset: vec2<f32>,
    lo: vec2<f32>,
    hi: vec2<f32>,
    sat_base: u32,
    far_base: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> vertices: array<Vertex>;
@group(0) @binding(2) var<storage, read> transfer: array<f32>;
// Per group, n² rgb coefficients.
@group(0) @binding(3) var<storage, read> lighting: array<vec4<f32>>;
// Per group and region, n² coefficients.
@group(0) @binding(4) var<storage, read> region_basis: array<f32>;
@group(0) @binding(5) var<storage, read> regions: array<Region>;
// Per group and region.
@group(0) @binding(6) var<storage, read> silhouettes: array<Silhouette>;
// Every silhouette's summed-area table and far depths, at their bases (one buffer: eight
// storage bindings is wgpu's default limit).
@group(0) @binding(7) var<storage, read> tables: array<f32>;
@group(0) @binding(8) var<storage, read_write> radiance: array<vec4<f32>>;

fn sat_row(s: Silhouette, y: u32, x: u32, f: f32) -> f32 {
    let at = s.sat_base + y * (s.res + 1u) + x;
    let l = tables[at];
    return l + (tables[at + 1u] - l) * f;
}

// ∫ of the coverage over the box [a, b] in texels (bilinear inside a texel: exact).
fn box_integral(s: Silhouette, a: vec2<f32>, b: vec2<f32>) -> f32 {
    let n = f32(s.res);
    let ca = clamp(a, vec2<f32>(0.0), vec2<f32>(n));
    let cb = clamp(b, vec2<f32>(0.0), vec2<f32>(n));
    let ia = min(vec2<u32>(ca), vec2<u32>(s.res - 1u));
    let ib = min(vec2<u32>(cb), vec2<u32>(s.res - 1u));
    let fa = ca - vec2<f32>(ia);
    let fb = cb - vec2<f32>(ib);
    let at = sat_at(s, ib.y, fb.y, ib.x, fb.x) - sat_at(s, ib.y, fb.y, ia.x, fa.x);
    return at - sat_at(s, ia.y, fa.y, ib.x, fb.x) + sat_at(s, ia.y, fa.y, ia.x, fa.x);
}

fn sat_at(s: Silhouette, y: u32, fy: f32, x: u32, fx: f32) -> f32 {
    let lo = sat_row(s, y, x, fx);
    return lo + (sat_row(s, y + 1u, x, fx) - lo) * fy;
}

// Fraction of a region of angular width `width` around w that the occluder hides from p.
fn occlusion(s: Silhouette, p: vec3<f32>, width: f32) -> f32 {
    let c = vec2<f32>(dot(p, s.u_axis), dot(p, s.v_axis)) + s.offset;
    let r = s.plane - dot(p, s.w);
    if (r <= 0.0) {
        let t = floor(c);
        if (t.x < s.lo.x || t.y < s.lo.y || t.x >= s.hi.x || t.y >= s.hi.y) {
            return 0.0;
        }
        let depth = tables[s.far_base + u32(t.y) * s.res + u32(t.x)];
        return select(0.0, 1.0, depth > dot(p, s.w));
    }
    let half = max(0.5 * width * r * s.texels_per_unit, 0.5);
    let a = c - half;
    let b = c + half;
    if (b.x <= s.lo.x || b.y <= s.lo.y || a.x >= s.hi.x || a.y >= s.hi.y) {
        return 0.0;
    }
    return clamp(box_integral(s, a, b) * (0.25 / (half * half)), 0.0, 1.0);
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let vi = id.x;
    if (vi >= params.vertex_count) {
        return;
    }
    let vx = vertices[vi];
    let n = params.coeffs;
    let t0 = vi * n;
    let l0 = vx.group * n;
    var l = vec3<f32>(0.0);
    for (var k = 0u; k < n; k = k + 1u) {
        l = l + transfer[t0 + k] * lighting[l0 + k].xyz;
    }
    for (var r = 0u; r < params.regions; r = r + 1u) {
        let y0 = (vx.group * params.regions + r) * n;
        var t = 0.0;
        for (var k = 0u; k < n; k = k + 1u) {
            t = t + transfer[t0 + k] * region_basis[y0 + k];
        }
        if (t <= 0.0) {
            continue;
        }
        let region = regions[r];
        var open = 1.0;
        for (var g = 0u; g < params.groups; g = g + 1u) {
            if (g != vx.group) {
                open = open * (1.0 - occlusion(silhouettes[g * params.regions + r], vx.p.xyz, region.power.w));
            }
        }
        if (open < 1.0) {
            l = l - region.power.xyz * (t * (1.0 - open));
        }
    }
    radiance[vi] = vec4<f32>(vx.albedo * max(l, vec3<f32>(0.0)), 1.0);
}
