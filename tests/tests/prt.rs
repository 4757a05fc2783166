//! PRT: self-transfer, environment lighting, and shadows between moving groups, against
//! closed forms and the reference integrator. Tolerances are stated where they are used.

use glam::{Affine3A, Quat, Vec3};
use kage_engine::math::relative_rmse as rel_rmse;
use kage_engine::prt::{self, Shadows, lighting::Window};
use kage_engine::reference::{Renderer, Settings};
use kage_engine::scene::{EnvMap, EnvironmentLight, Material, Scene, environment, flatten, shapes};
use kage_tests::asset;

const EYE: Vec3 = Vec3::new(0.0, 6.0, 6.0);

/// Per-vertex PRT radiance with `s`, per instance.
fn shade(scene: &Scene, s: &prt::Settings, shadows: Shadows) -> Vec<Vec<Vec3>> {
    let flat = flatten(scene);
    let bake = prt::bake(scene, &flat, s, &|_| {});
    let light = prt::Lighting::new(scene, s).expect("the scene has an environment");
    prt::Frame::prepare(scene, &flat, prt::Parts { bake: &bake, lighting: &light, settings: s }, shadows, EYE)
        .vertex_values(&flat)
}

/// Per-vertex reference (direct light only), per instance.
fn reference(scene: &Scene, spp: u32) -> Vec<Vec<Vec3>> {
    let r = Renderer::new(scene);
    let est = r.render_vertices(EYE, &Settings { spp, seed: 11, max_bounces: 0, min_bounces: 0 }, &|_| {});
    est.iter().map(|v| v.iter().map(|e| e.mean).collect()).collect()
}

/// A `256 × 128` map: uniform `sky` radiance and a 2×2-texel sun of radiance `sun` around `dir`.
fn sun_env(sky: f32, sun: f32, dir: Vec3) -> EnvironmentLight {
    let (w, h) = (256, 128);
    let mut t = vec![Vec3::splat(sky); w * h];
    let uv = environment::dir_to_uv(dir.normalize());
    let (x, y) = ((uv.x * w as f32) as usize, (uv.y * h as f32) as usize);
    for j in y..y + 2 {
        for i in x..x + 2 {
            t[j * w + i] = Vec3::splat(sun);
        }
    }
    EnvironmentLight::new(EnvMap::new(w, h, t, "sun".into()).unwrap())
}

fn settings(order: usize, regions: usize) -> prt::Settings {
    prt::Settings { order, regions, window: Window::None, ..prt::Settings::default() }
}

#[test]
fn unoccluded_convex_object_under_a_constant_environment_is_albedo_times_radiance() {
    let mut scene = Scene::new("sphere");
    scene.add_object(
        "sphere",
        shapes::sphere(1.0, 32, 16),
        Material::lambertian(Vec3::new(0.5, 0.25, 0.8)),
        Affine3A::IDENTITY,
    );
    let scene = scene.with_environment(EnvironmentLight::new(
        EnvMap::new(64, 32, vec![Vec3::splat(2.0); 2048], "c".into()).unwrap(),
    ));
    for shadows in [Shadows::SelfOnly, Shadows::WithOthers] {
        for v in &shade(&scene, &settings(4, 8), shadows)[0] {
            // 1024 stratified directions integrate the clamped cosine to a few 1e-3.
            assert!((*v / Vec3::new(1.0, 0.5, 1.6) - 1.0).abs().max_element() < 6e-3, "{v}");
        }
    }
}

/// A ground with a box floating above it, two groups, under `env`.
fn box_over_ground(env: EnvironmentLight) -> Scene {
    let mut scene = Scene::new("box over ground");
    scene.add_object("ground", shapes::grid(6.0, 30), Material::lambertian(Vec3::splat(0.8)), Affine3A::IDENTITY);
    let pose = Affine3A::from_translation(Vec3::new(0.0, 1.5, 0.0));
    scene.add_object("box", shapes::cuboid(Vec3::splat(0.5)), Material::lambertian(Vec3::splat(0.5)), pose);
    scene.with_environment(env)
}

#[test]
fn a_single_small_region_gives_the_direct_light_result() {
    // (Not a direction that puts shadow edges exactly on ground vertices.)
    let sun = Vec3::new(0.23, 1.0, 0.13).normalize();
    let scene = box_over_ground(sun_env(0.0, 1e5, sun));
    // A point-like light needs many bands: the truncated clamped cosine near the normal is 9 %
    // off at order 8. Order 12 with 4096 directions (T(ω) is then the order-12 reproducing
    // kernel sampled by the direction set) is close.
    let s = prt::Settings { directions: 4096, ..settings(12, 8) };
    let light = prt::Lighting::new(&scene, &s).unwrap();
    let power: f64 = light.regions.iter().map(|r| r.power.x).sum();
    let got = &shade(&scene, &s, Shadows::WithOthers)[0];
    // Direct light from a point-like sun of power B: ρ B cos θ / π, times the box's visibility.
    let flat = flatten(&scene);
    let occluder = kage_engine::accel::SceneBvh::new(&flat.triangles[flat.instances[1].first_triangle as usize..]);
    let want: Vec<Vec3> = (0..got.len())
        .map(|v| {
            let (p, n) = flat.vertex(0, v);
            let lit = !occluder.occluded(p + n * 1e-4, sun, f32::INFINITY);
            Vec3::splat(0.8 * power as f32 * sun.dot(n).max(0.0) / std::f32::consts::PI * f32::from(u8::from(lit)))
        })
        .collect();
    let err = rel_rmse(got, &want);
    // Measured: 0.006.
    assert!(err < 0.02, "relative RMSE {err}");
    let peak = want.iter().map(|v| v.x).fold(0.0, f32::max);
    for (g, w) in got.iter().zip(&want) {
        assert!(g.min_element() >= 0.0, "clamped at zero");
        if w.x == 0.0 {
            // In the umbra, Ls and B·T(p, w) ring alike and cancel: within 3 % of the peak.
            assert!(g.x < 0.03 * peak, "umbra vertex {g} (peak {peak})");
        }
    }
}

#[test]
fn a_sun_1e5_times_the_sky_matches_the_reference() {
    let scene = box_over_ground(sun_env(1.0, 1e5, Vec3::new(-0.3, 1.0, 0.2)));
    let s = settings(8, 32);
    let got = shade(&scene, &s, Shadows::WithOthers);
    let own = shade(&scene, &s, Shadows::SelfOnly);
    let want = reference(&scene, 256);
    assert!(got.iter().flatten().all(|v| v.is_finite() && v.min_element() >= 0.0));
    let (e, e_self) = (rel_rmse(&got[0], &want[0]), rel_rmse(&own[0], &want[0]));
    // Measured: 0.031 with shadows between groups, 0.19 without (256-spp reference).
    assert!(e < 0.06 && e_self > 3.0 * e, "prt {e}, prt-self {e_self}");
}

#[test]
fn moving_a_group_changes_its_lighting_but_not_its_bake() {
    let mut scene =
        kage_engine::scene::import::import(&asset("scenes/bunny_two_groups.gltf"), Default::default()).unwrap();
    scene.set_environment(EnvironmentLight::new(EnvMap::load(&asset("envmaps/studio.hdr")).unwrap()));
    let s = settings(4, 16);
    let before = prt::bake(&scene, &flatten(&scene), &s, &|_| {}).instances;
    let lit_before = shade(&scene, &s, Shadows::WithOthers);
    let g = scene.find_group("group_box_sphere").unwrap();
    scene.pose_group(g, Quat::from_rotation_z(1.1), Vec3::new(-0.4, 0.3, 0.5));
    let after = prt::bake(&scene, &flatten(&scene), &s, &|_| {}).instances;
    assert!(before == after, "the transfer lives in the group's frame: bit-identical");
    let lit_after = shade(&scene, &s, Shadows::WithOthers);
    let flat = flatten(&scene);
    for (i, inst) in flat.instances.iter().enumerate() {
        let moved = inst.group == g;
        let changed = rel_rmse(&lit_after[i], &lit_before[i]);
        // The moved group is lit differently; the ground's shadow from it moves too.
        if (moved || inst.id.node == 0) && lit_before[i].iter().any(|v| v.max_element() > 0.0) {
            assert!(changed > 0.01, "instance {i}: {changed}");
        }
    }
}

#[test]
fn groups_rotated_by_half_turns_and_mirrored_match_geometry_baked_in_place() {
    let env = EnvironmentLight::new(EnvMap::load(&asset("envmaps/city.hdr")).unwrap());
    let s = prt::Settings { directions: 4096, ..settings(6, 8) };
    let torus = || shapes::torus(0.8, 0.3, 48, 16);
    let half_turns = [
        Quat::from_rotation_x(std::f32::consts::PI),
        Quat::from_rotation_y(std::f32::consts::PI),
        Quat::from_rotation_z(std::f32::consts::PI),
    ];
    let mut poses: Vec<Affine3A> = half_turns.iter().map(|q| Affine3A::from_quat(*q)).collect();
    poses.push(Affine3A::from_scale(Vec3::new(1.0, -1.0, 1.0)) * Affine3A::from_rotation_x(0.7));
    for pose in poses {
        // Posed at run time: the transfer is in the torus's frame and the light is rotated.
        let mut moved = Scene::new("moved");
        moved.add_object("torus", torus(), Material::lambertian(Vec3::ONE), pose);
        let moved = moved.with_environment(env.clone());
        // Baked in place: an identity group whose member carries the pose.
        let mut fixed = Scene::new("fixed");
        let g = fixed.add_object(
            "anchor",
            shapes::sphere(0.01, 4, 2),
            Material::lambertian(Vec3::ONE),
            Affine3A::from_translation(Vec3::splat(50.0)),
        );
        fixed.pose_group(g, Quat::IDENTITY, Vec3::splat(-50.0));
        fixed.add_member(g, "torus", torus(), Material::lambertian(Vec3::ONE), pose);
        let fixed = fixed.with_environment(env.clone());
        let a = &shade(&moved, &s, Shadows::SelfOnly)[0];
        let b = &shade(&fixed, &s, Shadows::SelfOnly)[1];
        // Only the direction set's alignment differs: Monte Carlo noise of 4096 directions.
        let err = rel_rmse(a, b);
        assert!(err < 0.01, "pose {pose:?}: {err}");
    }
}

#[test]
fn a_direction_blocked_by_both_groups_is_not_subtracted_twice() {
    // Group A: ground with its own roof at y = 1; group B: a second roof at y = 2 above it.
    let sun = Vec3::new(0.0, 1.0, 0.15).normalize();
    let mut scene = Scene::new("two roofs");
    let a =
        scene.add_object("ground", shapes::grid(6.0, 24), Material::lambertian(Vec3::splat(0.8)), Affine3A::IDENTITY);
    let roof = || shapes::cuboid(Vec3::new(1.2, 0.05, 1.2));
    scene.add_member(a, "roof", roof(), Material::lambertian(Vec3::splat(0.5)), Affine3A::from_translation(Vec3::Y));
    scene.add_object(
        "upper roof",
        roof(),
        Material::lambertian(Vec3::splat(0.5)),
        Affine3A::from_translation(2.0 * Vec3::Y),
    );
    let scene = scene.with_environment(sun_env(1.0, 1e4, sun));
    let s = settings(8, 16);
    let got = shade(&scene, &s, Shadows::WithOthers);
    let want = reference(&scene, 512);
    let flat = flatten(&scene);
    let ground = flat.instances.iter().position(|i| i.id.node == 0).unwrap();
    let centre = (0..got[ground].len()).find(|&v| flat.vertex(ground, v).0.length() < 1e-4).unwrap();
    // Under both roofs only skylight arrives; subtracting the sun twice would clamp it to 0.
    // Measured: 0.263 vs reference 0.273.
    let (g, w) = (got[ground][centre].x, want[ground][centre].x);
    assert!(w > 0.05 && (g - w).abs() < 0.25 * w, "prt {g} vs reference {w}");
}

#[test]
fn touching_groups_and_a_single_region_stay_finite_and_shadowed() {
    // A box resting on the ground: each is inside the other's bounding sphere (R ≤ 0).
    let mut scene = Scene::new("resting box");
    scene.add_object("ground", shapes::grid(6.0, 30), Material::lambertian(Vec3::splat(0.8)), Affine3A::IDENTITY);
    scene.add_object(
        "box",
        shapes::cuboid(Vec3::splat(0.5)),
        Material::lambertian(Vec3::splat(0.5)),
        Affine3A::from_translation(Vec3::new(0.0, 0.5, 0.0)),
    );
    let scene = scene.with_environment(sun_env(1.0, 3e3, Vec3::new(0.3, 1.0, 0.0)));
    let want = reference(&scene, 256);
    for q in [1, 32] {
        let got = shade(&scene, &settings(8, q), Shadows::WithOthers);
        let own = shade(&scene, &settings(8, q), Shadows::SelfOnly);
        assert!(got.iter().flatten().all(|v| v.is_finite() && v.min_element() >= 0.0), "q = {q}");
        assert!(
            got.iter().flatten().zip(own.iter().flatten()).all(|(g, o)| g.cmple(*o + 1e-6).all()),
            "q = {q}: only subtracts"
        );
        let (e, e_self) = (rel_rmse(&got[0], &want[0]), rel_rmse(&own[0], &want[0]));
        // Measured (ground, 256-spp reference): q = 1: 0.10, q = 32: 0.069; prt-self 0.20.
        let bound = if q == 1 { 0.15 } else { 0.09 };
        assert!(e < bound && e < e_self, "q = {q}: prt {e}, prt-self {e_self}");
    }
}

fn bunny_scene(env: &str) -> Scene {
    let mut scene =
        kage_engine::scene::import::import(&asset("scenes/bunny_two_groups.gltf"), Default::default()).unwrap();
    scene.set_environment(EnvironmentLight::new(EnvMap::load(&asset(&format!("envmaps/{env}.hdr"))).unwrap()));
    scene
}

#[test]
fn bunny_two_groups_matches_the_reference_under_every_shared_environment() {
    for (env, bound) in [("city", 0.05), ("sky", 0.07), ("studio", 0.06)] {
        let scene = bunny_scene(env);
        let flat = flatten(&scene);
        let (s, _) = prt::budget::choose(&scene, &flat, 0.02, &prt::Settings::default());
        let want = reference(&scene, 1024);
        // The gold sphere (node 4) is GGX: PRT gives only its (zero) diffuse part.
        let diffuse = |v: &[Vec<Vec3>]| -> Vec<Vec3> {
            v.iter().zip(&flat.instances).filter(|(_, i)| i.id.node != 4).flat_map(|(v, _)| v.iter().copied()).collect()
        };
        let truth = diffuse(&want);
        let e = rel_rmse(&diffuse(&shade(&scene, &s, Shadows::WithOthers)), &truth);
        let e_self = rel_rmse(&diffuse(&shade(&scene, &s, Shadows::SelfOnly)), &truth);
        // Measured against this 1024-spp reference: city 0.028, sky 0.050, studio 0.044;
        // prt-self 0.18, 0.23, 0.29.
        assert!(e < bound && e_self > 3.0 * e, "{env}: prt {e}, prt-self {e_self}");
    }
}

/// The plan measures region counts with a truncated pilot bake when planning from scratch, and
/// with the database's bake at the chosen order after a move: the two must agree bit for bit.
#[test]
fn a_bake_truncated_to_a_lower_order_is_that_orders_bake_bit_for_bit() {
    let scene = bunny_scene("sky");
    let flat = flatten(&scene);
    let base = prt::Settings { directions: 256, ..prt::Settings::default() };
    let high = prt::bake(&scene, &flat, &prt::Settings { order: prt::budget::REFERENCE_ORDER, ..base }, &|_| {});
    for order in [2, 5, 8] {
        let direct = prt::bake(&scene, &flat, &prt::Settings { order, ..base }, &|_| {});
        let truncated = high.truncated(order);
        assert_eq!(truncated.order, order);
        let bits = |b: &prt::Bake| b.instances.iter().flatten().map(|t| t.to_bits()).collect::<Vec<_>>();
        assert!(bits(&truncated) == bits(&direct), "order {order}");
    }
}

#[test]
fn the_error_budget_plan_of_each_shared_scene() {
    let cases = [
        ("scenes/bunny_two_groups.gltf", "city", 3, Some(8)),
        ("scenes/bunny_two_groups.gltf", "sky", 6, Some(8)),
        ("scenes/bunny_two_groups.gltf", "studio", 7, Some(32)),
        ("scenes/cube_on_plane.gltf", "sky", 5, Some(8)),
        ("scenes/teapot_quad_light.gltf", "studio", 2, Some(8)),
        ("scenes/emissive_strength_cubes.gltf", "city", 3, Some(16)),
        ("scenes/textured_light.gltf", "sky", 5, Some(8)),
        ("models/teapot.glb", "city", 3, None),
    ];
    for (file, env, order, regions) in cases {
        let mut scene = kage_engine::scene::import::import(&asset(file), Default::default()).unwrap();
        scene.set_environment(EnvironmentLight::new(EnvMap::load(&asset(&format!("envmaps/{env}.hdr"))).unwrap()));
        let base = prt::Settings::default();
        let (s, why) = prt::budget::choose(&scene, &flatten(&scene), 0.05, &base);
        assert_eq!(s.order, order, "{file} under {env}: {why:?}");
        match regions {
            Some(q) => assert_eq!(s.regions, q, "{file} under {env}: {why:?}"),
            None => assert!(s.regions == base.regions && why[1].contains("one rigid group"), "{why:?}"),
        }
    }
}

#[test]
fn bakes_and_frames_are_bit_identical_across_thread_counts() {
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let scene = bunny_scene("sky");
            let s = settings(5, 16);
            let bake = prt::bake(&scene, &flatten(&scene), &s, &|_| {});
            let lit = shade(&scene, &s, Shadows::WithOthers);
            let bits: Vec<u32> = bake.instances.concat().iter().map(|v| v.to_bits()).collect();
            let lit: Vec<u32> = lit.concat().iter().flat_map(|v| v.to_array()).map(f32::to_bits).collect();
            (bits, lit)
        })
    };
    assert!(run(1) == run(2), "1 and 2 threads differ");
}
