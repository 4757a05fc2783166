//! Reading a pack into kage's scene: the pack read and checked by the runtime
//! ([`Pack::read`]), the scene through kage's glTF importer, then what the preview replaced
//! (the real materials, the lights' exact values) and the bakes put back.

use super::{Contents, schema};
use glam::DVec3;
use kage_engine::bspvt;
use kage_engine::prt::{self, Lighting, regions::Region};
use kage_engine::scene::import::{self, Channels, ImportOptions};
use kage_engine::scene::{
    Cutout, EnvMap, EnvironmentLight, FlatScene, Material, MaterialMaps, NodeId, PolygonLight, PrimitiveId, Scene,
    TextureSlot,
};
use kage_engine::{Error, Result};
use kage_runtime::pack::Pack;
use std::collections::HashMap;
use std::path::Path;

/// A pack's problem, naming the file.
fn bad(path: &Path, what: impl std::fmt::Display) -> Error {
    Error::Invalid(format!("{}: not a kage pack: {what}", path.display()))
}

/// Reads a pack: the scene (materials restored from the extension) and its bakes. Its
/// integrity (version 4 on) is verified before anything is read from it, and every number it
/// holds is checked finite and in range ([`Pack::read`]).
pub fn read(path: &Path) -> Result<(Scene, Contents)> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let mut pack = Pack::read(&bytes).map_err(|e| bad(path, e))?;
    let mut scene = import::import(path, ImportOptions { color_set: 1, ..Default::default() })?;
    restore_lights(&mut scene, &pack.lights).map_err(|e| bad(path, e))?;
    let flat = kage_engine::scene::flatten(&scene);
    let counts = |f: &FlatScene| (0..f.instances.len()).map(|i| f.vertex_count(i)).collect::<Vec<_>>();
    if counts(&flat) != pack.instances.iter().map(|i| i.mesh.positions.len()).collect::<Vec<_>>() {
        return Err(bad(path, "its baked meshes do not match the scene's instances"));
    }
    restore_materials(&mut scene, &flat, &pack).map_err(|e| bad(path, e))?;
    // The environment before the PRT record: its lighting splits the map's sun off.
    if let Some(env) = &pack.environment {
        scene.set_environment(environment(path, env).map_err(|e| bad(path, e))?);
    }
    let flat = kage_engine::scene::flatten(&scene);
    let bspvt =
        pack.header.bspvt.as_ref().map(|h| bspvt(h, &mut pack.instances)).transpose().map_err(|e| bad(path, e))?;
    let prt =
        pack.header.prt.as_ref().map(|h| prt(h, &mut pack.instances, &flat)).transpose().map_err(|e| bad(path, e))?;
    let warnings = pack.warnings.iter().map(|w| format!("{}: {w}", path.display())).collect();
    let bounce = pack.instances.iter_mut().map(|i| i.bounce.take()).collect();
    Ok((scene, Contents { bspvt, prt, bounce, warnings }))
}

type Checked<T> = std::result::Result<T, String>;

/// Puts each instance's real material (factors and textures) back in place of the preview.
fn restore_materials(scene: &mut Scene, flat: &FlatScene, pack: &Pack) -> Checked<()> {
    // Instances re-import in node order, which is the pack's instance order.
    let entities: HashMap<PrimitiveId, hecs::Entity> =
        scene.world.query::<(hecs::Entity, &PrimitiveId)>().iter().map(|(e, id)| (*id, e)).collect();
    let mut decoded = HashMap::new();
    for (k, (inst, record)) in flat.instances.iter().zip(&pack.instances).enumerate() {
        let m = &record.material;
        let material = Material::from(m);
        let mut slot = |s: &Option<schema::TextureSlot>, channels| {
            s.as_ref().map(|s| texture_slot(pack, s, channels, scene, &mut decoded)).transpose()
        };
        let cutout = match &m.cutout {
            Some(c) if !(c.factor.is_finite() && c.cutoff.is_finite()) => {
                return Err(format!("mesh {k}: the cut-out's factor and cutoff are not numbers"));
            }
            Some(c) => Some(Cutout {
                alpha: slot(&c.alpha_texture, Channels::Alpha).map_err(|e| format!("mesh {k}: alphaTexture: {e}"))?,
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
    pack: &Pack,
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
            let source =
                pack.textures.get(s.index as usize).ok_or_else(|| format!("texture {}: no such texture", s.index))?;
            let t = import::decode_texture(&source.image, channels, source.wrap)
                .map_err(|e| format!("texture {}: {e}", s.index))?;
            scene.textures.push(std::sync::Arc::new(t));
            let t = scene.textures.len() as u32 - 1;
            decoded.insert((s.index, channels), t);
            t
        }
    };
    let transform = glam::Affine2::from_cols_array(&s.transform);
    Ok(TextureSlot { texture, texcoord: s.tex_coord, transform })
}

/// The BSPVT bake: every instance's records (checked record by record as the pack was read).
fn bspvt(h: &schema::BspvtHeader, instances: &mut [kage_runtime::pack::Instance]) -> Checked<bspvt::Bake> {
    let settings = bspvt::Settings { res: count(h.face_resolution), epsilon: h.epsilon };
    settings.check().map_err(|e| format!("BSPVT: {e}"))?;
    let instances = instances.iter_mut().map(|i| i.bspvt.take().expect("read with the header")).collect();
    Ok(bspvt::Bake { settings, instances, stats: bspvt::Stats::default() })
}

/// The PRT bake, its lighting and settings (their ranges checked as the pack was read).
fn prt(
    h: &schema::PrtHeader,
    instances: &mut [kage_runtime::pack::Instance],
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
    let coeffs: Vec<DVec3> = h.lighting.iter().map(|c| DVec3::from_array(*c)).collect();
    let regions: Vec<Region> = h.regions.iter().map(Region::from).collect();
    let instances = instances.iter_mut().map(|i| i.transfer.take().expect("read with the header")).collect();
    let lobes = prt::lighting::negative_lobes(&coeffs, settings.window);
    let bake = prt::Bake { order: settings.order, instances, stats: prt::Stats::default() };
    let lighting = Lighting { coeffs, regions, window: settings.window, lobes, sunless: None };
    // With the map in the pack, the baked look shades its sun apart as from a database.
    let lighting = match &flat.environment {
        Some(env) => lighting.splitting_sun(env, &settings),
        None => lighting,
    };
    Ok((bake, lighting, settings))
}

/// The environment light: its exact texels, intensity and rotation.
fn environment(path: &Path, env: &kage_runtime::pack::Environment) -> Checked<EnvironmentLight> {
    let map = EnvMap::new(env.width, env.height, env.texels.clone(), format!("{}#environment", path.display()))
        .map_err(|e| format!("environment: {e}"))?;
    let mut light = EnvironmentLight::new(map);
    (light.intensity, light.rotation) = (env.intensity, env.rotation);
    Ok(light)
}

/// A declared count as `usize` (saturating: every count is checked against the data present).
fn count(n: u64) -> usize {
    usize::try_from(n).unwrap_or(usize::MAX)
}

/// Puts back each light's exact radiance, polygon, UVs and reach (lights re-import in the order
/// they were written).
fn restore_lights(scene: &mut Scene, lights: &[kage_runtime::pack::Light]) -> Checked<()> {
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
        let mut l = scene.world.get::<&mut PolygonLight>(*e).expect("queried above");
        if rec.polygon.len() != l.points.len() {
            return Err("a light polygon does not match its mesh".into());
        }
        if l.texture.is_some() && rec.uvs.len() != rec.polygon.len() {
            return Err("a textured light's UVs do not match its polygon".into());
        }
        (l.radiance, l.points, l.uvs, l.reach) = (rec.radiance, rec.polygon.clone(), rec.uvs.clone(), rec.reach);
    }
    Ok(())
}
