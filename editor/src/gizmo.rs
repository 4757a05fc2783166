//! The move, turn and scale gizmos: axis arrows, rings and scale handles drawn over the viewport with egui's painter
//! (no gizmo crate: the maintained ones lag egui's releases), and the drag math that turns
//! pointer motion into an edit, with grid, angle and scale snapping in world or local axes.
//!
//! Everything here is in viewport pixels and world units; the UI feeds it pointer positions and
//! applies what [`Drag::step`] returns through the editor's edits (so a drag is undoable, as one
//! step, like any other edit).

use glam::{Quat, Vec2, Vec3};
use kage_gpu::camera::Orbit;

/// What dragging a handle does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Move along an axis.
    Translate,
    /// Turn about an axis.
    Rotate,
    /// Scale uniformly (any axis's handle; dragging outward grows).
    Scale,
}

/// Which axes the handles follow.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Space {
    /// The world's X, Y and Z.
    World,
    /// The selected group's (or light's) own axes.
    Local,
}

/// The gizmo's options, as the viewport toolbar sets them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Move, turn or scale.
    pub mode: Mode,
    /// World or local axes.
    pub space: Space,
    /// Snap to `grid` and `angle`.
    pub snap: bool,
    /// Snapping step of moves, in world units.
    pub grid: f32,
    /// Snapping step of turns, in degrees.
    pub angle: f32,
}

impl Default for Settings {
    fn default() -> Self {
        Self { mode: Mode::Translate, space: Space::World, snap: false, grid: 0.25, angle: 15.0 }
    }
}

/// Handle length on screen, in pixels.
pub const HANDLE_PIXELS: f32 = 90.0;
/// How close (pixels) the pointer must be to a handle to grab it.
pub const GRAB_PIXELS: f32 = 8.0;
const RING_SEGMENTS: usize = 64;
/// The smallest total scale one drag reaches.
const MIN_SCALE: f32 = 0.05;
/// Snapping step of scale factors.
const SCALE_STEP: f32 = 0.1;

/// Where the gizmo stands: its origin and unit axes in world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// The point moved or turned about.
    pub origin: Vec3,
    /// X, Y and Z (unit).
    pub axes: [Vec3; 3],
}

/// A view of the viewport: camera, pixel size.
#[derive(Clone, Copy, Debug)]
pub struct View<'a> {
    /// The camera.
    pub orbit: &'a Orbit,
    /// Viewport width and height in pixels.
    pub size: Vec2,
}

impl View<'_> {
    fn aspect(&self) -> f32 {
        self.size.x / self.size.y.max(1.0)
    }

    /// Pixel position of world point `p`.
    pub fn pixel(&self, p: Vec3) -> Option<Vec2> {
        self.orbit.project(p, self.aspect()).map(|uv| uv * self.size)
    }

    /// World length that spans [`HANDLE_PIXELS`] at `p`.
    fn handle_length(&self, p: Vec3) -> f32 {
        let depth = (p - self.orbit.eye()).length();
        2.0 * depth * (0.5 * self.orbit.yfov).tan() * HANDLE_PIXELS / self.size.y.max(1.0)
    }
}

impl Placement {
    /// Each axis's handle as a pixel polyline: an arrow shaft for moves, a ring for turns.
    pub fn handles(&self, mode: Mode, view: &View) -> [Vec<Vec2>; 3] {
        let length = view.handle_length(self.origin);
        std::array::from_fn(|k| {
            let world: Vec<Vec3> = match mode {
                Mode::Translate | Mode::Scale => vec![self.origin, self.origin + self.axes[k] * length],
                Mode::Rotate => {
                    let (a, b) = (self.axes[(k + 1) % 3], self.axes[(k + 2) % 3]);
                    (0..=RING_SEGMENTS)
                        .map(|s| {
                            let u = s as f32 / RING_SEGMENTS as f32 * std::f32::consts::TAU;
                            self.origin + (a * u.cos() + b * u.sin()) * (0.8 * length)
                        })
                        .collect()
                }
            };
            world.into_iter().filter_map(|p| view.pixel(p)).collect()
        })
    }

    /// The axis whose handle passes within [`GRAB_PIXELS`] of `pointer` (the nearest), if any.
    pub fn grab(&self, mode: Mode, view: &View, pointer: Vec2) -> Option<usize> {
        let handles = self.handles(mode, view);
        (0..3)
            .map(|k| (k, distance_to_polyline(&handles[k], pointer)))
            .filter(|(_, d)| *d <= GRAB_PIXELS)
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(k, _)| k)
    }
}

fn distance_to_polyline(line: &[Vec2], p: Vec2) -> f32 {
    line.windows(2)
        .map(|s| {
            let (a, d) = (s[0], s[1] - s[0]);
            let t = ((p - a).dot(d) / d.length_squared().max(1e-12)).clamp(0.0, 1.0);
            (a + d * t).distance(p)
        })
        .fold(f32::INFINITY, f32::min)
}

/// What one pointer motion asks for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Edit {
    /// Move by this world offset.
    Move(Vec3),
    /// Turn by this rotation about the placement's origin.
    Turn(Quat),
    /// Scale by this factor about the placement's origin.
    Scale(f32),
}

/// A drag in progress on one axis: the pointer motion so far and how much of it (snapped) has
/// been applied, so that snapping never accumulates rounding.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Drag {
    /// The axis grabbed.
    pub axis: usize,
    /// Where the gizmo stood when the drag started.
    pub start: Placement,
    /// Mode at the start.
    pub mode: Mode,
    /// Pointer position at the start.
    pub from: Vec2,
    /// Total amount applied (world units, radians, or the scale factor minus one).
    applied: f32,
}

impl Drag {
    /// A drag of `axis` starting with the pointer at `from`.
    pub fn new(start: Placement, mode: Mode, axis: usize, from: Vec2) -> Self {
        Self { axis, start, mode, from, applied: 0.0 }
    }

    /// The edit that brings the selection to where the pointer at `to` asks, snapped when
    /// `settings.snap`; `None` when nothing changes.
    pub fn step(&mut self, view: &View, to: Vec2, settings: &Settings) -> Option<Edit> {
        // Scaling: one handle length outward doubles the size (never below MIN_SCALE).
        let total = match self.mode {
            Mode::Translate => self.distance(view, to),
            Mode::Rotate => self.angle(view, to),
            Mode::Scale => (self.distance(view, to) / view.handle_length(self.start.origin)).max(MIN_SCALE - 1.0),
        };
        let step = match (settings.snap, self.mode) {
            (false, _) => 0.0,
            (true, Mode::Translate) => settings.grid,
            (true, Mode::Rotate) => settings.angle.to_radians(),
            (true, Mode::Scale) => SCALE_STEP,
        };
        let wanted = if step > 0.0 { (total / step).round() * step } else { total };
        let delta = wanted - self.applied;
        if delta == 0.0 || !delta.is_finite() {
            return None;
        }
        let before = std::mem::replace(&mut self.applied, wanted);
        let axis = self.start.axes[self.axis];
        Some(match self.mode {
            Mode::Translate => Edit::Move(axis * delta),
            Mode::Rotate => Edit::Turn(Quat::from_axis_angle(axis, delta)),
            Mode::Scale => Edit::Scale((1.0 + wanted) / (1.0 + before)),
        })
    }

    /// World distance along the axis that the pointer's motion from `from` to `to` covers.
    fn distance(&self, view: &View, to: Vec2) -> f32 {
        let (o, axis) = (self.start.origin, self.start.axes[self.axis]);
        let length = view.handle_length(o);
        let (Some(a), Some(b)) = (view.pixel(o), view.pixel(o + axis * length)) else { return 0.0 };
        let along = b - a;
        // An axis pointing at the eye has no screen direction to drag along.
        if along.length() < 1.0 {
            return 0.0;
        }
        (to - self.from).dot(along) / along.length_squared() * length
    }

    /// Angle the pointer turned about the origin's pixel, counter-clockwise about the axis.
    fn angle(&self, view: &View, to: Vec2) -> f32 {
        let Some(c) = view.pixel(self.start.origin) else { return 0.0 };
        let (u, v) = (self.from - c, to - c);
        // Screen y points down, so a positive cross product is a clockwise turn on screen.
        let on_screen = -u.perp_dot(v).atan2(u.dot(v));
        let facing = self.start.axes[self.axis].dot(view.orbit.eye() - self.start.origin);
        if facing >= 0.0 { on_screen } else { -on_screen }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn setup() -> (Orbit, Placement) {
        let orbit = Orbit { target: Vec3::ZERO, distance: 8.0, yaw: 0.5, pitch: 0.4, yfov: 0.8 };
        (orbit, Placement { origin: Vec3::new(0.3, 0.2, -0.1), axes: [Vec3::X, Vec3::Y, Vec3::Z] })
    }

    fn moved(e: Option<Edit>) -> Vec3 {
        match e {
            Some(Edit::Move(v)) => v,
            other => panic!("expected a move, got {other:?}"),
        }
    }

    #[test]
    fn dragging_an_arrow_by_its_own_length_moves_one_handle_length_and_snaps() {
        let (orbit, place) = setup();
        let view = View { orbit: &orbit, size: Vec2::new(800.0, 600.0) };
        for axis in 0..3 {
            let handles = place.handles(Mode::Translate, &view);
            let (a, b) = (handles[axis][0], handles[axis][1]);
            assert_eq!(place.grab(Mode::Translate, &view, a.lerp(b, 0.7)), Some(axis), "axis {axis}");
            let mut drag = Drag::new(place, Mode::Translate, axis, a);
            let v = moved(drag.step(&view, b, &Settings::default()));
            let length = view.handle_length(place.origin);
            assert!((v - place.axes[axis] * length).length() < 1e-3 * length, "axis {axis}: {v}");
            // Snapped, the same pointer motion moves a whole number of grid steps in total.
            let snap = Settings { snap: true, grid: 0.25, ..Settings::default() };
            let mut drag = Drag::new(place, Mode::Translate, axis, a);
            let mut total = Vec3::ZERO;
            for t in [0.3, 0.6, 1.0, 1.7] {
                total += drag.step(&view, a.lerp(b, t), &snap).map_or(Vec3::ZERO, |e| moved(Some(e)));
                let steps = total.length() / 0.25;
                assert!((steps - steps.round()).abs() < 1e-4, "{total}");
            }
        }
        assert_eq!(place.grab(Mode::Translate, &view, Vec2::new(5.0, 5.0)), None);
    }

    #[test]
    fn turning_a_ring_a_quarter_turn_on_screen_turns_a_quarter_about_a_facing_axis() {
        let orbit = Orbit { target: Vec3::ZERO, distance: 8.0, yaw: 0.0, pitch: 1.5, yfov: 0.8 };
        let place = Placement { origin: Vec3::ZERO, axes: [Vec3::X, Vec3::Y, Vec3::Z] };
        let view = View { orbit: &orbit, size: Vec2::new(600.0, 600.0) };
        let c = view.pixel(Vec3::ZERO).unwrap();
        let ring = &place.handles(Mode::Rotate, &view)[1];
        assert_eq!(place.grab(Mode::Rotate, &view, ring[5]), Some(1), "looking down, the Y ring is a circle");
        // Counter-clockwise on screen while looking down −Y is counter-clockwise about +Y.
        let from = c + Vec2::new(50.0, 0.0);
        let to = c + Vec2::new(0.0, -50.0);
        let snap = Settings { snap: true, angle: 15.0, ..Settings::default() };
        let mut drag = Drag::new(place, Mode::Rotate, 1, from);
        let Some(Edit::Turn(q)) = drag.step(&view, to, &snap) else { panic!("a turn") };
        let (axis, angle) = q.to_axis_angle();
        assert!((axis.dot(Vec3::Y).abs() - 1.0).abs() < 1e-5);
        let signed = angle * axis.dot(Vec3::Y).signum();
        assert!((signed - std::f32::consts::FRAC_PI_2).abs() < 1e-5, "{}", signed.to_degrees());
        assert!(q.mul_vec3(Vec3::X).dot(Vec3::NEG_Z) > 0.999, "+X turns to −Z about +Y");
        assert_eq!(drag.step(&view, to, &snap), None, "no motion, no edit");
    }

    #[test]
    fn dragging_a_scale_handle_out_by_its_length_doubles_and_never_flips() {
        let (orbit, place) = setup();
        let view = View { orbit: &orbit, size: Vec2::new(800.0, 600.0) };
        let handles = place.handles(Mode::Scale, &view);
        let (a, b) = (handles[0][0], handles[0][1]);
        let mut drag = Drag::new(place, Mode::Scale, 0, a);
        let Some(Edit::Scale(f)) = drag.step(&view, b, &Settings::default()) else { panic!("a scale") };
        assert!((f - 2.0).abs() < 1e-3, "{f}");
        // Back past the origin: the total stops at the smallest scale, relative to what was applied.
        let Some(Edit::Scale(g)) = drag.step(&view, a - (b - a) * 3.0, &Settings::default()) else { panic!() };
        assert!((f * g - MIN_SCALE).abs() < 1e-4, "{}", f * g);
    }
}
