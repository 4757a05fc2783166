//! Choosing bake parameters from an error budget ("model only what the scene needs"): a pilot
//! bakes an even sample of receiver vertices with candidate (face resolution, ε) pairs, cheapest
//! first, and measures each against exact visibility at twice the finest resolution; the
//! cheapest configuration within the budget wins, and the choice says why.

use super::memo::SubtreeMemo;
use super::shade::{PointShader, Visibility};
use super::{Settings, bake_vertex, occluder_bvh, visibility};
use crate::math::{ltc, relative_rmse};
use crate::scene::FlatScene;
use glam::Vec3;
use rayon::prelude::*;

/// Candidate (face resolution, ε), cheapest first: resolution costs rays and tree work as res²,
/// a smaller ε more splits.
const CANDIDATES: [(usize, f64); 6] = [(16, 2.0), (32, 4.0), (32, 2.0), (64, 4.0), (64, 2.0), (64, 1.0)];

/// Vertices in the pilot.
const PILOT: usize = 192;

/// The chosen settings and a one-line reason with the measured pilot errors.
pub fn choose(flat: &FlatScene, budget: f64, eye: Vec3) -> (Settings, String) {
    let all: Vec<(usize, usize)> = flat.vertex_ids().collect();
    if all.is_empty() || flat.lights.is_empty() {
        return (Settings::default(), "no polygonal light or no receiver: nothing to bake".into());
    }
    let step = (all.len() / PILOT).max(1);
    let sample: Vec<(usize, usize)> = all.into_iter().step_by(step).collect();
    let occ = occluder_bvh(flat);
    let table = ltc::table();
    let reach = super::Reach::of_scene(flat);
    let truth_res = 2 * CANDIDATES[CANDIDATES.len() - 1].0;
    let shade = |s: Settings, exact: bool| -> Vec<Vec3> {
        let tiles = SubtreeMemo::new(&s);
        sample
            .par_iter()
            .map(|&(i, v)| {
                let (p, n) = flat.vertex(i, v);
                let shader = PointShader::new(&table, p, n, eye, &flat.vertex_material(i, v));
                if exact {
                    shader.shade(&flat.lights, Visibility::Exact(&visibility::cast_with_hits(&occ, p, n, s.res)))
                } else {
                    shader.shade(
                        &flat.lights,
                        Visibility::Tree(&bake_vertex(&occ, p, n, &tiles, &reach).record, tiles.settings().res),
                    )
                }
            })
            .collect()
    };
    let truth = shade(Settings { res: truth_res, ..Settings::default() }, true);
    let mut measured = Vec::new();
    for (res, epsilon) in CANDIDATES {
        let candidate = Settings { res, epsilon };
        let err = relative_rmse(&shade(candidate, false), &truth);
        measured.push(format!("{res}² ε {epsilon}: {:.2} %", 100.0 * err));
        if err <= budget {
            let why = format!(
                "error budget {:.2} %: {res}² faces, ε {epsilon} (pilot on {} vertices against exact visibility at {truth_res}²: {})",
                100.0 * budget,
                sample.len(),
                measured.join(", ")
            );
            return (candidate, why);
        }
    }
    let (res, epsilon) = CANDIDATES[CANDIDATES.len() - 1];
    let why = format!(
        "error budget {:.2} % not reached: using the finest, {res}² faces, ε {epsilon} ({})",
        100.0 * budget,
        measured.join(", ")
    );
    (Settings { res, epsilon }, why)
}
