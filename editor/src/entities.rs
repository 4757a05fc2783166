//! Adding, duplicating and deleting: quad and disc lights, copies of groups and lights, deleted
//! groups and lights, and the meshes of a dropped glTF file as a new group. Each is one undo
//! step ([`Stored::Presence`]: the entities with all their components) and a geometry change,
//! so the bakes it needs run incrementally in the background.

use super::history::Snapshot;
use super::state::{Editor, Selection};
use glam::{Affine3A, Vec3};
use kage_engine::scene::{Emitter, InGroup, MeshRef, NodeId, PolygonLight, PrimitiveId, RigidGroup, Transform};
use std::collections::HashMap;
use std::path::Path;

/// The outline of a new light.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shape {
    /// A 1 m square.
    Quad,
    /// A disc 1 m across (a 24-gon).
    Disc,
}

/// Radiance of a new light.
const NEW_RADIANCE: Vec3 = Vec3::splat(10.0);
/// How far a copy is placed from its original (world +X, metres).
const COPY_OFFSET: Vec3 = Vec3::new(1.0, 0.0, 0.0);

impl Shape {
    /// The outline in the light's frame, facing down (−Y), counter-clockwise about its normal.
    fn points(self) -> Vec<Vec3> {
        let sides = match self {
            Shape::Quad => 4,
            Shape::Disc => 24,
        };
        let radius = match self {
            Shape::Quad => std::f32::consts::FRAC_1_SQRT_2,
            Shape::Disc => 0.5,
        };
        // Angles growing from +X toward +Z turn counter-clockwise about −Y.
        (0..sides)
            .map(|k| {
                let a = std::f32::consts::FRAC_PI_4 + k as f32 / sides as f32 * std::f32::consts::TAU;
                Vec3::new(a.cos(), 0.0, a.sin()) * radius
            })
            .collect()
    }
}

impl Editor {
    /// Adds a light of `shape` as a new group 2 m above the point the view orbits; returns the
    /// new light, selected.
    pub fn add_light(&mut self, shape: Shape) -> hecs::Entity {
        let name = format!("{} light", if shape == Shape::Quad { "quad" } else { "disc" });
        let pose = Affine3A::from_translation(self.view.orbit.target + Vec3::Y * 2.0);
        let group = self.doc.scene.add_light(&name, shape.points(), NEW_RADIANCE, pose);
        let light = self.doc.scene.members(group)[0];
        self.added(vec![group, light]);
        self.doc.selection = Selection::Light(light);
        self.info(format!("added a {name}"));
        light
    }

    /// Copies a group (all its members) or a light (as a group of its own), 1 m along +X;
    /// returns the copy, selected.
    pub fn duplicate(&mut self, sel: Selection) -> Option<Selection> {
        let (source_group, members, copy) = match sel {
            Selection::Group(g) => (g, self.doc.scene.members(g), None),
            Selection::Light(e) => (self.doc.scene.world.get::<&InGroup>(e).ok()?.group, vec![e], Some(e)),
            _ => return None,
        };
        let pose = self.doc.scene.world.get::<&Transform>(source_group).ok()?.world;
        let name = self.doc.scene.world.get::<&kage_engine::scene::Name>(source_group).map(|n| n.0.clone()).ok()?;
        let world = Affine3A::from_translation(COPY_OFFSET) * pose;
        let index = self.doc.scene.next_group_index();
        let mut next = self.doc.scene.next_node();
        let group = self.doc.scene.world.spawn((
            RigidGroup { index },
            Transform { world },
            kage_engine::scene::Name(format!("{name} copy")),
            NodeId(next),
        ));
        next += 1;
        // Each source node gets one new node, shared by the primitives it held.
        let mut nodes: HashMap<u32, u32> = HashMap::new();
        let mut spawned = vec![group];
        for m in members {
            let snapshot = self.doc.scene.components(m)?;
            let e = self.doc.scene.world.spawn(&snapshot);
            let w = &self.doc.scene.world;
            let mut renumber = |old: u32| {
                *nodes.entry(old).or_insert_with(|| {
                    next += 1;
                    next - 1
                })
            };
            if let Ok(mut member) = w.get::<&mut InGroup>(e) {
                member.group = group;
            }
            if let Ok(mut id) = w.get::<&mut PrimitiveId>(e) {
                id.node = renumber(id.node);
            }
            if let Ok(mut emitter) = w.get::<&mut Emitter>(e) {
                emitter.id.node = renumber(emitter.id.node);
            }
            if let Ok(mut node) = w.get::<&mut NodeId>(e) {
                node.0 = renumber(node.0);
            }
            spawned.push(e);
        }
        kage_engine::scene::propagate_transforms(&mut self.doc.scene.world);
        let light = copy.and(spawned.get(1).copied());
        self.added(spawned);
        self.doc.selection = light.map_or(Selection::Group(group), Selection::Light);
        self.info(format!("duplicated '{name}'"));
        Some(self.doc.selection)
    }

    /// Deletes a group with its members, or a light (with its group when it was the last member).
    pub fn delete(&mut self, sel: Selection) {
        let mut doomed = match sel {
            Selection::Group(g) => [vec![g], self.doc.scene.members(g)].concat(),
            Selection::Light(e) => vec![e],
            _ => return,
        };
        if let Selection::Light(e) = sel
            && let Ok(group) = self.doc.scene.world.get::<&InGroup>(e).map(|m| m.group)
            && self.doc.scene.members(group).len() == 1
        {
            doomed.push(group);
        }
        let before: Vec<(hecs::Entity, Option<Snapshot>)> =
            doomed.iter().map(|e| (*e, self.doc.scene.components(*e).map(Snapshot::new))).collect();
        doomed.iter().for_each(|e| {
            let _ = self.doc.scene.world.despawn(*e);
        });
        self.record(before);
        self.doc.selection = Selection::None;
        self.info(format!("deleted {} entities", doomed.len()));
    }

    /// Adds the meshes and lights of the glTF file at `path` as one new group standing on the
    /// point the view orbits, in the file's own units (a file dropped on the viewport); returns
    /// the group.
    pub fn add_file(&mut self, path: &Path) -> Result<hecs::Entity, String> {
        let dropped = kage_engine::scene::import::import(path, self.options.import.clone())
            .map_err(|e| format!("add {}: {e}", path.display()))?;
        let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        // Standing on the point the view orbits: centred across, its lowest point there.
        let [lo, hi] = kage_engine::scene::flatten(&dropped)
            .triangles
            .iter()
            .flatten()
            .fold([Vec3::MAX, Vec3::MIN], |[lo, hi], p| [lo.min(*p), hi.max(*p)]);
        let foot = if lo.x <= hi.x { Vec3::new(0.5 * (lo.x + hi.x), lo.y, 0.5 * (lo.z + hi.z)) } else { Vec3::ZERO };
        let pose = Affine3A::from_translation(self.view.orbit.target - foot);
        let (meshes, textures) = (self.doc.scene.meshes.len() as u32, self.doc.scene.textures.len() as u32);
        self.doc.scene.meshes.extend(dropped.meshes.iter().cloned());
        self.doc.scene.textures.extend(dropped.textures.iter().cloned());
        let index = self.doc.scene.next_group_index();
        let mut next = self.doc.scene.next_node();
        let group = self.doc.scene.world.spawn((
            RigidGroup { index },
            Transform { world: pose },
            kage_engine::scene::Name(stem.clone()),
            NodeId(next),
        ));
        let mut spawned = vec![group];
        // Every member keeps where the file placed it, relative to the new group.
        for (e, t) in dropped.world.query::<(hecs::Entity, &Transform)>().iter() {
            if dropped.world.get::<&InGroup>(e).is_err() {
                continue;
            }
            next += 1;
            let snapshot = dropped.components(e).expect("queried just now");
            let copy = self.doc.scene.world.spawn(&snapshot);
            let w = &self.doc.scene.world;
            *w.get::<&mut InGroup>(copy).expect("members have one") = InGroup { group, local: t.world };
            if let Ok(mut r) = w.get::<&mut MeshRef>(copy) {
                r.index += meshes;
            }
            if let Ok(mut id) = w.get::<&mut PrimitiveId>(copy) {
                *id = PrimitiveId { node: next, mesh: id.mesh, primitive: id.primitive };
            }
            if let Ok(mut light) = w.get::<&mut PolygonLight>(copy) {
                light.texture = light.texture.map(|t| t + textures);
            }
            if let Ok(mut maps) = w.get::<&mut kage_engine::scene::MaterialMaps>(copy) {
                let maps = &mut *maps;
                for slot in [&mut maps.base_color, &mut maps.metallic_roughness].into_iter().flatten() {
                    slot.texture += textures;
                }
            }
            let _ = self.doc.scene.world.remove_one::<Emitter>(copy);
            if self.doc.scene.world.get::<&NodeId>(copy).is_ok() {
                self.doc.scene.world.insert_one(copy, NodeId(next)).expect("spawned just now");
            }
            spawned.push(copy);
        }
        kage_engine::scene::propagate_transforms(&mut self.doc.scene.world);
        let count = spawned.len() - 1;
        self.added(spawned);
        self.doc.selection = Selection::Group(group);
        self.info(format!("added {} ({count} meshes and lights) as group '{stem}'", path.display()));
        Ok(group)
    }

    /// Records that `entities` did not exist before (one undo step) and marks the change.
    fn added(&mut self, entities: Vec<hecs::Entity>) {
        self.record(entities.into_iter().map(|e| (e, None)).collect());
    }

    fn record(&mut self, before: Vec<(hecs::Entity, Option<Snapshot>)>) {
        let change = self.doc.record_presence(before);
        self.apply(change);
    }
}

#[cfg(test)]
mod tests {
    use super::Shape;
    use kage_engine::scene::import::polygon_normal_area;

    #[test]
    fn new_lights_face_down_with_the_area_they_promise() {
        for (shape, area) in [(Shape::Quad, 1.0), (Shape::Disc, 0.25 * std::f32::consts::PI)] {
            let (n, a) = polygon_normal_area(&shape.points());
            assert!(n.y < -0.999, "{shape:?} emits downward: {n}");
            assert!((a - area).abs() < 0.02 * area, "{shape:?}: {a}");
        }
    }
}
