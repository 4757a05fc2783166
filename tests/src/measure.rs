//! Measurements of receiver refinement on the two-triangle floor that `docs/receivers.md` and
//! `docs/benchmarks.md` report: minutes each in a release build, so they run on demand
//! (`cargo xtask measure WHAT`), not in the suite. Each prints one line per configuration.

use crate::asset;
use crate::floor::{
    error, floor_part, look_image, one_group_under_the_sky, over_geometry, reference, reference_with, refined,
    two_triangle_floor, vertices, with_reach,
};
use glam::Vec3;
use kage_engine::receivers::{self, Settings};
use kage_engine::reference::Renderer;
use kage_engine::scene::{EnvMap, EnvironmentLight, NO_LIGHT, Scene, flatten};
use kage_engine::{accel, bspvt};

/// The budgets the error curve is measured at unless others are given.
pub const CURVE_BUDGETS: [usize; 12] = [250, 300, 350, 500, 1000, 2000, 3000, 4000, 6000, 8000, 12000, 16000];

/// The curve of error against vertices, adaptive (at the default tolerance and at 0.005, at
/// `budgets`) against uniform refinement of the floor, with the default trees (64², ε 2), per
/// pixel over geometry against a 4096-spp reference of the same refined scene (a smooth
/// receiver's new vertices lie on its Phong surface, so each refinement has its own geometry),
/// the floor's part of it, and that reference's own noise.
pub fn error_curve(budgets: &[usize]) {
    let (s, camera) = (two_triangle_floor(), two_triangle_floor().first_camera().expect("the floor has a camera"));
    let r = Renderer::new(&s);
    let noise =
        over_geometry(&r, &camera, &reference_with(&r, &camera, 6, 4096), &reference_with(&r, &camera, 5, 4096));
    println!("the reference's own noise (seed 6 against seed 5): {noise:.4}");
    let measure = |scene: &Scene| {
        let r = Renderer::new(scene);
        let (ours, truth) = (look_image(scene, 64), reference_with(&r, &camera, 5, 4096));
        let (whole, floor) = (over_geometry(&r, &camera, &ours, &truth), floor_part(&r, &camera, &ours, &truth));
        format!("{whole:.5}, the floor's part {floor:.5} ({} vertices)", vertices(scene))
    };
    for tolerance in [Settings::default().tolerance, 0.005] {
        for &budget in budgets {
            let mut s = two_triangle_floor();
            receivers::refine(&mut s, &Settings { budget, tolerance, ..Settings::default() })
                .expect("the floor refines");
            println!("adaptive, tolerance {tolerance}, budget {budget}: {}", measure(&s));
        }
    }
    for floor in [2000usize, 4000, 8000, 16000, 32000, 50000] {
        let mut uniform = two_triangle_floor();
        uniform.refine_instances("floor", floor).expect("the scene has a floor");
        println!("uniform, floor {floor}: {}", measure(&uniform));
    }
}

/// Where adaptive refinement stops gaining: BSPVT's own error at the refined floor's vertices
/// (the visible share of the light's diffuse lobe, the tree against a 64 × 64 grid of shadow
/// rays over the light), at 64² and 128² faces, over the vertices in a penumbra, and at one
/// vertex under the slab's edge (`docs/receivers.md#where-adaptive-stops-gaining`).
pub fn bspvt_at_refined_vertices() {
    let s = refined(two_triangle_floor(), Settings::default().budget);
    let flat = flatten(&s);
    let occluders = accel::SceneBvh::new(&flat.select(|r| r.light == NO_LIGHT).0);
    let light = &flat.lights[0];
    let truth = |p: Vec3| {
        let (mut seen, mut all) = (0.0f64, 0.0f64);
        for (i, j) in (0..64).flat_map(|i| (0..64).map(move |j| (i, j))) {
            let [u, w] = [i, j].map(|k| (k as f32 + 0.5) / 64.0);
            let q = light.points[0] + u * (light.points[1] - light.points[0]) + w * (light.points[3] - light.points[0]);
            let (dist, dir) = ((q - p).length(), (q - p).normalize());
            let weight = (dir.y.max(0.0) * (-dir.dot(light.normal)).max(0.0) / (dist * dist)) as f64;
            all += weight;
            seen += if occluders.occluded(p + Vec3::Y * 1e-4, dir, dist * 0.999) { 0.0 } else { weight };
        }
        seen / all
    };
    let floor: Vec<(usize, Vec3, f64)> = (0..flat.vertex_count(0))
        .map(|v| (v, flat.vertex(0, v).0))
        .map(|(v, p)| (v, p, truth(p)))
        .filter(|(_, _, t)| (0.02..0.98).contains(t))
        .collect();
    let camera = s.first_camera().expect("the floor has a camera");
    for res in [64, 128] {
        let bake = bspvt::bake(&flat, &bspvt::Settings { res, epsilon: 2.0 }, &|_| {});
        let mut inside = bspvt::pixel::Inside::default();
        let (lobes, _) = bspvt::pixel::Lobes::at_vertices(&flat, Some(&bake), camera.eye(), inside.flags(&flat));
        let share = |v: usize| {
            let [shadowed, unshadowed] = lobes.vertex(0, v)[0][0];
            (shadowed / unshadowed) as f64
        };
        let errors: Vec<f64> = floor.iter().map(|&(v, _, t)| share(v) - t).collect();
        let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
        let worst = errors.iter().fold(0.0f64, |m, e| m.max(e.abs()));
        println!("{res}²: {} penumbra vertices, error RMS {rms:.4}, worst {worst:.4}", errors.len());
        for &(v, p, t) in floor.iter().filter(|(_, p, _)| p.distance(Vec3::new(0.875, 0.0, -0.375)) < 1e-3) {
            println!("  vertex at {p}: the tree {:.4}, the truth {t:.4}", share(v));
        }
    }
}

/// What refining a light without a declared reach for every place it could go would cost: the
/// floor scene's light declared free to go anywhere above the floor, against refinement for
/// where it is, by budget (error at the light's place).
pub fn anywhere_against_where_it_is() {
    let room = [Vec3::new(-4.0, 0.5, -4.0), Vec3::new(4.0, 6.0, 4.0)];
    for budget in [2000usize, 6000, 12000, 24000] {
        let (here, n) = error(&refined(two_triangle_floor(), budget));
        let (anywhere, m) = error(&refined(with_reach(two_triangle_floor(), room), budget));
        println!("budget {budget}: for where it is {here:.4} ({n}), for anywhere above the floor {anywhere:.4} ({m})");
    }
}

/// The environment's part of the refinement: the one-group scene under each map, seeded only
/// (0 rounds) against refined, and the reference's own noise.
pub fn environment_refinement() {
    for map in ["studio", "city", "sky"] {
        let path = asset(&format!("envmaps/{map}.hdr"));
        let env = || EnvironmentLight::new(EnvMap::load(&path).expect("the repository's maps load"));
        let s = one_group_under_the_sky().with_environment(env());
        let (camera, r) = (s.first_camera().expect("the floor has a camera"), Renderer::new(&s));
        let noise = over_geometry(&r, &camera, &reference(&r, &camera, 6), &reference(&r, &camera, 5));
        for (budget, rounds) in [(1000, 0), (1000, 12), (4000, 0), (4000, 12), (8000, 12)] {
            let mut t = one_group_under_the_sky().with_environment(env());
            receivers::refine(&mut t, &Settings { budget, rounds, ..Settings::default() }).expect("the floor refines");
            let (e, n) = error(&t);
            println!("{map} (reference noise {noise:.4}), budget {budget}, {rounds} rounds: {e:.4} ({n} vertices)");
        }
    }
}
