//! The editor's schedule: plain functions over the editor state and its ECS world, run in a
//! fixed order once per frame ([`run_frame`]). Nothing here blocks on a bake or a reference
//! pass: those run on rayon in the background and land here when done.

use super::bake_job::{BakeJob, ChunkData, Landed};
use super::indirect::{BakedParts, HitLight, Indirect, Job};
use super::pick::Seen;
use super::state::Editor;
use super::worker::Worker;
use glam::Vec3;
use kage_bake_db::DbError;
use kage_engine::bspvt::pixel::Lobes;
use kage_engine::math::color::metered_exposure_keeping;
use kage_engine::prt::prefilter::Prefiltered;
use kage_engine::reference::{Renderer, Settings};
use kage_engine::scene::VertexValues;
use kage_engine::scene::{EnvMap, EnvironmentLight, flatten, import};
use kage_engine::shading::Method;
use kage_engine::shading::baked::{Look, Polygonal};
use kage_engine::{bspvt, prt};
use kage_gpu::bspvt::BspvtShader;
use kage_gpu::prt::PrtShader;
use kage_gpu::reload::Change;
use kage_gpu::viewport::{PixelEnvironment, PixelLights, VertexSun};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Instant;

/// Samples per vertex of one progressive reference pass.
const REFERENCE_SPP: u32 = 4;
/// Passes after which the reference stops refining (REFERENCE_SPP × this samples).
const REFERENCE_PASSES: u32 = 256;

/// Runs every system once, in dependency order.
pub fn run_frame(ed: &mut Editor) {
    reload_system(ed);
    pose_system(ed);
    environment_system(ed);
    bake_system(ed);
    reference_system(ed);
    shade_system(ed);
    indirect_system(ed);
}

/// Hot reload: rebuilds pipelines after a shader save (keeping the last good ones when the new
/// source does not compile) and re-imports the scene or environment after theirs.
pub fn reload_system(ed: &mut Editor) {
    let Some(watcher) = &mut ed.backend.watcher else { return };
    let (changes, errors) = watcher.changes();
    errors.into_iter().for_each(|e| ed.error(e));
    for change in changes {
        match change {
            Change::Shader(name) => reload_shader(ed, &name),
            Change::Scene => scene_changed(ed),
            Change::Environment => reload_environment(ed),
        }
    }
}

fn reload_shader(ed: &mut Editor, changed: &str) {
    let start = Instant::now();
    // A file other shaders include rebuilds every one of them.
    let names = ed.backend.shaders.dependents(changed);
    if let Some(e) = names.iter().find_map(|n| ed.backend.shaders.checked(n).err()) {
        ed.error(format!("shader {}: keeping the last good pipeline\n{}", e.file, plain_frames(&e.report)));
        ed.shader_error = Some(e);
        return;
    }
    let gpu = ed.backend.gpu.clone();
    for name in &names {
        let result = match name.as_str() {
            "bspvt.wgsl" => ed.backend.bspvt_gpu.as_mut().map(|s| s.reload(&gpu, &ed.backend.shaders)),
            "prt.wgsl" => ed.backend.prt_gpu.as_mut().map(|s| s.reload(&gpu, &ed.backend.shaders)),
            _ => None,
        };
        if let Some(Err(e)) = result {
            ed.error(format!("{name}: {}; keeping the last good pipeline", plain_frames(&e.to_string())));
            return;
        }
    }
    ed.shader_error = None;
    ed.shader_generation += 1;
    ed.stats.shader_reload = start.elapsed().as_secs_f64();
    ed.info(format!("{changed}: reloaded {} in {:.1} ms", names.join(", "), 1e3 * ed.stats.shader_reload));
    ed.dirty.shade = true;
}

/// The compiler's diagnostic with its box-drawing frame in ASCII (the UI font has no glyphs
/// for U+2500–U+257F).
fn plain_frames(report: &str) -> String {
    report
        .chars()
        .map(|c| match c {
            '│' | '┃' | '╎' => '|',
            '\u{2500}'..='\u{257F}' => '-',
            c => c,
        })
        .collect()
}

/// A change of the scene file on disk (the editor's own saves are not reported: see
/// [`kage_gpu::reload::Watcher::note_write`]): a question ([`Editor::outside_change`]) when edits
/// are unsaved, a re-import otherwise.
fn scene_changed(ed: &mut Editor) {
    let Some(path) = ed.options.scene_path.clone() else { return };
    if ed.unsaved() {
        ed.outside_change = true;
        ed.info(format!("{}: changed on disk while edits are unsaved", path.display()));
        return;
    }
    reimport_scene(ed);
}

/// Re-imports the scene file (edits since the last save are dropped).
pub fn reimport_scene(ed: &mut Editor) {
    let Some(path) = ed.options.scene_path.clone() else { return };
    ed.outside_change = false;
    match import::import(&path, ed.options.import.clone()) {
        Ok(mut scene) => {
            if let Some(env) = ed.doc.scene.world.query::<&EnvironmentLight>().iter().next().cloned() {
                scene.set_environment(env);
            }
            ed.doc.scene = scene;
            ed.doc.selection = super::state::Selection::None;
            ed.view.hover = super::state::Selection::None;
            ed.doc.history.clear();
            ed.doc.mark_saved();
            ed.dirty.pose = true;
            ed.dirty.geometry = true;
            ed.dirty.meshes = true;
            ed.dirty.environment = true;
            ed.restart_reference();
            ed.info(format!("{}: re-imported", path.display()));
        }
        Err(e) => ed.error(format!("{}: {e} (keeping the previous scene)", path.display())),
    }
}

fn reload_environment(ed: &mut Editor) {
    let Some(path) = ed.options.env_path.clone() else { return };
    match EnvMap::load(&path) {
        Ok(map) => {
            ed.doc.scene.set_environment(EnvironmentLight::new(map));
            ed.dirty.pose = true;
            ed.dirty.environment = true;
            ed.restart_reference();
            ed.info(format!("{}: re-loaded", path.display()));
        }
        Err(e) => ed.error(format!("{}: {e} (keeping the previous environment)", path.display())),
    }
}

/// Propagates group poses to their members and rebuilds the snapshot.
pub fn pose_system(ed: &mut Editor) {
    if ed.dirty.pose {
        ed.doc.scene.update_transforms();
        ed.flat = flatten(&ed.doc.scene);
        ed.backend.memo.picker = None;
        ed.dirty.pose = false;
        ed.dirty.shade = true;
    }
}

/// Projects the environment for PRT again after it changed.
pub fn environment_system(ed: &mut Editor) {
    if ed.dirty.environment {
        ed.bakes.lighting = prt::Lighting::new(&ed.doc.scene, &ed.options.prt);
        ed.dirty.environment = false;
        ed.dirty.shade = true;
    }
}

/// Starts (or restarts) the background bake after geometry edits and takes in what landed.
pub fn bake_system(ed: &mut Editor) {
    if ed.dirty.geometry && !ed.dragging {
        ed.dirty.geometry = false;
        // A gather still running lights the old geometry: what it would land is stale, and
        // its rays would take the cores refinement and the bake need. One starts again once
        // the bake has landed.
        ed.backend.workers.indirect = None;
        refine_receivers(ed);
        start_bake(ed);
    }
    let Some(job) = &mut ed.backend.job else { return };
    let landed = job.landed();
    let (running, started) = (job.running(), job.started);
    let mut patched = ed.bakes.unshown;
    for l in landed {
        take(ed, l, &mut patched);
    }
    ed.bakes.unshown = patched;
    if patched.contains(&true) && (!running || preview_due(ed, started)) {
        show_patches(ed);
    }
    if !running {
        ed.backend.job = None;
    }
}

/// While a bake runs, a preview of what landed is due once the last one, or the bake's start,
/// is [`super::state::Options::preview_spacing`] times a preview's cost (shading and drawing)
/// ago.
fn preview_due(ed: &Editor, started: Instant) -> bool {
    let cost = ed.stats.shading + ed.stats.draw;
    let since = ed.bakes.shown_at.map_or(started, |t| t.max(started));
    since.elapsed().as_secs_f64() >= ed.options.preview_spacing * cost
}

/// Puts the patched bakes on the device and re-shades from them.
fn show_patches(ed: &mut Editor) {
    let [bspvt, prt] = std::mem::take(&mut ed.bakes.unshown);
    if bspvt {
        upload_bspvt(ed);
    }
    if prt {
        upload_prt(ed);
    }
    ed.bakes.streamed += 1;
    ed.bakes.shown_at = Some(Instant::now());
    ed.dirty.shade = true;
}

/// Writes a streamed chunk into the preview's bakes (BSPVT, PRT: `patched`). A bake that does
/// not fit the snapshot is replaced first by a placeholder: unshadowed records for BSPVT
/// (vertices show LTC without shadows until their trees land), zero transfer for PRT.
fn patch(ed: &mut Editor, instance: usize, first: usize, data: ChunkData, patched: &mut [bool; 2]) {
    let counts: Vec<usize> = (0..ed.flat.instances.len()).map(|i| ed.flat.vertex_count(i)).collect();
    let fits = |have: &[usize]| have == counts;
    match data {
        ChunkData::Trees(records) => {
            // Copy on write: an indirect job may still hold the previous trees.
            let bake = Arc::make_mut(
                ed.bakes.bspvt.get_or_insert_with(|| placeholder_trees(&counts, ed.options.bspvt).into()),
            );
            if !fits(&bake.instances.iter().map(bspvt::BakedInstance::vertices).collect::<Vec<_>>()) {
                *bake = placeholder_trees(&counts, ed.options.bspvt);
            }
            if first + records.len() <= counts.get(instance).copied().unwrap_or(0) {
                bake.instances[instance].splice(first, &records);
                patched[0] = true;
            }
        }
        ChunkData::Transfer(t) => {
            let order = ed.options.prt.order;
            let n = order * order;
            let zeros = || prt::Bake {
                order,
                instances: counts.iter().map(|c| vec![0.0; c * n]).collect(),
                stats: Default::default(),
            };
            let bake = ed.bakes.prt.get_or_insert_with(zeros);
            if bake.order != order || !fits(&bake.instances.iter().map(|t| t.len() / n).collect::<Vec<_>>()) {
                *bake = zeros();
            }
            if let Some(dst) = bake.instances.get_mut(instance).and_then(|d| d.get_mut(first * n..first * n + t.len()))
            {
                dst.copy_from_slice(&t);
                patched[1] = true;
            }
        }
    }
}

fn placeholder_trees(counts: &[usize], settings: bspvt::Settings) -> bspvt::Bake {
    let instances = counts.iter().map(|&c| bspvt::BakedInstance::unshadowed(c)).collect();
    bspvt::Bake { settings, instances, stats: Default::default() }
}

/// Puts the current BSPVT trees on the device when a GPU shader holds them (the CPU path reads
/// them in place; a shader made later takes the trees of its time).
fn upload_bspvt(ed: &mut Editor) {
    let (Some(shader), Some(bake)) = (&mut ed.backend.bspvt_gpu, &ed.bakes.bspvt) else { return };
    if let Err(e) = shader.set_bake(&ed.backend.gpu, Some(bake)) {
        ed.backend.bspvt_gpu = None;
        ed.error(format!("BSPVT on the GPU: {e} (shading on the CPU)"));
    }
}

/// Puts the current PRT transfer on the device.
fn upload_prt(ed: &mut Editor) {
    let Some(bake) = &ed.bakes.prt else { return };
    match PrtShader::new(&ed.backend.gpu, &ed.backend.shaders, bake, bake.order) {
        Ok(s) => ed.backend.prt_gpu = Some(s),
        Err(e) => ed.error(format!("PRT on the GPU: {e}")),
    }
}

/// Refines the receivers again from their source meshes for the lights and the environment as
/// they are now, as `kage bake` does when it loads a scene, so the editor bakes the CLI's
/// artefacts. Large levels (more receiver vertices than `background_shading`) stay as they
/// are: refining them would hold the window for minutes.
fn refine_receivers(ed: &mut Editor) {
    let Some(settings) = ed.options.refine else { return };
    let vertices =
        |flat: &kage_engine::scene::FlatScene| (0..flat.instances.len()).map(|i| flat.vertex_count(i)).sum::<usize>();
    if vertices(&ed.flat) > ed.options.background_shading {
        ed.info(format!(
            "receivers not refined: {} vertices is a large level (refining it takes minutes); `kage bake` refines it",
            vertices(&ed.flat)
        ));
        return;
    }
    let started = Instant::now();
    let meshes = |flat: &kage_engine::scene::FlatScene| {
        flat.instances.iter().map(|i| flat.meshes[i.mesh as usize].hash).collect::<Vec<_>>()
    };
    let was = meshes(&ed.flat);
    let refined = match ed.backend.store.clone() {
        Some(store) => kage_bake_db::memo::refinement::refine(&store, &mut ed.doc.scene, &settings, &|_| {})
            .map_err(|e| e.to_string()),
        None => kage_engine::receivers::refine(&mut ed.doc.scene, &settings).map(|r| (r, 0)).map_err(|e| e.to_string()),
    };
    let (report, kept) = match refined {
        Ok(r) => r,
        Err(e) => return ed.error(format!("refining receivers: {e}")),
    };
    let before: usize = report.iter().map(|r| r.0).sum();
    ed.dirty.pose = true;
    ed.dirty.meshes = true;
    pose_system(ed);
    let refined = super::state::Refined {
        vertices: (before, vertices(&ed.flat)),
        seconds: started.elapsed().as_secs_f64(),
        placed: super::state::placed_lights(&ed.flat),
    };
    // The reference's samples are per vertex: they do not carry over to other meshes.
    if meshes(&ed.flat) != was {
        ed.restart_reference();
    }
    ed.info(format!(
        "receivers refined: {} to {} vertices in {:.2} s (at most {} more each, tolerance {}{})",
        refined.vertices.0,
        refined.vertices.1,
        refined.seconds,
        settings.for_instances(report.len()).budget,
        settings.tolerance,
        kage_bake_db::memo::refinement::kept_note(kept, report.len())
    ));
    ed.bakes.receivers = Some(refined);
}

fn start_bake(ed: &mut Editor) {
    let Some(store) = ed.backend.store.clone() else { return };
    if let Some(old) = ed.backend.job.take() {
        old.cancel();
    }
    let wake = ed.backend.wake.clone();
    match BakeJob::start(store, &ed.doc.scene, Some(ed.options.bspvt), Some(ed.options.prt), move || wake()) {
        Ok(job) => {
            let line = |name: &str, t: &Option<super::bake_job::Track>| {
                t.as_ref().map(|t| format!("{name}: {} chunks cached, {} vertices to bake", t.cached, t.total))
            };
            let text = [line("BSPVT", &job.bspvt), line("PRT", &job.prt)].into_iter().flatten().collect::<Vec<_>>();
            ed.bakes.bspvt_stale = ed.bakes.bspvt.is_some() && job.bspvt.as_ref().is_some_and(|t| t.total > 0);
            ed.info(format!("bake plan: {}", text.join("; ")));
            ed.backend.job = Some(job);
        }
        Err(e) => ed.error(format!("bake: {e}")),
    }
}

/// Takes in what landed: a chunk is patched into the preview's bakes (`patched`), a finished
/// bake replaces them. Either is shown when previews are due ([`show_patches`]): a technique
/// that finishes while the other still bakes waits like a chunk.
fn take(ed: &mut Editor, landed: Landed, patched: &mut [bool; 2]) {
    match landed {
        Landed::Chunk(instance, first, data) => patch(ed, instance, first, data, patched),
        Landed::Bspvt(Ok((bake, stats))) => {
            ed.stats.runs[0] = Some(stats);
            ed.info(format!(
                "BSPVT: {} cached, {} cold, {} warm chunks ({} vertices) in {:.2} s",
                stats.cached, stats.cold, stats.warm, stats.vertices_baked, stats.seconds
            ));
            // A light the trees shut in shows only its bounce, metered up: say so.
            if let Some(warning) = bspvt::unseen_warning(&ed.doc.scene, &ed.flat, &bake) {
                ed.error(format!("warning: {warning}"));
            }
            ed.bakes.bspvt = Some(bake.into());
            ed.bakes.bspvt_stale = false;
            patched[0] = true;
        }
        Landed::Prt(Ok((bake, stats))) => {
            ed.stats.runs[1] = Some(stats);
            ed.info(format!("PRT: {} cached, {} cold chunks in {:.2} s", stats.cached, stats.cold, stats.seconds));
            ed.bakes.prt = Some(bake);
            patched[1] = true;
        }
        Landed::Bspvt(Err(DbError::Cancelled { done })) | Landed::Prt(Err(DbError::Cancelled { done })) => {
            ed.info(format!("bake cancelled; {done} vertices committed stay in the database"))
        }
        Landed::Bspvt(Err(e)) | Landed::Prt(Err(e)) => ed.error(format!("bake: {e}")),
    }
}

/// Refines the reference progressively while it is shown or compared against.
pub fn reference_system(ed: &mut Editor) {
    if ed.view.method != Method::Reference && !ed.view.overlay {
        ed.backend.workers.reference = None;
        return;
    }
    if ed.backend.workers.reference.is_none() && ed.results.reference.passes < REFERENCE_PASSES {
        ed.backend.workers.reference = Some(spawn_reference(ed));
    }
    let passes = ed.backend.workers.reference.as_ref().map(|w| w.results()).unwrap_or_default();
    for pass in passes {
        ed.results.reference.add(pass);
        ed.dirty.shade = true;
    }
}

/// The reference for the current method's lights, with one bounce when the indirect term is on.
fn spawn_reference(ed: &Editor) -> Worker<VertexValues> {
    let scene = ed.view.method.lit(&ed.doc.scene);
    let bounces = u32::from(ed.indirect && ed.view.method.direct());
    let (eye, first) = (ed.view.orbit.eye(), ed.results.reference.passes);
    let wake = ed.backend.wake.clone();
    Worker::spawn(
        move |stop, send| {
            let renderer = Renderer::new(&scene);
            for pass in first..REFERENCE_PASSES {
                if stop.load(Ordering::Relaxed) {
                    return;
                }
                let s = Settings { spp: REFERENCE_SPP, seed: pass as u64, max_bounces: bounces, min_bounces: 0 };
                let est = renderer.render_vertices(eye, &s, &|_| {});
                send(est.iter().map(|v| v.iter().map(|e| e.mean).collect()).collect());
            }
        },
        move || wake(),
    )
}

/// Shades the current method when anything it depends on changed, then the overlay.
pub fn shade_system(ed: &mut Editor) {
    if let Some((values, start)) =
        ed.backend.workers.shading.as_ref().and_then(|(w, start)| Some((w.results().pop()?, *start)))
    {
        ed.backend.workers.shading = None;
        land(ed, values, start);
        compose(ed);
    }
    // One background shading at a time: a change while it runs is shaded when it lands.
    if !ed.dirty.shade || ed.backend.workers.shading.is_some() {
        return;
    }
    ed.dirty.shade = false;
    let start = Instant::now();
    if ed.view.method != Method::Prt || ed.view.overlay {
        ed.results.per_pixel = None;
    }
    ed.results.pixel_lights = None;
    ed.results.vertex_sun = None;
    ed.dirty.per_pixel = true;
    if let Some(job) = Background::of(ed) {
        let wake = ed.backend.wake.clone();
        ed.backend.workers.shading = Some((Worker::spawn(move |_, send| send(job.shade()), move || wake()), start));
        return;
    }
    if let Some(values) = shade(ed) {
        land(ed, values, start);
    }
    compose(ed);
}

/// Takes newly shaded direct light, started at `start`.
fn land(ed: &mut Editor, values: VertexValues, start: Instant) {
    ed.results.direct = values;
    ed.backend.workers.generations.0 += 1;
    ed.stats.shading = start.elapsed().as_secs_f64();
    if let Some(t) = ed.edited_at.take() {
        ed.stats.edit_to_shade = t.elapsed().as_secs_f64();
    }
}

/// A CPU shading of the polygonal lights (run in the background for scenes larger than
/// [`super::state::Options::background_shading`]: a million vertices take seconds, and orbiting
/// the camera must not wait for them) ; for `baked`, the whole look of a scene without an
/// environment), with what it reads copied.
struct Background {
    flat: kage_engine::scene::FlatScene,
    trees: Option<Arc<bspvt::Bake>>,
    method: Method,
    eye: Vec3,
}

impl Background {
    /// The job for the editor's current view, when the scene is large enough and the method
    /// shades on the CPU with no environment term (those keep shading within the frame).
    fn of(ed: &Editor) -> Option<Self> {
        let vertices: usize = (0..ed.flat.instances.len()).map(|k| ed.flat.vertex_count(k)).sum();
        let cpu = match ed.view.method {
            Method::Bspvt | Method::LtcUnshadowed => true,
            Method::Baked => ed.flat.environment.is_none(),
            _ => false,
        };
        if vertices <= ed.options.background_shading || !cpu || ed.polygonal_on_gpu() {
            return None;
        }
        let trees = ed.bakes.bspvt.clone().filter(|b| trees_fit(ed, b));
        let trees = trees.filter(|_| ed.view.method != Method::LtcUnshadowed);
        Some(Self { flat: ed.flat.clone(), trees, method: ed.view.method, eye: ed.view.orbit.eye() })
    }

    fn shade(&self) -> VertexValues {
        let shadows = self.trees.as_deref().map_or(bspvt::Shadows::Unshadowed, bspvt::Shadows::Trees);
        let values = (!self.flat.lights.is_empty()).then(|| bspvt::shade_vertices(&self.flat, shadows, self.eye));
        match (self.method, values) {
            (Method::Baked, values) => {
                let polygonal = values.map(|values| Polygonal { bake: self.trees.as_deref(), values, lobes: None });
                Look::new(&self.flat, self.eye, polygonal, None).into_direct()
            }
            (_, values) => values.unwrap_or_else(|| self.flat.zeros()),
        }
    }
}

/// What the viewport shows: direct plus (when on and of the same shape) the indirect term,
/// or the error overlay of that.
fn compose(ed: &mut Editor) {
    let shapes = |v: &[Vec<Vec3>]| v.iter().map(Vec::len).collect::<Vec<_>>();
    let add = ed.indirect && ed.view.method.direct() && shapes(&ed.results.indirect) == shapes(&ed.results.direct);
    ed.results.radiance = if add {
        ed.results
            .direct
            .iter()
            .zip(&ed.results.indirect)
            .map(|(d, i)| d.iter().zip(i).map(|(d, i)| *d + *i).collect())
            .collect()
    } else {
        ed.results.direct.clone()
    };
    let values = if ed.view.overlay { overlay(ed) } else { ed.results.radiance.clone() };
    // A landing that changes nothing on screen (a bounce re-lit by the same light) draws nothing.
    if values != ed.results.values {
        ed.results.values = values;
        ed.results.values_revision += 1;
    }
    if ed.view.metering {
        meter_exposure(ed);
    }
}

/// Sets the exposure as `kage render --exposure auto` meters its image (within the slider's
/// range), from [`view_samples`]: their log-average to middle grey, at most 5 % of those on a
/// surface clipping. Metering the vertices instead weighed a refined shadow's many vertices as
/// much as a whole wall. Waits, metering on, while nothing is lit yet, and meters every result
/// again while a bake runs: the first results (unshadowed, or one light's part) are not the look.
pub fn meter_exposure(ed: &mut Editor) {
    let lit = ed.results.radiance.iter().flatten().any(|c| c.max_element() > 0.0);
    if lit {
        let (all, surfaces) = view_samples(ed);
        let kept = if surfaces.is_empty() { &all } else { &surfaces };
        ed.view.exposure = metered_exposure_keeping(&all, kept).clamp(-6.0, 6.0);
        ed.view.metering = ed.backend.job.is_some();
    }
}

/// View rays through a grid over the viewport: the radiance each meets — the vertex radiance
/// interpolated on a mesh, a light's own on its emitting side, the environment where nothing
/// is hit — for all of them and for those on a surface.
pub fn view_samples(ed: &mut Editor) -> (Vec<Vec3>, Vec<Vec3>) {
    const ACROSS: usize = 96;
    let down = ((ACROSS as f32 / ed.view.aspect.max(0.1)).round() as usize).clamp(1, 4 * ACROSS);
    let picker = ed.backend.memo.picker.get_or_insert_with(|| super::pick::Picker::new(&ed.flat));
    let fits = ed.results.radiance.len() == ed.flat.instances.len();
    let (mut all, mut surfaces) = (Vec::new(), Vec::new());
    for k in 0..ACROSS * down {
        let uv =
            glam::Vec2::new(((k % ACROSS) as f32 + 0.5) / ACROSS as f32, ((k / ACROSS) as f32 + 0.5) / down as f32);
        let (eye, dir) = ed.view.orbit.ray(uv, ed.view.aspect);
        match picker.seen(&ed.flat, eye, dir) {
            Seen::Surface(hit)
                if fits && ed.results.radiance[hit.instance].len() == ed.flat.vertex_count(hit.instance) =>
            {
                let l = hit.interpolate(&ed.results.radiance[hit.instance]);
                surfaces.push(l);
                all.push(l);
            }
            Seen::Surface(_) => {}
            Seen::Light(l) => {
                let light = &ed.flat.lights[l];
                all.push(if dir.dot(light.normal) < 0.0 { light.radiance } else { Vec3::ZERO });
            }
            Seen::Nothing => all.push(ed.flat.environment.as_ref().map_or(Vec3::ZERO, |e| e.background(dir))),
        }
    }
    (all, surfaces)
}

/// One bounce of indirect light from the HSH radiance cache, lit by the current direct result:
/// gathered in the background (one gather at a time; a newer direct result starts the next when
/// it ends), its records kept in the bake database. The preview adds the last term that landed.
/// No gather starts while a bake runs: its direct light changes with every chunk that lands, so
/// the term would be replaced, its records stored for lighting no finished bake has, and its
/// rays would take cores from the bake.
pub fn indirect_system(ed: &mut Editor) {
    if !ed.indirect || !ed.view.method.direct() {
        ed.backend.workers.indirect = None;
        return;
    }
    if ed.flat.unlit().is_some() {
        // Nothing lights the scene, so nothing bounces: no gather, and no bounce of a light
        // since deleted.
        ed.backend.workers.indirect = None;
        if !ed.results.indirect.is_empty() {
            ed.results.indirect.clear();
            ed.results.bounce_light.clear();
            compose(ed);
        }
        return;
    }
    let landed = ed.backend.workers.indirect.as_ref().map(|w| w.results()).unwrap_or_default();
    if let Some(last) = landed.into_iter().last() {
        ed.results.indirect = last.values;
        if let Some(light) = last.light {
            ed.results.bounce_light = light;
        }
        if let Some(base) = last.base {
            ed.backend.workers.indirect = None;
            ed.backend.workers.indirect_base = Some(base);
            ed.info(format!("indirect: {}", last.what));
        }
        compose(ed);
    }
    let (direct, started) = ed.backend.workers.generations;
    if ed.backend.workers.indirect.is_none()
        && started != direct
        && !ed.results.direct.is_empty()
        && ed.backend.job.is_none()
    {
        ed.backend.workers.generations.1 = direct;
        ed.backend.workers.indirect = Some(spawn_indirect(ed));
    }
}

/// True while an indirect gather runs.
pub fn gathering(ed: &Editor) -> bool {
    ed.backend.workers.indirect.is_some()
}

/// True while a large scene's direct light is shaded in the background.
pub fn shading(ed: &Editor) -> bool {
    ed.backend.workers.shading.is_some()
}

/// How the current method lights glossy hits toward the cache's records.
fn hit_light(ed: &Editor) -> HitLight {
    let trees = || ed.bakes.bspvt.clone().filter(|b| trees_fit(ed, b));
    HitLight::Method(match ed.view.method {
        Method::Baked if let Some(parts) = baked_parts(ed, trees()) => return HitLight::Baked(Box::new(parts)),
        // No environment shaded yet: the baked look is the polygonal lights alone.
        method => method.glossy_direct(trees()),
    })
}

/// The baked look's parts as [`baked`] shades them, where it shades the environment: the PRT
/// transfer fits the snapshot and the map is prefiltered. Polygonal lights without fitting
/// trees are lit unshadowed, as the view shows them.
fn baked_parts(ed: &Editor, trees: Option<Arc<bspvt::Bake>>) -> Option<BakedParts> {
    let (bake, lighting, prefiltered) =
        (ed.bakes.prt.as_ref()?, ed.bakes.lighting.as_ref()?, ed.backend.memo.prefiltered.as_ref()?);
    if !transfer_fits(ed, bake) {
        return None;
    }
    let counts = || (0..ed.flat.instances.len()).map(|i| ed.flat.vertex_count(i)).collect::<Vec<_>>();
    let bspvt = trees.or_else(|| {
        let unshadowed = || Arc::new(placeholder_trees(&counts(), ed.options.bspvt));
        (!ed.flat.lights.is_empty()).then(unshadowed)
    });
    let prt = (bake.clone(), lighting.clone(), ed.options.prt);
    Some(BakedParts { bspvt, prt, prefiltered: prefiltered.clone() })
}

fn spawn_indirect(ed: &mut Editor) -> Worker<Indirect> {
    let job = Job {
        scene: ed.view.method.lit(&ed.doc.scene),
        glossy: hit_light(ed),
        direct: ed.results.direct.clone(),
        eye: ed.view.orbit.eye(),
        settings: ed.options.cache,
        store: ed.backend.store.clone(),
        base: ed.backend.workers.indirect_base.take(),
    };
    let wake = ed.backend.wake.clone();
    Worker::spawn(move |stop, send| job.run(stop, send), move || wake())
}

/// The method's per-vertex radiance, or `None` while a background result is pending.
fn shade(ed: &mut Editor) -> Option<VertexValues> {
    let eye = ed.view.orbit.eye();
    match ed.view.method {
        Method::Bspvt | Method::LtcUnshadowed => Some(polygonal(ed, eye)),
        Method::LtcExactVis => exact_vis(ed, eye),
        Method::Prt | Method::PrtSelf => Some(prt_gpu(ed, eye)),
        Method::Baked => Some(baked(ed, eye)),
        Method::Reference => Some(ed.results.reference.mean().unwrap_or_else(|| ed.flat.zeros())),
    }
}

/// True when BSPVT trees fit the current snapshot ([`fits`]).
fn trees_fit(ed: &Editor, b: &bspvt::Bake) -> bool {
    fits(ed, &b.instances, |i| i.offsets.len() - 1)
}

/// True when a PRT transfer fits the current snapshot ([`fits`]).
fn transfer_fits(ed: &Editor, bake: &prt::Bake) -> bool {
    let n = kage_engine::math::sh::num_coeffs(bake.order);
    fits(ed, &bake.instances, |t| t.len() / n)
}

/// True when a bake's per-instance vertex counts match the current snapshot (a mesh replaced
/// since the bake leaves a stale bake that cannot shade it until the re-bake lands).
fn fits<T>(ed: &Editor, instances: &[T], vertices: impl Fn(&T) -> usize) -> bool {
    instances.len() == ed.flat.instances.len()
        && instances.iter().enumerate().all(|(k, b)| vertices(b) == ed.flat.vertex_count(k))
}

/// The current method's polygonal lights (BSPVT with the trees that fit the snapshot, else
/// unshadowed LTC): with the lobes the viewport draws per pixel when it does (on the CPU), else
/// on the GPU, or on the CPU when chosen (see [`super::state::ShadeOn`]) or when the GPU path
/// refuses the scene.
fn polygonal(ed: &mut Editor, eye: Vec3) -> VertexValues {
    let trees = ed.bakes.bspvt.clone().filter(|b| trees_fit(ed, b));
    let res = ed.options.bspvt.res;
    let shadows = ed.view.method.polygonal_shadows(trees.as_deref(), res).unwrap_or(bspvt::Shadows::Unshadowed);
    let bake = match shadows {
        bspvt::Shadows::Trees(b) => Some(b),
        _ => None,
    };
    if ed.lights_per_pixel() {
        let (lobes, values) = Lobes::at_vertices(&ed.flat, bake, eye, ed.backend.memo.inside.flags(&ed.flat));
        ed.results.pixel_lights = Some(PixelLights { lobes, values: values.clone(), environment: None });
        return values;
    }
    let gpu = ed.backend.gpu.clone();
    if ed.backend.bspvt_gpu.is_none() && ed.polygonal_on_gpu() {
        match BspvtShader::new(&gpu, &ed.backend.shaders, ed.bakes.bspvt.as_deref()) {
            Ok(s) => ed.backend.bspvt_gpu = Some(s),
            Err(e) => ed.error(format!("BSPVT on the GPU: {e}")),
        }
    }
    let on_gpu = ed.backend.bspvt_gpu.as_ref().filter(|_| ed.polygonal_on_gpu());
    let result = on_gpu.map(|s| kage_gpu::bspvt::shade_vertices(&gpu, s, &ed.flat, shadows, eye));
    match result {
        Some(Ok(v)) => v,
        other => {
            if let Some(Err(e)) = other {
                ed.error(format!("GPU shading: {e}; shading on the CPU"));
            }
            bspvt::shade_vertices(&ed.flat, shadows, eye)
        }
    }
}

/// The complete look per vertex: the polygonal lights (on the GPU when it can), the
/// environment's diffuse (PRT, with other groups' shadows) and specular terms on the CPU.
fn baked(ed: &mut Editor, eye: Vec3) -> VertexValues {
    let trees = ed.bakes.bspvt.as_deref().is_some_and(|b| trees_fit(ed, b));
    let values = (!ed.flat.lights.is_empty()).then(|| polygonal(ed, eye));
    let bake = ed.bakes.bspvt.as_deref().filter(|_| trees);
    let polygonal = values.map(|values| Polygonal { bake, values, lobes: None });
    let env = ed.flat.environment.clone();
    ed.backend.memo.prefiltered = env
        .as_ref()
        .map(|e| ed.backend.memo.prefiltered.as_ref().map_or_else(|| Prefiltered::new(e), |p| p.for_light(e)));
    let (Some(bake), Some(light), Some(pre)) = (&ed.bakes.prt, &ed.bakes.lighting, &ed.backend.memo.prefiltered) else {
        return Look::new(&ed.flat, eye, polygonal, None).into_direct();
    };
    if !transfer_fits(ed, bake) {
        return Look::new(&ed.flat, eye, polygonal, None).into_direct();
    }
    // A light moved and nothing else: the environment's part is reused.
    let parts = prt::Parts { bake, lighting: light, settings: &ed.options.prt };
    let (environment, silhouettes) = (&mut ed.backend.memo.environment, &mut ed.backend.memo.silhouettes);
    let direct = Look::direct_reusing(
        &ed.doc.scene,
        &ed.flat,
        eye,
        polygonal,
        Some((parts, Some(pre))),
        environment,
        silhouettes,
    );
    specular_per_pixel(ed, eye);
    sun_per_pixel(ed, eye);
    direct
}

/// The map's sun for the per-vertex draw to shade per pixel (the per-pixel lights' draw has
/// its own: [`specular_per_pixel`]).
fn sun_per_pixel(ed: &mut Editor, eye: Vec3) {
    let sun = ed.bakes.lighting.as_ref().and_then(|l| l.split_sun().0).filter(|_| !ed.lights_per_pixel());
    ed.results.vertex_sun = sun.map(|sun| {
        let (values, open) = kage_engine::shading::baked::sun_vertices(&ed.flat, &sun, eye);
        VertexSun { sun, values, open }
    });
}

/// Adds the environment's specular term of the frame just shaded to what the viewport draws
/// per pixel (with no polygonal light, the lights' part is empty).
fn specular_per_pixel(ed: &mut Editor, eye: Vec3) {
    let (Some(specular), Some(pre)) = (ed.backend.memo.environment.specular(), &ed.backend.memo.prefiltered) else {
        return;
    };
    if !ed.lights_per_pixel() {
        return;
    }
    let Some(lighting) = &ed.bakes.lighting else { return };
    let environment = Some(PixelEnvironment::new(&ed.flat, specular, pre, lighting, eye));
    let lights = ed.results.pixel_lights.get_or_insert_with(|| {
        let (lobes, values) = Lobes::at_vertices(&ed.flat, None, eye, ed.backend.memo.inside.flags(&ed.flat));
        PixelLights { lobes, values, environment: None }
    });
    lights.environment = environment;
}

/// The exact-visibility comparison casts cube maps per vertex: in the background.
fn exact_vis(ed: &mut Editor, eye: Vec3) -> Option<VertexValues> {
    if let Some(v) = ed.backend.workers.exact.as_ref().and_then(|w| w.results().pop()) {
        return Some(v);
    }
    if ed.backend.workers.exact.is_none() {
        let scene = ed.doc.scene.duplicate();
        let s = ed.options.bspvt;
        let wake = ed.backend.wake.clone();
        ed.backend.workers.exact = Some(Worker::spawn(
            move |_, send| {
                let flat = flatten(&scene);
                send(bspvt::shade_vertices(&flat, bspvt::Shadows::Exact { res: s.res }, eye));
            },
            move || wake(),
        ));
        ed.info("ltc-exact-vis: casting visibility per vertex in the background".into());
    }
    ed.dirty.shade = ed.backend.workers.exact.is_some();
    None
}

fn prt_gpu(ed: &mut Editor, eye: Vec3) -> VertexValues {
    let (Some(bake), Some(light), Some(shader)) = (&ed.bakes.prt, &ed.bakes.lighting, &ed.backend.prt_gpu) else {
        return ed.flat.zeros();
    };
    if !transfer_fits(ed, bake) {
        return ed.flat.zeros();
    }
    let shadows = ed.view.method.prt_shadows().unwrap_or(prt::Shadows::SelfOnly);
    let posed = prt::pose(
        &ed.doc.scene,
        &ed.flat,
        bake.order,
        light,
        shadows,
        &ed.options.prt,
        &mut ed.backend.memo.silhouettes,
    );
    let gpu = ed.backend.gpu.clone();
    let values = kage_gpu::prt::shade_vertices(&gpu, shader, &ed.flat, &posed, eye);
    // The viewport shades the shadows between groups per pixel from the frame's vertex terms.
    let frame = prt::Frame::from_posed(&ed.flat, bake, posed, eye);
    let values = values.map_err(|e| (e, frame.vertex_values(&ed.flat)));
    if shadows == prt::Shadows::WithOthers && !ed.view.overlay {
        ed.results.per_pixel = Some(frame);
    }
    values.unwrap_or_else(|(e, cpu)| {
        ed.error(format!("PRT on the GPU: {e}; shading on the CPU"));
        cpu
    })
}

/// Relative error against the reference as a heat map (blue 0 → red ≥ 50 %). Errors are
/// relative to the reference, floored at a tenth of its mean so that shadows (where a small
/// absolute error is a large relative one) do not drown the map.
fn overlay(ed: &Editor) -> VertexValues {
    let Some(reference) = ed.results.reference.mean().filter(|r| r.len() == ed.results.radiance.len()) else {
        return ed.results.radiance.iter().map(|v| vec![Vec3::splat(0.05); v.len()]).collect();
    };
    let count = reference.iter().map(Vec::len).sum::<usize>().max(1) as f32;
    let floor = 0.1 * reference.iter().flatten().map(|r| r.length()).sum::<f32>() / count;
    ed.results
        .radiance
        .iter()
        .zip(&reference)
        .map(|(m, r)| {
            m.iter().zip(r).map(|(m, r)| heat((*m - *r).length() / r.length().max(floor).max(1e-6))).collect()
        })
        .collect()
}

/// A blue–green–red ramp over relative error 0 … 0.5.
pub fn heat(e: f32) -> Vec3 {
    let t = (e / 0.5).clamp(0.0, 1.0);
    if t < 0.5 { Vec3::new(0.0, 2.0 * t, 1.0 - 2.0 * t) } else { Vec3::new(2.0 * t - 1.0, 2.0 - 2.0 * t, 0.0) }
}
