//! Where the scene's polygonal lights can be, and so which tiles of a vertex's cube map its
//! trees must cover: a tile through which no light can ever be seen is baked as occluded
//! without casting a ray (its pieces of a light would be empty anyway) — the bake models only
//! what the scene needs. Lights declare their reach in the scene
//! ([`crate::scene::PolygonLight::reach`], `extras.kage.light_reach`); a single light that may
//! go anywhere keeps every tile. Shading a light inside its reach gives what a bake without
//! culling gives: a tile's subtree depends on that tile alone.

use super::dirty::{Cover, SeenBox};
use crate::scene::FlatLight;
use glam::Vec3;

/// Where the lights can be, and whether bakes keep the occluders' depth for them.
#[derive(Clone, Debug, PartialEq)]
pub struct Reach {
    /// Where the lights can be.
    pub bounds: Bounds,
    /// Whether bakes keep how far the occluders are ([`super::depth`]): some light has geometry
    /// behind it (a ceiling light, a lamp in a shade, a wall light), so what lies beyond it
    /// must not hide it. Without, what a texel's ray meets hides the light at any distance.
    pub depth: bool,
}

/// Where the lights can be.
#[derive(Clone, Debug, PartialEq)]
pub enum Bounds {
    /// Some light may go anywhere.
    Anywhere,
    /// Every light stays inside one of these world-space boxes (min, max).
    Within(Vec<[Vec3; 2]>),
}

impl std::fmt::Display for Reach {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.bounds {
            Bounds::Anywhere => write!(f, "lights anywhere")?,
            Bounds::Within(boxes) if boxes.len() == 1 => write!(f, "lights within 1 reach box")?,
            Bounds::Within(boxes) => write!(f, "lights within {} reach boxes", boxes.len())?,
        }
        if self.depth {
            write!(f, ", occluders' depth kept (a light has geometry behind it)")?;
        }
        Ok(())
    }
}

/// Rays from a light's centre over the hemisphere behind it that look for geometry there.
const BEHIND_RAYS: u32 = 64;

impl Reach {
    /// Lights anywhere, no depth.
    pub const ANYWHERE: Reach = Reach { bounds: Bounds::Anywhere, depth: false };

    /// The reach of `lights`, without depth: each light's declared box, grown to hold the
    /// light where it is now (a light moved out of its box still casts correct shadows, from a
    /// bake keyed on the grown box), and padded for rays' offset origins as occluder bounds are.
    pub fn of(lights: &[FlatLight]) -> Self {
        let boxes: Option<Vec<[Vec3; 2]>> = lights
            .iter()
            .map(|l| {
                let [lo, hi] = l.reach?;
                let (lo, hi) = l.points.iter().fold((lo, hi), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
                let pad = Vec3::splat(1e-4 * (hi - lo).length() + 1e-5);
                Some([lo - pad, hi + pad])
            })
            .collect();
        Reach { bounds: boxes.map_or(Bounds::Anywhere, Bounds::Within), depth: false }
    }

    /// The reach of `flat`'s lights ([`Self::of`]), keeping depth when geometry lies behind
    /// some light where it is now: one of [`BEHIND_RAYS`] rays from its centre over the
    /// hemisphere behind it meets a triangle. A light moved to where that changes is baked
    /// for again.
    pub fn of_scene(flat: &crate::scene::FlatScene) -> Self {
        let mut reach = Self::of(&flat.lights);
        if !flat.lights.is_empty() && !flat.triangles.is_empty() {
            let bvh = crate::accel::SceneBvh::quick_over(flat);
            reach.depth = flat.lights.iter().any(|l| {
                let centre = l.points.iter().sum::<Vec3>() / l.points.len() as f32;
                let back = crate::math::frame::Frame::from_normal(-l.normal);
                (0..BEHIND_RAYS).any(|k| {
                    let d = back.to_world(crate::math::sampling::cosine_hemisphere(crate::math::sampling::hammersley(
                        k,
                        BEHIND_RAYS,
                    )));
                    bvh.occluded(crate::accel::offset_ray_origin(centre, -l.normal, d), d, f32::INFINITY)
                })
            });
        }
        reach
    }

    /// What a bake key needs of it: the boxes' bits (nothing for [`Bounds::Anywhere`]), then
    /// a 1 when depth is kept (nothing without).
    pub fn key_bytes(&self) -> Vec<u8> {
        let mut bytes = self.box_bytes();
        if self.depth {
            bytes.push(1);
        }
        bytes
    }

    /// The boxes' bits.
    fn box_bytes(&self) -> Vec<u8> {
        match &self.bounds {
            Bounds::Anywhere => Vec::new(),
            Bounds::Within(boxes) => {
                boxes.iter().flat_map(|b| b.iter().flat_map(|c| c.to_array())).flat_map(f32::to_le_bytes).collect()
            }
        }
    }

    /// Per tile (`6 · tiles_per_side²`, as [`SeenBox::tiles`]) of the vertex at `p` with unit
    /// normal `n`, whether a light in reach can be seen through it; `None` when every tile can.
    pub fn tiles(&self, p: Vec3, n: Vec3, res: usize) -> Option<Vec<bool>> {
        let Bounds::Within(boxes) = &self.bounds else { return None };
        let mut out = vec![false; 6 * super::tiles_per_side(res).pow(2)];
        for [lo, hi] in boxes {
            let cover = SeenBox::new(p, n, *lo, *hi).tiles(res);
            out.iter_mut().zip(cover).for_each(|(o, c)| *o |= c != Cover::None);
        }
        Some(out)
    }

    /// How far the ray from `origin` along unit `d` must look for occluders: to where it
    /// leaves the farthest reach box it meets, for what lies beyond every light it can meet
    /// cannot shadow it — a ceiling behind a light mounted under it, a wall behind a lamp.
    /// Infinite for [`Bounds::Anywhere`] and for a ray that meets no box (its answer shapes
    /// the trees between the lights, as it did before reach was declared).
    pub fn ray_end(&self, origin: Vec3, d: Vec3) -> f32 {
        let Bounds::Within(boxes) = &self.bounds else { return f32::INFINITY };
        let inv = d.recip();
        let exits = boxes.iter().filter_map(|[lo, hi]| {
            let (a, b) = ((*lo - origin) * inv, (*hi - origin) * inv);
            // `min`/`max` drop the NaN of a ray along a box face (0 · ∞).
            let near = a.x.min(b.x).max(a.y.min(b.y)).max(a.z.min(b.z));
            let far = a.x.max(b.x).min(a.y.max(b.y)).min(a.z.max(b.z));
            (far >= near.max(0.0)).then_some(far)
        });
        exits.reduce(f32::max).unwrap_or(f32::INFINITY)
    }

    /// Whether some ray ends short of infinity (see [`Self::ray_end`]).
    pub fn bounds_rays(&self) -> bool {
        matches!(self.bounds, Bounds::Within(_))
    }

    /// The share of a full bake's casting that the vertex at `p` (unit normal `n`) still
    /// needs: its reached tiles over its tiles above the horizon (1 for [`Bounds::Anywhere`]),
    /// by which plans scale their cost estimates.
    pub fn share(&self, p: Vec3, n: Vec3, res: usize) -> f64 {
        let Some(reached) = self.tiles(p, n, res) else { return 1.0 };
        let live = (0..6).flat_map(|f| super::visibility::live_tiles(n, f, res));
        let (hit, all) = live.zip(reached).fold((0, 0), |(h, a), (l, r)| (h + usize::from(l && r), a + usize::from(l)));
        if all == 0 { 0.0 } else { hit as f64 / all as f64 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::cubemap;
    use rand::Rng;

    fn within(boxes: Vec<[Vec3; 2]>) -> Reach {
        Reach { bounds: Bounds::Within(boxes), depth: false }
    }

    fn light(reach: Option<[Vec3; 2]>) -> FlatLight {
        let points = vec![Vec3::new(0.0, 2.0, 0.0), Vec3::new(1.0, 2.0, 0.0), Vec3::new(1.0, 2.0, 1.0)];
        FlatLight { points, uvs: vec![], normal: Vec3::NEG_Y, area: 0.5, radiance: Vec3::ONE, texture: None, reach }
    }

    #[test]
    fn one_roaming_light_reaches_everywhere_and_boxes_hold_their_lights() {
        let room = [Vec3::splat(-3.0), Vec3::splat(3.0)];
        assert_eq!(Reach::of(&[light(Some(room)), light(None)]), Reach::ANYWHERE);
        assert_eq!(Reach::ANYWHERE.tiles(Vec3::ZERO, Vec3::Y, 64), None);
        assert!(Reach::ANYWHERE.key_bytes().is_empty());
        // A light moved out of its box: the reach grows to hold it (padded).
        let Bounds::Within(boxes) = Reach::of(&[light(Some([Vec3::ZERO, Vec3::splat(0.5)]))]).bounds else { panic!() };
        let [lo, hi] = boxes[0];
        assert!(lo.cmple(Vec3::ZERO).all() && lo.cmpgt(Vec3::splat(-1e-3)).all(), "{lo}");
        assert!(hi.cmpge(Vec3::new(1.0, 2.0, 1.0)).all() && hi.cmplt(Vec3::new(1.001, 2.001, 1.001)).all(), "{hi}");
        assert_eq!(Reach { bounds: Bounds::Within(boxes), depth: true }.key_bytes().len(), 25);
    }

    /// Every direction from a vertex into a light's box (above its horizon) lies in a reached
    /// tile, and most tiles are not reached.
    #[test]
    fn every_direction_into_the_box_is_in_a_reached_tile() {
        let mut r = crate::math::rng::seeded(5);
        let res = 32;
        let k = crate::bspvt::tiles_per_side(res);
        let mut unreached = 0;
        for _ in 0..200 {
            let lo = Vec3::new(r.random_range(-2.0..2.0), r.random_range(-1.0..3.0), r.random_range(-2.0..2.0));
            let hi = lo + Vec3::new(r.random_range(0.0..1.0), r.random_range(0.0..0.3), r.random_range(0.0..1.0));
            let p = Vec3::new(r.random_range(-2.0..2.0), r.random_range(-0.5..0.5), r.random_range(-2.0..2.0));
            let n =
                Vec3::new(r.random_range(-1.0..1.0), r.random_range(0.2..1.0), r.random_range(-1.0..1.0)).normalize();
            let reached = within(vec![[lo, hi]]).tiles(p, n, res).unwrap();
            unreached += reached.iter().filter(|r| !**r).count();
            for _ in 0..500 {
                let q = lo + (hi - lo) * Vec3::new(r.random(), r.random(), r.random());
                let d = (q - p).normalize_or_zero().as_dvec3();
                if d.dot(n.as_dvec3()) <= 0.0 || d == glam::DVec3::ZERO {
                    continue;
                }
                let (f, st) = cubemap::dir_to_face(d);
                let (i, j) = cubemap::texel_of(st, res);
                let t = f * k * k + (j / crate::bspvt::node::TILE) * k + i / crate::bspvt::node::TILE;
                assert!(reached[t], "p {p} n {n} box {lo}..{hi}: {d} in face {f} texel ({i}, {j})");
            }
        }
        assert!(unreached > 200 * 6 * k * k / 2, "{unreached} unreached tiles");
    }

    /// A ray ends where it leaves the farthest box it meets: the point there is on that box's
    /// boundary and everything past it is outside every box; rays that meet no box, and every
    /// ray of [`Reach::ANYWHERE`], go on for ever.
    #[test]
    fn rays_end_where_they_leave_the_farthest_box_they_meet() {
        let mut r = crate::math::rng::seeded(11);
        let mut v =
            |lo: f32, hi: f32| Vec3::new(r.random_range(lo..hi), r.random_range(lo..hi), r.random_range(lo..hi));
        let (mut ended, mut endless) = (0, 0);
        for _ in 0..2000 {
            let boxes: Vec<[Vec3; 2]> = (0..2)
                .map(|_| {
                    let lo = v(-2.0, 2.0);
                    [lo, lo + v(0.0, 1.5)]
                })
                .collect();
            let (o, d) = (v(-3.0, 3.0), v(-1.0, 1.0).normalize());
            let reach = within(boxes.clone());
            assert_eq!(Reach::ANYWHERE.ray_end(o, d), f32::INFINITY);
            let end = reach.ray_end(o, d);
            let inside = |q: Vec3, slack: f32| {
                boxes.iter().any(|[lo, hi]| q.cmpge(*lo - slack).all() && q.cmple(*hi + slack).all())
            };
            // Sampled along the ray: a point inside a box is never past the end.
            let past = (1..400).map(|k| k as f32 * 0.02).filter(|&t| t > end + 1e-3).any(|t| inside(o + d * t, 0.0));
            assert!(!past, "o {o} d {d} boxes {boxes:?}: a box past the end {end}");
            if end.is_finite() {
                ended += 1;
                assert!(end >= 0.0 && inside(o + d * end, 1e-4), "o {o} d {d} boxes {boxes:?}: end {end}");
            } else {
                endless += 1;
                assert!(!(0..400).any(|k| inside(o + d * (k as f32 * 0.02), 0.0)), "o {o} d {d} meets {boxes:?}");
            }
        }
        assert!(ended > 40 && endless > 200, "{ended} rays ended, {endless} did not");
        // A ray along a box's face (a zero direction component on the face's plane) still ends.
        let flat = within(vec![[Vec3::new(-1.0, 2.0, -1.0), Vec3::new(1.0, 2.0, 1.0)]]);
        assert_eq!(flat.ray_end(Vec3::new(-3.0, 2.0, 0.0), Vec3::X), 4.0);
        assert_eq!(flat.ray_end(Vec3::ZERO, Vec3::Y), 2.0);
    }

    /// A vertex's share is its reached share of the tiles above its horizon.
    #[test]
    fn the_share_counts_reached_tiles_above_the_horizon() {
        let (p, up) = (Vec3::ZERO, Vec3::Y);
        assert_eq!(Reach::ANYWHERE.share(p, up, 64), 1.0);
        // A box around the vertex reaches every tile; one below its horizon none.
        assert_eq!(within(vec![[Vec3::splat(-1.0), Vec3::splat(1.0)]]).share(p, up, 64), 1.0);
        assert_eq!(within(vec![[Vec3::new(-1.0, -3.0, -1.0), Vec3::new(1.0, -2.0, 1.0)]]).share(p, up, 64), 0.0);
        // A small box overhead: a small share, more for a bigger box.
        let small = within(vec![[Vec3::new(-0.1, 2.0, -0.1), Vec3::new(0.1, 2.1, 0.1)]]).share(p, up, 64);
        let big = within(vec![[Vec3::new(-1.0, 2.0, -1.0), Vec3::new(1.0, 2.1, 1.0)]]).share(p, up, 64);
        assert!(0.0 < small && small < big && big < 0.5, "{small} {big}");
    }
}
