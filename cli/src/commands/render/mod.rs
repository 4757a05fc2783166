//! `kage render`: images and per-vertex radiance with a chosen method (by default the complete
//! baked look, [`baked`]).

pub(crate) mod baked;

use crate::db_args::DbArgs;
use crate::exposure::Exposure;
use crate::named_arg::named;
use crate::progress::{bar, with_bar};
use crate::prt_args::PrtArgs;
use crate::scene_args::SceneArgs;
use anyhow::{Context, Result, bail};
use glam::Vec3;
use kage_bake_db::pack::Contents;
use kage_engine::cache::record::{Glossy, GlossyDirect, GradientForm, Source};
use kage_engine::cache::{Blend, Bounces};
use kage_engine::material::detail::Detail;
use kage_engine::output::{ImageFormat, VertexRow, write_image, write_vertex_csv};
use kage_engine::reference::{Estimate, Renderer, Settings};
use kage_engine::scene::VertexValues;
use kage_engine::scene::{Camera, Scene};
use kage_engine::shading::Method;
use kage_engine::{bspvt, prt, raster};
use std::path::PathBuf;
use std::time::Instant;

/// Where one bounce of indirect light comes from.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Indirect {
    /// Direct light only.
    None,
    /// The HSH radiance cache (records with gradients, interpolated).
    Cache,
    /// Brute-force gathering at every vertex (--cache-rays rays), the cache's baseline.
    Gather,
    /// The reference integrator's one-bounce term (--spp paths per vertex).
    Reference,
    /// The bounces a pack carries (--pack), frozen where its lights and groups were baked: its
    /// light per vertex times the diffuse albedo, as bevy_kage shades them.
    Pack,
}

/// Arguments of `kage render`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    scene: SceneArgs,
    /// Shading method.
    #[arg(long, default_value = "baked", value_parser = named::<Method>())]
    method: Method,
    /// Samples per pixel / per vertex.
    #[arg(long, default_value_t = 64)]
    spp: u32,
    /// Image size as WxH.
    #[arg(long, default_value = "640x360", value_parser = parse_size)]
    size: (usize, usize),
    /// Output image: .exr (linear radiance) or .png (tonemapped sRGB). Default render.png
    /// unless only --vertices-out is given.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Per-vertex radiance toward the camera as CSV (node,mesh,primitive,vertex,x,y,z,r,g,b).
    #[arg(long)]
    vertices_out: Option<PathBuf>,
    /// Camera position x,y,z (with --target; overrides the scene's camera).
    #[arg(long, value_parser = parse_vec3, requires = "target")]
    eye: Option<Vec3>,
    /// Point the camera looks at, x,y,z.
    #[arg(long, value_parser = parse_vec3, requires = "eye")]
    target: Option<Vec3>,
    /// Vertical field of view in degrees.
    #[arg(long)]
    fov: Option<f32>,
    /// Seed of the random streams.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Indirect bounces: the reference's (default 0, direct lighting only), or the radiance
    /// cache's and `--indirect reference`'s (default: the cache chooses as many as the error
    /// budget needs, 2 % unless --error-budget says otherwise; 0 = direct light only)
    #[arg(long)]
    bounces: Option<u32>,
    /// PNG exposure: stops (radiance × 2^EV, then clamped), or `auto` to meter the image.
    #[arg(long, default_value = "auto", allow_negative_numbers = true)]
    exposure: Exposure,
    /// BSPVT cube-face resolution (texels per side).
    #[arg(long, default_value_t = 64)]
    face_res: usize,
    /// BSPVT split threshold ε (cluster error in texels).
    #[arg(long, default_value_t = 2.0)]
    epsilon: f64,
    /// Choose parameters (and report why) from a relative error budget, e.g. 0.01, measured
    /// by a pilot: BSPVT's face resolution and ε (override --face-res and --epsilon); PRT's SH order, window and
    /// region count (PRT chooses with 0.02 when no budget and no PRT parameter is given).
    #[arg(long)]
    error_budget: Option<f64>,
    #[command(flatten)]
    prt: PrtArgs,
    #[command(flatten)]
    db: DbArgs,
    /// One bounce of indirect light added to a per-vertex method (its per-vertex direct result
    /// lights Lambertian hits; glossy hits reflect direct light toward the gathering point).
    /// Default: cache for baked, none for the others.
    #[arg(long, value_enum)]
    indirect: Option<Indirect>,
    /// HSH order of the radiance cache.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=8))]
    hsh_order: u32,
    /// Rays per cache record (and per vertex for --indirect gather).
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..=65536))]
    cache_rays: u32,
    /// Cache accuracy a (records serve where their weight exceeds 1/a; smaller = denser).
    #[arg(long, default_value_t = 0.3)]
    cache_accuracy: f32,
    /// How lookups blend the records.
    #[arg(long, default_value = "ward", value_parser = named::<Blend>())]
    cache_blend: Blend,
    /// A cache record whose irradiance's standard error exceeds this share of the direct
    /// light's RMS over the receivers gathers again with 4× the rays (`inf`: never).
    #[arg(long, default_value_t = kage_engine::cache::DEFAULT_NOISE)]
    cache_noise: f32,
    /// Interpolate without the records' translational gradients.
    #[arg(long)]
    no_gradients: bool,
    /// How the records' gradients are computed: analytic (H9–H18) or numerical (H7–H8).
    #[arg(long, default_value = "analytic", value_parser = named::<GradientForm>())]
    gradient: GradientForm,
    /// Shade from an asset pack written by `kage export` (its scene and bakes) instead of a scene.
    #[arg(long, conflicts_with = "scene")]
    pack: Option<PathBuf>,
    /// Shade on the GPU: bspvt, ltc-unshadowed, prt and prt-self with the WGSL compute shaders
    /// per vertex (images interpolate the vertices, PRT's other-group shadows included); baked
    /// drawn as the editor's viewport draws it (lights and reflections per pixel).
    #[arg(long)]
    gpu: bool,
    /// Drop the environment light (the per-vertex polygonal-light methods never include it;
    /// use this to compare the reference with them).
    #[arg(long)]
    no_env: bool,
}

impl Args {
    /// Where the bounce comes from: `--indirect`, else the method's default.
    fn indirect(&self) -> Indirect {
        match (self.indirect, self.bounces) {
            (_, Some(0)) => Indirect::None,
            (Some(i), _) => i,
            (None, _) if self.method == Method::Baked => Indirect::Cache,
            (None, _) => Indirect::None,
        }
    }

    /// The cache's bounces: `--bounces`, else as many as the error budget needs.
    fn cache_bounces(&self) -> Bounces {
        match self.bounces {
            Some(n) => Bounces::Fixed(n as usize),
            None => Bounces::Budget(self.error_budget.unwrap_or(kage_engine::cache::bounces::DEFAULT_BUDGET)),
        }
    }
}

/// Parses `--method` from the engine's method names, listing each with its description.
pub(crate) fn parse_size(s: &str) -> Result<(usize, usize), String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or("expected WxH, e.g. 640x360")?;
    let p =
        |v: &str| v.trim().parse::<usize>().ok().filter(|&n| (1..=16384).contains(&n)).ok_or(format!("bad size '{s}'"));
    Ok((p(w)?, p(h)?))
}

fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let v: Vec<f32> =
        s.split(',').map(|c| c.trim().parse::<f32>()).collect::<Result<_, _>>().map_err(|e| format!("'{s}': {e}"))?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(Vec3::new(x, y, z)),
        _ => Err(format!("expected three finite numbers x,y,z, got '{s}'")),
    }
}

/// Renders what was asked for.
pub fn run(args: &Args) -> Result<()> {
    if args.spp == 0 {
        bail!("--spp must be at least 1");
    }
    if let Err(e) = (bspvt::Settings { res: args.face_res, epsilon: args.epsilon }).check() {
        bail!("--face-res/--epsilon: {e}");
    }
    if args.error_budget.is_some_and(|b| !(b > 0.0 && b < 1.0)) {
        bail!("--error-budget is a relative error in (0, 1), e.g. 0.01");
    }
    let (mut scene, pack) = match &args.pack {
        Some(path) => {
            args.scene.check_for_pack()?;
            let (mut scene, mut contents) = kage_bake_db::pack::read(path)?;
            contents.warnings.iter().for_each(|w| eprintln!("warning: {w}"));
            args.scene.pose(&mut scene)?;
            // The pack's lighting is the environment as baked; turned or scaled, it is
            // projected again from the map the pack holds (its sun split off anew).
            if let Some((_, lighting, settings)) = contents.prt.as_mut().filter(|_| args.scene.poses_environment()) {
                *lighting = prt::Lighting::new(&scene, settings).context("the pack's PRT data has no environment")?;
            }
            (scene, Some(contents))
        }
        None => {
            // The refinement is kept in the database the bakes use; it is closed again after
            // loading (the bake opens it once more).
            let store = match args.method {
                Method::Baked => Some(args.db.open(&args.scene)?),
                _ => args.db.open_if_used(&args.scene)?,
            };
            (args.scene.load_kept(store.as_ref())?, None)
        }
    };
    if args.no_env {
        scene.clear_environment();
    }
    let renderer = Renderer::new(&scene);
    if let Some(why) = renderer.flat.unlit() {
        eprintln!("warning: {}: {why}; `--env MAP.hdr` lights it with an environment map", scene.source);
    }
    if let Some(why) = renderer.flat.black_under_prt().filter(|_| matches!(args.method, Method::Prt | Method::PrtSelf))
    {
        eprintln!("note: {}: {why}; `--method baked` shows their reflections", scene.source);
    }
    let camera = camera(args, scene.first_camera(), &renderer.flat)?;
    let output = args.output.clone().or_else(|| args.vertices_out.is_none().then(|| PathBuf::from("render.png")));
    if let Some(path) = &output {
        ImageFormat::of(path)?;
    }
    if args.gpu && !args.method.on_gpu() {
        bail!("--gpu shades bspvt, ltc-unshadowed, prt, prt-self and baked; {} runs on the CPU only", args.method);
    }
    if args.method == Method::Reference && args.indirect.is_some_and(|i| i != Indirect::None) {
        bail!("--indirect is for the per-vertex methods; the reference takes --bounces N");
    }
    if args.indirect() == Indirect::Pack && pack.is_none() {
        bail!("--indirect pack reads the bounces a pack carries: give --pack PACK.glb");
    }
    let job = Job {
        args,
        scene: &scene,
        renderer: &renderer,
        camera: &camera,
        want_image: output.is_some(),
        pack: pack.as_ref(),
    };
    let Outputs { mut image, mut vertices, glossy } = match args.method {
        Method::Reference => reference(&job)?,
        Method::Baked => baked::run(&job)?,
        Method::Prt | Method::PrtSelf => prt(&job)?,
        m => per_vertex(&job, m)?,
    };
    let later = args.method != Method::Baked && args.indirect() != Indirect::None;
    if let Some(direct) = vertices.as_mut().filter(|_| later) {
        let extra = glossy.with(&renderer.flat, |g| indirect(&job, direct, g))?;
        if let (Some(pixels), Some(more)) = (image.as_mut(), job.vertex_image(&extra)) {
            pixels.iter_mut().zip(more).for_each(|(p, m)| *p += m);
        }
        direct.iter_mut().flatten().zip(extra.iter().flatten()).for_each(|(d, e)| *d += *e);
    }
    if let (Some(path), Some(pixels)) = (&output, image) {
        let surfaces = || raster::surface_pixels(&renderer, &camera, args.size.0, args.size.1);
        let stops =
            if ImageFormat::of(path)? == ImageFormat::Png { args.exposure.image_stops(&pixels, surfaces) } else { 0.0 };
        write_image(path, args.size.0, args.size.1, &pixels, stops)?;
        crate::emit(&format!("wrote {}\n", path.display()));
    }
    if let (Some(path), Some(values)) = (&args.vertices_out, vertices) {
        let rows = vertex_rows(&renderer, &values);
        write_vertex_csv(path, &rows).with_context(|| "writing per-vertex results")?;
        crate::emit(&format!("wrote {} ({} vertices)\n", path.display(), rows.len()));
    }
    Ok(())
}

/// What one render works on: the command line, the scene with its snapshot and camera, whether
/// an image is wanted, and the pack it reads its bakes from (if any).
struct Job<'a> {
    args: &'a Args,
    scene: &'a Scene,
    renderer: &'a Renderer,
    camera: &'a Camera,
    want_image: bool,
    pack: Option<&'a Contents>,
}

impl Job<'_> {
    /// The image of per-vertex `values` (at most 16 samples per pixel) with the materials'
    /// detail per sample ([`Detail`]), when one is wanted.
    fn vertex_image(&self, values: &[Vec<Vec3>]) -> Option<Vec<Vec3>> {
        let (w, h) = self.args.size;
        self.want_image.then(|| {
            let detail = Detail::new(&self.renderer.flat, self.camera.eye());
            let shade = |hit: &raster::SurfaceHit| hit.interpolate(&values[hit.instance]) * detail.scale(hit);
            raster::shade_image(self.renderer, self.camera, w, h, self.args.spp.min(16), &shade)
        })
    }
}

/// What a method produced: the image, the per-vertex values, and how the indirect term's
/// glossy hits are lit consistently with this direct term.
struct Outputs {
    image: Option<Vec<Vec3>>,
    vertices: Option<VertexValues>,
    glossy: GlossyDirect,
}

fn reference(job: &Job) -> Result<Outputs> {
    let Job { args, renderer, camera, want_image, .. } = *job;
    let settings = Settings { spp: args.spp, seed: args.seed, max_bounces: args.bounces.unwrap_or(0), min_bounces: 0 };
    let mut image = None;
    if want_image {
        let (w, h) = args.size;
        let pb = bar(h as u64, "pixels");
        let start = Instant::now();
        let est = renderer.render_image(camera, w, h, &settings, &|rows| pb.set_position(rows as u64));
        pb.finish_and_clear();
        report("image", &est, start);
        image = Some(est.iter().map(|e| e.mean).collect());
    }
    let mut vertices = None;
    if args.vertices_out.is_some() {
        let pb = bar(renderer.vertex_count() as u64, "vertices");
        let start = Instant::now();
        let per_instance = renderer.render_vertices(camera.eye(), &settings, &|n| pb.set_position(n as u64));
        pb.finish_and_clear();
        let all: Vec<Estimate> = per_instance.iter().flatten().copied().collect();
        report("vertices", &all, start);
        vertices = Some(per_instance.iter().map(|v| v.iter().map(|e| e.mean).collect()).collect());
    }
    Ok(Outputs { image, vertices, glossy: GlossyDirect::Reference })
}

fn per_vertex(job: &Job, method: Method) -> Result<Outputs> {
    let Job { args, scene, renderer, camera, pack, .. } = *job;
    let mut settings = bspvt::Settings { res: args.face_res, epsilon: args.epsilon };
    if let (Method::Bspvt, Some(budget)) = (method, args.error_budget) {
        let (chosen, why) = bspvt::budget::choose(&renderer.flat, budget, camera.eye());
        crate::emit(&format!("plan: {why}\n"));
        settings = chosen;
    }
    let store = if method == Method::Bspvt && pack.is_none() { args.db.open_if_used(&args.scene)? } else { None };
    let bake = if let Some(pack) = pack.filter(|_| method == Method::Bspvt) {
        let b = pack.bspvt.clone().context("the pack has no BSPVT data (its scene has no polygonal light)")?;
        settings = b.settings;
        Some(b)
    } else if let Some(store) = &store {
        from_database(store, scene, &renderer.flat, Some(settings), None)?.bspvt
    } else {
        (method == Method::Bspvt).then(|| in_memory_bspvt(renderer, &settings))
    };
    // No bake means no polygonal light (a database plans no BSPVT then): nothing to shadow.
    let kind = method.polygonal_shadows(bake.as_ref(), settings.res).context("not a polygonal-light method")?;
    // The GGX albedo table is built on first use: not part of shading a frame.
    let _ = kage_engine::math::ggx::directional_albedo(1.0, 0.5, Vec3::ONE, Vec3::ONE);
    let start = Instant::now();
    let values = if args.gpu {
        let gpu = gpu_device()?;
        let shader = kage_gpu::bspvt::BspvtShader::new(&gpu, &kage_gpu::Shaders::embedded(), bake.as_ref())?;
        kage_gpu::bspvt::shade_vertices(&gpu, &shader, &renderer.flat, kind, camera.eye())?
    } else {
        bspvt::shade_vertices(&renderer.flat, kind, camera.eye())
    };
    if let bspvt::Shadows::Trees(bake) = kind {
        warn_unseen(scene, &renderer.flat, bake);
    }
    let evals = renderer.vertex_count() * renderer.flat.lights.len();
    let secs = start.elapsed().as_secs_f64();
    crate::emit(&format!(
        "shade: {evals} vertex–light evaluations in {secs:.3} s ({:.2} M/s)\n",
        evals as f64 / secs / 1e6
    ));
    let image = job.vertex_image(&values);
    let glossy = method.glossy_direct(bake.map(Into::into));
    Ok(Outputs { image, vertices: Some(values), glossy })
}

/// Warns about the lights that `bake`'s trees let almost no receiver see
/// ([`bspvt::unseen_lights`]), naming them and the likely cause, so that a dark image is not
/// taken for a lit one metered up.
pub(crate) fn warn_unseen(scene: &Scene, flat: &kage_engine::scene::FlatScene, bake: &bspvt::Bake) {
    if let Some(warning) = bspvt::unseen_warning(scene, flat, bake) {
        eprintln!("warning: {warning}");
    }
}

/// Bakes BSPVT without a database, printing the bake statistics.
fn in_memory_bspvt(renderer: &Renderer, settings: &bspvt::Settings) -> bspvt::Bake {
    let b = with_bar(renderer.vertex_count(), "baking", |p| bspvt::bake(&renderer.flat, settings, p));
    let st = b.stats;
    crate::emit(&format!(
        "bake: {} vertices in {:.2} s ({:.0} vertices/s), {:.1} leaves and {:.1} nodes per vertex, {:.0} bytes per vertex ({:.2} MB)\n",
        st.vertices,
        st.seconds,
        st.vertices as f64 / st.seconds,
        st.leaves as f64 / st.vertices as f64,
        st.nodes as f64 / st.vertices as f64,
        st.bytes as f64 / st.vertices as f64,
        st.bytes as f64 / 1e6
    ));
    b
}

fn prt(job: &Job) -> Result<Outputs> {
    let Job { args, scene, renderer, .. } = *job;
    let flat = &renderer.flat;
    if let Some(pack) = job.pack {
        let (bake, lighting, settings) =
            pack.prt.as_ref().context("the pack has no PRT data (its scene has no environment)")?;
        return prt_shade(job, prt::Parts { bake, lighting, settings });
    }
    let store = args.db.open_if_used(&args.scene)?;
    let settings = match &store {
        Some(store) => args.prt.settings_cached(store, scene, flat, args.error_budget)?,
        None => args.prt.settings(scene, flat, args.error_budget),
    };
    let Some(lighting) = prt::Lighting::new(scene, &settings) else {
        bail!("{}: PRT shades environment lighting and the scene has none (pass --env FILE.hdr)", scene.source);
    };
    crate::emit(&format!(
        "lighting: order {}, {:?} window (negative lobes: min {:.1} % of the mean over {:.1} % of directions), {} regions\n",
        settings.order,
        settings.window,
        -100.0 * lighting.lobes.min_relative,
        100.0 * lighting.lobes.fraction,
        lighting.regions.len()
    ));
    let bake = match &store {
        Some(store) => from_database(store, scene, flat, None, Some(settings))?.prt.context("PRT was planned")?,
        None => {
            let bake = with_bar(renderer.vertex_count(), "baking", |p| prt::bake(scene, flat, &settings, p));
            let st = bake.stats;
            crate::emit(&format!(
                "bake: {} vertices in {:.2} s ({:.0} vertices/s), order {}, {} directions, {:.2} MB\n",
                st.vertices,
                st.seconds,
                st.vertices as f64 / st.seconds,
                settings.order,
                settings.direction_side().pow(2),
                st.bytes as f64 / 1e6
            ));
            bake
        }
    };
    prt_shade(job, prt::Parts { bake: &bake, lighting: &lighting, settings: &settings })
}

/// PRT shading of a frame: per-vertex values and, if wanted, the image.
fn prt_shade(job: &Job, parts: prt::Parts) -> Result<Outputs> {
    let Job { args, scene, renderer, camera, want_image, .. } = *job;
    let shadows = args.method.prt_shadows().context("a PRT method")?;
    if args.gpu {
        return prt_gpu(job, parts, shadows);
    }
    let start = Instant::now();
    let frame = prt::Frame::prepare(scene, &renderer.flat, parts, shadows, camera.eye());
    let values = frame.vertex_values(&renderer.flat);
    crate::emit(&format!("shade: {} vertices in {:.3} s\n", renderer.vertex_count(), start.elapsed().as_secs_f64()));
    let image = want_image.then(|| {
        let (w, h) = args.size;
        frame.render(renderer, camera, w, h, args.spp.min(16))
    });
    Ok(Outputs { image, vertices: Some(values), glossy: GlossyDirect::PerVertex })
}

/// [`prt_shade`] on the GPU: per-vertex values, the image interpolating them.
fn prt_gpu(job: &Job, prt::Parts { bake, lighting, settings }: prt::Parts, shadows: prt::Shadows) -> Result<Outputs> {
    let Job { scene, renderer, camera, .. } = *job;
    let gpu = gpu_device()?;
    let flat = &renderer.flat;
    let mut memo = prt::SilhouetteMemo::default();
    let posed = prt::pose(scene, flat, bake.order, lighting, shadows, settings, &mut memo);
    let shader = kage_gpu::prt::PrtShader::new(&gpu, &kage_gpu::Shaders::embedded(), bake, posed.order)?;
    let start = Instant::now();
    let values = kage_gpu::prt::shade_vertices(&gpu, &shader, flat, &posed, camera.eye())?;
    crate::emit(&format!("shade: {} vertices in {:.3} s\n", renderer.vertex_count(), start.elapsed().as_secs_f64()));
    Ok(Outputs { image: job.vertex_image(&values), vertices: Some(values), glossy: GlossyDirect::PerVertex })
}

/// The GPU device, announced on stderr.
pub(super) fn gpu_device() -> Result<kage_gpu::Gpu> {
    let gpu = kage_gpu::Gpu::new()?;
    crate::emit(&format!("gpu: {}\n", gpu.describe()));
    Ok(gpu)
}

/// Plans and runs the bakes through the database, printing what was cached and what baked.
fn from_database(
    store: &kage_bake_db::Store,
    scene: &Scene,
    flat: &kage_engine::scene::FlatScene,
    bspvt: Option<bspvt::Settings>,
    prt: Option<prt::Settings>,
) -> Result<kage_bake_db::Outcome> {
    let plan = kage_bake_db::plan(store, scene, flat, bspvt, prt)?;
    run_plan(store, scene, flat, &plan)
}

/// Bakes a plan's misses (progress bar) and assembles its bakes, printing what was cached and
/// what baked.
fn run_plan(
    store: &kage_bake_db::Store,
    scene: &Scene,
    flat: &kage_engine::scene::FlatScene,
    plan: &kage_bake_db::plan::Plan,
) -> Result<kage_bake_db::Outcome> {
    let total = plan.misses().map(|j| j.vertices.len()).sum();
    let out = with_bar(total, "baking", |p| kage_bake_db::run(store, scene, flat, plan, p))?;
    let s = out.stats;
    crate::emit(&format!(
        "bake: {}: {} chunks cached, {} baked cold, {} warm ({} vertices) in {:.2} s\n",
        store.path().display(),
        s.cached,
        s.cold,
        s.warm,
        s.vertices_baked,
        s.seconds
    ));
    Ok(out)
}

/// The indirect light per vertex `--indirect` asks for: none, the pack's frozen bounces, or
/// bounces lit by the per-vertex `direct` values (glossy hits as `glossy` says) from the
/// radiance cache, a brute-force gather or the reference. With a bake database in use, the
/// cache's records come from it (or are stored in it).
fn indirect(job: &Job, direct: &[Vec<Vec3>], glossy: Glossy<'_>) -> Result<VertexValues> {
    let Job { args, scene, renderer, camera, pack, .. } = *job;
    let eye = camera.eye();
    let zeros = || direct.iter().map(|v| vec![Vec3::ZERO; v.len()]).collect();
    let start = Instant::now();
    let s = kage_engine::cache::Settings {
        order: args.hsh_order as usize,
        rays: args.cache_rays as usize,
        accuracy: args.cache_accuracy,
        gradients: !args.no_gradients,
        gradient_form: args.gradient,
        blend: args.cache_blend,
        noise: args.cache_noise,
        ..Default::default()
    };
    let src = Source { renderer, direct, glossy };
    let (values, what) = match args.indirect() {
        Indirect::None => return Ok(zeros()),
        Indirect::Pack => {
            return frozen(pack.expect("--indirect pack is refused without --pack"), &renderer.flat, eye);
        }
        _ if renderer.flat.unlit().is_some() => {
            crate::emit("indirect: skipped, nothing lights the scene\n");
            return Ok(zeros());
        }
        Indirect::Cache => {
            let store = if args.pack.is_none() { args.db.open_if_used(&args.scene)? } else { None };
            let (cache, stored) = match &store {
                Some(store) => kage_bake_db::memo::records::load_or_place(store, scene, &src, &s)?,
                None => (kage_engine::cache::place_at_vertices(&src, &s), false),
            };
            let (v, bounced) = kage_engine::cache::bounce(&src, &cache, eye, args.cache_bounces());
            let from = if stored { " from the bake database" } else { "" };
            (v, format!("{bounced}; {} records{from}, {} rays", cache.records.len(), cache.rays()))
        }
        Indirect::Gather => {
            let v = kage_engine::cache::gather_vertices(&src, s.rays, eye);
            (v, format!("{} rays", renderer.vertex_count() * s.side().pow(2)))
        }
        Indirect::Reference => {
            let settings =
                Settings { spp: args.spp, seed: args.seed, max_bounces: args.bounces.unwrap_or(1), min_bounces: 1 };
            let est = renderer.render_vertices(eye, &settings, &|_| {});
            let v = est.iter().map(|e| e.iter().map(|x| x.mean).collect()).collect();
            (v, format!("{} paths per vertex", args.spp))
        }
    };
    crate::emit(&format!("indirect ({:?}): {what} in {:.2} s\n", args.indirect(), start.elapsed().as_secs_f64()));
    Ok(values)
}

/// The bounces `pack` carries as radiance toward `eye`: their light per vertex times the
/// vertex's diffuse albedo (the image's samples rescale it by theirs).
fn frozen(pack: &Contents, flat: &kage_engine::scene::FlatScene, eye: Vec3) -> Result<VertexValues> {
    let light =
        pack.bounce.as_ref().context("the pack carries no bounces (packs from kage export, version 5 on, do)")?;
    let albedo = kage_engine::material::albedo::at_vertices(flat, eye);
    crate::emit("indirect (Pack): the bounces the pack carries\n");
    Ok(light.iter().zip(albedo).map(|(l, a)| l.iter().zip(a).map(|(l, a)| *l * a).collect()).collect())
}

fn camera(args: &Args, scene_camera: Option<Camera>, flat: &kage_engine::scene::FlatScene) -> Result<Camera> {
    let mut cam = match (args.eye, args.target, scene_camera) {
        (Some(eye), Some(target), _) => Camera::look_at(eye, target, 45f32.to_radians()),
        (_, _, Some(c)) => c,
        _ => {
            let c = flat.framing_camera();
            let e = c.eye();
            crate::emit(&format!(
                "camera: the scene has none; framing it from {:.3},{:.3},{:.3} (--eye and --target choose)\n",
                e.x, e.y, e.z
            ));
            c
        }
    };
    if let Some(fov) = args.fov {
        if !(fov > 0.0 && fov < 180.0) {
            bail!("--fov must be between 0 and 180 degrees, got {fov}");
        }
        cam.projection = kage_engine::scene::Projection::Perspective { yfov: fov.to_radians() };
    }
    Ok(cam)
}

fn vertex_rows(renderer: &Renderer, per_instance: &[Vec<Vec3>]) -> Vec<VertexRow> {
    let mut rows = Vec::new();
    for (i, est) in per_instance.iter().enumerate() {
        let id = renderer.flat.instances[i].id;
        for (v, e) in est.iter().enumerate() {
            let (position, _) = renderer.vertex(i, v);
            rows.push(VertexRow {
                node: id.node,
                mesh: id.mesh,
                primitive: id.primitive,
                vertex: v as u32,
                position,
                radiance: *e,
            });
        }
    }
    rows
}

/// Prints time and the estimate's own relative standard error.
fn report(what: &str, est: &[Estimate], start: Instant) {
    let rel = kage_engine::reference::relative_standard_error(est);
    crate::emit(&format!(
        "{what}: {} estimates in {:.2} s, relative standard error {:.4}\n",
        est.len(),
        start.elapsed().as_secs_f64(),
        rel
    ));
}
