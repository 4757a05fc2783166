//! System: the world-space snapshot of a scene for one frame — triangles of every instance and
//! light (light triangles are occluders too), per-instance transforms, and the light polygons.

use crate::scene::{
    Camera, Cutout, EnvironmentLight, FlatLight, Holes, InGroup, Material, MaterialMaps, Mesh, MeshRef, PolygonLight,
    PrimitiveId, Scene, SourceMesh, Texture, Transform,
};
use glam::{Affine3A, Mat3A, Vec2, Vec3};
use std::sync::Arc;

/// Marks a triangle that belongs to no light.
pub const NO_LIGHT: u32 = u32::MAX;

/// A mesh instance in world space.
#[derive(Clone, Debug)]
pub struct Instance {
    /// Index into [`FlatScene::meshes`] (and [`Scene::meshes`]).
    pub mesh: u32,
    /// The mesh that casts its shadows (see [`SourceMesh::occluder`]): its source, when a flat
    /// refinement shows more vertices on the same triangles.
    pub occluder: u32,
    /// The mesh it had before receiver refinement (`mesh` itself when not refined).
    pub source: u32,
    /// World-from-local.
    pub world: Affine3A,
    /// Transforms normals (inverse transpose of the linear part).
    pub normal_matrix: Mat3A,
    /// True when the transform mirrors, so winding is reversed.
    pub mirrored: bool,
    /// Material factors (see [`FlatScene::material_at`] for the material at a point).
    pub material: Material,
    /// Where the material varies over the surface.
    pub maps: MaterialMaps,
    /// glTF origin.
    pub id: PrimitiveId,
    /// Group entity.
    pub group: hecs::Entity,
    /// Index of this instance's first triangle in [`FlatScene::triangles`].
    pub first_triangle: u32,
}

/// Which instance or light a world triangle belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TriangleRef {
    /// Instance index, or the light index when `light != NO_LIGHT`.
    pub owner: u32,
    /// Triangle index within the owner's mesh (or fan triangle of the light polygon).
    pub local: u32,
    /// Light index, or [`NO_LIGHT`].
    pub light: u32,
}

/// World-space snapshot of a scene.
#[derive(Clone, Debug)]
pub struct FlatScene {
    /// Triangle corners, in the order the BVH indexes them (winding already un-mirrored).
    pub triangles: Vec<[Vec3; 3]>,
    /// Owner of each triangle.
    pub refs: Vec<TriangleRef>,
    /// Mesh instances.
    pub instances: Vec<Instance>,
    /// Light polygons.
    pub lights: Vec<FlatLight>,
    /// Each light's entity, by light index (what the editor selects and edits).
    pub light_entities: Vec<hecs::Entity>,
    /// The environment light, if any.
    pub environment: Option<EnvironmentLight>,
    /// The scene's first camera, if any.
    pub camera: Option<Camera>,
    /// The scene's meshes (shared, not copied), indexed by [`Instance::mesh`].
    pub meshes: Vec<Arc<Mesh>>,
    /// The scene's textures (shared), indexed by [`crate::scene::TextureSlot::texture`].
    pub textures: Vec<Arc<Texture>>,
}

/// Per-instance, per-vertex values (radiance, usually), in [`FlatScene::instances`] order.
pub type VertexValues = Vec<Vec<Vec3>>;

/// Builds the snapshot from the ECS world (transforms must be propagated).
pub fn flatten(scene: &Scene) -> FlatScene {
    let mut flat = FlatScene {
        triangles: Vec::new(),
        refs: Vec::new(),
        instances: Vec::new(),
        lights: Vec::new(),
        light_entities: Vec::new(),
        environment: scene.world.query::<&EnvironmentLight>().iter().next().cloned(),
        camera: scene.first_camera(),
        meshes: scene.meshes.clone(),
        textures: scene.textures.clone(),
    };
    // Sorted by glTF origin so that triangle order (and hence every seeded estimate) does not
    // depend on entity allocation order.
    type Item = (PrimitiveId, MeshRef, Option<SourceMesh>, Material, MaterialMaps, Transform, hecs::Entity);
    let mut items: Vec<Item> = scene
        .world
        .query::<(&PrimitiveId, &MeshRef, Option<&SourceMesh>, &Material, Option<&MaterialMaps>, &Transform, &InGroup)>(
        )
        .iter()
        .map(|(id, m, source, mat, maps, t, g)| {
            (*id, *m, source.copied(), *mat, maps.copied().unwrap_or_default(), *t, g.group)
        })
        .collect();
    items.sort_by_key(|(id, ..)| (id.node, id.mesh, id.primitive));
    for (id, mref, source, material, maps, t, group) in items {
        let mesh = &scene.meshes[mref.index as usize];
        let mirrored = t.is_mirrored();
        let owner = flat.instances.len() as u32;
        flat.instances.push(Instance {
            mesh: mref.index,
            occluder: SourceMesh::occluder(mref, source.as_ref()).index,
            source: source.map_or(mref.index, |s| s.mesh.index),
            world: t.world,
            normal_matrix: t.world.matrix3.inverse().transpose(),
            mirrored,
            material,
            maps,
            id,
            group,
            first_triangle: flat.triangles.len() as u32,
        });
        for (k, p) in world_triangles(mesh, &t.world).enumerate() {
            flat.triangles.push(p);
            flat.refs.push(TriangleRef { owner, local: k as u32, light: NO_LIGHT });
        }
    }
    let mut lights: Vec<(u32, PolygonLight, Transform, hecs::Entity)> = scene
        .world
        .query::<(hecs::Entity, &PolygonLight, &Transform, &crate::scene::NodeId)>()
        .iter()
        .map(|(e, l, t, n)| (n.0, l.clone(), *t, e))
        .collect();
    lights.sort_by(|a, b| a.0.cmp(&b.0).then_with(|| a.1.points.len().cmp(&b.1.points.len())));
    for (_, light, t, entity) in lights {
        add_light(&mut flat, scene, &light, &t, entity);
    }
    flat
}

fn add_light(flat: &mut FlatScene, scene: &Scene, light: &PolygonLight, t: &Transform, entity: hecs::Entity) {
    let Some(mut placed) = FlatLight::placed(&light.points, &light.uvs, &t.world, light.radiance) else { return };
    let index = flat.lights.len() as u32;
    let points = &placed.points;
    for k in 0..points.len() - 2 {
        flat.triangles.push([points[0], points[k + 1], points[k + 2]]);
        flat.refs.push(TriangleRef { owner: index, local: k as u32, light: index });
    }
    placed.texture = light.texture.map(|i| scene.textures[i as usize].clone());
    placed.reach = light.reach;
    flat.lights.push(placed);
    flat.light_entities.push(entity);
}

/// `mesh`'s triangles placed by `to` (winding un-mirrored).
fn world_triangles<'a>(mesh: &'a Mesh, to: &'a Affine3A) -> impl Iterator<Item = [Vec3; 3]> + 'a {
    let mirrored = to.matrix3.determinant() < 0.0;
    mesh.triangles.iter().map(move |tri| {
        let mut p = tri.map(|i| to.transform_point3(mesh.positions[i as usize]));
        if mirrored {
            p.swap(1, 2);
        }
        p
    })
}

/// The triangles of one rigid group in the group's own frame (instances and lights, winding
/// un-mirrored), for a BVH that stays valid however the group moves, and their holes.
pub fn group_triangles(scene: &Scene, group: hecs::Entity) -> (Vec<[Vec3; 3]>, Holes) {
    let mut items: Vec<(PrimitiveId, MeshRef, InGroup, Option<Cutout>)> = scene
        .world
        .query::<(&PrimitiveId, &MeshRef, Option<&SourceMesh>, &InGroup, Option<&MaterialMaps>)>()
        .iter()
        .filter(|(_, _, _, g, _)| g.group == group)
        .map(|(id, m, source, g, maps)| (*id, SourceMesh::occluder(*m, source), *g, maps.and_then(|m| m.cutout)))
        .collect();
    items.sort_by_key(|(id, ..)| (id.node, id.mesh, id.primitive));
    let mut out = Vec::new();
    let mut holes = Vec::new();
    for (_, mref, member, cutout) in items {
        let mesh = &scene.meshes[mref.index as usize];
        let mirrored = member.local.matrix3.determinant() < 0.0;
        out.extend(world_triangles(mesh, &member.local));
        holes.push((Holes::of_mesh(mesh, cutout.as_ref(), &scene.textures, mirrored), mesh.triangles.len()));
    }
    for (light, member) in scene.world.query::<(&PolygonLight, &InGroup)>().iter().filter(|(_, g)| g.group == group) {
        let pts: Vec<Vec3> = light.points.iter().map(|p| member.local.transform_point3(*p)).collect();
        for k in 1..pts.len().saturating_sub(1) {
            out.push([pts[0], pts[k], pts[k + 1]]);
        }
    }
    (out, Holes::concat_counted(holes))
}

impl FlatScene {
    /// The light polygons of light entity `e` (a light mesh may make several).
    pub fn lights_of(&self, e: hecs::Entity) -> impl Iterator<Item = &FlatLight> {
        self.lights.iter().zip(&self.light_entities).filter(move |(_, le)| **le == e).map(|(l, _)| l)
    }

    /// The mesh of instance `inst`.
    pub fn mesh(&self, inst: usize) -> &Mesh {
        &self.meshes[self.instances[inst].mesh as usize]
    }

    /// The mesh that casts instance `inst`'s shadows ([`Instance::occluder`]).
    pub fn occluder_mesh(&self, inst: usize) -> &Mesh {
        &self.meshes[self.instances[inst].occluder as usize]
    }

    /// The holes of instance `inst`'s triangles (see [`crate::scene::cutout`]).
    pub fn instance_holes(&self, inst: usize) -> Holes {
        let i = &self.instances[inst];
        Holes::of_mesh(self.mesh(inst), i.maps.cutout.as_ref(), &self.textures, i.mirrored)
    }

    /// Instance `inst`'s occluding triangles in world space (its [`Self::occluder_mesh`]'s).
    pub fn occluder_triangles(&self, inst: usize) -> Vec<[Vec3; 3]> {
        world_triangles(self.occluder_mesh(inst), &self.instances[inst].world).collect()
    }

    /// The holes of [`Self::occluder_triangles`].
    pub fn occluder_holes(&self, inst: usize) -> Holes {
        let i = &self.instances[inst];
        Holes::of_mesh(self.occluder_mesh(inst), i.maps.cutout.as_ref(), &self.textures, i.mirrored)
    }

    /// A hash of what instance `inst` occludes with: its [`Self::occluder_mesh`] and the
    /// cut-out's mask (see [`crate::scene::cutout::occluder_hash`]).
    pub fn occluder_hash(&self, inst: usize) -> [u8; 32] {
        let cutout = self.instances[inst].maps.cutout.as_ref();
        crate::scene::cutout::occluder_hash(self.occluder_mesh(inst), cutout, &self.textures)
    }

    /// The holes of [`Self::triangles`] (lights' triangles are solid).
    pub fn holes(&self) -> Holes {
        Holes::concat_counted((0..self.instances.len()).map(|i| (self.instance_holes(i), self.mesh(i).triangles.len())))
    }

    /// The triangles whose refs `keep` accepts, in order, with their holes.
    pub fn select(&self, keep: impl Fn(&TriangleRef) -> bool) -> (Vec<[Vec3; 3]>, Holes) {
        let picked: Vec<usize> = (0..self.triangles.len()).filter(|&t| keep(&self.refs[t])).collect();
        let holes = self.holes().select(picked.iter().copied());
        (picked.into_iter().map(|t| self.triangles[t]).collect(), holes)
    }

    /// Why every image of this snapshot is black, when nothing lights it (no polygonal light
    /// and no environment): front ends warn with it and say how to light the scene.
    pub fn unlit(&self) -> Option<&'static str> {
        let unlit = self.lights.is_empty() && self.environment.is_none();
        unlit.then_some("nothing lights it: it has no emissive quad (polygonal light) and no environment")
    }

    /// Why diffuse transfer (PRT) shows some instances black, in whole or in part: metals
    /// everywhere (metallic 1, glTF's default, with no texture lowering it), and metals where a
    /// metallic-roughness texture says so (a banded ball): metal has no diffuse term. Front
    /// ends note it and name the method that shows them.
    pub fn black_under_prt(&self) -> Option<String> {
        let textured = |i: &Instance| i.maps.metallic_roughness.is_some();
        let metals = self.instances.iter().filter(|i| i.material.metallic >= 1.0 && !textured(i)).count();
        let partly = self.instances.iter().filter(|i| i.material.metallic > 0.0 && textured(i)).count();
        let n = self.instances.len();
        let mut which = Vec::new();
        if metals > 0 {
            which.push(format!(
                "{metals} of {n} instances are metals (metallic 1, glTF's default when a material sets no metallicFactor)"
            ));
        }
        if partly > 0 {
            which.push(format!("{partly} of {n} are metal where their metallic-roughness texture says so"));
        }
        (!which.is_empty())
            .then(|| format!("{}: PRT transfers diffuse light only, so their metal shows black", which.join("; ")))
    }

    /// Vertices of instance `inst`.
    pub fn vertex_count(&self, inst: usize) -> usize {
        self.mesh(inst).positions.len()
    }

    /// Every (instance, vertex) pair, instance-major.
    pub fn vertex_ids(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        (0..self.instances.len()).flat_map(move |i| (0..self.vertex_count(i)).map(move |v| (i, v)))
    }

    /// Zero for every vertex of every instance.
    pub fn zeros(&self) -> VertexValues {
        (0..self.instances.len()).map(|i| vec![Vec3::ZERO; self.vertex_count(i)]).collect()
    }

    /// World position and unit shading normal of vertex `v` of instance `inst`.
    pub fn vertex(&self, inst: usize, v: usize) -> (Vec3, Vec3) {
        let i = &self.instances[inst];
        let mesh = &self.meshes[i.mesh as usize];
        let p = i.world.transform_point3(mesh.positions[v]);
        let n = (i.normal_matrix * glam::Vec3A::from(mesh.normals[v])).normalize_or_zero();
        (p, n.into())
    }

    /// The material at barycentrics `bary` of instance `inst`'s triangle `corners`: the factors
    /// times the vertex colour and the textures at the point's UVs.
    pub fn material_at(&self, inst: usize, corners: [usize; 3], bary: [f32; 3]) -> Material {
        let (i, mesh) = (&self.instances[inst], self.mesh(inst));
        let mut m = i.material;
        if !mesh.colors.is_empty() {
            m.base_color *= (0..3).map(|k| mesh.colors[corners[k]] * bary[k]).sum::<Vec3>();
        }
        if i.maps.is_empty() {
            return m;
        }
        let lerp = |a: &[Vec2]| if a.is_empty() { Vec2::ZERO } else { (0..3).map(|k| a[corners[k]] * bary[k]).sum() };
        let (uv0, uv1) = (lerp(&mesh.uvs), lerp(&mesh.uvs1));
        let sample = |s: &crate::scene::TextureSlot| self.textures[s.texture as usize].sample(s.uv(uv0, uv1));
        if let Some(s) = &i.maps.base_color {
            m.base_color *= sample(s);
        }
        if let Some(s) = &i.maps.metallic_roughness {
            let t = sample(s);
            (m.roughness, m.metallic) = (m.roughness * t.y, m.metallic * t.z);
        }
        m
    }

    /// True when instance `inst`'s material varies over its surface (textures or vertex
    /// colours).
    pub fn varies(&self, inst: usize) -> bool {
        !self.instances[inst].maps.is_empty() || !self.mesh(inst).colors.is_empty()
    }

    /// The material at vertex `v` of instance `inst`.
    pub fn vertex_material(&self, inst: usize, v: usize) -> Material {
        self.material_at(inst, [v; 3], [1.0, 0.0, 0.0])
    }

    /// The centre and radius of the sphere around every triangle (lights included); the unit
    /// sphere for an empty scene.
    pub fn bounding_sphere(&self) -> (Vec3, f32) {
        let (lo, hi) =
            self.triangles.iter().flatten().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
        if lo.x <= hi.x { (0.5 * (lo + hi), (0.5 * (hi - lo).length()).max(1e-3)) } else { (Vec3::ZERO, 1.0) }
    }

    /// A camera for a scene that has none: looking at the bounding sphere's centre from the
    /// front (+Z) and 26° above, far enough back to see all of it.
    pub fn framing_camera(&self) -> Camera {
        const YFOV: f32 = 0.8;
        const PITCH: f32 = 0.45;
        let (centre, radius) = self.bounding_sphere();
        let distance = 1.1 * radius / (0.5 * YFOV).sin();
        let eye = centre + distance * Vec3::new(0.0, PITCH.sin(), PITCH.cos());
        Camera::look_at(eye, centre, YFOV)
    }

    /// Total emitted power proxy of light `l` (mean radiance × area), for light selection.
    pub fn light_power(&self, l: usize) -> f32 {
        let light = &self.lights[l];
        let mean = light.texture.as_ref().map_or(Vec3::ONE, |t| t.mean());
        crate::math::luminance(light.radiance * mean) * light.area
    }
}
