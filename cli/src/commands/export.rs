//! `kage export`: bake through the database (misses only) and write an asset pack — the scene,
//! its baked data under `KAGE_baked_shadows`, and an unlit `COLOR_0` preview of the baked look
//! (`--method baked` per vertex, one bounce included).

use crate::commands::bake::{BakeOptions, print_plan};
use crate::db_args::DbArgs;
use crate::exposure::Exposure;
use crate::progress::with_bar;
use crate::scene_args::SceneArgs;
use anyhow::{Context, Result};
use glam::Vec3;
use kage_bake_db::pack::{self, Export};
use kage_engine::scene::VertexValues;
use kage_engine::scene::flatten;
use kage_engine::shading::baked::{Bakes, Look};
use kage_engine::{bspvt, cache, prt};
use std::path::PathBuf;

/// Arguments of `kage export`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    db: DbArgs,
    /// The pack to write (.glb).
    #[arg(short, long)]
    output: PathBuf,
    /// Preview exposure: stops (COLOR_0 = clamp(radiance · 2^EV, 0, 1)), or `auto` to meter
    /// the vertices' radiance.
    #[arg(long, default_value = "auto", allow_negative_numbers = true)]
    exposure: Exposure,
    #[command(flatten)]
    options: BakeOptions,
}

/// Runs the command.
pub fn run(args: &Args) -> Result<()> {
    let store = args.db.open(&args.scene)?;
    let scene = args.scene.load_kept(Some(&store))?;
    let flat = flatten(&scene);
    let start = std::time::Instant::now();
    let plan = args.options.plan(&store, &scene, &flat)?;
    print_plan(&store, &scene, &flat, &plan, start.elapsed().as_secs_f64())?;
    anyhow::ensure!(!plan.jobs.is_empty(), "{}: no polygonal light and no environment: nothing to bake", scene.source);
    let total = plan.misses().map(|j| j.vertices.len()).sum();
    let out = with_bar(total, "baking", |p| kage_bake_db::run(&store, &scene, &flat, &plan, p))?;
    let eye = scene.first_camera().map_or(Vec3::new(0.0, 4.0, 8.0), |c| c.eye());
    let lighting = plan.prt.and_then(|s| prt::Lighting::new(&scene, &s).map(|l| (l, s)));
    let parts = out.prt.as_ref().zip(lighting.as_ref());
    let parts = parts.map(|(bake, (lighting, settings))| prt::Parts { bake, lighting, settings });
    let (radiance, bounce) = preview(&scene, out.bspvt.as_ref(), parts, eye);
    let export = Export {
        scene: &scene,
        flat: &flat,
        bspvt: out.bspvt.as_ref(),
        prt: parts,
        radiance: &radiance,
        bounce: Some(&bounce),
        exposure: args.exposure.stops(radiance.iter().flatten().copied()),
    };
    pack::write(&args.output, &export).with_context(|| format!("writing {}", args.output.display()))?;
    let size = std::fs::metadata(&args.output).map(|m| m.len()).unwrap_or(0);
    crate::emit(&format!("wrote {} ({:.2} MB)\n", args.output.display(), size as f64 / 1e6));
    Ok(())
}

/// The preview: the baked look toward `eye`, with the radiance cache's bounces; and the light
/// those bounces bring (irradiance over π).
fn preview(
    scene: &kage_engine::scene::Scene,
    trees: Option<&bspvt::Bake>,
    prt: Option<prt::Parts>,
    eye: Vec3,
) -> (VertexValues, VertexValues) {
    let renderer = kage_engine::reference::Renderer::new(scene);
    let flat = &renderer.flat;
    let prefiltered = flat.environment.as_ref().map(prt::prefilter::Prefiltered::new);
    let bakes = Bakes { bspvt: trees, prt, prefiltered: prefiltered.as_ref() };
    let look = Look::prepare(scene, flat, bakes, eye, &mut prt::SilhouetteMemo::default());
    let (values, light, _) =
        crate::commands::render::baked::with_cache(&look, &renderer, &cache::Settings::default(), |src, c| {
            cache::bounce_with_light(src, c, (eye, cache::Bounces::default()), &|| false).expect("never stopped")
        });
    (look.with_indirect(values).vertex_values(), light)
}
