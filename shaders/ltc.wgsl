// LTC over polygons in f32, shared by bspvt.wgsl (per vertex) and preview.wgsl (per pixel):
// Sutherland–Hodgman clipping, the clamped cosine's integral over a polygon (edge sums, as
// engine/src/math/ltc/mod.rs), and the light polygon as both upload it (kage_gpu::bspvt).
// An includer defines `fn overflowed()`, called when a clipped polygon outgrows MAX_VERTS.

const MAX_VERTS: u32 = 16u;
const PI: f32 = 3.14159265358979;
// Relative distance below which a point counts as on a plane (f32's counterpart of
// polygon::ON_PLANE).
const ON_PLANE: f32 = 1e-6;

struct Light {
    points: array<vec4<f32>, 8>,
    normal: vec3<f32>,
    count: u32,
    radiance: vec3<f32>,
    pad: u32,
}

struct Poly {
    v: array<vec3<f32>, 16>,
    n: u32,
}

fn push(p: ptr<function, Poly>, q: vec3<f32>) {
    if ((*p).n < MAX_VERTS) {
        (*p).v[(*p).n] = q;
        (*p).n = (*p).n + 1u;
    } else {
        overflowed();
    }
}

// dot(pl.xyz, q) − pl.w, or 0 within the rounding of the plane's distance.
fn side(pl: vec4<f32>, q: vec3<f32>) -> f32 {
    let d = dot(pl.xyz, q) - pl.w;
    if (abs(d) <= ON_PLANE * (abs(pl.w) + length(pl.xyz) * length(q))) {
        return 0.0;
    }
    return d;
}

// Keeps the part of the convex polygon where dot(pl, q) >= 0 (Sutherland–Hodgman).
fn clip(src: ptr<function, Poly>, pl: vec3<f32>) -> Poly {
    return clip_plane(src, vec4<f32>(pl, 0.0));
}

// Keeps the part of the convex polygon where dot(pl.xyz, q) >= pl.w (a plane not through the
// origin when pl.w != 0).
fn clip_plane(src: ptr<function, Poly>, pl: vec4<f32>) -> Poly {
    var out: Poly;
    out.n = 0u;
    let n = (*src).n;
    for (var i = 0u; i < n; i = i + 1u) {
        let a = (*src).v[i];
        let b = (*src).v[(i + 1u) % n];
        let da = side(pl, a);
        let db = side(pl, b);
        if (da >= 0.0) {
            push(&out, a);
        }
        if ((da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0)) {
            push(&out, a + (b - a) * (da / (da - db)));
        }
    }
    if (out.n < 3u) {
        out.n = 0u;
    }
    return out;
}

// ∫ max(0, z)/π over the polygon (cosine space, relative to the shading point): horizon clip,
// then the sum over edges; edge-on and back-facing polygons give 0 (ltc::integrate).
fn cosine_integral(p: ptr<function, Poly>) -> f32 {
    if ((*p).n < 3u || edge_on(p)) {
        return 0.0;
    }
    var c = clip(p, vec3<f32>(0.0, 0.0, 1.0));
    var z = 0.0;
    for (var i = 0u; i < c.n; i = i + 1u) {
        z = z + edge_z(c.v[i], c.v[(i + 1u) % c.n]);
    }
    return max(-z / (2.0 * PI), 0.0);
}

// True when the polygon's plane passes through the shading point: it is seen edge-on and
// integrates to 0 (a linear map keeps a plane through the origin through it, so the test holds
// in any lobe's space).
fn edge_on(p: ptr<function, Poly>) -> bool {
    let n = (*p).n;
    var newell = vec3<f32>(0.0);
    var scale = 0.0;
    for (var i = 0u; i < n; i = i + 1u) {
        newell = newell + cross((*p).v[i], (*p).v[(i + 1u) % n]);
        scale = max(scale, length((*p).v[i]));
    }
    let len = length(newell);
    return len == 0.0 || abs(dot(newell / len, (*p).v[0])) <= ON_PLANE * scale;
}

// The z component of one edge's θ · n (ltc::edge_integral).
fn edge_z(a: vec3<f32>, b: vec3<f32>) -> f32 {
    let e = cross(a, b);
    let l = length(e);
    return select(0.0, e.z * (atan2(l, dot(a, b)) / l), l > 0.0);
}

fn transformed(p: ptr<function, Poly>, r0: vec3<f32>, r1: vec3<f32>, r2: vec3<f32>) -> Poly {
    var out: Poly;
    out.n = (*p).n;
    for (var i = 0u; i < (*p).n; i = i + 1u) {
        let q = (*p).v[i];
        out.v[i] = vec3<f32>(dot(r0, q), dot(r1, q), dot(r2, q));
    }
    return out;
}

// The light polygon relative to the shading point `p`, clipped at the horizon of normal `n`:
// empty when the point is behind the (one-sided) light. No light arrives from below the
// horizon, but the specular LTC, clipped at its own transformed horizon, would gather some
// (engine/src/bspvt/shade.rs).
fn relative(light: Light, p: vec3<f32>, n: vec3<f32>) -> Poly {
    var rel: Poly;
    rel.n = light.count;
    for (var k = 0u; k < light.count; k = k + 1u) {
        rel.v[k] = light.points[k].xyz - p;
    }
    if (dot(light.normal, -rel.v[0]) <= 0.0) {
        rel.n = 0u;
        return rel;
    }
    return clip(&rel, n);
}

// cosine_integral of the polygon mapped by rows (r0, r1, r2), clipped at z = 0 edge by edge as
// it goes — no mapped or clipped copy of the polygon is built (private arrays are what a CPU
// device pays for most, per pixel). A convex polygon leaves the upper half-space at most once
// and comes back once: the clipped polygon closes with the edge from the exit to the entry.
fn lobe_integral(p: ptr<function, Poly>, r0: vec3<f32>, r1: vec3<f32>, r2: vec3<f32>) -> f32 {
    let n = (*p).n;
    var z = 0.0;
    var exit = vec3<f32>(0.0);
    var entry = vec3<f32>(0.0);
    var crossings = 0u;
    var q = (*p).v[0];
    var a = vec3<f32>(dot(r0, q), dot(r1, q), dot(r2, q));
    for (var i = 0u; i < n; i = i + 1u) {
        q = (*p).v[(i + 1u) % n];
        let b = vec3<f32>(dot(r0, q), dot(r1, q), dot(r2, q));
        if (a.z >= 0.0 && b.z >= 0.0) {
            z = z + edge_z(a, b);
        } else if (a.z >= 0.0) {
            exit = a + (b - a) * (a.z / (a.z - b.z));
            z = z + edge_z(a, exit);
            crossings = crossings + 1u;
        } else if (b.z >= 0.0) {
            entry = a + (b - a) * (a.z / (a.z - b.z));
            z = z + edge_z(entry, b);
            crossings = crossings + 1u;
        }
        a = b;
    }
    if (crossings == 2u) {
        z = z + edge_z(exit, entry);
    }
    return max(-z / (2.0 * PI), 0.0);
}
