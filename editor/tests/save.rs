//! Saving edits into the scene that was opened (`File > Save` / `Save As…`): the edits come back
//! on re-import, and everything kage does not edit stays as it was — untouched JSON values are
//! the same text, key order kept; the `.glb` binary chunk the same bytes.

use glam::{Affine3A, Quat, Vec3};
use indexmap::IndexMap;
use kage_editor::source::{Baseline, save};
use kage_engine::scene::{InGroup, Material, MeshRef, PolygonLight, Scene, Transform, flatten, import};
use serde_json::value::RawValue;
use std::path::{Path, PathBuf};

type Object = IndexMap<String, Box<RawValue>>;

/// A fresh folder for test `name` under Cargo's `target/tmp` (the next run replaces it).
fn scratch(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("kage-save").join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn asset(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../assets").join(rel)
}

fn open(path: &Path) -> Scene {
    import::import(path, Default::default()).unwrap()
}

fn objects(raw: &RawValue) -> Vec<Object> {
    serde_json::from_str(raw.get()).unwrap()
}

fn top(path: &Path) -> Object {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

fn entity_named(scene: &Scene, name: &str) -> hecs::Entity {
    scene.find_group(name).unwrap()
}

/// World-space light polygons, sorted for comparison.
fn light_points(scene: &Scene) -> Vec<Vec<Vec3>> {
    flatten(scene).lights.iter().map(|l| l.points.clone()).collect()
}

/// The Khronos validator finds no error in `file` (installed by `scripts/test`).
fn assert_valid(file: &Path) {
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tools/gltf-validator/validate.js");
    let out = std::process::Command::new("node")
        .arg(script)
        .arg(file)
        .output()
        .expect("node runs the glTF validator (scripts/test installs it)");
    assert!(out.status.success(), "{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
}

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() < 1e-4
}

/// cube_on_plane with things kage does not model: extras, a vendor extension, top-level extras.
fn scene_with_foreign_data(dir: &Path) -> PathBuf {
    let mut doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(asset("scenes/cube_on_plane.gltf")).unwrap()).unwrap();
    doc["nodes"][1]["extras"] = serde_json::json!({"zeta": 1, "alpha": [1, 2], "mid": {"y": true, "b": null}});
    doc["materials"][1]["extensions"]["VENDOR_sparkle"] = serde_json::json!({"b": 2, "a": 1});
    doc["extensionsUsed"].as_array_mut().unwrap().push("VENDOR_sparkle".into());
    doc["extras"] = serde_json::json!({"pipeline": "dcc", "version": 3});
    let path = dir.join("scene.gltf");
    std::fs::write(&path, serde_json::to_vec_pretty(&doc).unwrap()).unwrap();
    path
}

#[test]
fn saved_edits_come_back_and_everything_else_stays_the_same_text() {
    let dir = scratch("roundtrip");
    let path = scene_with_foreign_data(&dir);
    let original = std::fs::read(&path).unwrap();
    let mut scene = open(&path);
    let baseline = Baseline::of(&scene);

    // A group moved and turned, its material edited; the light moved, brightened past a factor
    // of 1 and resized.
    let cube = entity_named(&scene, "cube");
    scene.pose_group(cube, Quat::from_rotation_y(0.5), Vec3::new(0.4, 0.0, -0.3));
    let member =
        scene.world.query::<(hecs::Entity, &InGroup, &Material)>().iter().find(|(_, g, _)| g.group == cube).unwrap().0;
    let edited = Material { base_color: Vec3::new(0.1, 0.6, 0.2), metallic: 1.0, roughness: 0.3, specular: 0.0 };
    *scene.world.get::<&mut Material>(member).unwrap() = edited;
    let light = scene.world.query::<(hecs::Entity, &PolygonLight)>().iter().next().unwrap().0;
    {
        let mut l = scene.world.get::<&mut PolygonLight>(light).unwrap();
        let c = l.points.iter().copied().sum::<Vec3>() / l.points.len() as f32;
        l.points.iter_mut().for_each(|p| *p = c + (*p - c) * 1.5);
        l.radiance *= 3.0;
        let mut m = scene.world.get::<&mut InGroup>(light).unwrap();
        m.local = Affine3A::from_translation(Vec3::new(0.7, -0.2, 0.1)) * m.local;
    }
    kage_engine::scene::propagate_transforms(&mut scene.world);
    let saved = save(&scene, &baseline, &path, &path).unwrap();
    assert_eq!((saved.nodes, saved.materials), (2, 2), "{saved:?}");
    assert_eq!(std::fs::read(saved.backup.unwrap()).unwrap(), original, "the previous version is kept");

    // Re-opened, the file is the edited scene.
    assert_valid(&path);
    let back = open(&path);
    let pose = |s: &Scene| s.world.get::<&Transform>(entity_named(s, "cube")).unwrap().world;
    assert!(pose(&back).abs_diff_eq(pose(&scene), 1e-5), "{:?} vs {:?}", pose(&back), pose(&scene));
    let mat = back
        .world
        .query::<(&InGroup, &Material)>()
        .iter()
        .find(|(g, _)| g.group == entity_named(&back, "cube"))
        .map(|(_, m)| *m);
    assert_eq!(mat, Some(edited));
    let (a, b) = (light_points(&scene), light_points(&back));
    assert!(a.len() == 1 && a[0].iter().zip(&b[0]).all(|(p, q)| close(*p, *q)), "{a:?} vs {b:?}");
    let radiance = |s: &Scene| s.world.query::<&PolygonLight>().iter().next().unwrap().radiance;
    assert!(close(radiance(&back), radiance(&scene)), "{} vs {}", radiance(&back), radiance(&scene));

    // What kage does not edit is the same text, in the same order.
    let (before, after) = (serde_json::from_slice::<Object>(&original).unwrap(), top(&path));
    assert_eq!(before.keys().collect::<Vec<_>>(), after.keys().collect::<Vec<_>>());
    for key in ["asset", "scenes", "accessors", "bufferViews", "buffers", "cameras", "extras"] {
        assert_eq!(before[key].get(), after[key].get(), "{key}");
    }
    let (n0, n1) = (objects(&before["nodes"]), objects(&after["nodes"]));
    assert_eq!(n0[1]["extras"].get(), n1[1]["extras"].get(), "extras kept as text, key order too");
    assert_eq!(n0[0].get("name").map(|r| r.get()), n1[0].get("name").map(|r| r.get()));
    assert!(
        n0[0].iter().zip(&n1[0]).all(|(a, b)| a.0 == b.0 && a.1.get() == b.1.get()),
        "an unedited node is untouched"
    );
    let (m0, m1) = (objects(&before["materials"]), objects(&after["materials"]));
    assert_eq!(
        m0[0].iter().map(|(k, v)| (k, v.get())).collect::<Vec<_>>(),
        m1[0].iter().map(|(k, v)| (k, v.get())).collect::<Vec<_>>()
    );
    let ext =
        |m: &Object| serde_json::from_str::<Object>(m["extensions"].get()).unwrap()["VENDOR_sparkle"].get().to_string();
    assert_eq!(ext(&m0[1]), ext(&m1[1]), "an unknown extension on an edited material stays");
    let used: Vec<String> = serde_json::from_str(after["extensionsUsed"].get()).unwrap();
    assert!(
        used.contains(&"VENDOR_sparkle".to_string()) && used.contains(&"KHR_materials_emissive_strength".to_string())
    );

    // Saving again with nothing changed writes nothing new.
    let again = save(&back, &Baseline::of(&back), &path, &path).unwrap();
    assert_eq!((again.nodes, again.materials), (0, 0));
}

#[test]
fn save_as_copies_what_the_file_refers_to_and_a_glb_keeps_its_binary_chunk() {
    let dir = scratch("save-as");
    let src = dir.join("src");
    std::fs::create_dir_all(&src).unwrap();
    for f in ["textured_light.gltf", "textured_light.bin", "stained_glass.png"] {
        std::fs::copy(asset(&format!("scenes/{f}")), src.join(f)).unwrap();
    }
    let from = src.join("textured_light.gltf");
    let mut scene = open(&from);
    let baseline = Baseline::of(&scene);
    let teapot = entity_named(&scene, "teapot");
    scene.pose_group(teapot, Quat::IDENTITY, Vec3::new(0.5, 0.0, 0.0));
    let to = dir.join("out").join("moved.gltf");
    std::fs::create_dir_all(to.parent().unwrap()).unwrap();
    let saved = save(&scene, &baseline, &from, &to).unwrap();
    assert_eq!(saved.copied.len(), 2, "the .bin and the image: {saved:?}");
    assert!(saved.backup.is_none());
    let back = open(&to);
    let t = back.world.get::<&Transform>(entity_named(&back, "teapot")).unwrap().world;
    assert!(t.abs_diff_eq(scene.world.get::<&Transform>(teapot).unwrap().world, 1e-5));
    assert_eq!(light_points(&back).len(), 1, "the textured light comes back");
    assert!(save(&scene, &baseline, &from, &dir.join("x.glb")).unwrap_err().contains("keeps the format"));

    // A .glb: the JSON chunk edited, the binary chunk byte for byte.
    let glb = dir.join("suzanne.glb");
    std::fs::copy(asset("models/suzanne.glb"), &glb).unwrap();
    let bin = |p: &Path| gltf::binary::Glb::from_slice(&std::fs::read(p).unwrap()).unwrap().bin.unwrap().into_owned();
    let before = bin(&glb);
    let mut scene = open(&glb);
    let baseline = Baseline::of(&scene);
    let group = scene.world.query::<(hecs::Entity, &kage_engine::scene::RigidGroup)>().iter().next().unwrap().0;
    scene.pose_group(group, Quat::from_rotation_x(0.3), Vec3::Y);
    save(&scene, &baseline, &glb, &glb).unwrap();
    assert_eq!(bin(&glb), before);
    let back = open(&glb);
    let first = back.world.query::<(&kage_engine::scene::RigidGroup, &Transform)>().iter().next().unwrap().1.world;
    assert!(first.abs_diff_eq(scene.world.get::<&Transform>(group).unwrap().world, 1e-5));
}

#[test]
fn edits_the_file_cannot_hold_are_refused_by_name_and_nothing_is_written() {
    let dir = scratch("refused");
    let path = dir.join("scene.gltf");
    std::fs::copy(asset("scenes/bunny_two_groups.gltf"), &path).unwrap();
    std::fs::copy(asset("scenes/bunny_two_groups.bin"), dir.join("bunny_two_groups.bin")).unwrap();
    let original = std::fs::read(&path).unwrap();
    let scene = open(&path);
    let baseline = Baseline::of(&scene);
    // A replaced mesh: buffers are never rewritten.
    let (e, r) = scene.world.query::<(hecs::Entity, &MeshRef)>().iter().map(|(e, r)| (e, *r)).next().unwrap();
    let other = scene.world.query::<&MeshRef>().iter().find(|m| m.index != r.index).copied().unwrap();
    *scene.world.get::<&mut MeshRef>(e).unwrap() = other;
    let err = save(&scene, &baseline, &path, &path).unwrap_err();
    assert!(err.contains("mesh was replaced") && err.contains("nodes["), "{err}");
    assert_eq!(std::fs::read(&path).unwrap(), original, "nothing was written");
    assert!(!dir.join("scene.gltf.bak").exists());
}

#[test]
fn added_groups_become_new_nodes_and_deleted_ones_leave_the_scene() {
    let dir = scratch("presence");
    let path = dir.join("scene.gltf");
    std::fs::copy(asset("scenes/bunny_two_groups.gltf"), &path).unwrap();
    std::fs::copy(asset("scenes/bunny_two_groups.bin"), dir.join("bunny_two_groups.bin")).unwrap();
    let mut scene = open(&path);
    let baseline = Baseline::of(&scene);
    let groups = |s: &Scene| s.world.query::<&kage_engine::scene::RigidGroup>().iter().count();
    let before = groups(&scene);

    // Added in the editor: a new light and a copy of a group become new nodes.
    let mut added = scene.duplicate();
    let lamp = vec![Vec3::new(0.0, 3.0, 0.0), Vec3::new(0.0, 3.0, 1.0), Vec3::new(1.0, 3.0, 0.0)];
    added.add_light("new lamp", lamp.clone(), Vec3::splat(25.0), Affine3A::IDENTITY);
    let source = entity_named(&added, "group_box_sphere");
    let pose =
        Affine3A::from_translation(Vec3::new(0.0, 0.0, 3.0)) * added.world.get::<&Transform>(source).unwrap().world;
    let copy = added.world.spawn((
        kage_engine::scene::RigidGroup { index: 99 },
        Transform { world: pose },
        kage_engine::scene::Name("copy".into()),
        kage_engine::scene::NodeId(1000),
    ));
    for m in added.members(source) {
        let e = added.world.spawn(&added.components(m).unwrap());
        added.world.get::<&mut InGroup>(e).unwrap().group = copy;
    }
    kage_engine::scene::propagate_transforms(&mut added.world);
    let to = dir.join("added.gltf");
    let saved = save(&added, &baseline, &path, &to).unwrap();
    assert_eq!(saved.added, 2, "{saved:?}");
    assert_valid(&to);
    let back = open(&to);
    assert_eq!(groups(&back), before + 2);
    let lights = light_points(&back);
    assert!(lights.iter().any(|l| l.len() == 3 && l.iter().zip(&lamp).all(|(p, q)| close(*p, *q))), "{lights:?}");
    let copied = back.world.get::<&Transform>(entity_named(&back, "copy")).unwrap().world;
    assert!(copied.abs_diff_eq(pose, 1e-5));
    let after = top(&to);
    assert_eq!(objects(&after["meshes"]).len(), 5, "the copy shows the file's meshes; the lamp has one of its own");
    assert!(
        after["buffers"].get().contains("data:application/octet-stream;base64,"),
        "new geometry in a buffer of its own"
    );

    // Deleted: the group and its members leave the scene; the nodes stay in the file, unused.
    let group = entity_named(&scene, "group_bunny");
    for e in scene.members(group).into_iter().chain([group]) {
        scene.world.despawn(e).unwrap();
    }
    let saved = save(&scene, &baseline, &path, &path).unwrap();
    assert_eq!(saved.nodes, 1);
    assert_valid(&path);
    let back = open(&path);
    assert_eq!(groups(&back), before - 1);
    assert!(back.find_group("group_bunny").is_err());
    let after = top(&path);
    assert_eq!(objects(&after["nodes"]).len(), 7, "the nodes stay");
    let scenes = objects(&after["scenes"]);
    let roots: Vec<usize> = serde_json::from_str(scenes[0]["nodes"].get()).unwrap();
    assert!(!roots.contains(&2), "{roots:?}");
}
