//! Writing a pack: the glTF document as `gltf::json` structures, the extension as
//! [`schema`] records, and the GLB container through `kage_runtime::pack::glb`.

use super::{EXTENSION, Export, VERSION, integrity, schema};
use glam::Vec3;
use gltf::json::{self as gj, Index, validation::Checked::Valid, validation::USize64};
use kage_engine::bspvt;
use kage_engine::math::color::linear_to_srgb;
use kage_engine::prt;
use kage_engine::scene::texture::Wrap;
use kage_engine::scene::{
    Camera, EnvironmentLight, InGroup, Instance, Name, NodeId, PolygonLight, Projection, RigidGroup, Scene, Texture,
    TextureSlot, Transform,
};
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

/// Writes the pack at `path`: to a temporary file beside it, then renamed over it (a reader
/// never sees half a pack, and a symlink at `path` is replaced, never written through).
pub fn write(path: &Path, e: &Export) -> std::io::Result<()> {
    let bytes = encode(e)?;
    kage_engine::output::write_atomically(path, |file| std::io::Write::write_all(file, &bytes))
}

/// The pack's bytes.
fn encode(e: &Export) -> std::io::Result<Vec<u8>> {
    let mut b = Builder::default();
    let groups = groups(e.scene);
    let mut children: Vec<Vec<Index<gj::Node>>> = vec![Vec::new(); groups.len()];
    let group_of = |g: hecs::Entity| groups.iter().position(|x| x.entity == g).expect("every member's group is listed");
    // Group nodes come first (indices 0..groups), so members are numbered after them.
    let member = |b: &Builder| Index::new((b.members.len() + groups.len()) as u32);
    let locals = prt::local_transforms(e.scene, e.flat);
    // Only pixels shaded from the trees leave such vertices out.
    let mut inside = kage_engine::bspvt::pixel::Inside::default();
    let inside = e.bspvt.map(|_| inside.flags(e.flat));
    for (k, inst) in e.flat.instances.iter().enumerate() {
        children[group_of(inst.group)].push(member(&b));
        b.instance(e, k, (inst, &locals[k]), inside.map(|f| &f[k][..]));
    }
    for (light, m, name) in lights(e.scene) {
        children[group_of(m.group)].push(member(&b));
        b.light(e.scene, &light, &m.local, name);
    }
    let mut nodes: Vec<gj::Node> = groups
        .iter()
        .zip(children)
        .map(|(g, c)| node(Some(g.name.clone()), &g.pose, gj::Node { children: Some(c), ..Default::default() }))
        .collect();
    nodes.append(&mut b.members);
    let mut roots: Vec<Index<gj::Node>> = (0..groups.len() as u32).map(Index::new).collect();
    if let Some(cam) = e.scene.first_camera() {
        let camera = b.root.push(camera(&cam));
        roots.push(Index::new(nodes.len() as u32));
        nodes.push(node(Some("camera".into()), &cam.world, gj::Node { camera: Some(camera), ..Default::default() }));
    }
    let mut root = root_extension(e, &mut b);
    let mut doc = b.root;
    doc.nodes = nodes;
    doc.scenes = vec![gj::Scene { nodes: roots, name: None, extensions: None, extras: Default::default() }];
    doc.scene = Some(Index::new(0));
    doc.asset = gj::Asset {
        version: "2.0".into(),
        generator: Some(concat!("kage ", env!("CARGO_PKG_VERSION")).into()),
        ..Default::default()
    };
    doc.extensions_used =
        ["KHR_materials_unlit", "KHR_materials_emissive_strength", EXTENSION].map(String::from).to_vec();
    if b.transforms {
        doc.extensions_used.push("KHR_texture_transform".into());
    }
    doc.buffers = vec![gj::Buffer {
        byte_length: USize64(b.bin.len() as u64),
        name: None,
        uri: None,
        extensions: None,
        extras: Default::default(),
    }];
    let views: Vec<integrity::View> = doc
        .buffer_views
        .iter()
        .map(|v| integrity::View { byte_offset: v.byte_offset.map_or(0, |o| o.0), byte_length: v.byte_length.0 })
        .collect();
    root.integrity = Some(integrity::unsealed(&views, &b.bin));
    doc.extensions = Some(root_extensions(others(&root)));
    let mut json = doc.to_vec().map_err(std::io::Error::other)?;
    integrity::seal(&mut json);
    Ok(kage_runtime::pack::glb::join(&json, &b.bin))
}

/// A rigid group as the pack writes it.
struct Group {
    entity: hecs::Entity,
    pose: glam::Affine3A,
    name: String,
}

/// The scene's groups in their index order.
fn groups(scene: &Scene) -> Vec<Group> {
    let mut groups: Vec<(u32, Group)> = scene
        .world
        .query::<(hecs::Entity, &RigidGroup, &Transform, &Name)>()
        .iter()
        .map(|(entity, r, t, n)| (r.index, Group { entity, pose: t.world, name: n.0.clone() }))
        .collect();
    groups.sort_by_key(|g| g.0);
    groups.into_iter().map(|g| g.1).collect()
}

/// The scene's polygonal lights in source-node order, with their nodes' names.
fn lights(scene: &Scene) -> Vec<(PolygonLight, InGroup, String)> {
    let mut lights: Vec<(u32, PolygonLight, InGroup, String)> = scene
        .world
        .query::<(&PolygonLight, &InGroup, &NodeId, Option<&Name>)>()
        .iter()
        .map(|(l, g, n, name)| (n.0, l.clone(), *g, name.map_or_else(|| "light".into(), |n| n.0.clone())))
        .collect();
    lights.sort_by(|a, b| a.0.cmp(&b.0).then_with(|| a.1.points.len().cmp(&b.1.points.len())));
    lights.into_iter().map(|(_, l, g, name)| (l, g, name)).collect()
}

/// An extension record as the `others` map glTF's extension slots hold.
fn others(record: &impl serde::Serialize) -> serde_json::Map<String, serde_json::Value> {
    let value = serde_json::to_value(record).expect("extension records serialise");
    serde_json::Map::from_iter([(EXTENSION.to_string(), value)])
}

/// `n` named `name` with `a` as its `matrix` (omitted when it is the identity, as glTF asks).
fn node(name: Option<String>, a: &glam::Affine3A, n: gj::Node) -> gj::Node {
    let matrix = (*a != glam::Affine3A::IDENTITY).then(|| glam::Mat4::from(*a).to_cols_array());
    gj::Node { name, matrix, ..n }
}

/// The document under construction, its binary chunk, and the members' nodes.
#[derive(Default)]
struct Builder {
    root: gj::Root,
    bin: Vec<u8>,
    members: Vec<gj::Node>,
    /// Scene texture index → glTF texture, each written once.
    textures: HashMap<u32, Index<gj::Texture>>,
    /// Whether a preview material uses `KHR_texture_transform`.
    transforms: bool,
}

impl Builder {
    /// Appends 4-byte-aligned data as a buffer view.
    fn view(&mut self, data: &[u8], target: Option<gj::buffer::Target>) -> Index<gj::buffer::View> {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let view = gj::buffer::View {
            buffer: Index::new(0),
            byte_length: USize64(data.len() as u64),
            byte_offset: Some(USize64(self.bin.len() as u64)),
            byte_stride: None,
            name: None,
            target: target.map(Valid),
            extensions: None,
            extras: Default::default(),
        };
        self.bin.extend_from_slice(data);
        self.root.push(view)
    }

    /// The index of a buffer view of `data`, for the extension's records.
    fn raw(&mut self, data: &[u8]) -> u32 {
        self.view(data, None).value() as u32
    }

    /// An accessor over a new vertex or index view of `data`.
    fn accessor(&mut self, data: &[u8], count: usize, kind: Kind) -> Index<gj::Accessor> {
        let (component, type_, target) = match kind {
            Kind::Vec3 { .. } => {
                (gj::accessor::ComponentType::F32, gj::accessor::Type::Vec3, gj::buffer::Target::ArrayBuffer)
            }
            Kind::Vec2 => (gj::accessor::ComponentType::F32, gj::accessor::Type::Vec2, gj::buffer::Target::ArrayBuffer),
            Kind::Indices => {
                (gj::accessor::ComponentType::U32, gj::accessor::Type::Scalar, gj::buffer::Target::ElementArrayBuffer)
            }
        };
        let (min, max) = match kind {
            Kind::Vec3 { lo, hi } => (Some(lo.to_array().into()), Some(hi.to_array().into())),
            _ => (None, None),
        };
        let view = self.view(data, Some(target));
        self.root.push(gj::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64(count as u64),
            component_type: Valid(gj::accessor::GenericComponentType(component)),
            extensions: None,
            extras: Default::default(),
            type_: Valid(type_),
            min,
            max,
            name: None,
            normalized: false,
            sparse: None,
        })
    }

    /// A float VEC3 accessor (with min/max, which glTF requires for positions).
    fn vec3(&mut self, v: &[Vec3]) -> Index<gj::Accessor> {
        let (lo, hi) = v.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
        self.accessor(bytemuck::cast_slice(v), v.len(), Kind::Vec3 { lo, hi })
    }

    /// A float VEC2 accessor (texture coordinates).
    fn vec2(&mut self, v: &[glam::Vec2]) -> Index<gj::Accessor> {
        self.accessor(bytemuck::cast_slice(v), v.len(), Kind::Vec2)
    }

    /// A u32 index accessor.
    fn indices(&mut self, i: &[u32]) -> Index<gj::Accessor> {
        self.accessor(bytemuck::cast_slice(i), i.len(), Kind::Indices)
    }

    /// One mesh with one primitive, its node placed by `local`.
    fn member(&mut self, primitive: gj::mesh::Primitive, name: String, local: &glam::Affine3A) {
        let mesh = self.root.push(gj::Mesh {
            extensions: None,
            extras: Default::default(),
            name: None,
            primitives: vec![primitive],
            weights: None,
        });
        self.members.push(node(Some(name), local, gj::Node { mesh: Some(mesh), ..Default::default() }));
    }

    /// Mesh instance `k` (placed at `local` in its group): geometry, the preview on an unlit
    /// material, its bakes, and which of its vertices lie inside geometry (`inside`, per vertex).
    fn instance(&mut self, e: &Export, k: usize, (inst, local): (&Instance, &glam::Affine3A), inside: Option<&[bool]>) {
        let mesh = e.flat.mesh(k);
        let scale = 2f32.powf(e.exposure);
        let preview: Vec<Vec3> = e.radiance[k].iter().map(|v| (*v * scale).clamp(Vec3::ZERO, Vec3::ONE)).collect();
        // COLOR_0 is the preview; the source's own vertex colours go to COLOR_1.
        let mut attributes = BTreeMap::from([
            (Valid(gj::mesh::Semantic::Positions), self.vec3(&mesh.positions)),
            (Valid(gj::mesh::Semantic::Normals), self.vec3(&mesh.normals)),
            (Valid(gj::mesh::Semantic::Colors(0)), self.vec3(&preview)),
        ]);
        let idx: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
        let indices = self.indices(&idx);
        let material = self.material(inst, e.scene);
        let record = schema::Instance {
            instance: k as u64,
            material,
            radiance: self.raw(bytemuck::cast_slice(&e.radiance[k])),
            bounce: e.bounce.map(|b| self.raw(bytemuck::cast_slice(&b[k]))),
            inside: inside
                .map(|f| (0..f.len() as u32).filter(|&v| f[v as usize]).collect::<Vec<u32>>())
                .filter(|v| !v.is_empty())
                .map(|v| self.raw(bytemuck::cast_slice(&v))),
            bspvt: e.bspvt.map(|b| {
                let rec = &b.instances[k];
                schema::BspvtData {
                    offsets: self.raw(bytemuck::cast_slice(&rec.offsets)),
                    records: self.raw(&rec.data),
                }
            }),
            prt: e.prt.map(|p| schema::PrtData { transfer: self.raw(bytemuck::cast_slice(&p.bake.instances[k])) }),
        };
        let mut preview_material = gj::Material {
            name: Some(format!("preview {k}")),
            pbr_metallic_roughness: gj::material::PbrMetallicRoughness {
                base_color_factor: gj::material::PbrBaseColorFactor([1.0; 4]),
                metallic_factor: gj::material::StrengthFactor(0.0),
                roughness_factor: gj::material::StrengthFactor(1.0),
                ..Default::default()
            },
            extensions: Some(gj::extensions::material::Material {
                unlit: Some(gj::extensions::material::Unlit {}),
                ..Default::default()
            }),
            ..Default::default()
        };
        if let Some(c) = &record.material.cutout {
            self.cut_preview(&mut preview_material, c);
        }
        let preview_material = self.root.push(preview_material);
        for (set, uvs) in [(0, &mesh.uvs), (1, &mesh.uvs1)] {
            if !uvs.is_empty() {
                attributes.insert(Valid(gj::mesh::Semantic::TexCoords(set)), self.vec2(uvs));
            }
        }
        if !mesh.colors.is_empty() {
            attributes.insert(Valid(gj::mesh::Semantic::Colors(1)), self.vec3(&mesh.colors));
        }
        let primitive = primitive(attributes, indices, preview_material, &record);
        self.member(primitive, format!("instance {k}"), local);
    }

    /// Makes `m` cut out as `c` says, so that a glTF viewer shows the holes: `MASK`, the
    /// cutoff, the factor in the base colour's alpha, and the mask texture (RGB white) as the
    /// base-colour texture with its UV set and transform.
    fn cut_preview(&mut self, m: &mut gj::Material, c: &schema::Cutout) {
        m.alpha_mode = Valid(gj::material::AlphaMode::Mask);
        m.alpha_cutoff = Some(gj::material::AlphaCutoff(c.cutoff));
        m.pbr_metallic_roughness.base_color_factor.0[3] = c.factor;
        m.pbr_metallic_roughness.base_color_texture = c.alpha_texture.as_ref().map(|s| {
            let t = glam::Affine2::from_cols_array(&s.transform);
            let extensions = (t != glam::Affine2::IDENTITY).then(|| {
                self.transforms = true;
                gj::extensions::texture::Info {
                    texture_transform: Some(gj::extensions::texture::TextureTransform {
                        offset: gj::extensions::texture::TextureTransformOffset(t.translation.to_array()),
                        rotation: gj::extensions::texture::TextureTransformRotation(
                            (-t.matrix2.x_axis.y).atan2(t.matrix2.x_axis.x),
                        ),
                        scale: gj::extensions::texture::TextureTransformScale([
                            t.matrix2.x_axis.length(),
                            t.matrix2.y_axis.length(),
                        ]),
                        tex_coord: None,
                        extras: Default::default(),
                    }),
                    others: Default::default(),
                }
            });
            gj::texture::Info {
                index: Index::new(s.index),
                tex_coord: s.tex_coord,
                extensions,
                extras: Default::default(),
            }
        });
    }

    /// A polygonal light: an emissive triangle fan, its exact values in the extension.
    fn light(&mut self, scene: &Scene, light: &PolygonLight, local: &glam::Affine3A, name: String) {
        let mut attributes = BTreeMap::from([(Valid(gj::mesh::Semantic::Positions), self.vec3(&light.points))]);
        let fan: Vec<u32> = (1..light.points.len() as u32 - 1).flat_map(|i| [0, i, i + 1]).collect();
        let indices = self.indices(&fan);
        let strength = light.radiance.max_element().max(1e-30);
        // The exact radiance (factor × strength need not round-trip in f32), polygon and UVs
        // (the importer may start the re-imported loop at another corner).
        let mut record = schema::Light {
            light_radiance: light.radiance.to_array(),
            light_polygon: light.points.iter().flat_map(|p| p.to_array()).collect(),
            light_reach: light.reach.map(|[lo, hi]| [lo.x, lo.y, lo.z, hi.x, hi.y, hi.z]),
            light_uvs: None,
        };
        let mut emissive_texture = None;
        if let Some(t) = light.texture.filter(|_| light.uvs.len() == light.points.len()) {
            let index = self.texture(t, &scene.textures[t as usize], Encoding::Srgb);
            emissive_texture =
                Some(gj::texture::Info { index, tex_coord: 0, extensions: None, extras: Default::default() });
            attributes.insert(Valid(gj::mesh::Semantic::TexCoords(0)), self.vec2(&light.uvs));
            record.light_uvs = Some(light.uvs.iter().flat_map(|uv| uv.to_array()).collect());
        }
        let material = self.root.push(gj::Material {
            name: Some("light".into()),
            pbr_metallic_roughness: gj::material::PbrMetallicRoughness {
                base_color_factor: gj::material::PbrBaseColorFactor([0.0, 0.0, 0.0, 1.0]),
                ..Default::default()
            },
            emissive_factor: gj::material::EmissiveFactor((light.radiance / strength).to_array()),
            emissive_texture,
            extensions: Some(gj::extensions::material::Material {
                emissive_strength: Some(gj::extensions::material::EmissiveStrength {
                    emissive_strength: gj::extensions::material::EmissiveStrengthFactor(strength),
                }),
                ..Default::default()
            }),
            ..Default::default()
        });
        self.member(primitive(attributes, indices, material, &record), name, local);
    }

    /// The extension's record of an instance's material: its factors and texture slots.
    fn material(&mut self, inst: &Instance, scene: &Scene) -> schema::Material {
        let mut slot = |s: Option<TextureSlot>, encoding: Encoding| {
            s.map(|s| schema::TextureSlot {
                index: self.texture(s.texture, &scene.textures[s.texture as usize], encoding).value() as u32,
                tex_coord: s.texcoord,
                transform: s.transform.to_cols_array(),
            })
        };
        let base_color_texture = slot(inst.maps.base_color, Encoding::Srgb);
        let metallic_roughness_texture = slot(inst.maps.metallic_roughness, Encoding::Linear);
        let cutout = inst.maps.cutout.map(|c| schema::Cutout {
            factor: c.factor,
            cutoff: c.cutoff,
            alpha_texture: slot(c.alpha, Encoding::Alpha),
        });
        let m = &inst.material;
        schema::Material {
            base_color: m.base_color.to_array(),
            metallic: m.metallic,
            roughness: m.roughness,
            specular: m.specular,
            base_color_texture,
            metallic_roughness_texture,
            cutout,
        }
    }

    /// The glTF texture for scene texture `index`, written on first use as an 8-bit PNG.
    fn texture(&mut self, index: u32, t: &Texture, encoding: Encoding) -> Index<gj::Texture> {
        if let Some(&k) = self.textures.get(&index) {
            return k;
        }
        let view = self.view(&png(t, encoding), None);
        let source = self.root.push(gj::Image {
            buffer_view: Some(view),
            mime_type: Some(gj::image::MimeType("image/png".into())),
            name: None,
            uri: None,
            extensions: None,
            extras: Default::default(),
        });
        let wrap = |w: Wrap| {
            Valid(match w {
                Wrap::Clamp => gj::texture::WrappingMode::ClampToEdge,
                Wrap::Mirror => gj::texture::WrappingMode::MirroredRepeat,
                Wrap::Repeat => gj::texture::WrappingMode::Repeat,
            })
        };
        let sampler = self.root.push(gj::texture::Sampler {
            mag_filter: Some(Valid(gj::texture::MagFilter::Linear)),
            min_filter: Some(Valid(gj::texture::MinFilter::LinearMipmapLinear)),
            name: None,
            wrap_s: wrap(t.wrap[0]),
            wrap_t: wrap(t.wrap[1]),
            extensions: None,
            extras: Default::default(),
        });
        let texture = self.root.push(gj::Texture {
            name: None,
            sampler: Some(sampler),
            source,
            extensions: None,
            extras: Default::default(),
        });
        self.textures.insert(index, texture);
        texture
    }
}

/// What an accessor holds.
enum Kind {
    /// Float triples with their bounds.
    Vec3 { lo: Vec3, hi: Vec3 },
    /// Float pairs.
    Vec2,
    /// u32 triangle indices.
    Indices,
}

/// A triangle-list primitive carrying `record` as its extension.
fn primitive(
    attributes: BTreeMap<gltf::json::validation::Checked<gj::mesh::Semantic>, Index<gj::Accessor>>,
    indices: Index<gj::Accessor>,
    material: Index<gj::Material>,
    record: &impl serde::Serialize,
) -> gj::mesh::Primitive {
    gj::mesh::Primitive {
        attributes,
        extensions: Some(gj::extensions::mesh::Primitive { others: others(record) }),
        extras: Default::default(),
        indices: Some(indices),
        material: Some(material),
        mode: Valid(gj::mesh::Mode::Triangles),
        targets: None,
    }
}

/// `t` as a PNG, encoded as `encoding` says. Textures imported from 8-bit images come back bit
/// for bit (every byte round-trips through [`linear_to_srgb`]; tested beside it); others round
/// to the nearest byte.
fn png(t: &Texture, encoding: Encoding) -> Vec<u8> {
    let unit = |x: f32| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
    let (w, h) = (t.width as u32, t.height as u32);
    let image: image::DynamicImage = match encoding {
        Encoding::Alpha => {
            let rgba = t.texels.iter().flat_map(|c| [255, 255, 255, unit(c.x)]).collect();
            image::RgbaImage::from_raw(w, h, rgba).expect("texel count matches").into()
        }
        Encoding::Srgb | Encoding::Linear => {
            let srgb = encoding == Encoding::Srgb;
            let encode = |x: f32| unit(if srgb { linear_to_srgb(x.clamp(0.0, 1.0)) } else { x });
            let rgb = t.texels.iter().flat_map(|c| c.to_array().map(encode)).collect();
            image::RgbImage::from_raw(w, h, rgb).expect("texel count matches").into()
        }
    };
    let mut out = std::io::Cursor::new(Vec::new());
    image.write_to(&mut out, image::ImageFormat::Png).expect("PNG encoding into memory");
    out.into_inner()
}

/// How a scene texture's linear values become a PNG's bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Encoding {
    /// Colours, sRGB-encoded.
    Srgb,
    /// Data as is.
    Linear,
    /// A cut-out's mask in the alpha channel, RGB white: a viewer's MASK material reads it.
    Alpha,
}

/// The glTF camera for `c`.
fn camera(c: &Camera) -> gj::Camera {
    let (type_, perspective, orthographic) = match c.projection {
        Projection::Perspective { yfov } => (
            gj::camera::Type::Perspective,
            Some(gj::camera::Perspective {
                aspect_ratio: None,
                yfov,
                zfar: None,
                znear: 0.01,
                extensions: None,
                extras: Default::default(),
            }),
            None,
        ),
        Projection::Orthographic { ymag } => (
            gj::camera::Type::Orthographic,
            None,
            Some(gj::camera::Orthographic {
                xmag: ymag,
                ymag,
                zfar: 1000.0,
                znear: 0.0,
                extensions: None,
                extras: Default::default(),
            }),
        ),
    };
    gj::Camera {
        name: None,
        orthographic,
        perspective,
        type_: Valid(type_),
        extensions: None,
        extras: Default::default(),
    }
}

/// The root extension record: settings of the bakes and the environment's exact texels.
fn root_extension(e: &Export, b: &mut Builder) -> schema::Root {
    let bspvt = e.bspvt.map(|b| schema::BspvtHeader {
        face_resolution: b.settings.res as u64,
        epsilon: b.settings.epsilon,
        format: bspvt::layout::FORMAT_VERSION,
    });
    let prt = e.prt.map(|prt::Parts { bake: p, lighting: light, settings: s }| schema::PrtHeader {
        order: p.order as u64,
        directions: s.direction_side().pow(2) as u64,
        algorithm: prt::ALGORITHM_VERSION,
        window: light.window.into(),
        silhouette_resolution: s.silhouette_res as u64,
        lighting: light.coeffs.iter().map(|c| c.to_array()).collect(),
        regions: regions(&light.regions),
        sunless: light.sunless.as_ref().map(|(_, rest)| schema::Sunless {
            lighting: rest.coeffs.iter().map(|c| c.to_array()).collect(),
            regions: regions(&rest.regions),
        }),
    });
    // Exact texels (f32 RGB, row 0 = +Y): the specular term prefilters them on load.
    let environment = e.scene.world.query::<&EnvironmentLight>().iter().next().map(|env| schema::Environment {
        width: env.map.width as u64,
        height: env.map.height as u64,
        texels: b.raw(bytemuck::cast_slice(&env.map.texels)),
        intensity: env.intensity,
        rotation: env.rotation,
    });
    schema::Root { version: VERSION, preview_exposure: e.exposure, bspvt, prt, environment, integrity: None }
}

/// The root's extensions holding `others`. Its other fields depend on the gltf crate's
/// features (a build that also has Bevy's glTF loader turns on `KHR_lights_punctual`'s), so
/// they take their defaults — an update clippy finds needless where that feature is off.
#[allow(clippy::needless_update)]
fn root_extensions(others: serde_json::Map<String, serde_json::Value>) -> gj::extensions::root::Root {
    gj::extensions::root::Root { others, ..Default::default() }
}

/// An environment's regions as the pack records them.
fn regions(regions: &[prt::regions::Region]) -> Vec<schema::Region> {
    let record = |r: &prt::regions::Region| schema::Region {
        power: r.power.to_array(),
        direction: r.dir.to_array(),
        solid_angle: r.solid_angle,
        spread: r.spread,
    };
    regions.iter().map(record).collect()
}
