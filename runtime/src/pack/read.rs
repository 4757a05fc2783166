//! Reading a pack at run time: the GLB container, the glTF nodes, meshes and accessors as kage
//! writes them, and the extension's records — the integrity (version 4 on) verified and every
//! number range-checked before anything is sized by it. The result, [`Pack`], is plain data:
//! groups with their poses, instances with their meshes, real materials and bakes, lights, the
//! camera, the textures' images and the environment.

use super::{EXTENSION, SEALED, VERSIONS, integrity, ranges, schema};
use crate::bspvt::{BakedInstance, layout};
use crate::camera::{Camera, Projection};
use crate::light::FlatLight;
use crate::math::equirect;
use crate::texture::Wrap;
use glam::{Affine3A, Mat4, Quat, Vec2, Vec3};
use serde::Deserialize;
use serde::de::DeserializeOwned;
use std::collections::BTreeMap;

/// What went wrong, for the reader to prefix with the file's name.
pub type Checked<T> = Result<T, String>;

/// A pack's contents.
pub struct Pack {
    /// The root record: the bakes' settings, the environment's header, the preview exposure.
    pub header: schema::Root,
    /// The rigid groups (the scene's root nodes), in their index order.
    pub groups: Vec<Group>,
    /// The mesh instances, in the snapshot's order (the bakes' order).
    pub instances: Vec<Instance>,
    /// The polygonal lights, in the order they were written.
    pub lights: Vec<Light>,
    /// The camera, if the pack has one.
    pub camera: Option<Camera>,
    /// The core glTF textures: their images' bytes and wrap modes.
    pub textures: Vec<Texture>,
    /// The environment's texels, if the pack has an environment.
    pub environment: Option<Environment>,
    /// What a reader should tell the user (the pack still shades).
    pub warnings: Vec<String>,
}

/// A rigid group: a root node with the instances and lights that move with it.
pub struct Group {
    /// Its node's name.
    pub name: String,
    /// World from group.
    pub pose: Affine3A,
}

/// A mesh's vertices and triangles, as the bakes index them.
#[derive(Default)]
pub struct Mesh {
    /// Positions (the instance's frame).
    pub positions: Vec<Vec3>,
    /// Unit normals.
    pub normals: Vec<Vec3>,
    /// `TEXCOORD_0` (empty when absent).
    pub uvs: Vec<Vec2>,
    /// `TEXCOORD_1` (empty when absent).
    pub uvs1: Vec<Vec2>,
    /// The source's vertex colours, `COLOR_1` (empty when absent).
    pub colors: Vec<Vec3>,
    /// Counter-clockwise triangles.
    pub triangles: Vec<[u32; 3]>,
}

/// A mesh instance with its material and bakes.
pub struct Instance {
    /// Its node's name.
    pub name: String,
    /// Index into [`Pack::groups`].
    pub group: usize,
    /// Group from instance.
    pub local: Affine3A,
    /// Its geometry.
    pub mesh: Mesh,
    /// The real material (the preview's replaced it in the core glTF).
    pub material: schema::Material,
    /// The baked look per vertex (linear radiance): the preview before its exposure.
    pub radiance: Vec<Vec3>,
    /// The bounces' light per vertex at the bake's placement (irradiance over π), if stored.
    pub bounce: Option<Vec<Vec3>>,
    /// Per vertex, whether it lies inside geometry (all `false` when the pack names none).
    pub inside: Vec<bool>,
    /// BSPVT's vertex records.
    pub bspvt: Option<BakedInstance>,
    /// PRT's transfer, n² per vertex.
    pub transfer: Option<Vec<f32>>,
}

/// A polygonal light.
pub struct Light {
    /// Its node's name.
    pub name: String,
    /// Index into [`Pack::groups`].
    pub group: usize,
    /// Group from light.
    pub local: Affine3A,
    /// The polygon in the light's frame.
    pub polygon: Vec<Vec3>,
    /// Emitted radiance.
    pub radiance: Vec3,
    /// The world box it promises to stay inside, if declared.
    pub reach: Option<[Vec3; 2]>,
    /// Texture coordinates per corner (textured lights only).
    pub uvs: Vec<Vec2>,
    /// Its emissive texture: an index into [`Pack::textures`].
    pub texture: Option<usize>,
}

impl Light {
    /// The light in the world, its group posed at `pose` (`None` when it has no area).
    pub fn placed(&self, pose: &Affine3A) -> Option<FlatLight> {
        let mut flat = FlatLight::placed(&self.polygon, &self.uvs, &(*pose * self.local), self.radiance)?;
        flat.reach = self.reach;
        Some(flat)
    }
}

/// A core glTF texture.
pub struct Texture {
    /// The image's encoded bytes.
    pub image: Vec<u8>,
    /// Its MIME type (kage writes `image/png`).
    pub mime_type: String,
    /// Wrap along u and v.
    pub wrap: [Wrap; 2],
}

/// The environment map.
pub struct Environment {
    /// Width in texels.
    pub width: usize,
    /// Height in texels.
    pub height: usize,
    /// Linear RGB, row 0 toward +Y.
    pub texels: Vec<Vec3>,
    /// Radiance multiplier.
    pub intensity: f32,
    /// Rotation about +Y, radians.
    pub rotation: f32,
}

impl Environment {
    /// What a camera sees along world direction `dir`: the map filtered bilinearly, turned
    /// and scaled as the light is.
    pub fn background(&self, dir: Vec3) -> Vec3 {
        let uv = equirect::dir_to_uv(Quat::from_rotation_y(-self.rotation) * dir);
        equirect::bilinear(self.width, self.height, &self.texels, uv) * self.intensity
    }
}

impl Pack {
    /// Reads a pack's bytes: its integrity verified before anything else is read, every count
    /// checked against the data present and every number against its range.
    pub fn read(bytes: &[u8]) -> Checked<Self> {
        let glb = super::glb::split(bytes)?;
        let doc: Document = serde_json::from_slice(glb.json).map_err(|e| format!("glTF JSON: {e}"))?;
        let views = integrity::buffer_views(glb.json)?;
        let header: schema::Root =
            extension(doc.extensions.as_ref())?.ok_or_else(|| format!("no {EXTENSION} extension"))?;
        if !VERSIONS.contains(&header.version) {
            return Err(format!("{EXTENSION} version {} (this kage reads {VERSIONS:?})", header.version));
        }
        let mut warnings = Vec::new();
        match &header.integrity {
            Some(record) => integrity::check_json(glb.json, record)?,
            None if header.version >= SEALED => {
                return Err(format!("version {} without its integrity record", header.version));
            }
            None => warnings.push(format!(
                "a version {} pack carries no checksums: its numbers are range-checked only",
                header.version
            )),
        }
        let reader = Reader { doc: &doc, views: &views, bin: glb.bin };
        let records = reader.records()?;
        if let Some(record) = &header.integrity {
            integrity::check_views(&views, glb.bin, record, |v| reader.view_name(v, &header, &records))?;
        }
        ranges::root(&header)?;
        ranges::records(&records.instances, &records.lights)?;
        let mut pack = reader.scene(&records)?;
        pack.environment = header.environment.as_ref().map(|e| reader.environment(e)).transpose()?;
        if let Some(h) = &header.bspvt {
            reader.bspvt(h, &records.instances, &mut pack.instances)?;
            if h.format < layout::FORMAT_VERSION {
                warnings.push(
                    "its BSPVT records are format 1, without the occluders' depth: a light inside a closed room \
                     shades dark as it did when the pack was written; export the scene again"
                        .into(),
                );
            }
        }
        if let Some(h) = &header.prt {
            reader.prt(h, &records.instances, &mut pack.instances)?;
        }
        pack.warnings = warnings;
        pack.header = header;
        Ok(pack)
    }
}

/// The extension's records of every mesh's first primitive, by kind, in mesh order (which is
/// the order kage writes them: instances, then lights).
struct Records {
    instances: Vec<schema::Instance>,
    lights: Vec<schema::Light>,
    /// Mesh index → instance (`Ok`) or light (`Err`) record index.
    of_mesh: BTreeMap<usize, Result<usize, usize>>,
}

/// The `KAGE_baked_shadows` entry of an `extensions` object, as record `T`.
fn extension<T: DeserializeOwned>(others: Option<&serde_json::Map<String, serde_json::Value>>) -> Checked<Option<T>> {
    let Some(value) = others.and_then(|o| o.get(EXTENSION)) else { return Ok(None) };
    T::deserialize(value).map(Some).map_err(|e| format!("{EXTENSION}: {e}"))
}

/// A declared count as `usize` (saturating: every count is checked against the data present).
fn count(n: u64) -> usize {
    usize::try_from(n).unwrap_or(usize::MAX)
}

/// Little-endian 4-byte words.
fn words<T>(bytes: &[u8], from: fn([u8; 4]) -> T) -> Vec<T> {
    bytes.chunks_exact(4).map(|b| from(b.try_into().expect("chunks of 4"))).collect()
}

/// A pack's document, its buffer views and its binary chunk.
struct Reader<'a> {
    doc: &'a Document,
    views: &'a [integrity::View],
    bin: &'a [u8],
}

impl Reader<'_> {
    /// The bytes of buffer view `index`, if it lies inside the binary chunk.
    fn view(&self, index: usize) -> Checked<&[u8]> {
        if index >= self.views.len() {
            return Err(format!("no buffer view {index}"));
        }
        integrity::view(self.views, self.bin, index)
            .ok_or_else(|| format!("buffer view {index} lies outside the binary chunk"))
    }

    /// The extension records of every mesh.
    fn records(&self) -> Checked<Records> {
        let mut r = Records { instances: Vec::new(), lights: Vec::new(), of_mesh: BTreeMap::new() };
        for (m, mesh) in self.doc.meshes.iter().enumerate() {
            let others = mesh.primitives.first().and_then(|p| p.extensions.as_ref());
            let Some(value) = others.and_then(|o| o.get(EXTENSION)) else { continue };
            let named = |e: serde_json::Error| format!("mesh {m}: {EXTENSION}: {e}");
            if value.get("lightRadiance").is_some() {
                r.of_mesh.insert(m, Err(r.lights.len()));
                r.lights.push(schema::Light::deserialize(value).map_err(named)?);
            } else {
                r.of_mesh.insert(m, Ok(r.instances.len()));
                r.instances.push(schema::Instance::deserialize(value).map_err(named)?);
            }
        }
        Ok(r)
    }

    /// What buffer view `v` holds, for messages: the extension's field or the core glTF's
    /// attribute, indices or image that reads it.
    fn view_name(&self, v: usize, root: &schema::Root, records: &Records) -> String {
        let is = |x: u32| x as usize == v;
        for (k, r) in records.instances.iter().enumerate() {
            let field = if is(r.radiance) {
                "radiance"
            } else if r.bounce.is_some_and(is) {
                "bounce"
            } else if r.inside.is_some_and(is) {
                "inside"
            } else if r.bspvt.as_ref().is_some_and(|b| is(b.offsets)) {
                "bspvt.offsets"
            } else if r.bspvt.as_ref().is_some_and(|b| is(b.records)) {
                "bspvt.records"
            } else if r.prt.as_ref().is_some_and(|p| is(p.transfer)) {
                "prt.transfer"
            } else {
                continue;
            };
            return format!("instance {k}'s {EXTENSION} {field}");
        }
        if root.environment.as_ref().is_some_and(|e| is(e.texels)) {
            return format!("the {EXTENSION} environment.texels");
        }
        let accessor = |a: &usize| self.doc.accessors.get(*a).and_then(|a| a.buffer_view) == Some(v);
        for (m, mesh) in self.doc.meshes.iter().enumerate() {
            for p in &mesh.primitives {
                if let Some((name, _)) = p.attributes.iter().find(|(_, a)| accessor(a)) {
                    return format!("mesh {m}'s {name}");
                }
                if p.indices.as_ref().is_some_and(accessor) {
                    return format!("mesh {m}'s indices");
                }
            }
        }
        match self.doc.images.iter().position(|i| i.buffer_view == Some(v)) {
            Some(i) => format!("image {i}"),
            None => "data".into(),
        }
    }

    /// Groups, instances, lights and camera, walking the scene's nodes, and the textures.
    fn scene(&self, records: &Records) -> Checked<Pack> {
        let doc = self.doc;
        let scene = doc.scenes.get(doc.scene.unwrap_or(0)).ok_or("no scene")?;
        let mut pack = Pack {
            header: empty_root(),
            groups: Vec::new(),
            instances: Vec::new(),
            lights: Vec::new(),
            camera: None,
            textures: self.textures()?,
            environment: None,
            warnings: Vec::new(),
        };
        for &root in &scene.nodes {
            let node = doc.nodes.get(root).ok_or_else(|| format!("scene: no node {root}"))?;
            let pose = node.transform().map_err(|e| format!("node {root}: {e}"))?;
            if let Some(c) = node.camera {
                pack.camera = Some(self.camera(c, pose)?);
                continue;
            }
            let group = pack.groups.len();
            pack.groups.push(Group { name: node.name.clone().unwrap_or_default(), pose });
            for &child in &node.children {
                self.member(&mut pack, records, group, child).map_err(|e| format!("node {child}: {e}"))?;
            }
        }
        if pack.instances.len() != records.instances.len() || pack.lights.len() != records.lights.len() {
            return Err("a baked mesh is not a member of any group".into());
        }
        Ok(pack)
    }

    /// A group's member node: an instance (in the snapshot's order) or a light.
    fn member(&self, pack: &mut Pack, records: &Records, group: usize, index: usize) -> Checked<()> {
        let node = self.doc.nodes.get(index).ok_or("no such node")?;
        let (local, name) = (node.transform()?, node.name.clone().unwrap_or_default());
        let mesh = node.mesh.ok_or("a group's member without a mesh")?;
        let primitive = self.doc.meshes.get(mesh).and_then(|m| m.primitives.first()).ok_or("no such mesh")?;
        let place = Place { name, group, local };
        match records.of_mesh.get(&mesh) {
            None => Err(format!("mesh {mesh} carries no {EXTENSION} record")),
            Some(&Ok(k)) if k != pack.instances.len() => Err(format!("instance {k} out of order")),
            Some(&Ok(k)) => {
                let instance = self.instance(&records.instances[k], primitive, place)?;
                pack.instances.push(instance);
                Ok(())
            }
            Some(&Err(k)) => {
                let light = self.light(&records.lights[k], primitive, place)?;
                pack.lights.push(light);
                Ok(())
            }
        }
    }

    /// An instance: its mesh from the core accessors, its material and preview radiance from
    /// its record (the bakes are read once every instance is).
    fn instance(&self, record: &schema::Instance, p: &Primitive, at: Place) -> Checked<Instance> {
        let positions: Vec<Vec3> = self.floats(p.attribute("POSITION")?)?;
        let n = positions.len();
        let optional = |semantic: &str| p.attributes.get(semantic).map(|&a| self.floats(a)).transpose();
        let mesh = Mesh {
            normals: self.floats(p.attribute("NORMAL")?)?,
            uvs: optional("TEXCOORD_0")?.unwrap_or_default(),
            uvs1: optional("TEXCOORD_1")?.unwrap_or_default(),
            colors: p.attributes.get("COLOR_1").map(|&a| self.floats(a)).transpose()?.unwrap_or_default(),
            triangles: self.triangles(p, n)?,
            positions,
        };
        let optional_lengths = [mesh.uvs.len(), mesh.uvs1.len(), mesh.colors.len()];
        if mesh.normals.len() != n || optional_lengths.iter().any(|&l| l != 0 && l != n) {
            return Err(format!("attributes of other lengths than its {n} positions"));
        }
        let radiance = vec3s(&words(self.view(record.radiance as usize)?, f32::from_le_bytes));
        if radiance.len() != n || radiance.iter().any(|r| !r.is_finite()) {
            return Err(format!("{EXTENSION} radiance: not {n} finite RGB triples"));
        }
        let bounce = record.bounce.map(|v| self.view(v as usize)).transpose()?;
        let bounce = bounce.map(|view| vec3s(&words(view, f32::from_le_bytes)));
        if bounce.as_ref().is_some_and(|b| b.len() != n || b.iter().any(|l| !l.is_finite() || l.min_element() < 0.0)) {
            return Err(format!("{EXTENSION} bounce: not {n} finite RGB triples ≥ 0"));
        }
        let mut inside = vec![false; n];
        if let Some(view) = record.inside.map(|v| self.view(v as usize)).transpose()? {
            let indices = words(view, u32::from_le_bytes);
            if !indices.is_sorted_by(|a, b| a < b) || indices.last().is_some_and(|&v| v as usize >= n) {
                return Err(format!("{EXTENSION} inside: not ascending vertex indices below {n}"));
            }
            indices.iter().for_each(|&v| inside[v as usize] = true);
        }
        let material = record.material.clone();
        Ok(Instance {
            name: at.name,
            group: at.group,
            local: at.local,
            mesh,
            material,
            radiance,
            bounce,
            inside,
            bspvt: None,
            transfer: None,
        })
    }

    /// A light: its exact polygon, radiance, UVs and reach from its record.
    fn light(&self, r: &schema::Light, p: &Primitive, at: Place) -> Checked<Light> {
        let polygon = vec3s(&r.light_polygon);
        if polygon.len() < 3 || r.light_polygon.len() != 3 * polygon.len() {
            return Err("a light polygon is not 3 or more corners of 3 numbers".into());
        }
        let uvs: Vec<Vec2> =
            r.light_uvs.iter().flatten().copied().collect::<Vec<f32>>().chunks_exact(2).map(Vec2::from_slice).collect();
        let reach = match r.light_reach {
            None => None,
            Some([a, b, c, d, e, f]) if a <= d && b <= e && c <= f => Some([Vec3::new(a, b, c), Vec3::new(d, e, f)]),
            Some(_) => return Err("a light reach is not 6 finite numbers, min ≤ max".into()),
        };
        let material = p.material.and_then(|m| self.doc.materials.get(m));
        let texture = material.and_then(|m| m.emissive_texture.as_ref()).map(|t| t.index);
        if texture.is_some_and(|t| t >= self.doc.textures.len() || uvs.len() != polygon.len()) {
            return Err("a textured light's texture or UVs do not match its polygon".into());
        }
        let radiance = Vec3::from_array(r.light_radiance);
        Ok(Light { name: at.name, group: at.group, local: at.local, polygon, radiance, reach, uvs, texture })
    }

    /// Accessor `a` as float vectors `T`, tightly packed, every number finite.
    fn floats<T: Floats>(&self, a: usize) -> Checked<Vec<T>> {
        let values = words(self.accessor(a, T::TYPE, FLOAT)?, f32::from_le_bytes);
        if values.iter().any(|x| !x.is_finite()) {
            return Err(format!("accessor {a} holds a number that is not finite"));
        }
        Ok(values.chunks_exact(T::WIDTH).map(T::from_floats).collect())
    }

    /// The primitive's u32 triangle list, every index below `n`.
    fn triangles(&self, p: &Primitive, n: usize) -> Checked<Vec<[u32; 3]>> {
        let a = p.indices.ok_or("a primitive without indices")?;
        let indices = words(self.accessor(a, "SCALAR", UNSIGNED_INT)?, u32::from_le_bytes);
        if indices.len() % 3 != 0 || indices.iter().any(|&i| i as usize >= n) {
            return Err(format!("accessor {a}: not a triangle list over {n} vertices"));
        }
        Ok(indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect())
    }

    /// Accessor `a`'s bytes, checked to be `type_` of `component` and to lie in its view.
    fn accessor(&self, a: usize, type_: &str, component: u32) -> Checked<&[u8]> {
        let acc = self.doc.accessors.get(a).ok_or_else(|| format!("no accessor {a}"))?;
        if acc.type_ != type_ || acc.component_type != component || acc.sparse.is_some() {
            return Err(format!(
                "accessor {a} is {} of component type {}: kage packs hold {type_} of {component}, not sparse",
                acc.type_, acc.component_type
            ));
        }
        let width = 4 * match type_ {
            "VEC3" => 3,
            "VEC2" => 2,
            _ => 1,
        };
        let view = self.view(acc.buffer_view.ok_or_else(|| format!("accessor {a} has no buffer view"))?)?;
        let start = count(acc.byte_offset);
        let end = count(acc.count).checked_mul(width).and_then(|len| start.checked_add(len));
        end.and_then(|end| view.get(start..end)).ok_or_else(|| format!("accessor {a} reaches past its buffer view"))
    }

    /// Camera `c`, placed at `world`.
    fn camera(&self, c: usize, world: Affine3A) -> Checked<Camera> {
        let cam = self.doc.cameras.get(c).ok_or_else(|| format!("no camera {c}"))?;
        let projection = match (&cam.perspective, &cam.orthographic) {
            (Some(p), _) if p.yfov > 0.0 && p.yfov < std::f32::consts::PI => Projection::Perspective { yfov: p.yfov },
            (None, Some(o)) if o.ymag > 0.0 && o.ymag.is_finite() => Projection::Orthographic { ymag: o.ymag },
            _ => return Err(format!("camera {c}: not a perspective (0 < yfov < π) or orthographic camera")),
        };
        Ok(Camera { world, projection })
    }

    /// Every core texture's image bytes and wrap modes.
    fn textures(&self) -> Checked<Vec<Texture>> {
        let doc = self.doc;
        let texture = |t: usize, texture: &TextureRef| -> Checked<Texture> {
            let image = texture.source.and_then(|s| doc.images.get(s)).ok_or("no image")?;
            let view = image.buffer_view.ok_or("no image data in the pack")?;
            let sampler = texture.sampler.and_then(|s| doc.samplers.get(s));
            let wrap = |w: Option<u32>| match w {
                Some(CLAMP_TO_EDGE) => Wrap::Clamp,
                Some(MIRRORED_REPEAT) => Wrap::Mirror,
                _ => Wrap::Repeat,
            };
            Ok(Texture {
                image: self.view(view).map_err(|e| format!("texture {t}: {e}"))?.to_vec(),
                mime_type: image.mime_type.clone().unwrap_or_default(),
                wrap: [wrap(sampler.and_then(|s| s.wrap_s)), wrap(sampler.and_then(|s| s.wrap_t))],
            })
        };
        doc.textures.iter().enumerate().map(|(t, x)| texture(t, x).map_err(|e| format!("texture {t}: {e}"))).collect()
    }

    /// The environment map's exact texels.
    fn environment(&self, env: &schema::Environment) -> Checked<Environment> {
        let bytes = self.view(env.texels as usize).map_err(|e| format!("environment: {e}"))?;
        let (width, height) = (count(env.width), count(env.height));
        if width == 0 || width.checked_mul(height).and_then(|n| n.checked_mul(12)) != Some(bytes.len()) {
            return Err(format!("environment: {} bytes of texels for {width}×{height}", bytes.len()));
        }
        let texels = vec3s(&words(bytes, f32::from_le_bytes));
        if texels.iter().any(|t| !(t.is_finite() && t.min_element() >= 0.0)) {
            return Err("environment.texels: a texel is not a finite radiance ≥ 0".into());
        }
        Ok(Environment { width, height, texels, intensity: env.intensity, rotation: env.rotation })
    }

    /// Every instance's BSPVT offsets and records, checked record by record.
    fn bspvt(&self, h: &schema::BspvtHeader, records: &[schema::Instance], into: &mut [Instance]) -> Checked<()> {
        if !(1..=layout::FORMAT_VERSION).contains(&h.format) {
            return Err(format!("BSPVT record format {} (this kage reads 1..={})", h.format, layout::FORMAT_VERSION));
        }
        let res = count(h.face_resolution);
        for (k, (inst, r)) in into.iter_mut().zip(records).enumerate() {
            let data = r.bspvt.as_ref().ok_or_else(|| format!("mesh {k}: no BSPVT data"))?;
            let offsets = words(self.view(data.offsets as usize)?, u32::from_le_bytes);
            let bytes = self.view(data.records as usize)?;
            let ok = offsets.len() == inst.mesh.positions.len() + 1
                && offsets.last().is_some_and(|&o| o as usize == bytes.len())
                && offsets.windows(2).all(|w| w[0] <= w[1]);
            if !ok {
                return Err(format!("mesh {k}: BSPVT data does not match the mesh"));
            }
            let baked = BakedInstance { offsets, data: bytes.to_vec() };
            for v in 0..baked.vertices() {
                layout::check_record(baked.record(v), res)
                    .map_err(|e| format!("mesh {k}, vertex {v}: malformed BSPVT record: {e}"))?;
            }
            inst.bspvt = Some(baked);
        }
        Ok(())
    }

    /// Every instance's PRT transfer: n² floats per vertex, each within its band's bound.
    fn prt(&self, h: &schema::PrtHeader, records: &[schema::Instance], into: &mut [Instance]) -> Checked<()> {
        let order = count(h.order);
        let sunless = h.sunless.as_ref().map(|s| &s.lighting);
        for light in std::iter::once(&h.lighting).chain(sunless) {
            if order == 0 || order.checked_mul(order) != Some(light.len()) {
                return Err(format!("PRT: {} lighting coefficients for order {order}", light.len()));
            }
        }
        for (k, (inst, r)) in into.iter_mut().zip(records).enumerate() {
            let data = r.prt.as_ref().ok_or_else(|| format!("mesh {k}: no PRT transfer"))?;
            let transfer = words(self.view(data.transfer as usize)?, f32::from_le_bytes);
            if transfer.len() != inst.mesh.positions.len() * order * order {
                return Err(format!("mesh {k}: PRT transfer does not match the mesh"));
            }
            ranges::transfer(k, order, &transfer)?;
            inst.transfer = Some(transfer);
        }
        Ok(())
    }
}

/// Where a member node sits: its name, group and group-relative transform.
struct Place {
    name: String,
    group: usize,
    local: Affine3A,
}

/// Floats in threes.
fn vec3s(x: &[f32]) -> Vec<Vec3> {
    x.chunks_exact(3).map(Vec3::from_slice).collect()
}

/// A root record with nothing in it (replaced once the pack is read).
fn empty_root() -> schema::Root {
    schema::Root { version: 0, preview_exposure: 0.0, bspvt: None, prt: None, environment: None, integrity: None }
}

/// glTF's `FLOAT` component type.
const FLOAT: u32 = 5126;
/// glTF's `UNSIGNED_INT` component type.
const UNSIGNED_INT: u32 = 5125;
/// glTF's `CLAMP_TO_EDGE` wrap mode.
const CLAMP_TO_EDGE: u32 = 33071;
/// glTF's `MIRRORED_REPEAT` wrap mode.
const MIRRORED_REPEAT: u32 = 33648;

/// A float vector type an accessor holds.
trait Floats: Sized {
    /// The accessor's `type`.
    const TYPE: &'static str;
    /// Floats per element.
    const WIDTH: usize;
    /// One element from `WIDTH` floats.
    fn from_floats(x: &[f32]) -> Self;
}

impl Floats for Vec3 {
    const TYPE: &'static str = "VEC3";
    const WIDTH: usize = 3;
    fn from_floats(x: &[f32]) -> Self {
        Vec3::from_slice(x)
    }
}

impl Floats for Vec2 {
    const TYPE: &'static str = "VEC2";
    const WIDTH: usize = 2;
    fn from_floats(x: &[f32]) -> Self {
        Vec2::from_slice(x)
    }
}

/// The glTF document as far as a pack uses it (everything else is ignored).
#[derive(Deserialize, Default)]
#[serde(default)]
struct Document {
    scene: Option<usize>,
    scenes: Vec<SceneRoots>,
    nodes: Vec<Node>,
    meshes: Vec<MeshRef>,
    accessors: Vec<Accessor>,
    cameras: Vec<CameraRef>,
    materials: Vec<MaterialRef>,
    textures: Vec<TextureRef>,
    images: Vec<Image>,
    samplers: Vec<Sampler>,
    extensions: Option<serde_json::Map<String, serde_json::Value>>,
}

#[derive(Deserialize, Default)]
#[serde(default)]
struct SceneRoots {
    nodes: Vec<usize>,
}

#[derive(Deserialize, Default)]
#[serde(default)]
struct Node {
    name: Option<String>,
    children: Vec<usize>,
    mesh: Option<usize>,
    camera: Option<usize>,
    matrix: Option<[f32; 16]>,
    translation: Option<[f32; 3]>,
    rotation: Option<[f32; 4]>,
    scale: Option<[f32; 3]>,
}

impl Node {
    /// Parent from node: its `matrix`, or its translation, rotation and scale.
    fn transform(&self) -> Checked<Affine3A> {
        let m = match self.matrix {
            Some(m) => Mat4::from_cols_array(&m),
            None => Mat4::from_scale_rotation_translation(
                Vec3::from_array(self.scale.unwrap_or([1.0; 3])),
                Quat::from_array(self.rotation.unwrap_or([0.0, 0.0, 0.0, 1.0])),
                Vec3::from_array(self.translation.unwrap_or_default()),
            ),
        };
        let affine = Affine3A::from_mat4(m);
        if !affine.is_finite() || affine.matrix3.determinant() == 0.0 {
            return Err("its transform is not finite and invertible".into());
        }
        Ok(affine)
    }
}

#[derive(Deserialize, Default)]
#[serde(default)]
struct MeshRef {
    primitives: Vec<Primitive>,
}

#[derive(Deserialize, Default)]
#[serde(default)]
struct Primitive {
    attributes: BTreeMap<String, usize>,
    indices: Option<usize>,
    material: Option<usize>,
    extensions: Option<serde_json::Map<String, serde_json::Value>>,
}

impl Primitive {
    /// The accessor of a required attribute.
    fn attribute(&self, semantic: &str) -> Checked<usize> {
        self.attributes.get(semantic).copied().ok_or_else(|| format!("a mesh without {semantic}"))
    }
}

#[derive(Deserialize, Default)]
#[serde(default, rename_all = "camelCase")]
struct Accessor {
    buffer_view: Option<usize>,
    byte_offset: u64,
    count: u64,
    component_type: u32,
    #[serde(rename = "type")]
    type_: String,
    sparse: Option<serde_json::Value>,
}

#[derive(Deserialize, Default)]
#[serde(default)]
struct CameraRef {
    perspective: Option<Perspective>,
    orthographic: Option<Orthographic>,
}

#[derive(Deserialize, Default)]
#[serde(default)]
struct Perspective {
    yfov: f32,
}

#[derive(Deserialize, Default)]
#[serde(default)]
struct Orthographic {
    ymag: f32,
}

#[derive(Deserialize, Default)]
#[serde(default, rename_all = "camelCase")]
struct MaterialRef {
    emissive_texture: Option<TextureInfo>,
}

#[derive(Deserialize, Default)]
#[serde(default)]
struct TextureInfo {
    index: usize,
}

#[derive(Deserialize, Default)]
#[serde(default)]
struct TextureRef {
    sampler: Option<usize>,
    source: Option<usize>,
}

#[derive(Deserialize, Default)]
#[serde(default, rename_all = "camelCase")]
struct Image {
    buffer_view: Option<usize>,
    mime_type: Option<String>,
}

#[derive(Deserialize, Default)]
#[serde(default, rename_all = "camelCase")]
struct Sampler {
    wrap_s: Option<u32>,
    wrap_t: Option<u32>,
}
