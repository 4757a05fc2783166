//! What refinement probes, and against what: the visibility of every view of what lights the
//! scene from a receiver point, tested against the instances that can shadow that receiver
//! ([`Near`]) and no others, so that a receiver's refinement depends on them alone.

use crate::accel::Occluders;
use crate::accel::top_level::TopLevel;
use crate::math::color::luminance;
use crate::math::sampling::{hammersley, uniform_sphere, uniform_triangle};
use crate::scene::{EnvironmentLight, FlatLight, FlatScene};
use glam::Vec3;

/// Points a light is probed at, where it is.
const LIGHT_POINTS: u32 = 49;

/// Most cells a light's reach box is split into, per axis.
const MAX_CELLS_PER_AXIS: f32 = 3.0;

/// Directions the environment is probed in (a Hammersley set on the sphere).
const ENVIRONMENT_DIRECTIONS: u32 = 64;

/// What the probe measures the visibility of.
pub(super) enum Sources {
    /// Points on a light, or in one cell of a light's reach box. A point counts only from in
    /// front of `facing` (a light that may move and turn within its box has none).
    Points { points: Vec<Vec3>, facing: Option<Vec3> },
    /// Directions towards the environment, each with its weight (the radiance's luminance),
    /// against the receiver's own group only (PRT bakes per vertex only the shadows a group
    /// casts on itself; other groups' shadows and the sun are shaded per pixel,
    /// `docs/baked.md`).
    Directions(Vec<(Vec3, f32)>),
}

/// The instances that can shadow one receiver, by index, ascending.
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct Near {
    /// For the lights' views: those whose bounds meet the box around the receiver and a
    /// view's points (a segment from the one to the other lies in it), or the receiver's own
    /// bounds (what it may be inside); not the receiver when it is planar, nor what lies in its
    /// plane.
    pub lights: Vec<u32>,
    /// For the environment's: those of the receiver's group within the receiver's bounds
    /// grown by their diagonal — farther occluders' shadows are too soft to need vertices.
    pub environment: Vec<u32>,
}

/// What every receiver is probed for and where the instances lie: cheap to gather, enough to
/// name each receiver's refinement ([`super::keys`]) without casting a ray.
pub(super) struct Scope {
    /// The lights' views, then the environment's (if any).
    pub views: Vec<Sources>,
    /// How many of `views` are the lights'.
    pub lights: usize,
    /// Per instance, the world bounds of its occluding triangles (`None`: it has none).
    pub bounds: Vec<Option<(Vec3, Vec3)>>,
    /// The scene's size: the diagonal of all the instances' bounds, rounded down to a power of
    /// two (so that an edit changes it only when the size crosses a step).
    pub size: f32,
    /// Per instance, its group's rank among the groups (for the environment's lists).
    group_of: Vec<usize>,
    /// Per instance, the plane its triangles lie in (unit normal, offset), if they do: then
    /// neither they nor other instances lying in that plane can shadow its points (a ray
    /// leaving the plane does not meet it again), and they are left out of its lists — its
    /// own BVH, which every ray from a floor would descend near its start, and the tiles
    /// beside it in a floor of many.
    plane: Vec<Option<(Vec3, f32)>>,
    /// A tree over `bounds`, so that finding what meets a box costs the log of the instances.
    tree: TopLevel,
}

impl Scope {
    /// Gathers the views and bounds of `flat`.
    pub fn new(flat: &FlatScene) -> Self {
        let mut groups: Vec<hecs::Entity> = flat.instances.iter().map(|i| i.group).collect();
        groups.sort();
        groups.dedup();
        let group_of = flat.instances.iter().map(|i| groups.binary_search(&i.group).expect("listed")).collect();
        let mut views: Vec<Sources> = flat.lights.iter().flat_map(light_views).collect();
        let lights = views.len();
        views.extend(flat.environment.as_ref().map(environment_view));
        let triangles: Vec<Vec<[Vec3; 3]>> = (0..flat.instances.len()).map(|i| flat.occluder_triangles(i)).collect();
        let bounds: Vec<_> = triangles.iter().map(|t| bounds(t.iter().flatten())).collect();
        let plane = triangles.iter().map(|t| plane(t)).collect();
        let tree = box_tree(&bounds);
        let all = bounds.iter().flatten().copied().reduce(|a, b| (a.0.min(b.0), a.1.max(b.1)));
        let size = all.map_or(0.0, |(lo, hi)| power_of_two_below((hi - lo).length()));
        Self { views, lights, bounds, size, group_of, plane, tree }
    }

    /// The instances that can shadow instance `i`.
    pub fn near(&self, i: usize) -> Near {
        let Some(own) = self.bounds[i] else { return Near::default() };
        let mut boxes = vec![own];
        for view in &self.views[..self.lights] {
            if let Sources::Points { points, .. } = view {
                boxes.push(bounds(points.iter().chain([own.0, own.1].iter())).expect("points"));
            }
        }
        // Room for the probes' ray origins, lifted off the receiver along its normals.
        let boxes: Vec<(Vec3, Vec3)> = boxes.into_iter().map(padded).collect();
        let grown = (own.0 - (own.1 - own.0).length(), own.1 + (own.1 - own.0).length());
        // A subtree lying in a planar receiver's plane (tiles beside a tile) holds nothing near.
        let descend = |b| !self.box_in_plane_of(i, b);
        let lights = self.meeting(&boxes, descend, |j| !self.in_plane_of(i, j));
        let environment = if self.views.len() > self.lights {
            let keep = |j| self.group_of[j] == self.group_of[i] && !self.in_plane_of(i, j);
            self.meeting(&[padded(grown)], descend, keep)
        } else {
            Vec::new()
        };
        Near { lights, environment }
    }

    /// The instances other than `i` whose bounds come within `reach` of `i`'s, ascending: what
    /// the bounce on `i` may vary near ([`super::Seed`]); `None` when there are more than
    /// `most` (the search stops there, so that a crowd costs each of its members `most`).
    pub fn close(&self, i: usize, reach: f32, most: usize) -> Option<Vec<u32>> {
        let Some((lo, hi)) = self.bounds[i] else { return Some(Vec::new()) };
        let grown = (lo - Vec3::splat(reach), hi + Vec3::splat(reach));
        self.meeting_at_most(&[grown], |_| true, |j| j != i, most)
    }

    /// Whether instance `j` lies in instance `i`'s plane (`i` itself, when it has one).
    fn in_plane_of(&self, i: usize, j: usize) -> bool {
        self.plane[i].is_some() && (j == i || self.bounds[j].is_some_and(|b| self.box_in_plane_of(i, b)))
    }

    /// Whether the box `(lo, hi)` lies in instance `i`'s plane (false when it has none), to
    /// within 2·10⁻⁴ of its diagonal: more than the tree pads its boxes by, so that a subtree
    /// of tiles is left whole.
    fn box_in_plane_of(&self, i: usize, (lo, hi): (Vec3, Vec3)) -> bool {
        let Some((n, d)) = self.plane[i] else { return false };
        let slack = 1e-5 * (1.0 + d.abs()) + 2e-4 * (hi - lo).length();
        let corners = (0..8).map(|c| Vec3::select(glam::BVec3::new(c & 1 != 0, c & 2 != 0, c & 4 != 0), hi, lo));
        corners.into_iter().all(|p| (n.dot(p) - d).abs() <= slack)
    }

    /// The instances `keep` accepts whose bounds meet one of `boxes`, ascending, in the tree
    /// below nodes `descend` accepts the boxes of.
    fn meeting(
        &self,
        boxes: &[(Vec3, Vec3)],
        descend: impl Fn((Vec3, Vec3)) -> bool,
        keep: impl Fn(usize) -> bool,
    ) -> Vec<u32> {
        self.meeting_at_most(boxes, descend, keep, usize::MAX).expect("no limit to pass")
    }

    /// [`Self::meeting`], or `None` once more than `most` are found (the search stops there).
    fn meeting_at_most(
        &self,
        boxes: &[(Vec3, Vec3)],
        descend: impl Fn((Vec3, Vec3)) -> bool,
        keep: impl Fn(usize) -> bool,
        most: usize,
    ) -> Option<Vec<u32>> {
        let mut found = Vec::new();
        for &b in boxes {
            let whole = self.tree.each_within(
                |lo, hi| overlap((lo, hi), b) && descend((lo, hi)),
                |leaf| {
                    let meets = |j: &&u32| self.bounds[**j as usize].is_some_and(|o| overlap(o, b));
                    found.extend(leaf.iter().filter(meets).filter(|&&j| keep(j as usize)));
                    found.len() > most
                },
            );
            if !whole {
                return None;
            }
        }
        found.sort_unstable();
        found.dedup();
        Some(found)
    }
}

/// The probe: the scope and every instance's occluders, each its own BVH (so a ray's answer
/// against one instance does not depend on the others, [`Occluders`]).
pub(super) struct Probe<'a> {
    pub scope: &'a Scope,
    occluders: Occluders,
}

impl<'a> Probe<'a> {
    /// Builds the occluders of `flat` (lights excepted).
    pub fn new(flat: &FlatScene, scope: &'a Scope) -> Self {
        Self { scope, occluders: crate::bspvt::occluder_bvh(flat) }
    }

    /// What `p` (normal `n`) on a receiver shadowed by `near` sees: per light view, the share
    /// of its points seen and the share above the horizon (both in front of the light); then
    /// per environment view, the share seen. Empty for a point inside geometry
    /// ([`Occluders::inside_if`]), whose shading takes no part in what is seen
    /// (`bspvt::pixel`); a point whose rays all pass is not inside anything closed, and is
    /// not asked.
    pub fn visibility(&self, p: Vec3, n: Vec3, near: &Near) -> Vec<f32> {
        let (seen, passed) = self.seen(p, n, near);
        if !passed && self.occluders.inside_if(p, n, among(&near.lights)) {
            return Vec::new();
        }
        seen
    }

    /// [`Self::visibility`] without the inside test, and whether rays were cast and all passed.
    fn seen(&self, p: Vec3, n: Vec3, near: &Near) -> (Vec<f32>, bool) {
        let (mut cast, mut any_blocked) = (false, false);
        let origin = p + n * 1e-4 * (1.0 + p.abs().max_element());
        // As BSPVT's rays, every ray here passes what touches the point (a box resting on the
        // floor): `Occluders::occluded`.
        let mut out = Vec::with_capacity(self.scope.views.len() + self.scope.lights);
        for view in &self.scope.views {
            match view {
                Sources::Points { points, facing } => {
                    let (mut seen, mut above) = (0, 0);
                    for &s in points {
                        let d = s - origin;
                        let dist = d.length();
                        let dir = d / dist;
                        if dir.dot(n) > 0.0 && facing.is_none_or(|f| dir.dot(f) < 0.0) {
                            above += 1;
                            let blocked =
                                self.occluders.occluded_if(origin, dir, dist * (1.0 - 1e-4), among(&near.lights));
                            seen += usize::from(!blocked);
                            (cast, any_blocked) = (true, any_blocked | blocked);
                        }
                    }
                    out.extend([seen as f32 / points.len() as f32, above as f32 / points.len() as f32]);
                }
                Sources::Directions(dirs) => {
                    let (mut lit, mut all) = (0.0, 0.0);
                    for &(dir, w) in dirs.iter().filter(|(d, _)| d.dot(n) > 0.0) {
                        let w = w * dir.dot(n);
                        all += w;
                        let blocked = self.occluders.occluded_if(origin, dir, f32::MAX, among(&near.environment));
                        lit += if blocked { 0.0 } else { w };
                        (cast, any_blocked) = (true, any_blocked | blocked);
                    }
                    out.push(if all > 0.0 { lit / all } else { 1.0 });
                }
            }
        }
        (out, cast && !any_blocked)
    }
}

/// Whether instance `j` is in `list` (ascending).
fn among(list: &[u32]) -> impl Fn(usize) -> bool + '_ {
    move |j| list.binary_search(&(j as u32)).is_ok()
}

/// The largest power of two not above `x`, for a positive normal `x` (its exponent alone: exact).
fn power_of_two_below(x: f32) -> f32 {
    f32::from_bits(x.to_bits() & 0x7f80_0000)
}

/// The bounds of `points` (`None` when there are none).
fn bounds<'p>(points: impl Iterator<Item = &'p Vec3>) -> Option<(Vec3, Vec3)> {
    points.fold(None, |b, &p| Some(b.map_or((p, p), |(lo, hi): (Vec3, Vec3)| (lo.min(p), hi.max(p)))))
}

/// A tree over the boxes of the instances that have one.
fn box_tree(bounds: &[Option<(Vec3, Vec3)>]) -> TopLevel {
    let boxes: Vec<(Vec3, Vec3)> = bounds.iter().map(|b| b.unwrap_or((Vec3::ZERO, Vec3::ZERO))).collect();
    TopLevel::new(&boxes, (0..bounds.len() as u32).filter(|&j| bounds[j as usize].is_some()).collect())
}

/// Whether `triangles` (at least one) lie in one plane, within 10⁻⁵ of their extent.
fn plane(triangles: &[[Vec3; 3]]) -> Option<(Vec3, f32)> {
    let n = triangles.iter().map(|[a, b, c]| (b - a).cross(c - a)).find(|n| *n != Vec3::ZERO)?.normalize();
    let (lo, hi) = bounds(triangles.iter().flatten())?;
    let d = n.dot(triangles[0][0]);
    let slack = 1e-5 * (hi - lo).length();
    triangles.iter().flatten().all(|p| (n.dot(*p) - d).abs() <= slack).then_some((n, d))
}

/// A box grown by 10⁻³ of its largest coordinate (and 10⁻³): more than a probe's ray origin
/// is lifted off its surface.
fn padded((lo, hi): (Vec3, Vec3)) -> (Vec3, Vec3) {
    let pad = Vec3::splat(1e-3 * (1.0 + lo.abs().max(hi.abs()).max_element()));
    (lo - pad, hi + pad)
}

/// Whether two boxes meet.
fn overlap((a0, a1): (Vec3, Vec3), (b0, b1): (Vec3, Vec3)) -> bool {
    a0.cmple(b1).all() && b0.cmple(a1).all()
}

/// A light's views: where it is (49 points, seen from its front), or, with a declared reach,
/// each cell of its box (the box split into cells about the light's size, at most 3 per axis;
/// 9 points each, from any side). The cells depend on the box alone, so moving the light
/// inside it changes no refined mesh and no bake key.
fn light_views(light: &FlatLight) -> Vec<Sources> {
    let Some([lo, hi]) = light.reach else {
        return vec![Sources::Points {
            points: spread_points(&light.points, LIGHT_POINTS),
            facing: Some(light.normal),
        }];
    };
    // The box grown to hold the light where it is, as the bake's reach is (`bspvt::reach`).
    let (lo, hi) = light.points.iter().fold((lo, hi), |(a, b), p| (a.min(*p), b.max(*p)));
    let cells = ((hi - lo) / light.area.sqrt()).round().clamp(Vec3::ONE, Vec3::splat(MAX_CELLS_PER_AXIS));
    let (nx, ny, nz) = (cells.x as usize, cells.y as usize, cells.z as usize);
    let half = (hi - lo) / (2.0 * cells);
    let mut views = Vec::new();
    for (i, j, k) in (0..nx).flat_map(|i| (0..ny).flat_map(move |j| (0..nz).map(move |k| (i, j, k)))) {
        let centre = lo + half * (2.0 * Vec3::new(i as f32, j as f32, k as f32) + 1.0);
        let corners = (0..8).map(|c| {
            let sign = Vec3::new([-1.0, 1.0][c & 1], [-1.0, 1.0][(c >> 1) & 1], [-1.0, 1.0][c >> 2]);
            centre + 0.9 * half * sign
        });
        views.push(Sources::Points { points: std::iter::once(centre).chain(corners).collect(), facing: None });
    }
    views
}

/// The environment's view: fixed directions spread evenly over the sphere, weighted by the
/// radiance's luminance. A small bright source (a sun) is rarely among them: the look shades
/// it per pixel, not per vertex.
fn environment_view(env: &EnvironmentLight) -> Sources {
    let dirs = (0..ENVIRONMENT_DIRECTIONS)
        .map(|i| uniform_sphere(hammersley(i, ENVIRONMENT_DIRECTIONS)))
        .map(|d| (d, luminance(env.radiance(d))))
        .filter(|(_, w)| w.is_finite() && *w > 0.0)
        .collect();
    Sources::Directions(dirs)
}

/// Points spread evenly over a light polygon (area-uniform over its fan of triangles, from a
/// Hammersley set): no two share a row, so an occluder's straight edge sweeping over the light
/// hides them one at a time, and `V` steps by 1/`n` (rings through the corners and edge
/// midpoints lined up in rows of up to 13: their steps were edges refinement split without end).
fn spread_points(polygon: &[Vec3], n: u32) -> Vec<Vec3> {
    let fan: Vec<[Vec3; 3]> = (1..polygon.len() - 1).map(|k| [polygon[0], polygon[k], polygon[k + 1]]).collect();
    let areas: Vec<f32> = fan.iter().map(|[a, b, c]| 0.5 * (b - a).cross(c - a).length()).collect();
    let total: f32 = areas.iter().sum();
    (0..n)
        .map(|i| {
            let mut u = hammersley(i, n);
            // The first coordinate picks a triangle by area and is stretched over it.
            let mut k = 0;
            while k + 1 < fan.len() && u.x * total > areas[k] {
                u.x -= areas[k] / total;
                k += 1;
            }
            u.x = (u.x * total / areas[k].max(f32::MIN_POSITIVE)).min(1.0);
            let [a, b, c] = fan[k];
            let w = uniform_triangle(u);
            a + w.x * (b - a) + w.y * (c - a)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The scene's size step is exact: powers of two map to themselves, and everything
    /// between two of them to the lower.
    #[test]
    fn the_size_step_is_the_power_of_two_below() {
        for (x, step) in [(1.0, 1.0), (1.5, 1.0), (14.2, 8.0), (0.96, 0.5), (0.125, 0.125), (16.0, 16.0), (17.2, 16.0)]
        {
            assert_eq!(power_of_two_below(x), step, "{x}");
        }
        assert_eq!(power_of_two_below(f32::from_bits(2f32.to_bits() - 1)), 1.0, "just under 2");
    }

    /// A light's probe points lie on it, and no straight edge parallel to one of its sides hides
    /// two of them at once: along each side's direction, the points' projections all differ.
    #[test]
    fn a_lights_points_are_spread_and_lie_on_it() {
        let quad = [
            Vec3::new(-0.5, 3.0, -0.5),
            Vec3::new(0.5, 3.0, -0.5),
            Vec3::new(0.5, 3.0, 0.5),
            Vec3::new(-0.5, 3.0, 0.5),
        ];
        let points = spread_points(&quad, LIGHT_POINTS);
        assert_eq!(points.len(), LIGHT_POINTS as usize);
        assert!(points.iter().all(|p| p.y == 3.0 && p.x.abs() <= 0.5 && p.z.abs() <= 0.5), "{points:?}");
        for axis in [Vec3::X, Vec3::Z] {
            let mut along: Vec<f32> = points.iter().map(|p| p.dot(axis)).collect();
            along.sort_by(f32::total_cmp);
            let gap = along.windows(2).map(|w| w[1] - w[0]).fold(f32::MAX, f32::min);
            assert!(gap > 1e-4, "two points in a row along {axis}: gap {gap}");
        }
        let triangle = [Vec3::ZERO, Vec3::X, Vec3::Z];
        let inside = spread_points(&triangle, 16);
        assert!(inside.iter().all(|p| p.x >= 0.0 && p.z >= 0.0 && p.x + p.z <= 1.0 + 1e-6), "{inside:?}");
    }

    /// A floor's two triangles lie in one plane; a box's do not; nothing is not planar.
    #[test]
    fn a_floor_is_planar_and_a_box_is_not() {
        let floor = [[Vec3::ZERO, Vec3::X, Vec3::Z], [Vec3::X, Vec3::new(1.0, 0.0, 1.0), Vec3::Z]];
        let (n, d) = plane(&floor).expect("planar");
        assert!((n.abs() - Vec3::Y).length() < 1e-6 && d.abs() < 1e-6, "{n} {d}");
        assert!(plane(&[floor[0], [Vec3::ZERO, Vec3::X, Vec3::Y]]).is_none());
        assert!(plane(&[]).is_none());
    }

    /// A tile beside a planar tile in its plane cannot shadow it and is not near it; a tile
    /// just above the plane, or beside a box, is.
    #[test]
    fn tiles_in_one_plane_do_not_shadow_each_other() {
        let tile = |x: f32, y: f32| Some((Vec3::new(x, y, 0.0), Vec3::new(x + 1.0, y, 1.0)));
        let bounds =
            vec![tile(0.0, 0.0), tile(1.5, 0.0), tile(3.0, 0.01), tile(0.0, 0.0).map(|(lo, hi)| (lo, hi + Vec3::Y))];
        let tree = box_tree(&bounds);
        let plane = vec![Some((Vec3::Y, 0.0)), Some((Vec3::Y, 0.0)), Some((Vec3::Y, 0.01)), None];
        let scope = Scope { views: Vec::new(), lights: 0, bounds, size: 0.0, group_of: vec![0; 4], plane, tree };
        let [a, b, c, d] = [0, 1, 2, 3].map(|j| scope.in_plane_of(0, j));
        assert!(a && b && !c && !d, "itself and the tile beside it, not the raised tile or the box");
        assert!(!scope.in_plane_of(3, 0), "a box has no plane");
    }

    /// The tree finds what meets a box exactly as testing every instance does.
    #[test]
    fn the_tree_finds_every_instance_a_box_meets() {
        let at = |k: u32| Vec3::new((k * 7 % 13) as f32, (k * 5 % 11) as f32, (k * 3 % 17) as f32);
        let bounds: Vec<Option<(Vec3, Vec3)>> =
            (0..300).map(|k| (k % 29 != 0).then(|| (at(k), at(k) + Vec3::splat(0.5 + (k % 4) as f32)))).collect();
        let tree = box_tree(&bounds);
        let n = bounds.len();
        let scope =
            Scope { views: Vec::new(), lights: 0, bounds, size: 0.0, group_of: vec![0; n], plane: vec![None; n], tree };
        let mut found = 0;
        for k in 0..40 {
            let b = (at(k) - Vec3::splat(2.0), at(k) + Vec3::splat(2.0));
            let brute: Vec<u32> =
                (0..n as u32).filter(|&j| scope.bounds[j as usize].is_some_and(|o| overlap(o, b))).collect();
            assert_eq!(scope.meeting(&[b], |_| true, |_| true), brute, "box {k}");
            found += brute.len();
        }
        assert!(found > 40, "the boxes meet instances: {found}");
    }

    /// Two boxes meet when they share a point, faces touching included.
    #[test]
    fn boxes_meet_when_they_share_a_point() {
        let unit = (Vec3::ZERO, Vec3::ONE);
        assert!(overlap(unit, (Vec3::ONE, Vec3::splat(2.0))));
        assert!(!overlap(unit, (Vec3::new(1.01, 0.0, 0.0), Vec3::splat(2.0))));
        assert_eq!(bounds([Vec3::X, -Vec3::Y].iter()), Some((Vec3::new(0.0, -1.0, 0.0), Vec3::new(1.0, 0.0, 0.0))));
        assert_eq!(bounds(std::iter::empty()), None);
    }
}
