//! The eight symmetries of a cube face (the square's dihedral group: mirrors in s and in t,
//! and the swap of s and t), acting on tiles, texel masks and quantised lines.
//!
//! The solid angle a face subtends per unit of area depends on s² + t² alone, so mirror-image
//! texels subtend equal solid angles, and Algorithm 1's problem in a tile and in its mirror
//! images are the same problem. A tile's subtree is therefore built once per orbit, for
//! the orbit's least key ([`Symmetric::canonical`]), and mapped to the other seven (see
//! [`super::memo::SubtreeMemo::subtree`]): a shadow edge crossing a tile one way and its mirror
//! image cost one build. The mapping is exact — a mapped line puts every mapped point on the
//! side the original put the point on — because [`super::node::dequantise_line`] evaluates
//! every angle code from its first-octant image, so the codes' cosines and sines are exact
//! mirrors of one another, and because a face's texel centres are exact mirrors of one another
//! when the face resolution is a power of two (see [`Symmetric::of`]).

use super::node::{Node, TILE, TileKey};

/// Angle codes per turn (see [`super::layout`]): a quarter turn is 512 codes.
const TURN: i32 = 2048;

/// A symmetry of the face: mirror in s (s ↦ −s), then mirror in t, then swap s and t.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Symmetry {
    flip_s: bool,
    flip_t: bool,
    swap: bool,
}

impl Symmetry {
    /// The identity.
    pub const IDENTITY: Self = Self { flip_s: false, flip_t: false, swap: false };

    /// All eight, the identity first.
    pub const ALL: [Self; 8] = {
        let mut all = [Self::IDENTITY; 8];
        let mut k = 0;
        while k < 8 {
            all[k] = Self { flip_s: k & 1 != 0, flip_t: k & 2 != 0, swap: k & 4 != 0 };
            k += 1;
        }
        all
    };

    /// The symmetry undoing this one.
    pub fn inverse(self) -> Self {
        // Swapping after the mirrors moves each mirror to the other axis.
        if self.swap { Self { flip_s: self.flip_t, flip_t: self.flip_s, swap: true } } else { self }
    }

    /// The image of cell (i, j) of an `n` × `n` grid whose cells are centred on the face.
    pub fn cell(self, (i, j): (usize, usize), n: usize) -> (usize, usize) {
        let i = if self.flip_s { n - 1 - i } else { i };
        let j = if self.flip_t { n - 1 - j } else { j };
        if self.swap { (j, i) } else { (i, j) }
    }

    /// The image of a tile's texel mask (bit `j · TILE + i` is texel (i, j) of the tile).
    pub fn mask(self, mut m: u64) -> u64 {
        if self.flip_s {
            // Reverse each row (byte).
            m = m.reverse_bits().swap_bytes();
        }
        if self.flip_t {
            m = m.swap_bytes();
        }
        if self.swap { transpose(m) } else { m }
    }

    /// The image of tile key `key` on a face of `k` × `k` tiles.
    pub fn key(self, (index, live, visible): TileKey, k: usize) -> TileKey {
        let (i, j) = self.cell((index as usize % k, index as usize / k), k);
        ((j * k + i) as u32, self.mask(live), self.mask(visible))
    }

    /// The image of an angle code: the code of the mapped line's normal.
    pub fn angle(self, a: u16) -> u16 {
        let mut a = a as i32;
        if self.flip_s {
            a = TURN / 2 - a;
        }
        if self.flip_t {
            a = -a;
        }
        if self.swap {
            a = TURN / 4 - a;
        }
        a.rem_euclid(TURN) as u16
    }

    /// Appends the image of a subtree to `out`: the same shape, each split's line mapped (its offset is
    /// unchanged, and each side's subtree stays on its side).
    pub fn extend(self, out: &mut Vec<Node>, nodes: &[Node]) {
        let line = |n: &Node| match *n {
            Node::Split { angle, offset } => Node::Split { angle: self.angle(angle), offset },
            leaf => leaf,
        };
        out.extend(nodes.iter().map(line));
    }
}

/// Transposes an 8 × 8 bit matrix (bit `8 r + c` is row r, column c), by three delta swaps
/// (Hacker's Delight, 7–3).
fn transpose(mut x: u64) -> u64 {
    let mut swap = |shift: u32, mask: u64| {
        let t = (x ^ (x >> shift)) & mask;
        x ^= t ^ (t << shift);
    };
    swap(7, 0x00AA_00AA_00AA_00AA);
    swap(14, 0x0000_CCCC_0000_CCCC);
    swap(28, 0x0000_0000_F0F0_F0F0);
    x
}

/// Whether a face resolution's tiles and texel centres are exactly symmetric.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Symmetric(bool);

impl Symmetric {
    /// For face resolution `res`: whole tiles only, and texel centres that mirror to the bit
    /// (powers of two; other resolutions build every tile as it is).
    pub fn of(res: usize) -> Self {
        let centre = |i: usize| crate::math::cubemap::texel_center(i, 0, res).x;
        Self(res.is_multiple_of(TILE) && (0..res).all(|i| centre(res - 1 - i) == -centre(i)))
    }

    /// The least of `key`'s images (a face of `k` × `k` tiles) and the symmetry giving it; `key`
    /// and the identity when the resolution is not symmetric.
    pub fn canonical(self, key: TileKey, k: usize) -> (TileKey, Symmetry) {
        if !self.0 {
            return (key, Symmetry::IDENTITY);
        }
        // The least key has the least tile index: only the symmetries giving that index need
        // their masks mapped. Ties (a key its own mirror image) go to the first symmetry, for
        // determinism.
        let index = |g: Symmetry| {
            let (i, j) = g.cell((key.0 as usize % k, key.0 as usize / k), k);
            j * k + i
        };
        let least = Symmetry::ALL.iter().map(|&g| index(g)).min().expect("eight symmetries");
        Symmetry::ALL
            .iter()
            .filter(|&&g| index(g) == least)
            .map(|&g| (g.key(key, k), g))
            .min_by_key(|&(image, _)| image)
            .expect("a symmetry gives the least index")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bspvt::node::dequantise_line;
    use crate::bspvt::split::Line;
    use crate::math::cubemap;
    use rand::Rng;

    impl Symmetry {
        /// The image of face point (s, t).
        fn point(self, (s, t): (f64, f64)) -> (f64, f64) {
            let (s, t) = (if self.flip_s { -s } else { s }, if self.flip_t { -t } else { t });
            if self.swap { (t, s) } else { (s, t) }
        }
    }

    /// Every symmetry composed with its inverse is the identity, on cells, masks, keys and
    /// angle codes; the eight are distinct.
    #[test]
    fn symmetries_round_trip_through_their_inverses() {
        let mask = 0x0123_4567_89AB_CDEF_u64;
        for g in Symmetry::ALL {
            let h = g.inverse();
            for (i, j) in [(0, 0), (3, 5), (7, 2), (6, 6)] {
                assert_eq!(h.cell(g.cell((i, j), 8), 8), (i, j), "{g:?}");
            }
            assert_eq!(h.mask(g.mask(mask)), mask, "{g:?}");
            assert_eq!(h.key(g.key((13, u64::MAX >> 3, mask), 8), 8), (13, u64::MAX >> 3, mask));
            assert!((0..2048).all(|a| h.angle(g.angle(a)) == a), "{g:?}");
        }
        let images: std::collections::HashSet<u64> = Symmetry::ALL.iter().map(|g| g.mask(1 << 1)).collect();
        assert_eq!(images.len(), 8);
    }

    /// A mask's image moves texel (i, j) to the cell image of (i, j), bit by bit.
    #[test]
    fn masks_move_texels_as_cells_do() {
        for g in Symmetry::ALL {
            for b in 0..64 {
                let (i, j) = g.cell((b % TILE, b / TILE), TILE);
                assert_eq!(g.mask(1 << b), 1 << (j * TILE + i), "{g:?}, bit {b}");
            }
        }
    }

    /// A mapped line puts every mapped point on the side the line put the point on, exactly:
    /// the dequantised normals of mapped codes are the mapped normals, to the bit. Texel
    /// centres of a power-of-two face mirror to the bit, so mapped tiles split their texels
    /// as the originals do.
    #[test]
    fn mapped_lines_keep_mapped_points_on_their_side() {
        for g in Symmetry::ALL {
            for a in 0..2048u16 {
                let ((cos, sin), _) = dequantise_line(a, 0);
                let ((cos2, sin2), _) = dequantise_line(g.angle(a), 0);
                assert_eq!(g.point((cos, sin)), (cos2, sin2), "{g:?}, code {a}");
            }
        }
        let res = 64;
        let centre = |(i, j)| {
            let c = cubemap::texel_center(i, j, res);
            (c.x, c.y)
        };
        for (a, o) in [(0, 2047), (300, 1990), (1024 + 77, 2100), (2047, 2047 - 64)] {
            let line = Line::dequantised(a, o);
            for g in Symmetry::ALL {
                let image = Line::dequantised(g.angle(a), o);
                for k in (0..res * res).step_by(7) {
                    let texel = (k % res, k / res);
                    assert_eq!(g.point(centre(texel)), centre(g.cell(texel, res)));
                    let side = |l: &Line, (s, t)| l.side(s, t) > 0.0;
                    assert_eq!(side(&line, centre(texel)), side(&image, centre(g.cell(texel, res))));
                }
            }
        }
    }

    /// The canonical key is the least of a key's eight images, found by the first symmetry
    /// giving it (tiles on the face's diagonals and middle lines included, and keys that are
    /// their own mirror images); it is the same for every image of a key; resolutions that are
    /// not symmetric keep keys as they are.
    #[test]
    fn canonical_keys_are_shared_by_an_orbit() {
        let mut r = crate::math::rng::seeded(2);
        let masks = [0, u64::MAX, 0x0000_0000_0F0F_0301, 0xFF00_FF00_FF00_FF00, 0x8142_2418_1824_4281];
        for index in [0, 3, 9, 10, 27, 36, 63] {
            for key in masks.iter().flat_map(|&m| [(index, u64::MAX, m), (index, m | 1, m & r.random::<u64>())]) {
                let (canon, g) = Symmetric::of(64).canonical(key, 8);
                let least = Symmetry::ALL.iter().map(|&h| (h.key(key, 8), h)).min_by_key(|&(image, _)| image);
                assert_eq!(Some((canon, g)), least, "{key:?}");
                for h in Symmetry::ALL {
                    assert_eq!(Symmetric::of(64).canonical(h.key(key, 8), 8).0, canon, "{h:?}");
                }
            }
        }
        let key = (10, u64::MAX, 0x0000_0000_0F0F_0301);
        assert_eq!(Symmetric::of(60).canonical(key, 8), (key, Symmetry::IDENTITY));
        assert_eq!(Symmetric::of(48), Symmetric(false), "texel centres of 48 do not mirror exactly");
    }
}
