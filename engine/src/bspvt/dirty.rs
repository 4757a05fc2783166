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
        Self { p, n, lo, hi, corners, silhouette }
    }

    /// Whether the ray cast from the vertex in direction `d` (unit, above its horizon) can meet
    /// the box.
    pub fn meets(&self, d: Vec3) -> bool {
        if self.silhouette.is_empty() {
            return accel::ray_meets_box(accel::offset_ray_origin(self.p, self.n, d), d, self.lo, self.hi);
        }
        let d = d.as_dvec3();
        self.silhouette.iter().all(|m| m.dot(d) <= ORIGIN_SLACK)
    }

    /// Which tiles can see into the box (per face, row-major tiles: `6 · tiles_per_side²`
    /// flags): no plane of the tile's frustum nor of the box's silhouette separates the two,
    /// with a margin of two texels for the rays cast just above the horizon.
    pub fn tiles(&self, res: usize) -> Vec<bool> {
        let k = tiles_per_side(res);
        let pd = self.p.as_dvec3();
        if (pd.cmpge(self.lo.as_dvec3()) & pd.cmple(self.hi.as_dvec3())).all() {
            return vec![true; 6 * k * k];
        }
        let margin = 4.0 / res as f64;
        let outside = |plane: DVec3| self.corners.iter().all(|c| plane.dot(*c) < -margin * c.length());
        if outside(self.n.as_dvec3()) {
            return vec![false; 6 * k * k];
        }
        let edge = |t: usize| 2.0 * (t * tree::TILE).min(res) as f64 / res as f64 - 1.0;
        let mut out = Vec::with_capacity(6 * k * k);
        for f in 0..6 {
            let face_seen = !cubemap::face_frustum(f).iter().any(|pl| outside(pl.normalize()));
            let corner = |ti: usize, tj: usize| cubemap::face_to_dir(f, DVec2::new(edge(ti), edge(tj)));
            for (tj, ti) in (0..k).flat_map(|tj| (0..k).map(move |ti| (tj, ti))) {
                out.push(
                    face_seen && {
                        let planes = [
                            cubemap::line_plane(f, 1.0, 0.0, -edge(ti)),
                            cubemap::line_plane(f, -1.0, 0.0, edge(ti + 1)),
                            cubemap::line_plane(f, 0.0, 1.0, -edge(tj)),
                            cubemap::line_plane(f, 0.0, -1.0, edge(tj + 1)),
                        ];
                        // A direction in the tile is a positive combination of its corners: beyond
                        // a plane by the margin when all four corners are.
                        let dirs = [corner(ti, tj), corner(ti + 1, tj), corner(ti, tj + 1), corner(ti + 1, tj + 1)];
                        let beyond = |m: &DVec3| dirs.iter().all(|d| m.dot(*d) > margin);
                        !planes.iter().any(|pl| outside(pl.normalize())) && !self.silhouette.iter().any(beyond)
                    },
                );
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
        let (mut clean, mut dirty, mut wanted, mut hits) = (0, 0, 0, 0);
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
                    if flags[f * k * k + (j / tree::TILE) * k + i / tree::TILE] {
                        (dirty, wanted, hits) = (dirty + 1, wanted + seen.meets(d) as usize, hits + hit as usize);
                    } else {
                        clean += 1;
                        assert!(!hit, "{at} in a clean tile meets the box");
                    }
                }
            }
        }
        assert!(clean > 4 * dirty && hits > 0, "{clean} clean and {dirty} dirty texels");
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
