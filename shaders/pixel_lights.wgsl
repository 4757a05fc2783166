// Polygonal lights per pixel (engine/src/bspvt/pixel.rs, Lobes::shade), shared by kage's
// viewport (preview.wgsl) and the Bevy plugin (bevy_kage.wgsl): at each pixel the LTC setup
// (shading frame, M⁻¹ and albedos from the tables) and every light's diffuse and specular
// integrals, each scaled by its visible fraction — the ratio of the shadowed to the unshadowed
// integral, both interpolated from the triangle's corners. Where the corners' specular lobes
// all miss the light, the diffuse fraction stands in; where that is undefined too, the light
// is unshadowed.
//
// The includer includes ltc.wgsl too and defines `fn table(i: u32) -> f32`: the LTC table
// (64×64 entries of 6: a, b, c, d, magnitude, fresnel; index roughness column + 64 · view
// row), then the GGX directional albedo's A and B tables (32×32 each, index μ column + 32 ·
// roughness row).

const LTC_N: u32 = 64u;
const ALBEDO_N: u32 = 32u;
// Integrals below this count as "the lobe misses the light" (pixel.rs's MISSES).
const MISSES: f32 = 1e-9;

// The LTC table's bilinear lookup (ltc::Table::lookup): (a, b, c, d) of M⁻¹, magnitude, fresnel.
fn ltc_lookup(roughness: f32, cos_theta: f32) -> array<f32, 6> {
    let n = f32(LTC_N - 1u);
    let x = clamp(roughness, 0.0, 1.0) * n;
    let y = sqrt(1.0 - clamp(cos_theta, 0.0, 1.0)) * n;
    let a0 = min(u32(x), LTC_N - 2u);
    let t0 = min(u32(y), LTC_N - 2u);
    let fa = x - f32(a0);
    let ft = y - f32(t0);
    var e: array<f32, 6>;
    for (var k = 0u; k < 6u; k = k + 1u) {
        let at = (a0 + t0 * LTC_N) * 6u + k;
        let top = table(at) * (1.0 - fa) + table(at + 6u) * fa;
        let bottom = table(at + LTC_N * 6u) * (1.0 - fa) + table(at + LTC_N * 6u + 6u) * fa;
        e[k] = top * (1.0 - ft) + bottom * ft;
    }
    return e;
}

// The GGX directional albedo F0 A(μ, r) + F90 B(μ, r) (ggx::directional_albedo).
fn directional_albedo(mu: f32, roughness: f32, f0: vec3<f32>, f90: vec3<f32>) -> vec3<f32> {
    let n = f32(ALBEDO_N - 1u);
    let x = clamp(mu, 0.0, 1.0) * n;
    let y = clamp(roughness, 0.0, 1.0) * n;
    let x0 = min(u32(x), ALBEDO_N - 2u);
    let y0 = min(u32(y), ALBEDO_N - 2u);
    let f = vec2<f32>(x - f32(x0), y - f32(y0));
    var ab: array<f32, 2>;
    for (var t = 0u; t < 2u; t = t + 1u) {
        let at = LTC_N * LTC_N * 6u + t * ALBEDO_N * ALBEDO_N + y0 * ALBEDO_N + x0;
        let top = table(at) * (1.0 - f.x) + table(at + 1u) * f.x;
        let bottom = table(at + ALBEDO_N) * (1.0 - f.x) + table(at + ALBEDO_N + 1u) * f.x;
        ab[t] = top * (1.0 - f.y) + bottom * f.y;
    }
    return f0 * ab[0] + f90 * ab[1];
}

// A lobe's visible fraction from its interpolated (shadowed, unshadowed) integrals; -1 where
// the lobe misses the light at every corner.
fn fraction(shut: f32, open: f32) -> f32 {
    if (open <= MISSES) {
        return -1.0;
    }
    return clamp(shut / open, 0.0, 1.0);
}

// A pixel's shading point: the LTC frame (ltc::view_frame: x toward the view in the tangent
// plane), its view, and the BSDF's terms (Bsdf::new, PointShader::new).
struct Surface {
    p: vec3<f32>,
    n: vec3<f32>,
    v: vec3<f32>,
    t1: vec3<f32>,
    t2: vec3<f32>,
    mu: f32,
    roughness: f32,
    diffuse: vec3<f32>,
    f0: vec3<f32>,
    f90: vec3<f32>,
    has_spec: bool,
}

// The surface at `p` (unit normal `n`) seen from `eye`, with kage's material terms.
fn surface_at(p: vec3<f32>, n: vec3<f32>, eye: vec3<f32>, base: vec3<f32>, metallic_in: f32, roughness: f32,
    specular: f32) -> Surface {
    let to_eye = eye - p;
    let v = select(n, normalize(to_eye), length(to_eye) > 0.0);
    var t1 = v - n * dot(v, n);
    if (length(t1) <= 1e-7) {
        t1 = select(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(0.0, 1.0, 0.0), abs(n.x) > 0.9);
        t1 = t1 - n * dot(t1, n);
    }
    t1 = normalize(t1);
    let metallic = clamp(metallic_in, 0.0, 1.0);
    let s = max(specular, 0.0);
    let f0 = mix(vec3<f32>(0.04 * s), base, metallic);
    let f90 = mix(vec3<f32>(s), vec3<f32>(1.0), metallic);
    let mu = dot(v, n);
    let e_dielectric = directional_albedo(abs(mu), roughness, vec3<f32>(0.04 * s), vec3<f32>(s));
    let diffuse = base * (1.0 - metallic) * max(vec3<f32>(1.0) - e_dielectric, vec3<f32>(0.0));
    let has_spec = mu > 0.0 && max(max(f0.x, f0.y), max(max(f0.z, f90.x), max(f90.y, f90.z))) > 0.0;
    return Surface(p, n, v, t1, cross(n, t1), mu, roughness, diffuse, f0, f90, has_spec);
}

// The specular LTC at a surface point: rows 0 and 2 of world → its cosine space (M⁻¹, columns
// (a, 0, b), (0, 1, 0), (c, 0, d), times the frame; row 1 is the frame's t2) and its weight.
struct SpecularLobe {
    s0: vec3<f32>,
    s2: vec3<f32>,
    weight: vec3<f32>,
}

fn specular_lobe(s: Surface) -> SpecularLobe {
    let e = ltc_lookup(s.roughness, s.mu);
    let weight = select(vec3<f32>(0.0), s.f0 * (e[4] - e[5]) + s.f90 * e[5], s.has_spec);
    return SpecularLobe(e[0] * s.t1 + e[2] * s.n, e[1] * s.t1 + e[3] * s.n, weight);
}

// The radiance one light sends toward the eye from a surface point; `lobes` holds its
// diffuse and specular (shadowed, unshadowed) integrals interpolated from the corners.
fn light_at(s: Surface, lobe: SpecularLobe, light: Light, lobes: vec4<f32>) -> vec3<f32> {
    var rel = relative(light, s.p, s.n);
    if (rel.n == 0u || edge_on(&rel)) {
        return vec3<f32>(0.0);
    }
    var d = fraction(lobes.x, lobes.y);
    d = select(d, 1.0, d < 0.0);
    var sf = fraction(lobes.z, lobes.w);
    sf = select(sf, d, sf < 0.0);
    var out = d * s.diffuse * lobe_integral(&rel, s.t1, s.t2, s.n);
    if (s.has_spec) {
        out = out + sf * lobe.weight * lobe_integral(&rel, lobe.s0, s.t2, lobe.s2);
    }
    return light.radiance * out;
}
