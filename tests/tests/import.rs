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

/// Writes `doc` as `name.gltf` with `bytes` as its one buffer, `name.bin`, in `dir`.
fn gltf_with_buffer(dir: &std::path::Path, name: &str, mut doc: serde_json::Value, bytes: &[u8]) -> std::path::PathBuf {
    std::fs::write(dir.join(format!("{name}.bin")), bytes).unwrap();
    doc["asset"] = serde_json::json!({"version": "2.0"});
    doc["buffers"] = serde_json::json!([{"uri": format!("{name}.bin"), "byteLength": bytes.len()}]);
    let path = dir.join(format!("{name}.gltf"));
    std::fs::write(&path, doc.to_string()).unwrap();
    path
}

/// Little-endian bytes of `floats`.
fn f32_bytes(floats: &[f32]) -> Vec<u8> {
    floats.iter().flat_map(|f| f.to_le_bytes()).collect()
}

/// World-space positions of the instance of the node named `name`.
fn world_positions(s: &Scene, name: &str) -> Vec<Vec3> {
    use kage_engine::scene::{Name, Transform};
    let mut q = s.world.query::<(&MeshRef, &Transform, &Name)>();
    let (m, t, _) = q.iter().find(|(_, _, n)| n.0 == name).unwrap_or_else(|| panic!("no instance '{name}'"));
    s.meshes[m.index as usize].positions.iter().map(|p| t.world.transform_point3(*p)).collect()
}

fn assert_points(got: &[Vec3], want: &[[f32; 3]], what: &str) {
    assert_eq!(got.len(), want.len(), "{what}");
    for (g, w) in got.iter().zip(want) {
        assert!((*g - Vec3::from_array(*w)).abs().max_element() < 1e-5, "{what}: {got:?}");
    }
}

#[test]
fn morph_targets_import_with_their_default_weights() {
    let dir = kage_tests::scratch!("morph");
    // A triangle, two position targets; the mesh's weights (0.5, 0.25), overridden by a node's (1, 0).
    let mut bytes = f32_bytes(&[0., 0., 0., 1., 0., 0., 0., 1., 0.]);
    bytes.extend(f32_bytes(&[0., 0., 1., 0., 0., 1., 0., 0., 1.]));
    bytes.extend(f32_bytes(&[0., 0., 0., 0., 0., 0., 0., 1., 0.]));
    bytes.extend(f32_bytes(&[1., 0., 0., 0., 0., 0., 0., 0., 0.]));
    let vec3 = |offset: usize| serde_json::json!({"bufferView": 0, "byteOffset": offset, "componentType": 5126, "count": 3, "type": "VEC3"});
    let mut position = vec3(0);
    position["min"] = serde_json::json!([0, 0, 0]);
    position["max"] = serde_json::json!([1, 1, 0]);
    let doc = |target_count: usize| {
        let mut short = vec3(72);
        short["count"] = serde_json::json!(target_count);
        serde_json::json!({
            "scene": 0, "scenes": [{"nodes": [0, 1]}],
            "nodes": [{"name": "mesh weights", "mesh": 0}, {"name": "node weights", "mesh": 0, "weights": [1.0, 0.0]}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}, "targets": [{"POSITION": 2}, {"POSITION": 3}]}], "weights": [0.5, 0.25]}],
            "accessors": [position, vec3(36), short, vec3(108)],
            "bufferViews": [{"buffer": 0, "byteLength": bytes.len()}],
        })
    };
    let s = import(&gltf_with_buffer(&dir, "morph", doc(3), &bytes), ImportOptions::default()).unwrap();
    assert_points(&world_positions(&s, "mesh weights"), &[[0.25, 0., 0.], [1., 0., 0.], [0., 1.5, 0.]], "mesh");
    assert_points(&world_positions(&s, "node weights"), &[[0., 0., 0.], [1., 0., 0.], [0., 2., 0.]], "node");
    // A target with the wrong element count is named.
    let e = import(&gltf_with_buffer(&dir, "short", doc(2), &bytes), ImportOptions::default())
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("short.gltf") && e.contains("morph target 0") && e.contains("2 elements for 3 vertices"), "{e}");
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn skinned_meshes_import_posed_by_their_joints() {
    let dir = kage_tests::scratch!("skin");
    // A strip of two quads' corners: the bottom pair bound to joint 0, the top pair to joint 1,
    // which sits 1 m up and is turned 90° about Z. The skinned node's own translation is ignored.
    let mut bytes = f32_bytes(&[0., 0., 0., 1., 0., 0., 0., 2., 0., 1., 2., 0.]);
    bytes.extend(f32_bytes(&[0., 0., 1., 0., 0., 1., 0., 0., 1., 0., 0., 1.]));
    bytes.extend(f32_bytes(&[1., 0., 0., 0., 1., 0., 0., 0., 1., 0., 0., 0., 1., 0., 0., 0.]));
    let mut inverse_binds = glam::Mat4::IDENTITY.to_cols_array().to_vec();
    inverse_binds.extend(glam::Mat4::from_translation(Vec3::new(0., -1., 0.)).to_cols_array());
    bytes.extend(f32_bytes(&inverse_binds));
    let joints_offset = bytes.len();
    let joints = |top: u8| [0u8, 0, 0, 0, 0, 0, 0, 0, top, 0, 0, 0, top, 0, 0, 0];
    let doc = |top: u8| {
        let mut b = bytes.clone();
        b.extend(joints(top));
        let acc = |offset: usize, count: usize, component: u32, kind: &str| serde_json::json!({"bufferView": 0, "byteOffset": offset, "componentType": component, "count": count, "type": kind});
        let mut position = acc(0, 4, 5126, "VEC3");
        position["min"] = serde_json::json!([0, 0, 0]);
        position["max"] = serde_json::json!([1, 2, 0]);
        let s = (0.5f32).sqrt();
        let json = serde_json::json!({
            "scene": 0, "scenes": [{"nodes": [0, 1]}],
            "nodes": [
                {"name": "skinned", "mesh": 0, "skin": 0, "translation": [5, 0, 0]},
                {"name": "skeleton", "children": [2]},
                {"name": "joint0", "children": [3]},
                {"name": "joint1", "translation": [0, 1, 0], "rotation": [0, 0, s, s]},
            ],
            "skins": [{"joints": [2, 3], "inverseBindMatrices": 4}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "WEIGHTS_0": 2, "JOINTS_0": 3}}]}],
            "accessors": [position, acc(48, 4, 5126, "VEC3"), acc(96, 4, 5126, "VEC4"), acc(joints_offset, 4, 5121, "VEC4"), acc(160, 2, 5126, "MAT4")],
            "bufferViews": [{"buffer": 0, "byteLength": b.len()}],
        });
        (json, b)
    };
    let (json, b) = doc(1);
    let s = import(&gltf_with_buffer(&dir, "skin", json, &b), ImportOptions::default()).unwrap();
    let posed = [[0., 0., 0.], [1., 0., 0.], [-1., 1., 0.], [-1., 2., 0.]];
    assert_points(&world_positions(&s, "skinned"), &posed, "skinned");
    // A joint index beyond the skin's joints is named.
    let (json, b) = doc(7);
    let e =
        import(&gltf_with_buffer(&dir, "bad", json, &b), ImportOptions::default()).err().expect("refused").to_string();
    assert!(e.contains("bad.gltf") && e.contains("names joint 7, but the skin has 2 joints"), "{e}");
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn sparse_positions_without_a_base_view_substitute_into_zeros() {
    let dir = kage_tests::scratch!("sparse");
    // Three vertices, all zeros but for two substituted by the sparse data.
    let mut bytes = vec![1u8, 2, 0, 0];
    bytes.extend(f32_bytes(&[1., 0., 0., 0., 1., 0.]));
    let doc = serde_json::json!({
        "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "sparse", "mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "accessors": [{"componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0],
            "sparse": {"count": 2, "indices": {"bufferView": 0, "componentType": 5121}, "values": {"bufferView": 1}}}],
        "bufferViews": [{"buffer": 0, "byteLength": 2}, {"buffer": 0, "byteOffset": 4, "byteLength": 24}],
    });
    let s = import(&gltf_with_buffer(&dir, "sparse", doc, &bytes), ImportOptions::default()).unwrap();
    assert_points(&world_positions(&s, "sparse"), &[[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]], "sparse");
    std::fs::remove_dir_all(dir).unwrap();
}
