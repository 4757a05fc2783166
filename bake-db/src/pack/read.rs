//! Reading a pack: the scene through kage's glTF importer, then the extension's typed records
//! ([`schema`]), each checked against the data present and against the documented limits
//! before anything is sized by it.

use super::{Contents, EXTENSION, SEALED, VERSIONS, integrity, ranges, schema};
use glam::{DVec3, Vec2, Vec3};
use gltf::json as gj;
use kage_engine::bspvt;
use kage_engine::prt::{self, Lighting, regions::Region};
use kage_engine::scene::import::{self, Channels, ImportOptions};
use kage_engine::scene::texture::Wrap;
use kage_engine::scene::{
    Cutout, EnvMap, EnvironmentLight, FlatScene, Material, MaterialMaps, NodeId, PolygonLight, PrimitiveId, Scene,
    TextureSlot,
};
use kage_engine::{Error, Result};
use serde::Deserialize;
use std::collections::HashMap;
use std::path::Path;

/// A pack's problem, naming the file.
fn bad(path: &Path, what: impl std::fmt::Display) -> Error {
    Error::Invalid(format!("{}: not a kage pack: {what}", path.display()))
}

/// Reads a pack: the scene (materials restored from the extension) and its bakes. Its
/// integrity (version 4 on) is verified before anything is read from it, and every number it
/// holds is checked finite and in range.
pub fn read(path: &Path) -> Result<(Scene, Contents)> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let glb = kage_runtime::pack::glb::split(&bytes).map_err(|e| bad(path, e))?;
    let doc = gj::Root::from_slice(glb.json).map_err(|e| bad(path, e))?;
    let views = integrity::buffer_views(glb.json).map_err(|e| bad(path, e))?;
    let pack = Pack { doc: &doc, views: &views, bin: glb.bin };
    let root: schema::Root = extension(doc.extensions.as_ref().map(|e| &e.others)).map_err(|e| bad(path, e))?;
    if !VERSIONS.contains(&root.version) {
        return Err(bad(path, format!("{EXTENSION} version {} (this kage reads {VERSIONS:?})", root.version)));
    }
    let mut warnings = Vec::new();
    match &root.integrity {
        Some(record) => integrity::check_json(glb.json, record).map_err(|e| bad(path, e))?,
        None if root.version >= SEALED => {
            return Err(bad(path, format!("version {} without its integrity record", root.version)));
        }
        None => warnings.push(format!(
            "{}: a version {} pack carries no checksums: its numbers are range-checked only",
            path.display(),
            root.version
        )),
    }
    let (instances, lights) = pack.records().map_err(|e| bad(path, e))?;
    if let Some(record) = &root.integrity {
        integrity::check_views(&views, pack.bin, record, |v| pack.view_name(v, &root, &instances))
            .map_err(|e| bad(path, e))?;
    }
    ranges::root(&root).and_then(|()| ranges::records(&instances, &lights)).map_err(|e| bad(path, e))?;
    let mut scene = import::import(path, ImportOptions { color_set: 1, ..Default::default() })?;
    restore_lights(&mut scene, &lights).map_err(|e| bad(path, e))?;
    let flat = kage_engine::scene::flatten(&scene);
    if instances.len() != flat.instances.len() {
        return Err(bad(path, format!("{} baked meshes for {} instances", instances.len(), flat.instances.len())));
    }
    pack.restore_materials(&mut scene, &flat, &instances).map_err(|e| bad(path, e))?;
    // The environment before the PRT record: its lighting splits the map's sun off.
    if let Some(env) = &root.environment {
        scene.set_environment(pack.environment(path, env).map_err(|e| bad(path, e))?);
    }
    let flat = kage_engine::scene::flatten(&scene);
    let bspvt = root.bspvt.as_ref().map(|h| pack.bspvt(h, &instances, &flat)).transpose().map_err(|e| bad(path, e))?;
    let prt = root.prt.as_ref().map(|h| pack.prt(h, &instances, &flat)).transpose().map_err(|e| bad(path, e))?;
    if root.bspvt.as_ref().is_some_and(|h| h.format < bspvt::layout::FORMAT_VERSION) {
        warnings.push(format!(
            "{}: its BSPVT records are format 1, without the occluders' depth: a light inside a \
             closed room shades dark as it did when the pack was written; export the scene again",
            path.display()
        ));
    }
    Ok((scene, Contents { bspvt, prt, warnings }))
}

/// The `KAGE_baked_shadows` entry of an `extensions` object, as record `T`.
fn extension<T: serde::de::DeserializeOwned>(
    others: Option<&serde_json::Map<String, serde_json::Value>>,
) -> std::result::Result<T, String> {
    let value = others.and_then(|o| o.get(EXTENSION)).ok_or_else(|| format!("no {EXTENSION} extension"))?;
    T::deserialize(value).map_err(|e| format!("{EXTENSION}: {e}"))
}

/// A pack's document, its buffer views and its binary chunk.
struct Pack<'a> {
    doc: &'a gj::Root,
    views: &'a [integrity::View],
    bin: &'a [u8],
}

type Checked<T> = std::result::Result<T, String>;

impl Pack<'_> {
    /// The bytes of buffer view `index`, if it lies inside the binary chunk.
    fn view(&self, index: u32) -> Checked<&[u8]> {
        if index as usize >= self.views.len() {
            return Err(format!("no buffer view {index}"));
        }
        integrity::view(self.views, self.bin, index as usize)
            .ok_or_else(|| format!("buffer view {index} lies outside the binary chunk"))
    }

    /// What buffer view `v` holds, for messages: the extension's field or the core glTF's
    /// attribute, indices or image that reads it.
    fn view_name(&self, v: usize, root: &schema::Root, instances: &[schema::Instance]) -> String {
        let is = |x: u32| x as usize == v;
        for (k, r) in instances.iter().enumerate() {
            let field = if is(r.radiance) {
                "radiance"
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
        let accessor = |a: &gj::Index<gj::Accessor>| {
            self.doc.accessors.get(a.value()).and_then(|a| a.buffer_view).is_some_and(|b| b.value() == v)
        };
        for (m, mesh) in self.doc.meshes.iter().enumerate() {
            for p in &mesh.primitives {
                if let Some((name, _)) = p.attributes.iter().find(|(_, a)| accessor(a)) {
                    let name = match name {
                        gj::validation::Checked::Valid(s) => s.to_string(),
                        gj::validation::Checked::Invalid => "an attribute".into(),
                    };
                    return format!("mesh {m}'s {name}");
                }
                if p.indices.as_ref().is_some_and(accessor) {
                    return format!("mesh {m}'s indices");
                }
            }
        }
        match self.doc.images.iter().position(|i| i.buffer_view.is_some_and(|b| b.value() == v)) {
            Some(i) => format!("image {i}"),
            None => "data".into(),
        }
    }

    /// The extension records of every mesh: instances (in mesh order) and lights.
    fn records(&self) -> Checked<(Vec<schema::Instance>, Vec<schema::Light>)> {
        let (mut instances, mut lights) = (Vec::new(), Vec::new());
        for (m, mesh) in self.doc.meshes.iter().enumerate() {
            let others = mesh.primitives.first().and_then(|p| p.extensions.as_ref()).map(|e| &e.others);
            let Some(value) = others.and_then(|o| o.get(EXTENSION)) else { continue };
            let named = |e: serde_json::Error| format!("mesh {m}: {EXTENSION}: {e}");
            if value.get("lightRadiance").is_some() {
                lights.push(schema::Light::deserialize(value).map_err(named)?);
            } else {
                instances.push(schema::Instance::deserialize(value).map_err(named)?);
            }
        }
        Ok((instances, lights))
    }

    /// Puts each instance's real material (factors and textures) back in place of the preview.
    fn restore_materials(&self, scene: &mut Scene, flat: &FlatScene, records: &[schema::Instance]) -> Checked<()> {
        // Instances re-import in node order, which is the pack's instance order.
        let entities: HashMap<PrimitiveId, hecs::Entity> =
            scene.world.query::<(hecs::Entity, &PrimitiveId)>().iter().map(|(e, id)| (*id, e)).collect();
        let mut decoded = HashMap::new();
        for (k, (inst, record)) in flat.instances.iter().zip(records).enumerate() {
            let m = &record.material;
            let material = Material {
                base_color: Vec3::from_array(m.base_color),
                metallic: m.metallic,
                roughness: m.roughness,
                specular: m.specular,
            };
            let mut slot = |s: &Option<schema::TextureSlot>, channels| {
                s.as_ref().map(|s| self.texture_slot(s, channels, scene, &mut decoded)).transpose()
            };
            let cutout = match &m.cutout {
                Some(c) if !(c.factor.is_finite() && c.cutoff.is_finite()) => {
                    return Err(format!("mesh {k}: the cut-out's factor and cutoff are not numbers"));
                }
                Some(c) => Some(Cutout {
                    alpha: slot(&c.alpha_texture, Channels::Alpha)
                        .map_err(|e| format!("mesh {k}: alphaTexture: {e}"))?,
                    factor: c.factor,
                    cutoff: c.cutoff,
                }),
                None => None,
            };
            let maps = MaterialMaps {
                base_color: slot(&m.base_color_texture, Channels::Srgb)
                    .map_err(|e| format!("mesh {k}: baseColorTexture: {e}"))?,
                metallic_roughness: slot(&m.metallic_roughness_texture, Channels::Linear)
                    .map_err(|e| format!("mesh {k}: metallicRoughnessTexture: {e}"))?,
                cutout,
            };
            let entity = entities[&inst.id];
            let _ = scene.world.insert_one(entity, material);
            if !maps.is_empty() {
                let _ = scene.world.insert_one(entity, maps);
            }
        }
        Ok(())
    }

    /// A texture slot: its glTF texture decoded (once per texture and colour space, into the
    /// scene's textures), UV set and transform.
    fn texture_slot(
        &self,
        s: &schema::TextureSlot,
        channels: Channels,
        scene: &mut Scene,
        decoded: &mut HashMap<(u32, Channels), u32>,
    ) -> Checked<TextureSlot> {
        if s.tex_coord > 1 {
            return Err(format!("TEXCOORD_{} is not a set kage reads", s.tex_coord));
        }
        if !s.transform.iter().all(|x| x.is_finite()) {
            return Err("the UV transform is not 6 finite numbers".into());
        }
        let texture = match decoded.get(&(s.index, channels)) {
            Some(&t) => t,
            None => {
                let t = self.decode(s.index, channels).map_err(|e| format!("texture {}: {e}", s.index))?;
                scene.textures.push(std::sync::Arc::new(t));
                let t = scene.textures.len() as u32 - 1;
                decoded.insert((s.index, channels), t);
                t
            }
        };
        let transform = glam::Affine2::from_cols_array(&s.transform);
        Ok(TextureSlot { texture, texcoord: s.tex_coord, transform })
    }

    /// Core texture `index`, decoded from its image in the binary chunk.
    fn decode(&self, index: u32, channels: Channels) -> Checked<kage_engine::scene::Texture> {
        let texture = self.doc.textures.get(index as usize).ok_or("no such texture")?;
        let image = self.doc.images.get(texture.source.value()).ok_or("no such image")?;
        let bytes = self.view(image.buffer_view.ok_or("no image data in the pack")?.value() as u32)?;
        let sampler = texture.sampler.and_then(|s| self.doc.samplers.get(s.value()));
        let wrap = |w: Option<&gj::validation::Checked<gj::texture::WrappingMode>>| match w {
            Some(gj::validation::Checked::Valid(gj::texture::WrappingMode::ClampToEdge)) => Wrap::Clamp,
            Some(gj::validation::Checked::Valid(gj::texture::WrappingMode::MirroredRepeat)) => Wrap::Mirror,
            _ => Wrap::Repeat,
        };
        let wraps = [wrap(sampler.map(|s| &s.wrap_s)), wrap(sampler.map(|s| &s.wrap_t))];
        import::decode_texture(bytes, channels, wraps).map_err(|e| e.to_string())
    }

    /// The BSPVT bake: every instance's offsets and records, checked record by record.
    fn bspvt(&self, h: &schema::BspvtHeader, records: &[schema::Instance], flat: &FlatScene) -> Checked<bspvt::Bake> {
        // Format 1 is format 2 without depth: its records read as ones whose faces have none.
        if !(1..=bspvt::layout::FORMAT_VERSION).contains(&h.format) {
            return Err(format!(
                "BSPVT record format {} (this kage reads 1..={})",
                h.format,
                bspvt::layout::FORMAT_VERSION
            ));
        }
        let settings = bspvt::Settings { res: count(h.face_resolution), epsilon: h.epsilon };
        settings.check().map_err(|e| format!("BSPVT: {e}"))?;
        let instances = records
            .iter()
            .enumerate()
            .map(|(k, r)| {
                let data = r.bspvt.as_ref().ok_or_else(|| format!("mesh {k}: no BSPVT data"))?;
                let offsets: Vec<u32> = bytemuck::pod_collect_to_vec(self.view(data.offsets)?);
                let records = self.view(data.records)?;
                let ok = offsets.len() == flat.vertex_count(k) + 1
                    && offsets.last().is_some_and(|&o| o as usize == records.len())
                    && offsets.windows(2).all(|w| w[0] <= w[1]);
                if !ok {
                    return Err(format!("mesh {k}: BSPVT data does not match the mesh"));
                }
                let instance = bspvt::BakedInstance { offsets, data: records.to_vec() };
                for v in 0..instance.vertices() {
                    bspvt::layout::check_record(instance.record(v), settings.res)
                        .map_err(|e| format!("mesh {k}, vertex {v}: malformed BSPVT record: {e}"))?;
                }
                Ok(instance)
            })
            .collect::<Checked<Vec<_>>>()?;
        Ok(bspvt::Bake { settings, instances, stats: bspvt::Stats::default() })
    }

    /// The PRT bake, its lighting and settings: every count within its documented range, the
    /// lighting n² triples, every transfer n² floats per vertex.
    fn prt(
        &self,
        h: &schema::PrtHeader,
        records: &[schema::Instance],
        flat: &FlatScene,
    ) -> Checked<(prt::Bake, Lighting, prt::Settings)> {
        if h.algorithm != prt::ALGORITHM_VERSION {
            return Err(format!("PRT algorithm {} (this kage reads {})", h.algorithm, prt::ALGORITHM_VERSION));
        }
        let settings = prt::Settings {
            order: count(h.order),
            directions: count(h.directions),
            regions: h.regions.len(),
            window: h.window.into(),
            silhouette_res: count(h.silhouette_resolution),
        };
        settings.check().map_err(|e| format!("PRT: {e}"))?;
        let order = settings.order;
        if h.lighting.len() != order * order {
            return Err(format!("PRT: {} lighting coefficients for order {order}", h.lighting.len()));
        }
        let coeffs: Vec<DVec3> = h.lighting.iter().map(|c| DVec3::from_array(*c)).collect();
        let regions: Vec<Region> = h
            .regions
            .iter()
            .map(|r| Region {
                power: DVec3::from_array(r.power),
                dir: Vec3::from_array(r.direction),
                solid_angle: r.solid_angle,
                spread: r.spread,
            })
            .collect();
        let instances = records
            .iter()
            .enumerate()
            .map(|(k, r)| {
                let data = r.prt.as_ref().ok_or_else(|| format!("mesh {k}: no PRT transfer"))?;
                let bytes = self.view(data.transfer)?;
                if bytes.len() != flat.vertex_count(k) * order * order * 4 {
                    return Err(format!("mesh {k}: PRT transfer does not match the mesh"));
                }
                let transfer: Vec<f32> = bytemuck::pod_collect_to_vec(bytes);
                ranges::transfer(k, order, &transfer)?;
                Ok(transfer)
            })
            .collect::<Checked<Vec<Vec<f32>>>>()?;
        let lobes = prt::lighting::negative_lobes(&coeffs, settings.window);
        let bake = prt::Bake { order, instances, stats: prt::Stats::default() };
        let lighting = Lighting { coeffs, regions, window: settings.window, lobes, sunless: None };
        // With the map in the pack, the baked look shades its sun apart as from a database.
        let lighting = match &flat.environment {
            Some(env) => lighting.splitting_sun(env, &settings),
            None => lighting,
        };
        Ok((bake, lighting, settings))
    }

    /// The environment light: its exact texels, intensity and rotation.
    fn environment(&self, path: &Path, env: &schema::Environment) -> Checked<EnvironmentLight> {
        let bytes = self.view(env.texels).map_err(|e| format!("environment: {e}"))?;
        let (w, h) = (count(env.width), count(env.height));
        if w.checked_mul(h).and_then(|n| n.checked_mul(12)) != Some(bytes.len()) {
            return Err(format!("environment: {} bytes of texels for {w}×{h}", bytes.len()));
        }
        let texels: Vec<f32> = bytemuck::pod_collect_to_vec(bytes);
        let texels = texels.chunks_exact(3).map(Vec3::from_slice).collect();
        let map = EnvMap::new(w, h, texels, format!("{}#environment", path.display()))
            .map_err(|e| format!("environment: {e}"))?;
        let mut light = EnvironmentLight::new(map);
        (light.intensity, light.rotation) = (env.intensity, env.rotation);
        Ok(light)
    }
}

/// A declared count as `usize` (saturating: every count is checked against the data present).
fn count(n: u64) -> usize {
    usize::try_from(n).unwrap_or(usize::MAX)
}

/// Puts back each light's exact radiance, polygon, UVs and reach (lights re-import in the order
/// they were written).
fn restore_lights(scene: &mut Scene, records: &[schema::Light]) -> Checked<()> {
    let mut found: Vec<(u32, usize, hecs::Entity)> = scene
        .world
        .query::<(hecs::Entity, &PolygonLight, &NodeId)>()
        .iter()
        .map(|(e, l, n)| (n.0, l.points.len(), e))
        .collect();
    found.sort();
    if found.len() != records.len() {
        return Err(format!("{} light records for {} lights", records.len(), found.len()));
    }
    for ((_, _, e), rec) in found.iter().zip(records) {
        let points: Vec<Vec3> = rec.light_polygon.chunks_exact(3).map(Vec3::from_slice).collect();
        let uvs: Vec<Vec2> = rec
            .light_uvs
            .iter()
            .flatten()
            .copied()
            .collect::<Vec<f32>>()
            .chunks_exact(2)
            .map(Vec2::from_slice)
            .collect();
        let reach = match rec.light_reach {
            None => None,
            Some(r @ [a, b, c, d, e, f]) if a <= d && b <= e && c <= f && r.iter().all(|x| x.is_finite()) => {
                Some([Vec3::new(a, b, c), Vec3::new(d, e, f)])
            }
            Some(_) => return Err("a light reach is not 6 finite numbers, min ≤ max".into()),
        };
        let mut l = scene.world.get::<&mut PolygonLight>(*e).expect("queried above");
        if points.len() != l.points.len() {
            return Err("a light polygon does not match its mesh".into());
        }
        if l.texture.is_some() && uvs.len() != points.len() {
            return Err("a textured light's UVs do not match its polygon".into());
        }
        (l.radiance, l.points, l.uvs, l.reach) = (Vec3::from_array(rec.light_radiance), points, uvs, reach);
    }
    Ok(())
}
