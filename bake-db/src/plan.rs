//! The bake plan: which artefacts a scene needs (per instance, per chunk of vertices), their
//! keys, which are already in the store, and what the misses should cost.
//!
//! - **BSPVT** (polygonal lights present): visibility depends on the whole scene, so a chunk's
//!   key covers its receiver (mesh hash, world transform) and the occluder snapshot (every
//!   instance's id, mesh hash — with its cut-out's mask, if any — and world transform). Its *slot* (the key without the snapshot)
//!   remembers the last artefact baked there and the snapshot it saw — the lineage that lets an
//!   edit re-bake only the cube faces that can see what changed.
//! - **PRT** (an environment present): a chunk's key covers the instance's mesh hash, its
//!   transform relative to its group, and the group's own geometry in the group's frame — never
//!   where the group is.

use crate::key::{Key, KeyHasher};
use crate::store::{Result, Store};
use glam::{Affine3A, Vec3};
use kage_engine::scene::{FlatScene, InGroup, MaterialMaps, PolygonLight, PrimitiveId, Scene, cutout};
use kage_engine::{bspvt, prt};
use std::collections::HashMap;
use std::ops::Range;

/// Vertices per artefact: the unit of caching, resuming and writing.
pub const CHUNK: usize = 256;

/// Which technique a job bakes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Kind {
    /// BSPVT visibility trees.
    Bspvt,
    /// PRT self-transfer.
    Prt,
}

impl Kind {
    /// The name used in keys, metadata and messages.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Bspvt => "bspvt",
            Kind::Prt => "prt",
        }
    }
}

/// One artefact: a chunk of one instance's vertices for one technique.
#[derive(Clone, Debug)]
pub struct Job {
    /// Technique.
    pub kind: Kind,
    /// Instance index in the snapshot.
    pub instance: usize,
    /// Vertex range.
    pub vertices: Range<usize>,
    /// Bake key.
    pub key: Key,
    /// Lineage slot (BSPVT only).
    pub slot: Option<Key>,
    /// Already in the store.
    pub cached: bool,
}

/// One instance as an occluder: identity, mesh, placement, bounds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Occluder {
    /// glTF origin (node, mesh, primitive).
    pub id: [u32; 3],
    /// Mesh content hash (with the cut-out's mask: [`FlatScene::occluder_hash`]).
    pub mesh: [u8; 32],
    /// World transform.
    pub world: [f32; 12],
    /// World bounds (min, max).
    pub bounds: [f32; 6],
}

/// Bytes of one encoded [`Occluder`]: 3 u32 + 32 + 12 f32 + 6 f32.
pub const OCCLUDER_BYTES: usize = 12 + 32 + 48 + 24;

/// The scene's occluders, in snapshot order, and their hash.
#[derive(Clone, Debug, PartialEq)]
pub struct Snapshot {
    /// Every instance (lights are not occluders of BSPVT visibility).
    pub occluders: Vec<Occluder>,
    /// Hash of the list.
    pub hash: Key,
}

impl Snapshot {
    /// The snapshot of a flattened scene.
    pub fn of(flat: &FlatScene) -> Self {
        let occluders: Vec<Occluder> = flat
            .instances
            .iter()
            .enumerate()
            .map(|(i, inst)| {
                let mesh = &flat.meshes[inst.mesh as usize];
                let (lo, hi) = mesh.positions.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| {
                    let w = inst.world.transform_point3(*p);
                    (lo.min(w), hi.max(w))
                });
                Occluder {
                    id: [inst.id.node, inst.id.mesh, inst.id.primitive],
                    mesh: flat.occluder_hash(i),
                    world: inst.world.to_cols_array(),
                    bounds: [lo.x, lo.y, lo.z, hi.x, hi.y, hi.z],
                }
            })
            .collect();
        let hash = KeyHasher::new("occluders").bytes("list", &encode_occluders(&occluders)).finish();
        Self { occluders, hash }
    }
}

/// Serialises occluders as POD (id, mesh, world, bounds), [`OCCLUDER_BYTES`] each.
pub fn encode_occluders(o: &[Occluder]) -> Vec<u8> {
    let mut out = Vec::with_capacity(o.len() * OCCLUDER_BYTES);
    for x in o {
        out.extend_from_slice(bytemuck::cast_slice(&x.id));
        out.extend_from_slice(&x.mesh);
        out.extend_from_slice(bytemuck::cast_slice(&x.world));
        out.extend_from_slice(bytemuck::cast_slice(&x.bounds));
    }
    out
}

/// The inverse of [`encode_occluders`] (`None` for malformed bytes).
pub fn decode_occluders(b: &[u8]) -> Option<Vec<Occluder>> {
    if !b.len().is_multiple_of(OCCLUDER_BYTES) {
        return None;
    }
    Some(
        b.chunks_exact(OCCLUDER_BYTES)
            .map(|c| Occluder {
                id: bytemuck::pod_read_unaligned(&c[..12]),
                mesh: c[12..44].try_into().expect("32 bytes"),
                world: bytemuck::pod_read_unaligned(&c[44..92]),
                bounds: bytemuck::pod_read_unaligned(&c[92..116]),
            })
            .collect(),
    )
}

/// What a scene's bake needs: settings per technique (`None`: not needed) and the jobs.
#[derive(Clone, Debug)]
pub struct Plan {
    /// BSPVT settings, when the scene has polygonal lights.
    pub bspvt: Option<bspvt::Settings>,
    /// PRT settings, when the scene has an environment.
    pub prt: Option<prt::Settings>,
    /// Every artefact, instance by instance.
    pub jobs: Vec<Job>,
    /// The occluder snapshot BSPVT keys were made against.
    pub snapshot: Snapshot,
    /// Where the polygonal lights can be (part of BSPVT keys and slots).
    pub reach: bspvt::reach::Reach,
}

impl Plan {
    /// Jobs not yet in the store.
    pub fn misses(&self) -> impl Iterator<Item = &Job> {
        self.jobs.iter().filter(|j| !j.cached)
    }

    /// The parameters of a technique's artefacts, as recorded in their metadata (with the
    /// algorithm version).
    pub fn params(&self, kind: Kind) -> String {
        match kind {
            Kind::Bspvt => self.bspvt.map_or_else(String::new, |s| {
                format!(
                    "{}² faces, ε {}, {}, algorithm {}, format {}",
                    s.res,
                    s.epsilon,
                    self.reach,
                    bspvt::ALGORITHM_VERSION,
                    bspvt::layout::FORMAT_VERSION
                )
            }),
            Kind::Prt => self.prt.map_or_else(String::new, |s| {
                format!(
                    "order {}, {} directions, algorithm {}",
                    s.order,
                    s.direction_side().pow(2),
                    prt::ALGORITHM_VERSION
                )
            }),
        }
    }

    /// Every key (what the scene references).
    pub fn keys(&self) -> Vec<Key> {
        self.jobs.iter().map(|j| j.key).collect()
    }

    /// Seconds per vertex of a technique on one worker before any bake measured it (the
    /// defaults of `docs/bake-db.md`): BSPVT ≈ 10 ms at 64² faces, ∝ res²; PRT ≈ 80 µs at 1024
    /// directions, ∝ directions.
    pub fn default_seconds_per_vertex(&self, kind: Kind) -> f64 {
        match kind {
            Kind::Bspvt => self.bspvt.map_or(0.0, |s| 1e-2 * (s.res as f64 / 64.0).powi(2)),
            Kind::Prt => self.prt.map_or(0.0, |s| 8e-5 * s.direction_side().pow(2) as f64 / 1024.0),
        }
    }

    /// The work of a job in full-vertex units: a BSPVT vertex casts only the share of its tiles
    /// the lights can reach. Deterministic: summed in vertex order whatever the thread count.
    pub fn work(&self, flat: &FlatScene, job: &Job) -> f64 {
        use rayon::prelude::*;
        match (job.kind, self.bspvt, &self.reach) {
            (Kind::Bspvt, Some(s), reach @ bspvt::reach::Reach::Within(_)) => {
                let shares: Vec<f64> = job
                    .vertices
                    .clone()
                    .into_par_iter()
                    .map(|v| {
                        let (p, n) = flat.vertex(job.instance, v);
                        reach.share(p, n, s.res)
                    })
                    .collect();
                shares.iter().sum()
            }
            _ => job.vertices.len() as f64,
        }
    }
}

/// Plans the bakes of a snapshot: BSPVT when it has polygonal lights and `bspvt` is given, PRT
/// when it has an environment and `prt` is given.
pub fn plan(
    store: &Store,
    scene: &Scene,
    flat: &FlatScene,
    bspvt: Option<bspvt::Settings>,
    prt: Option<prt::Settings>,
) -> Result<Plan> {
    let bspvt = bspvt.filter(|_| !flat.lights.is_empty());
    let prt = prt.filter(|_| flat.environment.is_some());
    let snapshot = Snapshot::of(flat);
    let reach = bspvt::reach::Reach::of(&flat.lights);
    let mut jobs = Vec::new();
    if let Some(s) = bspvt {
        for (i, inst) in flat.instances.iter().enumerate() {
            let mut base = KeyHasher::new("bspvt")
                .u64("version", bspvt::layout::FORMAT_VERSION as u64)
                .u64("algorithm", bspvt::ALGORITHM_VERSION as u64)
                .u64("res", s.res as u64)
                .f64("epsilon", s.epsilon)
                .bytes("mesh", &flat.meshes[inst.mesh as usize].hash.0)
                .affine("world", &inst.world);
            // Lights that may go anywhere add nothing: keys baked before reaches existed stay valid.
            if reach != bspvt::reach::Reach::Anywhere {
                base = base.bytes("reach", &reach.key_bytes());
            }
            let id = [inst.id.node, inst.id.mesh, inst.id.primitive];
            for (c, vertices) in chunks(flat, i) {
                let key = base.clone().bytes("occluders", snapshot.hash.as_bytes()).u64("chunk", c as u64).finish();
                let slot = base.clone().bytes("id", bytemuck::cast_slice(&id)).u64("slot", c as u64).finish();
                jobs.push(Job { kind: Kind::Bspvt, instance: i, vertices, key, slot: Some(slot), cached: false });
            }
        }
    }
    if let Some(s) = prt {
        let groups = group_geometry(scene);
        let locals = prt::local_transforms(scene, flat);
        for (i, inst) in flat.instances.iter().enumerate() {
            let base = KeyHasher::new("prt")
                .u64("version", prt::ALGORITHM_VERSION as u64)
                .u64("order", s.order as u64)
                .u64("directions", s.direction_side().pow(2) as u64)
                .bytes("mesh", &flat.meshes[inst.mesh as usize].hash.0)
                .affine("local", &locals[i])
                .bytes("group", groups[&inst.group].as_bytes());
            for (c, vertices) in chunks(flat, i) {
                let key = base.clone().u64("chunk", c as u64).finish();
                jobs.push(Job { kind: Kind::Prt, instance: i, vertices, key, slot: None, cached: false });
            }
        }
    }
    let present = store.contains_all(&jobs.iter().map(|j| j.key).collect::<Vec<_>>())?;
    jobs.iter_mut().zip(present).for_each(|(j, p)| j.cached = p);
    Ok(Plan { bspvt, prt, jobs, snapshot, reach })
}

/// (chunk index, vertex range) of instance `i`.
fn chunks(flat: &FlatScene, i: usize) -> Vec<(usize, Range<usize>)> {
    let n = flat.vertex_count(i);
    (0..n.div_ceil(CHUNK)).map(|c| (c, c * CHUNK..((c + 1) * CHUNK).min(n))).collect()
}

/// Per group: a hash of its geometry in its own frame (members' meshes and group-relative
/// transforms, lights' polygons), in glTF order.
fn group_geometry(scene: &Scene) -> HashMap<hecs::Entity, Key> {
    let mut members: HashMap<hecs::Entity, Vec<(PrimitiveId, [u8; 32], Affine3A)>> = HashMap::new();
    let mut query =
        scene.world.query::<(&PrimitiveId, &kage_engine::scene::MeshRef, &InGroup, Option<&MaterialMaps>)>();
    for (id, m, g, maps) in query.iter() {
        let cutout = maps.and_then(|m| m.cutout.as_ref());
        let mesh = cutout::occluder_hash(&scene.meshes[m.index as usize], cutout, &scene.textures);
        members.entry(g.group).or_default().push((*id, mesh, g.local));
    }
    let mut lights: HashMap<hecs::Entity, Vec<f32>> = HashMap::new();
    for (l, g) in scene.world.query::<(&PolygonLight, &InGroup)>().iter() {
        let pts = lights.entry(g.group).or_default();
        pts.extend(l.points.iter().flat_map(|p| g.local.transform_point3(*p).to_array()));
    }
    members
        .into_iter()
        .map(|(g, mut list)| {
            list.sort_by_key(|(id, ..)| (id.node, id.mesh, id.primitive));
            let mut h = KeyHasher::new("group");
            for (_, mesh, local) in &list {
                h = h.bytes("mesh", mesh).affine("local", local);
            }
            let light_points = lights.remove(&g).unwrap_or_default();
            (g, h.bytes("lights", bytemuck::cast_slice(&light_points)).finish())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn occluders_round_trip_through_their_encoding() {
        let o = Occluder {
            id: [3, 1, 0],
            mesh: [7; 32],
            world: std::array::from_fn(|i| i as f32 * 0.5 - 1.0),
            bounds: [-1.0, 0.0, -2.5, 1.0, 3.0, 2.5],
        };
        let bytes = encode_occluders(&[o, o]);
        assert_eq!(bytes.len(), 2 * OCCLUDER_BYTES);
        assert_eq!(decode_occluders(&bytes).unwrap(), vec![o, o]);
        assert!(decode_occluders(&bytes[1..]).is_none());
    }
}
