//! The document: the scene being edited with its selection, its undo history and what its file
//! holds — everything an edit changes, and nothing of how it is shown or baked (no GPU, no
//! store, no workers). Each edit returns the [`Change`] the editor must follow up (a snapshot,
//! a re-bake, a re-projection of the environment); [`crate::state::Editor`] applies it.

use crate::history::{History, Snapshot, Stored, Target};
use crate::source::Baseline;
use crate::state::Selection;
use glam::{Affine3A, Quat, Vec3};
use kage_engine::scene::{EnvironmentLight, InGroup, Material, PolygonLight, Scene, Transform};
use std::sync::Arc;

/// What an edit changed beyond the world's values, for the editor to follow up.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Change {
    /// Something changed: the snapshot and the shading follow.
    pub pose: bool,
    /// Occluder geometry changed: the viewport's meshes and the bakes follow.
    pub geometry: bool,
    /// The environment changed: PRT's lighting is projected again.
    pub environment: bool,
}

impl Change {
    /// Nothing changed (the edit was a no-op, or what it named is gone).
    pub const NONE: Change = Change { pose: false, geometry: false, environment: false };
    /// Values that shading reads (a light, a material).
    pub const POSE: Change = Change { pose: true, geometry: false, environment: false };
    /// Geometry (a group moved or scaled, a mesh replaced, entities added or deleted).
    pub const GEOMETRY: Change = Change { pose: true, geometry: true, environment: false };
    /// The environment's intensity or rotation.
    pub const ENVIRONMENT: Change = Change { pose: true, geometry: false, environment: true };
}

/// The scene being edited, its selection, history and saved baseline.
pub struct Document {
    /// The scene being edited.
    pub scene: Scene,
    /// The outliner's selection (the viewport's too: a click picks).
    pub selection: Selection,
    /// Undo and redo.
    pub history: History,
    /// The values the scene file holds (as opened or last saved): what a save writes against
    /// (set with [`Document::mark_saved`]).
    baseline: Baseline,
    /// Bumped by every edit and save; [`Document::unsaved`] compares only when it moved.
    revision: u64,
    /// [`Document::unsaved`]'s last answer and the revision it was for.
    unsaved_memo: std::cell::Cell<Option<(u64, bool)>>,
}

impl Document {
    /// `scene` as its file holds it: nothing selected, no history, nothing unsaved.
    pub fn new(scene: Scene) -> Self {
        let baseline = Baseline::of(&scene);
        Self {
            scene,
            selection: Selection::None,
            history: History::default(),
            baseline,
            revision: 0,
            unsaved_memo: Default::default(),
        }
    }

    /// Records that entities existed as `before` says (`None`: not at all) before an addition or
    /// a deletion: one undo step of its own, a geometry change.
    pub(crate) fn record_presence(&mut self, before: Vec<(hecs::Entity, Option<Snapshot>)>) -> Change {
        self.history.seal();
        self.history.record(Stored::Presence(before));
        self.history.seal();
        self.edited(Change::GEOMETRY)
    }

    /// Counts an edit that made `change` (none for [`Change::NONE`]); returns it.
    pub(crate) fn edited(&mut self, change: Change) -> Change {
        if change != Change::NONE {
            self.revision += 1;
        }
        change
    }

    /// True when the scene differs from what its file holds (edits not saved).
    pub fn unsaved(&self) -> bool {
        if let Some((revision, unsaved)) = self.unsaved_memo.get()
            && revision == self.revision
        {
            return unsaved;
        }
        let unsaved = crate::source::Baseline::of(&self.scene) != self.baseline;
        self.unsaved_memo.set(Some((self.revision, unsaved)));
        unsaved
    }

    /// The scene as it is now is what its file holds (just opened again, or saved).
    pub fn mark_saved(&mut self) {
        self.baseline = crate::source::Baseline::of(&self.scene);
        self.revision += 1;
    }

    /// What a save of the scene writes against.
    pub fn baseline(&self) -> &crate::source::Baseline {
        &self.baseline
    }

    /// Records the current values of `target` before an edit changes them.
    pub(crate) fn remember(&mut self, target: Target) {
        if let Some(now) = self.stored(target) {
            self.history.record(now);
        }
    }

    /// Undoes the newest step; `None` when there is none.
    pub fn undo(&mut self) -> Option<Change> {
        let before = self.history.pop_undo()?;
        let (now, change) = self.swap_in(before);
        if let Some(now) = now {
            self.history.push_redo(now);
        }
        Some(change)
    }

    /// Redoes the newest undone step; `None` when there is none.
    pub fn redo(&mut self) -> Option<Change> {
        let after = self.history.pop_redo()?;
        let (now, change) = self.swap_in(after);
        if let Some(now) = now {
            self.history.push_undo(now);
        }
        Some(change)
    }

    /// The current values of `target` (`None` when it no longer exists).
    pub(crate) fn stored(&self, target: Target) -> Option<Stored> {
        let w = &self.scene.world;
        Some(match target {
            Target::Group(e) => Stored::Group(e, w.get::<&Transform>(e).ok()?.world),
            Target::Light(e) => {
                Stored::Light(e, w.get::<&InGroup>(e).ok()?.local, (*w.get::<&PolygonLight>(e).ok()?).clone())
            }
            Target::Material(e) => Stored::Material(e, *w.get::<&Material>(e).ok()?),
            // The source: a refinement is redone from it by the bake that follows.
            Target::Mesh(e) => Stored::Mesh(e, self.scene.source_mesh(e)?),
            Target::Environment => {
                let env = w.query::<&EnvironmentLight>().iter().next().map(|e| (e.intensity, e.rotation))?;
                Stored::Environment(env.0, env.1)
            }
            // A set of entities is read by `presence`, from its list.
            Target::Presence(_) => return None,
        })
    }

    /// Whether the entities of `list` exist now, with their components.
    fn presence(&self, list: &[(hecs::Entity, Option<Snapshot>)]) -> Stored {
        Stored::Presence(list.iter().map(|(e, _)| (*e, self.scene.components(*e).map(Snapshot::new))).collect())
    }

    /// Writes `values` into the world and returns the values they replaced (`None`: what they
    /// belong to no longer exists) and what must be redone, as the original edit did.
    fn swap_in(&mut self, values: Stored) -> (Option<Stored>, Change) {
        let now = match &values {
            Stored::Presence(list) => self.presence(list),
            other => match self.stored(other.target()) {
                Some(now) => now,
                None => return (None, Change::NONE),
            },
        };
        let change = self.write(values);
        (change.is_some().then_some(now), self.edited(change.unwrap_or(Change::NONE)))
    }

    /// Writes `values` into the world; what must be redone (`None` when an entity is gone).
    fn write(&mut self, values: Stored) -> Option<Change> {
        let w = &mut self.scene.world;
        match values {
            Stored::Presence(list) => {
                for (e, components) in list {
                    match components {
                        Some(c) => w.spawn_at(e, &*c.0),
                        None => {
                            let _ = w.despawn(e);
                        }
                    }
                }
                kage_engine::scene::propagate_transforms(w);
                self.selection = Selection::None;
                Some(Change::GEOMETRY)
            }
            Stored::Group(e, pose) => {
                w.get::<&mut Transform>(e).ok()?.world = pose;
                kage_engine::scene::propagate_transforms(w);
                Some(Change::GEOMETRY)
            }
            Stored::Light(e, local, light) => {
                w.get::<&mut InGroup>(e).ok()?.local = local;
                *w.get::<&mut PolygonLight>(e).ok()? = light;
                Some(Change::POSE)
            }
            Stored::Material(e, m) => {
                *w.get::<&mut Material>(e).ok()? = m;
                Some(Change::POSE)
            }
            Stored::Mesh(e, m) => {
                self.scene.set_source_mesh(e, m);
                Some(Change::GEOMETRY)
            }
            Stored::Environment(intensity, rotation) => {
                for env in w.query_mut::<&mut EnvironmentLight>() {
                    (env.intensity, env.rotation) = (intensity, rotation);
                }
                Some(Change::ENVIRONMENT)
            }
        }
    }

    /// Moves a polygonal light by `offset` (world units) and turns it by `rotation` about its
    /// centre: re-shaded at once, nothing re-baked (lights do not occlude). Refused, with the
    /// error to log, when it would leave its declared reach (the bake covers only that).
    pub fn move_light(&mut self, light: hecs::Entity, offset: Vec3, rotation: Quat) -> Result<Change, String> {
        if self.scene.world.get::<&PolygonLight>(light).is_err() {
            return Ok(Change::NONE);
        }
        let local = self.scene.light_moved(light, offset, rotation).map_err(|e| format!("{e}: refused"))?;
        self.remember(Target::Light(light));
        self.scene.place_light(light, local);
        Ok(self.edited(Change::POSE))
    }

    /// Scales a light's polygon about its centre by `factor` and sets its radiance (the size
    /// change refused, as in [`Self::move_light`], when it would leave the light's reach: the
    /// refusal comes with the change).
    pub fn set_light(&mut self, light: hecs::Entity, radiance: Vec3, factor: f32) -> (Change, Option<String>) {
        let world =
            self.group_pose_of(light) * self.scene.world.get::<&InGroup>(light).map_or(Affine3A::IDENTITY, |m| m.local);
        let Some(mut points) = self.scene.world.get::<&PolygonLight>(light).ok().map(|l| l.points.clone()) else {
            return (Change::NONE, None);
        };
        let c = points.iter().copied().sum::<Vec3>() / points.len().max(1) as f32;
        points.iter_mut().for_each(|p| *p = c + (*p - c) * factor);
        // A resize out of reach is refused; the radiance still changes (the error is logged).
        let refused = match self.scene.world.get::<&PolygonLight>(light) {
            Ok(l) if factor != 1.0 => l.within_reach(world, &points).map_err(|e| format!("{e}: refused")),
            _ => Ok(()),
        };
        let resize = refused.is_ok();
        self.remember(Target::Light(light));
        if let Ok(mut l) = self.scene.world.get::<&mut PolygonLight>(light) {
            if resize {
                l.points = points;
            }
            l.radiance = radiance;
        }
        (self.edited(Change::POSE), refused.err())
    }

    /// Moves and turns a rigid group about its origin: PRT shading and the shadows between
    /// groups update at once; BSPVT visibility is re-baked incrementally in the background.
    pub fn move_group(&mut self, group: hecs::Entity, offset: Vec3, rotation: Quat) -> Change {
        self.remember(Target::Group(group));
        self.scene.pose_group(group, rotation, offset);
        self.edited(Change::GEOMETRY)
    }

    /// Scales a rigid group uniformly about its origin by `factor` (a geometry edit, like a
    /// move: BSPVT and PRT re-bake what it changes in the background).
    pub fn scale_group(&mut self, group: hecs::Entity, factor: f32) -> Change {
        if !(factor.is_finite() && factor > 0.0) {
            return Change::NONE;
        }
        self.remember(Target::Group(group));
        if let Ok(mut t) = self.scene.world.get::<&mut Transform>(group) {
            t.world.matrix3 *= factor;
        }
        self.scene.update_transforms();
        self.edited(Change::GEOMETRY)
    }

    /// Sets an instance's material (no re-bake: bakes exclude albedo).
    pub fn set_material(&mut self, instance: hecs::Entity, m: Material) -> Change {
        self.remember(Target::Material(instance));
        if let Ok(mut mat) = self.scene.world.get::<&mut Material>(instance) {
            *mat = m;
        }
        self.edited(Change::POSE)
    }

    /// Sets the environment's intensity and rotation (radians about +Y).
    pub fn set_environment(&mut self, intensity: f32, rotation: f32) -> Change {
        self.remember(Target::Environment);
        for env in self.scene.world.query_mut::<&mut EnvironmentLight>() {
            env.intensity = intensity;
            env.rotation = rotation;
        }
        self.edited(Change::ENVIRONMENT)
    }

    /// Replaces an instance's mesh (a geometry edit: BSPVT and PRT re-bake what it affects).
    pub fn replace_mesh(&mut self, instance: hecs::Entity, mesh: kage_engine::scene::Mesh) -> Change {
        self.remember(Target::Mesh(instance));
        let index = self.scene.meshes.len() as u32;
        let hash = mesh.hash;
        self.scene.meshes.push(Arc::new(mesh));
        self.scene.set_source_mesh(instance, kage_engine::scene::MeshRef { index, hash });
        self.edited(Change::GEOMETRY)
    }

    /// The pose of the group `member` belongs to.
    fn group_pose_of(&self, member: hecs::Entity) -> Affine3A {
        let group = self.scene.world.get::<&InGroup>(member).map(|g| g.group).ok();
        group.and_then(|g| self.scene.world.get::<&Transform>(g).ok().map(|t| t.world)).unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kage_engine::scene::default_scene;

    fn pose(doc: &Document, group: hecs::Entity) -> Affine3A {
        doc.scene.world.get::<&Transform>(group).unwrap().world
    }

    /// Undo, redo and "unsaved" on a document alone: no GPU, no store, no window.
    #[test]
    fn undo_redo_and_unsaved_need_no_gpu() {
        let mut doc = Document::new(default_scene());
        let group = doc.scene.find_group("box").expect("the built-in scene has a box");
        let at_first = pose(&doc, group);
        assert!(!doc.unsaved() && doc.undo().is_none() && doc.redo().is_none());

        assert_eq!(doc.move_group(group, Vec3::new(0.3, 0.0, 0.0), Quat::IDENTITY), Change::GEOMETRY);
        assert!(doc.unsaved());
        assert_eq!(doc.undo(), Some(Change::GEOMETRY));
        assert_eq!(pose(&doc, group), at_first, "undo writes the stored pose back bit for bit");
        assert!(!doc.unsaved(), "back to what the file holds");
        assert_eq!(doc.redo(), Some(Change::GEOMETRY));
        assert!(doc.unsaved());

        doc.mark_saved();
        assert!(!doc.unsaved());
        assert_eq!(doc.undo(), Some(Change::GEOMETRY));
        assert!(doc.unsaved(), "undoing past a save differs from the file");
        assert_eq!(doc.redo(), Some(Change::GEOMETRY));
        assert!(!doc.unsaved());

        let (intensity, rotation) = {
            let env = doc.scene.world.query::<&EnvironmentLight>().iter().next().map(|e| (e.intensity, e.rotation));
            env.expect("the built-in scene has an environment")
        };
        assert_eq!(doc.set_environment(intensity * 2.0, rotation + 1.0), Change::ENVIRONMENT);
        assert_eq!(doc.undo(), Some(Change::ENVIRONMENT));
        assert!(!doc.unsaved());
        assert_eq!(doc.undo(), Some(Change::GEOMETRY), "the move, one step before the environment");
        assert_eq!(doc.undo(), None);
        assert_eq!(doc.scale_group(group, f32::NAN), Change::NONE, "a refused edit records nothing");
        assert_eq!(doc.history.undo_len(), 0);
    }
}
