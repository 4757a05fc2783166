//! File actions: save the edits into the scene file ([`super::source`]), export an asset pack
//! (glTF binary through the pack writer, with the bakes), and replace a mesh by one read from a
//! glTF file.

use super::state::Editor;
use glam::Vec3;
use kage_bake_db::pack::{self, Export};
use kage_engine::scene::{FlatScene, VertexValues, flatten};
use std::path::{Path, PathBuf};

/// `SCENE_DIR/<stem><suffix>`, or `kage-default<suffix>` in the working folder.
fn beside_scene(ed: &Editor, suffix: &str) -> PathBuf {
    match &ed.options.scene_path {
        Some(p) => {
            let stem = p.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "scene".into());
            p.with_file_name(format!("{stem}{suffix}"))
        }
        None => PathBuf::from(format!("kage-default{suffix}")),
    }
}

/// Writes `path` through the pack writer: an export (`with_bakes`) writes what was baked — the
/// refined meshes the bakes belong to — and a save the scene as it was made, on its source
/// meshes (refinement is the bake's business: reopening the file refines again from them).
fn write(ed: &mut Editor, path: PathBuf, with_bakes: bool) -> String {
    let source = (!with_bakes).then(|| {
        let mut s = ed.doc.scene.duplicate();
        s.restore_source_meshes();
        let flat = flatten(&s);
        (s, flat)
    });
    let (scene, flat) = source.as_ref().map_or((&ed.doc.scene, &ed.flat), |(s, f)| (s, f));
    let radiance = preview(ed, flat);
    let prt = match (&ed.bakes.prt, &ed.bakes.lighting) {
        (Some(bake), Some(lighting)) if with_bakes => {
            Some(kage_engine::prt::Parts { bake, lighting, settings: &ed.options.prt })
        }
        _ => None,
    };
    let export = Export {
        scene,
        flat,
        bspvt: ed.bakes.bspvt.as_deref().filter(|_| with_bakes && !ed.bakes.bspvt_stale),
        prt,
        radiance: &radiance,
        exposure: ed.view.exposure,
    };
    let message = match pack::write(&path, &export) {
        Ok(()) => format!("wrote {}", path.display()),
        Err(e) => format!("{}: {e}", path.display()),
    };
    if message.starts_with("wrote") {
        ed.info(message.clone())
    } else {
        ed.error(message.clone())
    }
    message
}

/// The preview radiance per vertex of `flat` (the snapshot or its source meshes): a refined
/// mesh starts with its source's vertices (refinement appends), so a source vertex keeps its
/// refined twin's value; zeros where the shapes do not fit (a result still on its way).
fn preview(ed: &Editor, flat: &FlatScene) -> VertexValues {
    let fits = ed.radiance.len() == flat.instances.len();
    (0..flat.instances.len())
        .map(|i| {
            let n = flat.vertex_count(i);
            let shown = ed.radiance.get(i).filter(|r| fits && r.len() >= n && ed.flat.vertex_count(i) >= n);
            let same = |k: usize| flat.vertex(i, k).0 == ed.flat.vertex(i, k).0;
            match shown {
                Some(r) if (0..n).all(same) => r[..n].to_vec(),
                _ => vec![Vec3::ZERO; n],
            }
        })
        .collect()
}

/// Saves the edits into the scene file that was opened ([`super::source::save`]); the built-in
/// scene, which has no file, is written as `kage-default.glb` through the pack writer.
pub fn save(ed: &mut Editor) -> String {
    match ed.options.scene_path.clone() {
        Some(path) => save_as(ed, &path),
        None => write(ed, beside_scene(ed, ".glb"), false),
    }
}

/// Saves the opened scene with its edits at `to` (the opened file itself for Save), keeping
/// everything kage does not edit; afterwards `to` is the scene the editor edits.
pub fn save_as(ed: &mut Editor, to: &Path) -> String {
    let Some(from) = ed.options.scene_path.clone() else {
        return write(ed, to.to_path_buf(), false);
    };
    match super::source::save(&ed.doc.scene, ed.doc.baseline(), &from, to) {
        Ok(saved) => {
            ed.doc.mark_saved();
            if to != from {
                ed.options.scene_path = Some(to.to_path_buf());
                ed.start_watching();
            } else if let Some(w) = &mut ed.backend.watcher {
                w.note_write(to);
            }
            // Added things now have nodes in the file, which their entities do not know.
            if saved.added > 0 {
                super::systems::reimport_scene(ed);
            }
            let message = format!(
                "saved {} ({} nodes and {} materials written{}{})",
                to.display(),
                saved.nodes,
                saved.materials,
                saved.backup.map(|b| format!("; the previous version is {}", b.display())).unwrap_or_default(),
                if saved.copied.is_empty() {
                    String::new()
                } else {
                    format!("; {} files copied beside it", saved.copied.len())
                },
            );
            ed.info(message.clone());
            message
        }
        Err(e) => {
            ed.error(e.clone());
            e
        }
    }
}

/// Writes an asset pack with the current bakes as `<stem>.pack.glb`.
pub fn export_pack(ed: &mut Editor) -> String {
    let path = beside_scene(ed, ".pack.glb");
    write(ed, path, true)
}

/// Replaces `instance`'s mesh by the first mesh of the glTF file at `path` (in its own frame: the
/// instance keeps its transform); a geometry edit, so the affected bakes re-run.
pub fn replace_mesh_from(ed: &mut Editor, instance: hecs::Entity, path: &Path) -> String {
    let imported = kage_engine::scene::import::import(path, ed.options.import.clone()).map_err(|e| e.to_string());
    let mesh = imported.and_then(|s| {
        s.meshes.first().map(|m| (**m).clone()).ok_or_else(|| format!("{}: the file has no mesh", path.display()))
    });
    match mesh {
        Ok(mesh) => {
            let message = format!("replaced the mesh by {}'s ({} vertices)", path.display(), mesh.positions.len());
            ed.replace_mesh(instance, mesh);
            ed.info(message.clone());
            message
        }
        Err(e) => {
            ed.error(format!("replace mesh: {e}"));
            e
        }
    }
}
