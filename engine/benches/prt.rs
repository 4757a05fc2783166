//! PRT throughput with rayon on all cores: the transfer bake (order 4, 1024 directions,
//! vertices/s) and a frame after a group moves in a scene of 8 rigid groups under a
//! procedural sky with 32 regions at 512²:
//! - `..._prt_work`: the group moved, the snapshot re-flattened, light coefficients rotated,
//!   SH shading and the other-group shadows per pixel, on primary hits from a raster;
//! - `..._with_bvh_rebuild`: the same plus what a CPU-only frame adds: the primary-ray BVH
//!   rebuilt and 512² primary rays cast (`primary_rays_512` alone).

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::{Affine3A, Quat, Vec3};
use kage_engine::prt::{self, Frame, Lighting, Shadows, SilhouetteMemo};
use kage_engine::raster;
use kage_engine::reference::Renderer;
use kage_engine::scene::{Camera, EnvMap, EnvironmentLight, Material, Scene, flatten, shapes};

/// A ground and seven objects, each its own group, under a sky.
fn eight_groups() -> Scene {
    let mut s = Scene::new("bench:eight-groups");
    let diffuse = |c: f32| Material::lambertian(Vec3::splat(c));
    s.add_object("ground", shapes::grid(12.0, 48), diffuse(0.8), Affine3A::IDENTITY);
    let at = |x: f32, y: f32, z: f32| Affine3A::from_translation(Vec3::new(x, y, z));
    s.add_object("torus a", shapes::torus(0.8, 0.3, 64, 24), diffuse(0.7), at(-3.0, 1.0, -1.0));
    s.add_object("torus b", shapes::torus(0.6, 0.25, 48, 16), diffuse(0.6), at(2.5, 0.8, 1.5));
    s.add_object("sphere a", shapes::sphere(0.7, 48, 24), diffuse(0.5), at(0.0, 0.7, 0.0));
    s.add_object("sphere b", shapes::sphere(0.5, 32, 16), diffuse(0.5), at(-1.5, 0.5, 2.5));
    s.add_object("sphere c", shapes::sphere(0.9, 48, 24), diffuse(0.5), at(3.0, 0.9, -2.5));
    s.add_object("box a", shapes::cuboid(Vec3::new(0.5, 1.0, 0.5)), diffuse(0.4), at(-0.5, 1.0, -3.0));
    s.add_object("box b", shapes::cuboid(Vec3::new(0.4, 0.4, 1.2)), diffuse(0.4), at(1.0, 0.4, 3.0));
    s.add_camera(Camera::look_at(Vec3::new(0.0, 6.0, 10.0), Vec3::new(0.0, 0.5, 0.0), 45f32.to_radians()));
    s.with_environment(EnvironmentLight::new(EnvMap::procedural_sky(256, 128, Vec3::new(-0.5, 0.6, -0.4))))
}

fn bench(c: &mut Criterion) {
    let mut scene = eight_groups();
    let s = prt::Settings { order: 4, directions: 1024, regions: 32, ..prt::Settings::default() };
    let flat = flatten(&scene);
    let vertices: usize = (0..flat.instances.len()).map(|i| flat.vertex_count(i)).sum();
    let mut g = c.benchmark_group("prt_eight_groups");
    g.sample_size(10);
    g.throughput(Throughput::Elements(vertices as u64));
    g.bench_function("bake_order4_1024dirs", |b| b.iter(|| prt::bake(&scene, &flat, &s, &|_| {}).stats.vertices));
    let bake = prt::bake(&scene, &flat, &s, &|_| {});
    let light = Lighting::new(&scene, &s).expect("sky");
    let parts = prt::Parts { bake: &bake, lighting: &light, settings: &s };
    let camera = scene.first_camera().expect("camera");
    let group = scene.find_group("torus a").expect("group");
    g.throughput(Throughput::Elements(1));
    let mut cache = SilhouetteMemo::default();
    g.bench_function("frame_after_group_move_512_with_bvh_rebuild", |b| {
        b.iter(|| {
            scene.pose_group(group, Quat::from_rotation_y(0.05), Vec3::new(0.01, 0.0, 0.0));
            let renderer = Renderer::new(&scene);
            let eye = camera.eye();
            let frame = Frame::prepare_cached(&scene, &renderer.flat, parts, Shadows::WithOthers, eye, &mut cache);
            frame.render(&renderer, &camera, 512, 512, 1).len()
        })
    });
    // The PRT work alone: primary hits come from a raster (the GPU's job in the editor).
    let renderer = Renderer::new(&scene);
    let (grid, _) = raster::primary_grid(&renderer, &camera, 512, 512, 1);
    g.bench_function("frame_after_group_move_512_prt_work", |b| {
        b.iter(|| {
            scene.pose_group(group, Quat::from_rotation_y(0.05), Vec3::new(0.01, 0.0, 0.0));
            let flat = flatten(&scene);
            let eye = camera.eye();
            let frame = Frame::prepare_cached(&scene, &flat, parts, Shadows::WithOthers, eye, &mut cache);
            frame.shade_grid(&grid, 512, &|_, l, _| l).len()
        })
    });
    g.bench_function("primary_rays_512", |b| {
        b.iter(|| kage_engine::raster::primary_grid(&renderer, &camera, 512, 512, 1).0.len())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
