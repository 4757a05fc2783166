//! Orthonormal frames: the local shading frame has +Z along the normal.

use glam::Vec3;

/// An orthonormal basis `(t, b, n)`; `to_local` and `to_world` are exact inverses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Tangent (local +X).
    pub t: Vec3,
    /// Bitangent (local +Y).
    pub b: Vec3,
    /// Normal (local +Z).
    pub n: Vec3,
}

impl Frame {
    /// A frame around the unit normal `n` (Duff et al. 2017, branchless, continuous except at n.z = −1).
    pub fn from_normal(n: Vec3) -> Self {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let t = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let bt = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Self { t, b: bt, n }
    }

    /// World direction → local coordinates.
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.t), v.dot(self.b), v.dot(self.n))
    }

    /// Local coordinates → world direction.
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.t * v.x + self.b * v.y + self.n * v.z
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_orthonormal_and_round_trip() {
        for n in
            [Vec3::Z, -Vec3::Z, Vec3::X, Vec3::new(0.3, -0.5, 0.81).normalize(), Vec3::new(1e-8, 0.0, -1.0).normalize()]
        {
            let f = Frame::from_normal(n);
            assert!((f.t.length() - 1.0).abs() < 1e-6 && (f.b.length() - 1.0).abs() < 1e-6);
            assert!(f.t.dot(f.b).abs() < 1e-6 && f.t.dot(n).abs() < 1e-6 && f.b.dot(n).abs() < 1e-6);
            assert!((f.t.cross(f.b) - n).length() < 1e-5, "right-handed");
            let v = Vec3::new(0.2, 0.7, -0.4);
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-6);
        }
    }
}
