//! How far the occluders are, beside the coverage trees: a light is shadowed only by what lies
//! between the shading point and the light, so a light under a ceiling is not hidden by the
//! ceiling behind it.
//!
//! Per face, a quadtree over the texels whose leaves are **bounding planes** `n · x = c` (x
//! relative to the vertex, `n` pointing away from it): every occluder a leaf's occluded
//! texels meet lies at or beyond its plane. Inside a tile of the coverage grid ([`TILE`]²
//! texels), a cell keeps the plane of its first occluded texel's first hit (a wall, a ceiling,
//! a floor, a box's side; [`Plane::of`]) when every other hit of the cell lies on it, else
//! splits in four, down to single texels (their hit's own plane): an edge between
//! two walls, an object in front of a wall, a curved surface are resolved texel by texel. Above
//! the tiles, cells split on tile boundaries (each axis spanning more than one tile halved);
//! four siblings that are the same leaf merge into one, as the coverage trees' uniform
//! siblings do: a wall seen through many tiles is one plane. A tile's subtree depends on that
//! tile's hits alone and the join is a fixed rule, so a warm re-bake rebuilds only the tiles it
//! re-casts ([`split_tiles`], [`join_tiles`]). At shading, the part of a light piece in front
//! of a leaf's plane (`n · x < c`) is seen past that leaf's occluders ([`front`]).
//!
//! Bytes (per face; empty when no texel has a plane): the quadtree in pre-order, a tag byte
//! per node — [`EMPTY`] (no plane: no occluded texel), [`PLANE`] then 7 bytes (the normal's octahedral coordinates as two
//! little-endian `u16`, then the top three bytes of `c`'s `f32` bits, big-endian: truncation
//! rounds toward the vertex, so the plane stays a bound), or [`SPLIT`] then its children
//! ([`children`] order; empty ranges omitted). Quantised from the `f32` bits and decoded with
//! arithmetic and a square root only: the same inputs give the same bytes and planes on every
//! machine.

use super::node::TILE;
use crate::math::{cubemap, polygon};
use glam::{DVec2, DVec3, Vec2, Vec3};

/// An occluded texel's first hit, relative to the vertex: the point and the plane it lies in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// The hit point relative to the vertex.
    pub q: Vec3,
    /// Unit normal of the surface there, pointing away from the vertex.
    pub n: Vec3,
    /// The surface's plane is `n · x = c`.
    pub c: f32,
}

impl Hit {
    /// The hit at `q` on the plane through `corner` with unit normal `normal` (either side),
    /// all relative to the vertex. A surface met edge-on bounds by the plane through the hit
    /// square to the ray.
    pub fn new(q: Vec3, normal: Vec3, corner: Vec3) -> Self {
        let n = if normal.dot(q) < 0.0 { -normal } else { normal };
        if n.dot(q) > 1e-3 * q.length() {
            Hit { q, n, c: n.dot(corner) }
        } else {
            let n = q.normalize_or(Vec3::Z);
            Hit { q, n, c: n.dot(q) }
        }
    }
}

/// How far in front of a surface (relative to its distance) a cell's plane is put: beyond the
/// rounding of the surface's points and of the stored normal.
pub const SAME: f32 = 1e-4;

/// A cell keeps its plane when all its hits lie on it: at most this far behind it, relative to
/// its distance. A plane that merely bounds them would hide a light beyond it but in front of
/// the occluders, in the directions between them.
pub const FLAT: f32 = 1e-3;

/// Tag: a cell without a plane (no occluded texel).
pub const EMPTY: u8 = 0;
/// Tag: a bounding plane follows.
pub const PLANE: u8 = 1;
/// Tag: four (or fewer) children follow.
pub const SPLIT: u8 = 2;

/// Bytes of a plane after its tag.
const PLANE_BYTES: usize = 7;

/// `n · x = c` with every occluder of its cell at or beyond it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// Unit normal, pointing away from the vertex.
    pub n: Vec3,
    /// Distance from the vertex (≥ 0; 0: nothing is in front).
    pub c: f32,
}

/// Octahedral coordinates of unit `n` in [−1, 1]² (Cigolle et al. 2014).
pub fn octahedral(n: Vec3) -> Vec2 {
    let p = Vec2::new(n.x, n.y) / (n.x.abs() + n.y.abs() + n.z.abs());
    if n.z >= 0.0 { p } else { (Vec2::ONE - Vec2::new(p.y.abs(), p.x.abs())) * sign(p) }
}

/// The unit vector at octahedral coordinates `p` (the inverse of [`octahedral`]).
pub fn from_octahedral(p: Vec2) -> Vec3 {
    let mut n = Vec3::new(p.x, p.y, 1.0 - p.x.abs() - p.y.abs());
    let t = (-n.z).max(0.0);
    n.x += if n.x >= 0.0 { -t } else { t };
    n.y += if n.y >= 0.0 { -t } else { t };
    n.normalize()
}

fn sign(p: Vec2) -> Vec2 {
    Vec2::new(if p.x >= 0.0 { 1.0 } else { -1.0 }, if p.y >= 0.0 { 1.0 } else { -1.0 })
}

/// Steps of an octahedral coordinate's 16-bit code: an even count, so that 0 (and with it
/// every axis direction) is a code and walls in axis planes are stored exactly.
const STEPS: f32 = 65534.0;

/// The 16-bit codes of unit `n`'s octahedral coordinates.
fn encode_normal(n: Vec3) -> [u16; 2] {
    let p = octahedral(n);
    [p.x, p.y].map(|v| ((v.clamp(-1.0, 1.0) * 0.5 + 0.5) * STEPS).round() as u16)
}

/// The unit normal of two 16-bit codes.
fn decode_normal(code: [u16; 2]) -> Vec3 {
    from_octahedral(Vec2::from(code.map(|c| c as f32 / STEPS * 2.0 - 1.0)))
}

/// `c` rounded toward zero to the 24 bits stored.
fn truncate(c: f32) -> f32 {
    f32::from_bits(c.to_bits() & 0xFFFF_FF00)
}

impl Plane {
    fn encode(&self, out: &mut Vec<u8>) {
        let [a, b] = encode_normal(self.n);
        out.extend_from_slice(&a.to_le_bytes());
        out.extend_from_slice(&b.to_le_bytes());
        out.extend_from_slice(&self.c.to_bits().to_be_bytes()[..3]);
    }

    fn decode(b: &[u8]) -> Plane {
        let code = [u16::from_le_bytes([b[0], b[1]]), u16::from_le_bytes([b[2], b[3]])];
        Plane { n: decode_normal(code), c: f32::from_bits(u32::from_be_bytes([b[4], b[5], b[6], 0])) }
    }

    /// The plane a tile keeps for its first hit: the hit's surface plane as stored, moved
    /// toward the vertex by [`SAME`] of its distance so that the surface's other points (its
    /// rounding, the stored normal's) lie beyond it; `None` when that leaves nothing in front.
    pub fn of(hit: &Hit) -> Option<Plane> {
        let n = decode_normal(encode_normal(hit.n));
        let c = truncate(hit.c * (1.0 - SAME));
        (c > 0.0 && c.is_finite()).then_some(Plane { n, c })
    }

    /// The plane as a leaf's bytes.
    pub fn leaf(&self) -> Vec<u8> {
        let mut out = vec![PLANE];
        self.encode(&mut out);
        out
    }
}

/// A tile's subtree from its occluded texels' first hits (`hits[bit]`, bits as in
/// `kage_engine::bspvt::visibility::TileBits`; `None`: not occluded) over its `w × h` texels ([`cell`]);
/// `None` when no texel is occluded.
pub fn encode_tile(hits: &[Option<Hit>; TILE * TILE], (w, h): (usize, usize)) -> Option<Vec<u8>> {
    let mut out = Vec::new();
    cell(hits, [0, w, 0, h], &mut out);
    (out != [EMPTY]).then_some(out)
}

/// Appends the subtree of the texels `[i0, i1) × [j0, j1)` of a tile: the plane of the cell's
/// first hit ([`Plane::of`]) when every hit of the cell lies on it (within [`FLAT`]), else the
/// cell's children, down to single texels (their hit's own plane).
fn cell(hits: &[Option<Hit>; TILE * TILE], r: [usize; 4], out: &mut Vec<u8>) {
    let [i0, i1, j0, j1] = r;
    let inside: Vec<Hit> = (j0..j1).flat_map(|j| (i0..i1).filter_map(move |i| hits[j * TILE + i])).collect();
    let Some(first) = inside.first() else {
        out.push(EMPTY);
        return;
    };
    let plane = Plane::of(first);
    let single = i1 - i0 == 1 && j1 - j0 == 1;
    match plane {
        Some(p) if single || inside.iter().all(|h| (p.c..=p.c * (1.0 + FLAT)).contains(&p.n.dot(h.q))) => {
            out.extend(p.leaf())
        }
        // At the vertex itself: nothing can be in front.
        None if single => out.push(EMPTY),
        _ => {
            let start = out.len();
            out.push(SPLIT);
            let kids: Vec<usize> = children(r)
                .map(|c| {
                    let at = out.len();
                    cell(hits, c, out);
                    at
                })
                .collect();
            merge_if_same(out, start, &kids);
        }
    }
}

/// Replaces the split at `start` by its children's leaf (starting at `kids`, ending at the end
/// of `out`) when they are all the same leaf.
fn merge_if_same(out: &mut Vec<u8>, start: usize, kids: &[usize]) {
    let ends: Vec<usize> = kids.iter().skip(1).copied().chain([out.len()]).collect();
    let child = |k: usize| &out[kids[k]..ends[k]];
    if (0..kids.len()).all(|k| child(k)[0] != SPLIT && child(k) == child(0)) {
        let leaf = child(0).to_vec();
        out.truncate(start);
        out.extend_from_slice(&leaf);
    }
}

/// The children of the cell of texel ranges `[i0, i1) × [j0, j1)`, in the stored order — (low
/// s, low t), (high s, low t), (low s, high t), (high s, high t), empty ranges omitted: a cell
/// of more than one tile halves each axis that spans more than one on a tile boundary; a cell
/// inside one tile halves both axes.
pub fn children([i0, i1, j0, j1]: [usize; 4]) -> impl Iterator<Item = [usize; 4]> {
    let tiles = |a: usize, b: usize| b.div_ceil(TILE) - a / TILE;
    let inside = tiles(i0, i1) == 1 && tiles(j0, j1) == 1;
    let half = |a: usize, b: usize| match (inside, tiles(a, b)) {
        (true, _) => (a + b) / 2,
        (false, 1) => b,
        (false, n) => (a / TILE + n / 2) * TILE,
    };
    let (im, jm) = (half(i0, i1), half(j0, j1));
    [[i0, im, j0, jm], [im, i1, j0, jm], [i0, im, jm, j1], [im, i1, jm, j1]]
        .into_iter()
        .filter(|[a, b, c, d]| a < b && c < d)
}

/// Whether the cell is exactly one tile of the grid (at face resolution `res`).
fn is_tile(r: [usize; 4], res: usize) -> bool {
    r[0].is_multiple_of(TILE)
        && r[2].is_multiple_of(TILE)
        && r[1] == (r[0] + TILE).min(res)
        && r[3] == (r[2] + TILE).min(res)
}

/// The face's bytes from its tiles' subtrees (row-major, [`encode_tile`]; `None`: no plane) at
/// face resolution `res`: joined cell by cell, four siblings that are the
/// same leaf merged; empty when no texel is occluded.
pub fn join_tiles(tiles: &[Option<&[u8]>], res: usize) -> Vec<u8> {
    let mut out = Vec::new();
    join(tiles, res, [0, res, 0, res], &mut out);
    if out == [EMPTY] { Vec::new() } else { out }
}

/// Appends the joined subtree of cell `r` (whole tiles).
fn join(tiles: &[Option<&[u8]>], res: usize, r: [usize; 4], out: &mut Vec<u8>) {
    if is_tile(r, res) {
        let k = res.div_ceil(TILE);
        out.extend_from_slice(tiles[(r[2] / TILE) * k + r[0] / TILE].unwrap_or(&[EMPTY]));
        return;
    }
    let start = out.len();
    out.push(SPLIT);
    let kids: Vec<usize> = children(r)
        .map(|c| {
            let at = out.len();
            join(tiles, res, c, out);
            at
        })
        .collect();
    merge_if_same(out, start, &kids);
}

/// Each tile's subtree of a well-formed face at face resolution `res` (the inverse of
/// [`join_tiles`]: a tile under a merged leaf gets that leaf; `None`: no occluded texel).
pub fn split_tiles(face: &[u8], res: usize) -> Vec<Option<Vec<u8>>> {
    let k = res.div_ceil(TILE);
    let mut out = vec![None; k * k];
    if !face.is_empty() {
        split(face, 0, [0, res, 0, res], res, &mut out);
    }
    out
}

/// Fills `out` with the tiles of cell `r` (whole tiles), whose subtree starts at byte `i`;
/// returns the index past it.
fn split(face: &[u8], i: usize, r: [usize; 4], res: usize, out: &mut [Option<Vec<u8>>]) -> usize {
    let k = res.div_ceil(TILE);
    if is_tile(r, res) || face[i] != SPLIT {
        // A tile's subtree, or a merged leaf: every tile under it is that leaf.
        let end = walk(face, i, r).expect("a well-formed quadtree");
        let bytes = (face[i..end] != [EMPTY]).then(|| face[i..end].to_vec());
        for tj in r[2] / TILE..r[3].div_ceil(TILE) {
            for ti in r[0] / TILE..r[1].div_ceil(TILE) {
                out[tj * k + ti] = bytes.clone();
            }
        }
        return end;
    }
    children(r).fold(i + 1, |at, c| split(face, at, c, res, out))
}

/// Checks a face's bytes read from outside (an asset pack) at face resolution `res`: empty, or
/// exactly one well-formed quadtree over the face.
pub fn check_face(face: &[u8], res: usize) -> Result<(), String> {
    if face.is_empty() {
        return Ok(());
    }
    match walk(face, 0, [0, res, 0, res])? {
        end if end == face.len() => Ok(()),
        end => Err(format!("{} bytes after the quadtree", face.len() - end)),
    }
}

/// Index just past the quadtree starting at byte `i` over the cell of texel ranges `r`, or
/// why it is malformed (a tag unknown, a plane cut short or not at a distance ≥ 0, a single
/// texel split).
fn walk(bytes: &[u8], i: usize, r: [usize; 4]) -> Result<usize, String> {
    match bytes.get(i) {
        Some(&EMPTY) => Ok(i + 1),
        Some(&PLANE) => {
            let b = bytes.get(i + 1..i + 1 + PLANE_BYTES).ok_or("a plane cut short")?;
            let c = Plane::decode(b).c;
            if !(c.is_finite() && c >= 0.0) {
                return Err(format!("a plane at distance {c}"));
            }
            Ok(i + 1 + PLANE_BYTES)
        }
        Some(&SPLIT) if r[1] - r[0] == 1 && r[3] - r[2] == 1 => Err("a single texel split".into()),
        Some(&SPLIT) => children(r).try_fold(i + 1, |at, c| walk(bytes, at, c)),
        Some(t) => Err(format!("tag {t}")),
        None => Err("cut short".into()),
    }
}

/// Calls `seen` with each part of `piece` (points relative to the vertex, inside face `f`'s
/// frustum) that lies in front of the occluders face `f`'s depth bytes `face` bound, at face
/// resolution `res`: the parts that a light there would shine past them.
pub fn front(face: &[u8], f: usize, res: usize, piece: &[DVec3], seen: &mut impl FnMut(&[DVec3])) {
    if face.is_empty() || piece.len() < 3 {
        return;
    }
    let (c, s_ax, t_ax) = cubemap::face_basis(f);
    let (mut lo, mut hi) = (DVec2::splat(f64::MAX), DVec2::splat(f64::MIN));
    for q in piece {
        let st = DVec2::new(q.dot(s_ax), q.dot(t_ax)) / q.dot(c);
        (lo, hi) = (lo.min(st), hi.max(st));
    }
    let under = (cubemap::texel_of(lo, res), cubemap::texel_of(hi, res));
    descend(face, 0, [0, res, 0, res], (f, res, under), piece, seen);
}

/// The texels `(first, last)` (inclusive) a piece's bounds cover.
type Under = ((usize, usize), (usize, usize));

/// [`front`] within the cell of texel ranges `r` whose quadtree starts at byte `i`; returns the
/// index past it. Cells outside the texels `under` are skipped.
fn descend(
    bytes: &[u8],
    i: usize,
    r: [usize; 4],
    (f, res, under): (usize, usize, Under),
    piece: &[DVec3],
    seen: &mut impl FnMut(&[DVec3]),
) -> usize {
    let ((i_lo, j_lo), (i_hi, j_hi)) = under;
    if !(r[0] <= i_hi && i_lo < r[1] && r[2] <= j_hi && j_lo < r[3]) {
        return walk(bytes, i, r).expect("a well-formed quadtree");
    }
    match bytes[i] {
        EMPTY => i + 1,
        PLANE => {
            let plane = Plane::decode(&bytes[i + 1..]);
            if plane.c > 0.0 {
                let inside = clip_to_cell(piece, f, res, r);
                let ahead = polygon::clip_below(&inside, plane.n.as_dvec3(), plane.c as f64);
                if ahead.len() >= 3 {
                    seen(&ahead);
                }
            }
            i + 1 + PLANE_BYTES
        }
        _ => children(r).fold(i + 1, |at, c| descend(bytes, at, c, (f, res, under), piece, seen)),
    }
}

/// `piece` clipped to the texels `[i0, i1) × [j0, j1)` of face `f`.
fn clip_to_cell(piece: &[DVec3], f: usize, res: usize, [i0, i1, j0, j1]: [usize; 4]) -> Vec<DVec3> {
    let edge = |k: usize| 2.0 * k as f64 / res as f64 - 1.0;
    let planes = [
        cubemap::line_plane(f, 1.0, 0.0, -edge(i0)),
        cubemap::line_plane(f, -1.0, 0.0, edge(i1)),
        cubemap::line_plane(f, 0.0, 1.0, -edge(j0)),
        cubemap::line_plane(f, 0.0, -1.0, edge(j1)),
    ];
    planes.iter().fold(piece.to_vec(), |p, n| if p.len() < 3 { p } else { polygon::clip(&p, *n) })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::Rng;

    /// Octahedral coordinates and their inverse round-trip every unit vector, and the stored
    /// 16-bit codes within 10⁻⁴.
    #[test]
    fn octahedral_coordinates_round_trip() {
        let mut r = crate::math::rng::seeded(2);
        for _ in 0..10_000 {
            let n = Vec3::new(r.random_range(-1.0..1.0), r.random_range(-1.0..1.0), r.random_range(-1.0..1.0));
            let Some(n) = n.try_normalize() else { continue };
            assert!(from_octahedral(octahedral(n)).distance(n) < 1e-6, "{n}");
            assert!(decode_normal(encode_normal(n)).distance(n) < 1e-4, "{n}");
        }
        for n in [Vec3::X, Vec3::NEG_Y, Vec3::Z, Vec3::NEG_Z] {
            assert!(decode_normal(encode_normal(n)).distance(n) < 1e-6, "{n}");
        }
    }

    /// A surface's plane is the same leaf from any of its points (one wall seen through many
    /// tiles merges), and in front of every point of the surface (of a tilted one within about
    /// twice its distance, where the stored normal's rounding stays under [`SAME`]).
    #[test]
    fn a_surface_is_one_plane_in_front_of_it() {
        let mut r = crate::math::rng::seeded(4);
        for k in 0..500 {
            let axis = [Vec3::Y, Vec3::NEG_X, Vec3::Z][k % 3];
            let tilted = Vec3::new(r.random_range(-0.8..0.8), 1.0, r.random_range(-0.8..0.8)).normalize();
            let n = if k % 2 == 0 { axis } else { tilted };
            let c = r.random_range(0.01..30.0f32);
            let (u, v) = (n.any_orthonormal_vector(), n.cross(n.any_orthonormal_vector()));
            let spread = if n == axis { 40.0 } else { 1.0 };
            let mut point = || n * c + (u * r.random_range(-1.0..1.0) + v * r.random_range(-1.0..1.0)) * c * spread;
            let (a, b) = (point(), point());
            let plane = Plane::of(&Hit::new(a, n, a)).unwrap();
            assert!(plane.c < c && plane.c > c * (1.0 - 2.0 * SAME), "{plane:?} for {n} {c}");
            if n == axis {
                assert_eq!(Plane::of(&Hit::new(b, -n, b)), Some(plane), "the same plane from any point");
            }
            for _ in 0..20 {
                let q = point();
                assert!(plane.n.dot(q) >= plane.c, "{plane:?}: {q} of {n} {c}");
            }
        }
        assert_eq!(Plane::of(&Hit::new(Vec3::ZERO, Vec3::Y, Vec3::ZERO)), None, "at the vertex");
    }

    /// A tile on one plane is one leaf; a box standing in front of the plane splits the
    /// tile where it stands, and every leaf bounds its cell's hits.
    #[test]
    fn a_tile_splits_where_an_object_stands_in_front_of_a_wall() {
        let at = |b: usize, y: f32| {
            let q = Vec3::new((b % TILE) as f32 - 3.5, y, (b / TILE) as f32 - 3.5);
            Hit::new(q, Vec3::Y, Vec3::Y * y)
        };
        let wall: [Option<Hit>; TILE * TILE] = std::array::from_fn(|b| Some(at(b, 2.5)));
        assert_eq!(encode_tile(&wall, (TILE, TILE)).unwrap().len(), 1 + PLANE_BYTES);
        let boxed: [Option<Hit>; TILE * TILE] =
            std::array::from_fn(|b| Some(at(b, if b % TILE >= 5 && b / TILE >= 5 { 2.0 } else { 2.5 })));
        let bytes = encode_tile(&boxed, (TILE, TILE)).unwrap();
        assert_eq!(bytes[0], SPLIT);
        let face = join_tiles(&[Some(&bytes[..])], TILE);
        check_face(&face, TILE).unwrap();
        let mut planes = 0;
        bound(&face, 0, [0, TILE, 0, TILE], &boxed, &mut planes);
        assert!(planes > 4 && bytes.len() < 20 * (1 + PLANE_BYTES), "{planes} planes, {} bytes", bytes.len());
    }

    /// Checks that every plane leaf of the subtree at `i` bounds its cell's hits.
    fn bound(bytes: &[u8], i: usize, r: [usize; 4], hits: &[Option<Hit>; 64], planes: &mut usize) -> usize {
        match bytes[i] {
            EMPTY => i + 1,
            PLANE => {
                *planes += 1;
                let p = Plane::decode(&bytes[i + 1..]);
                let cell = (r[2]..r[3]).flat_map(|j| (r[0]..r[1]).filter_map(move |i| hits[j * TILE + i]));
                cell.for_each(|h| assert!(p.n.dot(h.q) >= p.c, "{p:?} {h:?}"));
                i + 1 + PLANE_BYTES
            }
            _ => children(r).fold(i + 1, |at, c| bound(bytes, at, c, hits, planes)),
        }
    }

    /// Tiles join into a face's quadtree, four equal siblings merged, and split back; the
    /// check refuses damaged bytes.
    #[test]
    fn tiles_join_split_and_check() {
        let one = Plane::of(&Hit::new(Vec3::new(0.3, 2.5, 0.1), Vec3::Y, Vec3::Y * 2.5)).unwrap().leaf();
        let other = Plane::of(&Hit::new(Vec3::new(0.3, 3.0, 0.1), Vec3::Y, Vec3::Y * 3.0)).unwrap().leaf();
        assert_eq!(one.len(), 1 + PLANE_BYTES);
        let face = join_tiles(&[None, Some(&one), None, Some(&other)], 2 * TILE);
        assert_eq!(face[0], SPLIT);
        assert_eq!(split_tiles(&face, 2 * TILE), [None, Some(one.clone()), None, Some(other.clone())]);
        check_face(&face, 2 * TILE).unwrap();
        assert!(check_face(&face[..face.len() - 1], 2 * TILE).is_err());
        assert!(check_face(&[face.clone(), vec![0]].concat(), 2 * TILE).unwrap_err().contains("after"));
        let mut wrong = face.clone();
        wrong[2] = 9;
        assert!(check_face(&wrong, 2 * TILE).unwrap_err().contains("tag 9"));
        assert!(check_face(&[SPLIT, EMPTY, EMPTY, EMPTY, EMPTY], 1).unwrap_err().contains("a single texel split"));
        assert!(join_tiles(&[None; 4], 2 * TILE).is_empty());
        // Four tiles of the same plane merge into one leaf, and split back into four.
        let merged = join_tiles(&[Some(&one[..]); 4], 2 * TILE);
        assert_eq!(merged, one);
        assert_eq!(split_tiles(&merged, 2 * TILE), vec![Some(one.clone()); 4]);
        // A face whose last tiles are narrower (20 texels: 8, 8, 4) joins and splits back.
        let tiles: Vec<Option<&[u8]>> = (0..9).map(|t| [None, Some(&one[..]), Some(&other[..])][t % 3]).collect();
        let narrow = join_tiles(&tiles, 20);
        check_face(&narrow, 20).unwrap();
        let back = split_tiles(&narrow, 20);
        assert!(back.iter().zip(&tiles).all(|(b, t)| b.as_deref() == *t));
    }
}
