//! BSPVT throughput (64² faces, default ε): baking vertices/s and shading vertex–light
//! evaluations/s, on all cores with rayon, on two configurations:
//! - the built-in default scene, every 9th receiver vertex (so that setup stays short);
//! - the paper's named configuration: `teapot_quad_light.gltf` with its teapot refined to 17 000
//!   vertices (`--refine teapot=17000`), every receiver vertex shaded (the bake is sampled);
//! - the built-in scene under a pergola (three slats between the light and the ground), every
//!   9th receiver vertex: its shadows need ~120 leaves per vertex, above the paper's ~106, which
//!   no scene above reaches even at ε = 0 (their exact trees are smaller).
//!
//! Leaves and bytes per vertex, and LTC pieces per evaluation, are printed beside the numbers.
//! A third function per configuration times the split search alone: building again, from
//! scratch, every distinct mixed tile that configuration's bake met (Algorithm 1 per tile);
//! leaves per tile are printed beside it.

use criterion::measurement::WallTime;
use criterion::{BenchmarkGroup, Criterion, Throughput, criterion_group, criterion_main};
use glam::{Affine3A, Vec3};
use kage_engine::bspvt::memo::SubtreeMemo;
use kage_engine::bspvt::node::Node;
use kage_engine::bspvt::shade::{PointShader, Visibility};
use kage_engine::bspvt::tree::build_tile;
use kage_engine::bspvt::{Settings, bake_vertex, layout, occluder_bvh, reach::Reach};
use kage_engine::math::ltc;
use kage_engine::scene::{Material, Scene, default_scene, flatten, import, shapes};
use rayon::prelude::*;

const PAPER_SCENE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/scenes/teapot_quad_light.gltf");

fn paper_scene() -> Scene {
    let mut scene = import::import(PAPER_SCENE.as_ref(), Default::default()).expect("the teapot scene in assets/");
    scene.refine_instances("teapot", 17_000).expect("the teapot refines");
    scene.clear_environment();
    scene
}

/// The built-in scene with three 5 m slats 0.1 m wide, 1.2 m apart, across the light's beam.
fn pergola_scene() -> Scene {
    let mut scene = default_scene();
    let wood = Material::lambertian(Vec3::splat(0.6));
    for k in -1..=1 {
        let pose = Affine3A::from_translation(Vec3::new(0.0, 2.6, 1.2 * k as f32));
        scene.add_object(&format!("slat{k}"), shapes::cuboid(Vec3::new(2.5, 0.03, 0.05)), wood, pose);
    }
    scene
}

fn measure(c: &mut Criterion, name: &str, scene: &Scene, step: usize) {
    let flat = flatten(scene);
    let occ = occluder_bvh(&flat);
    let s = Settings::default();
    let eye = scene.first_camera().unwrap().eye();
    let verts: Vec<(usize, usize)> = flat.vertex_ids().step_by(step).collect();
    let mut g = c.benchmark_group(name);
    g.sample_size(10);
    // 64 vertices spread over the receivers.
    let bake_sample: Vec<(usize, usize)> = verts.iter().step_by(verts.len() / 64).take(64).copied().collect();
    g.throughput(Throughput::Elements(bake_sample.len() as u64));
    let reach = Reach::of_scene(&flat);
    g.bench_function("bake_vertices", |b| {
        // A fresh subtree memo per pass: 64 scattered vertices share few tiles, so this is about
        // the uncached rate (whole bakes, which share many, are measured with `kage bake`).
        b.iter(|| {
            let tiles = SubtreeMemo::new(&s);
            bake_sample
                .par_iter()
                .map(|&(i, v)| {
                    let (p, n) = flat.vertex(i, v);
                    bake_vertex(&occ, p, n, &tiles, &reach).record.len()
                })
                .sum::<usize>()
        })
    });
    let tiles = SubtreeMemo::new(&s);
    let start = std::time::Instant::now();
    let records: Vec<Vec<u8>> = verts
        .par_iter()
        .map(|&(i, v)| {
            let (p, n) = flat.vertex(i, v);
            bake_vertex(&occ, p, n, &tiles, &reach).record
        })
        .collect();
    let seconds = start.elapsed().as_secs_f64();
    bench_tile_builds(&mut g, &tiles);
    let leaves: usize = records.iter().map(|r| layout::tree_counts(r).0).sum();
    let table = ltc::table();
    let shade = |v: usize, rec: &[u8]| {
        let (i, v) = verts[v];
        let (p, n) = flat.vertex(i, v);
        PointShader::new(&table, p, n, eye, &flat.instances[i].material)
            .shade_counted(&flat.lights, Visibility::Tree(rec, tiles.settings().res))
    };
    // LTC pieces per vertex: the edge-gathering hint can only save work where a light is cut
    // into several pieces (their shared edges).
    let pieces: Vec<usize> = records.par_iter().enumerate().map(|(v, rec)| shade(v, rec).1).collect();
    let evaluations = verts.len() * flat.lights.len();
    eprintln!(
        "{name}: {} vertices baked once with one subtree memo at {:.0} vertices/s, {:.1} leaves and {:.0} bytes per vertex, {:.2} LTC pieces per evaluation, \
         {:.1} % of vertices with more pieces than lights",
        records.len(),
        records.len() as f64 / seconds,
        leaves as f64 / records.len() as f64,
        records.iter().map(Vec::len).sum::<usize>() as f64 / records.len() as f64,
        pieces.iter().sum::<usize>() as f64 / evaluations as f64,
        100.0 * pieces.iter().filter(|&&k| k > flat.lights.len()).count() as f64 / records.len() as f64,
    );
    g.throughput(Throughput::Elements(evaluations as u64));
    g.sample_size(20);
    g.bench_function("shade_vertex_lights", |b| {
        b.iter(|| records.par_iter().enumerate().map(|(v, rec)| shade(v, rec).0.x).sum::<f32>())
    });
    g.finish();
}

/// Times building every tile `tiles` holds again (in parallel, as a bake would).
fn bench_tile_builds(g: &mut BenchmarkGroup<WallTime>, tiles: &SubtreeMemo) {
    let keys = tiles.keys();
    let leaves = |nodes: &Vec<Node>| nodes.iter().filter(|n| matches!(n, Node::Leaf(_))).count();
    let total: usize = keys.par_iter().map(|&k| leaves(&build_tile(k, tiles))).sum();
    eprintln!("{} distinct mixed tiles, {:.3} leaves per tile", keys.len(), total as f64 / keys.len() as f64);
    g.throughput(Throughput::Elements(keys.len() as u64));
    g.bench_function("build_tiles", |b| b.iter(|| keys.par_iter().map(|&k| build_tile(k, tiles).len()).sum::<usize>()));
}

fn bench(c: &mut Criterion) {
    measure(c, "bspvt_default_scene", &default_scene(), 9);
    measure(c, "bspvt_paper_teapot", &paper_scene(), 1);
    measure(c, "bspvt_pergola", &pergola_scene(), 9);
}

criterion_group!(benches, bench);
criterion_main!(benches);
