//! Per-vertex visibility cube maps, ray-cast with the BVH. Texels whose centre lies below the
//! vertex's horizon are never cast: LTC clips there, so their visibility cannot matter.

use crate::accel::{SceneBvh, offset_ray_origin};
use crate::math::cubemap;
use glam::{DVec3, Vec3};

/// Texel state: blocked.
pub const OCCLUDED: u8 = 0;
/// Texel state: the light would be seen.
pub const VISIBLE: u8 = 1;
/// Texel state: below the horizon, not cast ("don't care").
pub const BELOW: u8 = 2;

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
pub fn cast(occluders: &SceneBvh, p: Vec3, n: Vec3, res: usize) -> CubeVisibility {
    let mut texels = Vec::with_capacity(6 * res * res);
    for f in 0..cubemap::FACES {
        for j in 0..res {
            for i in 0..res {
                let d: DVec3 = cubemap::face_to_dir(f, cubemap::texel_center(i, j, res));
                let d = d.as_vec3();
                texels.push(if d.dot(n) <= 0.0 {
                    BELOW
                } else if occluders.occluded(offset_ray_origin(p, n, d), d, f32::INFINITY) {
                    OCCLUDED
                } else {
                    VISIBLE
                });
            }
        }
    }
    CubeVisibility { res, texels }
}
