//! Import of the shared test assets: counts, transforms, lights, cameras, hashes.

use glam::Vec3;
use kage_engine::scene::import::{ImportOptions, import};
use kage_engine::scene::{Camera, MeshRef, PolygonLight, RigidGroup, Scene, flatten};
use kage_tests::asset;

fn load(rel: &str) -> Scene {
    import(&asset(rel), ImportOptions::default()).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

/// (receiver vertices, receiver triangles) summed over instances.
fn counts(s: &Scene) -> (usize, usize) {
    s.world.query::<&MeshRef>().iter().fold((0, 0), |(v, t), m| {
        let mesh = &s.meshes[m.index as usize];
        (v + mesh.positions.len(), t + mesh.triangles.len())
    })
}

fn lights(s: &Scene) -> Vec<PolygonLight> {
    s.world.query::<&PolygonLight>().iter().cloned().collect()
}

#[test]
fn models_have_the_published_counts() {
    for (rel, v, t) in [
        ("models/bunny.glb", 1839, 3674),
        ("models/teapot.glb", 3241, 6320),
        ("models/teapot_npm.glb", 529, 992),
        ("models/suzanne.glb", 7503, 14842),
    ] {
        let s = load(rel);
        assert_eq!(counts(&s), (v, t), "{rel}");
        assert_eq!(s.world.query::<&RigidGroup>().iter().count(), 1, "{rel}");
    }
}

#[test]
fn khronos_samples_import_with_instancing_scenes_and_cameras() {
    for (rel, v, t) in [
        ("khronos/Box/Box.gltf", 24, 12),
        ("khronos/BoxTextured/BoxTextured.gltf", 24, 12),
        ("khronos/SimpleMeshes/SimpleMeshes.gltf", 6, 2),
        ("khronos/MultipleScenes/MultipleScenes.gltf", 4, 2),
        ("khronos/Cameras/Cameras.gltf", 4, 2),
        ("khronos/SimpleSparseAccessor/SimpleSparseAccessor.gltf", 14, 12),
        ("khronos/TriangleWithoutIndices/TriangleWithoutIndices.gltf", 3, 1),
    ] {
        assert_eq!(counts(&load(rel)), (v, t), "{rel}");
    }
    // One mesh shared by two nodes: one unique mesh, two instances.
    let s = load("khronos/SimpleMeshes/SimpleMeshes.gltf");
    assert_eq!(s.meshes.len(), 1);
    assert_eq!(s.world.query::<&MeshRef>().iter().count(), 2);
    let cams = load("khronos/Cameras/Cameras.gltf");
    assert_eq!(cams.world.query::<&Camera>().iter().count(), 2);
    // Box: the root's matrix turns Z-up into Y-up; the world-space box still spans [-0.5, 0.5]³.
    let flat = flatten(&load("khronos/Box/Box.gltf"));
    let max = flat.triangles.iter().flatten().fold(Vec3::splat(f32::MIN), |m, p| m.max(*p));
    assert!((max - Vec3::splat(0.5)).abs().max_element() < 1e-5, "{max}");
    // Sparse accessor: three substituted positions are applied.
    let sparse = load("khronos/SimpleSparseAccessor/SimpleSparseAccessor.gltf");
    let top = sparse.meshes[0].positions.iter().map(|p| p.y).fold(f32::MIN, f32::max);
    assert!(top > 1.5, "sparse substitution raised some vertices: {top}");
}

#[test]
fn authored_scenes_find_their_lights() {
    let s = load("scenes/cube_on_plane.gltf");
    assert_eq!(counts(&s), (1705, 3212));
    let l = lights(&s);
    assert_eq!(l.len(), 1);
    assert_eq!(l[0].points.len(), 4, "a planar convex quad is one polygon");
    assert_eq!(l[0].radiance, Vec3::splat(10.0));
    let s = load("scenes/teapot_quad_light.gltf");
    assert_eq!(counts(&s), (5842, 11320));
    assert_eq!(lights(&s)[0].radiance, Vec3::new(8.0, 7.2, 6.0));
    let s = load("scenes/emissive_strength_cubes.gltf");
    let l = lights(&s);
    assert_eq!(l.len(), 60, "five closed cubes are not planar: one polygon per triangle");
    let mut strengths: Vec<u32> = l.iter().map(|l| (l.radiance.z / 0.9).round() as u32).collect();
    strengths.dedup();
    assert_eq!(strengths, vec![1, 2, 4, 8, 16]);
    let s = load("scenes/textured_light.gltf");
    let l = lights(&s);
    assert_eq!((l.len(), l[0].texture, l[0].uvs.len()), (1, Some(0), 4));
    assert_eq!((s.textures[0].width, s.textures[0].height), (128, 64));
    let s = load("scenes/bunny_two_groups.gltf");
    assert_eq!(s.world.query::<&RigidGroup>().iter().count(), 3, "ground, group_bunny, group_box_sphere");
    assert_eq!(counts(&s), (5106, 9966));
}

#[test]
fn a_mirrored_light_emits_like_the_plain_one() {
    let a = flatten(&load("scenes/cube_on_plane.gltf"));
    let b = flatten(&load("scenes/cube_on_plane_mirrored_light.gltf"));
    assert_eq!(a.lights.len(), 1);
    assert_eq!(b.lights.len(), 1);
    for f in [&a, &b] {
        assert!((f.lights[0].normal - Vec3::NEG_Y).length() < 1e-6, "faces the ground");
        assert!((f.lights[0].area - 1.0).abs() < 1e-5);
    }
    let centre = |f: &kage_engine::scene::FlatScene| f.lights[0].points.iter().sum::<Vec3>() / 4.0;
    assert!((centre(&a) - centre(&b)).length() < 1e-5);
}

#[test]
fn mesh_hashes_are_stable_across_loads_and_formats() {
    let a = load("models/teapot.glb");
    let b = load("models/teapot.glb");
    assert_eq!(a.meshes[0].hash, b.meshes[0].hash);
    // The teapot inside the scene is the same geometry as the model file.
    let s = load("scenes/teapot_quad_light.gltf");
    assert!(s.meshes.iter().any(|m| m.hash == a.meshes[0].hash));
    assert_ne!(a.meshes[0].hash, load("models/bunny.glb").meshes[0].hash);
}

#[test]
fn the_default_scene_has_everything_a_render_needs() {
    let s = kage_engine::scene::default_scene();
    let f = flatten(&s);
    assert_eq!(f.instances.len(), 4);
    assert_eq!(f.lights.len(), 1);
    assert!(f.environment.is_some() && f.camera.is_some());
    assert!((f.lights[0].normal - Vec3::NEG_Y).length() < 1e-6);
}
