//! Cameras: where they are and how they project (glTF's: looking down −Z, +Y up).

use glam::{Affine3A, Vec2, Vec3};

/// A camera; in its local frame it looks down −Z with +Y up (glTF).
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// World-from-camera transform (rigid).
    pub world: Affine3A,
    /// The projection.
    pub projection: Projection,
}

/// A camera projection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// Perspective with vertical field of view in radians.
    Perspective {
        /// Vertical field of view (radians).
        yfov: f32,
    },
    /// Orthographic with half height `ymag` (the width follows the image's aspect, as for
    /// perspective cameras).
    Orthographic {
        /// Half height.
        ymag: f32,
    },
}

impl Camera {
    /// A perspective camera at `eye` looking at `target` (+Y up).
    pub fn look_at(eye: Vec3, target: Vec3, yfov: f32) -> Self {
        let fwd = (target - eye).normalize_or(Vec3::NEG_Z);
        let up = if fwd.cross(Vec3::Y).length_squared() < 1e-8 { Vec3::Z } else { Vec3::Y };
        // Camera-local −Z looks along `fwd`.
        let z = -fwd;
        let x = up.cross(z).normalize();
        let y = z.cross(x);
        Self {
            world: Affine3A::from_cols(x.into(), y.into(), z.into(), eye.into()),
            projection: Projection::Perspective { yfov },
        }
    }

    /// Camera position.
    pub fn eye(&self) -> Vec3 {
        self.world.translation.into()
    }

    /// The primary ray `(origin, direction)` through `ndc` ∈ [−1, 1]² (+y up) for `aspect` = w/h.
    pub fn ray(&self, ndc: Vec2, aspect: f32) -> (Vec3, Vec3) {
        let (o, d) = match self.projection {
            Projection::Perspective { yfov } => {
                let t = (0.5 * yfov).tan();
                (Vec3::ZERO, Vec3::new(ndc.x * t * aspect, ndc.y * t, -1.0))
            }
            Projection::Orthographic { ymag } => (Vec3::new(ndc.x * ymag * aspect, ndc.y * ymag, 0.0), Vec3::NEG_Z),
        };
        (self.world.transform_point3(o), self.world.transform_vector3(d).normalize())
    }
}
