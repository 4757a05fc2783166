//! The HSH radiance cache: projections, gradients against finite differences of re-gathered
//! records, hard placements, determinism, and accuracy against the one-bounce reference.

use glam::{Affine3A, Vec3};
use kage_engine::cache::record::{GLOSSY_SPP, Glossy, GradientForm, MIN_COS_XI, Params, Source, gather};
use kage_engine::cache::{Blend, Cache, Settings, gather_vertices, indirect_vertices};
use kage_engine::math::hsh;
use kage_engine::reference::{Renderer, Settings as RefSettings};
use kage_engine::scene::{Material, Scene, shapes};

/// The eye every per-vertex estimate looks from.
const EYE: Vec3 = Vec3::new(0.0, 5.0, 5.0);

fn lambert(c: f32) -> Material {
    Material::lambertian(Vec3::splat(c))
}

#[test]
fn irradiance_of_projected_constant_and_cosine_radiance_is_exact() {
    let cache = Cache::new(Settings::default(), 1.0);
    let constant = hsh::project(3, 64, |_| 2.0);
    let c: Vec<glam::DVec3> = constant.iter().map(|&v| glam::DVec3::splat(v)).collect();
    assert!((cache.irradiance(&c).x as f64 - 2.0 * std::f64::consts::PI).abs() < 1e-6);
    // L = cos θ is in the span of order 2 (H_10 is linear in cos θ): ∫ cos² = 2π/3.
    let lobe = hsh::project(3, 64, |d| d.z);
    let c: Vec<glam::DVec3> = lobe.iter().map(|&v| glam::DVec3::splat(v)).collect();
    assert!((cache.irradiance(&c).x as f64 - 2.0 * std::f64::consts::PI / 3.0).abs() < 1e-6);
}

/// A 40×40 ceiling at height 1 (facing down) whose radiance grows along x: L = 1 + 0.4 x.
fn ceiling() -> (Renderer, Vec<Vec<Vec3>>) {
    let mut s = Scene::new("ceiling");
    let down = Affine3A::from_rotation_translation(glam::Quat::from_rotation_x(std::f32::consts::PI), Vec3::Y);
    s.add_object("ceiling", shapes::grid(40.0, 200), lambert(0.5), down);
    let r = Renderer::new(&s);
    let direct = vec![(0..r.mesh(0).positions.len()).map(|v| Vec3::splat(1.0 + 0.4 * r.vertex(0, v).0.x)).collect()];
    (r, direct)
}

#[test]
fn gradients_match_central_differences_of_regathered_records() {
    let (renderer, direct) = ceiling();
    let src = Source { renderer: &renderer, direct: &direct, glossy: Glossy::Reference(GLOSSY_SPP) };
    let analytic = Params {
        order: 3,
        side: 64,
        bounds: (0.0, f32::INFINITY),
        form: GradientForm::Analytic,
        min_cos_xi: MIN_COS_XI,
        noise: f32::INFINITY,
        noise_floor: 0.0,
    };
    let at = |p: Vec3| gather(&src, p, Vec3::Y, &analytic, 7);
    let r0 = at(Vec3::ZERO);
    let h = 0.01;
    let fd = |axis: Vec3| -> Vec<f64> {
        let (plus, minus) = (at(axis * h), at(-axis * h));
        plus.coeffs.iter().zip(&minus.coeffs).map(|(a, b)| (a.x - b.x) / (2.0 * h as f64)).collect()
    };
    let (along, across) = (fd(r0.frame.t), fd(r0.frame.b));
    // The slope runs along t (world x): its largest coefficient sets the scale for both axes.
    let scale = along.iter().map(|v| v.abs()).fold(0.0, f64::max);
    assert!(scale > 0.5, "{along:?}");
    // Not identical estimators: the gradient forms hold hit points fixed (with cos ξ clamped at
    // 0.1 for grazing hits), the re-gathered records hold directions fixed. Measured: analytic
    // within 4.4 % of the scale (0.934 vs 0.957 for the largest), numerical (H7–H8, whose
    // clamp drops the grazing hits' cos ξ change) within about 8 %; across the slope, within 0.9 %.
    let numerical = Params { form: GradientForm::Numerical, ..analytic };
    for (params, tolerance) in [(analytic, 0.06), (numerical, 0.1)] {
        let r = gather(&src, Vec3::ZERO, Vec3::Y, &params, 7);
        for (grad, fd) in [(&r.grad_x, &along), (&r.grad_y, &across)] {
            for (k, (g, f)) in grad.iter().zip(fd).enumerate() {
                let form = params.form;
                assert!(
                    (g.x - f).abs() < tolerance * scale,
                    "coefficient {k}: {form:?} {} vs finite difference {f}",
                    g.x
                );
            }
        }
    }
}

#[test]
fn unclamped_the_numerical_and_analytic_gradients_are_the_same_derivative() {
    let (renderer, direct) = ceiling();
    let src = Source { renderer: &renderer, direct: &direct, glossy: Glossy::Reference(GLOSSY_SPP) };
    let analytic = Params {
        order: 4,
        side: 64,
        bounds: (0.0, f32::INFINITY),
        form: GradientForm::Analytic,
        min_cos_xi: 0.0,
        noise: f32::INFINITY,
        noise_floor: 0.0,
    };
    let numerical = Params { form: GradientForm::Numerical, ..analytic };
    // Straight under the slope, and tilted (hit normals off the record's axis): the forms agree
    // to the central difference's own error (measured 1e-6 of the largest gradient).
    for (p, n) in [(Vec3::ZERO, Vec3::Y), (Vec3::new(0.5, 0.0, -0.3), Vec3::new(0.3, 1.0, 0.2).normalize())] {
        let (a, b) = (gather(&src, p, n, &analytic, 3), gather(&src, p, n, &numerical, 3));
        assert_eq!(a.coeffs, b.coeffs, "the coefficients do not depend on the gradient form");
        let all = |r: &kage_engine::cache::record::Record| [r.grad_x.clone(), r.grad_y.clone()].concat();
        let scale = all(&a).iter().map(|g| g.x.abs()).fold(0.0, f64::max);
        let worst = all(&a).iter().zip(all(&b)).map(|(a, b)| (a.x - b.x).abs()).fold(0.0, f64::max);
        assert!(worst < 1e-5 * scale, "the forms differ by {worst} (scale {scale})");
    }
}

#[test]
fn corners_clamp_the_radius_and_opposite_normals_get_their_own_record() {
    // A corner: ground and two walls meeting at the origin.
    let mut s = Scene::new("corner");
    s.add_object("ground", shapes::grid(2.0, 8), lambert(0.5), Affine3A::from_translation(Vec3::new(1.0, 0.0, 1.0)));
    let wall = |rot: glam::Quat, at: Vec3| Affine3A::from_rotation_translation(rot, at);
    s.add_object(
        "wall x",
        shapes::grid(2.0, 8),
        lambert(0.5),
        wall(glam::Quat::from_rotation_z(-std::f32::consts::FRAC_PI_2), Vec3::new(0.0, 1.0, 1.0)),
    );
    s.add_object(
        "wall z",
        shapes::grid(2.0, 8),
        lambert(0.5),
        wall(glam::Quat::from_rotation_x(std::f32::consts::FRAC_PI_2), Vec3::new(1.0, 1.0, 0.0)),
    );
    let r = Renderer::new(&s);
    let direct: Vec<Vec<Vec3>> = (0..3).map(|i| vec![Vec3::ONE; r.mesh(i).positions.len()]).collect();
    let src = Source { renderer: &r, direct: &direct, glossy: Glossy::Reference(GLOSSY_SPP) };
    let params = Params {
        order: 3,
        side: 16,
        bounds: (0.05, 1.0),
        form: GradientForm::Analytic,
        min_cos_xi: MIN_COS_XI,
        noise: f32::INFINITY,
        noise_floor: 0.0,
    };
    let rec = gather(&src, Vec3::splat(1e-3), Vec3::Y, &params, 1);
    assert_eq!(rec.radius, 0.05, "R → 0 in a corner is clamped");
    assert!(rec.coeffs.iter().chain(&rec.grad_x).chain(&rec.grad_y).all(|c| c.is_finite()));
    let mut cache = Cache::new(Settings::default(), 2.0);
    assert_eq!(cache.place(&src, &[(Vec3::new(1.0, 0.0, 1.0), Vec3::Y)]), 1);
    // The same point seen from below: no record is usable, so lookup says so and placement adds one.
    assert!(cache.incoming(Vec3::new(1.0, 0.0, 1.0), -Vec3::Y).is_none());
    assert_eq!(cache.place(&src, &[(Vec3::new(1.0, 0.0, 1.0), -Vec3::Y)]), 1);
    assert!(cache.incoming(Vec3::new(1.0, 0.0, 1.0), -Vec3::Y).is_some_and(|c| c.iter().all(|v| v.is_finite())));
}

/// A ground of material `ground`, a Lambertian sphere and a quad light; per-vertex direct light
/// from the reference (exact for the Lambertian sphere the gathers hit, whatever the eye).
fn lit_room(ground: Material) -> (Renderer, Vec<Vec<Vec3>>) {
    let r = Renderer::new(&room(ground));
    let est = r.render_vertices(EYE, &RefSettings { spp: 256, seed: 3, ..Default::default() }, &|_| {});
    let direct = est.iter().map(|v| v.iter().map(|e| e.mean).collect()).collect();
    (r, direct)
}

/// A ground (instance 0) with a Lambertian sphere (instance 1) on it under a quad light.
fn room(ground: Material) -> Scene {
    let mut s = Scene::new("room");
    s.add_object("ground", shapes::grid(6.0, 30), ground, Affine3A::IDENTITY);
    // Finely tessellated: hits see per-vertex direct light interpolated, which a coarse box's
    // four corners per face would not resolve.
    s.add_object(
        "sphere",
        shapes::sphere(0.8, 48, 24),
        lambert(0.7),
        Affine3A::from_translation(Vec3::new(0.0, 0.85, 0.0)),
    );
    let h = 0.5;
    let quad = vec![Vec3::new(-h, 0.0, -h), Vec3::new(h, 0.0, -h), Vec3::new(h, 0.0, h), Vec3::new(-h, 0.0, h)];
    s.add_light("light", quad, Vec3::splat(20.0), Affine3A::from_translation(Vec3::new(1.5, 3.0, 0.5)));
    s
}

/// The reference's one-bounce term per vertex at 1024 spp (its own noise ≈ 3 %).
fn one_bounce(renderer: &kage_engine::reference::Renderer) -> Vec<Vec<Vec3>> {
    let settings = RefSettings { spp: 1024, seed: 5, max_bounces: 1, min_bounces: 1 };
    renderer.render_vertices(EYE, &settings, &|_| {}).iter().map(|v| v.iter().map(|e| e.mean).collect()).collect()
}

fn rel(x: &[Vec<Vec3>], r: &[Vec<Vec3>]) -> f64 {
    kage_engine::math::relative_rmse(&x.concat(), &r.concat())
}

#[test]
fn the_cache_matches_the_one_bounce_reference_with_far_fewer_rays_than_gathering() {
    let (renderer, direct) = lit_room(lambert(0.7));
    let src = Source { renderer: &renderer, direct: &direct, glossy: Glossy::Reference(GLOSSY_SPP) };
    let truth = one_bounce(&renderer);
    let gathered = gather_vertices(&src, 256, EYE);
    let s = Settings { rays: 256, accuracy: 0.3, ..Settings::default() };
    let (cached, cache) = indirect_vertices(&src, &s, EYE);
    let (flat, _) = indirect_vertices(&src, &Settings { gradients: false, ..s }, EYE);
    let (e_gather, e_cache, e_flat) = (rel(&gathered, &truth), rel(&cached, &truth), rel(&flat, &truth));
    let gather_rays = renderer.vertex_count() * 256;
    eprintln!(
        "gathering {e_gather:.4} ({gather_rays} rays), cache {e_cache:.4} ({} rays), without gradients {e_flat:.4}",
        cache.rays()
    );
    // Measured against this 1024-spp reference (its own noise ≈ 3 %): gathering 256 rays per
    // vertex 0.047 (560K rays); the cache 0.047 with 414 records (106K rays), 0.055 without
    // gradients. Against 4096 spp: 0.034, 0.031 and 0.044 (docs/radiance-cache.md).
    assert!(e_gather < 0.06, "brute-force gathering vs the reference: {e_gather}");
    assert!(e_cache < 1.1 * e_gather && cache.rays() * 5 <= gather_rays, "cache {e_cache} with {} rays", cache.rays());
    assert!(e_cache < e_flat, "gradients help at equal record count: {e_cache} vs {e_flat}");
}

/// Neighbour clamping shrinks the records placed before a smaller one near them; placement
/// then passes again, so every vertex still finds a usable record (none is left unlit).
#[test]
fn after_placement_every_vertex_finds_a_record() {
    let (renderer, direct) = lit_room(lambert(0.7));
    let src = Source { renderer: &renderer, direct: &direct, glossy: Glossy::Reference(GLOSSY_SPP) };
    let cache = kage_engine::cache::place_at_vertices(&src, &Settings::default());
    let flat = &renderer.flat;
    for i in 0..flat.instances.len() {
        for v in 0..flat.vertex_count(i) {
            let (p, n) = flat.vertex(i, v);
            assert!(cache.incoming(p, n).is_some(), "instance {i}, vertex {v} at {p} finds no record");
        }
    }
}

/// Dense records of few rays: Ward's blend hands each record's noise to the vertex it sits on,
/// the wide blend averages the neighbourhood's records and reaches gathering's error with a
/// fraction of its rays.
#[test]
fn the_wide_blend_averages_the_noise_of_few_ray_records() {
    let (renderer, direct) = lit_room(lambert(0.7));
    let src = Source { renderer: &renderer, direct: &direct, glossy: Glossy::Reference(GLOSSY_SPP) };
    let truth = one_bounce(&renderer);
    let e_gather = rel(&gather_vertices(&src, 256, EYE), &truth);
    // Every record keeps its 64 rays, noisy or not.
    let dense = Settings { rays: 64, accuracy: 0.2, noise: f32::INFINITY, ..Settings::default() };
    let (ward, _) = indirect_vertices(&src, &dense, EYE);
    let (wide, cache) = indirect_vertices(&src, &Settings { blend: Blend::Wide, ..dense }, EYE);
    let (e_ward, e_wide) = (rel(&ward, &truth), rel(&wide, &truth));
    let ratio = (renderer.vertex_count() * 256) as f64 / cache.rays() as f64;
    eprintln!("gathering {e_gather:.4}; a 0.2, 64 rays: Ward {e_ward:.4}, wide {e_wide:.4}, {ratio:.1}× fewer rays");
    // Measured: gathering 0.047 (560K rays); a 0.2 with 64 rays per record (47K rays, 11.9×
    // fewer): Ward's blend 0.069, the wide blend 0.053. (On the bunny the wide blend reaches
    // gathering's error with 15× fewer rays: docs/radiance-cache.md.)
    assert!(e_wide < 0.85 * e_ward, "the wide blend averages noise: {e_wide} vs Ward's {e_ward}");
    assert!(e_wide < 1.15 * e_gather && ratio >= 10.0, "{e_wide} vs gathering's {e_gather}, {ratio}× fewer rays");
}

#[test]
fn the_cache_is_deterministic_across_thread_counts() {
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(|| {
            let (renderer, direct) = ceiling();
            let src = Source { renderer: &renderer, direct: &direct, glossy: Glossy::Reference(GLOSSY_SPP) };
            let (v, _) = indirect_vertices(&src, &Settings::default(), EYE);
            v.concat().iter().flat_map(|c| c.to_array()).map(f32::to_bits).collect::<Vec<u32>>()
        })
    };
    assert!(run(1) == run(2));
}

#[test]
fn record_rotation_is_identity_at_zero_and_composes() {
    let conv = hsh::Conversion::new(3, kage_engine::cache::ROTATION_SH_ORDER);
    // A smooth hemispherical radiance: brighter toward +x and the zenith.
    let c = hsh::project(3, 64, |d| 1.0 + 0.5 * d.x + 0.3 * d.z);
    let same = conv.rotate(&c, glam::DMat3::IDENTITY);
    assert!(c.iter().zip(&same).all(|(a, b)| (a - b).abs() < 0.02), "{c:?} vs {same:?}");
    let (a, b) = (glam::DMat3::from_rotation_z(0.4), glam::DMat3::from_rotation_x(0.2));
    let twice = conv.rotate(&conv.rotate(&c, a), b);
    let once = conv.rotate(&c, b * a);
    // The round trip through SH is not exact (the hemisphere's even extension is not
    // band-limited): stated tolerance 5 % of the leading coefficient.
    assert!(twice.iter().zip(&once).all(|(x, y)| (x - y).abs() < 0.05 * c[0].abs()), "{twice:?} vs {once:?}");
}

#[test]
fn smooth_glossy_receivers_fall_back_to_a_direct_gather() {
    // A smooth metal ground (roughness 0.2) under a lit Lambertian sphere.
    let metal = Material { base_color: Vec3::splat(0.9), metallic: 1.0, roughness: 0.2, specular: 1.0 };
    let (r, direct) = lit_room(metal);
    let src = Source { renderer: &r, direct: &direct, glossy: Glossy::Reference(GLOSSY_SPP) };
    let truth = gather_vertices(&src, 4096, EYE);
    let e = |v: &[Vec<Vec3>]| kage_engine::math::relative_rmse(&v[0], &truth[0]);
    let (fallback, _) = indirect_vertices(&src, &Settings::default(), EYE);
    let (forced, _) = indirect_vertices(&src, &Settings { glossy_fallback: 0.0, ..Settings::default() }, EYE);
    // Measured (against 16384 rays): gathering 256 rays 0.060; the order-3 cache 0.98.
    assert!(e(&fallback) < 0.1 && e(&forced) > 0.5, "fallback {}, cache {}", e(&fallback), e(&forced));
}

#[test]
fn glossy_hits_are_lit_toward_the_record_by_the_direct_method() {
    use kage_engine::bspvt;
    // A rough metal ground under a Lambertian sphere: the sphere's lower half gathers what the
    // ground reflects toward it, which is not what the ground reflects toward the camera.
    let metal = Material { base_color: Vec3::splat(0.9), metallic: 1.0, roughness: 0.5, specular: 1.0 };
    let scene = room(metal);
    let r = Renderer::new(&scene);
    let s = bspvt::Settings { res: 32, epsilon: 2.0 };
    let bake = bspvt::bake(&r.flat, &s, &|_| {});
    let direct = bspvt::shade_vertices(&r.flat, bspvt::Shadows::Trees(&bake), EYE);
    let toward = |i: usize, corners: [usize; 3], bary: [f32; 3], p: Vec3| {
        bspvt::shade_point(&r.flat, Some(&bake), i, corners, bary, p)
    };
    let one_bounce = RefSettings { spp: 1024, seed: 5, max_bounces: 1, min_bounces: 1 };
    let truth: Vec<Vec3> = r.render_vertices(EYE, &one_bounce, &|_| {})[1].iter().map(|e| e.mean).collect();
    let sphere = |glossy: Glossy| {
        let v = gather_vertices(&Source { renderer: &r, direct: &direct, glossy }, 256, EYE);
        kage_engine::math::relative_rmse(&v[1], &truth)
    };
    let (e_toward, e_camera) = (sphere(Glossy::Toward(&toward)), sphere(Glossy::PerVertex));
    // Measured: 0.109 toward the record (the reference's 4-sample estimate: 0.076 — LTC's GGX
    // fit errs at the grazing views the records see the ground from), 0.62 toward the camera.
    assert!(
        e_toward < 0.15 && e_toward < 0.25 * e_camera,
        "toward the record {e_toward}, toward the camera {e_camera}"
    );
}

/// The ground and sphere of [`lit_room`] under a quad light at `light`, with per-vertex "direct"
/// radiance from an unshadowed point-light falloff scaled per instance by `tint` (a re-light
/// is exact for any direct input, so a cheap one serves).
fn room_lit_from(light: Vec3, tint: [f32; 2]) -> (Renderer, Vec<Vec<Vec3>>) {
    let mut s = Scene::new("room");
    s.add_object("ground", shapes::grid(6.0, 30), lambert(0.7), Affine3A::IDENTITY);
    s.add_object("sphere", shapes::sphere(0.8, 24, 12), lambert(0.7), Affine3A::from_translation(Vec3::Y * 0.85));
    let h = 0.5;
    let quad = vec![Vec3::new(-h, 0.0, -h), Vec3::new(h, 0.0, -h), Vec3::new(h, 0.0, h), Vec3::new(-h, 0.0, h)];
    s.add_light("light", quad, Vec3::splat(20.0), Affine3A::from_translation(light));
    let r = Renderer::new(&s);
    let direct = (0..2)
        .map(|i| {
            let falloff = |(p, n): (Vec3, Vec3)| n.dot(light - p).max(0.0) / (light - p).length().powi(3);
            (0..r.mesh(i).positions.len()).map(|v| Vec3::splat(tint[i] * falloff(r.vertex(i, v)))).collect()
        })
        .collect();
    (r, direct)
}

#[test]
fn a_refresh_relights_only_what_changed_and_equals_fresh_gathers() {
    use kage_engine::cache::record::Change;
    let s = Settings { rays: 64, ..Settings::default() };
    let (before, old_direct) = room_lit_from(Vec3::new(1.5, 3.0, 0.5), [1.0, 1.0]);
    let src = Source { renderer: &before, direct: &old_direct, glossy: Glossy::Reference(GLOSSY_SPP) };
    let mut cache = kage_engine::cache::place_at_vertices(&src, &s);
    let check = |cache: &Cache, src: &Source| {
        for (i, r) in cache.records.iter().enumerate() {
            let fresh = gather(src, r.p, r.frame.n, &cache.params(), i as u64);
            // The radius as placed (neighbour-clamped: at most the gather's own).
            assert!(r.radius <= fresh.radius, "record {i}: radius {} over the gather's {}", r.radius, fresh.radius);
            let fresh = kage_engine::cache::record::Record { radius: r.radius, ..fresh };
            assert_eq!(*r, fresh, "record {i} equals a fresh gather under the new lighting");
        }
    };

    // The sphere's material changes: its direct light halves, nothing moves. Records on the
    // sphere see only the ground and the sky, so they stand.
    let (same, tinted) = room_lit_from(Vec3::new(1.5, 3.0, 0.5), [1.0, 0.5]);
    let src = Source { renderer: &same, direct: &tinted, glossy: Glossy::Reference(GLOSSY_SPP) };
    let done = cache.refresh(&src, &Change { old_direct: Some(&old_direct), moved: &[] });
    check(&cache, &src);
    let n = cache.records.len();
    assert_eq!((done.recast, done.gathered), (0, 0), "{done:?}");
    // Every record equals a fresh gather (above), so those skipped truly saw no change.
    assert!(done.relit > 0 && done.relit < n / 2, "{} of {n} records re-lit", done.relit);

    // The light moves: only rays crossing its old or new bounds are cast again.
    let tinted_cache = cache.clone();
    let (after, moved_direct) = room_lit_from(Vec3::new(-1.0, 2.5, -1.0), [1.0, 0.5]);
    let moved = kage_engine::cache::moved_lights(&same.flat.lights, &after.flat.lights);
    let src = Source { renderer: &after, direct: &moved_direct, glossy: Glossy::Reference(GLOSSY_SPP) };
    let done = cache.refresh(&src, &Change { old_direct: Some(&tinted), moved: &moved });
    check(&cache, &src);
    // Records of 64 rays that read the light noisily gather a dense grid, under either lighting.
    assert!(tinted_cache.dense_records() > 0 && cache.dense_records() > 0);
    assert!(done.recast > 0 && done.recast * 10 < cache.rays(), "{} of {} rays re-cast", done.recast, cache.rays());
    // Record places do not depend on lighting: the refreshed cache is the cold placement
    // under the new lighting (so the editor stores it under the new lighting's key).
    assert!(kage_engine::cache::place_at_vertices(&src, &s).records == cache.records);

    // Progressively, batch by batch: each landing shows the records so far re-lit; the end
    // result is the one-shot refresh's. Stopped early, the rest keep the old lighting.
    let mut progressive = tinted_cache.clone();
    let change = Change { old_direct: Some(&tinted), moved: &moved };
    let mut landings = Vec::new();
    let total = progressive.refresh_progressively(&src, &change, 64, &mut |c, so_far| {
        landings.push((so_far.visited, c.records[..so_far.visited] == cache.records[..so_far.visited]));
        true
    });
    assert_eq!((total, progressive.records == cache.records), (done, true));
    assert_eq!(landings.len(), n.div_ceil(64));
    assert!(landings.iter().all(|(_, same)| *same), "{landings:?}");
    let mut stopped = tinted_cache;
    let early = stopped.refresh_progressively(&src, &change, 64, &mut |_, _| false);
    assert_eq!(early.visited, 64.min(n));

    // Stored records carry no hits: a refresh gathers them anew.
    let mut stored = kage_engine::cache::from_records(&src, &s, cache.records.clone());
    let done = stored.refresh(&src, &Change { old_direct: Some(&moved_direct), moved: &[] });
    assert_eq!(done.gathered, n);
    check(&stored, &src);
}

/// A placement or its bounces stop when asked (an editor's gather outdated by an edit): a
/// placement asked to stop after k records has made k records and gives nothing; bounces
/// asked to stop give nothing; never asked, both equal the plain calls.
#[test]
fn placement_and_bounces_stop_when_asked() {
    use kage_engine::cache::{Bounces, bounce, bounce_with_light, place_at_vertices, place_at_vertices_unless};
    use std::cell::Cell;
    let s = Settings { rays: 64, ..Settings::default() };
    let (r, direct) = room_lit_from(Vec3::new(1.5, 3.0, 0.5), [1.0, 1.0]);
    let src = Source { renderer: &r, direct: &direct, glossy: Glossy::Reference(GLOSSY_SPP) };
    let whole = place_at_vertices(&src, &s);
    assert!(whole.records.len() > 10, "{} records", whole.records.len());
    let asked = &Cell::new(0);
    let stop_after = |k: usize| {
        move || {
            asked.set(asked.get() + 1);
            asked.get() > k
        }
    };
    let mut cache = Cache::new(s, 10.0);
    let points: Vec<(Vec3, Vec3)> = (0..r.flat.instances.len())
        .flat_map(|i| (0..r.mesh(i).positions.len()).map(move |v| (i, v)))
        .map(|(i, v)| r.vertex(i, v))
        .collect();
    assert_eq!(cache.place_unless(&src, &points, &stop_after(7)), None, "stopped");
    assert_eq!(cache.records.len(), 7, "a record per answer before the stop");
    asked.set(0);
    assert!(place_at_vertices_unless(&src, &s, &stop_after(7)).is_none());
    assert!(place_at_vertices_unless(&src, &s, &|| false).is_some_and(|c| c.records == whole.records));

    let bounces = (EYE, Bounces::Fixed(2));
    assert!(bounce_with_light(&src, &whole, bounces, &|| true).is_none(), "stopped before the first bounce");
    let (values, _, bounced) = bounce_with_light(&src, &whole, bounces, &|| false).expect("never stopped");
    assert_eq!((values, bounced), bounce(&src, &whole, EYE, Bounces::Fixed(2)));
}
