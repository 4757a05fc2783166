//! glTF 2.0 import (`.gltf` with embedded or external buffers, `.glb`) into a [`Scene`].
//!
//! The `gltf` crate panics on some invalid files and accepts cyclic node graphs, so this module
//! checks references and byte ranges itself before handing data to it, guards the node
//! traversal against cycles, and — as a last line — turns any panic inside it into an error.
//! Every error names the file and the glTF element at fault.

mod checks;
mod deform;
pub mod files;
mod light;
pub mod reach;

pub use light::polygon_normal_area;

use crate::scene::mesh::MeshProblem;
use crate::scene::{
    Camera, Cutout, Emitter, InGroup, Material, MaterialMaps, Mesh, MeshRef, Name, NodeId, PolygonLight, PrimitiveId,
    Projection, RigidGroup, Scene, Texture, TextureSlot, Transform, propagate_transforms, texture::Wrap,
};
use crate::{Error, Result};
use glam::{Affine2, Affine3A, Mat4, Vec2, Vec3};
use gltf::mesh::Mode;
use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

/// Nodes imported between two progress reports.
const PROGRESS_STEP: usize = 4096;

/// Extensions whose data kage reads; any other *required* extension is refused.
pub const SUPPORTED_EXTENSIONS: &[&str] =
    &["KHR_materials_emissive_strength", "KHR_materials_specular", "KHR_texture_transform"];

/// Options for [`import`].
#[derive(Clone, Debug, Default)]
pub struct ImportOptions {
    /// Drop zero-area triangles (with a warning) instead of rejecting the file.
    pub drop_degenerate: bool,
    /// A folder wider than the scene file's own that its buffer and image URIs may read from
    /// (see [`files`]); `None`: the scene's folder only.
    pub allow_root: Option<std::path::PathBuf>,
    /// The `COLOR_n` set read as vertex colours (0; packs keep the source's in 1, as their
    /// `COLOR_0` is the baked preview).
    pub color_set: u32,
}

/// Most light polygons a scene may hold: every light is shaded at every vertex and pixel (and
/// probed by receiver refinement at every vertex), so a frame's cost grows with their count; at
/// this many an 800×600 image already takes minutes on the CPU.
pub const MAX_LIGHTS: usize = 4096;

/// The radiance a material emits: its emissive factor times its strength (a light when any
/// channel is positive).
fn emission(m: &gltf::Material) -> Vec3 {
    Vec3::from_array(m.emissive_factor()) * m.emissive_strength().unwrap_or(1.0)
}

/// Imports a `.gltf` or `.glb` file.
pub fn import(path: &Path, options: ImportOptions) -> Result<Scene> {
    import_reporting(path, options, &|_, _| {})
}

/// [`import`], calling `progress` with the nodes imported so far and their total.
pub fn import_reporting(path: &Path, options: ImportOptions, progress: &dyn Fn(usize, usize)) -> Result<Scene> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    // Last line of defence: the gltf crate has panicked on malformed input before.
    crate::error::contain(|| Importer::run(path, &bytes, options, progress))
        .unwrap_or_else(|what| Err(Error::gltf(path, format!("malformed glTF (the parser failed: {what})"))))
}

struct Importer<'a> {
    path: &'a Path,
    root: files::Root,
    /// Shared, so that node handles do not borrow the importer while entities are spawned
    /// (a clone of the document would double the memory of a scene of many nodes).
    doc: std::rc::Rc<gltf::Document>,
    buffers: Vec<gltf::buffer::Data>,
    options: ImportOptions,
    scene: Scene,
    /// (glTF mesh, primitive) → imported mesh index, so instanced meshes are read once.
    mesh_cache: HashMap<(usize, usize), u32>,
    by_hash: HashMap<crate::scene::MeshHash, u32>,
    /// (glTF texture, decoded as sRGB) → imported texture index.
    texture_cache: HashMap<(usize, Channels), u32>,
    /// Every node's world transform, for skins' joints (empty without skins).
    world: Vec<Option<Affine3A>>,
    group_count: u32,
    /// Instances and lights spawned into the current group.
    members: usize,
    /// Light polygons spawned so far (at most [`MAX_LIGHTS`]).
    lights: usize,
    /// Imported mesh index → its light polygons, so a light placed many times is split once.
    light_polygons: HashMap<u32, std::rc::Rc<[Vec<u32>]>>,
}

impl<'a> Importer<'a> {
    fn run(path: &'a Path, bytes: &[u8], options: ImportOptions, progress: &dyn Fn(usize, usize)) -> Result<Scene> {
        let err = |m: String| Error::gltf(path, m);
        checks::glb_header(bytes).map_err(err)?;
        let raw = gltf::Gltf::from_slice_without_validation(bytes)
            .map_err(|e| err(format!("not a readable glTF file: {e}")))?;
        let blob = raw.blob;
        let mut json = raw.document.into_json();
        checks::references(&json).map_err(err)?;
        let zeros = checks::zero_accessors(&mut json).map_err(err)?;
        let doc = gltf::Document::from_json(json).map_err(|e| err(format!("invalid glTF: {}", describe(&e))))?;
        if let Some(ext) = doc.extensions_required().find(|e| !SUPPORTED_EXTENSIONS.contains(e)) {
            return Err(err(format!("requires extension {ext}, which kage does not support")));
        }
        checks::light_count(&doc).map_err(err)?;
        let root = files::Root::for_scene(path, options.allow_root.as_deref()).map_err(err)?;
        let buffers = load_buffers(&doc, base_dir(path), &root, blob, zeros)
            .map_err(|e| err(format!("cannot load buffer data: {e}")))?;
        checks::byte_ranges(&doc, &buffers).map_err(err)?;
        let scene = Scene {
            world: hecs::World::new(),
            meshes: Vec::new(),
            textures: Vec::new(),
            source: path.display().to_string(),
            warnings: Vec::new(),
        };
        let world = if doc.skins().len() > 0 { deform::world_transforms(&doc) } else { Vec::new() };
        let mut imp = Importer {
            path,
            root,
            doc: std::rc::Rc::new(doc),
            buffers,
            options,
            scene,
            mesh_cache: HashMap::new(),
            by_hash: HashMap::new(),
            texture_cache: HashMap::new(),
            world,
            group_count: 0,
            members: 0,
            lights: 0,
            light_polygons: HashMap::new(),
        };
        imp.import_nodes(progress)?;
        propagate_transforms(&mut imp.scene.world);
        checks::world_extent(&imp.scene).map_err(err)?;
        Ok(imp.scene)
    }

    /// The image `source` names: from a buffer view, or a URI through the scene's root.
    fn image(&self, source: gltf::image::Source) -> std::result::Result<image::RgbaImage, String> {
        match source {
            gltf::image::Source::View { view, .. } => {
                let data = &self.buffers[view.buffer().index()];
                let bytes = view
                    .offset()
                    .checked_add(view.length())
                    .and_then(|end| data.get(view.offset()..end))
                    .ok_or_else(|| format!("bufferViews[{}] extends past the end of its buffer", view.index()))?;
                decode_image(bytes)
            }
            gltf::image::Source::Uri { uri, .. } => {
                decode_image(&self.root.read(base_dir(self.path), uri, files::MAX_IMAGE_BYTES)?)
            }
        }
    }

    fn error(&self, message: String) -> Error {
        Error::gltf(self.path, message)
    }

    /// The default scene's root nodes, or every parentless node when the file has no scene.
    fn roots(&self) -> Vec<usize> {
        if let Some(s) = self.doc.default_scene().or_else(|| self.doc.scenes().next()) {
            return s.nodes().map(|n| n.index()).collect();
        }
        let mut is_child = vec![false; self.doc.nodes().len()];
        for n in self.doc.nodes() {
            n.children().for_each(|c| is_child[c.index()] = true);
        }
        (0..is_child.len()).filter(|&i| !is_child[i]).collect()
    }

    fn import_nodes(&mut self, progress: &dyn Fn(usize, usize)) -> Result<()> {
        let doc = std::rc::Rc::clone(&self.doc);
        let (total, mut done) = (doc.nodes().len(), 0);
        let mut seen = vec![false; total];
        for root in self.roots() {
            let node = doc.nodes().nth(root).expect("checked index");
            let pose =
                node_matrix(&node).ok_or_else(|| self.error(format!("nodes[{root}]: transform is not finite")))?;
            let name = node.name().map(str::to_string).unwrap_or_else(|| format!("node{root}"));
            let group = self.scene.world.spawn((
                RigidGroup { index: self.group_count },
                Transform { world: pose },
                Name(name),
                NodeId(root as u32),
            ));
            self.members = 0;
            // Depth-first, carrying the group-from-node transform; `seen` breaks cycles.
            let mut stack = vec![(root, Affine3A::IDENTITY)];
            while let Some((index, local)) = stack.pop() {
                if std::mem::replace(&mut seen[index], true) {
                    return Err(self.error(format!(
                        "nodes[{index}] is reached twice (a cycle in the node graph, or a node with two parents)"
                    )));
                }
                let node = doc.nodes().nth(index).expect("checked index");
                self.import_node(&node, group, pose, local)?;
                done += 1;
                if done % PROGRESS_STEP == 0 {
                    progress(done, total);
                }
                for child in node.children() {
                    let m = node_matrix(&child)
                        .ok_or_else(|| self.error(format!("nodes[{}]: transform is not finite", child.index())))?;
                    stack.push((child.index(), local * m));
                }
            }
            // Only subtrees with geometry are rigid groups (a lone camera node is not).
            if self.members == 0 {
                self.scene.world.despawn(group).expect("just spawned");
            } else {
                self.group_count += 1;
            }
        }
        Ok(())
    }

    fn import_node(&mut self, node: &gltf::Node, group: hecs::Entity, pose: Affine3A, local: Affine3A) -> Result<()> {
        let node_id = node.index() as u32;
        if let Some(cam) = node.camera() {
            let projection = match cam.projection() {
                gltf::camera::Projection::Perspective(p) => Projection::Perspective { yfov: p.yfov() },
                gltf::camera::Projection::Orthographic(o) => Projection::Orthographic { ymag: o.ymag() },
            };
            let world = orthonormalize(pose * local);
            self.scene.world.spawn((Camera { world, projection }, NodeId(node_id)));
        }
        let node_name = format!("nodes[{node_id}] ('{}')", node.name().unwrap_or(""));
        let declared = reach::declared(node.extras().as_deref().map(|r| r.get()))
            .map_err(|m| self.error(format!("{node_name}: {m}")))?;
        let Some(mesh) = node.mesh() else {
            self.unused_reach(declared, 0, &node_name);
            return Ok(());
        };
        let buffers = &self.buffers;
        let deform = deform::Deform::of(node, &mesh, |b| buffers.get(b.index()).map(|d| &d.0[..]), &self.world)
            .map_err(|m| self.error(format!("{node_name}: {m}")))?;
        // A skinned mesh is posed in world space: the node's own transform does not apply.
        let local = match deform.joints.is_empty() {
            true => local,
            false if pose.matrix3.determinant() != 0.0 => pose.inverse(),
            false => return Err(self.error(format!("{node_name}: a skinned mesh under a node scaled to zero"))),
        };
        let mut lights = 0;
        for prim in mesh.primitives() {
            let where_ =
                format!("meshes[{}] ('{}') primitives[{}]", mesh.index(), mesh.name().unwrap_or(""), prim.index());
            let mat = prim.material();
            let emissive = emission(&mat);
            let Some(mesh_index) = self.mesh(&mesh, &prim, &deform, &where_)? else {
                if emissive.max_element() > 0.0 {
                    return Err(self.error(format!("{where_}: emitter has zero area")));
                }
                continue;
            };
            let member = InGroup { group, local };
            let transform = Transform { world: pose * local };
            if emissive.max_element() > 0.0 {
                let texture = match mat.emissive_texture() {
                    Some(info) => Some(self.texture(&info.texture(), Channels::Srgb, &where_)?),
                    None => None,
                };
                let polys = self.light_polygons(mesh_index);
                if polys.is_empty() {
                    return Err(self.error(format!("{where_}: emitter has zero area")));
                }
                self.lights += polys.len();
                if self.lights > MAX_LIGHTS {
                    return Err(self.error(format!(
                        "{where_}: more than {MAX_LIGHTS} light polygons (kage's limit: every light is shaded at every vertex and pixel); its emitters split into {} with this node's",
                        self.lights
                    )));
                }
                let m = &self.scene.meshes[mesh_index as usize];
                let id = PrimitiveId { node: node_id, mesh: mesh.index() as u32, primitive: prim.index() as u32 };
                let mut spawned = Vec::with_capacity(polys.len());
                for (polygon, poly) in polys.iter().enumerate() {
                    let uvs = if texture.is_some() && !m.uvs.is_empty() {
                        poly.iter().map(|&i| m.uvs[i as usize]).collect()
                    } else {
                        vec![]
                    };
                    let points: Vec<Vec3> = poly.iter().map(|&i| m.positions[i as usize]).collect();
                    let world: Vec<Vec3> = points.iter().map(|p| transform.world.transform_point3(*p)).collect();
                    let reach = declared
                        .map(|d| reach::resolve(d, &world))
                        .transpose()
                        .map_err(|m| self.error(format!("{node_name}: {m}")))?;
                    let light = PolygonLight { points, uvs, radiance: emissive, texture, reach };
                    let emitter = Emitter { id, polygon: polygon as u32 };
                    spawned.push((light, member, transform, NodeId(node_id), emitter, node_label(node, node_id)));
                }
                lights += spawned.len();
                self.members += spawned.len();
                self.scene.world.spawn_batch(spawned);
            } else {
                let pbr = mat.pbr_metallic_roughness();
                let c = pbr.base_color_factor();
                let material = Material {
                    base_color: Vec3::new(c[0], c[1], c[2]),
                    metallic: pbr.metallic_factor().clamp(0.0, 1.0),
                    roughness: pbr.roughness_factor().clamp(0.0, 1.0),
                    specular: mat.specular().map(|s| s.specular_factor()).unwrap_or(1.0).max(0.0),
                };
                let maps = MaterialMaps {
                    base_color: self.slot(pbr.base_color_texture(), Channels::Srgb, &where_)?,
                    metallic_roughness: self.slot(pbr.metallic_roughness_texture(), Channels::Linear, &where_)?,
                    cutout: self.cutout(&mat, &where_)?,
                };
                let hash = self.scene.meshes[mesh_index as usize].hash;
                let id = PrimitiveId { node: node_id, mesh: mesh.index() as u32, primitive: prim.index() as u32 };
                let name = node_label(node, node_id);
                let entity = (MeshRef { index: mesh_index, hash }, material, member, transform, id, name);
                let e = self.scene.world.spawn(entity);
                if !maps.is_empty() {
                    self.scene.world.insert_one(e, maps).expect("the entity was just spawned");
                }
                self.members += 1;
            }
        }
        self.unused_reach(declared, lights, &node_name);
        Ok(())
    }

    /// The light polygons of imported mesh `index` (see [`light::polygons`]), split once.
    fn light_polygons(&mut self, index: u32) -> std::rc::Rc<[Vec<u32>]> {
        let meshes = &self.scene.meshes;
        self.light_polygons.entry(index).or_insert_with(|| light::polygons(&meshes[index as usize]).into()).clone()
    }

    /// Warns of a light reach declared on a node that has no light.
    fn unused_reach(&mut self, declared: Option<reach::Declared>, lights: usize, node: &str) {
        if declared.is_some() && lights == 0 {
            let w = format!("{}: {node}: extras.kage.light_reach ignored (no emissive primitive)", self.path.display());
            self.scene.warnings.push(w);
        }
    }

    /// Reads (or reuses) the mesh of one primitive, deformed as its node says; `None` when
    /// dropping degenerate triangles left it without a surface (skipped with a warning).
    fn mesh(
        &mut self,
        mesh: &gltf::Mesh,
        prim: &gltf::Primitive,
        deform: &deform::Deform,
        where_: &str,
    ) -> Result<Option<u32>> {
        let rigid = deform.is_rigid();
        if let Some(&i) = self.mesh_cache.get(&(mesh.index(), prim.index())).filter(|_| rigid) {
            return Ok(Some(i));
        }
        checks::attribute_formats(prim).map_err(|m| self.error(format!("{where_}: {m}")))?;
        let buffers = &self.buffers;
        let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]).filter(|d| !d.is_empty()));
        let mut positions: Vec<Vec3> = reader
            .read_positions()
            .ok_or_else(|| self.error(format!("{where_}: has no POSITION data")))?
            .map(Vec3::from_array)
            .collect();
        let normals = reader.read_normals().map(|n| n.map(Vec3::from_array).collect::<Vec<_>>());
        let mut normals = normals.filter(|n| n.len() == positions.len());
        if !rigid {
            deform
                .apply(&reader, prim, &mut positions, normals.as_mut())
                .map_err(|m| self.error(format!("{where_}: {m}")))?;
        }
        let uv_set = |set| reader.read_tex_coords(set).map(|t| t.into_f32().map(Vec2::from_array).collect());
        let (uvs, uvs1) = (uv_set(0).unwrap_or_default(), uv_set(1).unwrap_or_default());
        let colors = reader
            .read_colors(self.options.color_set)
            .map(|c| c.into_rgb_f32().map(Vec3::from_array).collect())
            .unwrap_or_default();
        let indices: Vec<u32> = match reader.read_indices() {
            Some(i) => i.into_u32().collect(),
            None => (0..positions.len() as u32).collect(),
        };
        let triangles = match prim.mode() {
            Mode::Triangles => indices.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            Mode::TriangleStrip => (2..indices.len())
                .map(|i| {
                    if i % 2 == 0 {
                        [indices[i - 2], indices[i - 1], indices[i]]
                    } else {
                        [indices[i - 1], indices[i - 2], indices[i]]
                    }
                })
                .collect(),
            Mode::TriangleFan => (2..indices.len()).map(|i| [indices[0], indices[i - 1], indices[i]]).collect(),
            other => {
                return Err(self.error(format!(
                    "{where_}: primitive mode {other:?} has no surface; only triangles are supported"
                )));
            }
        };
        let drop = self.options.drop_degenerate;
        let (m, dropped) = match Mesh::new(positions, normals, uvs, triangles, drop) {
            Ok(mesh) => mesh,
            Err(MeshProblem::Empty) if drop => {
                let warning = format!(
                    "{}: {where_}: no surface left after dropping degenerate triangles; skipped",
                    self.path.display()
                );
                self.scene.warnings.push(warning);
                return Ok(None);
            }
            Err(p) => return Err(self.error(format!("{where_}: {p}"))),
        };
        let m = m.with_attributes(uvs1, colors);
        if dropped > 0 {
            self.scene
                .warnings
                .push(format!("{}: {where_}: dropped {dropped} degenerate triangles", self.path.display()));
        }
        let index = match self.by_hash.get(&m.hash) {
            Some(&i) => i,
            None => {
                let i = self.scene.meshes.len() as u32;
                self.by_hash.insert(m.hash, i);
                self.scene.meshes.push(Arc::new(m));
                i
            }
        };
        if rigid {
            self.mesh_cache.insert((mesh.index(), prim.index()), index);
        }
        Ok(Some(index))
    }

    /// A material's cut-out when its `alphaMode` is `MASK` (`BLEND` is drawn opaque, with a
    /// warning: kage has no translucency).
    fn cutout(&mut self, mat: &gltf::Material, where_: &str) -> Result<Option<Cutout>> {
        match mat.alpha_mode() {
            gltf::material::AlphaMode::Opaque => Ok(None),
            gltf::material::AlphaMode::Blend => {
                let w = format!("{}: {where_}: alphaMode BLEND is drawn opaque", self.path.display());
                self.scene.warnings.push(w);
                Ok(None)
            }
            gltf::material::AlphaMode::Mask => {
                let pbr = mat.pbr_metallic_roughness();
                let alpha = self.slot(pbr.base_color_texture(), Channels::Alpha, where_)?;
                let cutoff = mat.alpha_cutoff().unwrap_or(0.5);
                if !cutoff.is_finite() {
                    return Err(self.error(format!("{where_}: alphaCutoff {cutoff} is not a number")));
                }
                Ok(Some(Cutout { alpha, factor: pbr.base_color_factor()[3], cutoff }))
            }
        }
    }

    /// A material texture's slot: texture (its channels decoded as `channels` says), UV set
    /// and `KHR_texture_transform`.
    fn slot(
        &mut self,
        info: Option<gltf::texture::Info>,
        channels: Channels,
        where_: &str,
    ) -> Result<Option<TextureSlot>> {
        let Some(info) = info else { return Ok(None) };
        let texture = self.texture(&info.texture(), channels, where_)?;
        let t = info.texture_transform();
        let texcoord = t.as_ref().and_then(|t| t.tex_coord()).unwrap_or(info.tex_coord());
        if texcoord > 1 {
            return Err(self.error(format!("{where_}: a texture reads TEXCOORD_{texcoord}; kage reads sets 0 and 1")));
        }
        let transform = t.map_or(Affine2::IDENTITY, |t| {
            texture_transform(Vec2::from(t.offset()), t.rotation(), Vec2::from(t.scale()))
        });
        Ok(Some(TextureSlot { texture, texcoord, transform }))
    }

    /// Decodes (or reuses) a texture as linear values, as `channels` says.
    fn texture(&mut self, tex: &gltf::Texture, channels: Channels, where_: &str) -> Result<u32> {
        if let Some(&i) = self.texture_cache.get(&(tex.index(), channels)) {
            return Ok(i);
        }
        let image = self
            .image(tex.source().source())
            .map_err(|e| self.error(format!("{where_}: texture {}: {e}", tex.index())))?;
        let wrap = |m: gltf::texture::WrappingMode| match m {
            gltf::texture::WrappingMode::ClampToEdge => Wrap::Clamp,
            gltf::texture::WrappingMode::MirroredRepeat => Wrap::Mirror,
            gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
        };
        let sampler = tex.sampler();
        let t = texture_from_image(&image, channels, [wrap(sampler.wrap_s()), wrap(sampler.wrap_t())]);
        let i = self.scene.textures.len() as u32;
        self.scene.textures.push(Arc::new(t));
        self.texture_cache.insert((tex.index(), channels), i);
        Ok(i)
    }
}

/// Which of an image's channels a texture holds, and how they are decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Channels {
    /// RGB, decoded from sRGB to linear (colours).
    Srgb,
    /// RGB as is (data: metallic-roughness).
    Linear,
    /// The alpha channel as is, in all three components (a cut-out's mask).
    Alpha,
}

/// An 8-bit image as a linear texture of the `channels` it names.
fn texture_from_image(image: &image::RgbaImage, channels: Channels, wrap: [Wrap; 2]) -> Texture {
    let unit = |c: u8| c as f32 / 255.0;
    let texel = |p: &image::Rgba<u8>| match channels {
        Channels::Srgb => Vec3::from([p.0[0], p.0[1], p.0[2]].map(|c| crate::math::color::srgb_to_linear(unit(c)))),
        Channels::Linear => Vec3::from([p.0[0], p.0[1], p.0[2]].map(unit)),
        Channels::Alpha => Vec3::splat(unit(p.0[3])),
    };
    let texels: Vec<Vec3> = image.pixels().map(texel).collect();
    Texture::new(image.width() as usize, image.height() as usize, texels, wrap)
}

/// A node's name as kage shows it: its glTF name, or `node<index>`.
fn node_label(node: &gltf::Node, node_id: u32) -> Name {
    Name(node.name().map(str::to_string).unwrap_or_else(|| format!("node{node_id}")))
}

/// A PNG or JPEG file's bytes as a linear texture (see [`texture_from_image`]), with the
/// importer's size limits.
pub fn decode_texture(bytes: &[u8], channels: Channels, wrap: [Wrap; 2]) -> std::result::Result<Texture, String> {
    Ok(texture_from_image(&decode_image(bytes)?, channels, wrap))
}

/// `KHR_texture_transform`'s `T · R · S` (rotation counter-clockwise in UV space, as the
/// extension's own example — the lower-left quadrant turned clockwise — reads).
pub fn texture_transform(offset: Vec2, rotation: f32, scale: Vec2) -> Affine2 {
    let (s, c) = rotation.sin_cos();
    Affine2::from_cols(Vec2::new(c, -s) * scale.x, Vec2::new(s, c) * scale.y, offset)
}

/// The folder relative URIs in the scene file at `path` start from.
fn base_dir(path: &Path) -> &Path {
    path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."))
}

/// Every buffer's bytes: from its URI through `root` (exactly `byteLength` of them), the GLB
/// binary chunk, or zeros for buffer `zeros` ([`checks::zero_accessors`]); padded to a
/// multiple of 4 as the gltf crate pads them. A buffer with no URI outside a GLB has no data
/// (empty): legal until an accessor that is used reads it.
fn load_buffers(
    doc: &gltf::Document,
    base: &Path,
    root: &files::Root,
    mut blob: Option<Vec<u8>>,
    zeros: Option<usize>,
) -> std::result::Result<Vec<gltf::buffer::Data>, String> {
    doc.buffers()
        .map(|b| {
            let at = |e: String| format!("buffers[{}]: {e}", b.index());
            let mut data = match b.source() {
                _ if Some(b.index()) == zeros => vec![0; b.length()],
                gltf::buffer::Source::Uri(uri) => root.read_exact(base, uri, b.length() as u64).map_err(at)?,
                gltf::buffer::Source::Bin => match blob.take() {
                    Some(bin) => bin,
                    None => return Ok(gltf::buffer::Data(Vec::new())),
                },
            };
            if data.len() < b.length() {
                return Err(at(format!("{} bytes where byteLength declares {}", data.len(), b.length())));
            }
            data.resize(data.len().next_multiple_of(4), 0);
            Ok(gltf::buffer::Data(data))
        })
        .collect()
}

/// An image file's bytes decoded as 8-bit RGBA (opaque where it has no alpha), with the
/// decoder's size limits set so that a small file cannot ask for a huge allocation.
fn decode_image(bytes: &[u8]) -> std::result::Result<image::RgbaImage, String> {
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| format!("cannot read image: {e}"))?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(16_384);
    limits.max_image_height = Some(16_384);
    limits.max_alloc = Some(1 << 30);
    reader.limits(limits);
    Ok(reader.decode().map_err(|e| format!("cannot decode image: {e}"))?.to_rgba8())
}

fn node_matrix(node: &gltf::Node) -> Option<Affine3A> {
    let m = Mat4::from_cols_array_2d(&node.transform().matrix());
    m.is_finite().then(|| Affine3A::from_mat4(m))
}

/// Removes scale (and shear) from a camera's pose, keeping position and orientation.
fn orthonormalize(m: Affine3A) -> Affine3A {
    let z = Vec3::from(m.matrix3.z_axis).normalize_or(Vec3::Z);
    let y0 = Vec3::from(m.matrix3.y_axis);
    let x = y0.cross(z).normalize_or(Vec3::X);
    let y = z.cross(x);
    Affine3A::from_cols(x.into(), y.into(), z.into(), m.translation)
}

fn describe(e: &gltf::Error) -> String {
    match e {
        gltf::Error::Validation(list) => {
            list.iter().map(|(path, err)| format!("{path}: {err}")).collect::<Vec<_>>().join("; ")
        }
        other => other.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The extension's own example: offset (0, 1), rotation 90°, scale ½ reads the lower-left
    /// quadrant of the image (v down) turned clockwise.
    #[test]
    fn texture_transform_reads_the_specs_example() {
        let t = texture_transform(Vec2::new(0.0, 1.0), std::f32::consts::FRAC_PI_2, Vec2::splat(0.5));
        let corners = [Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y].map(|uv| t.transform_point2(uv));
        for c in corners {
            assert!((-1e-6..=0.5 + 1e-6).contains(&c.x) && (0.5 - 1e-6..=1.0 + 1e-6).contains(&c.y), "{c}");
        }
        assert!((corners[1] - Vec2::new(0.0, 0.5)).length() < 1e-6, "u turns toward the top: {}", corners[1]);
        let plain = texture_transform(Vec2::ZERO, 0.0, Vec2::ONE);
        assert_eq!(plain, Affine2::IDENTITY);
    }
}
