//! The viewport's orbit camera: yaw and pitch about a target at a distance, with pan and zoom,
//! convertible to and from a scene camera.

use glam::{Mat4, Vec2, Vec3};
use kage_engine::scene::{Camera, Projection};

/// An orbit camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Orbit {
    /// The point orbited.
    pub target: Vec3,
    /// Distance from the target.
    pub distance: f32,
    /// Rotation about +Y in radians (0 looks down −Z).
    pub yaw: f32,
    /// Elevation in radians (positive looks down on the target).
    pub pitch: f32,
    /// Vertical field of view in radians.
    pub yfov: f32,
}

const PITCH_LIMIT: f32 = 1.55;

impl Orbit {
    /// The orbit that sees what `camera` sees, orbiting the point `distance` ahead of it.
    pub fn from_camera(camera: &Camera, distance: f32) -> Self {
        let eye = camera.eye();
        let forward = camera.world.transform_vector3(Vec3::NEG_Z).normalize();
        let yfov = match camera.projection {
            Projection::Perspective { yfov } => yfov,
            _ => 45f32.to_radians(),
        };
        Self {
            target: eye + forward * distance,
            distance,
            yaw: (-forward.x).atan2(-forward.z),
            pitch: (-forward.y).asin().clamp(-PITCH_LIMIT, PITCH_LIMIT),
            yfov,
        }
    }

    /// Unit direction from the target to the eye.
    fn back(&self) -> Vec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        Vec3::new(sy * cp, sp, cy * cp)
    }

    /// The eye position.
    pub fn eye(&self) -> Vec3 {
        self.target + self.back() * self.distance
    }

    /// Turns by a drag of `dx`, `dy` radians.
    pub fn rotate(&mut self, dx: f32, dy: f32) {
        self.yaw -= dx;
        self.pitch = (self.pitch + dy).clamp(-PITCH_LIMIT, PITCH_LIMIT);
    }

    /// Unit vectors to the eye, to the right and up of the view.
    fn basis(&self) -> (Vec3, Vec3, Vec3) {
        let back = self.back();
        let right = Vec3::Y.cross(back).normalize_or(Vec3::X);
        (back, right, back.cross(right))
    }

    /// Moves the target in the view plane by `dx`, `dy` (fractions of the view height).
    pub fn pan(&mut self, dx: f32, dy: f32) {
        let (_, right, up) = self.basis();
        let scale = 2.0 * self.distance * (0.5 * self.yfov).tan();
        self.target += (-right * dx + up * dy) * scale;
    }

    /// Zooms by `factor` (> 1 moves away).
    pub fn zoom(&mut self, factor: f32) {
        self.distance = (self.distance * factor).clamp(1e-3, 1e5);
    }

    /// Clip-from-world matrix for a viewport of `aspect` (wgpu depth in [0, 1]).
    pub fn view_proj(&self, aspect: f32) -> Mat4 {
        let near = (self.distance * 1e-3).max(1e-4);
        // wgpu's clip space is Direct3D's: z in [0, 1], y up.
        let proj = glam::camera::rh::proj::directx::perspective(
            self.yfov,
            aspect.max(1e-3),
            near,
            self.distance * 100.0 + 100.0,
        );
        proj * glam::camera::rh::view::look_at_mat4(self.eye(), self.target, Vec3::Y)
    }

    /// The ray (eye, unit direction) through viewport point `uv` (0 to 1 across, 0 to 1 down).
    pub fn ray(&self, uv: Vec2, aspect: f32) -> (Vec3, Vec3) {
        // From the camera's basis, as `view_proj` builds it (unprojecting through the far plane
        // loses digits in f32).
        let ndc = Vec2::new(2.0 * uv.x - 1.0, 1.0 - 2.0 * uv.y);
        let (back, right, up) = self.basis();
        let t = (0.5 * self.yfov).tan();
        (self.eye(), (-back + right * (ndc.x * t * aspect) + up * (ndc.y * t)).normalize())
    }

    /// Where `p` appears in the viewport (the inverse of [`Self::ray`]), or `None` behind the eye.
    pub fn project(&self, p: Vec3, aspect: f32) -> Option<Vec2> {
        let clip = self.view_proj(aspect) * p.extend(1.0);
        (clip.w > 1e-6).then(|| {
            let ndc = clip.truncate() / clip.w;
            Vec2::new(0.5 * (ndc.x + 1.0), 0.5 * (1.0 - ndc.y))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_camera_round_trips_through_the_orbit() {
        let cam = Camera::look_at(Vec3::new(3.0, 2.0, 5.0), Vec3::new(0.0, 0.5, 0.0), 0.8);
        let d = Vec3::new(3.0, 1.5, 5.0).length();
        let orbit = Orbit::from_camera(&cam, d);
        assert!(orbit.eye().distance(cam.eye()) < 1e-4, "{} vs {}", orbit.eye(), cam.eye());
        assert!(orbit.target.distance(Vec3::new(0.0, 0.5, 0.0)) < 1e-4, "{}", orbit.target);
        let back = Camera::look_at(orbit.eye(), orbit.target, orbit.yfov);
        assert!(back.world.transform_vector3(Vec3::NEG_Z).distance(cam.world.transform_vector3(Vec3::NEG_Z)) < 1e-5);
    }

    #[test]
    fn rotate_then_undo_is_identity_and_pan_keeps_the_distance() {
        let mut o = Orbit { target: Vec3::ZERO, distance: 4.0, yaw: 0.3, pitch: 0.2, yfov: 0.8 };
        let start = o;
        o.rotate(0.4, -0.1);
        o.rotate(-0.4, 0.1);
        assert!((o.yaw - start.yaw).abs() < 1e-6 && (o.pitch - start.pitch).abs() < 1e-6);
        o.pan(0.1, 0.2);
        assert!((o.eye().distance(o.target) - 4.0).abs() < 1e-4);
        // The projected target stays at the centre of the view.
        let c = o.view_proj(1.5).project_point3(o.target);
        assert!(c.x.abs() < 1e-5 && c.y.abs() < 1e-5, "{c}");
    }

    #[test]
    fn rays_and_projections_are_inverses() {
        let o = Orbit { target: Vec3::new(0.5, 1.0, -2.0), distance: 6.0, yaw: 0.7, pitch: 0.4, yfov: 0.9 };
        for uv in [Vec2::new(0.5, 0.5), Vec2::new(0.1, 0.9), Vec2::new(0.97, 0.03)] {
            let (eye, dir) = o.ray(uv, 1.6);
            assert!(eye.distance(o.eye()) < 1e-5 && (dir.length() - 1.0).abs() < 1e-5);
            for t in [0.5, 6.0, 40.0] {
                let back = o.project(eye + dir * t, 1.6).unwrap();
                assert!(back.distance(uv) < 1e-4, "{uv} at {t}: {back}");
            }
        }
        let (_, centre) = o.ray(Vec2::splat(0.5), 1.6);
        assert!(centre.dot((o.target - o.eye()).normalize()) > 1.0 - 1e-5, "the centre looks at the target");
        assert!(o.project(o.eye() - centre, 1.6).is_none(), "behind the eye");
    }
}
