// The editor's viewport: meshes drawn with per-vertex radiance (the shading methods' results),
// exposed and clamped like `kage render`'s PNGs.

struct View {
    view_proj: mat4x4<f32>,
    // x: exposure multiplier 2^stops; y: 1 to show the error overlay's display colours as they are.
    exposure: vec4<f32>,
}

@group(0) @binding(0) var<uniform> view: View;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) radiance: vec3<f32>,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) radiance: vec3<f32>,
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = view.view_proj * vec4<f32>(v.position, 1.0);
    out.radiance = v.radiance;
    return out;
}

// The target is plain Rgba8Unorm (what egui shows as an image): encode sRGB here.
fn srgb(c: vec3<f32>) -> vec3<f32> {
    return select(1.055 * pow(c, vec3<f32>(1.0 / 2.4)) - 0.055, 12.92 * c, c <= vec3<f32>(0.0031308));
}

@fragment
fn fs_main(v: VertexOut) -> @location(0) vec4<f32> {
    if (view.exposure.y > 0.5) {
        return vec4<f32>(v.radiance, 1.0);
    }
    // Clamped like the PNGs.
    return vec4<f32>(srgb(clamp(v.radiance * view.exposure.x, vec3<f32>(0.0), vec3<f32>(1.0))), 1.0);
}
