//! `kage render`: images and per-vertex radiance with a chosen method.

use crate::progress::bar;
use crate::scene_args::SceneArgs;
use anyhow::{Context, Result, bail};
use glam::Vec3;
use kage_engine::output::{VertexRow, write_image, write_vertex_csv};
use kage_engine::reference::{Estimate, Renderer, Settings};
use kage_engine::scene::Camera;
use std::path::PathBuf;
use std::time::Instant;

/// How radiance is computed.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Monte Carlo ground truth (path tracing with MIS).
    Reference,
}

/// Arguments of `kage render`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    scene: SceneArgs,
    /// Shading method.
    #[arg(long, value_enum, default_value = "reference")]
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
    /// Indirect bounces for the reference (0 = direct lighting only).
    #[arg(long, default_value_t = 0)]
    bounces: u32,
    /// PNG exposure in stops.
    #[arg(long, default_value_t = 0.0)]
    exposure: f32,
}

fn parse_size(s: &str) -> Result<(usize, usize), String> {
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
    let scene = args.scene.load()?;
    let camera = camera(args, scene.first_camera())?;
    let renderer = Renderer::new(&scene);
    let settings = Settings { spp: args.spp, seed: args.seed, max_bounces: args.bounces };
    let output = args.output.clone().or_else(|| args.vertices_out.is_none().then(|| PathBuf::from("render.png")));
    if let Some(path) = &output {
        let (w, h) = args.size;
        let pb = bar(h as u64, "pixels");
        let start = Instant::now();
        let est = renderer.render_image(&camera, w, h, &settings, &|rows| pb.set_position(rows as u64));
        pb.finish_and_clear();
        report("image", &est, start);
        let pixels: Vec<Vec3> = est.iter().map(|e| e.mean).collect();
        write_image(path, w, h, &pixels, args.exposure)?;
        crate::emit(&format!("wrote {}\n", path.display()));
    }
    if let Some(path) = &args.vertices_out {
        let pb = bar(renderer.vertex_count() as u64, "vertices");
        let start = Instant::now();
        let per_instance = renderer.render_vertices(camera.eye(), &settings, &|n| pb.set_position(n as u64));
        pb.finish_and_clear();
        let all: Vec<Estimate> = per_instance.iter().flatten().copied().collect();
        report("vertices", &all, start);
        let rows = vertex_rows(&renderer, &per_instance);
        write_vertex_csv(path, &rows).with_context(|| "writing per-vertex results")?;
        crate::emit(&format!("wrote {} ({} vertices)\n", path.display(), rows.len()));
    }
    Ok(())
}

fn camera(args: &Args, scene_camera: Option<Camera>) -> Result<Camera> {
    let mut cam = match (args.eye, args.target, scene_camera) {
        (Some(eye), Some(target), _) => Camera::look_at(eye, target, 45f32.to_radians()),
        (_, _, Some(c)) => c,
        _ => bail!("the scene has no camera: pass --eye x,y,z --target x,y,z"),
    };
    if let Some(fov) = args.fov {
        if !(fov > 0.0 && fov < 180.0) {
            bail!("--fov must be between 0 and 180 degrees, got {fov}");
        }
        cam.projection = kage_engine::scene::Projection::Perspective { yfov: fov.to_radians() };
    }
    Ok(cam)
}

fn vertex_rows(renderer: &Renderer, per_instance: &[Vec<Estimate>]) -> Vec<VertexRow> {
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
                radiance: e.mean,
            });
        }
    }
    rows
}

/// Prints time and the estimate's own relative standard error.
fn report(what: &str, est: &[Estimate], start: Instant) {
    let (num, den) = est.iter().fold((0.0f64, 0.0f64), |(n, d), e| {
        (n + e.std_error.length_squared() as f64, d + e.mean.length_squared() as f64)
    });
    let rel = if den > 0.0 { (num / den).sqrt() } else { 0.0 };
    crate::emit(&format!(
        "{what}: {} estimates in {:.2} s, relative standard error {:.4}\n",
        est.len(),
        start.elapsed().as_secs_f64(),
        rel
    ));
}
