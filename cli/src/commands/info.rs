//! `kage info`: what a scene holds.

use crate::scene_args::SceneArgs;
use anyhow::Result;
use kage_engine::scene::{
    Camera, EnvironmentLight, Material, MaterialMaps, MeshRef, Name, NodeId, PolygonLight, PrimitiveId, RigidGroup,
    Transform,
};
use std::fmt::Write;

/// Arguments of `kage info`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    scene: SceneArgs,
}

/// Prints meshes, vertices, triangles, lights, groups, cameras and hashes.
pub fn run(args: &Args) -> Result<()> {
    let scene = args.scene.load()?;
    crate::emit(&describe(&scene)?);
    Ok(())
}

/// The report `kage info` prints.
fn describe(scene: &kage_engine::scene::Scene) -> Result<String, std::fmt::Error> {
    let mut out = String::new();
    let w = &scene.world;
    writeln!(out, "scene: {}", scene.source)?;
    let mut groups: Vec<(u32, String, glam::Vec3)> = w
        .query::<(&RigidGroup, &Name, &Transform)>()
        .iter()
        .map(|(g, n, t)| (g.index, n.0.clone(), t.world.translation.into()))
        .collect();
    groups.sort_by_key(|g| g.0);
    writeln!(out, "groups: {}", groups.len())?;
    for (i, name, p) in &groups {
        writeln!(out, "  [{i}] {name} at ({:.3}, {:.3}, {:.3})", p.x, p.y, p.z)?;
    }
    writeln!(out, "meshes: {} unique", scene.meshes.len())?;
    for (i, m) in scene.meshes.iter().enumerate() {
        let extra = [(!m.uvs1.is_empty(), "  TEXCOORD_1"), (!m.colors.is_empty(), "  vertex colours")];
        let extra: String = extra.iter().filter(|(has, _)| *has).map(|(_, what)| *what).collect();
        writeln!(
            out,
            "  [{i}] hash {}  {} vertices  {} triangles  area {:.4}{extra}",
            m.hash,
            m.positions.len(),
            m.triangles.len(),
            m.area()
        )?;
    }
    let mut instances: Vec<(PrimitiveId, String, MeshRef, bool, String)> = w
        .query::<(&PrimitiveId, &Name, &MeshRef, &Transform, &Material, Option<&MaterialMaps>)>()
        .iter()
        .map(|(id, n, m, t, mat, maps)| (*id, n.0.clone(), *m, t.is_mirrored(), material(scene, mat, maps)))
        .collect();
    instances.sort_by_key(|i| (i.0.node, i.0.mesh, i.0.primitive));
    let (mut verts, mut tris) = (0, 0);
    writeln!(out, "instances: {}", instances.len())?;
    for (id, name, m, mirrored, material) in &instances {
        let mesh = &scene.meshes[m.index as usize];
        verts += mesh.positions.len();
        tris += mesh.triangles.len();
        let mirror = if *mirrored { "  (mirrored)" } else { "" };
        writeln!(
            out,
            "  node {} '{name}' mesh {} primitive {} → mesh [{}] {}{mirror}\n    {material}",
            id.node, id.mesh, id.primitive, m.index, m.hash
        )?;
    }
    writeln!(out, "totals: {verts} vertices, {tris} triangles (instanced, receivers)")?;
    let mut lights: Vec<(u32, PolygonLight)> =
        w.query::<(&PolygonLight, &NodeId)>().iter().map(|(l, n)| (n.0, l.clone())).collect();
    lights.sort_by_key(|l| l.0);
    writeln!(out, "lights: {} polygons", lights.len())?;
    for (node, l) in lights.iter().take(16) {
        let tex = l.texture.map_or(String::new(), |t| format!("  texture {t}"));
        writeln!(
            out,
            "  node {node}: {} vertices, radiance ({:.3}, {:.3}, {:.3}){tex}",
            l.points.len(),
            l.radiance.x,
            l.radiance.y,
            l.radiance.z
        )?;
    }
    if lights.len() > 16 {
        writeln!(out, "  … {} more", lights.len() - 16)?;
    }
    let cameras: Vec<Camera> = w.query::<&Camera>().iter().cloned().collect();
    writeln!(out, "cameras: {}", cameras.len())?;
    for c in &cameras {
        let e = c.eye();
        writeln!(out, "  at ({:.3}, {:.3}, {:.3}) {:?}", e.x, e.y, e.z, c.projection)?;
    }
    for env in w.query::<&EnvironmentLight>().iter() {
        writeln!(
            out,
            "environment: {} ({}×{}), intensity {}, rotation {:.1}°",
            env.map.source,
            env.map.width,
            env.map.height,
            env.intensity,
            env.rotation.to_degrees()
        )?;
        if let Some((sun, _)) = kage_engine::prt::sun::split_light(env) {
            let (d, e) = (sun.direction, sun.irradiance);
            writeln!(
                out,
                "  sun (shaded apart by the baked look): toward ({:.3}, {:.3}, {:.3}), {:.2}° radius, its power within {:.2}° ({} shadow), irradiance ({:.1}, {:.1}, {:.1})",
                d.x,
                d.y,
                d.z,
                sun.angular_radius.to_degrees(),
                sun.spread.to_degrees(),
                if sun.softness() > 0.0 { "soft" } else { "hard" },
                e.x,
                e.y,
                e.z
            )?;
        }
    }
    Ok(out)
}

/// One line for a material: its factors, and the textures that vary them.
fn material(scene: &kage_engine::scene::Scene, m: &Material, maps: Option<&MaterialMaps>) -> String {
    let texture = |slot: Option<kage_engine::scene::TextureSlot>, what: &str| {
        slot.map_or(String::new(), |s| {
            let t = &scene.textures[s.texture as usize];
            format!(" × texture {} ({}×{}, TEXCOORD_{}{what})", s.texture, t.width, t.height, s.texcoord)
        })
    };
    let maps = maps.copied().unwrap_or_default();
    let c = m.base_color;
    let cutout = maps.cutout.map_or(String::new(), |k| {
        format!(", cut out below alpha {} (factor {}{})", k.cutoff, k.factor, texture(k.alpha, "; alpha"))
    });
    format!(
        "material: base colour ({:.3}, {:.3}, {:.3}){}, metallic {:.2}, roughness {:.2}{}{cutout}",
        c.x,
        c.y,
        c.z,
        texture(maps.base_color, ""),
        m.metallic,
        m.roughness,
        texture(maps.metallic_roughness, "; roughness G, metalness B"),
    )
}
