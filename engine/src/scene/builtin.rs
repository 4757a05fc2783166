//! The built-in default scene, so every command works with no files: a torus (gold GGX), a
//! sphere and a box (diffuse) on a tessellated ground, lit by a quad light and a procedural sky.

use super::shapes;
use crate::scene::{Camera, EnvMap, EnvironmentLight, Material, Scene};
use glam::{Affine3A, Quat, Vec3};

/// Builds the built-in scene (source name `builtin:default`).
pub fn default_scene() -> Scene {
    let mut scene = Scene::new("builtin:default");
    let diffuse = Material::lambertian;
    let gold = Material { base_color: Vec3::new(1.0, 0.78, 0.34), metallic: 1.0, roughness: 0.45, specular: 1.0 };
    scene.add_object("ground", shapes::grid(10.0, 40), diffuse(Vec3::splat(0.8)), Affine3A::IDENTITY);
    let torus_pose = Affine3A::from_rotation_translation(Quat::from_rotation_x(0.5), Vec3::new(-1.6, 1.0, 0.2));
    scene.add_object("torus", shapes::torus(0.8, 0.3, 64, 24), gold, torus_pose);
    let sphere_pose = Affine3A::from_translation(Vec3::new(1.3, 0.7, 0.6));
    scene.add_object("sphere", shapes::sphere(0.7, 48, 24), diffuse(Vec3::new(0.8, 0.25, 0.2)), sphere_pose);
    let box_pose = Affine3A::from_rotation_translation(Quat::from_rotation_y(0.4), Vec3::new(0.2, 0.75, -1.4));
    scene.add_object("box", shapes::cuboid(Vec3::new(0.5, 0.75, 0.5)), diffuse(Vec3::new(0.2, 0.35, 0.8)), box_pose);
    // A 1.5 × 1.5 quad light at y = 4.5 facing −Y (CCW seen from below).
    let h = 0.75;
    let quad = vec![Vec3::new(-h, 0.0, -h), Vec3::new(h, 0.0, -h), Vec3::new(h, 0.0, h), Vec3::new(-h, 0.0, h)];
    scene.add_light(
        "light",
        quad,
        Vec3::new(1.0, 0.92, 0.8) * 20.0,
        Affine3A::from_translation(Vec3::new(0.3, 4.5, 0.5)),
    );
    scene.add_camera(Camera::look_at(Vec3::new(0.0, 4.2, 8.5), Vec3::new(0.0, 0.8, 0.0), 40f32.to_radians()));
    let mut sky = EnvironmentLight::new(EnvMap::procedural_sky(256, 128, Vec3::new(-0.5, 0.6, -0.4)));
    sky.intensity = 0.35;
    scene.set_environment(sky);
    scene
}
