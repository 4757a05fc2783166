//! Receiver refinement (`kage_engine::receivers`): a floor of two triangles under a quad light
//! gets its shadows, the refined meshes stay sound, and refinement is deterministic.

use glam::{Affine3A, Vec3};
use kage_engine::math::relative_rmse;
use kage_engine::raster;
use kage_engine::receivers::{self, Settings};
use kage_engine::reference::{self, Renderer};
use kage_engine::scene::{Camera, Material, Mesh, Scene, flatten, shapes};
use kage_engine::shading::baked::{Bakes, Look};
use kage_engine::{bspvt, prt};

/// An 8 m floor of two triangles, two boxes and a ball on it, a 1 m quad light 3 m up.
fn two_triangle_floor() -> Scene {
    let mut s = Scene::new("test:two-triangle-floor");
    let h = 4.0;
    let corners = vec![Vec3::new(-h, 0.0, -h), Vec3::new(-h, 0.0, h), Vec3::new(h, 0.0, h), Vec3::new(h, 0.0, -h)];
    let (floor, _) = Mesh::new(corners, None, vec![], vec![[0, 1, 2], [0, 2, 3]], false).unwrap();
    let grey = |c: f32| Material::lambertian(Vec3::splat(c));
    s.add_object("floor", floor, grey(0.7), Affine3A::IDENTITY);
    let at = |x: f32, y: f32, z: f32| Affine3A::from_translation(Vec3::new(x, y, z));
    s.add_object("box", shapes::cuboid(Vec3::new(0.4, 0.6, 0.4)), grey(0.5), at(-0.9, 0.6, 0.3));
    s.add_object("slab", shapes::cuboid(Vec3::new(0.8, 0.05, 0.3)), grey(0.5), at(1.0, 0.9, -0.6));
    s.add_object("ball", shapes::sphere(0.35, 16, 8), grey(0.6), at(0.4, 0.35, 1.3));
    let q = 0.5;
    let quad = vec![Vec3::new(-q, 0.0, -q), Vec3::new(q, 0.0, -q), Vec3::new(q, 0.0, q), Vec3::new(-q, 0.0, q)];
    // Counter-clockwise seen from below: the light faces down.
    s.add_light("light", quad, Vec3::splat(12.0), at(0.2, 3.0, 0.1));
    s.add_camera(Camera::look_at(Vec3::new(0.0, 6.5, 6.5), Vec3::new(0.0, 0.0, 0.3), 45f32.to_radians()));
    s
}

const SIZE: (usize, usize) = (160, 90);

/// A 256-spp direct-light reference of `scene` with `seed`.
fn reference(r: &Renderer, camera: &Camera, seed: u64) -> Vec<Vec3> {
    let settings = reference::Settings { spp: 256, seed, max_bounces: 0, min_bounces: 0 };
    r.render_image(camera, SIZE.0, SIZE.1, &settings, &|_| {}).iter().map(|e| e.mean).collect()
}

/// Relative RMSE of `ours` against `truth` over the pixels that see geometry.
fn over_geometry(r: &Renderer, camera: &Camera, ours: &[Vec3], truth: &[Vec3]) -> f64 {
    let hits = raster::shade_image(r, camera, SIZE.0, SIZE.1, 4, &|_| Vec3::ONE);
    let pick =
        |v: &[Vec3]| -> Vec<Vec3> { v.iter().zip(&hits).filter(|(_, m)| **m == Vec3::ONE).map(|(p, _)| *p).collect() };
    relative_rmse(&pick(ours), &pick(truth))
}

/// Relative RMSE per pixel over geometry of the baked look (polygonal light: BSPVT + LTC)
/// against the reference, and the scene's vertex count.
fn error(scene: &Scene) -> (f64, usize) {
    let flat = flatten(scene);
    let camera = scene.first_camera().unwrap();
    let r = Renderer::new(scene);
    let trees = bspvt::bake(&flat, &bspvt::Settings { res: 32, epsilon: 2.0 }, &|_| {});
    let bakes = Bakes { bspvt: Some(&trees), prt: None, prefiltered: None };
    let look = Look::prepare(scene, &flat, bakes, camera.eye(), &mut prt::SilhouetteMemo::default());
    let ours = look.render(&r, &camera, SIZE.0, SIZE.1, 4);
    (over_geometry(&r, &camera, &ours, &reference(&r, &camera, 5)), vertices(scene))
}

#[test]
fn a_two_triangle_floor_gets_its_shadows() {
    let coarse = two_triangle_floor();
    let (before, n0) = error(&coarse);
    let mut fine = two_triangle_floor();
    let report = receivers::refine(&mut fine, &Settings { budget: 4000, ..Settings::default() }).unwrap();
    let (after, n1) = error(&fine);
    // The same vertices spent uniformly on the floor alone.
    let mut uniform = two_triangle_floor();
    uniform.refine_instances("floor", n1 - (n0 - 4)).unwrap();
    let (even, n2) = error(&uniform);
    eprintln!(
        "two-triangle floor: {before:.4} with {n0} vertices; adaptive {after:.4} with {n1} ({report:?}); uniform {even:.4} with {n2}"
    );
    assert!(before > 0.3, "without refinement the floor has no shadows: {before:.4}");
    assert!(after < 0.045, "refined: {after:.4}, coarse: {before:.4}");
    assert!(after < 0.75 * even, "adaptive {after:.4} against uniform {even:.4} at as many vertices");
    assert!(n1 <= n0 + 4000 + 100, "within the budget (seams add a little): {n1}");
}

#[test]
fn refinement_is_deterministic_on_any_thread_count() {
    let refined = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let mut s = two_triangle_floor();
        pool.install(|| receivers::refine(&mut s, &Settings { budget: 3000, ..Settings::default() })).unwrap();
        let flat = flatten(&s);
        flat.instances.iter().map(|i| flat.meshes[i.mesh as usize].hash).collect::<Vec<_>>()
    };
    assert_eq!(refined(1), refined(2));
}

/// The curve of error against vertices, adaptive against uniform refinement of the floor, and
/// the reference's own noise, as `docs/benchmarks.md` reports it:
/// `cargo test --release -p kage-tests --test receivers -- --ignored --nocapture`.
#[test]
#[ignore]
fn error_against_vertices() {
    let (s, camera) = (two_triangle_floor(), two_triangle_floor().first_camera().unwrap());
    let r = Renderer::new(&s);
    let noise = over_geometry(&r, &camera, &reference(&r, &camera, 6), &reference(&r, &camera, 5));
    eprintln!("the reference's own noise (seed 6 against seed 5): {noise:.4}");
    for budget in [2000usize, 4000, 8000, 16000, 32000] {
        let mut fine = two_triangle_floor();
        receivers::refine(&mut fine, &Settings { budget, ..Settings::default() }).unwrap();
        let (a, n1) = error(&fine);
        let mut uniform = two_triangle_floor();
        uniform.refine_instances("floor", budget).unwrap();
        let (u, n2) = error(&uniform);
        eprintln!("budget {budget}: adaptive {a:.4} ({n1}), uniform floor {u:.4} ({n2})");
    }
}

/// Hard cases: a budget smaller than one round stops inside it; a receiver of a single
/// triangle is refined like any other; a scene without polygonal lights is left alone.
#[test]
fn tiny_budgets_single_triangles_and_unlit_scenes() {
    let mut s = two_triangle_floor();
    let n0: usize = vertices(&s);
    receivers::refine(&mut s, &Settings { budget: 3, ..Settings::default() }).unwrap();
    assert!((n0..=n0 + 3).contains(&vertices(&s)), "{} from {n0}", vertices(&s));
    let mut single = Scene::new("test:single");
    let (tri, _) = Mesh::new(
        vec![Vec3::new(-4.0, 0.0, -4.0), Vec3::new(0.0, 0.0, 4.0), Vec3::new(4.0, 0.0, -4.0)],
        None,
        vec![],
        vec![[0, 1, 2]],
        false,
    )
    .unwrap();
    single.add_object("floor", tri, Material::lambertian(Vec3::splat(0.7)), Affine3A::IDENTITY);
    let ball = Affine3A::from_translation(Vec3::new(0.0, 0.5, -1.0));
    single.add_object("ball", shapes::sphere(0.4, 12, 6), Material::lambertian(Vec3::ONE), ball);
    let q = 0.4;
    let quad = vec![Vec3::new(-q, 0.0, -q), Vec3::new(q, 0.0, -q), Vec3::new(q, 0.0, q), Vec3::new(-q, 0.0, q)];
    single.add_light("light", quad, Vec3::splat(10.0), Affine3A::from_translation(Vec3::new(0.0, 2.0, -1.0)));
    let report = receivers::refine(&mut single, &Settings { budget: 500, ..Settings::default() }).unwrap();
    assert!(report[0].1 > 50, "the single triangle is refined: {report:?}");
    let mut unlit = Scene::new("test:unlit");
    unlit.add_object("floor", shapes::grid(2.0, 2), Material::lambertian(Vec3::ONE), Affine3A::IDENTITY);
    let report = receivers::refine(&mut unlit, &Settings::default()).unwrap();
    assert_eq!(report, vec![(9, 9)]);
}

fn vertices(s: &Scene) -> usize {
    let flat = flatten(s);
    flat.instances.iter().map(|i| flat.meshes[i.mesh as usize].positions.len()).sum()
}
