//! Many planes through one point tested against a direction at once: the normals eight to a
//! single-precision vector, each dot product computed as [`Vec3::dot`] computes it (products
//! summed x, y, z in order, nothing fused), so a caller gets the bits a plane-by-plane loop
//! would, in a fraction of the instructions. Per-texel tests of warm re-bakes (a box's
//! silhouette, a beam's triangle edges) run it on hundreds of thousands of rays.

use glam::Vec3;
use wide::f32x8;

/// Plane normals, eight per vector (the last group padded with zero normals).
#[derive(Clone, Debug, Default)]
pub struct Planes {
    /// x, y and z lanes of each group of eight.
    groups: Vec<[f32x8; 3]>,
    len: usize,
}

impl Planes {
    /// The most planes a set holds (a mask has one bit per plane).
    pub const MAX: usize = 128;

    /// The planes with normals `normals` (at most [`Self::MAX`]), bit `b` of a mask standing
    /// for `normals[b]`.
    pub fn new(normals: &[Vec3]) -> Self {
        assert!(normals.len() <= Self::MAX, "{} planes", normals.len());
        let groups = normals
            .chunks(8)
            .map(|g| {
                let lanes = |axis: fn(&Vec3) -> f32| f32x8::new(std::array::from_fn(|l| g.get(l).map_or(0.0, axis)));
                [lanes(|m| m.x), lanes(|m| m.y), lanes(|m| m.z)]
            })
            .collect();
        Self { groups, len: normals.len() }
    }

    /// How many planes it holds.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether it holds no plane.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The planes `d` lies beyond by more than `b` (`m · d > b`) and those it lies behind by more
    /// than `b` (`m · d < −b`), as bit masks.
    #[inline]
    pub fn sides(&self, d: Vec3, b: f32) -> (u128, u128) {
        let (x, y, z) = (f32x8::splat(d.x), f32x8::splat(d.y), f32x8::splat(d.z));
        let (above, below) = (f32x8::splat(b), f32x8::splat(-b));
        let every = if self.len == Self::MAX { u128::MAX } else { (1 << self.len) - 1 };
        let (beyond, behind) = self.groups.iter().enumerate().fold((0, 0), |(beyond, behind), (g, [mx, my, mz])| {
            let dot = *mx * x + *my * y + *mz * z;
            let bits = |m: f32x8| u128::from(m.to_bitmask()) << (8 * g);
            (beyond | bits(dot.simd_gt(above)), behind | bits(dot.simd_lt(below)))
        });
        (beyond & every, behind & every)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::Rng;

    /// The masks hold exactly the planes a one-by-one `Vec3::dot` puts on each side, for sets of
    /// 0 to 40 planes (the padding lanes never show), including directions on a plane.
    #[test]
    fn sides_agree_with_one_plane_at_a_time() {
        let mut r = crate::math::rng::seeded(5);
        let mut unit =
            || Vec3::new(r.random_range(-1.0..1.0), r.random_range(-1.0..1.0), r.random_range(-1.0..1.0)).normalize();
        for count in [0, 1, 7, 8, 9, 36, 40] {
            let normals: Vec<Vec3> = (0..count).map(|_| unit()).collect();
            let planes = Planes::new(&normals);
            assert_eq!((planes.len(), planes.is_empty()), (count, count == 0));
            let mut directions: Vec<Vec3> = (0..300).map(|_| unit()).collect();
            directions.extend(normals.iter().map(|m| m.any_orthonormal_vector()));
            for d in directions {
                for b in [0.0, 2e-3, 0.3] {
                    let pick = |keep: &dyn Fn(f32) -> bool| {
                        normals.iter().enumerate().fold(0u128, |m, (k, n)| m | u128::from(keep(n.dot(d))) << k)
                    };
                    assert_eq!(planes.sides(d, b), (pick(&|x| x > b), pick(&|x| x < -b)), "{count} planes, {d}, {b}");
                }
            }
        }
    }
}
