//! Building scenes in code (the built-in scene, tests, tools): each object or light is its own
//! rigid group, as a top-level glTF node would be.

use crate::scene::{
    Camera, Emitter, EnvironmentLight, InGroup, Material, MaterialMaps, Mesh, MeshRef, Name, NodeId, PolygonLight,
    PrimitiveId, RigidGroup, Scene, SourceMesh, Transform, propagate_transforms,
};
use glam::{Affine3A, Vec3};
use std::sync::Arc;

impl Scene {
    /// An empty scene named `source`.
    pub fn new(source: &str) -> Self {
        Self {
            world: hecs::World::new(),
            meshes: Vec::new(),
            textures: Vec::new(),
            source: source.into(),
            warnings: Vec::new(),
        }
    }

    /// A node number no entity uses yet (nodes of lights and groups, and of mesh instances).
    pub fn next_node(&self) -> u32 {
        let nodes = self.world.query::<&NodeId>().iter().map(|n| n.0 + 1).max().unwrap_or(0);
        let instances = self.world.query::<&PrimitiveId>().iter().map(|p| p.node + 1).max().unwrap_or(0);
        nodes.max(instances)
    }

    /// A group index no group uses yet (after the last: groups keep their order).
    pub fn next_group_index(&self) -> u32 {
        self.world.query::<&RigidGroup>().iter().map(|g| g.index + 1).max().unwrap_or(0)
    }

    fn add_group(&mut self, name: &str, pose: Affine3A) -> (hecs::Entity, u32) {
        let node = self.next_node();
        let index = self.next_group_index();
        let group =
            self.world.spawn((RigidGroup { index }, Transform { world: pose }, Name(name.into()), NodeId(node)));
        (group, node)
    }

    /// Adds `mesh` as a new rigid group at `pose`; returns the group entity.
    pub fn add_object(&mut self, name: &str, mesh: Mesh, material: Material, pose: Affine3A) -> hecs::Entity {
        let (group, node) = self.add_group(name, pose);
        let mref = MeshRef { index: self.meshes.len() as u32, hash: mesh.hash };
        self.meshes.push(Arc::new(mesh));
        let id = PrimitiveId { node, mesh: mref.index, primitive: 0 };
        let member = InGroup { group, local: Affine3A::IDENTITY };
        self.world.spawn((mref, material, member, Transform { world: pose }, id, Name(name.into())));
        group
    }

    /// Adds `mesh` to an existing `group` at group-from-local transform `local`.
    pub fn add_member(&mut self, group: hecs::Entity, name: &str, mesh: Mesh, material: Material, local: Affine3A) {
        let node = self.next_node();
        let pose = self.world.get::<&Transform>(group).map_or(Affine3A::IDENTITY, |t| t.world);
        let mref = MeshRef { index: self.meshes.len() as u32, hash: mesh.hash };
        self.meshes.push(Arc::new(mesh));
        let id = PrimitiveId { node, mesh: mref.index, primitive: 0 };
        self.world.spawn((
            mref,
            material,
            InGroup { group, local },
            Transform { world: pose * local },
            id,
            Name(name.into()),
        ));
    }

    /// Adds a one-sided polygonal light (CCW about its emitting side) as a new rigid group.
    pub fn add_light(&mut self, name: &str, points: Vec<Vec3>, radiance: Vec3, pose: Affine3A) -> hecs::Entity {
        let (group, node) = self.add_group(name, pose);
        let light = PolygonLight { points, uvs: vec![], radiance, texture: None, reach: None };
        self.world.spawn((
            light,
            InGroup { group, local: Affine3A::IDENTITY },
            Transform { world: pose },
            NodeId(node),
        ));
        group
    }

    /// Adds a camera.
    pub fn add_camera(&mut self, camera: Camera) {
        let node = self.next_node();
        self.world.spawn((camera, NodeId(node)));
    }

    /// Recomputes derived transforms; call after moving groups.
    pub fn update_transforms(&mut self) {
        propagate_transforms(&mut self.world);
    }

    /// The mesh instance `e` was given (by the file or an edit), before any receiver
    /// refinement.
    pub fn source_mesh(&self, e: hecs::Entity) -> Option<MeshRef> {
        let refined = self.world.get::<&SourceMesh>(e).ok().map(|s| s.mesh);
        refined.or_else(|| self.world.get::<&MeshRef>(e).ok().map(|r| *r))
    }

    /// Gives instance `e` the mesh `mesh` as its source (an edit: any refinement of the old
    /// one is dropped).
    pub fn set_source_mesh(&mut self, e: hecs::Entity, mesh: MeshRef) {
        if let Ok(mut r) = self.world.get::<&mut MeshRef>(e) {
            *r = mesh;
        }
        let _ = self.world.remove_one::<SourceMesh>(e);
    }

    /// Every refined instance back on its source mesh.
    pub fn restore_source_meshes(&mut self) {
        let refined: Vec<(hecs::Entity, MeshRef)> =
            self.world.query::<(hecs::Entity, &SourceMesh)>().iter().map(|(e, s)| (e, s.mesh)).collect();
        for (e, mesh) in refined {
            self.set_source_mesh(e, mesh);
        }
    }

    /// Puts `mesh` in place of instance `e`'s mesh as a refinement of its source (a mesh
    /// already held with the same content is shared, so refining again adds nothing).
    pub fn set_refined_mesh(&mut self, e: hecs::Entity, mesh: Mesh) {
        let Some(source) = self.source_mesh(e) else { return };
        let index = match self.meshes.iter().position(|m| m.hash == mesh.hash) {
            Some(i) => i,
            None => {
                self.meshes.push(Arc::new(mesh));
                self.meshes.len() - 1
            }
        };
        let refined = MeshRef { index: index as u32, hash: self.meshes[index].hash };
        let _ = self.world.insert(e, (refined, SourceMesh { mesh: source }));
    }

    /// An independent copy with the same entity ids (a snapshot for a background bake while the
    /// original keeps being edited); meshes and textures are shared.
    pub fn duplicate(&self) -> Self {
        let mut world = hecs::World::new();
        for e in self.world.iter() {
            world.spawn_at(e.entity(), &clone_components(&e));
        }
        Self {
            world,
            meshes: self.meshes.clone(),
            textures: self.textures.clone(),
            source: self.source.clone(),
            warnings: self.warnings.clone(),
        }
    }

    /// A copy of every component of entity `e` (`None` when it does not exist), to spawn again
    /// later (the editor's undo of a deletion).
    pub fn components(&self, e: hecs::Entity) -> Option<hecs::BuiltEntityClone> {
        self.world.entity(e).ok().map(|e| clone_components(&e))
    }

    /// Sets the environment (see [`Scene::set_environment`]) and returns `self`, for chaining.
    pub fn with_environment(mut self, env: EnvironmentLight) -> Self {
        self.set_environment(env);
        self
    }
}

/// Every component type the importer and builders create, copied.
fn clone_components(e: &hecs::EntityRef) -> hecs::BuiltEntityClone {
    let mut b = hecs::EntityBuilderClone::new();
    copy::<Name>(e, &mut b);
    copy::<NodeId>(e, &mut b);
    copy::<Transform>(e, &mut b);
    copy::<RigidGroup>(e, &mut b);
    copy::<InGroup>(e, &mut b);
    copy::<PrimitiveId>(e, &mut b);
    copy::<MeshRef>(e, &mut b);
    copy::<SourceMesh>(e, &mut b);
    copy::<Material>(e, &mut b);
    copy::<MaterialMaps>(e, &mut b);
    copy::<PolygonLight>(e, &mut b);
    copy::<Emitter>(e, &mut b);
    copy::<Camera>(e, &mut b);
    copy::<EnvironmentLight>(e, &mut b);
    b.build()
}

fn copy<T: hecs::Component + Clone>(e: &hecs::EntityRef, b: &mut hecs::EntityBuilderClone) {
    if let Some(c) = e.get::<&T>() {
        b.add((*c).clone());
    }
}

#[cfg(test)]
mod tests {
    use crate::scene::{default_scene, flatten};

    #[test]
    fn a_duplicate_flattens_to_the_same_snapshot() {
        let scene = default_scene();
        let copy = scene.duplicate();
        let (a, b) = (flatten(&scene), flatten(&copy));
        assert_eq!(a.triangles, b.triangles);
        assert_eq!(a.instances.len(), b.instances.len());
        assert_eq!(a.lights.len(), b.lights.len());
        assert_eq!(scene.world.len(), copy.world.len());
    }
}
