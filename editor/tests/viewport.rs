//! The viewport's per-pixel PRT on the device (lavapipe in CI): the shadows cast between rigid
//! groups are looked up at every pixel, as `kage_engine::prt::Frame::render` does on the CPU.

use glam::Vec3;
use kage_editor::camera::Orbit;
use kage_editor::viewport::Viewport;
use kage_engine::output::display_srgb;
use kage_engine::prt::{self, Shadows};
use kage_engine::reference::Renderer;
use kage_engine::scene::{Camera, EnvMap, EnvironmentLight, flatten, import};
use kage_gpu::{Gpu, Shaders};
use std::path::PathBuf;

fn asset(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../assets").join(rel)
}

/// Fraction of pixels whose channels all lie within `levels` of the reference's.
fn within(img: &image::RgbaImage, reference: &[[u8; 3]], levels: u8) -> f64 {
    let close = img.pixels().zip(reference).filter(|(p, r)| (0..3).all(|c| p.0[c].abs_diff(r[c]) <= levels)).count();
    close as f64 / reference.len() as f64
}

#[test]
fn per_pixel_prt_matches_the_cpu_per_pixel_render_and_beats_per_vertex_shading() {
    let gpu = Gpu::new().expect("a wgpu device (lavapipe without a GPU)");
    let mut scene = import::import(&asset("scenes/bunny_two_groups.gltf"), Default::default()).unwrap();
    scene.set_environment(EnvironmentLight::new(EnvMap::load(&asset("envmaps/studio.hdr")).unwrap()));
    let s = prt::Settings { order: 4, directions: 256, regions: 16, ..prt::Settings::default() };
    let flat = flatten(&scene);
    let bake = prt::bake(&scene, &flat, &s, &|_| {});
    let light = prt::Lighting::new(&scene, &s).expect("the scene has an environment");
    let orbit = Orbit { target: Vec3::new(0.0, 0.3, 0.0), distance: 5.0, yaw: 0.6, pitch: 0.7, yfov: 0.8 };
    let frame = prt::Frame::prepare(&scene, &flat, &bake, &light, Shadows::WithOthers, &s, orbit.eye());
    let (w, h) = (240, 160);
    let camera = Camera::look_at(orbit.eye(), orbit.target, orbit.yfov);
    // The viewport draws no environment behind the geometry: neither does this CPU render.
    let mut renderer = Renderer::new(&scene);
    renderer.flat.environment = None;
    let cpu = frame.render(&renderer, &camera, w, h, 1);
    // Two stops down: the studio light saturates much of the view at 0.
    let exposure = -2.0f32;
    let reference: Vec<[u8; 3]> =
        cpu.iter().map(|p| (*p * exposure.exp2()).to_array().map(|c| (display_srgb(c) * 255.0 + 0.5) as u8)).collect();
    assert!(reference.iter().filter(|p| p.iter().any(|c| *c > 0)).count() > w * h / 3, "the scene fills the view");

    let mut vp = Viewport::new(&gpu, &Shaders::embedded()).unwrap();
    vp.upload_geometry(&gpu, &flat);
    vp.upload_prt(&gpu, &flat, Some(&frame));
    let per_pixel = vp.render_image(&gpu, [w as u32, h as u32], &orbit, exposure).unwrap();
    vp.upload_prt(&gpu, &flat, None);
    vp.upload_radiance(&gpu, &frame.vertex_values(&flat));
    let per_vertex = vp.render_image(&gpu, [w as u32, h as u32], &orbit, exposure).unwrap();
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/editor-snapshots");
    std::fs::create_dir_all(&dir).unwrap();
    per_pixel.save(dir.join("prt-per-pixel.png")).unwrap();
    per_vertex.save(dir.join("prt-per-vertex.png")).unwrap();

    // Rasterised and ray-cast silhouettes differ by a pixel at edges; f32 against f64 by a level.
    let (pixel, vertex) = (within(&per_pixel, &reference, 3), within(&per_vertex, &reference, 3));
    assert!(pixel >= 0.99, "per-pixel PRT matches the CPU render on {:.1} % of pixels", 100.0 * pixel);
    assert!(
        vertex < pixel - 0.03,
        "per-vertex shading ({:.1} %) misses shadows that per-pixel ({:.1} %) shows",
        100.0 * vertex,
        100.0 * pixel
    );
}
