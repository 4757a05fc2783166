//! Artefact load: a fully cached [`run`] reads every chunk of the plan from the database,
//! checks every BSPVT tree and assembles the engine's bakes — what `kage render` pays before
//! shading. Each iteration opens the database afresh (untimed), so redb's page cache starts
//! cold as in a new process (the OS file cache is warm). Throughput is in artefact bytes, on
//! two databases baked once in setup:
//! - the built-in default scene (BSPVT and PRT, 40 chunks);
//! - the paper's named configuration, `teapot_quad_light.gltf` with its teapot refined to
//!   17 000 vertices (BSPVT, 78 chunks).

use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};
use kage_bake_db::{Store, plan, run};
use kage_engine::scene::{Scene, default_scene, flatten, import};
use kage_engine::{bspvt, prt};

const PAPER_SCENE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/scenes/teapot_quad_light.gltf");

fn paper_scene() -> Scene {
    let mut scene = import::import(PAPER_SCENE.as_ref(), Default::default()).expect("the teapot scene in assets/");
    scene.refine_instances("teapot", 17_000).expect("the teapot refines");
    scene
}

fn measure(c: &mut Criterion, name: &str, scene: &Scene) {
    let path = std::env::temp_dir().join(format!("kage-load-bench-{}-{name}.redb", std::process::id()));
    let _ = std::fs::remove_file(&path);
    let store = Store::open(&path).expect("a scratch database");
    let flat = flatten(scene);
    let planned = || plan(&store, scene, &flat, Some(bspvt::Settings::default()), Some(prt::Settings::default()));
    run(&store, scene, &flat, &planned().expect("a plan"), &|_| {}).expect("the setup bake");
    let plan = planned().expect("a plan");
    assert_eq!(plan.misses().count(), 0, "everything is cached");
    let bytes: u64 = store.counts().expect("counts").1;
    drop(store);
    eprintln!("{name}: {} chunks, {:.2} MB", plan.jobs.len(), bytes as f64 / 1e6);
    let mut g = c.benchmark_group(name);
    g.sample_size(20);
    g.throughput(Throughput::Bytes(bytes));
    g.bench_function("load_artefacts", |b| {
        b.iter_batched(
            || Store::open(&path).expect("the database"),
            |store| (run(&store, scene, &flat, &plan, &|_| {}).expect("a load"), store),
            BatchSize::PerIteration,
        )
    });
    g.finish();
    let _ = std::fs::remove_file(&path);
}

fn bench(c: &mut Criterion) {
    measure(c, "load_default_scene", &default_scene());
    measure(c, "load_paper_teapot", &paper_scene());
}

criterion_group!(benches, bench);
criterion_main!(benches);
