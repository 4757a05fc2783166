//! `kage report`: speed against error. Runs each technique's methods and parameter sweeps
//! against the Monte Carlo reference and writes `report.md`, `report.csv` and `report.png`
//! (relative RMSE against time, log–log, one colour per method) into `--out`, plus
//! `report-rays.png` (error against rays cast) when the cache section ran.
//!
//! Sections run when the scene has what they shade: [`polygon`] (polygonal lights, the
//! environment dropped), [`prt`] (the environment, polygonal lights removed) and [`cache`] (one
//! bounce of indirect light from all of them). Errors are per vertex toward the scene camera,
//! and for PRT also per pixel.

mod cache;
mod polygon;
mod prt;

use crate::progress::bar;
use crate::scene_args::SceneArgs;
use anyhow::{Context, Result};
use glam::Vec3;
use kage_engine::reference::{Renderer, Settings};
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
    /// Size of the per-pixel comparison images (PRT), WxH.
    #[arg(long, default_value = "320x180", value_parser = super::render::parse_size)]
    image_size: (usize, usize),
    /// Samples per pixel of the reference image (PRT).
    #[arg(long, default_value_t = 256)]
    reference_image_spp: u32,
    /// PRT transfer directions per vertex.
    #[arg(long, default_value_t = 1024)]
    directions: usize,
    /// Run only these sections (comma-separated; default: every section the scene supports).
    #[arg(long, value_delimiter = ',')]
    only: Vec<Section>,
}

/// A part of the report.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
enum Section {
    /// Polygonal lights: BSPVT and its competitors.
    Polygon,
    /// The environment: PRT.
    Prt,
    /// One bounce of indirect light: the HSH radiance cache.
    Cache,
}

impl Args {
    fn wants(&self, section: Section) -> bool {
        self.only.is_empty() || self.only.contains(&section)
    }
}

/// One measured configuration.
pub(crate) struct Row {
    method: &'static str,
    config: String,
    bake_s: f64,
    bake_bytes: usize,
    /// BSPVT leaves per vertex (0 for other methods).
    leaves_per_vertex: f64,
    shade_s: f64,
    rmse: f64,
    rel_rmse: f64,
    /// Per-pixel relative RMSE, where the method is measured per pixel.
    pixel_rel_rmse: Option<f64>,
    /// BSPVT: relative RMSE against `ltc-exact-vis` (the tree's own error).
    tree_rel_rmse: Option<f64>,
    /// Indirect light: rays cast (gathering, or the cache's records).
    rays: Option<usize>,
}

/// The reference a section measures against: per-vertex means of the instances it keeps, and
/// the header line about it.
pub(crate) struct Truth {
    values: Vec<Vec3>,
    keep: Vec<bool>,
    line: String,
}

impl Truth {
    /// Per-vertex reference toward `eye` with `spp` samples over the instances in `keep`,
    /// counting light after `(min, max)` bounces, timed, with its own standard error.
    fn vertices(renderer: &Renderer, eye: Vec3, spp: u32, bounces: (u32, u32), keep: Vec<bool>, what: &str) -> Self {
        let pb = bar(renderer.vertex_count() as u64, "reference");
        let start = Instant::now();
        let est = renderer.render_vertices(
            eye,
            &Settings { spp, seed: 0x5EED, min_bounces: bounces.0, max_bounces: bounces.1 },
            &|k| pb.set_position(k as u64),
        );
        pb.finish_and_clear();
        let secs = start.elapsed().as_secs_f64();
        let est: Vec<_> = est.into_iter().zip(&keep).filter(|(_, k)| **k).map(|(e, _)| e).collect();
        let (se2, mean2) = est.iter().flatten().fold((0.0, 0.0), |(a, b), e| {
            (a + e.std_error.as_dvec3().length_squared(), b + e.mean.as_dvec3().length_squared())
        });
        let se = (se2 / mean2.max(f64::MIN_POSITIVE)).sqrt();
        Self {
            values: est.iter().flatten().map(|e| e.mean).collect(),
            keep,
            line: format!(
                "{what}: reference {spp} spp per vertex in {secs:.1} s, its own relative standard error {se:.4}"
            ),
        }
    }

    /// A row measured against this reference.
    fn row(&self, method: &'static str, config: String, shade_s: f64, values: &[Vec<Vec3>]) -> Row {
        let kept = values.iter().zip(&self.keep).filter(|(_, k)| **k).flat_map(|(v, _)| v.iter().copied());
        let (rmse, rel_rmse) = rel(kept, &self.values);
        Row {
            method,
            config,
            bake_s: 0.0,
            bake_bytes: 0,
            leaves_per_vertex: 0.0,
            shade_s,
            rmse,
            rel_rmse,
            pixel_rel_rmse: None,
            tree_rel_rmse: None,
            rays: None,
        }
    }
}

/// Runs the sections the scene supports and writes the report.
pub fn run(args: &Args) -> Result<()> {
    let scene = args.scene.load()?;
    let eye = scene.first_camera().map(|c| c.eye()).context("the scene has no camera to shade toward")?;
    let mut rows = Vec::new();
    let mut header = vec![format!("scene {}", scene.source)];
    let has_lights = scene.world.query::<&kage_engine::scene::PolygonLight>().iter().next().is_some();
    let has_env = scene.world.query::<&kage_engine::scene::EnvironmentLight>().iter().next().is_some();
    anyhow::ensure!(
        has_lights || has_env,
        "{}: no polygonal light and no environment: nothing to report",
        scene.source
    );
    if has_lights && args.wants(Section::Polygon) {
        header.push(polygon::run(args, eye, &mut rows)?);
    }
    if has_env && args.wants(Section::Prt) {
        header.push(prt::run(args, eye, &mut rows)?);
    }
    if args.wants(Section::Cache) {
        header.push(cache::run(args, eye, &mut rows)?);
    }
    anyhow::ensure!(!rows.is_empty(), "{}: none of the chosen sections applies to this scene", scene.source);
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let written = write_files(args, &header.join("\n\n"), &rows)?;
    crate::emit(&format!("wrote {}/{}\n", args.out.display(), written.join(", ")));
    Ok(())
}

/// Prints one row as it is measured.
fn announce(r: &Row) {
    let pixel = r.pixel_rel_rmse.map_or(String::new(), |p| format!("  per pixel {p:.4}"));
    crate::emit(&format!(
        "{:15} {:28} bake {:8.2} s  shade {:8.3} s  rel RMSE {:.4}{pixel}\n",
        r.method, r.config, r.bake_s, r.shade_s, r.rel_rmse
    ));
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

/// Writes the report's files; returns their names.
fn write_files(args: &Args, header: &str, rows: &[Row]) -> Result<Vec<&'static str>> {
    let mut md = format!("# kage report\n\n{header}\n\n");
    md.push_str("| method | configuration | bake (s) | bake size (KB) | leaves / vertex | shade (s / frame) | RMSE | relative RMSE | per-pixel relative RMSE | tree error (vs exact-vis) |\n");
    md.push_str("|---|---|---|---|---|---|---|---|---|---|\n");
    let mut csv = String::from(
        "method,config,bake_s,bake_bytes,leaves_per_vertex,shade_s,rmse,rel_rmse,pixel_rel_rmse,tree_rel_rmse,rays\n",
    );
    let dash = |x: Option<f64>| x.map_or("—".to_string(), |p| format!("{p:.4}"));
    for r in rows {
        let (pixel, tree) = (dash(r.pixel_rel_rmse), dash(r.tree_rel_rmse));
        writeln!(
            md,
            "| {} | {} | {:.2} | {:.1} | {:.1} | {:.4} | {:.5} | {:.4} | {pixel} | {tree} |",
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
            "{},{},{},{},{},{},{},{},{},{},{}",
            r.method,
            r.config,
            r.bake_s,
            r.bake_bytes,
            r.leaves_per_vertex,
            r.shade_s,
            r.rmse,
            r.rel_rmse,
            r.pixel_rel_rmse.map_or(String::new(), |p| p.to_string()),
            r.tree_rel_rmse.map_or(String::new(), |p| p.to_string()),
            r.rays.map_or(String::new(), |n| n.to_string())
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
    let rays = rows.iter().any(|r| r.rays.is_some());
    if rays {
        md.push_str("\nPlot (`report-rays.png`): the indirect rows' relative RMSE against rays cast, both log scale, same colours.\n");
    }
    let write =
        |name: &str, text: &str| std::fs::write(args.out.join(name), text).with_context(|| format!("writing {name}"));
    write("report.md", &md)?;
    write("report.csv", &csv)?;
    plot(rows, |r| Some(r.shade_s)).save(args.out.join("report.png")).context("writing report.png")?;
    let mut written = vec!["report.md", "report.csv", "report.png"];
    if rays {
        let png = args.out.join("report-rays.png");
        plot(rows, |r| r.rays.map(|n| n as f64)).save(png).context("writing report-rays.png")?;
        written.push("report-rays.png");
    }
    Ok(written)
}

const METHODS: [(&str, [u8; 3]); 12] = [
    ("bspvt", [220, 50, 40]),
    ("ltc-exact-vis", [40, 120, 220]),
    ("ltc-unshadowed", [120, 120, 120]),
    ("monte-carlo", [40, 170, 70]),
    ("ratio-estimator", [200, 140, 0]),
    ("prt", [150, 40, 180]),
    ("prt-self", [0, 170, 170]),
    ("indirect-gather", [90, 60, 20]),
    ("hsh-cache", [230, 100, 180]),
    ("hsh-cache-no-gradients", [160, 160, 40]),
    ("hsh-cache-numerical-gradients", [60, 200, 120]),
    ("hsh-cache-wide-blend", [100, 100, 230]),
];

/// A log–log scatter of relative RMSE against `x` (rows without it are left out) with lines
/// joining each method's points from left to right (no text: the Markdown says which colour is
/// which).
fn plot(rows: &[Row], x: impl Fn(&Row) -> Option<f64>) -> image::RgbImage {
    let (w, h, m) = (640u32, 400u32, 30.0f64);
    let mut img = image::RgbImage::from_pixel(w, h, image::Rgb([255, 255, 255]));
    let rows: Vec<(&Row, f64)> = rows.iter().filter_map(|r| x(r).map(|x| (r, x))).collect();
    let pts: Vec<(f64, f64)> = rows.iter().map(|(r, x)| (x.max(1e-6).log10(), r.rel_rmse.max(1e-5).log10())).collect();
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
        let mut line: Vec<(f64, f64)> =
            rows.iter().zip(&pts).filter(|((r, _), _)| r.method == name).map(|(_, p)| to_px(*p)).collect();
        line.sort_by(|a, b| a.0.total_cmp(&b.0));
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
