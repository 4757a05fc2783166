//! Cut-out surfaces (glTF `alphaMode: MASK`): a material whose alpha — `baseColorFactor`'s
//! alpha times the base-colour texture's — falls below `alphaCutoff` is absent there.
//!
//! Absent means absent to everything that sees the surface: ray casts ([`Holes`] attached to a
//! [`crate::accel::SceneBvh`]: the reference integrator, BSPVT occluders, PRT transfer, the
//! sun, refinement probes, picking), PRT silhouettes, and the preview's fragments. A cut-out
//! triangle is tested at the hit point's interpolated UVs, bilinearly, as a GPU samples.

use super::{Mesh, Texture, TextureSlot};
use glam::Vec2;
use std::sync::Arc;

/// A material's cut-out (glTF `alphaMode: MASK`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cutout {
    /// The base-colour texture's alpha channel (a grey texture in
    /// [`crate::scene::Scene::textures`]), read through the base colour's UV set and transform.
    pub alpha: Option<TextureSlot>,
    /// `baseColorFactor`'s alpha.
    pub factor: f32,
    /// `alphaCutoff` (glTF's default is 0.5).
    pub cutoff: f32,
}

impl Cutout {
    /// A hash of everything the cut-out's holes depend on (factor, cutoff, the alpha texture's
    /// texels and wrap, its UV set and transform), for bake keys.
    pub fn content(&self, textures: &[Arc<Texture>]) -> blake3::Hash {
        let mut h = blake3::Hasher::new();
        h.update(b"cutout\0");
        h.update(bytemuck::cast_slice(&[self.factor, self.cutoff]));
        if let Some(s) = &self.alpha {
            let t = &textures[s.texture as usize];
            h.update(&[(s.texcoord as u8), t.wrap[0] as u8, t.wrap[1] as u8]);
            h.update(bytemuck::cast_slice(&s.transform.to_cols_array()));
            h.update(&(t.width as u64).to_le_bytes());
            h.update(bytemuck::cast_slice(&t.texels));
        }
        h.finalize()
    }
}

/// What an instance's occlusion depends on besides its placement: its mesh's hash, or with a
/// cut-out, a hash of the mesh's and the cut-out's (so bake keys follow an edited mask).
pub fn occluder_hash(mesh: &Mesh, cutout: Option<&Cutout>, textures: &[Arc<Texture>]) -> [u8; 32] {
    match cutout {
        None => mesh.hash.0,
        Some(c) => {
            let mut h = blake3::Hasher::new();
            h.update(&mesh.hash.0);
            h.update(c.content(textures).as_bytes());
            *h.finalize().as_bytes()
        }
    }
}

/// Marks a triangle that is not cut out in [`Holes`].
const SOLID: u32 = u32::MAX;

/// One cut-out triangle: its mask and its corners' texture coordinates (slot-transformed).
#[derive(Clone, Copy, Debug)]
struct CutTriangle {
    mask: u32,
    uv: [Vec2; 3],
}

/// What a cut-out tests: the alpha texture (none: the factor alone), factor and cutoff.
#[derive(Clone, Debug)]
struct Mask {
    texture: Option<Arc<Texture>>,
    factor: f32,
    cutoff: f32,
}

/// Where the triangles of a list are open: per triangle, solid or cut out by a mask at its
/// UVs. Empty (no allocation, every test one branch) when nothing is cut out.
#[derive(Clone, Debug, Default)]
pub struct Holes {
    /// Per triangle, an index into `cut` or [`SOLID`]; empty when no triangle is cut out.
    index: Vec<u32>,
    cut: Vec<CutTriangle>,
    masks: Vec<Mask>,
}

/// The silhouettes of shadows between groups leave a cut-out's holes uncovered.
impl kage_runtime::prt::silhouette::Openings for Holes {
    fn cuts(&self, t: usize) -> bool {
        Holes::cuts(self, t)
    }

    fn open(&self, t: usize, b: Vec2) -> bool {
        Holes::open(self, t, b)
    }
}

impl Holes {
    /// The holes of one instance's triangles, in mesh order: none without a cut-out.
    /// `mirrored` swaps corners 1 and 2 as [`crate::scene::flatten`] does.
    pub fn of_mesh(mesh: &Mesh, cutout: Option<&Cutout>, textures: &[Arc<Texture>], mirrored: bool) -> Self {
        let Some(c) = cutout else { return Self::default() };
        let texture = c.alpha.map(|s| textures[s.texture as usize].clone());
        let uv = |v: u32| {
            let at = |a: &[Vec2]| a.get(v as usize).copied().unwrap_or(Vec2::ZERO);
            c.alpha.map_or(Vec2::ZERO, |s| s.uv(at(&mesh.uvs), at(&mesh.uvs1)))
        };
        let cut: Vec<CutTriangle> = mesh
            .triangles
            .iter()
            .map(|t| {
                let mut uv = t.map(uv);
                if mirrored {
                    uv.swap(1, 2);
                }
                CutTriangle { mask: 0, uv }
            })
            .collect();
        let masks = vec![Mask { texture, factor: c.factor, cutoff: c.cutoff }];
        Self { index: (0..cut.len() as u32).collect(), cut, masks }
    }

    /// True when no triangle is cut out.
    pub fn is_empty(&self) -> bool {
        self.cut.is_empty()
    }

    /// Whether triangle `t` is cut out at all (may have holes).
    #[inline]
    pub fn cuts(&self, t: usize) -> bool {
        self.index.get(t).is_some_and(|&i| i != SOLID)
    }

    /// Whether triangle `t` is open at barycentrics `b` = (b1, b2) of its corners.
    pub fn open(&self, t: usize, b: Vec2) -> bool {
        let Some(&i) = self.index.get(t).filter(|&&i| i != SOLID) else { return false };
        let c = &self.cut[i as usize];
        let uv = c.uv[0] * (1.0 - b.x - b.y) + c.uv[1] * b.x + c.uv[2] * b.y;
        let m = &self.masks[c.mask as usize];
        let alpha = m.factor * m.texture.as_ref().map_or(1.0, |t| t.sample(uv).x);
        alpha < m.cutoff
    }

    /// `count` solid triangles (empty: solid needs no entries unless holes follow).
    fn solid(count: usize) -> Self {
        Self { index: vec![SOLID; count], cut: Vec::new(), masks: Vec::new() }
    }

    /// The lists one after the other, as their triangles are concatenated.
    fn concat(parts: impl IntoIterator<Item = Self>) -> Self {
        let mut out = Self::default();
        for p in parts {
            let (cuts, masks) = (out.cut.len() as u32, out.masks.len() as u32);
            out.index.extend(p.index.iter().map(|&i| if i == SOLID { SOLID } else { i + cuts }));
            out.cut.extend(p.cut.iter().map(|c| CutTriangle { mask: c.mask + masks, uv: c.uv }));
            out.masks.extend(p.masks);
        }
        if out.cut.is_empty() { Self::default() } else { out }
    }

    /// The lists `(holes, triangle count)` one after the other, as their triangles are
    /// concatenated (a list with no holes stands for its count of solid triangles).
    pub fn concat_counted(parts: impl IntoIterator<Item = (Self, usize)>) -> Self {
        let parts: Vec<(Self, usize)> = parts.into_iter().collect();
        if parts.iter().all(|(h, _)| h.is_empty()) {
            return Self::default();
        }
        Self::concat(parts.into_iter().map(|(h, n)| if h.is_empty() { Self::solid(n) } else { h }))
    }

    /// True when both cut the same triangles by the same masks (textures compared by identity:
    /// a scene's textures are immutable and shared).
    pub fn same(&self, other: &Self) -> bool {
        let masks = self.masks.len() == other.masks.len()
            && self.masks.iter().zip(&other.masks).all(|(a, b)| {
                let texture = match (&a.texture, &b.texture) {
                    (Some(x), Some(y)) => Arc::ptr_eq(x, y),
                    (x, y) => x.is_none() && y.is_none(),
                };
                texture && a.factor == b.factor && a.cutoff == b.cutoff
            });
        let cut = self.cut.len() == other.cut.len()
            && self.cut.iter().zip(&other.cut).all(|(a, b)| a.mask == b.mask && a.uv == b.uv);
        masks && cut && self.index == other.index
    }

    /// The holes of the triangles `order` lists, in that order (a BVH's leaf order, a subset).
    pub fn select(&self, order: impl Iterator<Item = usize>) -> Self {
        if self.is_empty() {
            return Self::default();
        }
        let index = order.map(|t| self.index.get(t).copied().unwrap_or(SOLID)).collect();
        Self { index, cut: self.cut.clone(), masks: self.masks.clone() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::texture::Wrap;
    use glam::{Affine2, Vec3};

    /// A quad of two triangles whose alpha texture is open on its left half (u < 0.5).
    fn half_open(mirrored: bool) -> Holes {
        let mesh = Mesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
            normals: vec![Vec3::Z; 4],
            uvs: vec![Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y],
            uvs1: Vec::new(),
            colors: Vec::new(),
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            hash: crate::scene::MeshHash([0; 32]),
        };
        let alpha = Texture::new(2, 1, vec![Vec3::ZERO, Vec3::ONE], [Wrap::Clamp; 2]);
        let slot = TextureSlot { texture: 0, texcoord: 0, transform: Affine2::IDENTITY };
        let cutout = Cutout { alpha: Some(slot), factor: 1.0, cutoff: 0.5 };
        Holes::of_mesh(&mesh, Some(&cutout), &[Arc::new(alpha)], mirrored)
    }

    #[test]
    fn a_cut_out_triangle_is_open_where_alpha_is_below_the_cutoff() {
        let h = half_open(false);
        // Triangle 0's corners are uv (0,0), (1,0), (1,1): b1 = 0.9 is u ≈ 0.9+, solid.
        assert!(!h.open(0, Vec2::new(0.9, 0.05)));
        assert!(h.open(0, Vec2::new(0.1, 0.05)), "u 0.15: alpha 0");
        // Mirroring swaps corners 1 and 2, and the barycentrics with them.
        let m = half_open(true);
        assert!(!m.open(0, Vec2::new(0.05, 0.9)));
        assert!(m.open(0, Vec2::new(0.05, 0.1)));
    }

    /// Rays and instance occluders see through the open half; a beam (which sees whole
    /// triangles) is never made for a cut-out instance.
    #[test]
    fn bvhs_are_open_where_the_holes_are() {
        use crate::accel::{Occluders, SceneBvh};
        let quad = [[Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0)], [Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::Y]];
        let holes = half_open(false);
        let bvh = SceneBvh::new(&quad).cut(&holes);
        let occluders = Occluders::with(&[quad.to_vec()], std::slice::from_ref(&holes), |_, t| SceneBvh::new(t));
        for (x, open) in [(0.2, true), (0.4, true), (0.6, false), (0.9, false)] {
            let o = Vec3::new(x, 0.5, 1.0);
            assert_eq!(bvh.closest_hit(o, Vec3::NEG_Z, 2.0).is_none(), open, "x {x}");
            assert_eq!(bvh.occluded(o, Vec3::NEG_Z, 2.0), !open, "x {x}");
            assert_eq!(occluders.occluded(o, Vec3::NEG_Z, 2.0), !open, "x {x}");
        }
        assert!(occluders.beam(0, Vec3::Z).is_none());
        assert!(Occluders::new(&[quad.to_vec()]).beam(0, Vec3::Z).is_some(), "solid: a beam");
    }

    /// A silhouette covers only the solid half (the covered texel count is the table's last
    /// entry).
    #[test]
    fn silhouettes_are_open_where_the_holes_are() {
        use crate::prt::silhouette::Silhouette;
        let quad = [[Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0)], [Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::Y]];
        let covered = |holes: &Holes| {
            let s = Silhouette::build(&quad, holes, Vec3::new(0.5, 0.5, 0.0), 0.75, Vec3::Z, 64);
            *s.sat().last().unwrap()
        };
        let (solid, cut) = (covered(&Holes::default()), covered(&half_open(false)));
        assert!((cut / solid - 0.5).abs() < 0.05, "{cut} of {solid} texels");
    }

    #[test]
    fn selection_and_concatenation_keep_each_triangle_its_holes() {
        let h = half_open(false);
        let both = Holes::concat_counted([(Holes::default(), 3), (h.clone(), 2)]);
        assert!(!both.cuts(0) && !both.cuts(2) && both.cuts(3) && both.cuts(4));
        assert_eq!(both.open(4, Vec2::new(0.9, 0.05)), h.open(1, Vec2::new(0.9, 0.05)));
        let picked = both.select([4, 0].into_iter());
        assert!(picked.cuts(0) && !picked.cuts(1) && !picked.cuts(7), "out of range is solid");
        assert!(Holes::concat_counted([(Holes::default(), 5)]).is_empty());
    }
}
