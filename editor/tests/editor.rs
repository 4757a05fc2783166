//! The editor, headless: egui_kittest drives the real app (UI, systems, background bakes) with
//! kittest's wgpu renderer — lavapipe in CI, no skipping. Rendered frames are written to
//! `target/editor-snapshots/` for inspection and compared with each other.

mod common;

use common::harness;
use eframe::egui;
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use glam::{Quat, Vec3};
use kage_editor::state::{Editor, Options, Selection, ShadeOn};
use kage_editor::ui::App;
use kage_engine::scene::{default_scene, import};
use kage_engine::shading::Method;
use kage_engine::{bspvt, prt};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// A fresh folder for test `name` under Cargo's `target/tmp` (the next run replaces it).
fn scratch(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("kage-editor").join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn asset(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../assets").join(rel)
}

/// What `kage edit` runs by default: the CPU on lavapipe, the GPU on real hardware. Tests of the
/// GPU path itself (the lights drawn per pixel, WGSL pipelines) ask for it with [`on_gpu`]:
/// on lavapipe each of its redraws costs seconds, which every edit in every test would pay.
const SHADE_ON: ShadeOn = ShadeOn::Auto;

/// `o` on the GPU path, lavapipe in CI.
fn on_gpu(o: Options) -> Options {
    Options { shade_on: ShadeOn::Gpu, ..o }
}

fn options(dir: &Path, scene_path: Option<PathBuf>, shader_dir: Option<PathBuf>) -> Options {
    Options {
        scene_path,
        env_path: None,
        import: Default::default(),
        shader_dir,
        db_path: dir.join("bake.redb"),
        bspvt: bspvt::Settings { res: 16, epsilon: 2.0 },
        prt: prt::Settings { order: 4, directions: 256, regions: 16, ..prt::Settings::default() },
        cache: Default::default(),
        prt_budget: None,
        refine: None,
        bake_on_start: true,
        // Tests that need the bounce turn it on as a user would (the toggle).
        indirect: false,
        shade_on: SHADE_ON,
        background_shading: usize::MAX,
        preview_spacing: kage_editor::state::PREVIEW_SPACING,
    }
}

/// Steps until `done` holds (at most 900 s: bakes run in the background). The bound only
/// keeps a stuck test from hanging: this file's tests share the cores, and on a slow 2-core
/// machine the default scene's reference passes took over 300 s with the others running
/// (52 s alone).
fn step_until(h: &mut Harness<App>, what: &str, done: impl Fn(&Editor) -> bool) {
    let start = Instant::now();
    while !done(&h.state().editor) {
        assert!(
            start.elapsed() < Duration::from_secs(900),
            "timed out waiting for {what}; log: {:#?}",
            h.state().editor.log
        );
        h.step();
        std::thread::sleep(Duration::from_millis(20));
    }
    h.step();
}

fn settled(ed: &Editor) -> bool {
    ed.backend.job.is_none() && shaded(ed) && !ed.dirty.geometry && ed.bakes.bspvt.is_some()
}

/// Nothing left to shade, within the frame or in the background.
fn shaded(ed: &Editor) -> bool {
    !ed.dirty.shade && !kage_editor::systems::shading(ed)
}

/// Renders the window and keeps a copy; returns the pixels.
fn snapshot(h: &mut Harness<App>, name: &str) -> image::RgbaImage {
    let img = h.render().expect("the wgpu renderer draws");
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/editor-snapshots");
    std::fs::create_dir_all(&dir).unwrap();
    img.save(dir.join(format!("{name}.png"))).unwrap();
    img
}

/// Distinct colours in the viewport's middle region (blank or failed views have few).
fn viewport_colours(img: &image::RgbaImage) -> usize {
    let (w, h) = img.dimensions();
    let mut seen = std::collections::HashSet::new();
    for y in (h / 4..3 * h / 4).step_by(3) {
        for x in (w / 4..3 * w / 4).step_by(3) {
            seen.insert(img.get_pixel(x, y).0);
        }
    }
    seen.len()
}

fn values(h: &Harness<App>) -> Vec<Vec3> {
    h.state().editor.results.values.iter().flatten().copied().collect()
}

fn changed(a: &[Vec3], b: &[Vec3]) -> usize {
    a.iter().zip(b).filter(|(x, y)| (**x - **y).abs().max_element() > 1e-4).count()
}

/// The exposure `kage render --exposure auto` meters for a 192-pixel-wide image of the
/// editor's per-vertex radiance through its view (log-average of every pixel, at most 5 % of
/// the surface pixels clipping).
fn view_exposure(ed: &Editor) -> f32 {
    use kage_engine::raster::{Primary, primary_grid};
    let (w, h) = (192, (192.0 / ed.view.aspect).round() as usize);
    let camera = kage_engine::scene::Camera::look_at(ed.view.orbit.eye(), ed.view.orbit.target, ed.view.orbit.yfov);
    let renderer = kage_engine::reference::Renderer::new(&ed.doc.scene);
    let (grid, _) = primary_grid(&renderer, &camera, w, h, 1);
    let (mut all, mut surfaces) = (Vec::new(), Vec::new());
    for p in &grid {
        match p {
            Primary::Miss(l) | Primary::Emitter(l) => all.push(*l),
            Primary::Surface(hit) => {
                let l = hit.interpolate(&ed.results.radiance[hit.instance]);
                all.push(l);
                surfaces.push(l);
            }
        }
    }
    kage_engine::math::color::metered_exposure_keeping(&all, &surfaces)
}

fn errors(ed: &Editor) -> Vec<String> {
    ed.log.iter().filter(|l| l.error).map(|l| l.text.clone()).collect()
}

#[test]
fn the_default_scene_bakes_in_the_background_and_every_method_shades() {
    let dir = scratch("default");
    let mut h = harness(default_scene(), on_gpu(options(&dir, None, None)));
    step_until(&mut h, "the first bakes", settled);
    let ed = &h.state().editor;
    assert!(ed.bakes.prt.is_some() && ed.bakes.lighting.is_some(), "{:?}", ed.log);
    assert!(errors(ed).is_empty(), "{:?}", errors(ed));
    // The editor opens on the complete baked look.
    assert_eq!(ed.view.method, Method::Baked);
    let lit = ed.results.pixel_lights.as_ref().expect("the baked view draws the polygonal lights per pixel");
    assert_eq!(lit.values.len(), ed.flat.instances.len());
    assert!(lit.environment.is_some(), "and the environment's reflection");
    let baked = values(&h);
    assert!(baked.iter().any(|v| v.max_element() > 0.01) && baked.iter().all(|v| v.is_finite()));
    // The exposure was metered from the first lit result, as `kage render` meters its PNGs.
    assert!(
        !ed.view.metering && ed.view.exposure != 0.0 && ed.view.exposure.abs() < 6.0,
        "exposure {}",
        ed.view.exposure
    );
    let img = snapshot(&mut h, "default-baked");
    assert!(viewport_colours(&img) > 200, "the viewport shows the scene ({} colours)", viewport_colours(&img));
    let mut seen = vec![baked];
    for (label, method) in [
        ("bspvt", Method::Bspvt),
        ("prt", Method::Prt),
        ("prt-self", Method::PrtSelf),
        ("ltc-unshadowed", Method::LtcUnshadowed),
    ] {
        h.get_by_label(label).click();
        step_until(&mut h, label, |ed| ed.view.method == method && !ed.dirty.shade);
        let v = values(&h);
        assert!(v.iter().all(|x| x.is_finite() && x.min_element() >= 0.0), "{label}");
        // The methods that shade the polygonal lights with LTC draw them per pixel.
        let per_pixel = matches!(method, Method::Bspvt | Method::LtcUnshadowed);
        assert_eq!(h.state().editor.results.pixel_lights.is_some(), per_pixel, "{label}");
        // The gold torus is a metal: diffuse transfer shows it black, and the log says why.
        let noted =
            |ed: &Editor| ed.log.iter().any(|l| l.text.starts_with(&format!("{label}: 1 of 4 instances are metals")));
        assert_eq!(noted(&h.state().editor), matches!(method, Method::Prt | Method::PrtSelf), "{label}");
        assert!(seen.iter().all(|s| changed(s, &v) > 100), "{label} shades differently from the others");
        snapshot(&mut h, &format!("default-{label}"));
        seen.push(v);
    }
    // "meter" meters the current method's result as `kage render` meters its image: the
    // view's pixels (here a CPU image of the vertex radiance through the same camera), not the
    // vertices.
    h.state_mut().editor.view.exposure = 5.0;
    h.get_by_label("meter").click();
    h.step();
    let ed = &h.state().editor;
    let expected = view_exposure(ed);
    assert!((ed.view.exposure - expected).abs() < 0.1, "metered {}, the view's image {expected}", ed.view.exposure);
    let by_vertex = kage_engine::math::color::metered_exposure(ed.results.radiance.iter().flatten().copied());
    eprintln!("metered {:.2} stops; the view's image {expected:.2}; the vertices {by_vertex:.2}", ed.view.exposure);
    // The error overlay refines against the progressive reference.
    h.get_by_label("bspvt").click();
    h.get_by_label("Error overlay (vs progressive reference)").click();
    step_until(&mut h, "reference passes", |ed| ed.view.overlay && ed.results.reference.passes >= 2 && !ed.dirty.shade);
    let img = snapshot(&mut h, "default-overlay");
    assert!(viewport_colours(&img) > 20);
    let ed = &h.state().editor;
    assert!(ed.results.pixel_lights.is_none(), "the overlay's colours are per vertex");
    assert!(errors(ed).is_empty(), "{:?}", errors(ed));
}

#[test]
fn light_moves_reshade_at_once_and_group_moves_rebake_bspvt_incrementally() {
    let dir = scratch("moves");
    let mut h = harness(default_scene(), on_gpu(options(&dir, None, None)));
    step_until(&mut h, "the first bakes", settled);
    let first = h.state().editor.stats.runs[0].unwrap();
    let before = values(&h);
    let light = h.state().editor.outline().into_iter().find_map(|(s, ..)| match s {
        Selection::Light(e) => Some(e),
        _ => None,
    });
    h.state_mut().editor.move_light(
        light.expect("the default scene has a light"),
        Vec3::new(0.6, 0.0, 0.0),
        Quat::IDENTITY,
    );
    h.step();
    let ed = &h.state().editor;
    assert!(ed.backend.job.is_none(), "a light move re-bakes nothing");
    assert!(changed(&before, &values(&h)) > 1000, "the light move re-shaded in the same frame");
    assert!(ed.stats.edit_to_shade > 0.0);
    snapshot(&mut h, "moves-light");

    // A light that declares a reach (extras.kage.light_reach) is kept inside it.
    let light = light.unwrap();
    let ed = &mut h.state_mut().editor;
    let points = kage_engine::scene::flatten(&ed.doc.scene).lights[0].points.clone();
    let (lo, hi) = points.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    ed.doc.scene.world.get::<&mut kage_engine::scene::PolygonLight>(light).unwrap().reach = Some([lo - 0.3, hi + 0.3]);
    let at = values(&h);
    let ed = &mut h.state_mut().editor;
    ed.move_light(light, Vec3::new(0.5, 0.0, 0.0), Quat::IDENTITY);
    ed.set_light(light, Vec3::splat(10.0), 2.0);
    assert_eq!(errors(ed).len(), 2, "{:?}", errors(ed));
    assert!(errors(ed).iter().all(|e| e.contains("would leave its reach box")), "{:?}", errors(ed));
    ed.move_light(light, Vec3::new(0.2, 0.0, 0.0), Quat::IDENTITY);
    h.step();
    let ed = &h.state().editor;
    assert_eq!(errors(ed).len(), 2, "a move inside the reach is taken");
    assert!(ed.backend.job.is_none() && changed(&at, &values(&h)) > 1000);
    let ed = &mut h.state_mut().editor;
    ed.log.clear();
    // Back to roaming lights, so the group move below re-bakes against the same keys.
    ed.doc.scene.world.get::<&mut kage_engine::scene::PolygonLight>(light).unwrap().reach = None;

    // A group move: PRT (with shadows between groups) follows in the same frame, BSPVT re-bakes.
    h.get_by_label("prt").click();
    step_until(&mut h, "prt", |ed| ed.view.method == Method::Prt && !ed.dirty.shade);
    let prt_before = values(&h);
    let sphere = h.state().editor.doc.scene.find_group("sphere").unwrap();
    h.state_mut().editor.move_group(sphere, Vec3::new(-0.8, 0.0, 0.3), Quat::IDENTITY);
    h.step();
    let ed = &h.state().editor;
    assert!(changed(&prt_before, &values(&h)) > 50, "PRT shading follows the move at once");
    assert!(ed.backend.job.is_some() && ed.bakes.bspvt_stale, "an incremental BSPVT re-bake started");
    step_until(&mut h, "the re-bake", settled);
    let ed = &h.state().editor;
    let (b, p) = (ed.stats.runs[0].unwrap(), ed.stats.runs[1].unwrap());
    // The moved sphere's own chunks bake cold; every other receiver casts again only the rays
    // that meet the sphere's old or new bounds, and builds only the tiles whose visibility
    // changed.
    assert!(
        b.warm > 0 && b.cold < b.warm && 2 * b.rays_cast < first.rays_cast && b.tiles_built < first.tiles_built,
        "BSPVT re-baked incrementally: {b:?} after {first:?}"
    );
    assert!(p.cold == 0 && p.warm == 0 && p.cached > 0, "PRT transfer is cached after a rigid move: {p:?}");
    assert!(!ed.bakes.bspvt_stale);
    snapshot(&mut h, "moves-group");
}

#[test]
fn the_preview_refines_batch_by_batch_while_the_bakes_stream_in() {
    let dir = scratch("stream");
    let scene = import::import(&asset("scenes/teapot_quad_light.gltf"), Default::default()).unwrap();
    let mut o = options(&dir, None, None);
    o.bspvt.res = 32;
    // Per vertex: lavapipe draws the lights per pixel at a frame a second, and the bake would
    // land before the preview could show its batches.
    o.shade_on = ShadeOn::Cpu;
    // Every landing shown: paced by its cost on lavapipe, the bake would end before the
    // third preview.
    o.preview_spacing = 0.0;
    // Building the harness runs frames until the app is idle: start the bake afterwards.
    o.bake_on_start = false;
    let mut h = harness(scene, o);
    h.state_mut().editor.bake_now();
    h.step();
    // BSPVT previews seen while its bake is still running (each different from the last).
    let mut previews: Vec<Vec<Vec3>> = Vec::new();
    let start = Instant::now();
    while !settled(&h.state().editor) {
        assert!(start.elapsed() < Duration::from_secs(300), "{:#?}", h.state().editor.log);
        h.step();
        let ed = &h.state().editor;
        let baking = ed.backend.job.as_ref().is_some_and(|j| j.bspvt.as_ref().is_some_and(|t| t.running));
        let v = values(&h);
        if baking && ed.bakes.bspvt.is_some() && previews.last().is_none_or(|p| changed(p, &v) > 0) {
            previews.push(v);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    h.step();
    let ed = &h.state().editor;
    assert!(errors(ed).is_empty(), "{:?}", errors(ed));
    assert!(previews.len() >= 3, "the preview refined {} times during the bake", previews.len());
    // Vertices whose trees have not landed show unshadowed LTC; trees only take light away,
    // so each refinement darkens the view until the final bake.
    let total = |v: &[Vec3]| v.iter().map(|x| x.element_sum() as f64).sum::<f64>();
    let mut sums: Vec<f64> = previews.iter().map(|p| total(p)).collect();
    sums.push(total(&values(&h)));
    for w in sums.windows(2) {
        assert!(w[1] <= w[0] * (1.0 + 1e-4), "each landed batch only adds shadows: {sums:?}");
    }
    assert!(sums[sums.len() - 1] < 0.99 * sums[0], "the shadows landed: {sums:?}");
    assert!(ed.bakes.streamed >= previews.len(), "{} preview updates", ed.bakes.streamed);
}

/// The viewport draws a frame only when what it shows changed (on lavapipe a frame of per-pixel
/// lights takes a second of both cores, which idle frames would take from a bake).
#[test]
fn the_viewport_draws_a_frame_only_when_what_it_shows_changed() {
    let dir = scratch("draws");
    let mut h = harness(default_scene(), options(&dir, None, None));
    step_until(&mut h, "the bakes", settled);
    let frames = |h: &mut Harness<App>, n: usize| {
        let before = h.state().frames_drawn();
        for _ in 0..n {
            h.step();
            h.render().unwrap();
        }
        h.state().frames_drawn() - before
    };
    frames(&mut h, 3);
    assert_eq!(frames(&mut h, 4), 0, "an idle editor draws nothing");
    let ed = &mut h.state_mut().editor;
    ed.view.metering = false;
    ed.view.exposure += 1.0;
    assert_eq!(frames(&mut h, 3), 1, "a new exposure is one frame");
    h.state_mut().editor.view.orbit.yaw += 0.2;
    // The view moves (a frame), its re-shade lands (another); then nothing.
    let moved = frames(&mut h, 6);
    assert!((1..=3).contains(&moved), "{moved} frames for one view change");
    assert_eq!(frames(&mut h, 4), 0);
}

/// With the bounce on from the start, no gather runs while the first bake does (its direct
/// light changes with every chunk that lands): the term is gathered once, after the bakes.
#[test]
fn the_indirect_term_waits_for_the_bakes() {
    use kage_editor::systems::gathering;
    let dir = scratch("indirect-waits");
    let mut o = options(&dir, None, None);
    o.cache.rays = 64;
    o.indirect = true;
    let mut h = harness(default_scene(), o);
    let landed = |ed: &Editor| settled(ed) && !ed.results.indirect.is_empty() && !gathering(ed);
    step_until(&mut h, "the bakes and the indirect term", landed);
    let ed = &h.state().editor;
    assert!(errors(ed).is_empty(), "{:?}", errors(ed));
    let at = |prefix: &str| ed.log.iter().position(|l| l.text.starts_with(prefix));
    let gathers = ed.log.iter().filter(|l| l.text.starts_with("indirect: ")).count();
    let (bspvt, prt, first) = (at("BSPVT: ").unwrap(), at("PRT: ").unwrap(), at("indirect: ").unwrap());
    assert!(first > bspvt && first > prt, "gathered after the bakes landed: {:#?}", ed.log);
    assert_eq!(gathers, 1, "{:#?}", ed.log);
}

/// An exported pack carries the light of the bounces the editor shows (what `bevy_kage` adds):
/// read back, it is the editor's, and on the Lambertian cube and ground the editor's bounces
/// are it times the diffuse albedo at every vertex, every bounce counted.
#[test]
fn an_exported_pack_carries_the_bounces_light() {
    use kage_editor::systems::gathering;
    let dir = scratch("export-bounce");
    let path = dir.join("cube_on_plane.gltf");
    std::fs::copy(asset("scenes/cube_on_plane.gltf"), &path).unwrap();
    let mut o = options(&dir, Some(path.clone()), None);
    o.cache.rays = 64;
    o.indirect = true;
    let mut h = harness(import::import(&path, Default::default()).unwrap(), o);
    let landed = |ed: &Editor| settled(ed) && !ed.results.bounce_light.is_empty() && !gathering(ed);
    step_until(&mut h, "the bakes and the indirect term", landed);
    let message = h.state_mut().editor.export_pack();
    assert!(message.starts_with("wrote"), "{message}");
    let (scene, contents) = kage_bake_db::pack::read(&dir.join("cube_on_plane.pack.glb")).unwrap();
    let ed = &h.state().editor;
    assert_eq!(contents.bounce.as_ref(), Some(&ed.results.bounce_light));
    let flat = kage_engine::scene::flatten(&scene);
    let albedo = kage_engine::material::albedo::at_vertices(&flat, ed.view.orbit.eye());
    let light = ed.results.bounce_light.iter().flatten();
    let (mut worst, mut total) = (0.0f32, 0.0f32);
    for ((l, a), b) in light.zip(albedo.iter().flatten()).zip(ed.results.indirect.iter().flatten()) {
        worst = worst.max((*l * *a - *b).abs().max_element());
        total += b.element_sum();
    }
    assert!(total > 0.0 && worst <= 1e-5 * total, "off by {worst} (the bounces sum to {total})");
}

/// A geometry edit stops a gather still lighting the old geometry (its rays would take the
/// cores the re-bake needs, and what it landed would be stale); a fresh one runs once the
/// re-bake has landed, and its term fits the moved scene.
#[test]
fn a_geometry_edit_stops_the_running_gather() {
    use kage_editor::systems::gathering;
    let dir = scratch("indirect-edit");
    let mut o = options(&dir, None, None);
    o.indirect = true;
    let mut h = harness(default_scene(), o);
    step_until(&mut h, "the bakes and a gather", |ed| settled(ed) && gathering(ed));
    let sphere = h.state().editor.doc.scene.find_group("sphere").unwrap();
    h.state_mut().editor.move_group(sphere, Vec3::new(-0.8, 0.0, 0.3), Quat::IDENTITY);
    h.step();
    let ed = &h.state().editor;
    assert!(ed.backend.job.is_some() && !gathering(ed), "the edit's bake runs, the old gather stopped");
    let landed = |ed: &Editor| settled(ed) && !ed.results.indirect.is_empty() && !gathering(ed);
    step_until(&mut h, "the re-bake and its indirect term", landed);
    let ed = &h.state().editor;
    assert!(errors(ed).is_empty(), "{:?}", errors(ed));
    let counts = |v: &[Vec<Vec3>]| v.iter().map(Vec::len).collect::<Vec<_>>();
    assert_eq!(counts(&ed.results.indirect), counts(&ed.results.direct), "the term is the moved scene's");
}

/// The baked look's bounces light glossy hits as `kage render` does, the environment's diffuse
/// term, reflection and sun included: on an imported scene (every material glossy) under a sky,
/// the editor's bounces equal those gathered with the baked look's `Look::toward`, and lighting
/// those hits with the polygonal light alone would lose much of it.
#[test]
fn the_baked_bounce_lights_glossy_hits_with_the_environment_too() {
    use kage_editor::systems::gathering;
    use kage_engine::cache::{
        self,
        record::{Glossy, GlossyDirect, Source},
    };
    use kage_engine::shading::baked::{Bakes, Look};
    let dir = scratch("indirect-environment");
    let mut scene = import::import(&asset("scenes/textured_materials.gltf"), Default::default()).unwrap();
    let sky = kage_engine::scene::EnvMap::load(&asset("envmaps/sky.hdr")).unwrap();
    scene.set_environment(kage_engine::scene::EnvironmentLight::new(sky));
    let mut o = options(&dir, None, None);
    o.cache.rays = 64;
    o.indirect = true;
    let mut h = harness(scene, o);
    let landed = |ed: &Editor| settled(ed) && !ed.results.indirect.is_empty() && !gathering(ed);
    step_until(&mut h, "the bakes and the indirect term", landed);
    let ed = &h.state().editor;
    assert!(errors(ed).is_empty(), "{:?}", errors(ed));
    let renderer = kage_engine::reference::Renderer::new(&ed.doc.scene);
    let flat = &renderer.flat;
    let pre = kage_engine::prt::prefilter::Prefiltered::new(flat.environment.as_ref().unwrap());
    let (lighting, eye) = (ed.bakes.lighting.as_ref().unwrap(), ed.view.orbit.eye());
    let bakes = Bakes {
        bspvt: ed.bakes.bspvt.as_deref(),
        prt: Some(prt::Parts { bake: ed.bakes.prt.as_ref().unwrap(), lighting, settings: &ed.options.prt }),
        prefiltered: Some(&pre),
    };
    let look = Look::prepare(&ed.doc.scene, flat, bakes, eye, &mut prt::SilhouetteMemo::default());
    let bounce = |glossy: Glossy| {
        let src = Source { renderer: &renderer, direct: &ed.results.direct, glossy };
        let records = cache::place_at_vertices(&src, &ed.options.cache);
        cache::bounce(&src, &records, eye, cache::Bounces::default()).0
    };
    let toward = |i, corners, bary, to| look.toward(i, corners, bary, to);
    let expected = bounce(Glossy::Toward(&toward));
    let lights_alone = GlossyDirect::Ltc(ed.bakes.bspvt.clone()).with(flat, bounce);
    let total = |v: &[Vec<Vec3>]| v.iter().flatten().map(|x| x.element_sum() as f64).sum::<f64>();
    let off =
        ed.results.indirect.iter().flatten().zip(expected.iter().flatten()).map(|(a, b)| (*a - *b).abs().max_element());
    let (worst, n) = (off.fold(0.0f32, f32::max) as f64, expected.iter().map(Vec::len).sum::<usize>());
    assert!(worst <= 1e-4 * total(&expected) / n as f64, "off by up to {worst}");
    assert!(total(&lights_alone) < 0.8 * total(&expected), "{} vs {}", total(&lights_alone), total(&expected));
}

#[test]
fn the_cached_indirect_term_lands_in_the_background_follows_edits_and_persists() {
    use kage_editor::systems::gathering;
    let dir = scratch("indirect");
    let mut o = options(&dir, None, None);
    o.cache.rays = 64;
    let mut h = harness(default_scene(), o);
    step_until(&mut h, "the first bakes", settled);
    let direct = values(&h);
    h.get_by_label("Indirect light (HSH radiance cache)").click();
    let landed = |ed: &Editor| !ed.results.indirect.is_empty() && !gathering(ed) && !ed.dirty.shade;
    step_until(&mut h, "the indirect term", landed);
    let ed = &h.state().editor;
    assert!(errors(ed).is_empty(), "{:?}", errors(ed));
    let with = values(&h);
    let total = |v: &[Vec3]| v.iter().map(|x| x.element_sum() as f64).sum::<f64>();
    assert!(with.iter().zip(&direct).all(|(w, d)| w.is_finite() && (*w - *d).min_element() >= -1e-6));
    assert!(total(&with) > 1.01 * total(&direct), "one bounce adds light: {} vs {}", total(&with), total(&direct));
    let gathered = |ed: &Editor| ed.log.iter().filter(|l| l.text.starts_with("indirect: ")).count();
    assert_eq!(gathered(ed), 1);
    snapshot(&mut h, "indirect");

    // A light move re-shades the direct term at once; the indirect term follows when gathered.
    let first = h.state().editor.results.indirect.clone();
    let light = h.state().editor.outline().into_iter().find_map(|(s, ..)| match s {
        Selection::Light(e) => Some(e),
        _ => None,
    });
    h.state_mut().editor.move_light(light.unwrap(), Vec3::new(0.5, 0.0, 0.0), Quat::IDENTITY);
    h.step();
    assert!(changed(&with, &values(&h)) > 100, "the direct term follows at once");
    step_until(&mut h, "the new indirect term", |ed| landed(ed) && gathered(ed) == 2);
    let last = |ed: &Editor| ed.log.iter().rev().find(|l| l.text.starts_with("indirect: ")).unwrap().text.clone();
    let ed = &h.state().editor;
    assert!(last(ed).contains("refreshed") && last(ed).contains("re-cast, stored"), "{}", last(ed));
    let second: Vec<Vec3> = ed.results.indirect.iter().flatten().copied().collect();
    assert!(changed(&first.concat(), &second) > 100, "the indirect term follows the light");

    // Off and on again with the same lighting: the records are kept as they are.
    h.get_by_label("Indirect light (HSH radiance cache)").click();
    h.step();
    h.get_by_label("Indirect light (HSH radiance cache)").click();
    step_until(&mut h, "the same indirect term", |ed| landed(ed) && gathered(ed) == 3);
    let ed = &h.state().editor;
    assert!(last(ed).contains("records unchanged"), "{}", last(ed));
    assert_eq!(ed.results.indirect.concat(), second, "the same records give the same term");

    // Another session on the same database and lighting: the records come from the database.
    drop(h);
    let mut o = options(&dir, None, None);
    o.cache.rays = 64;
    let mut h = harness(default_scene(), o);
    step_until(&mut h, "the cached bakes", settled);
    h.get_by_label("Indirect light (HSH radiance cache)").click();
    step_until(&mut h, "the stored indirect term", landed);
    let ed = &h.state().editor;
    assert!(last(ed).contains("from the bake database"), "{}", last(ed));
    assert_eq!(ed.results.indirect, first, "the stored records give the same term");

    // The refresh after the light move was stored too: a session that moves the light the same
    // way before turning the term on loads it.
    drop(h);
    let mut o = options(&dir, None, None);
    o.cache.rays = 64;
    let mut h = harness(default_scene(), o);
    step_until(&mut h, "the cached bakes", settled);
    h.state_mut().editor.move_light(light.unwrap(), Vec3::new(0.5, 0.0, 0.0), Quat::IDENTITY);
    step_until(&mut h, "the moved light's direct term", settled);
    h.get_by_label("Indirect light (HSH radiance cache)").click();
    step_until(&mut h, "the stored refreshed term", landed);
    let ed = &h.state().editor;
    assert!(last(ed).contains("from the bake database"), "{}", last(ed));
    assert_eq!(ed.results.indirect.concat(), second, "the refreshed records, stored");

    // Moved back, to lighting whose records are stored: loaded, not refreshed from the ones
    // loaded without their hits (which would gather every record anew).
    let before = gathered(ed);
    h.state_mut().editor.move_light(light.unwrap(), Vec3::new(-0.5, 0.0, 0.0), Quat::IDENTITY);
    step_until(&mut h, "the first lighting's term", |ed| landed(ed) && gathered(ed) > before);
    let ed = &h.state().editor;
    assert!(last(ed).contains("from the bake database"), "{}", last(ed));
    assert_eq!(ed.results.indirect, first, "the first lighting's records");
}

#[test]
fn shader_saves_rebuild_pipelines_and_broken_shaders_keep_the_last_good_one() {
    let dir = scratch("reload");
    let shaders = dir.join("shaders");
    std::fs::create_dir_all(&shaders).unwrap();
    let repo_shaders = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shaders");
    for f in std::fs::read_dir(&repo_shaders).unwrap().map(|e| e.unwrap().path()) {
        std::fs::copy(&f, shaders.join(f.file_name().unwrap())).unwrap();
    }
    let mut h = harness(default_scene(), on_gpu(options(&dir, None, Some(shaders.clone()))));
    step_until(&mut h, "the first bakes", settled);
    let good = snapshot(&mut h, "reload-before");
    let generation = h.state().editor.shader_generation;

    // A valid edit (the preview inverts its colours), saved by writing in place.
    let source = std::fs::read_to_string(shaders.join("preview.wgsl")).unwrap();
    let inverted = source.replace("return vec4<f32>(srgb(", "return vec4<f32>(vec3<f32>(1.0) - srgb(");
    assert_ne!(inverted, source);
    std::fs::write(shaders.join("preview.wgsl"), &inverted).unwrap();
    step_until(&mut h, "the reload", |ed| ed.shader_generation > generation);
    assert!(h.state().editor.shader_error.is_none());
    let changed_img = snapshot(&mut h, "reload-inverted");
    let differ = good.pixels().zip(changed_img.pixels()).filter(|(a, b)| a != b).count();
    assert!(differ > 100_000, "the new pipeline draws differently ({differ} pixels)");

    // A broken edit, saved by rename-replace: the error names file and line, drawing goes on.
    let broken = inverted.replacen("fn fs_main", "fn fs_main(", 1);
    std::fs::write(dir.join("tmp.wgsl"), &broken).unwrap();
    std::fs::rename(dir.join("tmp.wgsl"), shaders.join("preview.wgsl")).unwrap();
    step_until(&mut h, "the shader error", |ed| ed.shader_error.is_some());
    let ed = &h.state().editor;
    let e = ed.shader_error.clone().unwrap();
    assert!(e.file.ends_with("preview.wgsl") && e.line > 0, "{e:?}");
    assert!(errors(ed).iter().any(|l| l.contains("keeping the last good pipeline")));
    let still = snapshot(&mut h, "reload-broken");
    // The same pipeline draws the same scene, a little smaller: the error's panel below the
    // viewport takes some of its height (a failed view would have a handful of colours).
    let (before, after) = (viewport_colours(&changed_img), viewport_colours(&still));
    assert!(before.abs_diff(after) * 50 < before, "the last good pipeline keeps drawing: {before} → {after} colours");

    // Fixed again: the error clears.
    std::fs::write(shaders.join("preview.wgsl"), &source).unwrap();
    step_until(&mut h, "the fix", |ed| ed.shader_error.is_none());
}

#[test]
fn touching_the_scene_file_reimports_it_and_rebakes_only_what_changed() {
    let dir = scratch("touch");
    let scene_path = dir.join("cube_on_plane.gltf");
    std::fs::copy(asset("scenes/cube_on_plane.gltf"), &scene_path).unwrap();
    let scene = import::import(&scene_path, Default::default()).unwrap();
    let mut opts = options(&dir, Some(scene_path.clone()), None);
    opts.prt = prt::Settings { order: 3, directions: 64, ..opts.prt };
    let mut h = harness(scene, opts);
    step_until(&mut h, "the first bakes", settled);
    let first = h.state().editor.stats.runs[0].unwrap();
    assert!(first.cold > 0, "{first:?}");

    // Move the cube 0.3 along x in the file, saved by rename-replace.
    let mut gltf: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&scene_path).unwrap()).unwrap();
    assert_eq!(gltf["nodes"][1]["name"], "cube");
    gltf["nodes"][1]["translation"] = serde_json::json!([0.3, 1.5, 0.0]);
    std::fs::write(dir.join("save.tmp"), serde_json::to_string_pretty(&gltf).unwrap()).unwrap();
    std::fs::rename(dir.join("save.tmp"), &scene_path).unwrap();
    step_until(&mut h, "the re-import", |ed| ed.log.iter().any(|l| l.text.contains("re-imported")));
    step_until(&mut h, "the re-bake", |ed| settled(ed) && !ed.bakes.bspvt_stale);
    let ed = &h.state().editor;
    let again = ed.stats.runs[0].unwrap();
    assert!(again.cold < first.cold, "only the moved cube's own chunks bake cold: {again:?} vs {first:?}");
    assert!(
        again.warm > 0 && again.rays_cast < again.vertices_baked * 16 * 16 && again.tiles_built < first.tiles_built,
        "only rays that can meet the cube are cast again: {again:?}"
    );
    assert!(errors(ed).is_empty(), "{:?}", errors(ed));

    // A geometry edit through the inspector: the cube's mesh replaced by Suzanne's (small
    // enough to stay below the light: a mesh reaching behind it would turn depth on and
    // re-bake everything, see bspvt::reach::Reach::of_scene).
    let cube = h.state().editor.outline().into_iter().find_map(|(s, label, _)| match s {
        Selection::Instance(e) if label.contains("cube") => Some(e),
        _ => None,
    });
    h.state_mut().editor.doc.selection = Selection::Instance(cube.expect("the cube is listed"));
    h.step();
    let field = h.get_by_role_and_label(egui::accesskit::Role::TextInput, "glTF file");
    field.focus();
    field.type_text(asset("models/suzanne.glb").to_str().unwrap());
    h.step();
    h.get_by_label("Replace mesh").click();
    h.step();
    let ed = &h.state().editor;
    assert!(ed.log.iter().any(|l| l.text.contains("replaced the mesh by")), "{:#?}", ed.log);
    step_until(&mut h, "a mesh replacement re-bakes", |ed| ed.backend.job.is_some());
    step_until(&mut h, "the re-bake after the mesh edit", |ed| settled(ed) && !ed.bakes.bspvt_stale);
    let edit = h.state().editor.stats.runs[0].unwrap();
    assert!(edit.cold > 0 && edit.warm > 0, "the new mesh bakes cold, the ground warm: {edit:?}");
}

/// A scene above the background threshold (here every scene: 0) shades on the CPU off the UI
/// thread and lands exactly what shading within the frame gives, for every CPU method.
#[test]
fn large_scenes_shade_in_the_background_to_the_same_values() {
    let d = scratch("background");
    let shade = |threshold: usize| {
        let mut o = options(&d, None, None);
        (o.shade_on, o.background_shading) = (ShadeOn::Cpu, threshold);
        let mut h = harness(import::import(&asset("scenes/cube_on_plane.gltf"), Default::default()).unwrap(), o);
        step_until(&mut h, "the first bakes", settled);
        let mut out = Vec::new();
        for (label, method) in
            [("bspvt", Method::Bspvt), ("ltc-unshadowed", Method::LtcUnshadowed), ("baked", Method::Baked)]
        {
            h.get_by_label(label).click();
            step_until(&mut h, label, |ed| ed.view.method == method && shaded(ed));
            out.push(values(&h));
        }
        out
    };
    let (background, in_frame) = (shade(0), shade(usize::MAX));
    assert!(background.iter().all(|v| v.iter().any(|x| x.max_element() > 0.01)), "lit");
    assert!(changed(&background[0], &background[1]) > 100, "shadowed differs from unshadowed");
    assert_eq!(background, in_frame);
}

/// The editor bakes PRT with the parameters `kage bake` chose for the scene: it reads the
/// choice the bake database keeps instead of measuring its own.
#[test]
fn the_editor_takes_prt_parameters_from_the_budget_kage_bake_chose() {
    let d = scratch("prt-budget");
    let mut scene = import::import(&asset("scenes/bunny_two_groups.gltf"), Default::default()).unwrap();
    let env = kage_engine::scene::EnvMap::load(&asset("envmaps/city.hdr")).unwrap();
    scene.set_environment(kage_engine::scene::EnvironmentLight::new(env));
    let base = prt::Settings { directions: 256, ..prt::Settings::default() };
    let mut o = options(&d, None, None);
    o.prt = base;
    o.prt_budget = Some(0.05);
    o.bake_on_start = false;
    // What `kage bake` chooses (the same function, the same database), before the editor opens.
    let store = kage_bake_db::Store::open(&o.db_path).unwrap();
    let flat = kage_engine::scene::flatten(&scene);
    let chosen = kage_bake_db::prt_budget::choose(&store, &scene, &flat, 0.05, &base, &mut |_| {}).unwrap();
    drop(store);
    assert_ne!(chosen, base, "the budget chose something other than the defaults");
    let h = harness(scene, o);
    let ed = &h.state().editor;
    assert_eq!(ed.options.prt, chosen);
    let cached = ed.log.iter().filter(|l| l.text.starts_with("PRT:") && l.text.contains("cached plan")).count();
    assert_eq!(cached, 2, "order and regions both read from the database: {:#?}", ed.log);
}

/// Screen position of world point `p` in the last frame's viewport.
fn on_screen(h: &Harness<App>, p: Vec3) -> egui::Pos2 {
    let app = h.state();
    let rect = app.viewport_rect.expect("the viewport was drawn");
    let uv = app.editor.view.orbit.project(p, rect.width() / rect.height()).expect("in front of the camera");
    rect.min + egui::vec2(uv.x * rect.width(), uv.y * rect.height())
}

fn pose(h: &Harness<App>, group: hecs::Entity) -> glam::Affine3A {
    h.state().editor.doc.scene.world.get::<&kage_engine::scene::Transform>(group).unwrap().world
}

/// Presses at `a` and moves to `b` over several frames, as a hand would (the button stays down).
fn press_and_move(h: &mut Harness<App>, a: egui::Pos2, b: egui::Pos2) {
    h.hover_at(a);
    h.step();
    h.drag_at(a);
    h.step();
    for k in 1..=8 {
        h.hover_at(a + (b - a) * (k as f32 / 8.0));
        h.step();
    }
}

/// Drags the pointer from `a` to `b` and releases it there.
fn drag(h: &mut Harness<App>, a: egui::Pos2, b: egui::Pos2) {
    press_and_move(h, a, b);
    h.drop_at(b);
    h.step();
}

#[test]
fn click_picks_the_gizmo_moves_and_undo_returns_to_the_cached_bakes_bit_for_bit() {
    let dir = scratch("gizmo");
    let mut h = harness(default_scene(), options(&dir, None, None));
    step_until(&mut h, "the first bakes", settled);
    let sphere = h.state().editor.doc.scene.find_group("sphere").unwrap();
    let start = pose(&h, sphere);
    let centre = Vec3::from(start.translation);

    // Hovering highlights, a click selects what is under the pointer, Escape clears.
    let at = on_screen(&h, centre);
    h.hover_at(at);
    h.step();
    assert_eq!(h.state().editor.view.hover, Selection::Group(sphere), "hovering the sphere highlights it");
    h.drag_at(at);
    h.step();
    h.drop_at(at);
    h.step();
    assert_eq!(h.state().editor.doc.selection, Selection::Group(sphere), "a click picks the sphere's group");
    h.key_press(egui::Key::Escape);
    h.step();
    assert_eq!(h.state().editor.doc.selection, Selection::None);
    let (light, light_entity) = (h.state().editor.flat.lights[0].clone(), h.state().editor.flat.light_entities[0]);
    let light_centre = light.points.iter().copied().sum::<Vec3>() / light.points.len() as f32;
    // The light hangs above the opening view: zoom out (as the wheel does) to see it.
    let mut wide = h.state().editor.view.orbit;
    wide.zoom(2.5);
    h.state_mut().editor.set_orbit(wide);
    h.step();
    h.hover_at(on_screen(&h, light_centre));
    h.step();
    h.drag_at(on_screen(&h, light_centre));
    h.step();
    h.drop_at(on_screen(&h, light_centre));
    h.step();
    assert_eq!(h.state().editor.doc.selection, Selection::Light(light_entity), "lights are picked too");

    // Dragging the X arrow moves the group along X; the whole drag is one undo step.
    h.state_mut().editor.doc.selection = Selection::Group(sphere);
    h.step();
    let place = kage_editor::interaction::placement(&h.state().editor, Selection::Group(sphere)).unwrap();
    let probe = place.origin + place.axes[0] * 0.05;
    let (a, tip) = (on_screen(&h, centre), on_screen(&h, probe));
    let grab = a + (tip - a).normalized() * 0.5 * kage_editor::gizmo::HANDLE_PIXELS;
    let plans = |h: &Harness<App>| h.state().editor.log.iter().filter(|l| l.text.starts_with("bake plan")).count();
    let planned = plans(&h);
    let to = grab + (tip - a).normalized() * 60.0;
    press_and_move(&mut h, grab, to);
    assert_eq!(plans(&h), planned, "no re-bake starts while the drag lasts");
    h.drop_at(to);
    h.step();
    let moved = pose(&h, sphere);
    let shift = Vec3::from(moved.translation) - centre;
    assert!(shift.x > 0.05 && shift.y.abs() < 1e-4 && shift.z.abs() < 1e-4, "moved along +X: {shift}");
    assert_eq!(h.state().editor.doc.history.undo_len(), 1, "one drag, one step");
    snapshot(&mut h, "gizmo-moved");
    step_until(&mut h, "the re-bake after the drag", settled);
    assert_eq!(plans(&h), planned + 1, "one re-bake, after the drag");

    // Ctrl+Z: the stored pose comes back bit for bit, and with it the bakes the database holds.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.step();
    assert_eq!(pose(&h, sphere), start, "undo restores the stored pose exactly");
    step_until(&mut h, "the bakes after undo", settled);
    let ed = &h.state().editor;
    let (b, p) = (ed.stats.runs[0].unwrap(), ed.stats.runs[1].unwrap());
    assert!(b.cold == 0 && b.warm == 0 && b.cached > 0, "after undo BSPVT is fully cached: {b:?}");
    assert!(p.cold == 0 && p.warm == 0, "PRT too: {p:?}");
    // Ctrl+Shift+Z redoes, to the moved pose exactly.
    h.key_press_modifiers(egui::Modifiers::COMMAND | egui::Modifiers::SHIFT, egui::Key::Z);
    h.step();
    assert_eq!(pose(&h, sphere), moved);
    assert_eq!((h.state().editor.doc.history.undo_len(), h.state().editor.doc.history.redo_len()), (1, 0));

    // Turning: the E key switches the gizmo, dragging the Y ring turns the group about +Y.
    h.key_press(egui::Key::E);
    h.step();
    assert_eq!(h.state().editor.view.gizmo.mode, kage_editor::gizmo::Mode::Rotate);
    let before = pose(&h, sphere);
    let orbit = h.state().editor.view.orbit;
    let rect = h.state().viewport_rect.unwrap();
    let view = kage_editor::gizmo::View { orbit: &orbit, size: glam::Vec2::new(rect.width(), rect.height()) };
    let place = kage_editor::interaction::placement(&h.state().editor, Selection::Group(sphere)).unwrap();
    let ring = &place.handles(kage_editor::gizmo::Mode::Rotate, &view)[1];
    let (r0, r1) = (ring[8], ring[16]);
    drag(&mut h, rect.min + egui::vec2(r0.x, r0.y), rect.min + egui::vec2(r1.x, r1.y));
    let turned = pose(&h, sphere);
    assert_eq!(Vec3::from(turned.translation), Vec3::from(before.translation), "a turn keeps the origin");
    let axis = turned.matrix3 * before.matrix3.inverse();
    assert!((axis * glam::Vec3A::Y - glam::Vec3A::Y).length() < 1e-4, "turned about Y");
    assert!((axis * glam::Vec3A::X - glam::Vec3A::X).length() > 0.05, "by a visible angle");
    h.state_mut().editor.undo();
    assert_eq!(pose(&h, sphere), before);

    // Scaling: R, then the X handle dragged outward grows the group uniformly about its origin.
    h.key_press(egui::Key::R);
    h.step();
    let place = kage_editor::interaction::placement(&h.state().editor, Selection::Group(sphere)).unwrap();
    let handle = &place.handles(kage_editor::gizmo::Mode::Scale, &view)[0];
    let (s0, s1) = (rect.min + egui::vec2(handle[0].x, handle[0].y), rect.min + egui::vec2(handle[1].x, handle[1].y));
    drag(&mut h, s0 + (s1 - s0) * 0.5, s1);
    let grown = pose(&h, sphere);
    let ratio = |k: usize| grown.matrix3.col(k).length() / before.matrix3.col(k).length();
    assert!(ratio(0) > 1.2 && (ratio(0) - ratio(1)).abs() < 1e-4 && (ratio(0) - ratio(2)).abs() < 1e-4, "{grown:?}");
    assert_eq!(Vec3::from(grown.translation), Vec3::from(before.translation));
    h.state_mut().editor.undo();
    assert_eq!(pose(&h, sphere), before, "undo restores the stored pose exactly");
    let ed = &h.state().editor;
    assert!(errors(ed).is_empty(), "{:?}", errors(ed));
}

#[test]
fn ctrl_s_saves_the_opened_file_which_is_not_reimported_and_outside_changes_ask_first() {
    let dir = scratch("save");
    let path = dir.join("cube_on_plane.gltf");
    std::fs::copy(asset("scenes/cube_on_plane.gltf"), &path).unwrap();
    let original = std::fs::read(&path).unwrap();
    let scene = import::import(&path, Default::default()).unwrap();
    let mut opts = options(&dir, Some(path.clone()), None);
    opts.prt = prt::Settings { order: 3, directions: 64, ..opts.prt };
    let mut h = harness(scene, opts);
    step_until(&mut h, "the first bakes", settled);
    assert!(!h.state().editor.unsaved());
    let cube = h.state().editor.doc.scene.find_group("cube").unwrap();
    h.state_mut().editor.move_group(cube, Vec3::new(0.5, 0.0, 0.0), Quat::IDENTITY);
    h.step();
    assert!(h.state().editor.unsaved(), "a move is an unsaved edit");

    // Ctrl+S writes the edit into the file; re-opened, the cube stands where it was moved.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::S);
    h.step();
    let ed = &h.state().editor;
    assert!(!ed.unsaved(), "{:?}", ed.log);
    let saved = import::import(&path, Default::default()).unwrap();
    let at = |s: &kage_engine::scene::Scene| {
        s.world.get::<&kage_engine::scene::Transform>(s.find_group("cube").unwrap()).unwrap().world.translation
    };
    assert!((at(&saved) - at(&ed.doc.scene)).length() < 1e-5);
    assert_eq!(std::fs::read(dir.join("cube_on_plane.gltf.bak")).unwrap(), original, "the old version is kept");
    // The editor's own save is not an outside change: no re-import.
    for _ in 0..40 {
        h.step();
        std::thread::sleep(Duration::from_millis(25));
    }
    assert!(!h.state().editor.log.iter().any(|l| l.text.contains("re-imported")), "{:#?}", h.state().editor.log);

    // An outside change while edits are unsaved asks first; keeping the edits keeps them.
    h.state_mut().editor.move_group(cube, Vec3::new(0.0, 0.0, 0.5), Quat::IDENTITY);
    let edited = pose(&h, cube);
    std::fs::write(dir.join("other.tmp"), &original).unwrap();
    std::fs::rename(dir.join("other.tmp"), &path).unwrap();
    step_until(&mut h, "the question", |ed| ed.outside_change);
    h.get_by_label("Keep my edits").click();
    h.step();
    assert!(!h.state().editor.outside_change);
    assert_eq!(pose(&h, cube), edited, "the edits stay");
    // Closing the window with edits unsaved asks first; Cancel keeps editing.
    h.input_mut().viewports.entry(egui::ViewportId::ROOT).or_default().events.push(egui::ViewportEvent::Close);
    h.step();
    h.step();
    h.get_by_label("Save your edits before closing?");
    h.get_by_label("Cancel").click();
    h.step();
    h.step();
    assert!(h.query_by_label("Save your edits before closing?").is_none());
    // With nothing unsaved, an outside change re-imports at once.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::S);
    h.step();
    std::fs::write(dir.join("other.tmp"), &original).unwrap();
    std::fs::rename(dir.join("other.tmp"), &path).unwrap();
    step_until(&mut h, "the re-import", |ed| ed.log.iter().any(|l| l.text.contains("re-imported")));
    let ed = &h.state().editor;
    assert!(!ed.unsaved() && errors(ed).is_empty(), "{:?}", errors(ed));
}

/// A file dropped on the window, as eframe hands it to egui.
#[derive(Debug)]
struct Dropped(PathBuf);

impl egui::DroppedFile for Dropped {
    fn path(&self) -> &Path {
        &self.0
    }

    fn bytes(&self) -> Result<Vec<u8>, String> {
        std::fs::read(&self.0).map_err(|e| e.to_string())
    }
}

#[test]
fn lights_are_added_groups_duplicated_deleted_and_dropped_files_added_each_one_undo_step() {
    let dir = scratch("add");
    let mut h = harness(default_scene(), options(&dir, None, None));
    step_until(&mut h, "the first bakes", settled);
    let counts = |h: &Harness<App>| (h.state().editor.flat.instances.len(), h.state().editor.flat.lights.len());
    let start = counts(&h);
    let before = values(&h);

    // Add > Quad light: a new light, selected, shading the scene once its bake lands.
    h.get_by_label("Add").click();
    h.step();
    h.step();
    h.get_by_label("Quad light").click();
    h.step();
    h.step();
    assert_eq!(counts(&h), (start.0, start.1 + 1));
    assert!(matches!(h.state().editor.doc.selection, Selection::Light(_)));
    step_until(&mut h, "the bake with the new light", settled);
    assert!(changed(&before, &values(&h)) > 1000, "the new light lights the scene");

    // Ctrl+D copies the selected group; Delete removes the copy.
    let sphere = h.state().editor.doc.scene.find_group("sphere").unwrap();
    h.state_mut().editor.doc.selection = Selection::Group(sphere);
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::D);
    h.step();
    h.step();
    assert_eq!(counts(&h), (start.0 + 1, start.1 + 1), "the sphere's copy");
    let copy = h.state().editor.doc.selection;
    assert!(matches!(copy, Selection::Group(g) if g != sphere));
    h.key_press(egui::Key::Delete);
    h.step();
    h.step();
    assert_eq!(counts(&h), (start.0, start.1 + 1));

    // A glTF dropped on the window becomes a group of its own.
    h.input_mut().dropped_files.push(std::sync::Arc::new(Dropped(asset("models/bunny.glb"))));
    h.step();
    h.step();
    assert_eq!(counts(&h), (start.0 + 1, start.1 + 1), "{:?}", errors(&h.state().editor));
    step_until(&mut h, "the bake with the bunny", settled);
    snapshot(&mut h, "added");
    let ed = &h.state().editor;
    assert!(errors(ed).is_empty(), "{:?}", errors(ed));
    assert_eq!(ed.doc.history.undo_len(), 4, "add, duplicate, delete, drop: four steps");

    // Undoing everything leads back to the scene that was opened, and to its bakes.
    for _ in 0..4 {
        h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
        h.step();
    }
    h.step();
    assert_eq!(counts(&h), start);
    step_until(&mut h, "the bakes after undoing", settled);
    let ed = &h.state().editor;
    let b = ed.stats.runs[0].unwrap();
    assert!(b.cold == 0 && b.warm == 0 && b.cached > 0, "the opened scene's bakes are all cached: {b:?}");
    // Redo brings the copy back, then deletes it again: the same entity, bit for bit.
    h.key_press_modifiers(egui::Modifiers::COMMAND | egui::Modifiers::SHIFT, egui::Key::Z);
    h.key_press_modifiers(egui::Modifiers::COMMAND | egui::Modifiers::SHIFT, egui::Key::Z);
    h.step();
    h.step();
    assert_eq!(counts(&h), (start.0 + 1, start.1 + 1));
    assert!(errors(&h.state().editor).is_empty());
}

/// A scene nothing lights opens with an error in the log that says why its view is black and
/// how to light it.
#[test]
fn an_unlit_scene_says_why_it_is_black() {
    let d = scratch("unlit");
    use kage_editor::systems::gathering;
    let mut o = options(&d, None, None);
    o.bake_on_start = false;
    o.indirect = true;
    let mut scene = kage_engine::scene::Scene::new("test:unlit");
    let mesh = kage_engine::scene::shapes::cuboid(Vec3::splat(0.5));
    let grey = kage_engine::scene::Material::lambertian(Vec3::splat(0.5));
    scene.add_object("box", mesh, grey, glam::Affine3A::IDENTITY);
    let mut h = harness(scene, o);
    let errors = errors(&h.state().editor);
    assert!(errors.iter().any(|e| e.contains("nothing lights it") && e.contains("Quad light")), "{errors:?}");
    for _ in 0..5 {
        h.step();
    }
    let ed = &h.state().editor;
    assert!(ed.indirect && !gathering(ed) && ed.results.indirect.is_empty(), "nothing lit bounces: no gather");
    h.get_by_label("BSPVT no polygonal light; PRT no environment");
}

/// Receivers are refined before each bake, from the file's meshes, as `kage bake` refines them
/// (the same refined meshes, so the same bake keys); a light move leaves the refinement stale
/// until "Refine again"; a group move refines again by itself; undo returns to the first
/// refinement's cached bakes; Save writes the file's own meshes, never the refined ones.
#[test]
fn receivers_are_refined_as_kage_bake_refines_them_and_again_after_edits() {
    let dir = scratch("refine");
    let path = dir.join("two_triangle_floor.gltf");
    std::fs::copy(asset("scenes/two_triangle_floor.gltf"), &path).unwrap();
    let settings = kage_engine::receivers::Settings { budget: 1500, ..Default::default() };
    let cold = |light_by: Vec3| {
        let mut s = import::import(&path, Default::default()).unwrap();
        s.pose_group(s.find_group("light").unwrap(), Quat::IDENTITY, light_by);
        kage_engine::receivers::refine(&mut s, &settings).unwrap();
        s
    };
    let hashes = |s: &kage_engine::scene::Scene| {
        let flat = kage_engine::scene::flatten(s);
        flat.instances.iter().map(|i| flat.meshes[i.mesh as usize].hash).collect::<Vec<_>>()
    };
    let mut opts = options(&dir, Some(path.clone()), None);
    opts.refine = Some(settings);
    let mut h = harness(import::import(&path, Default::default()).unwrap(), opts);
    step_until(&mut h, "the first bakes", settled);
    let ed = &h.state().editor;
    let first = hashes(&ed.doc.scene);
    assert_eq!(first, hashes(&cold(Vec3::ZERO)), "the editor refined differently from the engine");
    let (before, after) = ed.bakes.receivers.as_ref().expect("refined").vertices;
    // Measured: 1,111 (each instance refined until interpolation meets the tolerance).
    assert!(before == 205 && after > 800, "{before} → {after}");
    assert_eq!(ed.flat.vertex_count(0), ed.bakes.bspvt.as_ref().unwrap().instances[0].vertices());
    assert!(!ed.refinement_stale());

    // A light move re-shades at once and leaves the refinement stale; Refine again follows it.
    let by = Vec3::new(1.0, 0.0, -0.5);
    let light = ed.flat.light_entities[0];
    h.state_mut().editor.move_light(light, by, Quat::IDENTITY);
    h.step();
    assert!(h.state().editor.refinement_stale() && h.state().editor.backend.job.is_none());
    h.get_by_label("Refine again").click();
    step_until(&mut h, "the refinement for the moved light", |ed| settled(ed) && !ed.refinement_stale());
    let moved = cold(by);
    assert_eq!(kage_engine::scene::flatten(&moved).lights[0].points, h.state().editor.flat.lights[0].points);
    assert_eq!(hashes(&h.state().editor.doc.scene), hashes(&moved), "refined again unlike a cold refinement");
    h.state_mut().editor.undo();
    step_until(&mut h, "the light back", settled);

    // A group move refines again by itself; undo returns to the first refinement, all cached.
    let ball = h.state().editor.doc.scene.find_group("ball").unwrap();
    h.state_mut().editor.move_group(ball, Vec3::new(-1.5, 0.0, 0.0), Quat::IDENTITY);
    step_until(&mut h, "the re-bake after the move", settled);
    assert_ne!(hashes(&h.state().editor.doc.scene), first, "the move refined nothing again");
    h.state_mut().editor.undo();
    step_until(&mut h, "the re-bake after undo", settled);
    let ed = &h.state().editor;
    assert_eq!(hashes(&ed.doc.scene), first, "undo came back to another refinement");
    let b = ed.stats.runs[0].unwrap();
    assert!(b.cold == 0 && b.warm == 0, "undo re-baked: {b:?}");

    // Save writes the file's own meshes (a moved ball, the floor still two triangles).
    h.state_mut().editor.move_group(ball, Vec3::new(0.0, 0.0, 0.4), Quat::IDENTITY);
    h.step();
    h.state_mut().editor.save();
    let ed = &h.state().editor;
    assert!(!ed.unsaved() && errors(ed).is_empty(), "{:?}", errors(ed));
    let saved = import::import(&path, Default::default()).unwrap();
    let flat = kage_engine::scene::flatten(&saved);
    assert_eq!(flat.vertex_count(0), 4, "the saved floor is the file's two triangles");
    // So does saving a scene that has no file (the built-in one), through the pack writer.
    let ed = &mut h.state_mut().editor;
    ed.options.scene_path = None;
    let glb = dir.join("no-file.glb");
    let message = ed.save_as(&glb);
    assert!(message.starts_with("wrote"), "{message}");
    let saved = kage_engine::scene::flatten(&import::import(&glb, Default::default()).unwrap());
    assert_eq!(saved.vertex_count(0), 4, "a save without a file writes the floor's two triangles too");
}
