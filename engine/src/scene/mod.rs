//! Scenes: plain-data ECS components in a [`hecs::World`], the meshes they share, and the
//! systems that read them.
//!
//! Entities:
//! - one **rigid group** per top-level glTF node ([`RigidGroup`], [`Transform`], [`Name`]);
//! - one **mesh instance** per (node, primitive) that is not emissive ([`MeshRef`],
//!   [`Material`], [`InGroup`], [`Transform`], [`PrimitiveId`]);
//! - one **polygonal light** per emissive polygon ([`PolygonLight`], [`InGroup`], [`Transform`],
//!   [`Name`]: its node's);
//! - **cameras** ([`Camera`]) and at most one **environment** ([`EnvironmentLight`]).
//!
//! [`Transform::world`] of instances and lights is derived from the group's pose by
//! [`propagate_transforms`]; moving a group means changing its `Transform` and running it.

mod build;
mod builtin;
mod components;
pub mod cutout;
pub mod environment;
mod flatten;
pub mod import;
pub mod mesh;
pub mod refine;
pub mod shapes;
pub use kage_runtime::texture;

pub use builtin::default_scene;
pub use components::*;
pub use cutout::{Cutout, Holes};
pub use environment::{EnvMap, EnvironmentLight};
pub use flatten::{FlatScene, Instance, NO_LIGHT, TriangleRef, VertexValues, flatten, group_triangles};
pub use kage_runtime::light::FlatLight;
pub use mesh::{Mesh, MeshHash};
pub use texture::Texture;

use glam::{Affine3A, Quat, Vec3};
use std::sync::Arc;

/// An imported scene: the ECS world plus the assets its components refer to.
pub struct Scene {
    /// Entities and their components.
    pub world: hecs::World,
    /// Meshes, indexed by [`MeshRef::index`].
    pub meshes: Vec<Arc<Mesh>>,
    /// Textures (emissive), indexed by [`PolygonLight::texture`].
    pub textures: Vec<Arc<Texture>>,
    /// Where the scene came from (a path, or `builtin:default`).
    pub source: String,
    /// Non-fatal findings of the importer, e.g. dropped degenerate triangles.
    pub warnings: Vec<String>,
}

impl Scene {
    /// Replaces (or sets) the scene's environment light.
    pub fn set_environment(&mut self, env: EnvironmentLight) {
        self.clear_environment();
        self.world.spawn((env,));
    }

    /// Removes the environment light, if any.
    pub fn clear_environment(&mut self) {
        let old: Vec<hecs::Entity> =
            self.world.query::<(hecs::Entity, &EnvironmentLight)>().iter().map(|(e, _)| e).collect();
        for e in old {
            let _ = self.world.despawn(e);
        }
    }

    /// Removes every polygonal light (e.g. to compare environment-only methods).
    pub fn remove_polygon_lights(&mut self) {
        let lights: Vec<hecs::Entity> =
            self.world.query::<(hecs::Entity, &PolygonLight)>().iter().map(|(e, _)| e).collect();
        for e in lights {
            let _ = self.world.despawn(e);
        }
    }

    /// Checks that every rigid group's pose is a similarity (rotation, uniform scale, optional
    /// mirror, translation), as computations in a group's local frame require.
    pub fn check_rigid_groups(&self) -> crate::Result<()> {
        for (g, t, name) in self.world.query::<(&RigidGroup, &Transform, &Name)>().iter() {
            t.rigid_parts().map_err(|why| {
                crate::Error::Invalid(format!("{}: group {} ('{}') must be rigid: {why}", self.source, g.index, name.0))
            })?;
        }
        Ok(())
    }

    /// The rigid group whose node is named `name`, or whose group index is `name` as a number.
    pub fn find_group(&self, name: &str) -> crate::Result<hecs::Entity> {
        let groups: Vec<(hecs::Entity, u32, String)> = self
            .world
            .query::<(hecs::Entity, &RigidGroup, &Name)>()
            .iter()
            .map(|(e, g, n)| (e, g.index, n.0.clone()))
            .collect();
        groups.iter().find(|(_, i, n)| n == name || name.parse::<u32>() == Ok(*i)).map(|(e, ..)| *e).ok_or_else(|| {
            let names: Vec<String> = groups.iter().map(|(_, i, n)| format!("{i} '{n}'")).collect();
            crate::Error::Invalid(format!("{}: no rigid group '{name}' (groups: {})", self.source, names.join(", ")))
        })
    }

    /// The light entities (one per polygon) of the light node named `name`, or of the light
    /// whose index in node order is `name` as a number.
    pub fn find_lights(&self, name: &str) -> crate::Result<Vec<hecs::Entity>> {
        let mut lights: Vec<(NodeId, Emitter, String, hecs::Entity)> = self
            .world
            .query::<(hecs::Entity, &PolygonLight, &NodeId, &Emitter, Option<&Name>)>()
            .iter()
            .map(|(e, _, id, emitter, n)| (*id, *emitter, n.map(|n| n.0.clone()).unwrap_or_default(), e))
            .collect();
        lights.sort_by_key(|(id, emitter, ..)| (id.0, emitter.polygon));
        let mut nodes: Vec<(NodeId, String)> = lights.iter().map(|(id, _, n, _)| (*id, n.clone())).collect();
        nodes.dedup();
        // By name every node so named (a pack writes one node per polygon), else by index.
        let chosen: Vec<NodeId> = match nodes.iter().any(|(_, n)| n == name) {
            true => nodes.iter().filter(|(_, n)| n == name).map(|(id, _)| *id).collect(),
            false => name.parse::<usize>().ok().and_then(|i| nodes.get(i)).map(|(id, _)| *id).into_iter().collect(),
        };
        if chosen.is_empty() {
            let names: Vec<String> = nodes.iter().enumerate().map(|(i, (_, n))| format!("{i} '{n}'")).collect();
            return Err(crate::Error::Invalid(format!(
                "{}: no light '{name}' (lights: {})",
                self.source,
                names.join(", ")
            )));
        }
        Ok(lights.iter().filter(|(id, ..)| chosen.contains(id)).map(|(.., e)| *e).collect())
    }

    /// Where `light` goes, in its group's frame, when it turns by `rotation` about its centre and
    /// then moves by the world-space `offset`; refused when that leaves the reach box it
    /// declared (its shadows were baked for that box only).
    pub fn light_moved(&self, light: hecs::Entity, offset: Vec3, rotation: Quat) -> Result<Affine3A, String> {
        let member = self.world.get::<&InGroup>(light).map_err(|_| "not a light".to_string())?;
        let l = self.world.get::<&PolygonLight>(light).map_err(|_| "not a light".to_string())?;
        let pose = self.world.get::<&Transform>(member.group).map(|t| t.world).unwrap_or_default();
        let centre =
            member.local.transform_point3(l.points.iter().copied().sum::<Vec3>() / l.points.len().max(1) as f32);
        let turn =
            Affine3A::from_translation(centre) * Affine3A::from_quat(rotation) * Affine3A::from_translation(-centre);
        let local = Affine3A::from_translation(pose.inverse().transform_vector3(offset)) * turn * member.local;
        l.within_reach(pose * local, &l.points).map(|()| local)
    }

    /// Places `light` at `local` in its group's frame (see [`Self::light_moved`]).
    pub fn place_light(&mut self, light: hecs::Entity, local: Affine3A) {
        if let Ok(mut member) = self.world.get::<&mut InGroup>(light) {
            member.local = local;
        }
        propagate_transforms(&mut self.world);
    }

    /// The instances and lights of rigid group `group`, in entity order.
    pub fn members(&self, group: hecs::Entity) -> Vec<hecs::Entity> {
        let mut m: Vec<hecs::Entity> = self
            .world
            .query::<(hecs::Entity, &InGroup)>()
            .iter()
            .filter(|(_, g)| g.group == group)
            .map(|(e, _)| e)
            .collect();
        m.sort();
        m
    }

    /// Rotates `group` by `rotation` about its own origin, then moves it by `offset`, and
    /// re-derives its members' transforms (a run-time pose change: no bake depends on it but
    /// BSPVT visibility, which the caller re-bakes).
    pub fn pose_group(&mut self, group: hecs::Entity, rotation: glam::Quat, offset: glam::Vec3) {
        if let Ok(mut t) = self.world.get::<&mut Transform>(group) {
            let linear = glam::Affine3A { matrix3: t.world.matrix3, translation: glam::Vec3A::ZERO };
            let origin = glam::Vec3::from(t.world.translation) + offset;
            t.world = glam::Affine3A::from_rotation_translation(rotation, origin) * linear;
        }
        propagate_transforms(&mut self.world);
    }

    /// The name of `entity` (its glTF node's), if it has one.
    pub fn name_of(&self, entity: hecs::Entity) -> Option<String> {
        self.world.get::<&Name>(entity).ok().map(|n| n.0.clone())
    }

    /// Refines the mesh of every instance named `name` (its own node's name, or its rigid
    /// group's) to `target` vertices with [`refine::refine`]; returns how many instances changed.
    pub fn refine_instances(&mut self, name: &str, target: usize) -> crate::Result<usize> {
        let named = |e: hecs::Entity| self.world.get::<&Name>(e).map(|n| n.0 == name).unwrap_or(false);
        let matching: Vec<(hecs::Entity, u32)> = self
            .world
            .query::<(hecs::Entity, &MeshRef, &InGroup)>()
            .iter()
            .filter(|(e, _, g)| named(*e) || named(g.group))
            .map(|(e, r, _)| (e, r.index))
            .collect();
        if matching.is_empty() {
            return Err(crate::Error::Invalid(format!(
                "{}: no mesh instance or group named '{name}' to refine",
                self.source
            )));
        }
        let mut indices: Vec<u32> = matching.iter().map(|(_, i)| *i).collect();
        indices.sort_unstable();
        indices.dedup();
        let mut refined = std::collections::HashMap::new();
        for index in indices {
            let mesh = refine::refine(&self.meshes[index as usize], target).map_err(|why| {
                crate::Error::Invalid(format!("{}: refining '{name}' to {target} vertices: {why}", self.source))
            })?;
            // A mesh no other instance shares is replaced in place (no orphan left behind).
            let users = self.world.query::<&MeshRef>().iter().filter(|r| r.index == index).count();
            let shared = users > matching.iter().filter(|(_, i)| *i == index).count();
            let slot = if shared { self.meshes.len() as u32 } else { index };
            refined.insert(index, MeshRef { index: slot, hash: mesh.hash });
            if shared {
                self.meshes.push(Arc::new(mesh));
            } else {
                self.meshes[index as usize] = Arc::new(mesh);
            }
        }
        for (entity, index) in &matching {
            *self.world.get::<&mut MeshRef>(*entity).expect("queried above") = refined[index];
        }
        Ok(matching.len())
    }

    /// The first camera, if the scene has one.
    pub fn first_camera(&self) -> Option<Camera> {
        let mut cams: Vec<(u32, Camera)> =
            self.world.query::<(&Camera, &NodeId)>().iter().map(|(c, n)| (n.0, c.clone())).collect();
        cams.sort_by_key(|(n, _)| *n);
        cams.into_iter().next().map(|(_, c)| c)
    }
}

/// System: recomputes every instance's and light's world transform from its group's pose.
pub fn propagate_transforms(world: &mut hecs::World) {
    let poses: std::collections::HashMap<hecs::Entity, glam::Affine3A> =
        world.query::<(hecs::Entity, &RigidGroup, &Transform)>().iter().map(|(e, _, t)| (e, t.world)).collect();
    for (member, t) in world.query_mut::<(&InGroup, &mut Transform)>() {
        if let Some(pose) = poses.get(&member.group) {
            t.world = *pose * member.local;
        }
    }
}
