//! What an edit inside an axis-aligned box can change in a vertex's visibility cube map: the
//! tiles (see [`super::tree::TILE`]) whose cones of directions can see into the box, and in them
//! the texels whose rays can meet it. Both tests are conservative — a ray they leave out cannot
//! meet the box, so its visibility cannot have changed — and cheap where it matters: the texel
//! test runs on every texel of a touched tile, so from far enough away it is a few dot products
//! against the planes bounding the box's cone rather than a ray–box intersection.

use super::{tiles_per_side, tree};
use crate::accel;
use crate::math::cubemap;
use glam::{DVec2, DVec3, Vec3};

/// How far (in direction cosines) a ray may pass outside the box's cone from `p` and still meet
/// the box from its offset origin: the offset is below 6e-5 · (|p|∞ + 1) (see
/// [`accel::offset_ray_origin`]) and the cone test is only used beyond 1e-2 · (|p|∞ + 1).
const ORIGIN_SLACK: f64 = 1e-2;

/// How much of a tile's cone of directions can meet a box.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cover {
    /// No ray through the tile meets it.
    None,
    /// Some may: ask [`SeenBox::meets`] texel by texel.
    Some,
    /// Every direction through the tile lies inside the box's cone: take each texel as meeting it.
    All,
}

/// A box as seen from a vertex at `p` with unit normal `n`.
pub struct SeenBox {
    p: Vec3,
    n: Vec3,
    lo: Vec3,
    hi: Vec3,
    /// Corners relative to `p`.
    corners: [DVec3; 8],
    /// Unit normals of the planes through `p` touching the box along one of its edges, the box
    /// on their non-positive side (its silhouette); empty when `p` is inside or too close.
    silhouette: Vec<DVec3>,
    /// The same in single precision, for the per-texel test (whose slack dwarfs the rounding).
    silhouette32: Vec<Vec3>,
}

impl SeenBox {
    /// The box `[lo, hi]` seen from `p` (unit normal `n`).
    pub fn new(p: Vec3, n: Vec3, lo: Vec3, hi: Vec3) -> Self {
        let pd = p.as_dvec3();
        let (lod, hid) = (lo.as_dvec3(), hi.as_dvec3());
        let corners = corners_from(pd, lod, hid);
        let distance = (lod - pd).max(pd - hid).max(DVec3::ZERO).length();
        let far = distance >= ORIGIN_SLACK * (pd.abs().max_element() + 1.0);
        let silhouette = if far { silhouette_planes(&corners) } else { Vec::new() };
        let silhouette32 = silhouette.iter().map(|m| m.as_vec3()).collect();
        Self { p, n, lo, hi, corners, silhouette, silhouette32 }
    }

    /// Whether the ray cast from the vertex in direction `d` (unit, above its horizon) can meet
    /// the box.
    pub fn meets(&self, d: Vec3) -> bool {
        if self.silhouette.is_empty() {
            return accel::ray_meets_box(accel::offset_ray_origin(self.p, self.n, d), d, self.lo, self.hi);
        }
        self.silhouette32.iter().all(|m| m.dot(d) <= ORIGIN_SLACK as f32)
    }

    /// How much each tile sees of the box (per face, row-major tiles: `6 · tiles_per_side²`):
    /// [`Cover::None`] when a plane of the tile's frustum or of the box's silhouette separates
    /// the two, with a margin of two texels for the rays cast just above the horizon;
    /// [`Cover::All`] when the tile's corners lie inside every silhouette plane.
    pub fn tiles(&self, res: usize) -> Vec<Cover> {
        let k = tiles_per_side(res);
        let pd = self.p.as_dvec3();
        if (pd.cmpge(self.lo.as_dvec3()) & pd.cmple(self.hi.as_dvec3())).all() {
            return vec![Cover::Some; 6 * k * k];
        }
        let margin = 4.0 / res as f64;
        let lengths = self.corners.map(|c| c.length());
        let outside = |plane: DVec3| self.corners.iter().zip(&lengths).all(|(c, l)| plane.dot(*c) < -margin * l);
        if outside(self.n.as_dvec3()) {
            return vec![Cover::None; 6 * k * k];
        }
        let edge = |t: usize| 2.0 * (t * tree::TILE).min(res) as f64 / res as f64 - 1.0;
        let mut out = Vec::with_capacity(6 * k * k);
        for f in 0..6 {
            if cubemap::face_frustum(f).iter().any(|pl| outside(pl.normalize())) {
                out.extend(std::iter::repeat_n(Cover::None, k * k));
                continue;
            }
            // Tiles share their edges' planes and their corners: each is evaluated once. Per
            // grid line t: the box lies entirely before it, or entirely past it.
            let side = |a: f64, b: f64| -> Vec<(bool, bool)> {
                (0..=k)
                    .map(|t| cubemap::line_plane(f, a, b, -edge(t)).normalize())
                    .map(|pl| (outside(pl), outside(-pl)))
                    .collect()
            };
            let (cols, rows) = (side(1.0, 0.0), side(0.0, 1.0));
            let corner = |x: usize| cubemap::face_to_dir(f, DVec2::new(edge(x % (k + 1)), edge(x / (k + 1))));
            let corners: Vec<DVec3> = (0..(k + 1) * (k + 1)).map(corner).collect();
            // Per silhouette plane, the grid corners beyond it by the margin, and those inside.
            let side = |inside: bool| -> Vec<Vec<bool>> {
                let test = |m: &DVec3, d: &DVec3| if inside { m.dot(*d) <= 0.0 } else { m.dot(*d) > margin };
                self.silhouette.iter().map(|m| corners.iter().map(|d| test(m, d)).collect()).collect()
            };
            let (beyond, inside) = (side(false), side(true));
            for (tj, ti) in (0..k).flat_map(|tj| (0..k).map(move |ti| (tj, ti))) {
                let framed = !(cols[ti].0 || cols[ti + 1].1 || rows[tj].0 || rows[tj + 1].1);
                // A direction in the tile is a positive combination of its corners: beyond a
                // plane by the margin when all four corners are.
                let at =
                    [tj * (k + 1) + ti, tj * (k + 1) + ti + 1, (tj + 1) * (k + 1) + ti, (tj + 1) * (k + 1) + ti + 1];
                let all_in = |b: &Vec<bool>| at.iter().all(|&c| b[c]);
                out.push(if !framed || beyond.iter().any(all_in) {
                    Cover::None
                } else if !inside.is_empty() && inside.iter().all(all_in) {
                    // Positive combinations of directions inside every plane stay inside.
                    Cover::All
                } else {
                    Cover::Some
                });
            }
        }
        out
    }
}

/// The corners of the box `[lo, hi]` relative to `p` (bit 0 of the index picks x, 1 y, 2 z).
fn corners_from(p: DVec3, lo: DVec3, hi: DVec3) -> [DVec3; 8] {
    std::array::from_fn(|c| DVec3::select(glam::BVec3::new(c & 1 == 0, c & 2 == 0, c & 4 == 0), lo, hi) - p)
}

/// The box's silhouette planes (see [`SeenBox::silhouette`]) from its corners relative to the
/// viewpoint: of the planes through the viewpoint and a box edge, those with every corner on one
/// side. They bound the cone of directions that meet the box; an edge seen end-on gives none,
/// which only loosens the test.
fn silhouette_planes(corners: &[DVec3; 8]) -> Vec<DVec3> {
    let edges = (0..8).flat_map(|c| [1, 2, 4].into_iter().filter(move |b| c & b == 0).map(move |b| (c, c | b)));
    edges
        .filter_map(|(a, b)| {
            let m = corners[a].cross(corners[b]).normalize_or_zero();
            [m, -m].into_iter().find(|m| *m != DVec3::ZERO && corners.iter().all(|c| m.dot(*c) <= 1e-9 * c.length()))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bspvt::visibility;

    /// Both tests are conservative: no texel ray the texel test rejects, nor any in a tile the
    /// tile test leaves clean, meets the box (from the ray's offset origin, as cast); and both
    /// are tight enough to matter.
    #[test]
    fn rays_left_out_do_not_meet_the_box() {
        let (res, k) = (32, tiles_per_side(32));
        let (lo, hi) = (Vec3::new(-0.5, 1.0, -0.2), Vec3::new(0.7, 1.1, 0.4));
        let (mut clean, mut dirty, mut wanted, mut hits, mut covered) = (0, 0, 0, 0, 0);
        let points = (-3..=3).flat_map(|x| (-3..=3).map(move |z| Vec3::new(x as f32 * 0.7, 0.0, z as f32 * 0.7)));
        // The last point is so close to the box that the cone test gives way to the exact one.
        for p in points.chain([Vec3::new(0.1, 0.999, 0.1)]) {
            for n in [Vec3::Y, Vec3::new(0.6, 0.8, 0.0), Vec3::new(0.0, 0.6, -0.8)] {
                let seen = SeenBox::new(p, n, lo, hi);
                let flags = seen.tiles(res);
                for (f, i, j) in (0..6).flat_map(|f| (0..res * res).map(move |t| (f, t % res, t / res))) {
                    let Some(d) = visibility::texel_ray(f, i, j, n.as_dvec3(), res).map(|d| d.as_vec3()) else {
                        continue;
                    };
                    let hit = accel::ray_meets_box(accel::offset_ray_origin(p, n, d), d, lo, hi);
                    let at = format!("p {p}, n {n}: texel ({f}, {i}, {j})");
                    assert!(!hit || seen.meets(d), "{at} meets the box, the texel test says no");
                    match flags[f * k * k + (j / tree::TILE) * k + i / tree::TILE] {
                        Cover::None => {
                            clean += 1;
                            assert!(!hit, "{at} in a clean tile meets the box");
                        }
                        cover => {
                            assert!(cover == Cover::Some || seen.meets(d), "{at}: a covered tile's texel misses");
                            (dirty, wanted, hits) = (dirty + 1, wanted + seen.meets(d) as usize, hits + hit as usize);
                            covered += (cover == Cover::All) as usize;
                        }
                    }
                }
            }
        }
        assert!(clean > 4 * dirty && hits > 0, "{clean} clean and {dirty} dirty texels");
        assert!(covered > 0 && covered < hits, "{covered} texels in covered tiles, {hits} hits");
        assert!(wanted < dirty / 3 && wanted < hits + hits / 4, "{wanted} wanted of {dirty} dirty texels, {hits} hits");
    }

    /// The silhouette planes touch the box and bound its cone: every corner is on or behind
    /// each, and the box's centre strictly behind all of them.
    #[test]
    fn silhouette_planes_bound_the_cone() {
        let (lo, hi) = (DVec3::new(1.0, -0.5, 2.0), DVec3::new(1.5, 0.5, 3.0));
        for p in [DVec3::ZERO, DVec3::new(1.2, 0.0, 0.0), DVec3::new(5.0, 5.0, 5.0)] {
            let corners = corners_from(p, lo, hi);
            let planes = silhouette_planes(&corners);
            assert!((4..=6).contains(&planes.len()), "p {p}: {} planes", planes.len());
            let centre = (lo + hi) * 0.5 - p;
            for m in planes {
                assert!(corners.iter().all(|c| m.dot(*c) <= 1e-9) && m.dot(centre) < 0.0, "p {p}, plane {m}");
            }
        }
    }
}
