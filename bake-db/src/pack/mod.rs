//! Asset packs: a glTF 2.0 binary with the scene, its baked data under the `KAGE_baked_shadows`
//! extension (spec: `docs/KAGE_baked_shadows.md`), and a preview any viewer shows: the baked
//! radiance as `COLOR_0` on `KHR_materials_unlit` materials.
//!
//! Layout: one root node per rigid group (its pose as `matrix`), one child node per mesh
//! instance (its group-relative transform) with its own mesh, in the snapshot's instance order,
//! then one child node per polygonal light (an emissive triangle fan), then the camera. Packs
//! are read back by kage's glTF importer, which restores groups, lights and camera; the
//! extension restores what the preview material replaced (the real materials) and the bakes.

use glam::Vec3;
use kage_engine::bspvt;
use kage_engine::prt::{self, Lighting};
use kage_engine::scene::{FlatScene, Scene};

mod read;
mod write;

pub use kage_runtime::pack::{EXTENSION, SEALED, VERSION, VERSIONS, integrity, ranges, schema};

pub use kage_runtime::pack::integrity::reseal;
pub use read::read;
pub use write::write;

/// What a pack holds besides its glTF scene.
pub struct Contents {
    /// BSPVT bake, if the pack has one.
    pub bspvt: Option<bspvt::Bake>,
    /// PRT bake with its lighting and settings, if the pack has one.
    pub prt: Option<(prt::Bake, Lighting, prt::Settings)>,
    /// Per instance and vertex: the bounces' light at the bake's placement (irradiance over
    /// π), if the pack has it.
    pub bounce: Option<kage_engine::scene::VertexValues>,
    /// What a reader should tell the user about the pack (it still shades).
    pub warnings: Vec<String>,
}

/// Everything [`write`](fn@write) needs.
pub struct Export<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// Its snapshot.
    pub flat: &'a FlatScene,
    /// BSPVT bake.
    pub bspvt: Option<&'a bspvt::Bake>,
    /// PRT bake, lighting and settings.
    pub prt: Option<prt::Parts<'a>>,
    /// Per instance and vertex: the baked radiance for the preview (linear).
    pub radiance: &'a [Vec<Vec3>],
    /// Per instance and vertex: the bounces' light (irradiance over π), if the look has them.
    pub bounce: Option<&'a [Vec<Vec3>]>,
    /// Preview exposure in stops (COLOR_0 = clamp(radiance · 2^exposure, 0, 1)).
    pub exposure: f32,
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec2;
    use kage_engine::scene::import::{self, ImportOptions};
    use std::path::Path;

    /// Textured materials, both UV sets and the source's vertex colours survive a pack: the
    /// material at every vertex and at points inside triangles is the same after reading.
    #[test]
    fn textured_materials_survive_a_pack() {
        let path = textured_pack("materials");
        let scene = import::import(&textured_scene(), ImportOptions::default()).unwrap();
        let flat = kage_engine::scene::flatten(&scene);
        let (back, _) = read(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        let again = kage_engine::scene::flatten(&back);
        for i in 0..flat.instances.len() {
            let (a, b) = (flat.mesh(i), again.mesh(i));
            assert_eq!((&a.uvs, &a.uvs1, &a.colors), (&b.uvs, &b.uvs1, &b.colors), "instance {i}");
            assert_eq!(flat.instances[i].maps.is_empty(), again.instances[i].maps.is_empty());
            for (k, tri) in a.triangles.iter().enumerate().step_by(7) {
                let corners = tri.map(|v| v as usize);
                let bary = [0.2, 0.3, 0.5];
                let (m, n) = (flat.material_at(i, corners, bary), again.material_at(i, corners, bary));
                assert_eq!(m, n, "instance {i}, triangle {k}");
            }
        }
        let poster = again.instances.iter().find_map(|i| i.maps.base_color.filter(|s| s.texcoord == 1)).unwrap();
        assert_eq!(poster.uv(Vec2::ZERO, Vec2::ZERO), Vec2::new(0.5, 0.0));
    }

    /// A pack with BSPVT names the vertices inside geometry (the ground's under the box of the
    /// built-in scene), as the engine finds them, for readers without a BVH to leave out of
    /// their pixels; one whose list is not ascending is refused, naming the field.
    #[test]
    fn a_pack_names_the_vertices_inside_geometry() {
        let scene = kage_engine::scene::default_scene();
        let flat = kage_engine::scene::flatten(&scene);
        let bake = kage_engine::bspvt::bake(&flat, &kage_engine::bspvt::Settings { res: 8, epsilon: 2.0 }, &|_| {});
        let radiance = flat.zeros();
        let export = Export {
            scene: &scene,
            flat: &flat,
            bspvt: Some(&bake),
            prt: None,
            radiance: &radiance,
            bounce: None,
            exposure: 0.0,
        };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("inside.glb");
        write(&path, &export).unwrap();
        let pack = kage_runtime::pack::Pack::read(&std::fs::read(&path).unwrap()).unwrap();
        let expected = kage_engine::bspvt::pixel::Inside::default().flags(&flat).to_vec();
        let named: Vec<Vec<bool>> = pack.instances.iter().map(|i| i.inside.clone()).collect();
        assert_eq!(named, expected);
        assert!(named.iter().flatten().any(|&f| f), "the ground under the box");
        edit_json(&path, |d| {
            let record = &mut d["meshes"][0]["primitives"][0]["extensions"][EXTENSION];
            record["inside"] = record["radiance"].clone();
        });
        let e = read(&path).err().map(|e| e.to_string()).expect("the pack is refused");
        assert!(e.contains("inside: not ascending vertex indices"), "{e}");
    }

    fn textured_scene() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes/textured_materials.gltf")
    }

    /// Writes a pack of `scene` without bakes at `path`.
    fn write_unbaked(path: &Path, scene: &kage_engine::scene::Scene) {
        let flat = kage_engine::scene::flatten(scene);
        let radiance = flat.zeros();
        let export =
            Export { scene, flat: &flat, bspvt: None, prt: None, radiance: &radiance, bounce: None, exposure: 0.0 };
        write(path, &export).unwrap();
    }

    /// A pack of the textured scene without bakes, written to a fresh path.
    fn textured_pack(name: &str) -> std::path::PathBuf {
        let scene = import::import(&textured_scene(), ImportOptions::default()).unwrap();
        let path = std::env::temp_dir().join(format!("kage-pack-{name}-{}.glb", std::process::id()));
        write_unbaked(&path, &scene);
        path
    }

    /// Rewrites the JSON chunk of the GLB at `path` with `edit`, sealed again: a pack written
    /// wrong, not one damaged after writing.
    fn edit_json(path: &Path, edit: impl FnOnce(&mut serde_json::Value)) {
        let bytes = std::fs::read(path).unwrap();
        let glb = kage_runtime::pack::glb::split(&bytes).unwrap();
        let mut doc: serde_json::Value = serde_json::from_slice(glb.json).unwrap();
        edit(&mut doc);
        let json = serde_json::to_vec(&doc).unwrap();
        std::fs::write(path, reseal(&kage_runtime::pack::glb::join(&json, glb.bin)).unwrap()).unwrap();
    }

    /// The reading error for the pack at `path` after `edit`.
    fn error_after(name: &str, edit: impl FnOnce(&mut serde_json::Value)) -> String {
        let path = textured_pack(name);
        edit_json(&path, edit);
        let e = read(&path).err().map(|e| e.to_string());
        std::fs::remove_file(&path).unwrap();
        e.unwrap_or_else(|| panic!("{name}: the edited pack was read"))
    }

    /// Declared sizes are checked against the documented limits before anything is allocated
    /// for them, and a missing field is named.
    #[test]
    fn hostile_headers_are_refused_before_allocating() {
        let prt_header = |silhouette: u64, regions: usize| {
            let region = serde_json::json!({"power": [1.0, 1.0, 1.0], "direction": [0.0, 1.0, 0.0],
                "solidAngle": 0.1, "spread": 0.1});
            serde_json::json!({"order": 2, "directions": 1024, "algorithm": prt::ALGORITHM_VERSION, "window": "none",
                "silhouetteResolution": silhouette, "lighting": vec![[0.0; 3]; 4], "regions": vec![region; regions]})
        };
        let e = error_after("silhouette", |d| d["extensions"][EXTENSION]["prt"] = prt_header(4096, 16));
        assert!(e.contains("silhouette resolution 4096 is outside 8..=512") && e.contains(".glb"), "{e}");
        let e = error_after("regions", |d| d["extensions"][EXTENSION]["prt"] = prt_header(128, 5000));
        assert!(e.contains("region count 5000"), "{e}");
        let e = error_after("face", |d| {
            d["extensions"][EXTENSION]["bspvt"] = serde_json::json!({"faceResolution": 1u64 << 40, "epsilon": 2.0,
                "format": bspvt::layout::FORMAT_VERSION})
        });
        assert!(e.contains("face resolution 1099511627776 is outside"), "{e}");
        let newer = VERSION + 1;
        let e = error_after("version", |d| d["extensions"][EXTENSION]["version"] = newer.into());
        assert!(e.contains(&format!("version {newer} (this kage reads 1..={VERSION})")), "{e}");
        let e = error_after("field", |d| {
            let record = &mut d["meshes"][0]["primitives"][0]["extensions"][EXTENSION]["material"];
            record.as_object_mut().unwrap().remove("roughness");
        });
        assert!(e.contains("mesh 0") && e.contains("missing field `roughness`"), "{e}");
        let e = error_after("view", |d| d["bufferViews"][0]["byteLength"] = (1u64 << 60).into());
        assert!(e.contains(".glb"), "{e}");
    }

    /// A pack is written beside its target and renamed over it: a symlink at the target is
    /// replaced, its own target left untouched.
    #[cfg(unix)]
    #[test]
    fn writing_a_pack_never_follows_a_symlink() {
        let dir = tempfile::tempdir().unwrap();
        let victim = dir.path().join("victim.txt");
        std::fs::write(&victim, "keep").unwrap();
        let link = dir.path().join("out.glb");
        std::os::unix::fs::symlink(&victim, &link).unwrap();
        let pack = textured_pack("symlink");
        let bytes = std::fs::read(&pack).unwrap();
        std::fs::rename(&pack, dir.path().join("first.glb")).unwrap();
        let (scene, _) = read(&dir.path().join("first.glb")).unwrap();
        write_unbaked(&link, &scene);
        assert_eq!(std::fs::read_to_string(&victim).unwrap(), "keep");
        assert!(!std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
        // Written again from what it read, the pack has the same bytes.
        assert_eq!(std::fs::read(&link).unwrap(), bytes);
    }
}
