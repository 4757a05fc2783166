//! Choosing SH order, window and region count from an error budget ("model only what the
//! scene needs"). A pilot bakes the transfer at a high order once, then:
//! - **order**: the smallest n in 2..=8 whose shading (best of no window and Hanning) is within
//!   the budget of the order-12 unwindowed shading, relative RMSE over the receivers;
//! - **q**: the smallest of 8, 16, 32, 64 whose other-group term `Σ B_i T V_o` is within the
//!   budget (relative to the shading) of a Monte Carlo estimate of the same term (1024
//!   importance-sampled environment rays per pilot vertex, shadow rays against the groups);
//!   skipped when the scene has one group.
//!
//! Shading is measured with head-on albedos, so no camera enters a plan. The order reads only
//! each group's own geometry, orientation, materials and the environment, never where groups
//! are; callers that cache plans ([`choose_order`], [`choose_regions`] apart) keep the order
//! across moves and measure only q again.

use super::lighting::{self, Window};
use super::{Bake, Frame, Lighting, Settings, Shadows, bake, regions};
use crate::accel::{SceneBvh, offset_ray_origin};
use crate::math::{relative_rmse, rng};
use crate::scene::VertexValues;
use crate::scene::{EnvironmentLight, FlatScene, NO_LIGHT, Scene};
use glam::{Vec2, Vec3};
use rand::Rng;
use rayon::prelude::*;

/// The order the others are measured against.
pub const REFERENCE_ORDER: usize = 12;
/// Candidate orders.
pub const ORDERS: std::ops::RangeInclusive<usize> = 2..=8;
/// Candidate region counts.
pub const REGION_COUNTS: [usize; 4] = [8, 16, 32, 64];
/// Pilot vertices for the other-group term.
const PILOT: usize = 400;
/// Environment samples per pilot vertex.
const PILOT_SAMPLES: usize = 1024;

/// What a choice says for a scene without an environment.
pub const NO_ENVIRONMENT: &str = "no environment light: PRT has nothing to shade";

/// The chosen settings with one line per decision, each with the measured errors.
///
/// Shading is measured with every albedo seen head-on ([`Frame::prepare_head_on`]): the bake serves
/// every view, so no camera enters the plan.
pub fn choose(scene: &Scene, flat: &FlatScene, budget: f64, base: &Settings) -> (Settings, Vec<String>) {
    let Some(env) = &flat.environment else {
        return (*base, vec![NO_ENVIRONMENT.into()]);
    };
    let high = pilot(scene, flat, base);
    let (s, why_order) = choose_order(scene, flat, env, budget, base, &high);
    let (s, why_regions) = choose_regions(scene, flat, env, &high.truncated(s.order), budget, &s);
    (s, vec![why_order, why_regions])
}

/// Shading of `b` under `l`, with head-on albedos.
fn shade(scene: &Scene, flat: &FlatScene, b: &Bake, l: &Lighting, m: Shadows, s: &Settings) -> VertexValues {
    Frame::prepare_head_on(scene, flat, b, l, m, s).vertex_values(flat)
}

/// `env` at [`REFERENCE_ORDER`] with no regions, under `window`.
fn unshadowed(coeffs: &lighting::RgbCoeffs, window: Window) -> Lighting {
    let lobes = lighting::negative_lobes(coeffs, window);
    Lighting { coeffs: coeffs.clone(), regions: Vec::new(), window, lobes, sunless: None }
}

/// The transfer the plan measures against: every instance at [`REFERENCE_ORDER`] with `base`'s
/// directions. Like every PRT bake it reads only each group's own geometry.
pub fn pilot(scene: &Scene, flat: &FlatScene, base: &Settings) -> Bake {
    bake(scene, flat, &Settings { order: REFERENCE_ORDER, ..*base }, &|_| {})
}

/// The SH order and window (the rest of `base` kept) and the reason, measured with `high`, the
/// [`pilot`]. Self-shadowed shading reads only each group's own geometry, its orientation, the
/// materials and the environment, so moving a group never changes this choice.
pub fn choose_order(
    scene: &Scene,
    flat: &FlatScene,
    env: &EnvironmentLight,
    budget: f64,
    base: &Settings,
    high: &Bake,
) -> (Settings, String) {
    let coeffs = lighting::project(env, REFERENCE_ORDER);
    let self_only = |b: &Bake, w| shade(scene, flat, b, &unshadowed(&coeffs, w), Shadows::SelfOnly, base).concat();
    let truth = self_only(high, Window::None);
    let mut measured = Vec::new();
    for order in ORDERS {
        let b = high.truncated(order);
        let errs = [Window::None, Window::Hanning].map(|w| (relative_rmse(&self_only(&b, w), &truth), w));
        let (err, window) = if errs[1].0 < errs[0].0 { errs[1] } else { errs[0] };
        let hanning = if window == Window::Hanning { " (Hanning)" } else { "" };
        measured.push(format!("{order}: {:.2} %{hanning}", 100.0 * err));
        let met = err <= budget;
        if met || order == *ORDERS.end() {
            let why = format!(
                "SH order {order}{}: {} budget {:.1} % against order {REFERENCE_ORDER} ({})",
                if window == Window::Hanning { " with a Hanning window" } else { "" },
                if met { "smallest within the" } else { "highest tried; misses the" },
                100.0 * budget,
                measured.join(", ")
            );
            return (Settings { order, window, ..*base }, why);
        }
    }
    unreachable!("the last order always returns")
}

/// The region count for `s` (whose order and window are chosen), measured with `b`, the
/// transfer at `s.order`, against Monte Carlo; the settings with it, and the reason.
pub fn choose_regions(
    scene: &Scene,
    flat: &FlatScene,
    env: &EnvironmentLight,
    b: &Bake,
    budget: f64,
    s: &Settings,
) -> (Settings, String) {
    let groups: std::collections::BTreeSet<_> = flat.instances.iter().map(|i| i.group).collect();
    if groups.len() < 2 {
        return (*s, "one rigid group: no shadows between groups to compute".into());
    }
    let coeffs = lighting::project(env, REFERENCE_ORDER);
    let sample = pilot_vertices(flat);
    let exact = exact_other_term(flat, env, &sample);
    let pick = |v: &[Vec<Vec3>]| sample.iter().map(|&(i, k)| v[i][k]).collect::<Vec<_>>();
    // Self-shadowed shading does not depend on the regions.
    let light = unshadowed(&coeffs, s.window);
    let own = pick(&shade(scene, flat, b, &light, Shadows::SelfOnly, s));
    let den: f64 = own.iter().map(|a| a.as_dvec3().length_squared()).sum();
    let mut measured = Vec::new();
    for q in REGION_COUNTS {
        let l = Lighting { regions: regions::decompose(env, q), ..light.clone() };
        let with = pick(&shade(scene, flat, b, &l, Shadows::WithOthers, &Settings { regions: q, ..*s }));
        let num: f64 =
            own.iter().zip(&with).zip(&exact).map(|((a, b), e)| (*a - *b - *e).as_dvec3().length_squared()).sum();
        let err = if den > 0.0 { (num / den).sqrt() } else { 0.0 };
        measured.push(format!("{q}: {:.2} %", 100.0 * err));
        if err <= budget || q == REGION_COUNTS[REGION_COUNTS.len() - 1] {
            let why = format!(
                "{q} regions: {} budget for the other-group term against Monte Carlo on {} vertices ({})",
                if err <= budget { "smallest within the" } else { "largest tried; misses the" },
                sample.len(),
                measured.join(", ")
            );
            return (Settings { regions: q, ..*s }, why);
        }
    }
    unreachable!("the last candidate always returns")
}

/// An even sample of receiver vertices (instance, vertex).
fn pilot_vertices(flat: &FlatScene) -> Vec<(usize, usize)> {
    let all: Vec<(usize, usize)> = flat.vertex_ids().collect();
    let step = (all.len() / PILOT).max(1);
    all.into_iter().step_by(step).collect()
}

/// Monte Carlo of `ρ/π ∫ L cos V_self (1 − V_others) dω` at each sample vertex.
fn exact_other_term(flat: &FlatScene, env: &EnvironmentLight, sample: &[(usize, usize)]) -> Vec<Vec3> {
    let mut groups: Vec<hecs::Entity> = flat.instances.iter().map(|i| i.group).collect();
    groups.sort();
    groups.dedup();
    let bvhs: Vec<SceneBvh> = groups
        .iter()
        .map(|g| {
            let (tris, holes) = flat.select(|r| r.light == NO_LIGHT && flat.instances[r.owner as usize].group == *g);
            SceneBvh::new(&tris).cut(&holes)
        })
        .collect();
    let albedos = crate::material::albedo::head_on(flat);
    sample
        .par_iter()
        .enumerate()
        .map(|(k, &(i, v))| {
            let (p, n) = flat.vertex(i, v);
            let own = groups.iter().position(|g| *g == flat.instances[i].group).expect("listed");
            let albedo = albedos[i];
            let mut r = rng::stream(0xE0, k as u64);
            let side = (PILOT_SAMPLES as f64).sqrt() as usize;
            let mut sum = Vec3::ZERO;
            for j in 0..side * side {
                let u = Vec2::new(
                    ((j % side) as f32 + r.random::<f32>()) / side as f32,
                    ((j / side) as f32 + r.random::<f32>()) / side as f32,
                );
                let Some(s) = env.sample(u) else { continue };
                let cos = s.dir.dot(n);
                if cos <= 0.0 {
                    continue;
                }
                let o = offset_ray_origin(p, n, s.dir);
                if bvhs[own].occluded_past_touching(o, s.dir, f32::INFINITY) {
                    continue;
                }
                if bvhs.iter().enumerate().any(|(g, b)| g != own && b.occluded_past_touching(o, s.dir, f32::INFINITY)) {
                    sum += s.radiance * cos / (std::f32::consts::PI * s.pdf);
                }
            }
            albedo * sum / (side * side) as f32
        })
        .collect()
}
