// Shadows cast between rigid groups (engine/src/prt/silhouette.rs): each other group's
// silhouette along a region's direction, box-filtered per receiver with a summed-area table.
// Included by prt.wgsl (per vertex) and preview.wgsl (per pixel); the includer declares
// `silhouettes: array<Silhouette>` (per group and region) and `tables: array<f32>` (every
// silhouette's summed-area table and far depths, at their bases).

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

// Π_o (1 − V_o): the fraction of region r's light at p that the groups other than `own` leave.
fn open_fraction(own: u32, r: u32, groups: u32, regions: u32, p: vec3<f32>, width: f32) -> f32 {
    var open = 1.0;
    for (var g = 0u; g < groups; g = g + 1u) {
        if (g != own) {
            open = open * (1.0 - occlusion(silhouettes[g * regions + r], p, width));
        }
    }
    return open;
}
