// PRT per-vertex shading (engine/src/prt/mod.rs, Frame::vertex_values, on the GPU):
//   L = ρ · max(0, Ls − Σ_i B_i T(w_i) (1 − Π_o (1 − V_o(p, w_i))))
// with Ls = Σ_k t_k l_k (the vertex transfer against the group's windowed lighting) and
// T(w_i) = max(0, Σ_k t_k y_ik) (against the windowed basis at the region direction), and V_o
// each other group's box-filtered silhouette (prt/silhouette.rs, Silhouette::occlusion; the
// lookups are in silhouette.wgsl, included at the end).

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
        let open = open_fraction(vx.group, r, params.groups, params.regions, vx.p.xyz, region.power.w);
        if (open < 1.0) {
            l = l - region.power.xyz * (t * (1.0 - open));
        }
    }
    radiance[vi] = vec4<f32>(vx.albedo * max(l, vec3<f32>(0.0)), 1.0);
}

// #include "silhouette.wgsl"
