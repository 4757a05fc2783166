//! Undo and redo. Every edit records the stored values it is about to change; undoing writes
//! them back bit for bit — never an inverse transform, which would drift — and keeps the values
//! it replaced for redo. Because a bake's key is a hash of those values, undoing a move leads
//! back to bakes the database already holds.
//!
//! A *gesture* (one drag of a gizmo or a field) is one step: consecutive edits of the same thing
//! merge until [`History::seal`] ends the gesture (the UI seals whenever no pointer button is
//! down).

use glam::Affine3A;
use kage_engine::scene::{Material, MeshRef, PolygonLight};

/// The stored values of one editable thing.
#[derive(Clone, Debug, PartialEq)]
pub enum Stored {
    /// A rigid group's pose (its world transform).
    Group(hecs::Entity, Affine3A),
    /// A light's placement in its group, and its polygon and radiance.
    Light(hecs::Entity, Affine3A, PolygonLight),
    /// An instance's material factors.
    Material(hecs::Entity, Material),
    /// Which mesh an instance shows.
    Mesh(hecs::Entity, MeshRef),
    /// The environment's intensity and rotation (radians about +Y).
    Environment(f32, f32),
    /// Whether entities exist, with all their components (adding, duplicating, deleting).
    Presence(Vec<(hecs::Entity, Option<Snapshot>)>),
}

/// Every component of one entity, to spawn it again exactly as it was.
#[derive(Clone)]
pub struct Snapshot(pub(crate) std::sync::Arc<hecs::BuiltEntityClone>);

impl Snapshot {
    /// Keeps `components`.
    pub fn new(components: hecs::BuiltEntityClone) -> Self {
        Self(std::sync::Arc::new(components))
    }
}

impl PartialEq for Snapshot {
    /// The same snapshot (components are not comparable as a whole).
    fn eq(&self, other: &Self) -> bool {
        std::sync::Arc::ptr_eq(&self.0, &other.0)
    }
}

impl std::fmt::Debug for Snapshot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Snapshot")
    }
}

/// What a [`Stored`] value belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Target {
    /// A group's pose.
    Group(hecs::Entity),
    /// A light.
    Light(hecs::Entity),
    /// An instance's material.
    Material(hecs::Entity),
    /// An instance's mesh.
    Mesh(hecs::Entity),
    /// The environment.
    Environment,
    /// A set of entities added or deleted together (named by the first).
    Presence(hecs::Entity),
}

impl Stored {
    /// What these values belong to.
    pub fn target(&self) -> Target {
        match self {
            Self::Group(e, _) => Target::Group(*e),
            Self::Light(e, ..) => Target::Light(*e),
            Self::Material(e, _) => Target::Material(*e),
            Self::Mesh(e, _) => Target::Mesh(*e),
            Self::Environment(..) => Target::Environment,
            Self::Presence(list) => Target::Presence(list.first().map_or(hecs::Entity::DANGLING, |p| p.0)),
        }
    }
}

/// The undo and redo stacks.
#[derive(Debug, Default)]
pub struct History {
    undo: Vec<Stored>,
    redo: Vec<Stored>,
    /// The target of the gesture in progress, whose first values are already recorded.
    open: Option<Target>,
}

impl History {
    /// Records `before`, the values an edit is about to replace (merged into the open gesture
    /// when it edits the same thing); a new edit clears the redo stack.
    pub fn record(&mut self, before: Stored) {
        let target = before.target();
        if self.open != Some(target) {
            self.undo.push(before);
            self.open = Some(target);
        }
        self.redo.clear();
    }

    /// Ends the gesture in progress: the next edit is a new step.
    pub fn seal(&mut self) {
        self.open = None;
    }

    /// Takes the newest step to undo.
    pub fn pop_undo(&mut self) -> Option<Stored> {
        self.seal();
        self.undo.pop()
    }

    /// Takes the newest step to redo.
    pub fn pop_redo(&mut self) -> Option<Stored> {
        self.seal();
        self.redo.pop()
    }

    /// Keeps `now`, the values an undo replaced, for redo.
    pub fn push_redo(&mut self, now: Stored) {
        self.redo.push(now);
    }

    /// Keeps `now`, the values a redo replaced, for undo (the redo stack stays).
    pub fn push_undo(&mut self, now: Stored) {
        self.undo.push(now);
    }

    /// Steps that can be undone.
    pub fn undo_len(&self) -> usize {
        self.undo.len()
    }

    /// Steps that can be redone.
    pub fn redo_len(&self) -> usize {
        self.redo.len()
    }

    /// Forgets everything (the scene was replaced, e.g. re-imported: its entities are new).
    pub fn clear(&mut self) {
        *self = Self::default();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn pose(x: f32) -> Affine3A {
        Affine3A::from_translation(Vec3::new(x, 0.0, 0.0))
    }

    #[test]
    fn a_gesture_is_one_step_and_a_new_edit_clears_redo() {
        let mut world = hecs::World::new();
        let (a, b) = (world.spawn(()), world.spawn(()));
        let mut h = History::default();
        h.record(Stored::Group(a, pose(0.0)));
        h.record(Stored::Group(a, pose(1.0)));
        h.record(Stored::Group(a, pose(2.0)));
        assert_eq!(h.undo_len(), 1, "one drag, one step");
        h.record(Stored::Group(b, pose(5.0)));
        assert_eq!(h.undo_len(), 2, "another thing, another step");
        h.seal();
        h.record(Stored::Group(b, pose(6.0)));
        assert_eq!(h.undo_len(), 3, "after a seal, the same thing is a new step");
        let undone = h.pop_undo().unwrap();
        assert_eq!(undone, Stored::Group(b, pose(6.0)));
        h.push_redo(Stored::Group(b, pose(7.0)));
        assert_eq!(h.redo_len(), 1);
        h.record(Stored::Environment(1.0, 0.0));
        assert_eq!(h.redo_len(), 0, "a new edit forgets what was undone");
        assert_eq!(h.pop_undo(), Some(Stored::Environment(1.0, 0.0)));
        assert_eq!(h.pop_undo(), Some(Stored::Group(b, pose(5.0))));
        assert_eq!(h.pop_undo(), Some(Stored::Group(a, pose(0.0))), "the gesture's first values");
        assert_eq!(h.pop_undo(), None);
    }
}
