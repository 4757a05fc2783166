//! The editor on the teapot scene (`assets/scenes/teapot_quad_light.gltf`, 64² faces,
//! ε 2), headless through egui_kittest on the wgpu device wgpu picks (lavapipe without a GPU):
//! - `frame_ui`: one editor frame with nothing to re-shade (systems, UI, viewport draw);
//! - `frame_rendered`: the same plus egui's render of the window and its read-back;
//! - `shade_bspvt` / `shade_prt`: one re-shade of every vertex on the GPU (view changed);
//! - `light_drag_to_frame`: a light moved by a drag step until the frame shows it;
//! - `shader_save_to_pipeline`: `bspvt.wgsl` re-written on disk until its pipeline is rebuilt
//!   (includes the watcher's 150 ms debounce).
//!
//! The first run bakes into `target/bench-editor/bake.redb`; later runs find it cached.
//!
//! And on the built-in scene as `kage edit` opens it (receivers refined, the bounce on, the
//! lights shaded where `--shade-on auto` puts them: per vertex on the CPU on lavapipe;
//! `KAGE_SHADE_ON=gpu` for the per-pixel path):
//! - `group_drag_to_shadows`: the box moved to a placement it has never had, from the end of
//!   the drag (refinement, the incremental bake, the bounce) until a frame shows the shadows of
//!   the new placement. Its database starts empty each run, so no placement is cached.

#[path = "../tests/common/mod.rs"]
mod common;

use common::harness;
use criterion::{Criterion, criterion_group, criterion_main};
use egui_kittest::Harness;
use glam::{Quat, Vec3};
use kage_editor::state::{Options, Selection, ShadeOn};
use kage_editor::ui::App;
use kage_engine::scene::{EnvMap, EnvironmentLight, import};
use kage_engine::shading::Method;
use kage_engine::{bspvt, prt};
use std::path::PathBuf;
use std::time::Duration;

/// Where polygonal lights shade: `KAGE_SHADE_ON` (`cpu`, `gpu` or `auto`), else `default`.
fn shade_on(default: ShadeOn) -> ShadeOn {
    match std::env::var("KAGE_SHADE_ON").as_deref() {
        Ok("cpu") => ShadeOn::Cpu,
        Ok("gpu") => ShadeOn::Gpu,
        Ok("auto") => ShadeOn::Auto,
        _ => default,
    }
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn teapot_editor() -> Harness<'static, App> {
    let assets = root().join("assets");
    let mut scene = import::import(&assets.join("scenes/teapot_quad_light.gltf"), Default::default()).unwrap();
    scene.set_environment(EnvironmentLight::new(EnvMap::load(&assets.join("envmaps/studio.hdr")).unwrap()));
    let work = root().join("target/bench-editor");
    let shaders = work.join("shaders");
    std::fs::create_dir_all(&shaders).unwrap();
    for f in std::fs::read_dir(root().join("shaders")).unwrap().map(|e| e.unwrap().path()) {
        std::fs::copy(&f, shaders.join(f.file_name().unwrap())).unwrap();
    }
    let options = Options {
        scene_path: None,
        env_path: None,
        import: Default::default(),
        shader_dir: Some(shaders),
        db_path: work.join("bake.redb"),
        bspvt: bspvt::Settings::default(),
        prt: prt::Settings::default(),
        cache: Default::default(),
        prt_budget: None,
        // The benchmark's teapot keeps its vertex count, so frames compare across commits.
        refine: None,
        bake_on_start: true,
        indirect: false,
        // The GPU path by default, so lavapipe's numbers compare across commits.
        shade_on: shade_on(ShadeOn::Gpu),
        background_shading: usize::MAX,
        preview_spacing: kage_editor::state::PREVIEW_SPACING,
    };
    let mut h = harness(scene, options);
    while h.state().editor.backend.job.is_some() || h.state().editor.bakes.bspvt.is_none() {
        h.step();
        std::thread::sleep(Duration::from_millis(50));
    }
    h.step();
    h
}

/// The editor on the built-in scene with `kage edit`'s defaults, its first bake done.
fn builtin_editor() -> Harness<'static, App> {
    let work = root().join("target/bench-editor");
    std::fs::create_dir_all(&work).unwrap();
    let db = work.join("builtin.redb");
    let _ = std::fs::remove_file(&db);
    let options = Options {
        scene_path: None,
        env_path: None,
        import: Default::default(),
        shader_dir: None,
        db_path: db,
        bspvt: bspvt::Settings::default(),
        prt: prt::Settings::default(),
        cache: Default::default(),
        prt_budget: None,
        refine: Some(kage_engine::receivers::Settings::default()),
        bake_on_start: true,
        indirect: true,
        // As `kage edit` does: on a CPU device (lavapipe) the lights shade per vertex on the CPU.
        shade_on: shade_on(ShadeOn::Auto),
        background_shading: usize::MAX,
        preview_spacing: kage_editor::state::PREVIEW_SPACING,
    };
    let mut h = harness(kage_engine::scene::default_scene(), options);
    settle(&mut h);
    h
}

/// Steps the editor until its bake job has landed and been taken in, then renders a frame.
fn settle(h: &mut Harness<App>) {
    h.step();
    while h.state().editor.backend.job.is_some() {
        h.step();
        std::thread::sleep(Duration::from_millis(10));
    }
    h.step();
    h.render().unwrap();
}

fn group_drag(c: &mut Criterion) {
    let mut h = builtin_editor();
    let group = h.state().editor.outline().into_iter().find_map(|(s, name, _)| match s {
        Selection::Group(g) if name.ends_with(": box") => Some(g),
        _ => None,
    });
    let group = group.expect("the built-in scene has a box");
    let mut g = c.benchmark_group(format!("editor_builtin_{:?}", h.state().editor.options.shade_on));
    g.sample_size(10);
    let mut k = 0.0;
    g.bench_function("group_drag_to_shadows", |b| {
        b.iter_custom(|iterations| {
            let mut took = Duration::ZERO;
            for _ in 0..iterations {
                // Out and back by steps never taken before: every placement is new.
                k += 1.0;
                let offset = Vec3::new(if k % 2.0 == 1.0 { 0.3 } else { -0.3 } + 0.002 * k, 0.0, 0.0);
                h.state_mut().editor.move_group(group, offset, Quat::IDENTITY);
                let start = std::time::Instant::now();
                settle(&mut h);
                took += start.elapsed();
            }
            took
        })
    });
    g.finish();
    let ed = &h.state().editor;
    let refined = ed.bakes.receivers.as_ref().map_or(0.0, |r| r.seconds);
    let errors: Vec<&str> = ed.log.iter().filter(|l| l.error).map(|l| l.text.as_str()).collect();
    assert!(errors.is_empty(), "the editor must measure a working state: {errors:#?}");
    let bspvt = ed.stats.runs[0].map_or(String::new(), |r| {
        format!("; BSPVT {} cold, {} warm, {} cached chunks in {:.2} s", r.cold, r.warm, r.cached, r.seconds)
    });
    let prt = ed.stats.runs[1]
        .map_or(String::new(), |r| format!("; PRT {} cold, {} cached chunks in {:.2} s", r.cold, r.cached, r.seconds));
    println!("last drag: receivers refined in {refined:.2} s{bspvt}{prt}");
}

fn vertices(h: &Harness<App>) -> usize {
    h.state().editor.results.values.iter().map(Vec::len).sum()
}

fn bench(c: &mut Criterion) {
    let mut h = teapot_editor();
    let errors: Vec<&str> = h.state().editor.log.iter().filter(|l| l.error).map(|l| l.text.as_str()).collect();
    assert!(errors.is_empty(), "the editor must measure a working state: {errors:#?}");
    let mut g = c.benchmark_group(format!("editor_teapot_{}v_{:?}", vertices(&h), h.state().editor.options.shade_on));
    g.sample_size(10);
    g.bench_function("frame_ui", |b| b.iter(|| h.step()));
    g.bench_function("frame_rendered", |b| {
        b.iter(|| {
            h.step();
            h.render().unwrap()
        })
    });
    for (name, method) in [("shade_bspvt", Method::Bspvt), ("shade_prt", Method::Prt)] {
        h.state_mut().editor.set_method(method);
        h.step();
        g.bench_function(name, |b| {
            b.iter(|| {
                let ed = &mut h.state_mut().editor;
                ed.dirty.shade = true;
                kage_editor::systems::shade_system(ed);
            })
        });
    }
    h.state_mut().editor.set_method(Method::Bspvt);
    let light = h.state().editor.outline().into_iter().find_map(|(s, ..)| match s {
        Selection::Light(e) => Some(e),
        _ => None,
    });
    let light = light.expect("the teapot scene has a light");
    let mut sign = 1.0;
    g.bench_function("light_drag_to_frame", |b| {
        b.iter(|| {
            sign = -sign;
            h.state_mut().editor.move_light(light, Vec3::new(0.05 * sign, 0.0, 0.0), Quat::IDENTITY);
            h.step();
            h.render().unwrap()
        })
    });
    let path = root().join("target/bench-editor/shaders/bspvt.wgsl");
    let source = std::fs::read_to_string(&path).unwrap();
    let mut k = 0u32;
    g.bench_function("shader_save_to_pipeline", |b| {
        b.iter(|| {
            k += 1;
            let generation = h.state().editor.shader_generation;
            std::fs::write(&path, format!("{source}\n// save {k}\n")).unwrap();
            while h.state().editor.shader_generation == generation {
                h.step();
                std::thread::sleep(Duration::from_millis(2));
            }
        })
    });
    g.finish();
    let s = h.state().editor.stats;
    println!(
        "editor stats: edit to shaded frame {:.1} ms, shader validate + rebuild {:.1} ms",
        1e3 * s.edit_to_shade,
        1e3 * s.shader_reload
    );
}

criterion_group!(benches, bench, group_drag);
criterion_main!(benches);
