//! The editor's model: the scene (an ECS world), the view, the bakes and the shading results,
//! with the edits the UI (and the tests) make. Nothing here draws; [`super::systems`] advances
//! it once per frame.

use super::bake_job::BakeJob;
use super::document::{Change, Document};
use super::worker::Worker;
use glam::{Quat, Vec3};
use kage_bake_db::Store;
use kage_engine::named::Named;
use kage_engine::scene::VertexValues;
use kage_engine::scene::{
    Camera, FlatScene, InGroup, Material, Name, PolygonLight, PrimitiveId, RigidGroup, Scene, flatten,
};
use kage_engine::shading::Method;
use kage_engine::{bspvt, prt};
use kage_gpu::bspvt::BspvtShader;
use kage_gpu::camera::Orbit;
use kage_gpu::prt::PrtShader;
use kage_gpu::reload::Watcher;
use kage_gpu::{Gpu, Shaders};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

/// The reference refined in the background: the sum of its passes' per-vertex estimates.
#[derive(Default)]
pub struct ReferenceSum {
    /// Sum over the passes (empty before the first).
    pub sum: VertexValues,
    /// Passes summed.
    pub passes: u32,
}

impl ReferenceSum {
    /// Adds one pass.
    pub fn add(&mut self, pass: VertexValues) {
        if self.sum.is_empty() {
            self.sum = pass;
        } else {
            self.sum.iter_mut().flatten().zip(pass.iter().flatten()).for_each(|(s, p)| *s += *p);
        }
        self.passes += 1;
    }

    /// The mean of the passes, or `None` before the first.
    pub fn mean(&self) -> Option<VertexValues> {
        let scale = 1.0 / self.passes.max(1) as f32;
        (!self.sum.is_empty()).then(|| self.sum.iter().map(|v| v.iter().map(|x| *x * scale).collect()).collect())
    }
}

/// What the editor computed for the current snapshot and view: the values it shows, the
/// method's radiance and its parts, the reference's passes, and the terms the viewport draws
/// per pixel.
#[derive(Default)]
pub struct Results {
    /// Per instance and vertex: the displayed radiance (or the error overlay's colours).
    pub values: VertexValues,
    /// Bumped whenever `values` is set: the viewport uploads them once per change.
    pub values_revision: u64,
    /// Per instance and vertex: the method's radiance, plus the cached indirect term when on
    /// (what the overlay compares).
    pub radiance: VertexValues,
    /// Per instance and vertex: the method's direct radiance alone.
    pub direct: VertexValues,
    /// Per instance and vertex: the last indirect term (lit by an earlier direct result while a
    /// new one is gathered).
    pub indirect: VertexValues,
    /// Per instance and vertex: the light of the last complete indirect term (irradiance over
    /// π), which an exported pack carries.
    pub bounce_light: VertexValues,
    /// The progressive reference: running sums and passes.
    pub reference: ReferenceSum,
    /// PRT's per-vertex terms when the viewport shades PRT per pixel (method `prt`, no overlay).
    pub per_pixel: Option<prt::Frame>,
    /// The lobes the viewport draws the polygonal lights with per pixel
    /// ([`Editor::lights_per_pixel`]).
    pub pixel_lights: Option<kage_gpu::viewport::PixelLights>,
    /// The map's sun per vertex, which the per-vertex draw shades per pixel under its depth
    /// map (`baked`, when the lights are not drawn per pixel).
    pub vertex_sun: Option<kage_gpu::viewport::VertexSun>,
}

/// What is selected in the outliner.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Selection {
    /// Nothing.
    None,
    /// A rigid group (its entity).
    Group(hecs::Entity),
    /// A mesh instance (its entity).
    Instance(hecs::Entity),
    /// A polygonal light (its entity).
    Light(hecs::Entity),
    /// The environment.
    Environment,
}

/// One line of the log.
#[derive(Clone, Debug, PartialEq)]
pub struct LogLine {
    /// Seconds since the editor started.
    pub at: f64,
    /// True for errors.
    pub error: bool,
    /// The message.
    pub text: String,
}

/// Timings shown in the statistics panel.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stats {
    /// Seconds between the last two frames.
    pub frame: f64,
    /// Seconds of the last shading.
    pub shading: f64,
    /// Seconds the viewport's last drawn frame took to record, submit and finish on the device.
    pub draw: f64,
    /// Seconds from the last edit to its shaded result.
    pub edit_to_shade: f64,
    /// Seconds from the last shader file change to its rebuilt pipeline.
    pub shader_reload: f64,
    /// What the last finished bake runs did (BSPVT, PRT).
    pub runs: [Option<kage_bake_db::RunStats>; 2],
}

/// What changed since the last frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Dirty {
    /// Transforms must be propagated and the snapshot rebuilt.
    pub pose: bool,
    /// The shading must be redone (view, lights, materials, bakes, method).
    pub shade: bool,
    /// Occluder geometry changed: an incremental BSPVT re-bake is due.
    pub geometry: bool,
    /// The environment changed: PRT's lighting must be projected again.
    pub environment: bool,
    /// The viewport's meshes must be uploaded again.
    pub meshes: bool,
    /// The viewport's per-pixel PRT terms ([`Editor::per_pixel`]) changed.
    pub per_pixel: bool,
}

/// The bakes the shading uses.
#[derive(Default)]
pub struct Bakes {
    /// BSPVT trees (possibly of an earlier geometry while a re-bake runs).
    pub bspvt: Option<std::sync::Arc<bspvt::Bake>>,
    /// True while the trees predate the latest geometry edit.
    pub bspvt_stale: bool,
    /// PRT transfer.
    pub prt: Option<prt::Bake>,
    /// PRT's lighting for the current environment.
    pub lighting: Option<prt::Lighting>,
    /// Frames in which streamed chunks updated the preview.
    pub streamed: usize,
    /// Landed but not yet shown: BSPVT chunks, PRT chunks (previews are spaced while a bake runs).
    pub unshown: [bool; 2],
    /// When the last preview of streamed chunks was shown.
    pub shown_at: Option<Instant>,
    /// What receiver refinement last did (`None`: not refined).
    pub receivers: Option<Refined>,
}

/// What receiver refinement last did, for the bake panel.
#[derive(Clone, Debug)]
pub struct Refined {
    /// Receiver vertices over the scene before and after.
    pub vertices: (usize, usize),
    /// Seconds it took.
    pub seconds: f64,
    /// The lights with no declared reach, as they were placed: refinement follows them there,
    /// so moving one leaves it stale until refined again.
    pub placed: Vec<Vec<Vec3>>,
}

/// The polygons of the lights that receiver refinement follows (those with no declared reach).
pub fn placed_lights(flat: &FlatScene) -> Vec<Vec<Vec3>> {
    flat.lights.iter().filter(|l| l.reach.is_none()).map(|l| l.points.clone()).collect()
}

/// Options `kage edit` starts with.
#[derive(Clone, Debug)]
pub struct Options {
    /// The scene file (`None`: the built-in scene).
    pub scene_path: Option<PathBuf>,
    /// The environment map file, when given.
    pub env_path: Option<PathBuf>,
    /// How the scene file is read when it changes on disk (and meshes the user loads).
    pub import: kage_engine::scene::import::ImportOptions,
    /// Where WGSL is read from (`None`: the embedded shaders, no hot reload).
    pub shader_dir: Option<PathBuf>,
    /// The bake database.
    pub db_path: PathBuf,
    /// BSPVT parameters.
    pub bspvt: bspvt::Settings,
    /// PRT parameters (directions and defaults, when `prt_budget` chooses the rest).
    pub prt: prt::Settings,
    /// Choose PRT's order, window and region count from this relative error budget, kept in
    /// the bake database, as `kage bake` does (so both bake the same artefacts); `None` uses
    /// `prt` as given.
    pub prt_budget: Option<f64>,
    /// Radiance-cache parameters (the indirect term).
    pub cache: kage_engine::cache::Settings,
    /// Refine receivers before each bake, from their source meshes, for the lights and the
    /// environment as placed then (as `kage bake` refines when it loads a scene); `None`: the
    /// source meshes are baked as they are.
    pub refine: Option<kage_engine::receivers::Settings>,
    /// Start baking at once.
    pub bake_on_start: bool,
    /// Start with the indirect term on (the baked look's one bounce).
    pub indirect: bool,
    /// Where polygonal-light shading (BSPVT, LTC) runs.
    pub shade_on: ShadeOn,
    /// Scenes with more receiver vertices than this shade on the CPU in the background (the
    /// last shading stays on screen meanwhile) instead of within the frame.
    pub background_shading: usize,
    /// While a bake runs, previews of what landed are this many times their own cost apart
    /// (see [`PREVIEW_SPACING`]; 0 shows every landing).
    pub preview_spacing: f64,
}

/// The default [`Options::preview_spacing`]: previews take at most a ninth of the machine from
/// the bake, and a re-bake shorter than eight previews shows only its result. On a GPU that is
/// tens of previews a second; on a CPU device, whose preview of the built-in scene takes 0.4 s
/// of both cores, one every four seconds.
pub const PREVIEW_SPACING: f64 = 8.0;

/// Where the editor shades polygonal lights. PRT always shades on the GPU.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShadeOn {
    /// The GPU, unless the adapter is a CPU emulation (lavapipe), where the native CPU path
    /// is faster (measured on the teapot: 5 ms on the CPU against 365 ms on lavapipe per re-shade).
    Auto,
    /// The GPU: the viewport draws the lights per pixel ([`Editor::lights_per_pixel`]), or the
    /// WGSL compute shaders shade them per vertex.
    Gpu,
    /// The engine's CPU path (rayon), per vertex.
    Cpu,
}

impl Named for ShadeOn {
    const ALL: &'static [ShadeOn] = &[ShadeOn::Auto, ShadeOn::Gpu, ShadeOn::Cpu];

    fn name(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::Gpu => "gpu",
            Self::Cpu => "cpu",
        }
    }

    fn about(self) -> &'static str {
        match self {
            Self::Auto => "the GPU unless it is a CPU emulation (lavapipe), where the CPU is faster",
            Self::Gpu => "the GPU: per pixel in the viewport",
            Self::Cpu => "the CPU, per vertex",
        }
    }
}

/// How the editor shows its scene: none of it is the scene's, none of it is saved.
pub struct ViewState {
    /// The viewport camera.
    pub orbit: Orbit,
    /// The displayed method.
    pub method: Method,
    /// The gizmo's mode, axes and snapping.
    pub gizmo: super::gizmo::Settings,
    /// What the pointer hovers in the viewport.
    pub hover: Selection,
    /// Show the error against the progressive reference as a heat map.
    pub overlay: bool,
    /// Display exposure in stops.
    pub exposure: f32,
    /// Meter the exposure from the next lit result (set when a scene opens).
    pub metering: bool,
    /// The viewport's width over its height (the view exposure is metered through).
    pub aspect: f32,
}

/// What the editor computes with; none of it is shown or saved.
pub struct Backend {
    /// The bake database.
    pub store: Option<Arc<Store>>,
    /// The running bake, if any.
    pub job: Option<BakeJob>,
    pub(super) gpu: Gpu,
    pub(super) shaders: Shaders,
    pub(super) bspvt_gpu: Option<BspvtShader>,
    pub(super) prt_gpu: Option<PrtShader>,
    /// What shading keeps between frames.
    pub(super) memo: Memo,
    pub(super) watcher: Option<Watcher>,
    /// Computations running off the UI thread.
    pub(super) workers: Workers,
    pub(super) wake: Arc<dyn Fn() + Send + Sync>,
}

/// The editor's state.
pub struct Editor {
    /// The scene being edited, its selection, history and saved baseline.
    pub doc: Document,
    /// How the scene is shown: the orbit, the method, the exposure, the overlay, the gizmo.
    pub view: ViewState,
    /// Its current snapshot.
    pub flat: FlatScene,
    /// How it was opened.
    pub options: Options,
    /// The scene's own cameras.
    pub cameras: Vec<Camera>,
    /// The scene file changed on disk while edits were unsaved: the UI asks what to do.
    pub outside_change: bool,
    /// A drag is in progress (a pointer button is down): BSPVT re-bakes wait for its end
    /// rather than restarting at every frame of it.
    pub dragging: bool,
    /// What it computed: the values shown, the method's radiance and its parts.
    pub results: Results,
    /// Add one bounce of indirect light from the HSH radiance cache.
    pub indirect: bool,
    /// Everything that happened, errors included.
    pub log: Vec<LogLine>,
    /// Timings.
    pub stats: Stats,
    /// The bakes in use.
    pub bakes: Bakes,
    /// The last shader error (cleared by a good reload).
    pub shader_error: Option<kage_gpu::ShaderError>,
    /// Bumped whenever the viewport must rebuild its pipeline.
    pub shader_generation: u64,
    /// What changed since the last frame.
    pub dirty: Dirty,
    /// What the editor computes with: the GPU, the store, the running bake, the workers.
    pub backend: Backend,
    pub(super) started: Instant,
    pub(super) edited_at: Option<Instant>,
}

/// What shading keeps between frames, so that a frame whose inputs did not change costs less.
#[derive(Default)]
pub(super) struct Memo {
    /// PRT's silhouettes of groups that did not move.
    pub(super) silhouettes: prt::SilhouetteMemo,
    /// The environment prefiltered for the specular term (method `baked`), kept while its map is.
    pub(super) prefiltered: Option<prt::prefilter::Prefiltered>,
    /// The environment's part of the look per vertex (method `baked`), kept while a light moves.
    pub(super) environment: kage_engine::shading::baked::EnvironmentMemo,
    /// Picking's BVH of the current snapshot, built on the first pick after it changed.
    pub(super) picker: Option<super::pick::Picker>,
    /// Which vertices lie inside geometry, kept while the instances stay put.
    pub(super) inside: kage_engine::bspvt::pixel::Inside,
}

/// The editor's background computations (each streams results the systems take in).
#[derive(Default)]
pub(super) struct Workers {
    /// The progressive reference.
    pub(super) reference: Option<Worker<VertexValues>>,
    /// Exact visibility (`ltc-exact-vis`).
    pub(super) exact: Option<Worker<VertexValues>>,
    /// The direct light of a large scene, shaded in the background, and when it started.
    pub(super) shading: Option<(Worker<VertexValues>, std::time::Instant)>,
    /// The indirect term.
    pub(super) indirect: Option<Worker<super::indirect::Indirect>>,
    /// The last indirect cache with what it was lit by, for the next refresh.
    pub(super) indirect_base: Option<Box<super::indirect::IndirectBase>>,
    /// Bumped whenever `direct` changes; the generation the indirect term was started from.
    pub(super) generations: (u64, u64),
}

impl Editor {
    /// Opens `scene` on `gpu`; `wake` asks the UI for a repaint (from any thread).
    pub fn new(scene: Scene, options: Options, gpu: Gpu, wake: Arc<dyn Fn() + Send + Sync>) -> Self {
        let flat = flatten(&scene);
        let cameras = cameras(&scene);
        let orbit = initial_orbit(&flat, cameras.first());
        let shaders = options.shader_dir.clone().map_or_else(Shaders::embedded, Shaders::from_dir);
        let mut ed = Self {
            doc: Document::new(scene),
            flat,
            view: ViewState {
                orbit,
                method: Method::Baked,
                gizmo: Default::default(),
                hover: Selection::None,
                overlay: false,
                exposure: 0.0,
                metering: true,
                aspect: 16.0 / 9.0,
            },
            cameras,
            outside_change: false,
            dragging: false,
            results: Results::default(),
            indirect: options.indirect,
            log: Vec::new(),
            stats: Stats::default(),
            bakes: Bakes::default(),
            shader_error: None,
            shader_generation: 0,
            dirty: Dirty { shade: true, environment: true, meshes: true, ..Dirty::default() },
            backend: Backend {
                gpu,
                shaders,
                store: None,
                job: None,
                bspvt_gpu: None,
                prt_gpu: None,
                memo: Memo::default(),
                watcher: None,
                workers: Workers::default(),
                wake,
            },
            started: Instant::now(),
            edited_at: None,
            options,
        };
        let where_ = if ed.polygonal_on_gpu() { "on the GPU" } else { "on the CPU" };
        let lights = if ed.lights_per_pixel() { "per pixel (their vertex lobes on the CPU)" } else { where_ };
        ed.info(format!("{}: GPU {}; polygonal lights shade {lights}", ed.doc.scene.source, ed.backend.gpu.describe()));
        if let Some(why) = ed.flat.unlit() {
            ed.error(format!(
                "{}: {why}; Add > Quad light adds one (or open it with --env MAP.hdr)",
                ed.doc.scene.source
            ));
        }
        ed.open_store();
        ed.choose_prt();
        ed.start_watching();
        if ed.options.bake_on_start {
            ed.dirty.geometry = true;
        }
        ed
    }

    fn open_store(&mut self) {
        let path = self.options.db_path.clone();
        if let Some(dir) = path.parent() {
            let _ = std::fs::create_dir_all(dir);
        }
        match Store::open(&path) {
            Ok(s) => self.backend.store = Some(Arc::new(s)),
            Err(e) => self.error(format!("bake database: {e}")),
        }
    }

    /// PRT's parameters from the error budget, as `kage bake` chooses them (from the database
    /// when it holds the choice; measured and stored otherwise).
    fn choose_prt(&mut self) {
        let (Some(budget), Some(store)) = (self.options.prt_budget, self.backend.store.clone()) else {
            return;
        };
        let mut notes = Vec::new();
        let chosen = kage_bake_db::prt_budget::choose(
            &store,
            &self.doc.scene,
            &self.flat,
            budget,
            &self.options.prt,
            &mut |n| notes.push(n),
        );
        notes.into_iter().for_each(|n| self.info(format!("PRT: {n}")));
        match chosen {
            Ok(s) => self.options.prt = s,
            Err(e) => self.error(format!("PRT parameters: {e}")),
        }
    }

    pub(super) fn start_watching(&mut self) {
        let wake = self.backend.wake.clone();
        let o = &self.options;
        if o.shader_dir.is_none() && o.scene_path.is_none() && o.env_path.is_none() {
            return;
        }
        match Watcher::new(o.shader_dir.as_deref(), o.scene_path.as_deref(), o.env_path.as_deref(), move || wake()) {
            Ok(w) => self.backend.watcher = Some(w),
            Err(e) => self.error(format!("{e:#}")),
        }
    }

    /// Logs a message.
    pub fn info(&mut self, text: String) {
        self.log_line(false, text);
    }

    /// Logs an error.
    pub fn error(&mut self, text: String) {
        self.log_line(true, text);
    }

    /// Adds a line to the log panel, and to stderr: a terminal or a script that started the
    /// editor sees what it did, and when (`tools/editor_drag.sh` reads a drag's re-bake there).
    fn log_line(&mut self, error: bool, text: String) {
        let at = self.started.elapsed().as_secs_f64();
        eprintln!("{at:8.2} s  {}{text}", if error { "error: " } else { "" });
        self.log.push(LogLine { at, error, text });
    }

    /// The GPU the editor shades on.
    pub fn gpu(&self) -> &Gpu {
        &self.backend.gpu
    }

    /// How often the window repaints while work runs in the background (a bake's progress and
    /// streamed chunks, a shading, a gather): ten times a second on a GPU, once a second on a
    /// CPU device, where a frame of the 1280×800 window takes about 0.15 s of both cores and at
    /// ten a second took half the machine from the bake.
    pub fn progress_interval(&self) -> std::time::Duration {
        let cpu = self.backend.gpu.info.device_type == wgpu::DeviceType::Cpu;
        std::time::Duration::from_millis(if cpu { 1000 } else { 100 })
    }

    /// True when this frame left work for the next one's systems (an edit's pose, its shading
    /// unless one runs in the background, the re-bake after a drag): the next frame comes at
    /// once, not at the next [`Self::progress_interval`].
    pub fn due_next_frame(&self) -> bool {
        let shade = self.dirty.shade && !super::systems::shading(self);
        self.dirty.pose || shade || (self.dirty.geometry && !self.dragging)
    }

    /// True when polygonal lights shade on the GPU.
    pub fn polygonal_on_gpu(&self) -> bool {
        match self.options.shade_on {
            ShadeOn::Gpu => true,
            ShadeOn::Cpu => false,
            ShadeOn::Auto => self.backend.gpu.info.device_type != wgpu::DeviceType::Cpu,
        }
    }

    /// True when the viewport draws the polygonal lights (and in `baked`, the environment's
    /// specular term) per pixel, as `kage render` does: when
    /// they shade on the GPU ([`ShadeOn`]: a CPU emulation draws an 800×600 view per pixel in
    /// 120 ms, per vertex in 7 ms), for the methods that shade them with LTC (`baked`, `bspvt`,
    /// `ltc-unshadowed`), without the overlay, with lights the shader takes (untextured, at
    /// most 8 corners), and for scenes whose lobes are shaded within the frame (at most
    /// `background_shading` vertices).
    pub fn lights_per_pixel(&self) -> bool {
        let vertices: usize = (0..self.flat.instances.len()).map(|k| self.flat.vertex_count(k)).sum();
        self.polygonal_on_gpu()
            && matches!(self.view.method, Method::Baked | Method::Bspvt | Method::LtcUnshadowed)
            && !self.view.overlay
            && self.flat.lights.iter().all(|l| kage_gpu::bspvt::gpu_light(l).is_ok())
            && vertices <= self.options.background_shading
    }

    /// Where shaders come from.
    pub fn shaders(&self) -> &Shaders {
        &self.backend.shaders
    }

    pub(super) fn edited(&mut self) {
        self.edited_at = Some(Instant::now());
        self.dirty.shade = true;
    }

    /// Follows up an edit of the document: the snapshot, the meshes and bakes for geometry,
    /// PRT's lighting for the environment, the shading and the reference.
    pub(super) fn apply(&mut self, change: Change) {
        if change == Change::NONE {
            return;
        }
        self.dirty.pose = true;
        if change.geometry {
            self.dirty.geometry = true;
            self.dirty.meshes = true;
        }
        self.dirty.environment |= change.environment;
        self.restart_reference();
        self.edited();
    }

    /// Undoes the newest step; false when there is none.
    pub fn undo(&mut self) -> bool {
        self.doc.undo().map(|c| self.apply(c)).is_some()
    }

    /// Redoes the newest undone step; false when there is none.
    pub fn redo(&mut self) -> bool {
        self.doc.redo().map(|c| self.apply(c)).is_some()
    }

    /// True when the scene differs from what its file holds (edits not saved).
    pub fn unsaved(&self) -> bool {
        self.doc.unsaved()
    }

    /// Moves a polygonal light by `offset` (world units) and turns it by `rotation` about its
    /// centre ([`Document::move_light`]); a refusal is logged.
    pub fn move_light(&mut self, light: hecs::Entity, offset: Vec3, rotation: Quat) {
        match self.doc.move_light(light, offset, rotation) {
            Ok(change) => self.apply(change),
            Err(e) => self.error(e),
        }
    }

    /// Scales a light's polygon and sets its radiance ([`Document::set_light`]); a refused
    /// resize is logged.
    pub fn set_light(&mut self, light: hecs::Entity, radiance: Vec3, factor: f32) {
        let (change, refused) = self.doc.set_light(light, radiance, factor);
        if let Some(e) = refused {
            self.error(e);
        }
        self.apply(change);
    }

    /// Moves and turns a rigid group about its origin ([`Document::move_group`]).
    pub fn move_group(&mut self, group: hecs::Entity, offset: Vec3, rotation: Quat) {
        let change = self.doc.move_group(group, offset, rotation);
        self.apply(change);
    }

    /// Scales a rigid group uniformly about its origin ([`Document::scale_group`]).
    pub fn scale_group(&mut self, group: hecs::Entity, factor: f32) {
        let change = self.doc.scale_group(group, factor);
        self.apply(change);
    }

    /// Sets an instance's material ([`Document::set_material`]).
    pub fn set_material(&mut self, instance: hecs::Entity, m: Material) {
        let change = self.doc.set_material(instance, m);
        self.apply(change);
    }

    /// Sets the environment's intensity and rotation ([`Document::set_environment`]).
    pub fn set_environment(&mut self, intensity: f32, rotation: f32) {
        let change = self.doc.set_environment(intensity, rotation);
        self.apply(change);
    }

    /// Replaces an instance's mesh ([`Document::replace_mesh`]).
    pub fn replace_mesh(&mut self, instance: hecs::Entity, mesh: kage_engine::scene::Mesh) {
        let change = self.doc.replace_mesh(instance, mesh);
        self.apply(change);
    }

    /// Switches the displayed method (the reference restarts: each method is compared with the
    /// reference of its own lights).
    pub fn set_method(&mut self, m: Method) {
        if m != self.view.method {
            self.view.method = m;
            if let Some(why) = self.flat.black_under_prt().filter(|_| matches!(m, Method::Prt | Method::PrtSelf)) {
                self.info(format!("{}: {why}; `baked` shows their reflections", m.name()));
            }
            self.restart_reference();
            self.edited();
        }
    }

    /// Turns the cached indirect term on or off (the reference follows: one bounce or none).
    pub fn set_indirect(&mut self, on: bool) {
        if on != self.indirect {
            self.indirect = on;
            self.restart_reference();
            self.edited();
        }
    }

    /// Turns the error overlay on or off.
    pub fn set_overlay(&mut self, on: bool) {
        if on != self.view.overlay {
            self.view.overlay = on;
            self.edited();
        }
    }

    /// Moves the viewport camera (the view-dependent shading follows).
    pub fn set_orbit(&mut self, orbit: Orbit) {
        if orbit != self.view.orbit {
            self.view.orbit = orbit;
            self.restart_reference();
            self.edited();
        }
    }

    /// Looks through scene camera `k`.
    pub fn use_camera(&mut self, k: usize) {
        if let Some(c) = self.cameras.get(k) {
            let distance = self.view.orbit.target.distance(self.view.orbit.eye()).max(1.0);
            self.set_orbit(Orbit::from_camera(c, distance));
        }
    }

    /// True when a light that refinement follows (no declared reach) moved since the receivers
    /// were refined: its shadows are as fine as the refinement where they now fall.
    pub fn refinement_stale(&self) -> bool {
        self.bakes.receivers.as_ref().is_some_and(|r| r.placed != placed_lights(&self.flat))
    }

    /// Refines the receivers again for the lights as they are now, and bakes what that changed.
    pub fn refine_again(&mut self) {
        self.dirty.geometry = true;
    }

    /// Stops a running bake after its chunks in flight (finished batches stay in the database).
    pub fn cancel_bake(&mut self) {
        if let Some(job) = &self.backend.job {
            job.cancel();
            self.info("bake: cancelling after the chunks in flight".into());
        }
    }

    /// Re-plans and bakes what the current scene misses.
    pub fn bake_now(&mut self) {
        self.dirty.geometry = true;
    }

    /// The progressive reference restarts from zero (its scene or view changed).
    pub(super) fn restart_reference(&mut self) {
        self.backend.workers.reference = None;
        self.backend.workers.exact = None;
        self.results.reference = ReferenceSum::default();
    }

    /// The outliner's rows: (entity, label, kind) for groups, their instances and lights.
    pub fn outline(&self) -> Vec<(Selection, String, usize)> {
        let name = |e: hecs::Entity| self.doc.scene.world.get::<&Name>(e).map(|n| n.0.clone()).unwrap_or_default();
        let mut groups: Vec<(u32, hecs::Entity)> =
            self.doc.scene.world.query::<(hecs::Entity, &RigidGroup)>().iter().map(|(e, g)| (g.index, e)).collect();
        groups.sort();
        let mut rows = Vec::new();
        for (index, g) in groups {
            rows.push((Selection::Group(g), format!("group {index}: {}", name(g)), 0));
            let mut members: Vec<(u32, Selection, String)> = Vec::new();
            for (e, member, id) in self.doc.scene.world.query::<(hecs::Entity, &InGroup, &PrimitiveId)>().iter() {
                if member.group == g {
                    members.push((id.node, Selection::Instance(e), format!("mesh {}: {}", id.mesh, name(e))));
                }
            }
            for (e, member, _) in self.doc.scene.world.query::<(hecs::Entity, &InGroup, &PolygonLight)>().iter() {
                if member.group == g {
                    members.push((u32::MAX, Selection::Light(e), format!("light {}", name(g))));
                }
            }
            members.sort_by_key(|m| m.0);
            rows.extend(members.into_iter().map(|(_, s, l)| (s, l, 1)));
        }
        if self.flat.environment.is_some() {
            rows.push((Selection::Environment, "environment".into(), 0));
        }
        rows
    }
}

fn cameras(scene: &Scene) -> Vec<Camera> {
    let mut cams: Vec<(u32, Camera)> =
        scene.world.query::<(&Camera, &kage_engine::scene::NodeId)>().iter().map(|(c, n)| (n.0, c.clone())).collect();
    cams.sort_by_key(|(n, _)| *n);
    cams.into_iter().map(|(_, c)| c).collect()
}

/// The first scene camera, or a view of the whole scene from the front and above.
fn initial_orbit(flat: &FlatScene, camera: Option<&Camera>) -> Orbit {
    let (centre, _) = flat.bounding_sphere();
    let c = camera.cloned().unwrap_or_else(|| flat.framing_camera());
    Orbit::from_camera(&c, c.eye().distance(centre).max(1e-3))
}
