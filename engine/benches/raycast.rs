//! Ray casting throughput on a ≥100K-triangle scene: coherent (all rays from one point) and
//! incoherent (random origins and directions) any-hit rays, and incoherent closest-hit rays,
//! on all cores with rayon, and the BVH build time. Goal: ≥ 8 M any-hit rays/s on 2 cores.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::{Affine3A, Vec2, Vec3};
use kage_engine::accel::SceneBvh;
use kage_engine::math::{rng, sampling};
use kage_engine::scene::{Material, Scene, flatten, shapes};
use rand::Rng;
use rayon::prelude::*;

const RAYS: usize = 1 << 16;

/// A ground plane with a grid of tori and spheres: 100K+ triangles.
fn big_scene() -> Vec<[Vec3; 3]> {
    let mut s = Scene::new("bench");
    let m = Material::lambertian(Vec3::splat(0.5));
    s.add_object("ground", shapes::grid(20.0, 100), m, Affine3A::IDENTITY);
    for i in 0..4 {
        for j in 0..4 {
            let p = Vec3::new(i as f32 * 4.0 - 6.0, 1.0, j as f32 * 4.0 - 6.0);
            let shape = if (i + j) % 2 == 0 { shapes::torus(1.2, 0.4, 96, 48) } else { shapes::sphere(1.0, 96, 48) };
            s.add_object("o", shape, m, Affine3A::from_translation(p));
        }
    }
    flatten(&s).triangles
}

fn rays(coherent: bool) -> Vec<(Vec3, Vec3, f32)> {
    let mut r = rng::seeded(5);
    (0..RAYS)
        .map(|_| {
            let d = sampling::uniform_sphere(Vec2::new(r.random(), r.random()));
            let o = if coherent {
                Vec3::new(0.5, 0.3, 0.5)
            } else {
                Vec3::new(r.random::<f32>() * 20.0 - 10.0, r.random::<f32>() * 3.0, r.random::<f32>() * 20.0 - 10.0)
            };
            (o, d, 30.0)
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let tris = big_scene();
    assert!(tris.len() >= 100_000, "{} triangles", tris.len());
    let bvh = SceneBvh::new(&tris);
    let mut g = c.benchmark_group(format!("raycast_{}k_tris", tris.len() / 1000));
    g.throughput(Throughput::Elements(RAYS as u64));
    for (name, coherent) in [("anyhit_coherent", true), ("anyhit_incoherent", false)] {
        let rs = rays(coherent);
        g.bench_function(name, |b| b.iter(|| rs.par_iter().filter(|(o, d, t)| bvh.occluded(*o, *d, *t)).count()));
    }
    let rs = rays(false);
    g.bench_function("closest_incoherent", |b| {
        b.iter(|| rs.par_iter().filter_map(|(o, d, t)| bvh.closest_hit(*o, *d, *t)).count())
    });
    g.finish();
    let mut b = c.benchmark_group(format!("bvh_build_{}k_tris", tris.len() / 1000));
    b.sample_size(10);
    b.bench_function("build", |bench| bench.iter(|| SceneBvh::new(&tris).len()));
    b.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
