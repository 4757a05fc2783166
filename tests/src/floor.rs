//! The two-triangle floor: a floor of two triangles with boxes and a ball on it under a quad
//! light (or a sky), and how far the baked look of it is from the reference per pixel — the
//! scene receiver refinement is tested and measured on (`tests/tests/receivers.rs`,
//! `cargo xtask measure`).

use glam::{Affine3A, Vec3};
use kage_engine::math::relative_rmse;
use kage_engine::raster;
use kage_engine::receivers::{self, Settings};
use kage_engine::reference::{self, Renderer};
use kage_engine::scene::{Camera, EnvMap, EnvironmentLight, Material, Mesh, PolygonLight, Scene, flatten, shapes};
use kage_engine::shading::baked::{Bakes, Look};
use kage_engine::{bspvt, prt};

/// An 8 m floor of two triangles with two boxes and a ball on it, each its own rigid group or,
/// with `one_group`, all members of the floor's, and the camera.
pub fn floor_and_objects(name: &str, one_group: bool) -> Scene {
    let mut s = Scene::new(name);
    let h = 4.0;
    let corners = vec![Vec3::new(-h, 0.0, -h), Vec3::new(-h, 0.0, h), Vec3::new(h, 0.0, h), Vec3::new(h, 0.0, -h)];
    let (floor, _) = Mesh::new(corners, None, vec![], vec![[0, 1, 2], [0, 2, 3]], false).unwrap();
    let grey = |c: f32| Material::lambertian(Vec3::splat(c));
    let g = s.add_object("floor", floor, grey(0.7), Affine3A::IDENTITY);
    let at = |x: f32, y: f32, z: f32| Affine3A::from_translation(Vec3::new(x, y, z));
    let objects = [
        ("box", shapes::cuboid(Vec3::new(0.4, 0.6, 0.4)), grey(0.5), at(-0.9, 0.6, 0.3)),
        ("slab", shapes::cuboid(Vec3::new(0.8, 0.05, 0.3)), grey(0.5), at(1.0, 0.9, -0.6)),
        ("ball", shapes::sphere(0.35, 16, 8), grey(0.6), at(0.4, 0.35, 1.3)),
    ];
    for (name, mesh, material, pose) in objects {
        if one_group {
            s.add_member(g, name, mesh, material, pose);
        } else {
            s.add_object(name, mesh, material, pose);
        }
    }
    s.add_camera(Camera::look_at(Vec3::new(0.0, 6.5, 6.5), Vec3::new(0.0, 0.0, 0.3), 45f32.to_radians()));
    s
}

/// The floor and objects as separate groups, a 1 m quad light 3 m up.
pub fn two_triangle_floor() -> Scene {
    let mut s = floor_and_objects("test:two-triangle-floor", false);
    let q = 0.5;
    let quad = vec![Vec3::new(-q, 0.0, -q), Vec3::new(q, 0.0, -q), Vec3::new(q, 0.0, q), Vec3::new(-q, 0.0, q)];
    // Counter-clockwise seen from below: the light faces down.
    s.add_light("light", quad, Vec3::splat(12.0), Affine3A::from_translation(Vec3::new(0.2, 3.0, 0.1)));
    s
}

/// The measured images' size.
pub const SIZE: (usize, usize) = (160, 90);

/// A 256-spp direct-light reference of `scene` with `seed`.
pub fn reference(r: &Renderer, camera: &Camera, seed: u64) -> Vec<Vec3> {
    reference_with(r, camera, seed, 256)
}

/// A direct-light reference of `scene` with `seed` at `spp` samples a pixel.
pub fn reference_with(r: &Renderer, camera: &Camera, seed: u64, spp: u32) -> Vec<Vec3> {
    let settings = reference::Settings { spp, seed, max_bounces: 0, min_bounces: 0 };
    r.render_image(camera, SIZE.0, SIZE.1, &settings, &|_| {}).iter().map(|e| e.mean).collect()
}

/// Relative RMSE of `ours` against `truth` over the pixels that see geometry.
pub fn over_geometry(r: &Renderer, camera: &Camera, ours: &[Vec3], truth: &[Vec3]) -> f64 {
    let hits = raster::shade_image(r, camera, SIZE.0, SIZE.1, 4, &|_| Vec3::ONE);
    let pick =
        |v: &[Vec3]| -> Vec<Vec3> { v.iter().zip(&hits).filter(|(_, m)| **m == Vec3::ONE).map(|(p, _)| *p).collect() };
    relative_rmse(&pick(ours), &pick(truth))
}

/// The part of [`over_geometry`] from the pixels whose samples all see instance 0 (the floor):
/// the squares of the floor's part and of the rest's (objects, and pixels at silhouettes, where
/// 4 samples of coverage meet the reference's many) add up to the square of the whole.
pub fn floor_part(r: &Renderer, camera: &Camera, ours: &[Vec3], truth: &[Vec3]) -> f64 {
    let hits = raster::shade_image(r, camera, SIZE.0, SIZE.1, 4, &|_| Vec3::ONE);
    let floor = raster::shade_image(r, camera, SIZE.0, SIZE.1, 4, &|h| Vec3::splat((h.instance == 0) as u8 as f32));
    let sum = |keep: &dyn Fn(usize) -> bool, f: &dyn Fn(usize) -> f64| {
        (0..truth.len()).filter(|&k| keep(k)).map(f).sum::<f64>()
    };
    let all = sum(&|k| hits[k] == Vec3::ONE, &|k| truth[k].as_dvec3().length_squared());
    let error = sum(&|k| floor[k] == Vec3::ONE, &|k| (ours[k] - truth[k]).as_dvec3().length_squared());
    (error / all).sqrt()
}

/// Relative RMSE per pixel over geometry of the baked look (polygonal lights: BSPVT + LTC;
/// the environment: PRT, diffuse) against the reference, and the scene's vertex count.
pub fn error(scene: &Scene) -> (f64, usize) {
    let camera = scene.first_camera().unwrap();
    let r = Renderer::new(scene);
    let ours = look_image(scene, 32);
    (over_geometry(&r, &camera, &ours, &reference(&r, &camera, 5)), vertices(scene))
}

/// The baked look's image of `scene` (polygonal lights: BSPVT at `res`² faces, ε 2, + LTC;
/// the environment: PRT, diffuse) through its first camera.
pub fn look_image(scene: &Scene, res: usize) -> Vec<Vec3> {
    let flat = flatten(scene);
    let camera = scene.first_camera().unwrap();
    let r = Renderer::new(scene);
    let trees = (!flat.lights.is_empty()).then(|| bspvt::bake(&flat, &bspvt::Settings { res, epsilon: 2.0 }, &|_| {}));
    let ps = prt::Settings::default();
    let env = flat
        .environment
        .as_ref()
        .map(|_| (prt::bake(scene, &flat, &ps, &|_| {}), prt::Lighting::new(scene, &ps).unwrap()));
    let parts = env.as_ref().map(|(bake, lighting)| prt::Parts { bake, lighting, settings: &ps });
    let bakes = Bakes { bspvt: trees.as_ref(), prt: parts, prefiltered: None };
    let look = Look::prepare(scene, &flat, bakes, camera.eye(), &mut prt::SilhouetteMemo::default());
    look.render(&r, &camera, SIZE.0, SIZE.1, 4)
}

/// The floor scene with its light promising to stay within `reach`.
pub fn with_reach(mut s: Scene, reach: [Vec3; 2]) -> Scene {
    for light in s.world.query_mut::<&mut PolygonLight>() {
        light.reach = Some(reach);
    }
    s
}

/// `s` with its receivers refined at `budget` (the default tolerance).
pub fn refined(mut s: Scene, budget: usize) -> Scene {
    receivers::refine(&mut s, &Settings { budget, ..Settings::default() }).unwrap();
    s
}

/// The floor scene's objects as one rigid group (one glTF node) under a sky, no polygonal
/// light: the floor's shadows are the group's own, which PRT bakes per vertex.
pub fn one_group_under_the_sky() -> Scene {
    let s = floor_and_objects("test:one-group-sky", true);
    s.with_environment(EnvironmentLight::new(EnvMap::procedural_sky(256, 128, Vec3::new(-0.5, 0.6, -0.4))))
}

/// Vertices over `s`'s instances.
pub fn vertices(s: &Scene) -> usize {
    let flat = flatten(s);
    flat.instances.iter().map(|i| flat.meshes[i.mesh as usize].positions.len()).sum()
}
