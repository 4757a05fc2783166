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

/// Where the lights can be.
#[derive(Clone, Debug, PartialEq)]
pub enum Reach {
    /// Some light may go anywhere.
    Anywhere,
    /// Every light stays inside one of these world-space boxes (min, max).
    Within(Vec<[Vec3; 2]>),
}

impl std::fmt::Display for Reach {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Reach::Anywhere => write!(f, "lights anywhere"),
            Reach::Within(boxes) if boxes.len() == 1 => write!(f, "lights within 1 reach box"),
            Reach::Within(boxes) => write!(f, "lights within {} reach boxes", boxes.len()),
        }
    }
}

impl Reach {
    /// The reach of `lights`: each light's declared box, grown to hold the light where it is
    /// now (a light moved out of its box still casts correct shadows, from a bake keyed on the
    /// grown box), and padded for rays' offset origins as occluder bounds are.
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
        boxes.map_or(Reach::Anywhere, Reach::Within)
    }

    /// What a bake key needs of it: the boxes' bits (nothing for [`Reach::Anywhere`]).
    pub fn key_bytes(&self) -> Vec<u8> {
        match self {
            Reach::Anywhere => Vec::new(),
            Reach::Within(boxes) => {
                boxes.iter().flat_map(|b| b.iter().flat_map(|c| c.to_array())).flat_map(f32::to_le_bytes).collect()
            }
        }
    }

    /// Per tile (`6 · tiles_per_side²`, as [`SeenBox::tiles`]) of the vertex at `p` with unit
    /// normal `n`, whether a light in reach can be seen through it; `None` when every tile can.
    pub fn tiles(&self, p: Vec3, n: Vec3, res: usize) -> Option<Vec<bool>> {
        let Reach::Within(boxes) = self else { return None };
        let mut out = vec![false; 6 * super::tiles_per_side(res).pow(2)];
        for [lo, hi] in boxes {
            let cover = SeenBox::new(p, n, *lo, *hi).tiles(res);
            out.iter_mut().zip(cover).for_each(|(o, c)| *o |= c != Cover::None);
        }
        Some(out)
    }

    /// The share of a full bake's casting that the vertex at `p` (unit normal `n`) still
    /// needs: its reached tiles over its tiles above the horizon (1 for [`Reach::Anywhere`]),
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

    fn light(reach: Option<[Vec3; 2]>) -> FlatLight {
        let points = vec![Vec3::new(0.0, 2.0, 0.0), Vec3::new(1.0, 2.0, 0.0), Vec3::new(1.0, 2.0, 1.0)];
        FlatLight {
            points,
            uvs: vec![],
            normal: Vec3::NEG_Y,
            area: 0.5,
            radiance: Vec3::ONE,
            texture: None,
            reach,
            entity: hecs::Entity::DANGLING,
        }
    }

    #[test]
    fn one_roaming_light_reaches_everywhere_and_boxes_hold_their_lights() {
        let room = [Vec3::splat(-3.0), Vec3::splat(3.0)];
        assert_eq!(Reach::of(&[light(Some(room)), light(None)]), Reach::Anywhere);
        assert_eq!(Reach::Anywhere.tiles(Vec3::ZERO, Vec3::Y, 64), None);
        assert!(Reach::Anywhere.key_bytes().is_empty());
        // A light moved out of its box: the reach grows to hold it (padded).
        let Reach::Within(boxes) = Reach::of(&[light(Some([Vec3::ZERO, Vec3::splat(0.5)]))]) else { panic!() };
        let [lo, hi] = boxes[0];
        assert!(lo.cmple(Vec3::ZERO).all() && lo.cmpgt(Vec3::splat(-1e-3)).all(), "{lo}");
        assert!(hi.cmpge(Vec3::new(1.0, 2.0, 1.0)).all() && hi.cmplt(Vec3::new(1.001, 2.001, 1.001)).all(), "{hi}");
        assert_eq!(Reach::Within(boxes).key_bytes().len(), 24);
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
            let reached = Reach::Within(vec![[lo, hi]]).tiles(p, n, res).unwrap();
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

    /// A vertex's share is its reached share of the tiles above its horizon.
    #[test]
    fn the_share_counts_reached_tiles_above_the_horizon() {
        let (p, up) = (Vec3::ZERO, Vec3::Y);
        assert_eq!(Reach::Anywhere.share(p, up, 64), 1.0);
        // A box around the vertex reaches every tile; one below its horizon none.
        assert_eq!(Reach::Within(vec![[Vec3::splat(-1.0), Vec3::splat(1.0)]]).share(p, up, 64), 1.0);
        assert_eq!(Reach::Within(vec![[Vec3::new(-1.0, -3.0, -1.0), Vec3::new(1.0, -2.0, 1.0)]]).share(p, up, 64), 0.0);
        // A small box overhead: a small share, more for a bigger box.
        let small = Reach::Within(vec![[Vec3::new(-0.1, 2.0, -0.1), Vec3::new(0.1, 2.1, 0.1)]]).share(p, up, 64);
        let big = Reach::Within(vec![[Vec3::new(-1.0, 2.0, -1.0), Vec3::new(1.0, 2.1, 1.0)]]).share(p, up, 64);
        assert!(0.0 < small && small < big && big < 0.5, "{small} {big}");
    }
}
