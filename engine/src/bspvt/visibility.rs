//! Per-vertex visibility cube maps, ray-cast with the BVH. Texels entirely below the vertex's
//! horizon are never cast: LTC clips there, so their visibility cannot matter.

use super::tree::TILE;
use crate::accel::{Occluders, offset_ray_origin};
use crate::math::cubemap;
use glam::{DVec3, Vec3};

/// Texel state: blocked.
pub const OCCLUDED: u8 = 0;
/// Texel state: the light would be seen.
pub const VISIBLE: u8 = 1;
/// Texel state: below the horizon, not cast ("don't care").
pub const BELOW: u8 = 2;
/// Texel state: above the horizon but not cast (an incremental re-bake keeps its old result).
pub const SKIPPED: u8 = 3;

/// A visibility cube map: 6 faces of `res × res` texels, row-major per face.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CubeVisibility {
    /// Face resolution.
    pub res: usize,
    /// `6·res²` texel states.
    pub texels: Vec<u8>,
}

impl CubeVisibility {
    /// The texels of face `f`.
    pub fn face(&self, f: usize) -> &[u8] {
        let n = self.res * self.res;
        &self.texels[f * n..(f + 1) * n]
    }
}

/// Casts the visibility cube map of a vertex at `p` with unit normal `n` against `occluders`.
/// A texel is below the horizon only when all four of its corners are; a texel the horizon
/// crosses is cast just above the horizon, so that grazing lights are not cut off by half a
/// texel.
pub fn cast(occluders: &Occluders, p: Vec3, n: Vec3, res: usize) -> CubeVisibility {
    let texels = (0..cubemap::FACES).flat_map(|f| cast_face(occluders, p, n, f, res)).collect();
    CubeVisibility { res, texels }
}

/// The `res²` texel states of face `f` alone (see [`cast`]).
pub fn cast_face(occluders: &Occluders, p: Vec3, n: Vec3, f: usize, res: usize) -> Vec<u8> {
    TileBits::to_face(&cast_face_tiles(occluders, p, n, f, res), res)
}

/// [`cast_face`] as tiles: every texel above the horizon cast.
pub fn cast_face_tiles(occluders: &Occluders, p: Vec3, n: Vec3, f: usize, res: usize) -> Vec<TileBits> {
    let all = vec![true; res.div_ceil(TILE).pow(2)];
    cast_tiles(n, f, res, &all, |_, _| 0..res, |_, _, d| cast_ray(occluders, p, n, d))
}

/// The direction cast for texel (i, j) of face `f` above the horizon of unit normal `nd`:
/// its centre, or for a texel the horizon crosses the centre's projection onto the horizon
/// lifted slightly above it; `None` when the texel is entirely below the horizon.
pub fn texel_ray(f: usize, i: usize, j: usize, nd: DVec3, res: usize) -> Option<DVec3> {
    ray_through(cubemap::face_to_dir(f, cubemap::texel_center(i, j, res)), f, i, j, nd, res)
}

/// [`texel_ray`] given the texel's unit centre direction.
fn ray_through(centre: DVec3, f: usize, i: usize, j: usize, nd: DVec3, res: usize) -> Option<DVec3> {
    let edge = |k: usize| 2.0 * k as f64 / res as f64 - 1.0;
    let height = centre.dot(nd);
    // A texel spans less than 2/res radians: only those near the horizon need corners.
    let crossed = || {
        [(i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1)]
            .iter()
            .any(|&(a, b)| cubemap::face_to_dir(f, glam::DVec2::new(edge(a), edge(b))).dot(nd) > 0.0)
    };
    if height <= -2.0 / res as f64 || (height <= 0.0 && !crossed()) {
        None
    } else if height > 0.0 {
        Some(centre)
    } else {
        Some(((centre - nd * centre.dot(nd)).normalize_or(centre) + nd * 1e-3).normalize())
    }
}

/// The texel states of one [`TILE`]×[`TILE`] tile as bit masks: bit `(j mod TILE)·TILE +
/// i mod TILE` is texel (i, j).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TileBits {
    /// Above the horizon (cast or not).
    pub live: u64,
    /// Cast and visible.
    pub visible: u64,
    /// Above the horizon and not cast ([`SKIPPED`]).
    pub skipped: u64,
}

impl TileBits {
    /// The tiles (row-major) of a face's `res²` texel states.
    pub fn from_face(face: &[u8], res: usize) -> Vec<TileBits> {
        let k = res.div_ceil(TILE);
        let mut tiles = vec![TileBits::default(); k * k];
        for (x, &state) in face.iter().enumerate() {
            let (t, bit) = tile_bit(x % res, x / res, k);
            let t = &mut tiles[t];
            t.live |= if state == BELOW { 0 } else { bit };
            t.visible |= if state == VISIBLE { bit } else { 0 };
            t.skipped |= if state == SKIPPED { bit } else { 0 };
        }
        tiles
    }

    /// The face's `res²` texel states (the inverse of [`Self::from_face`]).
    pub fn to_face(tiles: &[TileBits], res: usize) -> Vec<u8> {
        let k = res.div_ceil(TILE);
        (0..res * res)
            .map(|x| {
                let (t, bit) = tile_bit(x % res, x / res, k);
                match tiles[t] {
                    t if t.live & bit == 0 => BELOW,
                    t if t.skipped & bit != 0 => SKIPPED,
                    t if t.visible & bit != 0 => VISIBLE,
                    _ => OCCLUDED,
                }
            })
            .collect()
    }
}

/// Texel (i, j)'s tile index (`k` tiles per side) and bit in its tile's masks.
fn tile_bit(i: usize, j: usize, k: usize) -> (usize, u64) {
    ((j / TILE) * k + i / TILE, 1u64 << ((j % TILE) * TILE + i % TILE))
}

/// Which tiles of face `f` (row-major) have a texel above the horizon of unit normal `n`: those
/// with a corner above it (the height's sign is affine over a face, so a tile's highest point
/// is a corner, and a texel with a corner above the horizon is cast; see [`texel_ray`]).
pub fn live_tiles(n: Vec3, f: usize, res: usize) -> Vec<bool> {
    let k = res.div_ceil(TILE);
    let height = corner_height(n.as_dvec3(), f, res);
    (0..k * k)
        .map(|t| {
            let (i0, j0) = ((t % k) * TILE, (t / k) * TILE);
            let (i1, j1) = ((i0 + TILE).min(res), (j0 + TILE).min(res));
            [(i0, j0), (i1, j0), (i0, j1), (i1, j1)].iter().any(|&(i, j)| height(i, j) > 0.0)
        })
        .collect()
}

/// The height above the horizon of unit normal `nd` of texel corner (i, j) of face `f`.
fn corner_height(nd: DVec3, f: usize, res: usize) -> impl Fn(usize, usize) -> f64 {
    let edge = move |k: usize| 2.0 * k as f64 / res as f64 - 1.0;
    move |i, j| cubemap::face_to_dir(f, glam::DVec2::new(edge(i), edge(j))).dot(nd)
}

/// The tiles of face `f` for a vertex with unit normal `n`, asking `texel` for the state of
/// each texel above the horizon in the tiles flagged in `tiles` (row-major, [`TILE`]-texel
/// tiles, the last ones narrower when `res` is not a multiple): `texel(tile, bit, direction)`
/// returns [`VISIBLE`], [`OCCLUDED`] or [`SKIPPED`]. An unflagged tile is not looked at texel by
/// texel: when it is live (see [`live_tiles`]) all of it is `SKIPPED`. In a flagged tile
/// entirely above the horizon only the texels of row `j` in `columns(tile, j)` are asked; the
/// others are `SKIPPED` too.
pub fn cast_tiles(
    n: Vec3,
    f: usize,
    res: usize,
    tiles: &[bool],
    columns: impl Fn(usize, usize) -> std::ops::Range<usize>,
    mut texel: impl FnMut(usize, u64, Vec3) -> u8,
) -> Vec<TileBits> {
    let nd = n.as_dvec3();
    let height = corner_height(nd, f, res);
    let k = res.div_ceil(TILE);
    let mut out = vec![TileBits::default(); k * k];
    // A face is below the horizon when its corners are (with a margin for rounding at the
    // face's corners).
    if [(0, 0), (res, 0), (0, res), (res, res)].iter().all(|&(i, j)| height(i, j) < -1e-9) {
        return out;
    }
    CENTRES.with_borrow_mut(|(at, centres)| {
        if *at != res {
            *at = res;
            *centres = (0..cubemap::FACES * res * res)
                .map(|k| cubemap::face_to_dir(k / (res * res), cubemap::texel_center(k % res, k / res % res, res)))
                .collect();
        }
        for (t, bits) in out.iter_mut().enumerate() {
            let (i0, j0) = ((t % k) * TILE, (t / k) * TILE);
            let (i1, j1) = ((i0 + TILE).min(res), (j0 + TILE).min(res));
            let heights = [(i0, j0), (i1, j0), (i0, j1), (i1, j1)].map(|(i, j)| height(i, j));
            let all = (j0..j1).flat_map(|j| (i0..i1).map(move |i| (i, j))).fold(0, |m, (i, j)| m | tile_bit(i, j, k).1);
            if !tiles[t] {
                if heights.iter().any(|&h| h > 0.0) {
                    *bits = TileBits { live: all, visible: 0, skipped: all };
                }
                continue;
            }
            // Entirely above the horizon (its lowest point is a corner): every texel is cast
            // through its centre, and only the asked columns need looking at.
            let above = heights.iter().all(|&h| h > 1e-9);
            let mut asked = 0;
            for j in j0..j1 {
                let cols = if above { columns(t, j) } else { i0..i1 };
                for i in cols.start.max(i0)..cols.end.min(i1) {
                    let centre = centres[(f * res + j) * res + i];
                    let d = if above { Some(centre) } else { ray_through(centre, f, i, j, nd, res) };
                    let Some(d) = d else { continue };
                    let bit = tile_bit(i, j, k).1;
                    asked |= bit;
                    match texel(t, bit, d.as_vec3()) {
                        VISIBLE => bits.visible |= bit,
                        SKIPPED => bits.skipped |= bit,
                        _ => {}
                    }
                }
            }
            if above {
                bits.live = all;
                bits.skipped |= all & !asked;
            } else {
                bits.live = asked;
            }
        }
    });
    out
}

/// Whether the ray from `p` (unit normal `n`) in direction `d` reaches the sky.
pub fn cast_ray(occluders: &Occluders, p: Vec3, n: Vec3, d: Vec3) -> u8 {
    if occluders.occluded(offset_ray_origin(p, n, d), d, f32::INFINITY) { OCCLUDED } else { VISIBLE }
}

thread_local! {
    /// Unit centre directions of every texel (face-major) at the last resolution this thread
    /// cast: normalising them per cast was a fifth of a bake. Per thread rather than one lazily
    /// built shared table, because a rayon worker blocked in a shared initialiser can deadlock.
    static CENTRES: std::cell::RefCell<(usize, Vec<DVec3>)> = const { std::cell::RefCell::new((0, Vec::new())) };
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An unflagged tile is all `SKIPPED` exactly when the full cast has a texel of it above
    /// the horizon (else all `BELOW`, and [`live_tiles`] agrees); a flagged one has the states
    /// `texel` gives, which it is asked for exactly above the horizon.
    #[test]
    fn selected_casts_agree_with_the_full_cast() {
        let roof = [Vec3::new(-2.0, 1.0, -2.0), Vec3::new(2.0, 1.0, -2.0), Vec3::new(0.0, 1.0, 2.0)];
        let occ = Occluders::new(&[vec![roof]]);
        // 20: the last tile of a face is narrower.
        let res: usize = 20;
        let k = res.div_ceil(TILE);
        let flags: Vec<bool> = (0..k * k).map(|t| t % 3 == 1).collect();
        for n in [Vec3::Y, Vec3::new(0.6, 0.0, 0.8), Vec3::new(-0.3, -0.9, 0.3).normalize()] {
            for f in 0..cubemap::FACES {
                let full = cast_face(&occ, Vec3::ZERO, n, f, res);
                let live = live_tiles(n, f, res);
                let texel = |_, _, d: Vec3| if d.x > 0.0 { cast_ray(&occ, Vec3::ZERO, n, d) } else { SKIPPED };
                // Rows ask for columns [j mod 5, j mod 5 + 9): most tiles are cut by it.
                let columns = |_, j: usize| j % 5..j % 5 + 9;
                let some = TileBits::to_face(&cast_tiles(n, f, res, &flags, columns, texel), res);
                for (x, (&a, &b)) in full.iter().zip(&some).enumerate() {
                    let (i, j) = (x % res, x / res);
                    let tile = (j / TILE) * k + i / TILE;
                    let in_live_tile =
                        (0..res * res).any(|y| tile_bit(y % res, y / res, k).0 == tile && full[y] != BELOW);
                    assert_eq!(live[tile], in_live_tile, "n {n}, face {f}, tile {tile}");
                    let expected = if flags[tile] {
                        let d = texel_ray(f, i, j, n.as_dvec3(), res).map(|d| d.as_vec3());
                        let (i0, j0) = (i / TILE * TILE, j / TILE * TILE);
                        let above = [(i0, j0), (i0 + TILE, j0), (i0, j0 + TILE), (i0 + TILE, j0 + TILE)]
                            .iter()
                            .all(|&(a, b)| corner_height(n.as_dvec3(), f, res)(a.min(res), b.min(res)) > 1e-9);
                        let asked = !above || (j % 5..j % 5 + 9).contains(&i);
                        if d.is_none_or(|d| d.x > 0.0 && asked) { a } else { SKIPPED }
                    } else if in_live_tile {
                        SKIPPED
                    } else {
                        BELOW
                    };
                    assert_eq!(b, expected, "n {n}, face {f}, texel ({i}, {j})");
                }
            }
        }
    }

    /// Tile bits and texel states convert both ways without loss.
    #[test]
    fn tile_bits_round_trip_texel_states() {
        let res = 20;
        let face: Vec<u8> = (0..res * res).map(|x| [OCCLUDED, VISIBLE, BELOW, SKIPPED][(x * 7 + x / 3) % 4]).collect();
        assert_eq!(TileBits::to_face(&TileBits::from_face(&face, res), res), face);
    }
}
