//! The reference integrator against closed forms, with its own standard error.

use glam::{Affine3A, DVec3, Vec3};
use kage_engine::math::frame::Frame;
use kage_engine::math::ggx;
use kage_engine::reference::{Estimate, Renderer, Settings, SurfacePoint};
use kage_engine::scene::import::{ImportOptions, import};
use kage_engine::scene::{EnvMap, EnvironmentLight, Material, Scene, shapes};
use kage_tests::asset;

/// Irradiance from a polygon of radiance 1 at `p` with normal `n` (Lambert's formula).
fn lambert_irradiance(p: Vec3, n: Vec3, poly: &[Vec3]) -> f64 {
    let (p, n) = (p.as_dvec3(), n.as_dvec3());
    let r: Vec<DVec3> = poly.iter().map(|q| (q.as_dvec3() - p).normalize()).collect();
    let mut sum = 0.0;
    for i in 0..r.len() {
        let (a, b) = (r[i], r[(i + 1) % r.len()]);
        sum += a.dot(b).clamp(-1.0, 1.0).acos() * n.dot(a.cross(b).normalize());
    }
    0.5 * sum.abs()
}

/// Every estimate lies within 4 standard errors of `exact`, and the squared z-scores average
/// near 1 (the reported standard errors are honest).
fn assert_consistent(est: &[Estimate], exact: &[f64], what: &str) {
    let mut z2 = 0.0;
    for (e, &x) in est.iter().zip(exact) {
        let se = e.std_error.x as f64;
        let z = (e.mean.x as f64 - x) / se.max(1e-9);
        assert!(z.abs() < 4.0 || (e.mean.x as f64 - x).abs() < 1e-6, "{what}: {} vs {x} (se {se})", e.mean.x);
        z2 += z * z;
    }
    let mean_z2 = z2 / est.len() as f64;
    // The pooled mean deviation in units of its own standard error: catches a small bias that
    // hides in per-point noise.
    let bias: f64 = est.iter().zip(exact).map(|(e, x)| e.mean.x as f64 - x).sum();
    let pooled_se = est.iter().map(|e| (e.std_error.x as f64).powi(2)).sum::<f64>().sqrt();
    let rel_se = pooled_se / exact.iter().sum::<f64>();
    eprintln!(
        "{what}: mean z² {mean_z2:.3}, pooled z {:.3}, pooled relative se {rel_se:.2e}",
        bias / pooled_se.max(1e-12)
    );
    assert!(bias.abs() < 4.0 * pooled_se + 1e-9, "{what}: pooled bias {bias} vs se {pooled_se}");
    assert!((0.4..2.0).contains(&mean_z2), "{what}: mean z² = {mean_z2}");
}

fn quad(h: f32) -> Vec<Vec3> {
    vec![Vec3::new(-h, 0.0, -h), Vec3::new(h, 0.0, -h), Vec3::new(h, 0.0, h), Vec3::new(-h, 0.0, h)]
}

#[test]
fn unoccluded_lambertian_matches_lamberts_formula() {
    let mut scene = Scene::new("test:lambert");
    let albedo = 0.5f64;
    scene.add_object(
        "ground",
        shapes::grid(6.0, 6),
        Material::lambertian(Vec3::splat(albedo as f32)),
        Affine3A::IDENTITY,
    );
    let light_pose = Affine3A::from_translation(Vec3::new(0.4, 2.0, -0.3));
    scene.add_light("light", quad(0.5), Vec3::ONE, light_pose);
    let r = Renderer::new(&scene);
    let s = Settings { spp: 512, seed: 1, max_bounces: 0, min_bounces: 0 };
    let est = &r.render_vertices(Vec3::new(0.0, 5.0, 5.0), &s, &|_| {})[0];
    let poly = &r.flat.lights[0].points;
    let exact: Vec<f64> = (0..est.len())
        .map(|v| {
            let (p, n) = r.vertex(0, v);
            albedo / std::f64::consts::PI * lambert_irradiance(p, n, poly)
        })
        .collect();
    assert_consistent(est, &exact, "Lambert");
}

#[test]
fn cube_on_plane_shadow_and_unshadowed_irradiance() {
    let scene = import(&asset("scenes/cube_on_plane.gltf"), ImportOptions::default()).unwrap();
    let r = Renderer::new(&scene);
    let ground = r
        .flat
        .instances
        .iter()
        .position(|i| r.vertex_count() > 0 && i.material.base_color == Vec3::splat(0.8))
        .unwrap();
    // The published unshadowed irradiance at the ground centre.
    let e = lambert_irradiance(Vec3::ZERO, Vec3::Y, &r.flat.lights[0].points) * 10.0;
    assert!((e - 0.61226).abs() < 1e-4, "{e}");
    let s = Settings { spp: 64, seed: 2, max_bounces: 0, min_bounces: 0 };
    let est = &r.render_vertices(Vec3::new(0.0, 6.0, 6.0), &s, &|_| {})[ground];
    let mut umbra = 0;
    for (v, e) in est.iter().enumerate() {
        let (p, _) = r.vertex(ground, v);
        if p.x.abs() < 0.3 && p.z.abs() < 0.3 {
            umbra += 1;
            assert_eq!(e.mean, Vec3::ZERO, "vertex {v} at {p} is fully shadowed");
        }
    }
    assert_eq!(umbra, 9);
}

fn constant_env(l: f32) -> EnvironmentLight {
    EnvironmentLight::new(EnvMap::new(8, 4, vec![Vec3::splat(l); 32], "test:constant".into()).unwrap())
}

#[test]
fn uniform_environment_gives_albedo_times_radiance() {
    let mut scene = Scene::new("test:furnace").with_environment(constant_env(2.0));
    let albedo = 0.6f64;
    scene.add_object(
        "sphere",
        shapes::sphere(1.0, 16, 8),
        Material::lambertian(Vec3::splat(albedo as f32)),
        Affine3A::IDENTITY,
    );
    let r = Renderer::new(&scene);
    let est = &r.render_vertices(
        Vec3::new(0.0, 0.0, 5.0),
        &Settings { spp: 256, seed: 3, max_bounces: 0, min_bounces: 0 },
        &|_| {},
    )[0];
    assert_consistent(est, &vec![albedo * 2.0; est.len()], "diffuse furnace");
}

/// ∫ f cos dωi of a white GGX metal by a fine midpoint rule in (cos θ, φ).
fn ggx_albedo_quadrature(wo: Vec3, alpha: f32) -> f64 {
    let (nt, np) = (1500, 600);
    let mut sum = 0.0;
    for i in 0..nt {
        let c = (i as f64 + 0.5) / nt as f64;
        for j in 0..np {
            let phi = 2.0 * std::f64::consts::PI * (j as f64 + 0.5) / np as f64;
            let s = (1.0 - c * c).sqrt();
            let wi = DVec3::new(s * phi.cos(), s * phi.sin(), c).as_vec3();
            sum += ggx::eval(wo, wi, alpha, Vec3::ONE, Vec3::ONE).x as f64 * c;
        }
    }
    sum * 2.0 * std::f64::consts::PI / (nt * np) as f64
}

#[test]
fn ggx_white_furnace_conserves_energy_and_matches_quadrature() {
    let scene = Scene::new("test:ggx-furnace").with_environment(constant_env(1.0));
    let r = Renderer::new(&scene);
    let metal = Material { base_color: Vec3::ONE, metallic: 1.0, roughness: 0.6, specular: 1.0 };
    let sp = SurfacePoint { p: Vec3::ZERO, ng: Vec3::Z, frame: Frame::from_normal(Vec3::Z), material: metal };
    let mut est = Vec::new();
    let mut exact = Vec::new();
    for (k, cos_o) in [0.05f32, 0.3, 0.6, 0.95].into_iter().enumerate() {
        let wo = Vec3::new((1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o);
        let e = r.estimate_point(&sp, wo, &Settings { spp: 20_000, seed: 4, max_bounces: 0, min_bounces: 0 }, k as u64);
        assert!(e.mean.x <= 1.0 + 3.0 * e.std_error.x, "energy at cos θo = {cos_o}: {}", e.mean.x);
        est.push(e);
        exact.push(ggx_albedo_quadrature(wo, ggx::alpha_from_roughness(0.6)));
    }
    for (e, x) in est.iter().zip(&exact) {
        assert!(
            ((e.mean.x as f64) - x).abs() < 4.0 * e.std_error.x as f64 + 2e-3,
            "{} vs {x} ± {}",
            e.mean.x,
            e.std_error.x
        );
    }
}
