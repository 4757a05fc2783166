//! File actions: save the edits into the scene file ([`super::source`]), export an asset pack
//! (glTF binary through the pack writer, with the bakes), and replace a mesh by one read from a
//! glTF file.

use super::state::Editor;
use glam::Vec3;
use kage_bake_db::pack::{self, Export};
use kage_engine::scene::{FlatScene, VertexValues, flatten};
use std::path::{Path, PathBuf};

impl Editor {
    /// `SCENE_DIR/<stem><suffix>`, or `kage-default<suffix>` in the working folder.
    fn beside_scene(&self, suffix: &str) -> PathBuf {
        match &self.options.scene_path {
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
    fn write(&mut self, path: PathBuf, with_bakes: bool) -> String {
        let source = (!with_bakes).then(|| {
            let mut s = self.doc.scene.duplicate();
            s.restore_source_meshes();
            let flat = flatten(&s);
            (s, flat)
        });
        let (scene, flat) = source.as_ref().map_or((&self.doc.scene, &self.flat), |(s, f)| (s, f));
        let radiance = self.preview(flat);
        let prt = match (&self.bakes.prt, &self.bakes.lighting) {
            (Some(bake), Some(lighting)) if with_bakes => {
                Some(kage_engine::prt::Parts { bake, lighting, settings: &self.options.prt })
            }
            _ => None,
        };
        let export = Export {
            scene,
            flat,
            bspvt: self.bakes.bspvt.as_deref().filter(|_| with_bakes && !self.bakes.bspvt_stale),
            prt,
            radiance: &radiance,
            bounce: self.bounce_light().filter(|_| with_bakes),
            exposure: self.view.exposure,
        };
        let message = match pack::write(&path, &export) {
            Ok(()) => format!("wrote {}", path.display()),
            Err(e) => format!("{}: {e}", path.display()),
        };
        if message.starts_with("wrote") {
            self.info(message.clone())
        } else {
            self.error(message.clone())
        }
        message
    }

    /// The preview radiance per vertex of `flat` (the snapshot or its source meshes): a refined
    /// mesh starts with its source's vertices (refinement appends), so a source vertex keeps its
    /// refined twin's value; zeros where the shapes do not fit (a result still on its way).
    fn preview(&self, flat: &FlatScene) -> VertexValues {
        let fits = self.results.radiance.len() == flat.instances.len();
        (0..flat.instances.len())
            .map(|i| {
                let n = flat.vertex_count(i);
                let shown =
                    self.results.radiance.get(i).filter(|r| fits && r.len() >= n && self.flat.vertex_count(i) >= n);
                let same = |k: usize| flat.vertex(i, k).0 == self.flat.vertex(i, k).0;
                match shown {
                    Some(r) if (0..n).all(same) => r[..n].to_vec(),
                    _ => vec![Vec3::ZERO; n],
                }
            })
            .collect()
    }

    /// The light of the bounces the preview shows, when it fits the snapshot (an export's
    /// meshes) and the indirect term is on.
    fn bounce_light(&self) -> Option<&[Vec<Vec3>]> {
        let light = &self.results.bounce_light;
        let fits = light.len() == self.flat.instances.len()
            && light.iter().enumerate().all(|(i, l)| l.len() == self.flat.vertex_count(i));
        (fits && self.indirect && self.view.method.direct()).then_some(light.as_slice())
    }

    /// Saves the edits into the scene file that was opened ([`super::source::save`]); the built-in
    /// scene, which has no file, is written as `kage-default.glb` through the pack writer.
    pub fn save(&mut self) -> String {
        match self.options.scene_path.clone() {
            Some(path) => self.save_as(&path),
            None => self.write(self.beside_scene(".glb"), false),
        }
    }

    /// Saves the opened scene with its edits at `to` (the opened file itself for Save), keeping
    /// everything kage does not edit; afterwards `to` is the scene the editor edits.
    pub fn save_as(&mut self, to: &Path) -> String {
        let Some(from) = self.options.scene_path.clone() else {
            return self.write(to.to_path_buf(), false);
        };
        match super::source::save(&self.doc.scene, self.doc.baseline(), &from, to) {
            Ok(saved) => {
                self.doc.mark_saved();
                if to != from {
                    self.options.scene_path = Some(to.to_path_buf());
                    self.start_watching();
                } else if let Some(w) = &mut self.backend.watcher {
                    w.note_write(to);
                }
                // Added things now have nodes in the file, which their entities do not know.
                if saved.added > 0 {
                    super::systems::reimport_scene(self);
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
                self.info(message.clone());
                message
            }
            Err(e) => {
                self.error(e.clone());
                e
            }
        }
    }

    /// Writes an asset pack with the current bakes as `<stem>.pack.glb`.
    pub fn export_pack(&mut self) -> String {
        let path = self.beside_scene(".pack.glb");
        self.write(path, true)
    }

    /// Replaces `instance`'s mesh by the first mesh of the glTF file at `path` (in its own frame: the
    /// instance keeps its transform); a geometry edit, so the affected bakes re-run.
    pub fn replace_mesh_from(&mut self, instance: hecs::Entity, path: &Path) -> String {
        let imported = kage_engine::scene::import::import(path, self.options.import.clone()).map_err(|e| e.to_string());
        let mesh = imported.and_then(|s| {
            s.meshes.first().map(|m| (**m).clone()).ok_or_else(|| format!("{}: the file has no mesh", path.display()))
        });
        match mesh {
            Ok(mesh) => {
                let message = format!("replaced the mesh by {}'s ({} vertices)", path.display(), mesh.positions.len());
                self.replace_mesh(instance, mesh);
                self.info(message.clone());
                message
            }
            Err(e) => {
                self.error(format!("replace mesh: {e}"));
                e
            }
        }
    }
}
