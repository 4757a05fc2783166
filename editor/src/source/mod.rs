//! Saving the scene that was opened: the edits written into the source glTF's own JSON. Every
//! value the edits do not touch — other nodes and their keys, extensions, extras, animations,
//! skins, images, samplers, extensions kage does not know — is copied as the raw text it was,
//! in its order; buffers are never rewritten (a `.glb` keeps its binary chunk as it was).
//!
//! What is written, compared with the [`Baseline`] (the values the file held when it was
//! opened or last saved):
//! - a moved or turned group: its top-level node's translation, rotation and scale;
//! - a moved, turned or resized light: its node's transform (the polygon's vertices stay in the
//!   buffer; a resize becomes a scale of the node about the polygon's centre);
//! - a light's radiance: its material's `emissiveFactor` (and `KHR_materials_emissive_strength`
//!   when a factor would exceed 1);
//! - an instance's material factors: base colour (alpha kept), metallic, roughness, specular.
//!
//! What cannot be written is refused with a message naming it, before anything is written: a
//! light edit on a node that also holds meshes or children (they would move with it), a glTF
//! material shared by things edited differently, a replaced mesh (buffers are never rewritten).

mod added;
mod json;

use super::history::{Stored, Target};
use glam::{Affine3A, Mat4, Vec3};
use json::{GltfJson, Object, edit_object, set};
use kage_engine::scene::import::files::Root;
use kage_engine::scene::{
    Emitter, InGroup, Material, MeshRef, NodeId, PolygonLight, PrimitiveId, RigidGroup, Scene, Transform,
};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The values the source file holds, per editable thing, and the glTF node of each group and
/// light.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Baseline {
    values: HashMap<Target, Stored>,
    nodes: HashMap<hecs::Entity, usize>,
    /// The mesh each of the file's (mesh, primitive) pairs was imported as.
    primitives: HashMap<(u32, u32), MeshRef>,
}

impl Baseline {
    /// The values of `scene` now (as opened, or as just saved).
    pub fn of(scene: &Scene) -> Self {
        let w = &scene.world;
        let mut values = HashMap::new();
        let mut keep = |s: Stored| {
            values.insert(s.target(), s);
        };
        w.query::<(hecs::Entity, &RigidGroup, &Transform)>()
            .iter()
            .for_each(|(e, _, t)| keep(Stored::Group(e, t.world)));
        for (e, l, m) in w.query::<(hecs::Entity, &PolygonLight, &InGroup)>().iter() {
            keep(Stored::Light(e, m.local, l.clone()));
        }
        for (e, m) in w.query::<(hecs::Entity, &Material)>().with::<&MeshRef>().iter() {
            keep(Stored::Material(e, *m));
            keep(Stored::Mesh(e, scene.source_mesh(e).expect("queried with a mesh")));
        }
        let nodes = w.query::<(hecs::Entity, &NodeId)>().iter().map(|(e, n)| (e, n.0 as usize)).collect();
        let primitives = w
            .query::<(hecs::Entity, &PrimitiveId)>()
            .with::<&MeshRef>()
            .iter()
            .map(|(e, id)| ((id.mesh, id.primitive), scene.source_mesh(e).expect("queried with a mesh")))
            .collect();
        Self { values, nodes, primitives }
    }

    /// The stored values of `target`, if the file holds it.
    pub fn get(&self, target: Target) -> Option<&Stored> {
        self.values.get(&target)
    }
}

/// What a save wrote.
#[derive(Clone, Debug)]
pub struct Saved {
    /// Nodes whose transform was written.
    pub nodes: usize,
    /// Materials whose factors were written.
    pub materials: usize,
    /// Files the scene refers to, copied beside a `Save As` target.
    pub copied: Vec<PathBuf>,
    /// A copy of the file that was replaced, if there was one.
    pub backup: Option<PathBuf>,
    /// Groups added in the editor and written as new nodes (their entities do not know their
    /// nodes: the editor reads the saved file again).
    pub added: usize,
}

/// Writes the edits `scene` made since `baseline` into the glTF at `from`, saving the result
/// at `to` (the same path for Save; another for Save As, which copies the buffers and images
/// the file refers to). Atomic; the replaced file is kept as `<to>.bak`.
pub fn save(scene: &Scene, baseline: &Baseline, from: &Path, to: &Path) -> Result<Saved, String> {
    let name = from.display();
    let glb = is_glb(from);
    if glb != is_glb(to) {
        return Err(format!("{}: Save As keeps the format of {name} (.gltf or .glb)", to.display()));
    }
    let bytes = std::fs::read(from).map_err(|e| format!("{name}: {e}"))?;
    // A GLB's chunks are checked before the gltf crate reads it (it panics on some damaged headers).
    let chunks = glb.then(|| kage_runtime::pack::glb::split(&bytes)).transpose().map_err(|e| format!("{name}: {e}"))?;
    let doc = gltf::Gltf::from_slice(&bytes).map_err(|e| format!("{name}: {e}"))?.document;
    let (json, bin) = match chunks {
        Some(g) => (g.json.to_vec(), (!g.bin.is_empty()).then(|| g.bin.to_vec())),
        None => (bytes, None),
    };
    let mut file = GltfJson::parse(&json).map_err(|e| format!("{name}: {e}"))?;
    let mut plan =
        SaveEdits { scene, baseline, doc: &doc, file: &mut file, problems: Vec::new(), nodes: 0, materials: 0 };
    let added = plan.added();
    plan.deleted();
    plan.groups_and_lights();
    plan.materials();
    plan.replaced_meshes();
    if !plan.problems.is_empty() {
        return Err(format!("{name}: not saved:\n  {}", plan.problems.join("\n  ")));
    }
    let (nodes, materials) = (plan.nodes, plan.materials);
    let json = file.into_json().map_err(|e| format!("{name}: {e}"))?;
    let out = match bin {
        Some(bin) => gltf::binary::Glb {
            header: gltf::binary::Header { magic: *b"glTF", version: 2, length: 0 },
            json: json.into(),
            bin: Some(bin.into()),
        }
        .to_vec()
        .map_err(|e| format!("{name}: {e}"))?,
        None => json,
    };
    let copied = copy_resources(&doc, from, to)?;
    let backup = to.exists().then(|| PathBuf::from(format!("{}.bak", to.display())));
    if let Some(b) = &backup {
        std::fs::copy(to, b).map_err(|e| format!("{}: cannot keep a backup: {e}", b.display()))?;
    }
    kage_engine::output::write_atomically(to, |f| std::io::Write::write_all(f, &out))
        .map_err(|e| format!("{}: {e}", to.display()))?;
    Ok(Saved { nodes, materials, copied, backup, added })
}

fn is_glb(p: &Path) -> bool {
    p.extension().is_some_and(|e| e.eq_ignore_ascii_case("glb"))
}

fn set_transform(node: &mut Object, m: Affine3A) {
    let (s, r, t) = m.to_scale_rotation_translation();
    node.shift_remove("matrix");
    set(node, "translation", t.to_array());
    set(node, "rotation", r.to_array());
    set(node, "scale", s.to_array());
}

/// The edits to write, and what stops them.
struct SaveEdits<'a> {
    scene: &'a Scene,
    baseline: &'a Baseline,
    doc: &'a gltf::Document,
    file: &'a mut GltfJson,
    problems: Vec<String>,
    nodes: usize,
    materials: usize,
}

impl SaveEdits<'_> {
    fn node_name(&self, n: usize) -> String {
        let name = self.doc.nodes().nth(n).and_then(|x| x.name().map(str::to_string)).unwrap_or_default();
        format!("nodes[{n}] ('{name}')")
    }

    fn matrix(&self, n: usize) -> Affine3A {
        let node = self.doc.nodes().nth(n).expect("nodes come from this document");
        Affine3A::from_mat4(Mat4::from_cols_array_2d(&node.transform().matrix()))
    }

    /// Group-from-node transforms, as the importer composes them (a root's own is the identity).
    fn group_from_node(&self) -> HashMap<usize, Affine3A> {
        let mut out = HashMap::new();
        let mut stack: Vec<(usize, Affine3A)> =
            self.doc.scenes().flat_map(|s| s.nodes()).map(|n| (n.index(), Affine3A::IDENTITY)).collect();
        while let Some((n, local)) = stack.pop() {
            if out.insert(n, local).is_some() {
                continue;
            }
            for c in self.doc.nodes().nth(n).expect("indices from this document").children() {
                stack.push((c.index(), local * self.matrix(c.index())));
            }
        }
        out
    }

    fn groups_and_lights(&mut self) {
        let w = &self.scene.world;
        // New node transforms: moved groups' roots first, then lights composed onto them.
        let mut frames: HashMap<usize, Affine3A> = HashMap::new();
        for (e, _, t, node) in w.query::<(hecs::Entity, &RigidGroup, &Transform, &NodeId)>().iter() {
            if let Some(Stored::Group(_, before)) = self.baseline.get(Target::Group(e))
                && *before != t.world
            {
                frames.insert(node.0 as usize, t.world);
            }
        }
        let mut deltas: HashMap<usize, Vec<Affine3A>> = HashMap::new();
        let mut emitters: HashMap<usize, usize> = HashMap::new();
        for (e, light, member, emitter) in w.query::<(hecs::Entity, &PolygonLight, &InGroup, &Emitter)>().iter() {
            let node = emitter.id.node as usize;
            *emitters.entry(node).or_default() += 1;
            let Some(Stored::Light(_, local, before)) = self.baseline.get(Target::Light(e)) else { continue };
            if *local == member.local && before.points == light.points {
                continue;
            }
            match resize(&before.points, &light.points) {
                Some(s) => deltas.entry(node).or_default().push(member.local * s * local.inverse()),
                None => self
                    .problems
                    .push(format!("{}: the light's polygon changed shape, not only size", self.node_name(node))),
            }
        }
        let chains = self.group_from_node();
        for (node, list) in deltas {
            let Some(delta) = self.light_delta(node, &list, emitters[&node]) else { continue };
            let chain = chains.get(&node).copied().unwrap_or(Affine3A::IDENTITY);
            let base = frames.get(&node).copied().unwrap_or_else(|| self.matrix(node));
            frames.insert(node, base * chain.inverse() * delta * chain);
        }
        self.nodes += frames.len();
        for (node, m) in frames {
            match self.file.array("nodes").get_mut(node) {
                Some(object) => set_transform(object, m),
                None => self.problems.push(format!("nodes[{node}] is not in the file")),
            }
        }
    }

    /// The one change every light of `node` made, if its node can carry it alone.
    fn light_delta(&mut self, node: usize, deltas: &[Affine3A], lights: usize) -> Option<Affine3A> {
        let instances = self.scene.world.query::<&PrimitiveId>().iter().filter(|id| id.node as usize == node).count();
        let children = self.doc.nodes().nth(node).map_or(0, |n| n.children().count());
        let same = deltas.len() == lights && deltas.iter().all(|d| d.abs_diff_eq(deltas[0], 1e-5));
        let why = if instances > 0 || children > 0 {
            "the node also holds meshes or children, which would move with it"
        } else if !same {
            "its polygons were moved differently, and they share one node"
        } else {
            return Some(deltas[0]);
        };
        self.problems.push(format!("{}: a light edit cannot be written: {why}", self.node_name(node)));
        None
    }

    fn material_index(&self, id: PrimitiveId) -> Option<usize> {
        let mesh = self.doc.meshes().nth(id.mesh as usize)?;
        mesh.primitives().nth(id.primitive as usize)?.material().index()
    }

    fn materials(&mut self) {
        let w = &self.scene.world;
        // Per glTF material: what its users want now, and whether any of them changed.
        let mut wanted: HashMap<Option<usize>, (Vec<Wanted>, bool)> = HashMap::new();
        // Things added in the editor are written with materials of their own (see `added`).
        for (e, m, id) in w.query::<(hecs::Entity, &Material, &PrimitiveId)>().iter() {
            let Some(before) = self.baseline.get(Target::Material(e)) else { continue };
            let changed = matches!(before, Stored::Material(_, b) if b != m);
            let entry = wanted.entry(self.material_index(*id)).or_default();
            entry.0.push(Wanted::Surface(*m, *id));
            entry.1 |= changed;
        }
        for (e, l, emitter) in w.query::<(hecs::Entity, &PolygonLight, &Emitter)>().iter() {
            let Some(before) = self.baseline.get(Target::Light(e)) else { continue };
            let changed = matches!(before, Stored::Light(_, _, b) if b.radiance != l.radiance);
            let entry = wanted.entry(self.material_index(emitter.id)).or_default();
            entry.0.push(Wanted::Emission(l.radiance, emitter.id));
            entry.1 |= changed;
        }
        for (index, (users, changed)) in wanted {
            if !changed {
                continue;
            }
            if !users.windows(2).all(|p| p[0].same(&p[1])) {
                let nodes: Vec<String> = users.iter().map(|u| self.node_name(u.id().node as usize)).collect();
                let what = index.map_or("glTF's default material".to_string(), |i| format!("materials[{i}]"));
                self.problems.push(format!(
                    "{what} is shared by {} edited differently (give them their own materials to edit them apart)",
                    nodes.join(", ")
                ));
                continue;
            }
            // Primitives on glTF's default material get a material of their own.
            let index = index.unwrap_or_else(|| {
                let i = self.file.push("materials", Object::new());
                users.iter().for_each(|u| self.file.assign(u.id().mesh as usize, u.id().primitive as usize, i));
                i
            });
            self.write_material(index, users[0]);
        }
    }

    fn write_material(&mut self, index: usize, wanted: Wanted) {
        let source = self.doc.materials().nth(index);
        let alpha = source.as_ref().map_or(1.0, |s| s.pbr_metallic_roughness().base_color_factor()[3]);
        let specular = source.as_ref().and_then(|s| s.specular()).map_or(1.0, |s| s.specular_factor());
        let strength = source.as_ref().and_then(|s| s.emissive_strength()).unwrap_or(1.0);
        self.materials += 1;
        let object = &mut self.file.array("materials")[index];
        match wanted {
            Wanted::Surface(m, _) => {
                edit_object(object, "pbrMetallicRoughness", |pbr| {
                    set(pbr, "baseColorFactor", m.base_color.extend(alpha).to_array());
                    set(pbr, "metallicFactor", m.metallic);
                    set(pbr, "roughnessFactor", m.roughness);
                });
                if specular != m.specular {
                    edit_object(object, "extensions", |ext| {
                        edit_object(ext, "KHR_materials_specular", |s| set(s, "specularFactor", m.specular))
                    });
                    self.file.uses("KHR_materials_specular");
                }
            }
            Wanted::Emission(radiance, _) => {
                // glTF caps emissiveFactor at 1: brighter lights raise the strength.
                let wanted_strength = strength.max(radiance.max_element());
                set(object, "emissiveFactor", (radiance / wanted_strength.max(f32::MIN_POSITIVE)).to_array());
                if wanted_strength != strength {
                    edit_object(object, "extensions", |ext| {
                        edit_object(ext, "KHR_materials_emissive_strength", |s| {
                            set(s, "emissiveStrength", wanted_strength)
                        })
                    });
                    self.file.uses("KHR_materials_emissive_strength");
                }
            }
        }
    }

    /// Deleted groups leave the scene's node list (their nodes stay, unused, as glTF allows);
    /// a light deleted from a group that stays leaves its parent's children.
    fn deleted(&mut self) {
        let w = &self.scene.world;
        let gone = |e: &hecs::Entity| !w.contains(*e);
        let node_of = |e: &hecs::Entity| self.baseline.nodes.get(e).copied();
        let entities = |light: bool| {
            self.baseline.values.values().filter_map(move |s| match s {
                Stored::Group(e, _) if !light => Some(*e),
                Stored::Light(e, ..) if light => Some(*e),
                _ => None,
            })
        };
        let roots: Vec<usize> = entities(false).filter(gone).filter_map(|e| node_of(&e)).collect();
        let lights: Vec<usize> = entities(true).filter(gone).filter_map(|e| node_of(&e)).collect();
        for node in lights.into_iter().filter(|n| !roots.contains(n)) {
            let parent = self.doc.nodes().find(|p| p.children().any(|c| c.index() == node));
            match parent {
                Some(p) if !self.holds_more(node) => self.file.drop_child(p.index(), node),
                _ => self.problems.push(format!(
                    "{}: the deleted light shares its node with other things, which would go too",
                    self.node_name(node)
                )),
            }
        }
        self.nodes += roots.len();
        self.file.drop_roots(&roots);
    }

    /// Whether glTF node `node` holds anything still in the scene (meshes, other polygons of
    /// its emitter) or has children.
    fn holds_more(&self, node: usize) -> bool {
        let w = &self.scene.world;
        let kept = |e: hecs::Entity, t: Target| self.baseline.get(t).is_some() && w.contains(e);
        w.query::<(hecs::Entity, &PrimitiveId)>()
            .iter()
            .any(|(e, id)| id.node as usize == node && kept(e, Target::Mesh(e)))
            || w.query::<(hecs::Entity, &Emitter)>()
                .iter()
                .any(|(e, x)| x.id.node as usize == node && kept(e, Target::Light(e)))
            || self.doc.nodes().nth(node).is_some_and(|n| n.children().next().is_some())
    }

    fn replaced_meshes(&mut self) {
        for (e, id) in self.scene.world.query::<(hecs::Entity, &PrimitiveId)>().with::<&MeshRef>().iter() {
            let source = self.scene.source_mesh(e);
            if matches!(self.baseline.get(Target::Mesh(e)), Some(Stored::Mesh(_, b)) if Some(*b) != source) {
                self.problems.push(format!(
                    "{}: its mesh was replaced, and kage never rewrites buffers (export a pack to keep the result)",
                    self.node_name(id.node as usize)
                ));
            }
        }
    }
}

/// What one user of a glTF material wants it to be.
#[derive(Clone, Copy, Debug)]
enum Wanted {
    Surface(Material, PrimitiveId),
    Emission(Vec3, PrimitiveId),
}

impl Wanted {
    fn id(&self) -> PrimitiveId {
        match self {
            Self::Surface(_, id) | Self::Emission(_, id) => *id,
        }
    }

    fn same(&self, other: &Self) -> bool {
        match (self, other) {
            (Self::Surface(a, _), Self::Surface(b, _)) => a == b,
            (Self::Emission(a, _), Self::Emission(b, _)) => a == b,
            _ => false,
        }
    }
}

/// The similarity that scales polygon `before` about its centre into `after` (how the editor
/// resizes lights), or `None` when `after` is not such an image of `before`.
fn resize(before: &[Vec3], after: &[Vec3]) -> Option<Affine3A> {
    if before.len() != after.len() || before.is_empty() {
        return None;
    }
    let perimeter = |p: &[Vec3]| (0..p.len()).map(|i| p[i].distance(p[(i + 1) % p.len()])).sum::<f32>();
    let factor = perimeter(after) / perimeter(before).max(f32::MIN_POSITIVE);
    let c = before.iter().copied().sum::<Vec3>() / before.len() as f32;
    let s = Affine3A::from_translation(c) * Affine3A::from_scale(Vec3::splat(factor)) * Affine3A::from_translation(-c);
    let extent = perimeter(after).max(1e-6);
    before.iter().zip(after).all(|(b, a)| s.transform_point3(*b).distance(*a) <= 1e-4 * extent).then_some(s)
}

/// Copies the files the document refers to by relative URI from beside `from` to beside `to`
/// (Save As into another folder), through the importer's rules (regular files inside the
/// scene's folder only); files already there are kept.
fn copy_resources(doc: &gltf::Document, from: &Path, to: &Path) -> Result<Vec<PathBuf>, String> {
    let (src, dst) = (parent(from), parent(to));
    if src.canonicalize().ok() == dst.canonicalize().ok() {
        return Ok(Vec::new());
    }
    let root = Root::for_scene(from, None)?;
    let buffers = doc.buffers().filter_map(|b| match b.source() {
        gltf::buffer::Source::Uri(u) => Some(u.to_string()),
        gltf::buffer::Source::Bin => None,
    });
    let images = doc.images().filter_map(|i| match i.source() {
        gltf::image::Source::Uri { uri, .. } => Some(uri.to_string()),
        gltf::image::Source::View { .. } => None,
    });
    let mut copied = Vec::new();
    for uri in buffers.chain(images).filter(|u| !u.starts_with("data:")) {
        let real = root.resolve(src, &uri).map_err(|e| format!("{}: {e}", from.display()))?;
        let target = dst.join(&*percent_encoding::percent_decode_str(&uri).decode_utf8_lossy());
        if target.exists() {
            continue;
        }
        if let Some(dir) = target.parent() {
            std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        }
        std::fs::copy(&real, &target).map_err(|e| format!("{}: {e}", target.display()))?;
        copied.push(target);
    }
    Ok(copied)
}

fn parent(p: &Path) -> &Path {
    p.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."))
}
