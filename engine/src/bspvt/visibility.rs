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
    cast_face_where(occluders, p, n, f, res, &vec![true; res.div_ceil(TILE).pow(2)], |_| true)
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

/// [`cast_face`] casting, in the tiles flagged in `tiles` (row-major, [`TILE`]-texel tiles,
/// the last ones narrower when `res` is not a multiple), only the texels whose ray direction
/// `wanted` accepts; the other texels above the horizon are [`SKIPPED`]. An unflagged tile is
/// not looked at texel by texel: when any of it is above the horizon, all of it is `SKIPPED`.
pub fn cast_face_where(
    occluders: &Occluders,
    p: Vec3,
    n: Vec3,
    f: usize,
    res: usize,
    tiles: &[bool],
    wanted: impl Fn(Vec3) -> bool,
) -> Vec<u8> {
    let nd = n.as_dvec3();
    let edge = |k: usize| 2.0 * k as f64 / res as f64 - 1.0;
    // The sign of the height is affine over a face: a region is below the horizon when its
    // corners are (with a margin for rounding at the face's corners).
    let height = |i: usize, j: usize| cubemap::face_to_dir(f, glam::DVec2::new(edge(i), edge(j))).dot(nd);
    if [(0, 0), (res, 0), (0, res), (res, res)].iter().all(|&(i, j)| height(i, j) < -1e-9) {
        return vec![BELOW; res * res];
    }
    let k = res.div_ceil(TILE);
    let mut texels = vec![BELOW; res * res];
    CENTRES.with_borrow_mut(|(at, centres)| {
        if *at != res {
            *at = res;
            *centres = (0..cubemap::FACES * res * res)
                .map(|k| cubemap::face_to_dir(k / (res * res), cubemap::texel_center(k % res, k / res % res, res)))
                .collect();
        }
        for (tj, ti) in (0..k).flat_map(|tj| (0..k).map(move |ti| (tj, ti))) {
            let (i0, j0, i1, j1) = (ti * TILE, tj * TILE, (ti * TILE + TILE).min(res), (tj * TILE + TILE).min(res));
            let rows = (j0..j1).flat_map(|j| (i0..i1).map(move |i| (i, j)));
            if !tiles[tj * k + ti] {
                if [(i0, j0), (i1, j0), (i0, j1), (i1, j1)].iter().any(|&(i, j)| height(i, j) > 0.0) {
                    rows.for_each(|(i, j)| texels[j * res + i] = SKIPPED);
                }
                continue;
            }
            for (i, j) in rows {
                let centre = centres[(f * res + j) * res + i];
                texels[j * res + i] = match ray_through(centre, f, i, j, nd, res).map(|d| d.as_vec3()) {
                    None => BELOW,
                    Some(d) if !wanted(d) => SKIPPED,
                    Some(d) => cast_ray(occluders, p, n, d),
                };
            }
        }
    });
    texels
}

/// Whether the ray from `p` (unit normal `n`) in direction `d` reaches the sky.
fn cast_ray(occluders: &Occluders, p: Vec3, n: Vec3, d: Vec3) -> u8 {
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
    /// the horizon (else all `BELOW`); a flagged one casts what `wanted` accepts, as the full
    /// cast does, and skips the rest.
    #[test]
    fn selected_casts_agree_with_the_full_cast() {
        let roof = [Vec3::new(-2.0, 1.0, -2.0), Vec3::new(2.0, 1.0, -2.0), Vec3::new(0.0, 1.0, 2.0)];
        let occ = Occluders::new(&[vec![roof]]);
        // 20: the last tile of a face is narrower.
        let res: usize = 20;
        let k = res.div_ceil(TILE);
        let flags: Vec<bool> = (0..k * k).map(|t| t % 3 == 1).collect();
        let wanted = |d: Vec3| d.x > 0.0;
        for n in [Vec3::Y, Vec3::new(0.6, 0.0, 0.8), Vec3::new(-0.3, -0.9, 0.3).normalize()] {
            for f in 0..cubemap::FACES {
                let full = cast_face(&occ, Vec3::ZERO, n, f, res);
                let some = cast_face_where(&occ, Vec3::ZERO, n, f, res, &flags, wanted);
                for (x, (&a, &b)) in full.iter().zip(&some).enumerate() {
                    let (i, j) = (x % res, x / res);
                    let tile = (j / TILE) * k + i / TILE;
                    let expected = if flags[tile] {
                        let d = texel_ray(f, i, j, n.as_dvec3(), res).map(|d| d.as_vec3());
                        if d.is_none_or(&wanted) { a } else { SKIPPED }
                    } else {
                        let live =
                            (0..res * res).any(|y| (y / res / TILE) * k + (y % res) / TILE == tile && full[y] != BELOW);
                        if live { SKIPPED } else { BELOW }
                    };
                    assert_eq!(b, expected, "n {n}, face {f}, texel ({i}, {j})");
                }
            }
        }
    }
}
