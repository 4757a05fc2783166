//! Per-vertex visibility cube maps, ray-cast with the BVH. Texels entirely below the vertex's
//! horizon are never cast: LTC clips there, so their visibility cannot matter.

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
    cast_face_where(occluders, p, n, f, res, |_, _| true)
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

/// [`cast_face`] casting only texels (i, j) that `wanted` accepts; the others above the horizon
/// are [`SKIPPED`].
pub fn cast_face_where(
    occluders: &Occluders,
    p: Vec3,
    n: Vec3,
    f: usize,
    res: usize,
    wanted: impl Fn(usize, usize) -> bool,
) -> Vec<u8> {
    let nd = n.as_dvec3();
    // The sign of the height is linear over a face: below at its four corners (with a margin
    // for rounding) means every texel is below.
    let corner = |s: f64, t: f64| cubemap::face_to_dir(f, glam::DVec2::new(s, t)).dot(nd);
    if [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)].iter().all(|&(s, t)| corner(s, t) < -1e-9) {
        return vec![BELOW; res * res];
    }
    let mut texels = Vec::with_capacity(res * res);
    CENTRES.with_borrow_mut(|(at, centres)| {
        if *at != res {
            *at = res;
            *centres = (0..cubemap::FACES * res * res)
                .map(|k| cubemap::face_to_dir(k / (res * res), cubemap::texel_center(k % res, k / res % res, res)))
                .collect();
        }
        for j in 0..res {
            for i in 0..res {
                let centre = centres[(f * res + j) * res + i];
                texels.push(cast_texel(occluders, p, n, ray_through(centre, f, i, j, nd, res), wanted(i, j)));
            }
        }
    });
    texels
}

/// The state of one texel given its cast direction (`None`: below the horizon).
fn cast_texel(occluders: &Occluders, p: Vec3, n: Vec3, ray: Option<DVec3>, wanted: bool) -> u8 {
    let Some(d) = ray else { return BELOW };
    if !wanted {
        return SKIPPED;
    }
    let d = d.as_vec3();
    if occluders.occluded(offset_ray_origin(p, n, d), d, f32::INFINITY) { OCCLUDED } else { VISIBLE }
}

thread_local! {
    /// Unit centre directions of every texel (face-major) at the last resolution this thread
    /// cast: normalising them per cast was a fifth of a bake. Per thread rather than one lazily
    /// built shared table, because a rayon worker blocked in a shared initialiser can deadlock.
    static CENTRES: std::cell::RefCell<(usize, Vec<DVec3>)> = const { std::cell::RefCell::new((0, Vec::new())) };
}
