//! Radiance-cache work when a light moves, on the built-in default scene lit by its quad light
//! (256 rays per record, default settings; direct light per vertex from the reference at 16
//! samples): placing the records cold against refreshing them (`Cache::refresh`: only records
//! whose rays see changed light are integrated again, only rays crossing the light's old or new
//! bounds are cast again). The light moves 0.5 m back and forth between the two states. Then
//! the bounce at every vertex from the records (`cache::shade_vertices`).

use criterion::{Criterion, criterion_group, criterion_main};
use glam::{Quat, Vec3};
use kage_engine::cache::record::{Change, GLOSSY_SPP, Glossy, Source};
use kage_engine::cache::{self, Settings};
use kage_engine::reference::{Renderer, Settings as RefSettings};
use kage_engine::scene::default_scene;

/// The default scene without its sky, the light moved by `offset`: renderer and direct light.
fn lit(offset: Vec3) -> (Renderer, Vec<Vec<Vec3>>) {
    let mut scene = default_scene();
    scene.clear_environment();
    let light = scene.find_group("light").expect("the default scene's light");
    scene.pose_group(light, Quat::IDENTITY, offset);
    let r = Renderer::new(&scene);
    let eye = scene.first_camera().expect("camera").eye();
    let est = r.render_vertices(eye, &RefSettings { spp: 16, seed: 9, ..Default::default() }, &|_| {});
    let direct = est.iter().map(|v| v.iter().map(|e| e.mean).collect()).collect();
    (r, direct)
}

fn bench(c: &mut Criterion) {
    let s = Settings::default();
    let states = [lit(Vec3::ZERO), lit(Vec3::new(0.5, 0.0, 0.0))];
    let source =
        |k: usize| Source { renderer: &states[k].0, direct: &states[k].1, glossy: Glossy::Reference(GLOSSY_SPP) };
    let moved = cache::moved_lights(&states[0].0.flat.lights, &states[1].0.flat.lights);
    let mut g = c.benchmark_group("cache_default_scene_light_move");
    g.sample_size(10);
    g.bench_function("place_cold", |b| b.iter(|| cache::place_at_vertices(&source(1), &s).records.len()));
    let mut cache = cache::place_at_vertices(&source(0), &s);
    let mut at = 0;
    let mut step = |cache: &mut cache::Cache| {
        let change = Change { old_direct: Some(&states[at].1), moved: &moved };
        at = 1 - at;
        cache.refresh(&source(at), &change)
    };
    let first = step(&mut cache);
    eprintln!(
        "{} records, {} rays; a light move re-lit {} records and re-cast {} rays",
        cache.records.len(),
        cache.rays(),
        first.relit,
        first.recast
    );
    g.bench_function("refresh_after_light_move", |b| b.iter(|| step(&mut cache).relit));
    let eye = default_scene().first_camera().expect("camera").eye();
    g.bench_function("shade_vertices", |b| b.iter(|| cache::shade_vertices(&source(at), &cache, eye).len()));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
