//! BSPVT throughput on the built-in default scene (64² faces, default ε): baking vertices/s
//! and shading vertex–light evaluations/s, on all cores with rayon. Every 9th receiver vertex
//! is used so that setup stays short.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use kage_engine::bspvt::shade::{PointShader, Visibility};
use kage_engine::bspvt::{Settings, bake_vertex, occluder_bvh};
use kage_engine::math::ltc;
use kage_engine::scene::{default_scene, flatten};
use rayon::prelude::*;

fn bench(c: &mut Criterion) {
    let scene = default_scene();
    let flat = flatten(&scene);
    let occ = occluder_bvh(&flat);
    let s = Settings::default();
    let eye = scene.first_camera().unwrap().eye();
    let verts: Vec<(usize, usize)> = (0..flat.instances.len())
        .flat_map(|i| (0..scene.meshes[flat.instances[i].mesh as usize].positions.len()).map(move |v| (i, v)))
        .step_by(9)
        .collect();
    let mut g = c.benchmark_group("bspvt_default_scene");
    g.sample_size(10);
    let bake_sample = &verts[..64];
    g.throughput(Throughput::Elements(bake_sample.len() as u64));
    g.bench_function("bake_vertices", |b| {
        b.iter(|| {
            bake_sample
                .par_iter()
                .map(|&(i, v)| {
                    let (p, n) = flat.vertex(&scene.meshes, i, v);
                    bake_vertex(&occ, p, n, &s).0.len()
                })
                .sum::<usize>()
        })
    });
    let baked: Vec<(Vec<u8>, usize, usize)> = verts
        .par_iter()
        .map(|&(i, v)| {
            let (p, n) = flat.vertex(&scene.meshes, i, v);
            bake_vertex(&occ, p, n, &s)
        })
        .collect();
    let leaves: usize = baked.iter().map(|b| b.1).sum();
    let records: Vec<Vec<u8>> = baked.into_iter().map(|b| b.0).collect();
    eprintln!(
        "{} vertices, {:.1} leaves and {:.0} bytes per vertex",
        records.len(),
        leaves as f64 / records.len() as f64,
        records.iter().map(Vec::len).sum::<usize>() as f64 / records.len() as f64
    );
    let table = ltc::table();
    g.throughput(Throughput::Elements((verts.len() * flat.lights.len()) as u64));
    g.sample_size(20);
    g.bench_function("shade_vertex_lights", |b| {
        b.iter(|| {
            verts
                .par_iter()
                .zip(&records)
                .map(|(&(i, v), rec)| {
                    let (p, n) = flat.vertex(&scene.meshes, i, v);
                    PointShader::new(&table, p, n, eye, &flat.instances[i].material)
                        .shade(&flat.lights, Visibility::Tree(rec))
                        .x
                })
                .sum::<f32>()
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
