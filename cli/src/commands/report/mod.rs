//! `kage report`: speed against error. Runs each technique's methods and parameter sweeps
//! against the Monte Carlo reference and writes `report.md`, `report.csv` and the plot
//! `report.png`/`.svg` (relative RMSE against time, log–log, a legend per method, points
//! labelled with their configuration) into `--out`, plus `report-rays.png`/`.svg` (error
//! against rays cast) when the cache section ran.
//!
//! Sections run when the scene has what they shade: [`baked`] (the complete look against the
//! full reference, and each light's part alone), [`polygon`] (polygonal lights, the
//! environment dropped), [`prt`] (the environment, polygonal lights removed) and [`cache`] (one
//! bounce of indirect light from all of them). Errors are per vertex toward the scene camera,
//! and for the baked look and PRT also per pixel.

mod baked;
mod cache;
mod plot;
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
    /// Size of the per-pixel comparison images (baked look and PRT), WxH.
    #[arg(long, default_value = "320x180", value_parser = super::render::parse_size)]
    image_size: (usize, usize),
    /// Samples per pixel of the reference images (baked look and PRT).
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
    /// The complete baked look (`--method baked`) and its parts.
    Baked,
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
        let se = kage_engine::reference::relative_standard_error(est.iter().flatten());
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
    // Every section shades toward one camera: the scene's, or the framing of the whole scene.
    let camera = scene.first_camera().unwrap_or_else(|| kage_engine::scene::flatten(&scene).framing_camera());
    let eye = camera.eye();
    let mut rows = Vec::new();
    let mut header = vec![format!("scene {}", scene.source)];
    let has_lights = scene.world.query::<&kage_engine::scene::PolygonLight>().iter().next().is_some();
    let has_env = scene.world.query::<&kage_engine::scene::EnvironmentLight>().iter().next().is_some();
    anyhow::ensure!(
        has_lights || has_env,
        "{}: no polygonal light and no environment: nothing to report",
        scene.source
    );
    if args.wants(Section::Baked) {
        header.push(baked::run(args, &camera, &mut rows)?);
    }
    if has_lights && args.wants(Section::Polygon) {
        header.push(polygon::run(args, eye, &mut rows)?);
    }
    // PRT transfers diffuse light only: it is measured where the surface is Lambertian.
    let has_lambertian = scene.world.query::<&kage_engine::scene::Material>().iter().any(|m| !m.has_specular());
    let mut skipped = None;
    if has_env && args.wants(Section::Prt) {
        if has_lambertian {
            header.push(prt::run(args, &camera, &mut rows)?);
        } else {
            let why = "the PRT section needs a Lambertian surface and the scene has none (PRT transfers the diffuse \
                       part; the baked section measures the environment on glossy surfaces)";
            header.push(format!("PRT: skipped, {why}"));
            skipped = Some(why);
        }
    }
    if args.wants(Section::Cache) {
        header.push(cache::run(args, eye, &mut rows)?);
    }
    anyhow::ensure!(
        !rows.is_empty(),
        "{}: none of the chosen sections applies to this scene{}",
        scene.source,
        skipped.map_or(String::new(), |why| format!(": {why}"))
    );
    if let Some(why) = skipped {
        eprintln!("warning: {why}");
    }
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let title = format!("kage report: {}", scene_name(&scene.source));
    let written = write_files(args, &title, &header.join("\n\n"), &rows)?;
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

/// `text` as one CSV field: quoted (inner quotes doubled) when it holds a comma or a quote.
fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n']) { format!("\"{}\"", text.replace('"', "\"\"")) } else { text.to_string() }
}

/// Writes the report's files; returns their names.
fn write_files(args: &Args, title: &str, header: &str, rows: &[Row]) -> Result<Vec<&'static str>> {
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
            csv_field(&r.config),
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
    let rays = rows.iter().any(|r| r.rays.is_some());
    md.push_str("\n![Relative RMSE against shade time per frame](report.svg)\n\n[report.png](report.png) · [report.svg](report.svg)\n");
    if rays {
        md.push_str("\n![The indirect rows' relative RMSE against rays cast](report-rays.svg)\n\n[report-rays.png](report-rays.png) · [report-rays.svg](report-rays.svg)\n");
    }
    let write = |name: &str, text: &str| {
        let path = args.out.join(name);
        kage_engine::output::write_atomically(&path, |f| std::io::Write::write_all(f, text.as_bytes()))
            .with_context(|| format!("writing {}", path.display()))
    };
    write("report.md", &md)?;
    write("report.csv", &csv)?;
    plot::write(&args.out, "report", &format!("{title}: error against shade time"), rows, &plot::SHADE_TIME)?;
    let mut written = vec!["report.md", "report.csv", "report.png", "report.svg"];
    if rays {
        plot::write(&args.out, "report-rays", &format!("{title}: error against rays cast"), rows, &plot::RAYS)?;
        written.extend(["report-rays.png", "report-rays.svg"]);
    }
    Ok(written)
}

/// A scene's name for titles: the file name of its source, or the source itself.
fn scene_name(source: &str) -> &str {
    std::path::Path::new(source).file_name().and_then(|n| n.to_str()).unwrap_or(source)
}
