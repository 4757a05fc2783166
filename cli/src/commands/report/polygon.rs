//! The polygonal-light section: BSPVT sweeps (face resolution, ε), exact visibility, no
//! visibility, and at equal time Monte Carlo shadow rays and the ratio estimator, per vertex
//! with the environment dropped.

use super::{Args, Row, Truth, announce, rel};
use anyhow::Result;
use glam::Vec3;
use kage_engine::bspvt;
use kage_engine::reference::{Renderer, Settings};
use kage_engine::scene::VertexValues;
use kage_engine::shading::ratio;
use std::time::Instant;

/// Measures the section into `rows`; returns its header line.
pub fn run(args: &Args, eye: Vec3, rows: &mut Vec<Row>) -> Result<String> {
    let mut scene = args.scene.load()?;
    scene.clear_environment();
    let renderer = Renderer::new(&scene);
    let all = vec![true; renderer.flat.instances.len()];
    let truth = Truth::vertices(&renderer, eye, args.reference_spp, (0, 0), all, "polygonal lights");
    let mut push = |row: Row| {
        announce(&row);
        rows.push(row);
    };
    let exact_s = bspvt::Settings::default();
    let t = Instant::now();
    let exact = bspvt::shade_vertices(&renderer.flat, bspvt::Shadows::Exact { res: exact_s.res }, eye);
    push(truth.row("ltc-exact-vis", "64² faces (cast per frame)".into(), t.elapsed().as_secs_f64(), &exact));
    let exact_flat: Vec<Vec3> = exact.iter().flatten().copied().collect();
    for (res, eps) in [(16, 2.0), (32, 2.0), (64, 2.0), (64, 0.5)] {
        let s = bspvt::Settings { res, epsilon: eps };
        let b = bspvt::bake(&renderer.flat, &s, &|_| {});
        let t = Instant::now();
        let v = bspvt::shade_vertices(&renderer.flat, bspvt::Shadows::Trees(&b), eye);
        let st = b.stats;
        // Against exact visibility at the tree's own face resolution (64² above).
        let tree = (res == exact_s.res).then(|| rel(v.iter().flatten().copied(), &exact_flat).1);
        push(Row {
            bake_s: st.seconds,
            bake_bytes: st.bytes,
            leaves_per_vertex: st.leaves as f64 / st.vertices.max(1) as f64,
            tree_rel_rmse: tree,
            ..truth.row("bspvt", format!("{res}² faces, ε {eps}"), t.elapsed().as_secs_f64(), &v)
        });
    }
    let t = Instant::now();
    let v = bspvt::shade_vertices(&renderer.flat, bspvt::Shadows::Unshadowed, eye);
    push(truth.row("ltc-unshadowed", String::new(), t.elapsed().as_secs_f64(), &v));
    for spp in [1u32, 4, 16, 64] {
        let t = Instant::now();
        let est = renderer.render_vertices(eye, &Settings { spp, seed: 7, max_bounces: 0, min_bounces: 0 }, &|_| {});
        let v: VertexValues = est.iter().map(|e| e.iter().map(|x| x.mean).collect()).collect();
        push(truth.row("monte-carlo", format!("{spp} spp"), t.elapsed().as_secs_f64(), &v));
    }
    for rays in [1u32, 4, 16] {
        let t = Instant::now();
        let v = ratio::shade_vertices(&renderer, rays, 7, eye);
        push(truth.row("ratio-estimator", format!("{rays} rays per light"), t.elapsed().as_secs_f64(), &v));
    }
    Ok(format!("{} ({} vertices, {} lights)", truth.line, renderer.vertex_count(), renderer.flat.lights.len()))
}
