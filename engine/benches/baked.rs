//! Re-shading the baked look after a light or camera change on the paper's teapot
//! configuration (`teapot_quad_light.gltf`, teapot refined to 17 000 vertices, 64² faces) under
//! a procedural sky, on all cores:
//! - `relight_vertices`: the light moved — per-vertex BSPVT shading with the lobes' pairs the
//!   viewport's per-pixel lights read, and the sun, the environment's part reused from the memo
//!   (nothing it reads changed), as the editor's `baked` view shades on the CPU;
//! - `camera_moved`: the eye moved — everything view-dependent again: BSPVT shading and lobes,
//!   the PRT frame (lighting posed, other groups' silhouettes reused) and the environment's
//!   specular term;
//! - `polygonal_part`, `environment_part`: each light alone as `kage render` prepares it for
//!   the per-pixel resolve (the polygonal part with the lobes' shadowed/unshadowed pairs);
//! - `resolve_640x360`: the per-pixel resolve of one frame at 640×360, 1 sample per pixel
//!   (primary rays included).
//!
//! The bakes (BSPVT, PRT) and the prefiltered environment are made once, outside the timing.

use criterion::{Criterion, criterion_group, criterion_main};
use glam::Vec3;
use kage_engine::bspvt;
use kage_engine::prt::{self, Lighting, SilhouetteMemo, prefilter::Prefiltered};
use kage_engine::reference::Renderer;
use kage_engine::scene::{EnvMap, EnvironmentLight, InGroup, PolygonLight, Scene, flatten, import};
use kage_engine::shading::baked::{Bakes, EnvironmentMemo, Look, Polygonal};

const PAPER_SCENE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/scenes/teapot_quad_light.gltf");

fn scene() -> Scene {
    let mut scene = import::import(PAPER_SCENE.as_ref(), Default::default()).expect("the teapot scene in assets/");
    scene.refine_instances("teapot", 17_000).expect("the teapot refines");
    scene.with_environment(EnvironmentLight::new(EnvMap::procedural_sky(256, 128, Vec3::new(-0.5, 0.6, -0.4))))
}

/// Moves the scene's light by `dx` along x (in its group's frame) and propagates.
fn nudge_light(scene: &mut Scene, dx: f32) {
    for (_, member) in scene.world.query_mut::<(&PolygonLight, &mut InGroup)>() {
        member.local.translation.x += dx;
    }
    scene.update_transforms();
}

fn bench(c: &mut Criterion) {
    let mut scene = scene();
    let flat = flatten(&scene);
    let vertices: usize = flat.vertex_ids().count();
    println!("baked look bench: {vertices} vertices");
    let trees = bspvt::bake(&flat, &bspvt::Settings::default(), &|_| {});
    let s = prt::Settings { order: 4, regions: 32, ..prt::Settings::default() };
    let transfer = prt::bake(&scene, &flat, &s, &|_| {});
    let light = Lighting::new(&scene, &s).expect("sky");
    let pre = Prefiltered::new(flat.environment.as_ref().expect("sky"));
    let camera = scene.first_camera().expect("camera");
    let mut memo = SilhouetteMemo::default();
    let mut environment = EnvironmentMemo::default();
    let mut g = c.benchmark_group("baked_teapot_17k");
    g.sample_size(10);
    let parts = prt::Parts { bake: &transfer, lighting: &light, settings: &s };
    // Per-vertex direct values as the editor's `baked` view shades them on the CPU: polygonal
    // lights from the trees with the lobes' pairs its viewport draws them with per pixel, the
    // environment's part through the memo.
    let mut inside = bspvt::pixel::Inside::default();
    let mut shade = |scene: &Scene, eye: Vec3| {
        let flat = flatten(scene);
        let (_lobes, values) = bspvt::pixel::Lobes::at_vertices(&flat, Some(&trees), eye, inside.flags(&flat));
        let polygonal = Polygonal { bake: Some(&trees), values, lobes: None };
        Look::direct_reusing(scene, &flat, eye, Some(polygonal), Some((parts, Some(&pre))), &mut environment, &mut memo)
            .len()
    };
    let mut step = 0.01;
    g.bench_function("relight_vertices", |b| {
        b.iter(|| {
            step = -step;
            nudge_light(&mut scene, step);
            shade(&scene, camera.eye())
        })
    });
    g.bench_function("camera_moved", |b| {
        b.iter(|| {
            step = -step;
            shade(&scene, camera.eye() + Vec3::new(step, 0.0, 0.0))
        })
    });
    let mut memo = SilhouetteMemo::default();
    // The two parts alone (after the light move above).
    let flat = flatten(&scene);
    g.bench_function("polygonal_part", |b| {
        b.iter(|| {
            let bakes = Bakes { bspvt: Some(&trees), prt: None, prefiltered: None };
            Look::prepare(&scene, &flat, bakes, camera.eye(), &mut memo).vertex_values().len()
        })
    });
    g.bench_function("environment_part", |b| {
        b.iter(|| {
            let bakes = Bakes {
                bspvt: None,
                prt: Some(prt::Parts { bake: &transfer, lighting: &light, settings: &s }),
                prefiltered: Some(&pre),
            };
            Look::prepare(&scene, &flat, bakes, camera.eye(), &mut memo).vertex_values().len()
        })
    });
    let renderer = Renderer::new(&scene);
    let bakes = Bakes {
        bspvt: Some(&trees),
        prt: Some(prt::Parts { bake: &transfer, lighting: &light, settings: &s }),
        prefiltered: Some(&pre),
    };
    let look = Look::prepare(&scene, &renderer.flat, bakes, camera.eye(), &mut memo);
    g.bench_function("resolve_640x360", |b| b.iter(|| look.render(&renderer, &camera, 640, 360, 1).len()));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
