//! Triangle meshes: validation, angle-weighted normals, and the content hash that keys bakes.

use glam::{Vec2, Vec3};
use std::fmt;

/// Bumped whenever the canonical byte layout of [`MeshHash`] changes.
pub const MESH_HASH_VERSION: u32 = 1;

/// blake3 content hash of a mesh's canonical bytes.
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct MeshHash(pub [u8; 32]);

impl fmt::Debug for MeshHash {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "MeshHash({self})")
    }
}

impl fmt::Display for MeshHash {
    /// The first 16 hex digits, enough to tell meshes apart in listings.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for b in &self.0[..8] {
            write!(f, "{b:02x}")?;
        }
        Ok(())
    }
}

/// An indexed triangle mesh in its local frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Unit vertex normals (same length as `positions`).
    pub normals: Vec<Vec3>,
    /// Texture coordinates, set 0 (empty, or same length as `positions`).
    pub uvs: Vec<Vec2>,
    /// Texture coordinates, set 1 (empty, or same length as `positions`).
    pub uvs1: Vec<Vec2>,
    /// Linear vertex colours `COLOR_0` (RGB; empty, or same length as `positions`).
    pub colors: Vec<Vec3>,
    /// Counter-clockwise triangles.
    pub triangles: Vec<[u32; 3]>,
    /// Content hash, see [`Mesh::compute_hash`].
    pub hash: MeshHash,
}

/// What is wrong with a mesh's data.
#[derive(Clone, Debug, PartialEq)]
pub enum MeshProblem {
    /// A position or normal is NaN or infinite.
    NonFinite {
        /// Vertex index.
        vertex: usize,
    },
    /// A triangle references a vertex that does not exist.
    IndexOutOfRange {
        /// Triangle index.
        triangle: usize,
        /// The bad index.
        index: u32,
    },
    /// A triangle has (numerically) zero area.
    Degenerate {
        /// Triangle index.
        triangle: usize,
    },
    /// The mesh has no triangles.
    Empty,
}

impl fmt::Display for MeshProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NonFinite { vertex } => {
                write!(f, "vertex {vertex} has a NaN or infinite coordinate")
            }
            Self::IndexOutOfRange { triangle, index } => {
                write!(f, "triangle {triangle} uses vertex index {index}, past the end of the vertex data")
            }
            Self::Degenerate { triangle } => {
                write!(f, "triangle {triangle} is degenerate (zero area; --drop-degenerate removes such triangles)")
            }
            Self::Empty => write!(f, "no triangles"),
        }
    }
}

/// True when the triangle's area is zero to within f32 resolution of its edge lengths.
pub fn is_degenerate(a: Vec3, b: Vec3, c: Vec3) -> bool {
    let (a, b, c) = (a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
    let (e1, e2) = (b - a, c - a);
    let longest2 = e1.length_squared().max(e2.length_squared()).max((c - b).length_squared());
    // |e1 × e2| = |e1||e2| sin γ; a sine below ~f32 epsilon is noise.
    e1.cross(e2).length() <= 1e-7 * longest2 || longest2 == 0.0
}

impl Mesh {
    /// Builds a mesh, checking its data; missing normals are computed angle-weighted.
    /// With `drop_degenerate`, zero-area triangles are removed (and counted) instead of rejected.
    pub fn new(
        positions: Vec<Vec3>,
        normals: Option<Vec<Vec3>>,
        uvs: Vec<Vec2>,
        triangles: Vec<[u32; 3]>,
        drop_degenerate: bool,
    ) -> Result<(Self, usize), MeshProblem> {
        if let Some(v) = positions.iter().position(|p| !p.is_finite()) {
            return Err(MeshProblem::NonFinite { vertex: v });
        }
        let n = positions.len() as u32;
        for (t, tri) in triangles.iter().enumerate() {
            if let Some(&index) = tri.iter().find(|&&i| i >= n) {
                return Err(MeshProblem::IndexOutOfRange { triangle: t, index });
            }
        }
        let total = triangles.len();
        let mut kept = Vec::with_capacity(total);
        for (t, tri) in triangles.into_iter().enumerate() {
            let [a, b, c] = tri.map(|i| positions[i as usize]);
            if !is_degenerate(a, b, c) {
                kept.push(tri);
            } else if !drop_degenerate {
                return Err(MeshProblem::Degenerate { triangle: t });
            }
        }
        if kept.is_empty() {
            return Err(MeshProblem::Empty);
        }
        let computed = angle_weighted_normals(&positions, &kept);
        let normals = match normals {
            // Zero, non-finite or missing normals fall back to the computed ones. Unit normals
            // are kept bit for bit (re-normalising can move the last bit, and a mesh written
            // out and read back must keep its content hash).
            Some(ns) => ns
                .iter()
                .zip(&computed)
                .map(|(n, c)| match n.length_squared() {
                    l if (l - 1.0).abs() <= 4.0 * f32::EPSILON => *n,
                    l if n.is_finite() && l > 1e-12 => n.normalize(),
                    _ => *c,
                })
                .collect(),
            None => computed,
        };
        let uvs = if uvs.len() == positions.len() { uvs } else { Vec::new() };
        let dropped = total - kept.len();
        let mut mesh = Self {
            positions,
            normals,
            uvs,
            uvs1: Vec::new(),
            colors: Vec::new(),
            triangles: kept,
            hash: MeshHash([0; 32]),
        };
        mesh.hash = mesh.compute_hash();
        Ok((mesh, dropped))
    }

    /// The mesh with a second UV set and vertex colours (each kept only when it has one entry
    /// per vertex), its hash updated.
    pub fn with_attributes(mut self, uvs1: Vec<Vec2>, colors: Vec<Vec3>) -> Self {
        let n = self.positions.len();
        self.uvs1 = if uvs1.len() == n { uvs1 } else { Vec::new() };
        self.colors = if colors.len() == n { colors } else { Vec::new() };
        self.hash = self.compute_hash();
        self
    }

    /// blake3 over a canonical little-endian layout: version, counts, positions, normals, uvs,
    /// triangles, then — only when present, so meshes without them keep their hashes — the
    /// second UV set and the vertex colours, each tagged. `-0.0` is written as `0.0` so equal
    /// geometry hashes equally everywhere.
    pub fn compute_hash(&self) -> MeshHash {
        let mut h = blake3::Hasher::new();
        h.update(b"kage.mesh");
        h.update(&MESH_HASH_VERSION.to_le_bytes());
        for count in [self.positions.len(), self.uvs.len(), self.triangles.len()] {
            h.update(&(count as u64).to_le_bytes());
        }
        let canon = |x: f32| if x == 0.0 { 0.0f32 } else { x }.to_le_bytes();
        for v in self.positions.iter().chain(&self.normals) {
            for x in v.to_array() {
                h.update(&canon(x));
            }
        }
        for uv in &self.uvs {
            for x in uv.to_array() {
                h.update(&canon(x));
            }
        }
        for t in &self.triangles {
            for i in t {
                h.update(&i.to_le_bytes());
            }
        }
        let extra: [(&[u8], Vec<f32>); 2] = [
            (b"uvs1", self.uvs1.iter().flat_map(|v| v.to_array()).collect()),
            (b"colors", self.colors.iter().flat_map(|v| v.to_array()).collect()),
        ];
        for (tag, values) in extra.iter().filter(|(_, v)| !v.is_empty()) {
            h.update(tag);
            for &x in values {
                h.update(&canon(x));
            }
        }
        MeshHash(*h.finalize().as_bytes())
    }

    /// Total surface area.
    pub fn area(&self) -> f32 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.positions[i as usize]);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    }
}

/// Vertex normals as the sum of incident face normals weighted by the corner angle
/// (Thürmer & Wüthrich), which does not depend on how faces are triangulated.
pub fn angle_weighted_normals(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
    let mut acc = vec![Vec3::ZERO; positions.len()];
    for tri in triangles {
        let p = tri.map(|i| positions[i as usize]);
        let face = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
        for k in 0..3 {
            let e1 = (p[(k + 1) % 3] - p[k]).normalize_or_zero();
            let e2 = (p[(k + 2) % 3] - p[k]).normalize_or_zero();
            acc[tri[k] as usize] += face * e1.dot(e2).clamp(-1.0, 1.0).acos();
        }
    }
    acc.into_iter().map(|n| n.normalize_or(Vec3::Y)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad() -> (Vec<Vec3>, Vec<[u32; 3]>) {
        (vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 0.0, -1.0), Vec3::NEG_Z], vec![[0, 1, 2], [0, 2, 3]])
    }

    #[test]
    fn normals_point_along_ccw_face_normal() {
        let (p, t) = quad();
        let (m, _) = Mesh::new(p, None, vec![], t, false).unwrap();
        assert!(m.normals.iter().all(|n| (*n - Vec3::Y).length() < 1e-6));
    }

    #[test]
    fn hash_is_stable_and_sensitive() {
        let (p, t) = quad();
        let (a, _) = Mesh::new(p.clone(), None, vec![], t.clone(), false).unwrap();
        let (b, _) = Mesh::new(p.clone(), None, vec![], t.clone(), false).unwrap();
        assert_eq!(a.hash, b.hash);
        let mut moved = p.clone();
        moved[2].x += 1e-6;
        let (c, _) = Mesh::new(moved, None, vec![], t.clone(), false).unwrap();
        assert_ne!(a.hash, c.hash);
        let mut negzero = p;
        negzero[0] = Vec3::new(-0.0, 0.0, -0.0);
        let (d, _) = Mesh::new(negzero, None, vec![], t, false).unwrap();
        assert_eq!(a.hash, d.hash, "-0.0 and 0.0 hash alike");
        // Pinned value: the canonical layout must not drift across platforms or releases
        // without bumping MESH_HASH_VERSION.
        assert_eq!(a.hash.to_string(), PINNED_QUAD_HASH);
    }

    const PINNED_QUAD_HASH: &str = "473c367e15f4cd90";

    #[test]
    fn colours_and_a_second_uv_set_join_the_hash_only_when_present() {
        let (p, t) = quad();
        let (a, _) = Mesh::new(p, None, vec![], t, false).unwrap();
        let same = a.clone().with_attributes(vec![], vec![Vec3::ONE; 3]);
        assert_eq!(same.hash, a.hash, "a colour per vertex or none: 3 of 4 is dropped");
        assert!(same.colors.is_empty());
        let red = a.clone().with_attributes(vec![], vec![Vec3::X; 4]);
        let uv1 = a.clone().with_attributes(vec![Vec2::ZERO; 4], vec![]);
        assert!(red.hash != a.hash && uv1.hash != a.hash && red.hash != uv1.hash);
        assert_eq!(red.hash, red.compute_hash());
    }

    #[test]
    fn bad_data_is_reported() {
        let (mut p, t) = quad();
        assert_eq!(
            Mesh::new(p.clone(), None, vec![], vec![[0, 1, 9]], false).unwrap_err(),
            MeshProblem::IndexOutOfRange { triangle: 0, index: 9 }
        );
        assert_eq!(
            Mesh::new(p.clone(), None, vec![], vec![[0, 1, 1]], false).unwrap_err(),
            MeshProblem::Degenerate { triangle: 0 }
        );
        let (m, _) = Mesh::new(p.clone(), None, vec![], vec![[0, 1, 1], [0, 1, 2]], true).unwrap();
        assert_eq!(m.triangles.len(), 1);
        p[1].y = f32::NAN;
        assert_eq!(Mesh::new(p, None, vec![], t, false).unwrap_err(), MeshProblem::NonFinite { vertex: 1 });
    }
}
