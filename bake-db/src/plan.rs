//! The bake plan: which artefacts a scene needs (per instance, per chunk of vertices), their
//! keys, which are already in the store, and what the misses should cost.
//!
//! A chunk is a run of an instance's vertices cut where their content says ([`chunks`]), and
//! its keys hash those vertices (positions and normals), not the whole mesh: an edit that
//! changes one stretch of a mesh's vertices — receiver refinement following a moved shadow —
//! leaves the other chunks' keys as they were.
//!
//! - **BSPVT** (polygonal lights present): visibility depends on the whole scene, so a chunk's
//!   key covers its vertices, its instance's world transform, and the occluder snapshot (every
//!   instance's id, occluding mesh's hash — with its cut-out's mask, if any — and world
//!   transform). Its *slot* (its instance, transform and place: the vertex the chunk ends at)
//!   remembers the last artefact baked there, the snapshot it saw and its vertices — the
//!   lineage that lets an edit re-bake only the cube faces that can see what changed, of every
//!   vertex the chunk still holds.
//! - **PRT** (an environment present): a chunk's key covers its vertices, the instance's
//!   transform relative to its group, and the group's own occluding geometry in the group's
//!   frame — never where the group is.

use crate::key::{Key, KeyHasher};
use crate::store::{Result, Store};
use glam::{Affine3A, Vec3};
use kage_engine::math::rng::mix64;
use kage_engine::scene::{
    FlatScene, InGroup, MaterialMaps, MeshRef, PolygonLight, PrimitiveId, Scene, SourceMesh, cutout,
};
use kage_engine::{bspvt, prt};
use std::collections::HashMap;
use std::ops::Range;

/// Vertices per artefact on average: the unit of caching, resuming and writing.
pub const CHUNK: usize = 256;

/// Fewest vertices in a chunk, but for an instance's last.
const MIN_CHUNK: usize = 64;

/// Most vertices in a chunk.
const MAX_CHUNK: usize = 1024;

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
    /// Occluding mesh's content hash (with the cut-out's mask: [`FlatScene::occluder_hash`]).
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
                let mesh = flat.occluder_mesh(i);
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
    /// Per instance, where the store lists its BSPVT chunks' slots (`None` without BSPVT): its
    /// slot without the place, so that a warm re-bake finds a vertex that another chunk of the
    /// same instance held last time (a receiver refined again moves its chunks' cuts).
    pub slot_lists: Vec<Option<Key>>,
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
            (Kind::Bspvt, Some(s), reach) if reach.bounds_rays() => {
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
    let reach = bspvt::reach::Reach::of_scene(flat);
    let mut jobs = Vec::new();
    let mut slot_lists = vec![None; flat.instances.len()];
    if let Some(s) = bspvt {
        for (i, inst) in flat.instances.iter().enumerate() {
            let mut base = KeyHasher::new("bspvt")
                .u64("version", bspvt::layout::FORMAT_VERSION as u64)
                .u64("algorithm", bspvt::ALGORITHM_VERSION as u64)
                .u64("res", s.res as u64)
                .f64("epsilon", s.epsilon)
                .affine("world", &inst.world);
            // Lights that may go anywhere, without depth, add nothing.
            if reach != bspvt::reach::Reach::ANYWHERE {
                base = base.bytes("reach", &reach.key_bytes());
            }
            let id = [inst.id.node, inst.id.mesh, inst.id.primitive];
            slot_lists[i] = Some(base.clone().bytes("id", bytemuck::cast_slice(&id)).bytes("slot list", &[]).finish());
            for vertices in chunks(flat, i) {
                let content = chunk_content(flat, i, &vertices);
                let key =
                    base.clone().bytes("vertices", &content).bytes("occluders", snapshot.hash.as_bytes()).finish();
                // The chunk's place: the vertex it ends at, a content-defined cut that
                // vertices added or dropped elsewhere in the chunk leave where it is.
                let end = vertex_bits(flat, i, vertices.end - 1);
                let slot = base
                    .clone()
                    .bytes("id", bytemuck::cast_slice(&id))
                    .bytes("ends at", bytemuck::cast_slice(&end))
                    .finish();
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
                .affine("local", &locals[i])
                .bytes("group", groups[&inst.group].as_bytes());
            for vertices in chunks(flat, i) {
                let key = base.clone().bytes("vertices", &chunk_content(flat, i, &vertices)).finish();
                jobs.push(Job { kind: Kind::Prt, instance: i, vertices, key, slot: None, cached: false });
            }
        }
    }
    let present = store.contains_all(&jobs.iter().map(|j| j.key).collect::<Vec<_>>())?;
    jobs.iter_mut().zip(present).for_each(|(j, p)| j.cached = p);
    Ok(Plan { bspvt, prt, jobs, snapshot, reach, slot_lists })
}

/// Instance `i`'s vertices cut into chunks by their content, as content-defined chunking cuts
/// a file: after a vertex whose hash (of its position and normal) is 0 modulo
/// `CHUNK − MIN_CHUNK`, once the chunk has [`MIN_CHUNK`] vertices, and at [`MAX_CHUNK`] in any
/// case — [`CHUNK`] vertices on average. Vertices added or dropped in one stretch of the list
/// change the chunks there; past the next cut the chunks are the same as before.
pub fn chunks(flat: &FlatScene, i: usize) -> Vec<Range<usize>> {
    let mesh = flat.mesh(i);
    let cut_after = |v: usize| {
        let b = vertex_bits(flat, i, v);
        let h = (0..3).fold(0u64, |h, k| mix64(h ^ ((b[2 * k] as u64) << 32 | b[2 * k + 1] as u64)));
        h.is_multiple_of((CHUNK - MIN_CHUNK) as u64)
    };
    let mut out = Vec::new();
    let mut start = 0;
    for v in 0..mesh.positions.len() {
        let len = v + 1 - start;
        if len == MAX_CHUNK || (len >= MIN_CHUNK && cut_after(v)) {
            out.push(start..v + 1);
            start = v + 1;
        }
    }
    if start < mesh.positions.len() {
        out.push(start..mesh.positions.len());
    }
    out
}

/// The bits of vertex `v` of instance `i`: its position and normal (mesh frame).
pub fn vertex_bits(flat: &FlatScene, i: usize, v: usize) -> [u32; 6] {
    let mesh = flat.mesh(i);
    let (p, n) = (mesh.positions[v].to_array(), mesh.normals[v].to_array());
    [p[0], p[1], p[2], n[0], n[1], n[2]].map(f32::to_bits)
}

/// What a chunk's bake reads of its own vertices: their positions and normals (mesh frame).
fn chunk_content(flat: &FlatScene, i: usize, vertices: &Range<usize>) -> Vec<u8> {
    let mesh = flat.mesh(i);
    let mut out: Vec<u8> = bytemuck::cast_slice(&mesh.positions[vertices.clone()]).to_vec();
    out.extend_from_slice(bytemuck::cast_slice(&mesh.normals[vertices.clone()]));
    out
}

/// Per group: a hash of its occluding geometry in its own frame (members' occluding meshes and
/// group-relative transforms, lights' polygons), in glTF order: what [`prt::Baker`] casts
/// against.
fn group_geometry(scene: &Scene) -> HashMap<hecs::Entity, Key> {
    let mut members: HashMap<hecs::Entity, Vec<(PrimitiveId, [u8; 32], Affine3A)>> = HashMap::new();
    let mut query =
        scene.world.query::<(&PrimitiveId, &MeshRef, Option<&SourceMesh>, &InGroup, Option<&MaterialMaps>)>();
    for (id, m, source, g, maps) in query.iter() {
        let cutout = maps.and_then(|m| m.cutout.as_ref());
        let occluder = SourceMesh::occluder(*m, source);
        let mesh = cutout::occluder_hash(&scene.meshes[occluder.index as usize], cutout, &scene.textures);
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
    use kage_engine::scene::{Material, Mesh, flatten, shapes};

    /// The chunks of a scene holding only `mesh`, with each chunk's positions.
    fn chunked(mesh: Mesh) -> Vec<Vec<Vec3>> {
        let mut scene = Scene::new("test:chunks");
        scene.add_object("m", mesh, Material::lambertian(Vec3::ONE), glam::Affine3A::IDENTITY);
        let flat = flatten(&scene);
        chunks(&flat, 0).into_iter().map(|r| flat.mesh(0).positions[r].to_vec()).collect()
    }

    /// Chunks cover the vertices in order, [`MIN_CHUNK`] to [`MAX_CHUNK`] long (the last may be
    /// shorter), [`CHUNK`] on average; vertices inserted in the middle change the chunks there
    /// and leave those before and, past the next cut, those after as they were.
    #[test]
    fn chunks_are_cut_by_content() {
        let grid = shapes::grid(8.0, 80);
        let n = grid.positions.len();
        let before = chunked(grid.clone());
        assert_eq!(before.iter().map(Vec::len).sum::<usize>(), n);
        let (last, rest) = before.split_last().unwrap();
        assert!(rest.iter().all(|c| (MIN_CHUNK..=MAX_CHUNK).contains(&c.len())) && last.len() <= MAX_CHUNK);
        let mean = n as f64 / before.len() as f64;
        assert!((0.7..1.4).contains(&(mean / CHUNK as f64)), "{mean} vertices a chunk");

        let at = n / 2;
        let mut positions = grid.positions.clone();
        let extra: Vec<Vec3> = (0..40).map(|k| Vec3::new(0.01 * k as f32, 0.0, 0.123)).collect();
        positions.splice(at..at, extra.iter().copied());
        let mut normals = grid.normals.clone();
        normals.splice(at..at, extra.iter().map(|_| Vec3::Y));
        let shift = |i: u32| if i as usize >= at { i + extra.len() as u32 } else { i };
        let triangles: Vec<[u32; 3]> = grid.triangles.iter().map(|t| t.map(shift)).collect();
        let (edited, _) = Mesh::new(positions, Some(normals), vec![], triangles, false).unwrap();
        let after = chunked(edited);
        let kept = after.iter().filter(|c| before.contains(c)).count();
        assert!(kept + 2 >= before.len(), "{kept} of {} chunks kept", before.len());
        assert!(after.len() > kept, "the chunk with the new vertices is new");
    }

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
