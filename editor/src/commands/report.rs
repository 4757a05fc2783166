//! `kage report`: speed against error. Runs the polygonal-light methods and parameter sweeps
//! against the Monte Carlo reference and writes `report.md`, `report.csv` and `report.png`
//! (relative RMSE against time, log–log, one colour per method) into `--out`.
//!
//! Everything is per vertex, toward the scene camera, from the polygonal lights only (the
//! environment is dropped: PRT covers it).

use crate::progress::bar;
use crate::scene_args::SceneArgs;
use anyhow::{Context, Result};
use glam::Vec3;
use kage_engine::reference::{Renderer, Settings};
use kage_engine::{bspvt, ratio};
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `kage report`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    scene: SceneArgs,
    /// Output folder.
    #[arg(long, default_value = "report")]
    out: PathBuf,
    /// Samples per vertex of the reference.
    #[arg(long, default_value_t = 1024)]
    reference_spp: u32,
}

/// One measured configuration.
struct Row {
    method: &'static str,
    config: String,
    bake_s: f64,
    bake_bytes: usize,
    leaves_per_vertex: f64,
    shade_s: f64,
    rmse: f64,
    rel_rmse: f64,
}

/// Runs the sweeps and writes the report.
pub fn run(args: &Args) -> Result<()> {
    let mut scene = args.scene.load()?;
    scene.clear_environment();
    let renderer = Renderer::new(&scene);
    let eye = scene.first_camera().map(|c| c.eye()).context("the scene has no camera to shade toward")?;
    let n = renderer.vertex_count();
    let pb = bar(n as u64, "reference");
    let start = Instant::now();
    let reference =
        renderer.render_vertices(eye, &Settings { spp: args.reference_spp, seed: 0x5EED, max_bounces: 0 }, &|k| {
            pb.set_position(k as u64)
        });
    pb.finish_and_clear();
    let ref_time = start.elapsed().as_secs_f64();
    let truth: Vec<Vec3> = reference.iter().flatten().map(|e| e.mean).collect();
    let (se2, mean2) = reference.iter().flatten().fold((0.0, 0.0), |(a, b), e| {
        (a + e.std_error.as_dvec3().length_squared(), b + e.mean.as_dvec3().length_squared())
    });
    let ref_se = (se2 / mean2.max(f64::MIN_POSITIVE)).sqrt();
    let mut rows = Vec::new();
    let mut push = |method, config: String, bake: Option<&bspvt::Bake>, shade_s: f64, values: Vec<Vec<Vec3>>| {
        let (rmse, rel_rmse) = rel(values.into_iter().flatten(), &truth);
        let (bake_s, bake_bytes, leaves) = bake.map_or((0.0, 0, 0.0), |b| {
            (b.stats.seconds, b.stats.bytes, b.stats.leaves as f64 / b.stats.vertices.max(1) as f64)
        });
        crate::emit(&format!(
            "{method:15} {config:22} bake {bake_s:8.2} s  shade {shade_s:8.3} s  rel RMSE {rel_rmse:.4}\n"
        ));
        rows.push(Row { method, config, bake_s, bake_bytes, leaves_per_vertex: leaves, shade_s, rmse, rel_rmse });
    };
    for (res, eps) in [(16, 2.0), (32, 2.0), (64, 2.0), (64, 0.5)] {
        let s = bspvt::Settings { res, epsilon: eps };
        let b = bspvt::bake(&scene, &renderer.flat, &s, &|_| {});
        let t = Instant::now();
        let v = bspvt::shade_vertices(&scene, &renderer.flat, bspvt::Method::Bspvt, Some(&b), &s, eye);
        push("bspvt", format!("{res}² faces, ε {eps}"), Some(&b), t.elapsed().as_secs_f64(), v);
    }
    let s = bspvt::Settings::default();
    let t = Instant::now();
    let v = bspvt::shade_vertices(&scene, &renderer.flat, bspvt::Method::ExactVis, None, &s, eye);
    push("ltc-exact-vis", "64² faces (cast per frame)".into(), None, t.elapsed().as_secs_f64(), v);
    let t = Instant::now();
    let v = bspvt::shade_vertices(&scene, &renderer.flat, bspvt::Method::Unshadowed, None, &s, eye);
    push("ltc-unshadowed", String::new(), None, t.elapsed().as_secs_f64(), v);
    for spp in [1u32, 4, 16, 64] {
        let t = Instant::now();
        let est = renderer.render_vertices(eye, &Settings { spp, seed: 7, max_bounces: 0 }, &|_| {});
        let v = est.iter().map(|e| e.iter().map(|x| x.mean).collect()).collect();
        push("monte-carlo", format!("{spp} spp"), None, t.elapsed().as_secs_f64(), v);
    }
    for rays in [1u32, 4, 16] {
        let t = Instant::now();
        let v = ratio::shade_vertices(&renderer, rays, 7, eye);
        push("ratio-estimator", format!("{rays} rays per light"), None, t.elapsed().as_secs_f64(), v);
    }
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let header = format!(
        "scene {}: {n} vertices, {} lights; reference {} spp in {ref_time:.1} s, its own relative standard error {ref_se:.4}",
        scene.source,
        renderer.flat.lights.len(),
        args.reference_spp
    );
    write_files(args, &header, &rows)?;
    crate::emit(&format!("wrote {}/report.md, report.csv, report.png\n", args.out.display()));
    Ok(())
}

/// (RMSE, relative RMSE) of `values` against `truth`, per channel of linear radiance.
fn rel(values: impl Iterator<Item = Vec3>, truth: &[Vec3]) -> (f64, f64) {
    let (mut num, mut den, mut count) = (0.0, 0.0, 0usize);
    for (x, r) in values.zip(truth) {
        num += (x - *r).as_dvec3().length_squared();
        den += r.as_dvec3().length_squared();
        count += 3;
    }
    ((num / count.max(1) as f64).sqrt(), if den > 0.0 { (num / den).sqrt() } else { 0.0 })
}

fn write_files(args: &Args, header: &str, rows: &[Row]) -> Result<()> {
    let mut md = format!("# kage report\n\n{header}\n\n");
    md.push_str("| method | configuration | bake (s) | bake size (KB) | leaves / vertex | shade (s / frame) | RMSE | relative RMSE |\n");
    md.push_str("|---|---|---|---|---|---|---|---|\n");
    let mut csv = String::from("method,config,bake_s,bake_bytes,leaves_per_vertex,shade_s,rmse,rel_rmse\n");
    for r in rows {
        writeln!(
            md,
            "| {} | {} | {:.2} | {:.1} | {:.1} | {:.4} | {:.5} | {:.4} |",
            r.method,
            r.config,
            r.bake_s,
            r.bake_bytes as f64 / 1024.0,
            r.leaves_per_vertex,
            r.shade_s,
            r.rmse,
            r.rel_rmse
        )?;
        writeln!(
            csv,
            "{},{},{},{},{},{},{},{}",
            r.method, r.config, r.bake_s, r.bake_bytes, r.leaves_per_vertex, r.shade_s, r.rmse, r.rel_rmse
        )?;
    }
    md.push_str("\nPlot (`report.png`): relative RMSE (vertical) against shade time per frame (horizontal), both log scale; colours: ");
    md.push_str(
        &METHODS
            .iter()
            .map(|(m, c)| format!("{m} = #{:02x}{:02x}{:02x}", c[0], c[1], c[2]))
            .collect::<Vec<_>>()
            .join(", "),
    );
    md.push_str(".\n");
    let write =
        |name: &str, text: &str| std::fs::write(args.out.join(name), text).with_context(|| format!("writing {name}"));
    write("report.md", &md)?;
    write("report.csv", &csv)?;
    plot(rows).save(args.out.join("report.png")).context("writing report.png")
}

const METHODS: [(&str, [u8; 3]); 5] = [
    ("bspvt", [220, 50, 40]),
    ("ltc-exact-vis", [40, 120, 220]),
    ("ltc-unshadowed", [120, 120, 120]),
    ("monte-carlo", [40, 170, 70]),
    ("ratio-estimator", [200, 140, 0]),
];

/// A log–log scatter with lines joining each method's points (no text: the Markdown says
/// which colour is which).
fn plot(rows: &[Row]) -> image::RgbImage {
    let (w, h, m) = (640u32, 400u32, 30.0f64);
    let mut img = image::RgbImage::from_pixel(w, h, image::Rgb([255, 255, 255]));
    let pts: Vec<(f64, f64)> =
        rows.iter().map(|r| (r.shade_s.max(1e-6).log10(), r.rel_rmse.max(1e-5).log10())).collect();
    let (x0, x1) = pts.iter().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.0), b.max(p.0)));
    let (y0, y1) = pts.iter().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.1), b.max(p.1)));
    let to_px = |(x, y): (f64, f64)| {
        let fx = if x1 > x0 { (x - x0) / (x1 - x0) } else { 0.5 };
        let fy = if y1 > y0 { (y - y0) / (y1 - y0) } else { 0.5 };
        (m + fx * (w as f64 - 2.0 * m), h as f64 - m - fy * (h as f64 - 2.0 * m))
    };
    let dot = |img: &mut image::RgbImage, (x, y): (f64, f64), r: i32, c: [u8; 3]| {
        for dy in -r..=r {
            for dx in -r..=r {
                let (px, py) = (x as i32 + dx, y as i32 + dy);
                if px >= 0 && py >= 0 && (px as u32) < w && (py as u32) < h && dx * dx + dy * dy <= r * r {
                    img.put_pixel(px as u32, py as u32, image::Rgb(c));
                }
            }
        }
    };
    for i in 0..w {
        dot(&mut img, (i as f64, h as f64 - m), 0, [0, 0, 0]);
    }
    for j in 0..h {
        dot(&mut img, (m, j as f64), 0, [0, 0, 0]);
    }
    for (name, colour) in METHODS {
        let line: Vec<(f64, f64)> =
            rows.iter().zip(&pts).filter(|(r, _)| r.method == name).map(|(_, p)| to_px(*p)).collect();
        for pair in line.windows(2) {
            for k in 0..=100 {
                let t = k as f64 / 100.0;
                dot(
                    &mut img,
                    (pair[0].0 + t * (pair[1].0 - pair[0].0), pair[0].1 + t * (pair[1].1 - pair[0].1)),
                    1,
                    colour,
                );
            }
        }
        for p in line {
            dot(&mut img, p, 4, colour);
        }
    }
    img
}
