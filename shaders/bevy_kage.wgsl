// The Bevy plugin's material (bevy_kage/src/material.rs): Bevy's StandardMaterial with kage's
// polygonal lights added per pixel (pixel_lights.wgsl). The vertex stage is Bevy's mesh vertex
// stage (bevy_pbr's mesh.wgsl, without skins and morphs) that also passes on, per vertex, what
// the CPU computed from the bakes: the specular radiance of the lights shaded per vertex and of
// the environment (`rest`), the light that the pixel's diffuse albedo multiplies
// (`diffuse_light`: those lights' diffuse light, the environment's through PRT, and the pack's
// frozen bounces) and, for
// each light shaded per pixel, its lobes' (shadowed, unshadowed) integrals. The
// fragment stage is Bevy's StandardMaterial with the kage lights added to its lighting, scaled
// by the view's exposure as Bevy's own lights are.
//
// Specialised by two defs (bevy_kage/src/material.rs, `Variant`): KAGE_PIXEL_LIGHTS compiles in
// the per-pixel lights, KAGE_BEVY_LIGHTING Bevy's own lighting (without it, only the emission
// Bevy's lighting would add): on a CPU device a fragment stage pays for code a uniform branch
// skips.

#import bevy_pbr::{
    mesh_bindings::mesh,
    mesh_functions,
    mesh_view_bindings::view,
    view_transformations::position_world_to_clip,
    forward_io::{VertexOutput, FragmentOutput},
    pbr_fragment::pbr_input_from_standard_material,
    pbr_functions::{alpha_discard, apply_pbr_lighting, main_pass_post_lighting_processing},
    pbr_types::PbrInput,
}

// #include "ltc.wgsl"
// #include "pixel_lights.wgsl"

// Lights shaded per pixel at most (bevy_kage::shade::PIXEL_LIGHTS).
const PIXEL_LIGHTS: u32 = 4u;

struct KageParams {
    // This instance's first vertex in `kage_vertices`.
    first: u32,
    // Lights shaded per pixel (≤ PIXEL_LIGHTS).
    lights: u32,
    // KHR_materials_specular's factor.
    specular: f32,
    // The material's perceptual roughness factor (its texture not applied).
    roughness: f32,
}

// Per vertex: rest (rgb: specular), the diffuse light (rgb, albedo not applied), then
// PIXEL_LIGHTS × (diffuse shadowed, unshadowed, specular shadowed, unshadowed).
struct KageVertex {
    rest: vec4<f32>,
    diffuse_light: vec4<f32>,
    lobes: array<vec4<f32>, 4>,
}

@group(#{MATERIAL_BIND_GROUP}) @binding(100) var<uniform> kage: KageParams;
@group(#{MATERIAL_BIND_GROUP}) @binding(101) var<storage, read> kage_vertices: array<KageVertex>;
@group(#{MATERIAL_BIND_GROUP}) @binding(102) var<storage, read> kage_lights: array<Light>;
@group(#{MATERIAL_BIND_GROUP}) @binding(103) var<storage, read> kage_tables: array<f32>;

fn overflowed() {}

fn table(i: u32) -> f32 {
    return kage_tables[i];
}

struct Vertex {
    @builtin(instance_index) instance_index: u32,
    @builtin(vertex_index) index: u32,
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
#ifdef VERTEX_UVS_A
    @location(2) uv: vec2<f32>,
#endif
#ifdef VERTEX_UVS_B
    @location(3) uv_b: vec2<f32>,
#endif
#ifdef VERTEX_COLORS
    @location(5) color: vec4<f32>,
#endif
}

// Bevy's VertexOutput (forward_io.wgsl), location for location, then kage's terms.
struct KageOut {
    @builtin(position) position: vec4<f32>,
    @location(0) world_position: vec4<f32>,
    @location(1) world_normal: vec3<f32>,
#ifdef VERTEX_UVS_A
    @location(2) uv: vec2<f32>,
#endif
#ifdef VERTEX_UVS_B
    @location(3) uv_b: vec2<f32>,
#endif
#ifdef VERTEX_COLORS
    @location(5) color: vec4<f32>,
#endif
#ifdef VERTEX_OUTPUT_INSTANCE_INDEX
    @location(6) @interpolate(flat) instance_index: u32,
#endif
#ifdef VISIBILITY_RANGE_DITHER
    @location(7) @interpolate(flat) visibility_range_dither: i32,
#endif
    @location(8) rest: vec3<f32>,
    @location(9) diffuse_light: vec3<f32>,
#ifdef KAGE_PIXEL_LIGHTS
    @location(10) lobes0: vec4<f32>,
    @location(11) lobes1: vec4<f32>,
    @location(12) lobes2: vec4<f32>,
    @location(13) lobes3: vec4<f32>,
#else
    // The share of the diffuse albedo the specular layer leaves (1 − its directional albedo).
    @location(10) diffuse_kept: f32,
#endif
}

@vertex
fn vertex(v: Vertex) -> KageOut {
    var out: KageOut;
    let world_from_local = mesh_functions::get_world_from_local(v.instance_index);
    out.world_position = mesh_functions::mesh_position_local_to_world(world_from_local, vec4<f32>(v.position, 1.0));
    out.position = position_world_to_clip(out.world_position.xyz);
    out.world_normal = mesh_functions::mesh_normal_local_to_world(v.normal, v.instance_index);
#ifdef VERTEX_UVS_A
    out.uv = v.uv;
#endif
#ifdef VERTEX_UVS_B
    out.uv_b = v.uv_b;
#endif
#ifdef VERTEX_COLORS
    out.color = v.color;
#endif
#ifdef VERTEX_OUTPUT_INSTANCE_INDEX
    out.instance_index = v.instance_index;
#endif
#ifdef VISIBILITY_RANGE_DITHER
    out.visibility_range_dither = mesh_functions::get_visibility_range_dither_level(
        v.instance_index, world_from_local[3]);
#endif
    // The vertex's index in its own mesh: Bevy draws from a shared slab.
    let k = kage.first + v.index - mesh[v.instance_index].first_vertex_index;
    let terms = kage_vertices[k];
    out.rest = terms.rest.xyz;
    out.diffuse_light = terms.diffuse_light.xyz;
#ifdef KAGE_PIXEL_LIGHTS
    out.lobes0 = terms.lobes[0];
    out.lobes1 = terms.lobes[1];
    out.lobes2 = terms.lobes[2];
    out.lobes3 = terms.lobes[3];
#else
    out.diffuse_kept = diffuse_kept(out.world_position.xyz, out.world_normal);
#endif
    return out;
}

// What the diffuse albedo keeps under the dielectric specular layer (surface_at's
// 1 − E(μ, r)), per vertex with the material's roughness factor: where the lights are shaded
// per vertex, the table lookups per pixel were a fifth of lavapipe's frame.
fn diffuse_kept(p: vec3<f32>, normal: vec3<f32>) -> f32 {
    let to_eye = view.world_position - p;
    let n = normalize(normal);
    let mu = select(1.0, abs(dot(n, normalize(to_eye))), length(to_eye) > 0.0);
    let s = max(kage.specular, 0.0);
    return max(1.0 - directional_albedo(mu, kage.roughness, vec3<f32>(0.04 * s), vec3<f32>(s)).x, 0.0);
}

// Bevy's VertexOutput from ours.
fn bevy_input(k: KageOut) -> VertexOutput {
    var out: VertexOutput;
    out.position = k.position;
    out.world_position = k.world_position;
    out.world_normal = k.world_normal;
#ifdef VERTEX_UVS_A
    out.uv = k.uv;
#endif
#ifdef VERTEX_UVS_B
    out.uv_b = k.uv_b;
#endif
#ifdef VERTEX_COLORS
    out.color = k.color;
#endif
#ifdef VERTEX_OUTPUT_INSTANCE_INDEX
    out.instance_index = k.instance_index;
#endif
#ifdef VISIBILITY_RANGE_DITHER
    out.visibility_range_dither = k.visibility_range_dither;
#endif
    return out;
}

// What apply_pbr_lighting gives with no light to shade with: the emission (bevy_pbr's
// pbr_functions.wgsl, without clearcoat), and the base colour's alpha.
fn emission(pbr_input: PbrInput) -> vec4<f32> {
    let e = pbr_input.material.emissive;
    let a = pbr_input.material.base_color.a;
    return vec4<f32>(e.rgb * a * mix(1.0, view.exposure, e.a), a);
}

@fragment
fn fragment(k: KageOut, @builtin(front_facing) is_front: bool) -> FragmentOutput {
    var pbr_input = pbr_input_from_standard_material(bevy_input(k), is_front);
    pbr_input.material.base_color = alpha_discard(pbr_input.material, pbr_input.material.base_color);
    var out: FragmentOutput;
#ifdef KAGE_BEVY_LIGHTING
    out.color = apply_pbr_lighting(pbr_input);
#else
    out.color = emission(pbr_input);
#endif
    let m = pbr_input.material;
#ifdef KAGE_PIXEL_LIGHTS
    let s = surface_at(k.world_position.xyz, normalize(pbr_input.N), view.world_position, m.base_color.rgb,
        m.metallic, m.perceptual_roughness, kage.specular);
    var total = k.rest + k.diffuse_light * s.diffuse;
    let lobe = specular_lobe(s);
    var lobes = array<vec4<f32>, 4>(k.lobes0, k.lobes1, k.lobes2, k.lobes3);
    for (var l = 0u; l < min(kage.lights, PIXEL_LIGHTS); l = l + 1u) {
        total = total + light_at(s, lobe, kage_lights[l], lobes[l]);
    }
#else
    let diffuse = m.base_color.rgb * (1.0 - clamp(m.metallic, 0.0, 1.0)) * k.diffuse_kept;
    let total = k.rest + k.diffuse_light * diffuse;
#endif
    out.color = vec4<f32>(out.color.rgb + total * view.exposure, out.color.a);
    out.color = main_pass_post_lighting_processing(pbr_input, out.color);
    return out;
}
