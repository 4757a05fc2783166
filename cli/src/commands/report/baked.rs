//! The baked-look section: `--method baked` (BSPVT trees + PRT with its specular term + the HSH
//! cache's bounces, bakes in memory with the parameters `kage render` plans) against the full
//! reference with as many bounces, per vertex and per pixel over the pixels whose primary ray hits
//! geometry; next to it, each light's direct term alone against the reference of that light
//! alone (the polygonal lights through the trees, the environment through PRT), so that the
//! whole's error can be traced to its parts.

use super::{Args, Row, Truth, announce};
use crate::progress::bar;
use anyhow::Result;
use glam::Vec3;
use kage_engine::math::relative_rmse;
use kage_engine::prt::{self, prefilter::Prefiltered};
use kage_engine::raster;
use kage_engine::reference::{Renderer, Settings};
use kage_engine::scene::{Camera, Scene};
use kage_engine::shading::baked::{Bakes, Look};
use kage_engine::{bspvt, cache};
use std::time::Instant;

/// Which lights a row shades.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Part {
    /// Everything, with the bounces the error budget chooses.
    Whole,
    /// The polygonal lights' direct term.
    Polygonal,
    /// The environment's direct term.
    Environment,
}

/// Measures the section into `rows`; returns its header line.
pub fn run(args: &Args, camera: &Camera, rows: &mut Vec<Row>) -> Result<String> {
    let scene = args.scene.load()?;
    let mut lines = Vec::new();
    for part in [Part::Whole, Part::Polygonal, Part::Environment] {
        let mut lit = scene.duplicate();
        match part {
            Part::Whole => {}
            Part::Polygonal => lit.clear_environment(),
            Part::Environment => lit.remove_polygon_lights(),
        }
        let renderer = Renderer::new(&lit);
        let has = (!renderer.flat.lights.is_empty(), renderer.flat.environment.is_some());
        let applies = match part {
            Part::Whole => has.0 && has.1,
            Part::Polygonal => has.0,
            Part::Environment => has.1,
        };
        if applies {
            let (row, line) = measure(args, &lit, &renderer, camera, part)?;
            announce(&row);
            rows.push(row);
            lines.push(line);
        }
    }
    Ok(lines.join("\n\n"))
}

/// One row: bake, shade (vertices and image), compare.
fn measure(args: &Args, scene: &Scene, renderer: &Renderer, camera: &Camera, part: Part) -> Result<(Row, String)> {
    let eye = camera.eye();
    let flat = &renderer.flat;
    let t = Instant::now();
    let trees = (!flat.lights.is_empty()).then(|| bspvt::bake(flat, &bspvt::Settings::default(), &|_| {}));
    let prt_parts = flat.environment.as_ref().map(|_| {
        let (s, _) = prt::budget::choose(scene, flat, crate::prt_args::DEFAULT_BUDGET, &prt::Settings::default());
        let bake = prt::bake(scene, flat, &s, &|_| {});
        (bake, prt::Lighting::new(scene, &s).expect("the scene has an environment"), s)
    });
    let bake_s = t.elapsed().as_secs_f64();
    let bake_bytes = trees.as_ref().map_or(0, |b| b.stats.bytes) + prt_parts.as_ref().map_or(0, |p| p.0.stats.bytes);
    let t = Instant::now();
    let prefiltered = flat.environment.as_ref().map(Prefiltered::new);
    let bakes = Bakes {
        bspvt: trees.as_ref(),
        prt: prt_parts.as_ref().map(|(bake, lighting, settings)| prt::Parts { bake, lighting, settings }),
        prefiltered: prefiltered.as_ref(),
    };
    let mut look = Look::prepare(scene, flat, bakes, eye, &mut prt::SilhouetteMemo::default());
    let mut parts = Vec::new();
    if trees.is_some() {
        parts.push("trees 64², ε 2, LTC per pixel".to_string());
    }
    if let Some((_, l, s)) = &prt_parts {
        parts.push(format!("PRT order {}, {} regions", s.order, l.regions.len()));
    }
    let mut config = parts.join("; ");
    let mut bounces = 0;
    if part == Part::Whole {
        let s = cache::Settings::default();
        let (bounce, bounced) = crate::commands::render::baked::with_cache(&look, renderer, &s, |src, c| {
            cache::bounce(src, c, eye, cache::Bounces::default())
        });
        bounces = bounced.count as u32;
        config = format!("{config}; cache order {}, accuracy {}, {bounced}", s.order, s.accuracy);
        look = look.with_indirect(bounce);
    }
    let (w, h) = args.image_size;
    let image = look.render(renderer, camera, w, h, 4);
    let shade_s = t.elapsed().as_secs_f64();
    let what = match part {
        Part::Whole => format!("baked look against the full reference (direct + {bounces} bounces)"),
        Part::Polygonal => "baked look, polygonal lights alone (direct)".to_string(),
        Part::Environment => "baked look, environment alone (direct)".to_string(),
    };
    let truth =
        Truth::vertices(renderer, eye, args.reference_spp, (0, bounces), vec![true; flat.instances.len()], &what);
    let (pixels, noise) = reference_image(args, renderer, camera, bounces);
    let hits = raster::shade_image(renderer, camera, w, h, 4, &|_| Vec3::ONE);
    let pick =
        |v: &[Vec3]| -> Vec<Vec3> { v.iter().zip(&hits).filter(|(_, m)| **m == Vec3::ONE).map(|(p, _)| *p).collect() };
    let row = Row {
        bake_s,
        bake_bytes,
        pixel_rel_rmse: Some(relative_rmse(&pick(&image), &pick(&pixels))),
        ..truth.row(part.name(), config, shade_s, &look.vertex_values())
    };
    let counted = hits.iter().filter(|m| **m == Vec3::ONE).count();
    let line = format!(
        "{}; reference image {w}×{h} at {} spp ({counted} geometry pixels counted, its own relative standard error {noise:.4})",
        truth.line, args.reference_image_spp
    );
    Ok((row, line))
}

impl Part {
    fn name(self) -> &'static str {
        match self {
            Part::Whole => "baked",
            Part::Polygonal => "baked-polygonal",
            Part::Environment => "baked-environment",
        }
    }
}

/// The reference image with `bounces`, and its relative standard error over the image.
fn reference_image(args: &Args, renderer: &Renderer, camera: &Camera, bounces: u32) -> (Vec<Vec3>, f64) {
    let (w, h) = args.image_size;
    let pb = bar(h as u64, "reference image");
    let settings = Settings { spp: args.reference_image_spp, seed: 0xBA6E, max_bounces: bounces, min_bounces: 0 };
    let est = renderer.render_image(camera, w, h, &settings, &|r| pb.set_position(r as u64));
    pb.finish_and_clear();
    (est.iter().map(|e| e.mean).collect(), kage_engine::reference::relative_standard_error(&est))
}
