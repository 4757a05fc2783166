//! The PRT section: SH orders 2–8 × q ∈ {8, 16, 32, 64} with shadows between groups, next to
//! self-shadowing only, and two windowed rows, against the reference with the polygonal lights
//! removed. Errors cover the Lambertian instances (PRT's scope: a glossy surface gets only its
//! diffuse part), per vertex and per pixel; a frame's time is `Frame::prepare` plus a 2×2-spp
//! image at `--image-size`.

use super::{Args, Row, Truth, announce};
use crate::progress::bar;
use anyhow::{Context, Result};
use glam::Vec3;
use kage_engine::math::relative_rmse;
use kage_engine::prt::{self, Lighting, budget, lighting::Window};
use kage_engine::raster;
use kage_engine::reference::{Renderer, Settings};
use kage_engine::scene::{Camera, Scene};
use std::time::Instant;

/// Everything one measurement needs.
struct Bench<'a> {
    scene: &'a Scene,
    renderer: &'a Renderer,
    camera: &'a Camera,
    size: (usize, usize),
    truth: Truth,
    /// Reference pixels and which pixels count (Lambertian surface under every subsample).
    pixels: Vec<Vec3>,
    mask: Vec<bool>,
}

/// Measures the section into `rows`; returns its header line.
pub fn run(args: &Args, camera: &Camera, rows: &mut Vec<Row>) -> Result<String> {
    let eye = camera.eye();
    let mut scene = args.scene.load()?;
    scene.remove_polygon_lights();
    let renderer = Renderer::new(&scene);
    let keep: Vec<bool> = renderer.flat.instances.iter().map(|i| !i.material.has_specular()).collect();
    let truth =
        Truth::vertices(&renderer, eye, args.reference_spp, (0, 0), keep.clone(), "environment (Lambertian instances)");
    let (w, h) = args.image_size;
    let pb = bar(h as u64, "reference image");
    let settings = Settings { spp: args.reference_image_spp, seed: 0x1A6E, max_bounces: 0, min_bounces: 0 };
    let pixels = renderer.render_image(camera, w, h, &settings, &|r| pb.set_position(r as u64));
    pb.finish_and_clear();
    let coverage =
        raster::shade_image(&renderer, camera, w, h, 4, &|hit| Vec3::splat(f32::from(u8::from(keep[hit.instance]))));
    let bench = Bench {
        scene: &scene,
        renderer: &renderer,
        camera,
        size: (w, h),
        truth,
        pixels: pixels.iter().map(|e| e.mean).collect(),
        mask: coverage.iter().map(|c| c.x == 1.0).collect(),
    };
    let base = prt::Settings { directions: args.directions, window: Window::None, ..prt::Settings::default() };
    let top = *budget::ORDERS.end();
    let lightings: Vec<(usize, Lighting)> = budget::REGION_COUNTS
        .iter()
        .map(|&q| {
            Ok((q, Lighting::new(&scene, &prt::Settings { order: top, regions: q, ..base }).context("no environment")?))
        })
        .collect::<Result<_>>()?;
    let mut push = |row: Row| {
        announce(&row);
        rows.push(row);
    };
    for order in budget::ORDERS {
        let s = prt::Settings { order, ..base };
        let bake = prt::bake(&scene, &renderer.flat, &s, &|_| {});
        push(bench.measure("prt-self", format!("order {order}"), &bake, &lightings[0].1, &s));
        for (q, light) in &lightings {
            push(bench.measure(
                "prt",
                format!("order {order}, {q} regions"),
                &bake,
                light,
                &prt::Settings { regions: *q, ..s },
            ));
        }
    }
    for order in [4, top] {
        let s = prt::Settings { order, window: Window::Hanning, ..base };
        let bake = prt::bake(&scene, &renderer.flat, &s, &|_| {});
        let light = Lighting { window: Window::Hanning, ..lightings[2].1.clone() };
        push(bench.measure("prt", format!("order {order}, {} regions, Hanning", lightings[2].0), &bake, &light, &s));
    }
    let counted = bench.mask.iter().filter(|m| **m).count();
    Ok(format!(
        "{} ({} vertices); reference image {w}×{h} at {} spp ({counted} Lambertian pixels counted); {} transfer directions",
        bench.truth.line,
        renderer.vertex_count(),
        args.reference_image_spp,
        base.direction_side().pow(2)
    ))
}

impl Bench<'_> {
    /// One configuration: a frame (prepare + image), its per-vertex values, and both errors.
    fn measure(
        &self,
        method: &'static str,
        config: String,
        bake: &prt::Bake,
        light: &Lighting,
        s: &prt::Settings,
    ) -> Row {
        let kind = if method == "prt" { prt::Shadows::WithOthers } else { prt::Shadows::SelfOnly };
        let eye = self.camera.eye();
        let t = Instant::now();
        let frame = prt::Frame::prepare(
            self.scene,
            &self.renderer.flat,
            prt::Parts { bake, lighting: light, settings: s },
            kind,
            eye,
        );
        let (w, h) = self.size;
        let image = frame.render(self.renderer, self.camera, w, h, 4);
        let shade_s = t.elapsed().as_secs_f64();
        let values = frame.vertex_values(&self.renderer.flat);
        let pick =
            |v: &[Vec3]| -> Vec<Vec3> { v.iter().zip(&self.mask).filter(|(_, m)| **m).map(|(p, _)| *p).collect() };
        Row {
            bake_s: bake.stats.seconds,
            bake_bytes: bake.stats.bytes,
            pixel_rel_rmse: Some(relative_rmse(&pick(&image), &pick(&self.pixels))),
            ..self.truth.row(method, config, shade_s, &values)
        }
    }
}
