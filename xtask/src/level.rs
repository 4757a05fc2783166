//! `cargo xtask level`: a generated large scene for scaling benchmarks — a rolling terrain at a
//! fixed 0.5 m vertex spacing, strewn with instanced boulders and standing stones, lit by four
//! quad lights. The level grows with the vertex count at a constant density (terrain area and
//! instance count both ∝ vertices), so a vertex's surroundings look alike at 17K and at 1M and
//! the bake rate per vertex is comparable between sizes.
//!
//! Written as glTF (JSON plus one `.bin`) with real instancing: the boulder and stone meshes
//! are stored once and placed by nodes. The output depends only on the vertex count.

use anyhow::{Context, Result};
use glam::{Quat, Vec2, Vec3};
use kage_engine::scene::shapes;
use serde_json::{Value, json};
use std::path::Path;

/// Terrain vertex spacing in metres.
const SPACING: f32 = 0.5;
/// Share of the vertices in the terrain; the rest are the instances'.
const TERRAIN_SHARE: f64 = 0.6;
/// One instance in this many is a standing stone, the others boulders.
const STONE_EVERY: usize = 5;

/// What [`write`] made.
pub struct Summary {
    /// Receiver vertices in all (terrain plus every instance's).
    pub vertices: usize,
    /// Terrain vertices.
    pub terrain: usize,
    /// Instanced objects.
    pub instances: usize,
    /// The level's side in metres.
    pub side: f32,
}

/// Writes a level of about `vertices` receiver vertices as `out` (`.gltf`) and its `.bin`. With
/// `reach`, each light declares it stays within that many metres of where it is
/// (`extras.kage.light_reach`); without, the lights may go anywhere.
pub fn write(out: &Path, vertices: usize, reach: Option<f32>) -> Result<Summary> {
    let n = ((vertices as f64 * TERRAIN_SHARE).sqrt().round() as usize).max(2);
    let side = (n - 1) as f32 * SPACING;
    let boulder = shapes::sphere(1.0, 32, 16);
    let stone = shapes::cuboid(Vec3::new(0.35, 1.4, 0.2));
    let per_group = (STONE_EVERY - 1) * boulder.positions.len() + stone.positions.len();
    let instances = (vertices.saturating_sub(n * n) * STONE_EVERY).div_ceil(per_group);
    let mut doc = Gltf::default();
    let terrain = terrain(n);
    let materials = [("terrain", [0.45, 0.5, 0.35]), ("boulder", [0.55, 0.5, 0.45]), ("stone", [0.6, 0.6, 0.62])];
    for (name, c) in materials {
        doc.materials.push(json!({"name": name, "pbrMetallicRoughness":
            {"baseColorFactor": [c[0], c[1], c[2], 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.9}}));
    }
    doc.materials.push(json!({"name": "light", "emissiveFactor": [1.0, 0.95, 0.85],
        "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 40.0}},
        "pbrMetallicRoughness": {"baseColorFactor": [0.0, 0.0, 0.0, 1.0]}}));
    let meshes = [("terrain", &terrain, 0), ("boulder", &boulder, 1), ("stone", &stone, 2)];
    for (name, m, material) in meshes {
        doc.mesh(name, &m.positions, &m.normals, &m.triangles, material);
    }
    let h = 1.5;
    let quad = [Vec3::new(-h, 0.0, -h), Vec3::new(h, 0.0, -h), Vec3::new(h, 0.0, h), Vec3::new(-h, 0.0, h)];
    doc.mesh("light", &quad, &[Vec3::NEG_Y; 4], &[[0, 1, 2], [0, 2, 3]], 3);
    doc.nodes.push(json!({"name": "terrain", "mesh": 0}));
    let mut rng = Hash(0x6b61_6765);
    for k in 0..instances {
        let at = Vec2::new(rng.next(), rng.next()) * side - side / 2.0;
        let turn = Quat::from_rotation_y(rng.next() * std::f32::consts::TAU);
        let size = 0.6 + rng.next();
        let (mesh, scale, lift) = if k % STONE_EVERY == STONE_EVERY - 1 {
            (2, Vec3::splat(size), 1.2 * size)
        } else {
            let scale = Vec3::new(1.0 + rng.next(), 0.5 + 0.5 * rng.next(), 1.0 + rng.next()) * size;
            (1, scale, 0.3 * scale.y)
        };
        doc.nodes.push(json!({"name": format!("rock {k}"), "mesh": mesh,
            "translation": [at.x, height(at) + lift, at.y], "rotation": turn.to_array(), "scale": scale.to_array()}));
    }
    for (k, corner) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)].into_iter().enumerate() {
        let at = Vec2::new(corner.0, corner.1) * side / 4.0;
        let at = Vec3::new(at.x, height(at) + 8.0, at.y);
        let mut light = json!({"name": format!("light {k}"), "mesh": 3, "translation": at.to_array()});
        if let Some(r) = reach {
            // The box holds the quad (half-size `h`) wherever it moves within `r`.
            let (lo, hi) = (at - Vec3::new(h + r, r, h + r), at + Vec3::new(h + r, r, h + r));
            light["extras"] = json!({"kage": {"light_reach": {"min": lo.to_array(), "max": hi.to_array()}}});
        }
        doc.nodes.push(light);
    }
    let eye = Vec3::new(-0.55 * side, 0.25 * side + 10.0, 0.55 * side);
    let look = Quat::from_mat3(&glam::Mat3::from_cols_array(&look_at(eye, Vec3::ZERO).to_cols_array()));
    doc.nodes.push(json!({"name": "camera", "camera": 0, "translation": eye.to_array(), "rotation": look.to_array()}));
    doc.save(out)?;
    let terrain_vertices = n * n;
    let (b, s) = (instances - instances / STONE_EVERY, instances / STONE_EVERY);
    let vertices = terrain_vertices + b * boulder.positions.len() + s * stone.positions.len();
    Ok(Summary { vertices, terrain: terrain_vertices, instances, side })
}

/// The terrain's height at `p` (x, z): two octaves of rolling hills, about ±1.5 m.
fn height(p: Vec2) -> f32 {
    1.1 * (0.09 * p.x + 0.3).sin() * (0.07 * p.y).cos() + 0.4 * (0.23 * p.y + 0.17 * p.x).sin()
}

/// An `n × n` vertex terrain centred on the origin.
fn terrain(n: usize) -> kage_engine::scene::Mesh {
    let side = (n - 1) as f32 * SPACING;
    let mut positions = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            let p = Vec2::new(i as f32, j as f32) * SPACING - side / 2.0;
            positions.push(Vec3::new(p.x, height(p), p.y));
        }
    }
    let mut triangles = Vec::with_capacity(2 * (n - 1) * (n - 1));
    let w = n as u32;
    for j in 0..w - 1 {
        for i in 0..w - 1 {
            let a = j * w + i;
            triangles.push([a, a + w, a + 1]);
            triangles.push([a + 1, a + w, a + w + 1]);
        }
    }
    kage_engine::scene::Mesh::new(positions, None, Vec::new(), triangles, false).expect("the terrain is valid").0
}

/// A camera's rotation looking from `eye` at `target` (−Z forward, +Y up, as glTF has it).
fn look_at(eye: Vec3, target: Vec3) -> glam::Mat3 {
    let back = (eye - target).normalize();
    let right = Vec3::Y.cross(back).normalize();
    glam::Mat3::from_cols(right, back.cross(right), back)
}

/// A deterministic stream of numbers in [0, 1) (SplitMix64).
struct Hash(u64);

impl Hash {
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// A glTF document under construction, with its binary buffer.
#[derive(Default)]
struct Gltf {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
    meshes: Vec<Value>,
    materials: Vec<Value>,
    nodes: Vec<Value>,
}

impl Gltf {
    /// Appends `bytes` as a buffer view and an accessor over it; returns the accessor's index.
    fn accessor(&mut self, bytes: &[u8], count: usize, kind: &str, component: u32, extra: Value) -> usize {
        let target = if kind == "SCALAR" { 34963 } else { 34962 };
        self.views
            .push(json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len(), "target": target}));
        self.bin.extend_from_slice(bytes);
        let mut a =
            json!({"bufferView": self.views.len() - 1, "componentType": component, "count": count, "type": kind});
        if let (Value::Object(a), Value::Object(extra)) = (&mut a, extra) {
            a.extend(extra);
        }
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    fn mesh(&mut self, name: &str, positions: &[Vec3], normals: &[Vec3], triangles: &[[u32; 3]], material: usize) {
        let (lo, hi) = positions.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
        let bounds = json!({"min": lo.to_array(), "max": hi.to_array()});
        let p = self.accessor(bytes_of(positions), positions.len(), "VEC3", 5126, bounds);
        let n = self.accessor(bytes_of(normals), normals.len(), "VEC3", 5126, json!({}));
        let i = self.accessor(bytes_of(triangles), triangles.len() * 3, "SCALAR", 5125, json!({}));
        self.meshes.push(json!({"name": name, "primitives":
            [{"attributes": {"POSITION": p, "NORMAL": n}, "indices": i, "material": material}]}));
    }

    /// Writes `path` and the buffer beside it (`path` with `.bin`).
    fn save(self, path: &Path) -> Result<()> {
        let bin = path.with_extension("bin");
        let name = bin.file_name().context("the output needs a file name")?.to_string_lossy();
        let nodes: Vec<usize> = (0..self.nodes.len()).collect();
        let doc = json!({
            "asset": {"version": "2.0", "generator": "cargo xtask level"},
            "extensionsUsed": ["KHR_materials_emissive_strength"],
            "scene": 0, "scenes": [{"nodes": nodes}], "nodes": self.nodes,
            "cameras": [{"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.1}}],
            "meshes": self.meshes, "materials": self.materials, "accessors": self.accessors,
            "bufferViews": self.views, "buffers": [{"uri": name, "byteLength": self.bin.len()}],
        });
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        }
        std::fs::write(&bin, &self.bin).with_context(|| format!("writing {}", bin.display()))?;
        std::fs::write(path, serde_json::to_vec(&doc)?).with_context(|| format!("writing {}", path.display()))
    }
}

fn bytes_of<T: bytemuck::Pod>(v: &[T]) -> &[u8] {
    bytemuck::cast_slice(v)
}

#[cfg(test)]
mod tests {
    use super::*;
    use kage_engine::scene::import::{self, ImportOptions};

    /// The level imports cleanly, with the receiver vertices it says, and is the same bytes
    /// when written twice.
    #[test]
    fn a_generated_level_imports_with_the_vertices_asked_for() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a/level.gltf"), dir.path().join("b/level.gltf"));
        let made = write(&a, 17_000, Some(2.0)).unwrap();
        write(&b, 17_000, Some(2.0)).unwrap();
        assert!((17_000..17_700).contains(&made.vertices), "{} vertices", made.vertices);
        assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
        let scene = import::import(&a, ImportOptions::default()).unwrap();
        let flat = kage_engine::scene::flatten(&scene);
        let receivers: usize = flat.instances.iter().map(|i| flat.meshes[i.mesh as usize].positions.len()).sum();
        assert_eq!(receivers, made.vertices);
        assert_eq!(flat.lights.len(), 4);
        assert_eq!(flat.instances.len(), 1 + made.instances);
    }
}
