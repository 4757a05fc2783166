//! Asset packs: a glTF 2.0 binary with the scene, its baked data under the `KAGE_baked_shadows`
//! extension (spec: `docs/KAGE_baked_shadows.md`), and a preview any viewer shows: the baked
//! radiance as `COLOR_0` on `KHR_materials_unlit` materials.
//!
//! Layout: one root node per rigid group (its pose as `matrix`), one child node per mesh
//! instance (its group-relative transform) with its own mesh, in the snapshot's instance order,
//! then one child node per polygonal light (an emissive triangle fan), then the camera. Packs
//! are read back by kage's glTF importer, which restores groups, lights and camera; the
//! extension restores what the preview material replaced (the real materials) and the bakes.

use glam::{DVec3, Vec3};
use kage_engine::bspvt;
use kage_engine::math::color::linear_to_srgb;
use kage_engine::prt::{self, Lighting, lighting::Window, regions::Region};
use kage_engine::scene::import::{self, ImportOptions};
use kage_engine::scene::texture::Wrap;
use kage_engine::scene::{
    Camera, EnvMap, EnvironmentLight, FlatScene, InGroup, Instance, Material, MaterialMaps, Name, NodeId, PolygonLight,
    Projection, RigidGroup, Scene, Texture, TextureSlot, Transform,
};
use serde_json::{Value, json};
use std::path::Path;

/// The extension's name.
pub const EXTENSION: &str = "KAGE_baked_shadows";
/// The extension's version.
pub const VERSION: u64 = 1;

/// What a pack holds besides its glTF scene.
pub struct Contents {
    /// BSPVT bake, if the pack has one.
    pub bspvt: Option<bspvt::Bake>,
    /// PRT bake with its lighting and settings, if the pack has one.
    pub prt: Option<(prt::Bake, Lighting, prt::Settings)>,
}

/// Everything [`write`](fn@write) needs.
pub struct Export<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// Its snapshot.
    pub flat: &'a FlatScene,
    /// BSPVT bake.
    pub bspvt: Option<&'a bspvt::Bake>,
    /// PRT bake, lighting and settings.
    pub prt: Option<prt::Parts<'a>>,
    /// Per instance and vertex: the baked radiance for the preview (linear).
    pub radiance: &'a [Vec<Vec3>],
    /// Preview exposure in stops (COLOR_0 = clamp(radiance · 2^exposure, 0, 1)).
    pub exposure: f32,
}

/// A growing binary chunk with its buffer views and accessors.
#[derive(Default)]
struct Bin {
    bytes: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Bin {
    /// Appends 4-byte-aligned data as a buffer view; returns its index.
    fn view(&mut self, data: &[u8], target: Option<u32>) -> usize {
        while !self.bytes.len().is_multiple_of(4) {
            self.bytes.push(0);
        }
        let mut v = json!({"buffer": 0, "byteOffset": self.bytes.len(), "byteLength": data.len()});
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        self.bytes.extend_from_slice(data);
        self.views.push(v);
        self.views.len() - 1
    }

    /// A float VEC3 accessor (with min/max).
    fn vec3(&mut self, v: &[Vec3]) -> usize {
        let (lo, hi) = v.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
        let view = self.view(bytemuck::cast_slice(v), Some(34962));
        self.accessors.push(json!({"bufferView": view, "componentType": 5126, "count": v.len(), "type": "VEC3",
            "min": lo.to_array(), "max": hi.to_array()}));
        self.accessors.len() - 1
    }

    /// A float VEC2 accessor (texture coordinates).
    fn vec2(&mut self, v: &[glam::Vec2]) -> usize {
        let view = self.view(bytemuck::cast_slice(v), Some(34962));
        self.accessors.push(json!({"bufferView": view, "componentType": 5126, "count": v.len(), "type": "VEC2"}));
        self.accessors.len() - 1
    }

    /// A u32 index accessor.
    fn indices(&mut self, i: &[u32]) -> usize {
        let view = self.view(bytemuck::cast_slice(i), Some(34963));
        self.accessors.push(json!({"bufferView": view, "componentType": 5125, "count": i.len(), "type": "SCALAR"}));
        self.accessors.len() - 1
    }
}

/// A node with an optional `matrix` (omitted when it is the identity, as glTF asks).
fn node(mut n: Value, a: &glam::Affine3A) -> Value {
    if *a != glam::Affine3A::IDENTITY {
        n["matrix"] = json!(glam::Mat4::from(*a).to_cols_array());
    }
    n
}

/// The extension's record of an instance's material: its factors and texture slots (each naming
/// a glTF texture written into the pack).
fn material_json(inst: &Instance, scene: &Scene, textures: &mut Textures, bin: &mut Bin) -> Value {
    let m = &inst.material;
    let mut out = json!({"baseColor": m.base_color.to_array(), "metallic": m.metallic, "roughness": m.roughness,
        "specular": m.specular});
    let slots = [
        ("baseColorTexture", inst.maps.base_color, true),
        ("metallicRoughnessTexture", inst.maps.metallic_roughness, false),
    ];
    for (key, slot, srgb) in slots {
        if let Some(s) = slot {
            let index = textures.add(bin, s.texture, &scene.textures[s.texture as usize], srgb);
            out[key] = json!({"index": index, "texCoord": s.texcoord, "transform": s.transform.to_cols_array()});
        }
    }
    out
}

/// Writes the pack.
pub fn write(path: &Path, e: &Export) -> std::io::Result<()> {
    let mut bin = Bin::default();
    let (mut nodes, mut meshes, mut materials) = (Vec::<Value>::new(), Vec::<Value>::new(), Vec::<Value>::new());
    let mut groups: Vec<(u32, hecs::Entity, glam::Affine3A, String)> = e
        .scene
        .world
        .query::<(hecs::Entity, &RigidGroup, &Transform, &Name)>()
        .iter()
        .map(|(g, r, t, n)| (r.index, g, t.world, n.0.clone()))
        .collect();
    groups.sort_by_key(|g| g.0);
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); groups.len()];
    let group_of = |g: hecs::Entity| groups.iter().position(|x| x.1 == g).expect("every member's group is listed");
    let locals = prt::local_transforms(e.scene, e.flat);
    let scale = 2f32.powf(e.exposure);
    let mut textures = Textures::default();
    for (k, inst) in e.flat.instances.iter().enumerate() {
        let mesh = e.flat.mesh(k);
        let preview: Vec<Vec3> = e.radiance[k].iter().map(|v| (*v * scale).clamp(Vec3::ZERO, Vec3::ONE)).collect();
        let (pos, nor, col) = (bin.vec3(&mesh.positions), bin.vec3(&mesh.normals), bin.vec3(&preview));
        let idx: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
        let ind = bin.indices(&idx);
        let material = material_json(inst, e.scene, &mut textures, &mut bin);
        let mut ext = json!({"instance": k, "material": material, "radiance": bin.view(bytemuck::cast_slice(&e.radiance[k]), None)});
        if let Some(b) = e.bspvt {
            let rec = &b.instances[k];
            ext["bspvt"] = json!({"offsets": bin.view(bytemuck::cast_slice(&rec.offsets), None), "records": bin.view(&rec.data, None)});
        }
        if let Some(prt::Parts { bake: p, .. }) = e.prt {
            ext["prt"] = json!({"transfer": bin.view(bytemuck::cast_slice(&p.instances[k]), None)});
        }
        materials.push(json!({"name": format!("preview {k}"), "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0},
            "extensions": {"KHR_materials_unlit": {}}}));
        // COLOR_0 is the preview; the source's own vertex colours go to COLOR_1.
        let mut attributes = json!({"POSITION": pos, "NORMAL": nor, "COLOR_0": col});
        for (key, uvs) in [("TEXCOORD_0", &mesh.uvs), ("TEXCOORD_1", &mesh.uvs1)] {
            if !uvs.is_empty() {
                attributes[key] = json!(bin.vec2(uvs));
            }
        }
        if !mesh.colors.is_empty() {
            attributes["COLOR_1"] = json!(bin.vec3(&mesh.colors));
        }
        meshes.push(json!({"primitives": [{"attributes": attributes, "indices": ind, "material": materials.len() - 1,
            "extensions": {EXTENSION: ext}}]}));
        children[group_of(inst.group)].push(nodes.len() + groups.len());
        nodes.push(node(json!({"name": format!("instance {k}"), "mesh": meshes.len() - 1}), &locals[k]));
    }
    let mut lights: Vec<(u32, PolygonLight, InGroup)> = e
        .scene
        .world
        .query::<(&PolygonLight, &InGroup, &NodeId)>()
        .iter()
        .map(|(l, g, n)| (n.0, l.clone(), *g))
        .collect();
    lights.sort_by(|a, b| a.0.cmp(&b.0).then_with(|| a.1.points.len().cmp(&b.1.points.len())));
    for (_, light, member) in &lights {
        let pos = bin.vec3(&light.points);
        let fan: Vec<u32> = (1..light.points.len() as u32 - 1).flat_map(|i| [0, i, i + 1]).collect();
        let ind = bin.indices(&fan);
        let strength = light.radiance.max_element().max(1e-30);
        let mut material = json!({"name": "light", "pbrMetallicRoughness": {"baseColorFactor": [0.0, 0.0, 0.0, 1.0]},
            "emissiveFactor": (light.radiance / strength).to_array(), "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": strength}}});
        // The exact radiance (factor × strength need not round-trip in f32), polygon and UVs
        // (the importer may start the re-imported loop at another corner).
        let points: Vec<f32> = light.points.iter().flat_map(|p| p.to_array()).collect();
        let mut ext = json!({"lightRadiance": light.radiance.to_array(), "lightPolygon": points});
        if let Some([lo, hi]) = light.reach {
            ext["lightReach"] = json!([lo.to_array(), hi.to_array()].concat());
        }
        let mut attributes = json!({"POSITION": pos});
        let textured = light.texture.filter(|_| light.uvs.len() == light.points.len());
        if let Some(t) = textured {
            let index = textures.add(&mut bin, t, &e.scene.textures[t as usize], true);
            material["emissiveTexture"] = json!({"index": index});
            attributes["TEXCOORD_0"] = json!(bin.vec2(&light.uvs));
            ext["lightUvs"] = json!(light.uvs.iter().flat_map(|uv| uv.to_array()).collect::<Vec<f32>>());
        }
        materials.push(material);
        meshes.push(json!({"primitives": [{"attributes": attributes, "indices": ind, "material": materials.len() - 1,
            "extensions": {EXTENSION: ext}}]}));
        children[group_of(member.group)].push(nodes.len() + groups.len());
        nodes.push(node(json!({"name": "light", "mesh": meshes.len() - 1}), &member.local));
    }
    // Group nodes first (indices 0..groups), then the members pushed above.
    let mut all: Vec<Value> = groups
        .iter()
        .zip(&children)
        .map(|((_, _, pose, name), c)| node(json!({"name": name, "children": c}), pose))
        .collect();
    all.extend(nodes);
    let mut roots: Vec<usize> = (0..groups.len()).collect();
    let mut cameras = Vec::new();
    if let Some(cam) = e.scene.first_camera() {
        cameras.push(camera_json(&cam));
        roots.push(all.len());
        all.push(node(json!({"name": "camera", "camera": 0}), &cam.world));
    }
    let mut root = root_extension(e);
    if let Some(env) = e.scene.world.query::<&EnvironmentLight>().iter().next() {
        // Exact texels (f32 RGB, row 0 = +Y): the specular term prefilters them on load.
        let texels = bin.view(bytemuck::cast_slice(&env.map.texels), None);
        root["environment"] = json!({"width": env.map.width, "height": env.map.height, "texels": texels,
            "intensity": env.intensity, "rotation": env.rotation});
    }
    let mut doc = json!({
        "asset": {"version": "2.0", "generator": concat!("kage ", env!("CARGO_PKG_VERSION"))},
        "extensionsUsed": ["KHR_materials_unlit", "KHR_materials_emissive_strength", EXTENSION],
        "extensions": {EXTENSION: root},
        "scene": 0, "scenes": [{"nodes": roots}], "nodes": all, "meshes": meshes, "materials": materials,
        "accessors": bin.accessors, "bufferViews": bin.views,
        "buffers": [{"byteLength": bin.bytes.len()}],
    });
    // glTF forbids empty top-level arrays: `cameras` and textures only when there are some.
    if !cameras.is_empty() {
        doc["cameras"] = json!(cameras);
    }
    if !textures.textures.is_empty() {
        doc["images"] = json!(textures.images);
        doc["samplers"] = json!(textures.samplers);
        doc["textures"] = json!(textures.textures);
    }
    std::fs::write(path, glb(&doc.to_string(), bin.bytes))
}

/// The scene's textures as 8-bit PNGs (sRGB-encoded colours, linear data), each written once.
#[derive(Default)]
struct Textures {
    /// Scene texture index → glTF texture index.
    written: std::collections::HashMap<u32, usize>,
    images: Vec<Value>,
    samplers: Vec<Value>,
    textures: Vec<Value>,
}

impl Textures {
    /// The glTF texture for scene texture `index` (colours when `srgb`), written on first use.
    fn add(&mut self, bin: &mut Bin, index: u32, t: &Texture, srgb: bool) -> usize {
        if let Some(&k) = self.written.get(&index) {
            return k;
        }
        let view = bin.view(&png(t, srgb), None);
        self.images.push(json!({"bufferView": view, "mimeType": "image/png"}));
        let wrap = |w: Wrap| match w {
            Wrap::Clamp => 33071,
            Wrap::Mirror => 33648,
            Wrap::Repeat => 10497,
        };
        self.samplers
            .push(json!({"magFilter": 9729, "minFilter": 9987, "wrapS": wrap(t.wrap[0]), "wrapT": wrap(t.wrap[1])}));
        self.textures.push(json!({"sampler": self.samplers.len() - 1, "source": self.images.len() - 1}));
        self.written.insert(index, self.textures.len() - 1);
        self.textures.len() - 1
    }
}

/// `t` as a PNG, sRGB-encoded when `srgb`. Textures imported from 8-bit images come back bit
/// for bit (every byte round-trips through [`linear_to_srgb`]; tested beside it); others round
/// to the nearest byte.
fn png(t: &Texture, srgb: bool) -> Vec<u8> {
    let encode = |x: f32| {
        let x = x.clamp(0.0, 1.0);
        (if srgb { linear_to_srgb(x) } else { x } * 255.0).round() as u8
    };
    let rgb: Vec<u8> = t.texels.iter().flat_map(|c| c.to_array().map(encode)).collect();
    let image = image::RgbImage::from_raw(t.width as u32, t.height as u32, rgb).expect("texel count matches");
    let mut out = std::io::Cursor::new(Vec::new());
    image.write_to(&mut out, image::ImageFormat::Png).expect("PNG encoding into memory");
    out.into_inner()
}

fn camera_json(c: &Camera) -> Value {
    match c.projection {
        Projection::Perspective { yfov } => {
            json!({"type": "perspective", "perspective": {"yfov": yfov, "znear": 0.01}})
        }
        Projection::Orthographic { ymag } => {
            json!({"type": "orthographic", "orthographic": {"xmag": ymag, "ymag": ymag, "znear": 0.0, "zfar": 1000.0}})
        }
    }
}

fn root_extension(e: &Export) -> Value {
    let mut root = json!({"version": VERSION, "previewExposure": e.exposure});
    if let Some(b) = e.bspvt {
        root["bspvt"] = json!({"faceResolution": b.settings.res, "epsilon": b.settings.epsilon, "format": bspvt::layout::FORMAT_VERSION});
    }
    if let Some(prt::Parts { bake: p, lighting: light, settings: s }) = e.prt {
        let window = match light.window {
            Window::None => "none",
            Window::Hanning => "hanning",
            Window::Lanczos => "lanczos",
        };
        root["prt"] = json!({
            "order": p.order, "directions": s.direction_side().pow(2), "algorithm": prt::ALGORITHM_VERSION,
            "window": window, "silhouetteResolution": s.silhouette_res,
            "lighting": light.coeffs.iter().map(|c| c.to_array()).collect::<Vec<_>>(),
            "regions": light.regions.iter().map(|r| json!({"power": r.power.to_array(), "direction": r.dir.to_array(),
                "solidAngle": r.solid_angle, "spread": r.spread})).collect::<Vec<_>>(),
        });
    }
    root
}

/// The GLB container: header, JSON chunk (space-padded), BIN chunk (zero-padded).
fn glb(json: &str, mut bin: Vec<u8>) -> Vec<u8> {
    let mut j = json.as_bytes().to_vec();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + j.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&j);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

/// A pack's problem, naming the file.
fn bad(path: &Path, what: impl std::fmt::Display) -> kage_engine::Error {
    kage_engine::Error::Invalid(format!("{}: not a kage pack: {what}", path.display()))
}

/// Reads a pack: the scene (materials restored from the extension) and its bakes.
pub fn read(path: &Path) -> kage_engine::Result<(Scene, Contents)> {
    let mut scene = kage_engine::scene::import::import(path, ImportOptions { color_set: 1, ..Default::default() })?;
    let bytes = std::fs::read(path).map_err(|e| kage_engine::Error::io(path, e))?;
    let (doc, bin) = split_glb(&bytes).ok_or_else(|| bad(path, "not a GLB with a JSON and a BIN chunk"))?;
    let doc: Value = serde_json::from_slice(doc).map_err(|e| bad(path, e))?;
    let root = &doc["extensions"][EXTENSION];
    if root["version"].as_u64() != Some(VERSION) {
        return Err(bad(path, format!("no {EXTENSION} version {VERSION} extension")));
    }
    let views = doc["bufferViews"].as_array().ok_or_else(|| bad(path, "no bufferViews"))?;
    let view = |v: &Value| -> Option<&[u8]> {
        let view = views.get(v.as_u64()? as usize)?;
        let start = view["byteOffset"].as_u64().unwrap_or(0) as usize;
        bin.get(start..start + view["byteLength"].as_u64()? as usize)
    };
    let all: Vec<&Value> = doc["meshes"]
        .as_array()
        .map(|m| m.iter().filter_map(|m| m["primitives"][0]["extensions"].get(EXTENSION)).collect())
        .unwrap_or_default();
    let (exts, lights): (Vec<&Value>, Vec<&Value>) = all.into_iter().partition(|e| e.get("lightRadiance").is_none());
    restore_light_radiance(&mut scene, &lights).map_err(|what| bad(path, what))?;
    let flat = kage_engine::scene::flatten(&scene);
    if exts.len() != flat.instances.len() {
        return Err(bad(path, format!("{} baked meshes for {} instances", exts.len(), flat.instances.len())));
    }
    // Instances re-import in node order, which is the pack's instance order.
    let entities: Vec<(kage_engine::scene::PrimitiveId, hecs::Entity)> = scene
        .world
        .query::<(hecs::Entity, &kage_engine::scene::PrimitiveId)>()
        .iter()
        .map(|(e, id)| (*id, e))
        .collect();
    let mut decoded = std::collections::HashMap::new();
    for (k, inst) in flat.instances.iter().enumerate() {
        let m = &exts[k]["material"];
        let f = |key: &str| m[key].as_f64().map(|v| v as f32);
        let c = m["baseColor"]
            .as_array()
            .filter(|c| c.len() == 3)
            .ok_or_else(|| bad(path, format!("mesh {k}: no material")))?;
        let material = Material {
            base_color: Vec3::new(
                c[0].as_f64().unwrap_or(0.0) as f32,
                c[1].as_f64().unwrap_or(0.0) as f32,
                c[2].as_f64().unwrap_or(0.0) as f32,
            ),
            metallic: f("metallic").unwrap_or(0.0),
            roughness: f("roughness").unwrap_or(1.0),
            specular: f("specular").unwrap_or(1.0),
        };
        let maps = MaterialMaps {
            base_color: texture_slot(&doc, m, "baseColorTexture", true, &view, &mut scene, &mut decoded)
                .map_err(|what| bad(path, format!("mesh {k}: {what}")))?,
            metallic_roughness: texture_slot(
                &doc,
                m,
                "metallicRoughnessTexture",
                false,
                &view,
                &mut scene,
                &mut decoded,
            )
            .map_err(|what| bad(path, format!("mesh {k}: {what}")))?,
        };
        let entity =
            entities.iter().find(|(id, _)| *id == inst.id).map(|(_, e)| *e).expect("flattened from this world");
        let _ = scene.world.insert_one(entity, material);
        if !maps.is_empty() {
            let _ = scene.world.insert_one(entity, maps);
        }
    }
    let flat = kage_engine::scene::flatten(&scene);
    let bspvt = root.get("bspvt").map(|b| -> kage_engine::Result<bspvt::Bake> {
        let settings = bspvt::Settings {
            res: b["faceResolution"].as_u64().unwrap_or(64) as usize,
            epsilon: b["epsilon"].as_f64().unwrap_or(2.0),
        };
        let instances = exts
            .iter()
            .enumerate()
            .map(|(k, x)| {
                let offsets =
                    view(&x["bspvt"]["offsets"]).ok_or_else(|| bad(path, format!("mesh {k}: no BSPVT offsets")))?;
                let data =
                    view(&x["bspvt"]["records"]).ok_or_else(|| bad(path, format!("mesh {k}: no BSPVT records")))?;
                let offsets: Vec<u32> = bytemuck::pod_collect_to_vec(offsets);
                let ok = offsets.len() == flat.vertex_count(k) + 1
                    && offsets.last().is_some_and(|&o| o as usize == data.len())
                    && offsets.windows(2).all(|w| w[0] <= w[1]);
                if !ok {
                    return Err(bad(path, format!("mesh {k}: BSPVT data does not match the mesh")));
                }
                let instance = bspvt::BakedInstance { offsets, data: data.to_vec() };
                for v in 0..instance.vertices() {
                    bspvt::layout::check_record(instance.record(v))
                        .map_err(|e| bad(path, format!("mesh {k}, vertex {v}: malformed BSPVT record: {e}")))?;
                }
                Ok(instance)
            })
            .collect::<kage_engine::Result<Vec<_>>>()?;
        Ok(bspvt::Bake { settings, instances, stats: bspvt::Stats::default() })
    });
    let prt = root.get("prt").map(|p| read_prt(path, p, &exts, &view, &flat));
    if let Some(env) = root.get("environment") {
        scene.set_environment(read_environment(path, env, &view)?);
    }
    Ok((scene, Contents { bspvt: bspvt.transpose()?, prt: prt.transpose()? }))
}

/// The texture slot `key` of an extension material record `m`: its glTF texture decoded
/// (once per texture and colour space, into the scene's textures), UV set and transform.
fn texture_slot<'a>(
    doc: &Value,
    m: &Value,
    key: &str,
    srgb: bool,
    view: &dyn Fn(&Value) -> Option<&'a [u8]>,
    scene: &mut Scene,
    decoded: &mut std::collections::HashMap<(u64, bool), u32>,
) -> Result<Option<TextureSlot>, String> {
    let Some(slot) = m.get(key) else { return Ok(None) };
    let index = slot["index"].as_u64().ok_or_else(|| format!("{key} has no texture index"))?;
    let texture = match decoded.get(&(index, srgb)) {
        Some(&t) => t,
        None => {
            let gltf_texture = &doc["textures"][index as usize];
            let image = &doc["images"][gltf_texture["source"].as_u64().unwrap_or(u64::MAX) as usize];
            let bytes =
                view(&image["bufferView"]).ok_or_else(|| format!("{key}: texture {index} has no image data"))?;
            let sampler = &doc["samplers"][gltf_texture["sampler"].as_u64().unwrap_or(u64::MAX) as usize];
            let wrap = |k: &str| match sampler[k].as_u64() {
                Some(33071) => Wrap::Clamp,
                Some(33648) => Wrap::Mirror,
                _ => Wrap::Repeat,
            };
            let t = import::decode_texture(bytes, srgb, [wrap("wrapS"), wrap("wrapT")])
                .map_err(|e| format!("{key}: texture {index}: {e}"))?;
            scene.textures.push(std::sync::Arc::new(t));
            let t = scene.textures.len() as u32 - 1;
            decoded.insert((index, srgb), t);
            t
        }
    };
    let transform: Vec<f32> =
        slot["transform"].as_array().into_iter().flatten().filter_map(|v| v.as_f64()).map(|v| v as f32).collect();
    let transform = match transform[..] {
        [] if slot.get("transform").is_none() => glam::Affine2::IDENTITY,
        [a, b, c, d, e, f] if transform.iter().all(|x| x.is_finite()) => {
            glam::Affine2::from_cols_array(&[a, b, c, d, e, f])
        }
        _ => return Err(format!("{key}: the UV transform is not 6 finite numbers")),
    };
    let texcoord = match slot["texCoord"].as_u64() {
        None => 0,
        Some(n @ 0..=1) => n as u32,
        Some(n) => return Err(format!("{key}: TEXCOORD_{n} is not a set kage reads")),
    };
    Ok(Some(TextureSlot { texture, texcoord, transform }))
}

/// The environment light a pack carries: its exact texels, intensity and rotation.
fn read_environment<'a>(
    path: &Path,
    env: &Value,
    view: &dyn Fn(&Value) -> Option<&'a [u8]>,
) -> kage_engine::Result<EnvironmentLight> {
    let (w, h) = (env["width"].as_u64().unwrap_or(0) as usize, env["height"].as_u64().unwrap_or(0) as usize);
    let bytes = view(&env["texels"]).ok_or_else(|| bad(path, "environment: no texels"))?;
    if w.checked_mul(h).and_then(|n| n.checked_mul(12)) != Some(bytes.len()) {
        return Err(bad(path, format!("environment: {} bytes of texels for {w}×{h}", bytes.len())));
    }
    let texels: Vec<f32> = bytemuck::pod_collect_to_vec(bytes);
    let texels = texels.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect();
    let map = EnvMap::new(w, h, texels, format!("{}#environment", path.display()))
        .map_err(|e| bad(path, format!("environment: {e}")))?;
    let f = |key: &str, default: f64| env[key].as_f64().unwrap_or(default) as f32;
    let mut light = EnvironmentLight::new(map);
    (light.intensity, light.rotation) = (f("intensity", 1.0), f("rotation", 0.0));
    Ok(light)
}

/// Puts back each light's exact radiance and polygon (lights re-import in the order they were
/// written).
fn restore_light_radiance(scene: &mut Scene, lights: &[&Value]) -> Result<(), String> {
    let mut found: Vec<(u32, usize, hecs::Entity)> = scene
        .world
        .query::<(hecs::Entity, &PolygonLight, &NodeId)>()
        .iter()
        .map(|(e, l, n)| (n.0, l.points.len(), e))
        .collect();
    found.sort();
    if found.len() != lights.len() {
        return Err(format!("{} light records for {} lights", lights.len(), found.len()));
    }
    for ((_, _, e), rec) in found.iter().zip(lights) {
        let floats = |key: &str| -> Vec<f32> {
            rec[key]
                .as_array()
                .map(|a| a.iter().filter_map(|v| v.as_f64()).map(|v| v as f32).collect())
                .unwrap_or_default()
        };
        let [r, g, b] = floats("lightRadiance")[..] else { return Err("a light radiance is not 3 numbers".into()) };
        let points: Vec<Vec3> = floats("lightPolygon").chunks_exact(3).map(Vec3::from_slice).collect();
        if let Ok(mut l) = scene.world.get::<&mut PolygonLight>(*e) {
            if points.len() != l.points.len() {
                return Err("a light polygon does not match its mesh".into());
            }
            let uvs: Vec<glam::Vec2> = floats("lightUvs").chunks_exact(2).map(glam::Vec2::from_slice).collect();
            if l.texture.is_some() && uvs.len() != points.len() {
                return Err("a textured light's UVs do not match its polygon".into());
            }
            l.reach = match floats("lightReach")[..] {
                [] if rec.get("lightReach").is_none() => None,
                [a, b, c, d, e, f]
                    if a <= d && b <= e && c <= f && [a, b, c, d, e, f].iter().all(|x| x.is_finite()) =>
                {
                    Some([Vec3::new(a, b, c), Vec3::new(d, e, f)])
                }
                _ => return Err("a light reach is not 6 finite numbers, min ≤ max".into()),
            };
            l.radiance = Vec3::new(r, g, b);
            l.points = points;
            l.uvs = uvs;
        }
    }
    Ok(())
}

fn read_prt<'a>(
    path: &Path,
    p: &Value,
    exts: &[&Value],
    view: &dyn Fn(&Value) -> Option<&'a [u8]>,
    flat: &FlatScene,
) -> kage_engine::Result<(prt::Bake, Lighting, prt::Settings)> {
    let order = p["order"].as_u64().filter(|&o| (1..=16).contains(&o)).ok_or_else(|| bad(path, "PRT order"))? as usize;
    let window = match p["window"].as_str() {
        Some("hanning") => Window::Hanning,
        Some("lanczos") => Window::Lanczos,
        _ => Window::None,
    };
    let triple = |v: &Value| -> Option<DVec3> {
        let a = v.as_array().filter(|a| a.len() == 3)?;
        Some(DVec3::new(a[0].as_f64()?, a[1].as_f64()?, a[2].as_f64()?))
    };
    let coeffs: Vec<DVec3> =
        p["lighting"].as_array().map(|a| a.iter().filter_map(triple).collect()).unwrap_or_default();
    if coeffs.len() != order * order {
        return Err(bad(path, "PRT lighting coefficients"));
    }
    let regions: Vec<Region> = p["regions"]
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|r| {
                    Some(Region {
                        power: triple(&r["power"])?,
                        dir: triple(&r["direction"])?.as_vec3(),
                        solid_angle: r["solidAngle"].as_f64()?,
                        spread: r["spread"].as_f64()?,
                    })
                })
                .collect()
        })
        .unwrap_or_default();
    let settings = prt::Settings {
        order,
        directions: p["directions"].as_u64().unwrap_or(1024) as usize,
        regions: regions.len(),
        window,
        silhouette_res: p["silhouetteResolution"].as_u64().unwrap_or(128) as usize,
    };
    let instances = exts
        .iter()
        .enumerate()
        .map(|(k, x)| {
            let t: Vec<f32> = view(&x["prt"]["transfer"])
                .map(bytemuck::pod_collect_to_vec)
                .ok_or_else(|| bad(path, format!("mesh {k}: no PRT transfer")))?;
            if t.len() != flat.vertex_count(k) * order * order {
                return Err(bad(path, format!("mesh {k}: PRT transfer does not match the mesh")));
            }
            Ok(t)
        })
        .collect::<kage_engine::Result<Vec<_>>>()?;
    let lobes = prt::lighting::negative_lobes(&coeffs, window);
    let bake = prt::Bake { order, instances, stats: prt::Stats::default() };
    Ok((bake, Lighting { coeffs, regions, window, lobes }, settings))
}

/// The JSON and BIN chunks of a GLB.
fn split_glb(b: &[u8]) -> Option<(&[u8], &[u8])> {
    let u32_at = |i: usize| -> Option<usize> { Some(u32::from_le_bytes(b.get(i..i + 4)?.try_into().ok()?) as usize) };
    if b.get(..4)? != b"glTF" {
        return None;
    }
    let json_len = u32_at(12)?;
    let json = b.get(20..20 + json_len)?;
    let at = 20 + json_len;
    let bin_len = u32_at(at)?;
    (b.get(at + 4..at + 8)? == b"BIN\0").then_some(())?;
    Some((json, b.get(at + 8..at + 8 + bin_len)?))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec2;

    /// Textured materials, both UV sets and the source's vertex colours survive a pack: the
    /// material at every vertex and at points inside triangles is the same after reading.
    #[test]
    fn textured_materials_survive_a_pack() {
        let asset = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/scenes/textured_materials.gltf");
        let scene = import::import(&asset, ImportOptions::default()).unwrap();
        let flat = kage_engine::scene::flatten(&scene);
        let path = std::env::temp_dir().join(format!("kage-pack-materials-{}.glb", std::process::id()));
        let radiance = flat.zeros();
        let export = Export { scene: &scene, flat: &flat, bspvt: None, prt: None, radiance: &radiance, exposure: 0.0 };
        write(&path, &export).unwrap();
        let (back, _) = read(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        let again = kage_engine::scene::flatten(&back);
        for i in 0..flat.instances.len() {
            let (a, b) = (flat.mesh(i), again.mesh(i));
            assert_eq!((&a.uvs, &a.uvs1, &a.colors), (&b.uvs, &b.uvs1, &b.colors), "instance {i}");
            assert_eq!(flat.instances[i].maps.is_empty(), again.instances[i].maps.is_empty());
            for (k, tri) in a.triangles.iter().enumerate().step_by(7) {
                let corners = tri.map(|v| v as usize);
                let bary = [0.2, 0.3, 0.5];
                let (m, n) = (flat.material_at(i, corners, bary), again.material_at(i, corners, bary));
                assert_eq!(m, n, "instance {i}, triangle {k}");
            }
        }
        let poster = again.instances.iter().find_map(|i| i.maps.base_color.filter(|s| s.texcoord == 1)).unwrap();
        assert_eq!(poster.uv(Vec2::ZERO, Vec2::ZERO), Vec2::new(0.5, 0.0));
    }
}
