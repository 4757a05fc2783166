//! The radiance-cache section: one bounce of indirect light per vertex against the reference's
//! one-bounce term, for brute-force gathering (64, 256, 1024 rays per vertex) and the HSH cache
//! (orders 2–6 × accuracy 0.3 and 0.5 — record density —; 64 and 128 rays per record; the
//! wide blend; without gradients), over every receiver, Lambertian and glossy (imported glTF
//! materials are GGX dielectrics, so on most assets only glossy receivers exist). The gather
//! rays' hits are lit by the reference's per-vertex direct light (exact for Lambertian hit
//! surfaces). "shade" is the whole indirect pass: placing and gathering the records and every
//! lookup (or the whole brute-force gather). For Lambertian receivers only bands 0–1 reach the
//! result (the cosine lies in the span of order 2); the order matters for glossy receivers.

use super::{Args, Row, Truth, announce};
use anyhow::Result;
use glam::Vec3;
use kage_engine::cache::record::{GLOSSY_SPP, Glossy, Source};
use kage_engine::cache::{Blend, Settings as CacheSettings, gather_vertices, indirect_vertices};
use kage_engine::reference::{Renderer, Settings};
use kage_engine::scene::VertexValues;
use std::time::Instant;

/// Measures the section into `rows`; returns its header line.
pub fn run(args: &Args, eye: Vec3, rows: &mut Vec<Row>) -> Result<String> {
    let scene = args.scene.load()?;
    let renderer = Renderer::new(&scene);
    let instances = &renderer.flat.instances;
    let direct_spp = (args.reference_spp / 4).max(16);
    let direct: VertexValues = renderer
        .render_vertices(eye, &Settings { spp: direct_spp, seed: 0xD1, ..Settings::default() }, &|_| {})
        .iter()
        .map(|v| v.iter().map(|e| e.mean).collect())
        .collect();
    let truth = Truth::vertices(
        &renderer,
        eye,
        args.reference_spp,
        (1, 1),
        vec![true; instances.len()],
        "one bounce of indirect light (every receiver)",
    );
    let src = Source { renderer: &renderer, direct: &direct, glossy: Glossy::Reference(GLOSSY_SPP) };
    let n = renderer.vertex_count();
    let mut push = |row: Row| {
        announce(&row);
        rows.push(row);
    };
    for rays in [64usize, 256, 1024] {
        let t = Instant::now();
        let v = gather_vertices(&src, rays, eye);
        let config = format!("{rays} rays per vertex ({} rays)", n * rays);
        push(Row { rays: Some(n * rays), ..truth.row("indirect-gather", config, t.elapsed().as_secs_f64(), &v) });
    }
    let mut cache_row = |method: &'static str, s: CacheSettings| {
        let t = Instant::now();
        let (v, cache) = indirect_vertices(&src, &s, eye);
        let secs = t.elapsed().as_secs_f64();
        let config =
            format!("order {}, a {}: {} records, {} rays", s.order, s.accuracy, cache.records.len(), cache.rays());
        push(Row { rays: Some(cache.rays()), ..truth.row(method, config, secs, &v) });
    };
    for order in 2..=6 {
        for accuracy in [0.3f32, 0.5] {
            cache_row("hsh-cache", CacheSettings { order, accuracy, ..CacheSettings::default() });
        }
    }
    // The error-against-rays curve: fewer rays per record, denser records; Ward's blend copies
    // a record's noise to its vertex, the wide blend averages neighbours.
    for (rays, accuracy) in [(64usize, 0.2f32), (128, 0.2)] {
        cache_row("hsh-cache", CacheSettings { rays, accuracy, ..CacheSettings::default() });
    }
    for (rays, accuracy) in [(64usize, 0.2f32), (64, 0.3), (128, 0.2), (128, 0.3), (256, 0.3)] {
        let blend = Blend::Wide;
        cache_row("hsh-cache-wide-blend", CacheSettings { rays, accuracy, blend, ..CacheSettings::default() });
    }
    cache_row("hsh-cache-no-gradients", CacheSettings { gradients: false, ..CacheSettings::default() });
    let numerical = kage_engine::cache::record::GradientForm::Numerical;
    cache_row("hsh-cache-numerical-gradients", CacheSettings { gradient_form: numerical, ..CacheSettings::default() });
    let lambertian: usize = (0..instances.len())
        .filter(|&i| !instances[i].material.has_specular())
        .map(|i| renderer.mesh(i).positions.len())
        .sum();
    Ok(format!(
        "{} ({n} vertices, {lambertian} of them Lambertian; hits lit by the reference's direct light at {direct_spp} spp)",
        truth.line
    ))
}
