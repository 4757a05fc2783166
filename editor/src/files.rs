//! File actions: save the edited scene and export an asset pack, both as glTF binary through
//! the pack writer (so poses, materials, lights and cameras round-trip through
//! `kage_bake_db::pack::read`), and replace a mesh by one read from a glTF file.

use super::state::Editor;
use kage_bake_db::pack::{self, Export};
use kage_engine::scene::VertexValues;
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

fn write(ed: &mut Editor, path: PathBuf, with_bakes: bool) -> String {
    let zeros: VertexValues;
    let radiance = if ed.radiance.len() == ed.flat.instances.len() {
        &ed.radiance
    } else {
        zeros = ed.flat.zeros();
        &zeros
    };
    let prt = match (&ed.bakes.prt, &ed.bakes.lighting) {
        (Some(bake), Some(lighting)) if with_bakes => {
            Some(kage_engine::prt::Parts { bake, lighting, settings: &ed.options.prt })
        }
        _ => None,
    };
    let export = Export {
        scene: &ed.scene,
        flat: &ed.flat,
        bspvt: ed.bakes.bspvt.as_deref().filter(|_| with_bakes && !ed.bakes.bspvt_stale),
        prt,
        radiance,
        exposure: ed.exposure,
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

/// Writes the edited scene (no bakes) beside the original as `<stem>.edited.glb`.
pub fn save(ed: &mut Editor) -> String {
    let path = beside_scene(ed, ".edited.glb");
    write(ed, path, false)
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
