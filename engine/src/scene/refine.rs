//! Mesh refinement for per-vertex bakes: a per-vertex method resolves shadows only as finely
//! as the receiver is tessellated, so a coarse mesh can be refined — uniformly to a vertex
//! budget ([`refine`]), or where a criterion asks ([`Adaptive`], driven by
//! [`crate::receivers`]).
//!
//! Uniform: longest-edge bisection (Rivara): the globally longest edge is split at a time, in every
//! triangle that shares it, so the mesh stays conforming (no T-junctions) and, since that edge
//! is the longest of each of its triangles, angles stay bounded. A new vertex lies on the
//! edge's Phong-tessellation curve (Boubekeur & Alexa 2008, α = ¾) so a curved surface stays
//! curved; its normal is the normalised mean of the edge's, and its uv the midpoint. Each split
//! adds exactly one vertex, so the result has exactly the requested count. Deterministic: ties
//! between equal lengths go to the smaller vertex pair.
//!
//! Adaptive: edges are named by their ends' *positions*, so an edge along a UV seam or a hard
//! crease (two vertices at one position) is split in every triangle that shares it — one new
//! vertex per side of the seam, all at one position: no crack, no T-junction. A new vertex is
//! lifted onto the Phong surface only where every side agrees on the ends' normals (smooth
//! there); on a crease it stays on the flat edge, so an occluder's silhouette does not move.
//!
//! Lifted only outward: a refined instance occludes as its source
//! ([`crate::scene::SourceMesh::occluder`]), so a vertex's rays must start on or outside the
//! source's surface. Where the Phong point lies behind the flat edge (a concave part) the
//! vertex stays on the edge — Hanika's rule against shadow-terminator artefacts (*Hacking the
//! Shadow Terminator*, Ray Tracing Gems II ch. 4).

use super::mesh::{Mesh, MeshProblem};
use crate::math::morton;
use glam::Vec3;
use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};

/// Phong tessellation's shape factor: 0 is flat, 1 the full quadratic patch.
const PHONG_ALPHA: f32 = 0.75;

/// A Phong point this close to its flat edge's midpoint (relative to the edge's length) is the
/// midpoint: the difference is rounding on a flat surface, and a curved one lifts far more.
const FLAT_LIFT: f32 = 1e-5;

type Edge = (u32, u32);

fn edge(a: u32, b: u32) -> Edge {
    (a.min(b), a.max(b))
}

/// A mesh being refined: its arrays, which triangles use each edge, and edges by length.
#[derive(Clone)]
struct Refiner {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    uvs: Vec<glam::Vec2>,
    uvs1: Vec<glam::Vec2>,
    colors: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    /// Per vertex: the vertex that names its position (itself, unless welded to an earlier one).
    canon: Vec<u32>,
    users: HashMap<Edge, Vec<u32>>,
    /// (squared length bits, reversed pair): the longest first, then the smallest pair.
    queue: BinaryHeap<(u32, Reverse<Edge>)>,
    /// Vertices of the source mesh (the first ones); the rest were added by splits.
    source_vertices: usize,
    /// The source's bounds, which places are coded over ([`Refiner::place`]).
    bounds: (Vec3, Vec3),
}

impl Refiner {
    /// A refiner of `mesh`; with `weld`, vertices at one position share their edges.
    fn new(mesh: &Mesh, weld: bool) -> Self {
        let canon = if weld { welded(&mesh.positions) } else { (0..mesh.positions.len() as u32).collect() };
        let mut r = Self {
            positions: mesh.positions.clone(),
            normals: mesh.normals.clone(),
            uvs: mesh.uvs.clone(),
            uvs1: mesh.uvs1.clone(),
            colors: mesh.colors.clone(),
            triangles: Vec::with_capacity(mesh.triangles.len()),
            canon,
            users: HashMap::new(),
            queue: BinaryHeap::new(),
            source_vertices: mesh.positions.len(),
            bounds: mesh.positions.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| (lo.min(*p), hi.max(*p))),
        };
        for tri in &mesh.triangles {
            r.push_triangle(*tri);
        }
        r
    }

    fn push_triangle(&mut self, tri: [u32; 3]) {
        let t = self.triangles.len() as u32;
        self.triangles.push(tri);
        for k in 0..3 {
            self.use_edge(self.named(tri[k], tri[(k + 1) % 3]), t);
        }
    }

    /// The edge between vertices `a` and `b`, named by their positions' vertices.
    fn named(&self, a: u32, b: u32) -> Edge {
        edge(self.canon[a as usize], self.canon[b as usize])
    }

    /// Records that triangle `t` uses `e`, queueing `e` when it is new.
    fn use_edge(&mut self, e: Edge, t: u32) {
        let users = self.users.entry(e).or_default();
        if users.is_empty() {
            let len2 = self.positions[e.0 as usize].distance_squared(self.positions[e.1 as usize]);
            // Non-negative floats order like their bits.
            self.queue.push((len2.to_bits(), Reverse(e)));
        }
        users.push(t);
    }

    /// Splits the longest edge; false when there is none left.
    fn split_longest(&mut self) -> bool {
        while let Some((_, Reverse(e))) = self.queue.pop() {
            if let Some(users) = self.users.remove(&e) {
                self.split(e, &users);
                return true;
            }
        }
        false
    }

    /// Splits edge `e` in every triangle that uses it: one new vertex per distinct pair of
    /// vertices along it (per side of a seam), all at one position.
    fn split(&mut self, e: Edge, users: &[u32]) {
        let sides: Vec<(u32, u32, u32)> = users
            .iter()
            .map(|&t| {
                let tri = self.triangles[t as usize];
                // Rotate so the split edge is p → q in the triangle's winding.
                let k = (0..3).find(|&k| self.named(tri[k], tri[(k + 1) % 3]) == e).expect("the edge's user has it");
                (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3])
            })
            .collect();
        let position = self.split_point(&sides);
        let name = self.positions.len() as u32;
        let mut mids: Vec<((u32, u32), u32)> = Vec::new();
        for (&t, &(p, q, r)) in users.iter().zip(&sides) {
            let m = match mids.iter().find(|(pair, _)| *pair == edge(p, q)) {
                Some(&(_, m)) => m,
                None => {
                    let m = self.push_vertex(p, q, position, name, self.triangles[t as usize]);
                    mids.push((edge(p, q), m));
                    m
                }
            };
            self.triangles[t as usize] = [p, m, r];
            let u = self.triangles.len() as u32;
            self.triangles.push([m, q, r]);
            let qr = self.users.get_mut(&self.named(q, r)).expect("the triangle's edge is known");
            *qr.iter_mut().find(|x| **x == t).expect("the edge knows its triangle") = u;
            let (pm, mq, mr) = (self.named(p, m), self.named(m, q), self.named(m, r));
            self.use_edge(pm, t);
            self.use_edge(mq, u);
            self.use_edge(mr, t);
            self.use_edge(mr, u);
        }
    }

    /// Where a split edge's new vertex goes: on the Phong curve of the first side when every
    /// side has the same normals at the ends (smooth), else on the flat edge.
    fn split_point(&self, sides: &[(u32, u32, u32)]) -> Vec3 {
        let (p, q, r) = sides[0];
        let normals = |a: u32, b: u32| {
            let (na, nb) = (self.normals[a as usize], self.normals[b as usize]);
            if self.canon[a as usize] < self.canon[b as usize] { (na, nb) } else { (nb, na) }
        };
        let smooth = sides.iter().all(|&(a, b, _)| normals(a, b) == normals(p, q));
        if smooth {
            self.midpoint(p, q, [p, q, r])
        } else {
            0.5 * (self.positions[p as usize] + self.positions[q as usize])
        }
    }

    /// A new vertex at `position` between `a` and `b` of `tri` (normal, UVs and colour
    /// interpolated), named `name`.
    fn push_vertex(&mut self, a: u32, b: u32, position: Vec3, name: u32, tri: [u32; 3]) -> u32 {
        let m = self.positions.len() as u32;
        self.positions.push(position);
        self.canon.push(name);
        let face = self.face_normal(tri);
        self.normals.push((self.normals[a as usize] + self.normals[b as usize]).normalize_or(face));
        let (a_, b_) = (a as usize, b as usize);
        for uvs in [&mut self.uvs, &mut self.uvs1].into_iter().filter(|u| !u.is_empty()) {
            uvs.push(0.5 * (uvs[a_] + uvs[b_]));
        }
        if !self.colors.is_empty() {
            self.colors.push(0.5 * (self.colors[a_] + self.colors[b_]));
        }
        m
    }

    /// The edge's midpoint moved onto its Phong-tessellation curve.
    fn midpoint(&self, a: u32, b: u32, tri: [u32; 3]) -> Vec3 {
        let (pa, pb) = (self.positions[a as usize], self.positions[b as usize]);
        let (na, nb) = (self.normals[a as usize], self.normals[b as usize]);
        let mid = 0.5 * (pa + pb);
        let onto = |p: Vec3, n: Vec3| mid - (mid - p).dot(n) * n;
        let curved = (1.0 - PHONG_ALPHA) * mid + PHONG_ALPHA * 0.5 * (onto(pa, na) + onto(pb, nb));
        // Normals that disagree wildly (a crease) would pull the point off: stay flat there. A
        // lift within rounding (a flat surface) is none, so a flat mesh refines exactly flat. A
        // lift behind the edge would start the vertex's rays inside what it occludes as.
        let lifted = (curved - mid).length() > FLAT_LIFT * pa.distance(pb);
        let outward = (curved - mid).dot(na + nb) > 0.0;
        let smooth = na.dot(nb) > 0.0 && self.face_normal(tri).dot(na + nb) > 0.0;
        if lifted && outward && smooth { curved } else { mid }
    }

    fn face_normal(&self, tri: [u32; 3]) -> Vec3 {
        let [a, b, c] = tri.map(|i| self.positions[i as usize]);
        (b - a).cross(c - a).normalize_or_zero()
    }
}

/// Refines `mesh` to exactly `target_vertices` vertices (a mesh already that large is returned
/// unchanged). Fails only if a split produced a degenerate triangle.
pub fn refine(mesh: &Mesh, target_vertices: usize) -> Result<Mesh, MeshProblem> {
    if mesh.positions.len() >= target_vertices {
        return Ok(mesh.clone());
    }
    let mut r = Refiner::new(mesh, false);
    while r.positions.len() < target_vertices && r.split_longest() {}
    r.finish()
}

impl Refiner {
    /// The refined mesh.
    fn finish(self) -> Result<Mesh, MeshProblem> {
        let (m, _) = Mesh::new(self.positions, Some(self.normals), self.uvs, self.triangles, false)?;
        Ok(m.with_attributes(self.uvs1, self.colors))
    }
}

/// Per vertex, the first vertex at the same position (bit for bit).
fn welded(positions: &[Vec3]) -> Vec<u32> {
    let mut first: HashMap<[u32; 3], u32> = HashMap::new();
    positions
        .iter()
        .enumerate()
        .map(|(i, p)| *first.entry(p.to_array().map(f32::to_bits)).or_insert(i as u32))
        .collect()
}

/// A mesh refined where a criterion asks, in rounds: list the edges, split the ones it marks.
/// Edges are named by position (see the module documentation).
#[derive(Clone)]
pub struct Adaptive(Refiner);

impl Adaptive {
    /// Starts from `mesh` (refinement always starts from the source mesh).
    pub fn new(mesh: &Mesh) -> Self {
        Self(Refiner::new(mesh, true))
    }

    /// The current vertex positions (the mesh's frame).
    pub fn positions(&self) -> &[Vec3] {
        &self.0.positions
    }

    /// The current unit vertex normals.
    pub fn normals(&self) -> &[Vec3] {
        &self.0.normals
    }

    /// The current triangles.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.0.triangles
    }

    /// Every edge once, as the two vertices that name its ends' positions, in a fixed order.
    pub fn edges(&self) -> Vec<[u32; 2]> {
        let mut edges: Vec<[u32; 2]> = self.0.users.keys().map(|&(a, b)| [a, b]).collect();
        edges.sort_unstable();
        edges
    }

    /// Splits `edges` (as [`Adaptive::edges`] names them), longest first, while the mesh has
    /// fewer than `limit` vertices; returns how many were split. An edge a previous split in
    /// this call already divided is split no further.
    pub fn split(&mut self, edges: &[[u32; 2]], limit: usize) -> usize {
        let length = |e: &[u32; 2]| self.0.positions[e[0] as usize].distance_squared(self.0.positions[e[1] as usize]);
        let mut order: Vec<(f32, [u32; 2])> = edges.iter().map(|e| (length(e), *e)).collect();
        order.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        let mut done = 0;
        for (_, [a, b]) in order {
            if self.0.positions.len() >= limit {
                break;
            }
            if let Some(users) = self.0.users.remove(&(a, b)) {
                self.0.split((a, b), &users);
                done += 1;
            }
        }
        done
    }

    /// For edge `e`, the longest edge of each triangle that uses it (`e` itself where it is
    /// the longest): splitting those instead keeps triangles well shaped, as Rivara's
    /// bisection does, and `e` is divided by a later round if it still needs to be.
    pub fn longest_around(&self, e: [u32; 2]) -> Vec<[u32; 2]> {
        let r = &self.0;
        let Some(users) = r.users.get(&(e[0], e[1])) else { return Vec::new() };
        users
            .iter()
            .map(|&t| {
                let tri = r.triangles[t as usize];
                let (a, b) = (0..3)
                    .map(|k| r.named(tri[k], tri[(k + 1) % 3]))
                    .max_by(|x, y| {
                        let len = |(a, b): &Edge| r.positions[*a as usize].distance_squared(r.positions[*b as usize]);
                        len(x).total_cmp(&len(y)).then(y.cmp(x))
                    })
                    .expect("three edges");
                [a, b]
            })
            .collect()
    }

    /// Edge `e` (as [`Adaptive::edges`] names it) as each triangle using it has it: its own
    /// two vertices, in `e`'s order, each pair once. Across a hard crease the sides' vertices
    /// differ in normal, which the canonical pair carries for one side only.
    pub fn sides(&self, e: [u32; 2]) -> Vec<[u32; 2]> {
        let r = &self.0;
        let mut sides: Vec<[u32; 2]> = r
            .users
            .get(&(e[0], e[1]))
            .into_iter()
            .flatten()
            .flat_map(|&t| {
                let tri = r.triangles[t as usize];
                (0..3).map(move |k| (tri[k], tri[(k + 1) % 3]))
            })
            .filter(|&(a, b)| r.named(a, b) == (e[0], e[1]))
            .map(|(a, b)| if r.canon[a as usize] == e[0] { [a, b] } else { [b, a] })
            .collect();
        sides.sort_unstable();
        sides.dedup();
        sides
    }

    /// Where edge `e` lies, as an order of places ([`Refiner::place`] of its midpoint): ties
    /// between equal marks go by it, so which of them a budget takes depends on where they
    /// are, not on when their vertices were made.
    pub fn place(&self, e: [u32; 2]) -> u64 {
        let r = &self.0;
        r.place(0.5 * (r.positions[e[0] as usize] + r.positions[e[1] as usize]))
    }

    /// Vertices so far.
    pub fn vertices(&self) -> usize {
        self.0.positions.len()
    }

    /// The refined mesh, the vertices splits added in spatial order after the source's (see
    /// [`Refiner::spatial_order`]).
    pub fn finish(self) -> Result<Mesh, MeshProblem> {
        let mut r = self.0;
        r.spatial_order();
        r.finish()
    }
}

impl Refiner {
    /// The Morton code of `p` over the source's bounds: an order of places that keeps nearby
    /// ones mostly together, the same for every refinement of one source.
    fn place(&self, p: Vec3) -> u64 {
        morton::encode(morton::quantize(p, self.bounds.0, self.bounds.1))
    }

    /// Puts the vertices splits added in Morton order over the source's bounds, ties by
    /// content. Where a vertex lies, not when it was split, decides its place, so two
    /// refinements that differ in one region differ in one stretch of the vertex list — and so
    /// in a few of the bake's chunks of vertices.
    fn spatial_order(&mut self) {
        let n0 = self.source_vertices;
        let bits = |v: Vec3| v.to_array().map(f32::to_bits);
        let mut added: Vec<u32> = (n0 as u32..self.positions.len() as u32).collect();
        added.sort_by_cached_key(|&v| {
            let (p, n) = (self.positions[v as usize], self.normals[v as usize]);
            let uv = self.uvs.get(v as usize).map_or([0; 2], |t| t.to_array().map(f32::to_bits));
            (self.place(p), bits(p), bits(n), uv)
        });
        let order: Vec<usize> = (0..n0).chain(added.iter().map(|&v| v as usize)).collect();
        let mut new_index = vec![0u32; order.len()];
        order.iter().enumerate().for_each(|(new, &old)| new_index[old] = new as u32);
        let permute = |a: &mut Vec<_>| *a = order.iter().map(|&i| a[i]).collect();
        permute(&mut self.positions);
        permute(&mut self.normals);
        for uvs in [&mut self.uvs, &mut self.uvs1].into_iter().filter(|u| !u.is_empty()) {
            *uvs = order.iter().map(|&i| uvs[i]).collect();
        }
        if !self.colors.is_empty() {
            self.colors = order.iter().map(|&i| self.colors[i]).collect();
        }
        self.triangles.iter_mut().flatten().for_each(|i| *i = new_index[*i as usize]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::shapes;

    /// Every edge with its number of triangles.
    fn edge_users(m: &Mesh) -> HashMap<Edge, usize> {
        let mut users = HashMap::new();
        for t in &m.triangles {
            for k in 0..3 {
                *users.entry(edge(t[k], t[(k + 1) % 3])).or_default() += 1;
            }
        }
        users
    }

    /// A closed unit icosahedron (welded: every edge has two triangles), smooth normals.
    fn icosahedron() -> Mesh {
        let g = (1.0 + 5f32.sqrt()) / 2.0;
        let pairs = [(-1.0, g), (1.0, g), (-1.0, -g), (1.0, -g)];
        let planes: [fn(f32, f32) -> Vec3; 3] =
            [|a, b| Vec3::new(a, b, 0.0), |a, b| Vec3::new(0.0, a, b), |a, b| Vec3::new(b, 0.0, a)];
        let p: Vec<Vec3> = planes.iter().flat_map(|f| pairs.map(|(a, b)| f(a, b).normalize())).collect();
        #[rustfmt::skip]
        let t = vec![
            [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
            [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5],
            [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1],
        ];
        Mesh::new(p.clone(), Some(p), vec![], t, false).unwrap().0
    }

    #[test]
    fn reaches_the_target_exactly_and_stays_closed() {
        let sphere = icosahedron();
        let fine = refine(&sphere, 1000).unwrap();
        assert_eq!(fine.positions.len(), 1000);
        // Closed before → closed after: every edge has exactly two triangles (no T-junction).
        assert!(edge_users(&sphere).values().all(|&n| n == 2));
        assert!(edge_users(&fine).values().all(|&n| n == 2));
        // Euler characteristic of a sphere: V − E + F = 2.
        let (v, e, f) = (fine.positions.len(), edge_users(&fine).len(), fine.triangles.len());
        assert_eq!(v as i64 - e as i64 + f as i64, 2);
    }

    #[test]
    fn colours_and_both_uv_sets_are_interpolated() {
        let sphere = icosahedron();
        let n = sphere.positions.len();
        let tint = |p: &Vec3| *p * 0.5 + Vec3::splat(0.5);
        let colours: Vec<Vec3> = sphere.positions.iter().map(tint).collect();
        let uv = |p: &Vec3| glam::Vec2::new(p.x, p.y);
        let uvs: Vec<glam::Vec2> = sphere.positions.iter().map(uv).collect();
        let (m, _) = Mesh::new(
            sphere.positions.clone(),
            Some(sphere.normals.clone()),
            uvs.clone(),
            sphere.triangles.clone(),
            false,
        )
        .unwrap();
        let fine = refine(&m.with_attributes(uvs, colours), 42).unwrap();
        assert_eq!((fine.colors.len(), fine.uvs.len(), fine.uvs1.len()), (42, 42, 42));
        // Midpoints of first-generation splits: each is the mean of its edge's two ends.
        let midpoint_of_some_edge = |k: usize| {
            (0..n).any(|a| {
                (0..n).any(|b| {
                    a != b
                        && (fine.colors[k] - 0.5 * (fine.colors[a] + fine.colors[b])).length() < 1e-6
                        && (fine.uvs1[k] - 0.5 * (fine.uvs1[a] + fine.uvs1[b])).length() < 1e-6
                })
            })
        };
        assert!((n..42).all(midpoint_of_some_edge));
    }

    #[test]
    fn new_vertices_follow_the_curved_surface() {
        let sphere = icosahedron();
        let fine = refine(&sphere, 42).unwrap();
        // One split per edge (30 edges): every new vertex is a first-generation midpoint. A flat
        // one sits 1 − cos(θ/2) inside the sphere (θ the edge's angle); Phong's far less.
        let theta = sphere.positions[0].angle_between(sphere.positions[11]);
        let flat_inset = 1.0 - (theta / 2.0).cos();
        let worst = fine.positions.iter().map(|p| (p.length() - 1.0).abs()).fold(0.0, f32::max);
        assert!(worst < 0.25 * flat_inset, "{worst} vs flat {flat_inset}");
        assert!(fine.normals.iter().zip(&fine.positions).all(|(n, p)| n.dot(p.normalize()) > 0.98));
    }

    /// Seen from inside (normals and winding reversed) the sphere is concave: its Phong points
    /// lie behind the flat triangles, where a ray from them would meet the source, so every new
    /// vertex stays on its flat edge (see [`crate::scene::SourceMesh`]).
    #[test]
    fn new_vertices_are_never_lifted_behind_the_source() {
        let outside = icosahedron();
        let normals = outside.normals.iter().map(|n| -*n).collect();
        let triangles = outside.triangles.iter().map(|[a, b, c]| [*a, *c, *b]).collect();
        let inside = Mesh::new(outside.positions.clone(), Some(normals), vec![], triangles, false).unwrap().0;
        let fine = refine(&inside, 42).unwrap();
        let theta = outside.positions[0].angle_between(outside.positions[11]);
        let flat = (theta / 2.0).cos();
        assert!(fine.positions[12..].iter().all(|p| (p.length() - flat).abs() < 1e-5));
    }

    #[test]
    fn a_flat_grid_stays_flat_keeps_its_area_boundary_and_winding() {
        let grid = shapes::grid(2.0, 4);
        let fine = refine(&grid, 200).unwrap();
        assert_eq!(fine.positions.len(), 200);
        assert!(fine.positions.iter().all(|p| p.y == 0.0));
        assert!((fine.area() - grid.area()).abs() < 1e-4);
        let boundary = |m: &Mesh| {
            edge_users(m)
                .iter()
                .filter(|(_, n)| **n == 1)
                .map(|(e, _)| m.positions[e.0 as usize].distance(m.positions[e.1 as usize]))
                .sum::<f32>()
        };
        assert!((boundary(&fine) - 8.0).abs() < 1e-4);
        assert!(fine.triangles.iter().all(|t| {
            let [a, b, c] = t.map(|i| fine.positions[i as usize]);
            (b - a).cross(c - a).y > 0.0
        }));
    }

    #[test]
    fn a_scene_refines_only_the_named_instances_and_keeps_shared_meshes_for_the_others() {
        use crate::scene::{Material, MeshRef, Name, Scene};
        let mut scene = Scene::new("test");
        let m = Material::lambertian(Vec3::ONE);
        scene.add_object("a", shapes::sphere(1.0, 8, 4), m, glam::Affine3A::IDENTITY);
        scene.add_object("c", shapes::sphere(1.0, 8, 4), m, glam::Affine3A::IDENTITY);
        let refs = |scene: &Scene| -> HashMap<String, MeshRef> {
            scene.world.query::<(&Name, &MeshRef)>().iter().map(|(n, r)| (n.0.clone(), *r)).collect()
        };
        // "c" instances a's mesh, as glTF nodes can.
        let shared = refs(&scene)["a"];
        for (name, r) in scene.world.query_mut::<(&Name, &mut MeshRef)>() {
            if name.0 == "c" {
                *r = shared;
            }
        }
        assert_eq!(scene.refine_instances("a", 100).unwrap(), 1);
        let (a, c) = (refs(&scene)["a"], refs(&scene)["c"]);
        assert_eq!((a.index, c), (2, shared), "a gets a new mesh, c keeps the shared one");
        assert_eq!(scene.meshes[2].positions.len(), 100);
        assert_eq!(scene.meshes[2].hash, a.hash);
        // Now c alone uses mesh 0: refined in place.
        assert_eq!(scene.refine_instances("c", 60).unwrap(), 1);
        assert_eq!((refs(&scene)["c"].index, scene.meshes[0].positions.len()), (0, 60));
        let e = scene.refine_instances("nope", 10).unwrap_err().to_string();
        assert!(e.contains("test: no mesh instance or group named 'nope'"), "{e}");
    }

    /// Edges by position (bit patterns) with their number of triangles.
    fn welded_edge_users(m: &Mesh) -> HashMap<([u32; 3], [u32; 3]), usize> {
        let key = |i: u32| m.positions[i as usize].to_array().map(f32::to_bits);
        let mut users = HashMap::new();
        for t in &m.triangles {
            for k in 0..3 {
                let (a, b) = (key(t[k]), key(t[(k + 1) % 3]));
                *users.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        users
    }

    /// Splits every edge of `m` adaptively `rounds` times.
    fn split_all(m: &Mesh, rounds: usize) -> Mesh {
        let mut a = Adaptive::new(m);
        for _ in 0..rounds {
            let edges = a.edges();
            a.split(&edges, usize::MAX);
        }
        a.finish().unwrap()
    }

    /// A UV seam (two vertices at each position along x = 0) is split on both sides at once:
    /// no crack opens along it (the only boundary is the outline) and no T-junction forms.
    #[test]
    fn adaptive_splits_conform_across_a_uv_seam() {
        let (mut p, mut uv) = (Vec::new(), Vec::new());
        for side in [0.0, 1.0f32] {
            for z in 0..3 {
                for x in 0..2 {
                    p.push(Vec3::new(side - 1.0 + x as f32, 0.0, z as f32 - 1.0));
                    uv.push(glam::Vec2::new(side * 10.0 + x as f32, z as f32));
                }
            }
        }
        // Each side is a 1×2 strip of quads; side 0's right column and side 1's left column
        // coincide (x = 0) but are different vertices.
        let quads = |o: u32| [[o, o + 2, o + 3], [o, o + 3, o + 1], [o + 2, o + 4, o + 5], [o + 2, o + 5, o + 3]];
        let tris: Vec<[u32; 3]> = quads(0).into_iter().chain(quads(6)).collect();
        let (m, _) = Mesh::new(p, None, uv, tris, false).unwrap();
        let fine = split_all(&m, 3);
        let users = welded_edge_users(&fine);
        assert!(users.values().all(|&n| n <= 2), "no edge shared by three triangles");
        let boundary: f32 = users
            .iter()
            .filter(|(_, n)| **n == 1)
            .map(|((a, b), _)| {
                Vec3::from_array(a.map(f32::from_bits)).distance(Vec3::from_array(b.map(f32::from_bits)))
            })
            .sum();
        assert!((boundary - 8.0).abs() < 1e-4, "the seam stays closed: boundary {boundary}");
        assert!((fine.area() - 4.0).abs() < 1e-4);
        // Both sides keep their own UVs at the seam's new vertices.
        let at_seam: Vec<glam::Vec2> =
            (0..fine.positions.len()).filter(|&i| fine.positions[i].x == 0.0).map(|i| fine.uvs[i]).collect();
        assert!(at_seam.iter().any(|uv| uv.x == 1.0) && at_seam.iter().any(|uv| uv.x == 10.0));
    }

    /// A box's crease edges have two sides, each with its own face's vertices (so normals) at
    /// the edge's ends, in the edge's order; an edge inside a face has one.
    #[test]
    fn sides_give_each_face_its_own_ends() {
        let a = Adaptive::new(&shapes::cuboid(Vec3::splat(0.5)));
        let (p, n) = (a.positions(), a.normals());
        for e in a.edges() {
            let sides = a.sides(e);
            // A box edge changes one coordinate; a face's diagonal, two.
            let d = p[e[0] as usize] - p[e[1] as usize];
            let crease = d.to_array().iter().filter(|c| c.abs() > 1e-6).count() == 1;
            assert_eq!(sides.len(), if crease { 2 } else { 1 }, "{e:?}: {sides:?}");
            for [x, y] in sides {
                assert_eq!((p[x as usize], p[y as usize]), (p[e[0] as usize], p[e[1] as usize]));
                assert_eq!(n[x as usize], n[y as usize], "a side's ends lie on one face");
            }
        }
    }

    /// A box's hard edges (per-face normals) stay closed and sharp: new vertices on a crease sit
    /// on the flat edge, never lifted off it.
    #[test]
    fn adaptive_splits_keep_a_creased_box_closed_and_flat() {
        let h = 0.5;
        let cube = shapes::cuboid(Vec3::splat(h));
        let fine = split_all(&cube, 2);
        assert!(fine.positions.len() > cube.positions.len());
        assert!(welded_edge_users(&fine).values().all(|&n| n == 2), "closed: every edge has two triangles");
        assert!(fine.positions.iter().all(|p| (p.abs().max_element() - h).abs() < 1e-6), "on the box's faces");
        assert!((fine.area() - 6.0).abs() < 1e-4);
    }

    /// Added vertices follow their place, not the order of the splits that made them: two
    /// refinements with the same splits in another order are the same mesh, vertex for vertex,
    /// and a flat grid refines flat.
    #[test]
    fn added_vertices_lie_in_spatial_order_and_a_flat_grid_stays_flat() {
        let grid = shapes::grid(2.0, 6);
        let edges = Adaptive::new(&grid).edges();
        let (first, last) = (edges[..4].to_vec(), edges[edges.len() - 4..].to_vec());
        let refine_in = |order: [&[[u32; 2]]; 2]| {
            let mut a = Adaptive::new(&grid);
            order.iter().for_each(|e| _ = a.split(e, usize::MAX));
            a.finish().unwrap()
        };
        let (one, other) = (refine_in([&first, &last]), refine_in([&last, &first]));
        assert!(one.positions.len() > grid.positions.len());
        assert!(one.positions.iter().all(|p| p.y == 0.0), "a flat grid refines flat");
        assert_eq!(one.positions, other.positions);
        let n0 = grid.positions.len();
        let (lo, hi) = (Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 0.0, 1.0));
        let codes: Vec<u64> =
            one.positions[n0..].iter().map(|p| morton::encode(morton::quantize(*p, lo, hi))).collect();
        assert!(codes.windows(2).all(|w| w[0] <= w[1]), "{codes:?}");
    }

    #[test]
    fn deterministic_and_a_no_op_at_or_below_the_size() {
        let torus = shapes::torus(1.0, 0.3, 16, 8);
        assert_eq!(refine(&torus, 500).unwrap().hash, refine(&torus, 500).unwrap().hash);
        assert_eq!(refine(&torus, 10).unwrap().hash, torus.hash);
    }
}
