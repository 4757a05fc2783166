//! Writing groups added in the editor (new lights, copies, dropped files) into the source: each
//! becomes a new top-level node with one child node per glTF node its members came from. A
//! child shows the file's own mesh when its members are exactly that mesh's primitives (a
//! copy); otherwise its geometry is written anew into the added buffer — light polygons as
//! fans, meshes with their normals, texture coordinates and colours — with the file's material
//! where the member has one, or a material made from its factors.

use super::json::{Object, edit_object, set};
use super::{SaveEdits, set_transform};
use glam::{Affine3A, Vec3};
use kage_engine::scene::{
    Emitter, InGroup, Material, MaterialMaps, Mesh, MeshRef, Name, PolygonLight, PrimitiveId, RigidGroup, Transform,
};
use std::collections::BTreeMap;

/// One member of an added group, as the file will hold it.
enum Member {
    /// A mesh instance: its primitive in the file (if it came from there), mesh and material.
    Instance { file: Option<PrimitiveId>, mesh: MeshRef, material: Material, textured: bool },
    /// A light polygon: its primitive in the file (if it came from there).
    Light { file: Option<PrimitiveId>, light: PolygonLight },
}

impl Member {
    fn file(&self) -> Option<PrimitiveId> {
        match self {
            Member::Instance { file, .. } | Member::Light { file, .. } => *file,
        }
    }
}

impl SaveEdits<'_> {
    /// Writes every group the baseline does not hold; returns how many.
    pub(super) fn added(&mut self) -> usize {
        let w = &self.scene.world;
        let mut groups: Vec<(u32, hecs::Entity, Affine3A, String)> = w
            .query::<(hecs::Entity, &RigidGroup, &Transform, &Name)>()
            .iter()
            .filter(|(e, ..)| self.baseline.get(super::Target::Group(*e)).is_none())
            .map(|(e, g, t, n)| (g.index, e, t.world, n.0.clone()))
            .collect();
        groups.sort_by_key(|g| g.0);
        for (_, group, pose, name) in &groups {
            let mut children = Vec::new();
            for (local, members) in self.nodes_of(*group) {
                if let Some(mesh) = self.mesh_for(&members, name) {
                    let mut node = Object::new();
                    set(&mut node, "name", name);
                    set(&mut node, "mesh", mesh);
                    set_transform(&mut node, local);
                    children.push(self.file.push("nodes", node));
                }
            }
            let mut root = Object::new();
            set(&mut root, "name", name);
            set_transform(&mut root, *pose);
            set(&mut root, "children", &children);
            let root = self.file.push("nodes", root);
            self.file.add_root(root);
            self.nodes += 1 + children.len();
        }
        groups.len()
    }

    /// The members of `group` by the glTF node they came from (a new light is a node of its
    /// own), with their group-from-node transform.
    fn nodes_of(&self, group: hecs::Entity) -> Vec<(Affine3A, Vec<Member>)> {
        let w = &self.scene.world;
        let mut nodes: BTreeMap<(u32, u64), (Affine3A, Vec<Member>)> = BTreeMap::new();
        let mut members: Vec<(hecs::Entity, InGroup)> = w
            .query::<(hecs::Entity, &InGroup)>()
            .iter()
            .filter(|(_, m)| m.group == group)
            .map(|(e, m)| (e, *m))
            .collect();
        members.sort_by_key(|m| m.0);
        for (e, m) in members {
            let (key, member) = if let Ok(light) = w.get::<&PolygonLight>(e) {
                let emitter = w.get::<&Emitter>(e).ok().map(|x| *x);
                let key = emitter.map_or((u32::MAX, e.to_bits().get()), |x| (x.id.node, 0));
                (key, Member::Light { file: emitter.map(|x| x.id), light: (*light).clone() })
            } else {
                // The mesh as given, not as refinement left it: refinement is redone on load.
                let (Ok(id), Some(mesh), Ok(material)) =
                    (w.get::<&PrimitiveId>(e), self.scene.source_mesh(e), w.get::<&Material>(e))
                else {
                    continue;
                };
                let from_file = self.baseline.primitives.get(&(id.mesh, id.primitive)) == Some(&mesh);
                let textured = w.get::<&MaterialMaps>(e).is_ok_and(|m| !m.is_empty());
                let member = Member::Instance { file: from_file.then_some(*id), mesh, material: *material, textured };
                ((id.node, 0), member)
            };
            nodes.entry(key).or_insert_with(|| (m.local, Vec::new())).1.push(member);
        }
        nodes.into_values().collect()
    }

    /// The glTF mesh showing `members`: the file's own when they are all its primitives,
    /// else one written anew (`None`, with the reason noted, when that cannot be done).
    fn mesh_for(&mut self, members: &[Member], name: &str) -> Option<usize> {
        let files: Vec<Option<PrimitiveId>> = members.iter().map(Member::file).collect();
        if let Some(Some(first)) = files.first()
            && let Some(mesh) = self.doc.meshes().nth(first.mesh as usize)
        {
            let mut prims: Vec<u32> =
                files.iter().flatten().filter(|f| f.mesh == first.mesh).map(|f| f.primitive).collect();
            prims.sort_unstable();
            prims.dedup();
            if files.iter().all(Option::is_some) && prims.len() == mesh.primitives().count() {
                return Some(first.mesh as usize);
            }
        }
        let mut primitives = Vec::new();
        for m in members {
            match self.primitive(m) {
                Ok(p) => primitives.push(p),
                Err(why) => {
                    self.problems.push(format!("group '{name}' was added in the editor, but {why}"));
                    return None;
                }
            }
        }
        let mut mesh = Object::new();
        set(&mut mesh, "name", name);
        set(&mut mesh, "primitives", primitives);
        Some(self.file.push("meshes", mesh))
    }

    /// One member written as a glTF primitive over new accessors.
    fn primitive(&mut self, member: &Member) -> Result<Object, String> {
        let (mesh, material) = match member {
            Member::Instance { file, mesh, material, textured } => {
                let own = file.and_then(|id| self.material_index(id));
                if own.is_none() && *textured {
                    return Err(
                        "the textures of a dropped file's meshes are not written (Export pack keeps them)".into()
                    );
                }
                let material = own.unwrap_or_else(|| self.surface_material(material));
                (self.scene.meshes[mesh.index as usize].as_ref().clone(), material)
            }
            Member::Light { file, light } => {
                if file.is_none() && light.texture.is_some() {
                    return Err("the texture of a dropped light is not written (Export pack keeps it)".into());
                }
                let material = match file.and_then(|id| self.material_index(id)) {
                    Some(m) => m,
                    None => self.emissive_material(light.radiance),
                };
                (fan(&light.points)?, material)
            }
        };
        let mut primitive = Object::new();
        set(&mut primitive, "attributes", self.attributes(&mesh));
        let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
        set(
            &mut primitive,
            "indices",
            self.file.accessor(bytemuck::cast_slice(&indices), indices.len(), "SCALAR", None),
        );
        set(&mut primitive, "material", material);
        Ok(primitive)
    }

    fn attributes(&mut self, mesh: &Mesh) -> Object {
        let n = mesh.positions.len();
        let bounds = mesh
            .positions
            .iter()
            .fold([Vec3::MAX, Vec3::MIN], |[lo, hi], p| [lo.min(*p), hi.max(*p)])
            .map(|v| v.to_array());
        let mut attributes = Object::new();
        let f = &mut self.file;
        set(&mut attributes, "POSITION", f.accessor(bytemuck::cast_slice(&mesh.positions), n, "VEC3", Some(bounds)));
        set(&mut attributes, "NORMAL", f.accessor(bytemuck::cast_slice(&mesh.normals), n, "VEC3", None));
        if !mesh.uvs.is_empty() {
            set(&mut attributes, "TEXCOORD_0", f.accessor(bytemuck::cast_slice(&mesh.uvs), n, "VEC2", None));
        }
        if !mesh.colors.is_empty() {
            set(&mut attributes, "COLOR_0", f.accessor(bytemuck::cast_slice(&mesh.colors), n, "VEC3", None));
        }
        attributes
    }

    /// A new material with `m`'s factors.
    fn surface_material(&mut self, m: &Material) -> usize {
        let mut material = Object::new();
        edit_object(&mut material, "pbrMetallicRoughness", |pbr| {
            set(pbr, "baseColorFactor", m.base_color.extend(1.0).to_array());
            set(pbr, "metallicFactor", m.metallic);
            set(pbr, "roughnessFactor", m.roughness);
        });
        if m.specular != 1.0 {
            edit_object(&mut material, "extensions", |ext| {
                edit_object(ext, "KHR_materials_specular", |s| set(s, "specularFactor", m.specular))
            });
            self.file.uses("KHR_materials_specular");
        }
        self.file.push("materials", material)
    }

    /// A new black material emitting `radiance`.
    fn emissive_material(&mut self, radiance: Vec3) -> usize {
        let strength = radiance.max_element().max(1.0);
        let mut material = Object::new();
        edit_object(&mut material, "pbrMetallicRoughness", |pbr| set(pbr, "baseColorFactor", [0.0f32, 0.0, 0.0, 1.0]));
        set(&mut material, "emissiveFactor", (radiance / strength).to_array());
        if strength > 1.0 {
            edit_object(&mut material, "extensions", |ext| {
                edit_object(ext, "KHR_materials_emissive_strength", |s| set(s, "emissiveStrength", strength))
            });
            self.file.uses("KHR_materials_emissive_strength");
        }
        self.file.push("materials", material)
    }
}

/// A convex polygon (counter-clockwise about its emitting side) as a triangle fan.
fn fan(points: &[Vec3]) -> Result<Mesh, String> {
    let (normal, _) = kage_engine::scene::import::polygon_normal_area(points);
    let triangles = (1..points.len().saturating_sub(1) as u32).map(|k| [0, k, k + 1]).collect();
    Mesh::new(points.to_vec(), Some(vec![normal; points.len()]), Vec::new(), triangles, false)
        .map(|(mesh, _)| mesh)
        .map_err(|e| format!("its light polygon is invalid: {e:?}"))
}
