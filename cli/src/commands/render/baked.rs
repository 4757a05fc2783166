//! `--method baked`: plans and bakes what the scene needs into its database (or reads a pack),
//! then shades the complete look ([`kage_engine::shading::baked`]).

use super::{Args, Job, Outputs, indirect, run_plan};
use crate::commands::bake::print_plan;
use anyhow::{Context, Result, bail};
use kage_engine::bspvt;
use kage_engine::bspvt::pixel::Lobes;
use kage_engine::cache;
use kage_engine::cache::record::{Glossy, GlossyDirect, Source};
use kage_engine::prt::{self, prefilter::Prefiltered};
use kage_engine::reference::Renderer;
use kage_engine::scene::Scene;
use kage_engine::scene::VertexValues;
use kage_engine::shading::baked::{Bakes, EnvironmentMemo, Look};
use kage_gpu::camera::Orbit;
use std::time::Instant;

/// The bakes the look shades from, read from a pack or the database.
struct Loaded {
    bspvt: Option<bspvt::Bake>,
    prt: Option<(prt::Bake, prt::Lighting, prt::Settings)>,
}

/// Bakes (or reads) and shades; the indirect term is part of the look.
pub(super) fn run(job: &Job) -> Result<Outputs> {
    let Job { args, scene, renderer, camera, want_image, pack } = *job;
    let bakes = match pack {
        Some(p) => Loaded { bspvt: p.bspvt.clone(), prt: p.prt.clone() },
        None => bake(args, scene, renderer)?,
    };
    let (flat, eye) = (&renderer.flat, camera.eye());
    if let Some(b) = &bakes.bspvt {
        super::warn_unseen(scene, flat, b);
    }
    let start = Instant::now();
    let prefiltered = flat.environment.as_ref().map(Prefiltered::new);
    let parts = Bakes {
        bspvt: bakes.bspvt.as_ref(),
        prt: bakes.prt.as_ref().map(|(bake, lighting, settings)| prt::Parts { bake, lighting, settings }),
        prefiltered: prefiltered.as_ref(),
    };
    let mut look = Look::prepare(scene, flat, parts, eye, &mut prt::SilhouetteMemo::default());
    crate::emit(&format!("shade: {} vertices in {:.3} s\n", renderer.vertex_count(), start.elapsed().as_secs_f64()));
    if args.indirect() != super::Indirect::None {
        let direct = look.direct_vertices();
        let toward = |i, corners, bary, to| look.toward(i, corners, bary, to);
        let extra = indirect(job, direct, Glossy::Toward(&toward))?;
        look = look.with_indirect(extra);
    }
    let values = look.vertex_values();
    let image = want_image
        .then(|| {
            let start = Instant::now();
            let (w, h) = args.size;
            let image = if args.gpu {
                gpu_image(job, parts, &values)?
            } else {
                look.render(renderer, camera, w, h, args.spp.min(16))
            };
            crate::emit(&format!("image: {w}×{h} in {:.2} s\n", start.elapsed().as_secs_f64()));
            Ok::<_, anyhow::Error>(image)
        })
        .transpose()?;
    Ok(Outputs { image, vertices: Some(values), glossy: GlossyDirect::PerVertex })
}

/// The look through the scene's camera as the editor's viewport draws it on the GPU: the
/// polygonal lights, the environment's reflection and its sun per pixel (their visibility from
/// the vertices), everything else (`values`: the look per vertex) interpolated, materials per
/// pixel. Where the device or a light does not allow per-pixel lights, per vertex (said).
fn gpu_image(job: &Job, bakes: Bakes, values: &VertexValues) -> Result<Vec<glam::Vec3>> {
    use kage_gpu::viewport::{PixelEnvironment, PixelLights, Viewport};
    let Job { args, scene, renderer, camera, .. } = *job;
    let (flat, eye) = (&renderer.flat, camera.eye());
    let kage_engine::scene::Projection::Perspective { .. } = camera.projection else {
        bail!("--gpu draws through perspective cameras only; this camera is orthographic");
    };
    let gpu = super::gpu_device()?;
    let shaders = kage_gpu::Shaders::embedded();
    let mut viewport = Viewport::new(&gpu, &shaders)?;
    viewport.set_environment(&gpu, flat.environment.as_ref());
    viewport.upload_geometry(&gpu, flat);
    let mut inside = kage_engine::bspvt::pixel::Inside::default();
    let (lobes, lights) = Lobes::at_vertices(flat, bakes.bspvt, eye, inside.flags(flat));
    let environment = match (bakes.prt, bakes.prefiltered) {
        (Some(parts), Some(pre)) => {
            let mut memo = EnvironmentMemo::default();
            let environment = Some((parts, Some(pre)));
            let _ = Look::direct_reusing(scene, flat, eye, None, environment, &mut memo, &mut Default::default());
            memo.specular().map(|s| PixelEnvironment::new(flat, s, pre, parts.lighting, eye))
        }
        _ => None,
    };
    viewport.upload_lights(&gpu, flat, Some(&PixelLights { lobes, values: lights, environment }));
    if !viewport.drawing_lights() {
        eprintln!(
            "note: --gpu draws per vertex here (the device cannot bind the per-pixel lights' buffers, or a light is textured or has more than 8 corners)"
        );
    }
    viewport.upload_radiance(&gpu, values);
    if camera.world.matrix3.x_axis.y.abs() > 1e-3 {
        eprintln!("note: --gpu draws without the camera's roll (the editor's orbit stays upright)");
    }
    let (w, h) = args.size;
    let orbit = Orbit::from_camera(camera, flat.bounding_sphere().1);
    // Edges antialiased as the CPU's image is (16 samples a pixel): drawn at 4× and averaged.
    let k = (4096 / w.max(h)).clamp(1, 4);
    let fine = viewport.render_radiance(&gpu, &shaders, [(k * w) as u32, (k * h) as u32], &orbit)?;
    Ok(downsample(&fine, (w, h), k))
}

/// The mean of every `k`×`k` block of `fine` (`k·w` × `k·h`, rows from the top).
fn downsample(fine: &[glam::Vec3], (w, h): (usize, usize), k: usize) -> Vec<glam::Vec3> {
    let block = |x: usize, y: usize| {
        let rows = (0..k).flat_map(|j| fine[(k * y + j) * k * w + k * x..][..k].iter());
        rows.copied().sum::<glam::Vec3>() / (k * k) as f32
    };
    (0..w * h).map(|p| block(p % w, p / w)).collect()
}

/// Plans the scene's bakes against its database (created on first use), prints the plan and
/// its estimate, and bakes the misses. The database is closed again before shading (the
/// radiance cache opens it for its records).
fn bake(args: &Args, scene: &Scene, renderer: &Renderer) -> Result<Loaded> {
    let flat = &renderer.flat;
    let store = args.db.open(&args.scene)?;
    let start = Instant::now();
    let bspvt_settings = bspvt::Settings { res: args.face_res, epsilon: args.epsilon };
    let prt_settings = flat
        .environment
        .is_some()
        .then(|| args.prt.settings_cached(&store, scene, flat, args.error_budget))
        .transpose()?;
    let plan = kage_bake_db::plan(&store, scene, flat, Some(bspvt_settings), prt_settings)?;
    print_plan(&store, scene, flat, &plan, start.elapsed().as_secs_f64())?;
    let out = run_plan(&store, scene, flat, &plan)?;
    let prt = match (out.prt, prt_settings) {
        (Some(b), Some(s)) => {
            let light = prt::Lighting::new(scene, &s).context("PRT was planned, so the scene has an environment")?;
            Some((b, light, s))
        }
        _ => None,
    };
    Ok(Loaded { bspvt: out.bspvt, prt })
}

/// `f` of the radiance cache's source lit by `look`'s direct light (glossy hits reflect it
/// toward the records) and of an in-memory cache with `settings` placed under it.
pub(crate) fn with_cache<R>(
    look: &Look,
    renderer: &Renderer,
    settings: &cache::Settings,
    f: impl FnOnce(&Source, &cache::Cache) -> R,
) -> R {
    let toward = |i, corners, bary, to| look.toward(i, corners, bary, to);
    let src = Source { renderer, direct: look.direct_vertices(), glossy: Glossy::Toward(&toward) };
    f(&src, &cache::place_at_vertices(&src, settings))
}
