//! What an edit inside an axis-aligned box can change in a vertex's visibility cube map: the
//! tiles (see [`super::node::TILE`]) whose cones of directions can see into the box, and in them
//! the texels whose rays can meet it. Both tests are conservative — a ray they leave out cannot
//! meet the box, so its visibility cannot have changed — and cheap where it matters: the texel
//! test runs on every texel of a touched tile, so from far enough away it is a few dot products
//! against the planes bounding the box's cone rather than a ray–box intersection.

use super::grid::{FaceGrid, with_grids};
use super::tiles_per_side;
use crate::accel::{self, beam::Beam};
use crate::math::cubemap;
use crate::math::planes::Planes;
use glam::{DVec3, Vec3};
use std::ops::Range;
use wide::f64x4;

/// A ray's origin lies within this times (|p|∞ + 1) of the vertex `p` it is cast from (see
/// [`accel::offset_ray_origin`]).
const ORIGIN_OFFSET: f64 = 6e-5;

/// The cone test is used for boxes farther than this times (|p|∞ + 1) from the vertex: there a
/// ray passes at most ORIGIN_OFFSET / (CONE_DISTANCE − ORIGIN_OFFSET) ≈ 6·10⁻³ (in direction
/// cosines) outside the box's cone from `p` and still meets it from its offset origin.
const CONE_DISTANCE: f64 = 1e-2;

/// More than the rounding of the single-precision dot products of unit vectors that the
/// per-texel tests ([`SeenBox::meets`], [`Beam::hits`]) compute, the vectors' own conversion to
/// single precision included.
const SINGLE_ROUNDING: f64 = 1e-6;

/// How far above the horizon (in cosines) every direction of a tile must be for its rays'
/// origin to be the shared one whatever the single-precision rounding.
const HIGH_ENOUGH: f32 = 1e-4;

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
    /// The same in single precision, for the per-texel test.
    silhouette32: Planes,
    /// The same four at a time, as x, y and z lanes (the last group padded with zero planes),
    /// for the tile test.
    silhouette4: Vec<[f64x4; 3]>,
    /// How far outside the cone (in direction cosines) a ray from the offset origin can pass
    /// and still meet the box, single-precision rounding included: δ / (distance − δ) for an
    /// origin offset δ.
    slack: f32,
}

impl SeenBox {
    /// The box `[lo, hi]` seen from `p` (unit normal `n`).
    pub fn new(p: Vec3, n: Vec3, lo: Vec3, hi: Vec3) -> Self {
        let pd = p.as_dvec3();
        let (lod, hid) = (lo.as_dvec3(), hi.as_dvec3());
        let corners = corners_from(pd, lod, hid);
        let distance = (lod - pd).max(pd - hid).max(DVec3::ZERO).length();
        let scale = pd.abs().max_element() + 1.0;
        let far = distance >= CONE_DISTANCE * scale;
        let silhouette = if far { silhouette_planes(&corners) } else { Vec::new() };
        let silhouette32 = Planes::new(&silhouette.iter().map(|m| m.as_vec3()).collect::<Vec<_>>());
        let silhouette4 = silhouette
            .chunks(4)
            .map(|g| {
                let lanes = |axis: fn(&DVec3) -> f64| f64x4::new(std::array::from_fn(|l| g.get(l).map_or(0.0, axis)));
                [lanes(|m| m.x), lanes(|m| m.y), lanes(|m| m.z)]
            })
            .collect();
        let offset = ORIGIN_OFFSET * scale;
        let slack = (offset / (distance - offset) + SINGLE_ROUNDING) as f32;
        Self { p, n, lo, hi, corners, silhouette, silhouette32, silhouette4, slack }
    }

    /// Whether the ray cast from the vertex in direction `d` (unit, above its horizon) can meet
    /// the box.
    #[inline]
    pub fn meets(&self, d: Vec3) -> bool {
        if self.silhouette.is_empty() {
            return accel::ray_meets_box(accel::offset_ray_origin(self.p, self.n, d), d, self.lo, self.hi);
        }
        self.silhouette32.sides(d, self.slack).0 == 0
    }

    /// Per texel row `j` in `rows` of face `f`, the columns whose centre directions can pass
    /// [`Self::meets`] (a superset): the silhouette planes bound an interval of the row's face
    /// coordinate s, since a direction's unnormalised form `u = c + s·S + t·T` (face basis)
    /// is at most √(2 + t²) long on the row. All columns when there are no planes (the exact
    /// test applies).
    pub fn columns(&self, f: usize, res: usize, rows: Range<usize>) -> Vec<Range<usize>> {
        let (c, s_axis, t_axis) = cubemap::face_basis(f);
        // m · c, m · T, m · S and its reciprocal (a product, not a quotient, per row: the bounds'
        // rounding changes by an ulp, far inside the columns' widening below).
        let planes: Vec<[f64; 4]> =
            self.silhouette.iter().map(|m| [m.dot(c), m.dot(t_axis), m.dot(s_axis), 1.0 / m.dot(s_axis)]).collect();
        rows.map(|j| {
            let t = cubemap::texel_center(0, j, res).y;
            // m · û ≤ slack in single precision implies m · u ≤ (slack + rounding) · |u|.
            let bound = (self.slack as f64 + SINGLE_ROUNDING) * (2.0 + t * t).sqrt();
            let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
            for [mc, mt, b, inv_b] in &planes {
                // m · u = a + s·b ≤ bound.
                let a = mc + t * mt;
                match b.partial_cmp(&0.0) {
                    Some(std::cmp::Ordering::Greater) => hi = hi.min((bound - a) * inv_b),
                    Some(std::cmp::Ordering::Less) => lo = lo.max((bound - a) * inv_b),
                    _ if a > bound => hi = f64::NEG_INFINITY,
                    _ => {}
                }
            }
            // The centres in [lo, hi], widened far beyond this arithmetic's rounding.
            let first = (column(lo, res) - 1e-6).ceil().max(0.0) as usize;
            let end = ((column(hi, res) + 1e-6).floor() + 1.0).clamp(0.0, res as f64) as usize;
            first.min(end)..end
        })
        .collect()
    }

    /// Which silhouette planes the unit direction `c` lies beyond by `margin` (bit b for plane
    /// b), and which it lies inside or on: four planes per instruction, each dot product
    /// computed as [`DVec3::dot`] computes it (so with the same bits).
    fn corner_masks(&self, c: DVec3, margin: f64) -> (u16, u16) {
        let every = (1u16 << self.silhouette.len()) - 1;
        let (x, y, z) = (f64x4::splat(c.x), f64x4::splat(c.y), f64x4::splat(c.z));
        let (beyond, inside) =
            self.silhouette4.iter().enumerate().fold((0, 0), |(beyond, inside), (g, [mx, my, mz])| {
                let dot = *mx * x + *my * y + *mz * z;
                let (b, i) = (dot.simd_gt(f64x4::splat(margin)), dot.simd_le(f64x4::ZERO));
                (beyond | (b.to_bitmask() as u16) << (4 * g), inside | (i.to_bitmask() as u16) << (4 * g))
            });
        (beyond & every, inside & every)
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
        let corners = Corners::new(&self.corners, margin);
        let outside = |plane: DVec3| corners.sides(plane).0;
        if outside(self.n.as_dvec3()) {
            return vec![Cover::None; 6 * k * k];
        }
        let mut out = Vec::with_capacity(6 * k * k);
        with_grids(res, |grids| {
            for (f, grid) in grids.iter().enumerate() {
                if cubemap::face_frustum(f).iter().any(|pl| outside(pl.normalize())) {
                    out.extend(std::iter::repeat_n(Cover::None, k * k));
                    continue;
                }
                // Per grid line: the box lies entirely before it, or entirely past it.
                let sides: Vec<(bool, bool)> = grid.lines.iter().map(|pl| corners.sides(*pl)).collect();
                let (cols, rows) = sides.split_at(k + 1);
                // The columns and rows of tiles whose bounding grid lines leave the box between
                // them: only their tiles can see it.
                let between =
                    |lines: &[(bool, bool)]| (0..k).filter(|&x| !lines[x].0 && !lines[x + 1].1).collect::<Vec<_>>();
                let (across, down) = (between(cols), between(rows));
                // Per grid corner, computed when a tile first needs it: bit b set when it lies
                // beyond silhouette plane b by the margin, or inside it (a box has at most 12
                // such planes, one per edge).
                let mut masks: Vec<Option<(u16, u16)>> = vec![None; grid.corners.len()];
                let mut mask = |c: usize| *masks[c].get_or_insert_with(|| self.corner_masks(grid.corners[c], margin));
                let every = (1u16 << self.silhouette.len()) - 1;
                let face = out.len();
                out.resize(face + k * k, Cover::None);
                for t in down.iter().flat_map(|tj| across.iter().map(move |ti| tj * k + ti)) {
                    // A direction in the tile is a positive combination of its corners: beyond a
                    // plane by the margin when all four corners are, inside every plane when all
                    // four are.
                    let (beyond, inside) = FaceGrid::tile_corners(t, k)
                        .into_iter()
                        .fold((every, every), |(b, i), c| (b & mask(c).0, i & mask(c).1));
                    out[face + t] = if beyond != 0 {
                        Cover::None
                    } else if every != 0 && inside == every {
                        Cover::All
                    } else {
                        Cover::Some
                    };
                }
            }
        });
        out
    }
}

/// A box's eight corners relative to a viewpoint, four per vector, with the margins
/// (`margin` times their lengths) by which a plane through the viewpoint must clear them.
struct Corners {
    x: [f64x4; 2],
    y: [f64x4; 2],
    z: [f64x4; 2],
    margins: [f64x4; 2],
}

impl Corners {
    fn new(corners: &[DVec3; 8], margin: f64) -> Self {
        let lanes = |h: usize, axis: fn(&DVec3) -> f64| f64x4::new(std::array::from_fn(|l| axis(&corners[4 * h + l])));
        let half = |axis: fn(&DVec3) -> f64| [lanes(0, axis), lanes(1, axis)];
        let (x, y, z) = (half(|c| c.x), half(|c| c.y), half(|c| c.z));
        let margins = [0, 1].map(|h| f64x4::new(std::array::from_fn(|l| margin * corners[4 * h + l].length())));
        Self { x, y, z, margins }
    }

    /// Whether every corner lies before the plane through the viewpoint with normal `pl` by its
    /// margin, and whether every corner lies past it: each dot product computed as
    /// [`DVec3::dot`] computes it (so with the same bits).
    fn sides(&self, pl: DVec3) -> (bool, bool) {
        let (px, py, pz) = (f64x4::splat(pl.x), f64x4::splat(pl.y), f64x4::splat(pl.z));
        (0..2).fold((true, true), |(before, past), h| {
            let d = px * self.x[h] + py * self.y[h] + pz * self.z[h];
            let m = self.margins[h];
            (before && d.simd_lt(-m).all(), past && d.simd_gt(m).all())
        })
    }
}

/// Per tile (as [`SeenBox::tiles`]), whether every direction through it certainly meets one of
/// `beam`'s triangles (see [`Beam::inside`]) and lies clearly above the horizon of unit normal
/// `n` — so that no rounding can move its rays' origin off the beam's (see
/// [`super::visibility::ray_origin`]). Only the tiles `cover` (the triangles' bounds seen from
/// the beam's origin) marks [`Cover::All`] can be: the rest are `false`.
pub fn blocked_tiles(beam: &Beam, cover: &[Cover], n: Vec3, res: usize) -> Vec<bool> {
    let k = tiles_per_side(res);
    let mut out = vec![false; 6 * k * k];
    if !cover.contains(&Cover::All) {
        return out;
    }
    with_grids(res, |grids| {
        for (f, grid) in grids.iter().enumerate() {
            // Per grid corner, computed when a tile first needs it.
            let mut inside = vec![None; (k + 1) * (k + 1)];
            for t in (0..k * k).filter(|t| cover[f * k * k + t] == Cover::All) {
                let mask = FaceGrid::tile_corners(t, k).into_iter().fold(u32::MAX, |m, c| {
                    m & *inside[c].get_or_insert_with(|| {
                        let d = grid.corners[c].as_vec3();
                        // Any positive combination of the corners is as high (see `Beam::inside`).
                        if n.dot(d) > HIGH_ENOUGH { beam.inside(d) } else { 0 }
                    })
                });
                out[f * k * k + t] = mask != 0;
            }
        }
    });
    out
}

/// On the texel rows `rows` of face `f`, per front triangle of `beam` and row `j`, the run of
/// columns whose centre rays certainly meet it — by more than [`Beam::hits`] asks, so it
/// answers them `Some(true)` — and lie `HIGH_ENOUGH` (10⁻⁴) above the horizon of unit normal
/// `n`, so that they are cast through their centres from the beam's origin: `(j, run)` pairs,
/// empty runs left out (runs of one row may overlap).
pub fn certain_runs(beam: &Beam, n: Vec3, f: usize, res: usize, rows: Range<usize>) -> Vec<(usize, Range<usize>)> {
    let horizon = HalfSpace::new(f, n, HIGH_ENOUGH);
    let triangles: Vec<[HalfSpace; 3]> =
        beam.front_edge_planes().map(|p| p.map(|m| HalfSpace::new(f, m, accel::beam::MARGIN))).collect();
    let mut out = Vec::new();
    for j in rows {
        let t = cubemap::texel_center(0, j, res).y;
        // The longest |u| on the row, |s| ≤ 1.
        let row = (t, (2.0 + t * t).sqrt());
        let Some(above) = horizon.clip(row, (-1.0, 1.0)) else { continue };
        for planes in &triangles {
            let Some((lo, hi)) = planes.iter().try_fold(above, |span, h| h.clip(row, span)) else { continue };
            // Centres strictly inside (lo, hi).
            let first = (column(lo, res).floor() + 1.0).max(0.0) as usize;
            let end = column(hi, res).ceil().clamp(0.0, res as f64) as usize;
            if first < end {
                out.push((j, first..end));
            }
        }
    }
    out
}

/// The directions û with `m · û > b` (plus the single-precision rounding of that test) on the
/// rows of a face: where `m · u > b·|u|max` on the row's unnormalised `u = c + s·S + t·T`,
/// with |u|max = √(2 + t²) over the row, a half-line of s.
struct HalfSpace {
    /// m · c, m · T, 1/(m · S) (infinite when 0), b.
    mc: f64,
    mt: f64,
    inv_ms: f64,
    b: f64,
}

impl HalfSpace {
    fn new(f: usize, m: Vec3, b: f32) -> Self {
        let (c, s_axis, t_axis) = cubemap::face_basis(f);
        let m = m.as_dvec3();
        Self { mc: m.dot(c), mt: m.dot(t_axis), inv_ms: 1.0 / m.dot(s_axis), b: b as f64 + SINGLE_ROUNDING }
    }

    /// The part of the interval `(lo, hi)` of s inside the half-space on the row at `t` whose
    /// longest |u| is `longest`, if any.
    fn clip(&self, (t, longest): (f64, f64), (lo, hi): (f64, f64)) -> Option<(f64, f64)> {
        let excess = self.b * longest - (self.mc + t * self.mt);
        let (lo, hi) = match self.inv_ms {
            x if x.is_infinite() => (if excess < 0.0 { lo } else { hi }, hi),
            x if x > 0.0 => (lo.max(excess * x), hi),
            x => (lo, hi.min(excess * x)),
        };
        (lo < hi).then_some((lo, hi))
    }
}

/// The fractional column index of face coordinate s (texel i's centre is at i).
fn column(s: f64, res: usize) -> f64 {
    (s + 1.0) * res as f64 / 2.0 - 0.5
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
    use crate::bspvt::{node, visibility};

    /// The tests are conservative: no texel ray the texel test rejects, nor any in a tile the
    /// tile test leaves clean, meets the box (from the ray's offset origin, as cast), and no
    /// texel centre outside its row's columns passes the texel test; and all are tight enough
    /// to matter.
    #[test]
    fn rays_left_out_do_not_meet_the_box() {
        let points: Vec<Vec3> =
            (-3..=3).flat_map(|x| (-3..=3).map(move |z| Vec3::new(x as f32 * 0.7, 0.0, z as f32 * 0.7))).collect();
        // The last point is so close to the box that the cone test gives way to the exact one.
        let close = Vec3::new(0.1, 0.999, 0.1);
        let [clean, dirty, wanted, hits, covered, spare, rows] = check_box_tests(32, points.iter().chain([&close]));
        assert!(clean > 4 * dirty && hits > 0, "{clean} clean and {dirty} dirty texels");
        assert!(covered > 0 && covered < hits, "{covered} texels in covered tiles, {hits} hits");
        // The columns' ends are the texel centres the row's bounds allow, not a texel more.
        assert!(spare < rows / 4, "{spare} texels in the columns fail the texel test, on {rows} rows");
        assert!(wanted < dirty / 3 && wanted < hits + hits / 4, "{wanted} wanted of {dirty} dirty texels, {hits} hits");
        // Just beyond the distance where the cone test starts (its slack is widest there, ≈ 5e-3)
        // and far away (narrowest).
        let edges = [Vec3::new(0.1, 0.975, 0.1), Vec3::new(0.725, 1.05, 0.3), Vec3::new(15.0, 0.0, 6.0)];
        let [.., hits, _, _, _] = check_box_tests(64, edges.iter());
        assert!(hits > 0);
        // A resolution whose tile grid has more than 128 corners per face.
        let [_, _, _, hits, ..] = check_box_tests(136, points.iter().step_by(12));
        assert!(hits > 0);
    }

    /// Checks every texel ray of vertices at `points` (three normals each) against the box
    /// tests; returns the counts of texels in clean tiles, in dirty ones, wanted by the texel
    /// test among those, meeting the box, in covered tiles, in their row's columns though their
    /// centre fails the texel test, and the number of rows with columns.
    fn check_box_tests<'a>(res: usize, points: impl Iterator<Item = &'a Vec3>) -> [usize; 7] {
        let k = tiles_per_side(res);
        let (lo, hi) = (Vec3::new(-0.5, 1.0, -0.2), Vec3::new(0.7, 1.1, 0.4));
        let [mut clean, mut dirty, mut wanted, mut hits, mut covered, mut spare, mut rows] = [0; 7];
        for &p in points {
            for n in [Vec3::Y, Vec3::new(0.6, 0.8, 0.0), Vec3::new(0.0, 0.6, -0.8)] {
                let seen = SeenBox::new(p, n, lo, hi);
                let flags = seen.tiles(res);
                let columns: Vec<_> = (0..6).map(|f| seen.columns(f, res, 0..res)).collect();
                // Without silhouette planes every column is taken (the exact test applies).
                let planes = !seen.silhouette.is_empty();
                rows += columns.iter().flatten().filter(|c| planes && !c.is_empty()).count();
                for (f, i, j) in (0..6).flat_map(|f| (0..res * res).map(move |t| (f, t % res, t / res))) {
                    let Some(d) = visibility::texel_ray(f, i, j, n.as_dvec3(), res).map(|d| d.as_vec3()) else {
                        continue;
                    };
                    let hit = accel::ray_meets_box(accel::offset_ray_origin(p, n, d), d, lo, hi);
                    let at = || format!("res {res}, p {p}, n {n}: texel ({f}, {i}, {j})");
                    assert!(!hit || seen.meets(d), "{} meets the box, the texel test says no", at());
                    let centre = cubemap::face_to_dir(f, cubemap::texel_center(i, j, res)).as_vec3();
                    let column = columns[f][j].contains(&i);
                    assert!(column || !seen.meets(centre), "{}: meets the box outside its row's columns", at());
                    spare += (planes && column && !seen.meets(centre)) as usize;
                    match flags[f * k * k + (j / node::TILE) * k + i / node::TILE] {
                        Cover::None => {
                            clean += 1;
                            assert!(!hit, "{} in a clean tile meets the box", at());
                        }
                        cover => {
                            assert!(cover == Cover::Some || seen.meets(d), "{}: a covered tile's texel misses", at());
                            (dirty, wanted, hits) = (dirty + 1, wanted + seen.meets(d) as usize, hits + hit as usize);
                            covered += (cover == Cover::All) as usize;
                        }
                    }
                }
            }
        }
        [clean, dirty, wanted, hits, covered, spare, rows]
    }

    /// The tile test's corner masks, four planes at a time, equal the plane-by-plane ones.
    #[test]
    fn corner_masks_equal_the_scalar_ones() {
        use rand::Rng as _;
        let mut rng = crate::math::rng::seeded(5);
        let (lo, hi) = (Vec3::new(-0.5, 1.0, -0.2), Vec3::new(0.7, 1.1, 0.4));
        for p in [Vec3::ZERO, Vec3::new(2.0, 0.5, -1.0), Vec3::new(0.1, 1.05, 2.0), Vec3::new(-3.0, 4.0, 0.3)] {
            let seen = SeenBox::new(p, Vec3::Y, lo, hi);
            assert!(seen.silhouette.len() >= 4);
            for _ in 0..2000 {
                let c =
                    DVec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
                let c = c.normalize();
                let margin = rng.random_range(0.0..0.1);
                let scalar = seen.silhouette.iter().enumerate().fold((0, 0), |(beyond, inside), (b, m)| {
                    let x = m.dot(c);
                    (beyond | ((x > margin) as u16) << b, inside | ((x <= 0.0) as u16) << b)
                });
                assert_eq!(seen.corner_masks(c, margin), scalar, "p {p}, c {c}");
            }
        }
    }

    /// Rays from a vertex's offset origin aimed at the box's corners graze it: each that meets
    /// the box must pass the cone test, whose slack covers the origin's offset — checked where
    /// that matters most, just beyond the distance where the cone test starts.
    #[test]
    fn rays_grazing_the_box_from_the_offset_origin_are_taken() {
        let (lo, hi) = (Vec3::new(-0.5, 1.0, -0.2), Vec3::new(0.7, 1.1, 0.4));
        let normals = [Vec3::Y, Vec3::X, Vec3::NEG_X, Vec3::Z, Vec3::new(0.6, 0.8, 0.0), Vec3::new(0.0, 0.6, -0.8)];
        let mut grazing = 0;
        for p in [Vec3::new(0.1, 0.975, 0.1), Vec3::new(0.725, 1.05, 0.3), Vec3::new(-0.52, 0.98, -0.23)] {
            for n in normals {
                let seen = SeenBox::new(p, n, lo, hi);
                assert!(!seen.silhouette.is_empty(), "p {p}: the cone test applies");
                let origin = visibility::horizon_origin(p, n);
                for q in corners_from(DVec3::ZERO, lo.as_dvec3(), hi.as_dvec3()) {
                    let d = (q.as_vec3() - origin).normalize();
                    if n.dot(d) > 1e-3 && accel::ray_meets_box(origin, d, lo, hi) {
                        grazing += 1;
                        assert!(seen.meets(d), "p {p}, n {n}: the ray to corner {q} meets the box");
                    }
                }
            }
        }
        assert!(grazing > 30, "{grazing} grazing rays");
    }

    /// Every texel ray of a tile found blocked meets the triangles, as the BVH casts it; and
    /// tiles are found blocked.
    #[test]
    fn rays_of_blocked_tiles_are_blocked() {
        let (a, b, c, d) = (
            Vec3::new(-2.0, 1.0, -2.0),
            Vec3::new(3.0, 1.2, -2.0),
            Vec3::new(3.0, 1.0, 3.0),
            Vec3::new(-2.0, 1.3, 3.0),
        );
        let roof = vec![[a, b, c], [a, c, d]];
        let occ = accel::Occluders::new(std::slice::from_ref(&roof));
        let res = 32;
        let k = tiles_per_side(res);
        let mut found = 0;
        for (p, n) in [(Vec3::ZERO, Vec3::Y), (Vec3::new(0.5, 0.2, -0.3), Vec3::new(0.6, 0.8, 0.0))] {
            let origin = visibility::horizon_origin(p, n);
            let beam = occ.beam(0, origin).expect("two triangles make a beam");
            let cover = SeenBox::new(p, n, Vec3::new(-2.0, 1.0, -2.0), Vec3::new(3.0, 1.3, 3.0)).tiles(res);
            let blocked = blocked_tiles(&beam, &cover, n, res);
            for t in (0..6 * k * k).filter(|&t| blocked[t]) {
                found += 1;
                let (f, ti, tj) = (t / (k * k), t % k, t / k % k);
                for (i, j) in (0..node::TILE)
                    .flat_map(|j| (0..node::TILE).map(move |i| (ti * node::TILE + i, tj * node::TILE + j)))
                {
                    let d = visibility::texel_ray(f, i, j, n.as_dvec3(), res).expect("above the horizon").as_vec3();
                    assert!(
                        occ.occluded(accel::offset_ray_origin(p, n, d), d, f32::INFINITY),
                        "p {p}: texel ({f}, {i}, {j})"
                    );
                }
            }
        }
        assert!(found > 20, "{found} blocked tiles");
    }

    /// Every texel of a certain run is answered `Some(true)` by the beam, through its centre,
    /// from the beam's origin; and the runs hold most of the texels the beam answers so.
    #[test]
    fn certain_runs_are_certain_hits() {
        let slab = crate::scene::shapes::cuboid(Vec3::new(1.5, 0.1, 0.5));
        let at = |v: u32| slab.positions[v as usize] + Vec3::new(0.3, 1.2, -0.2);
        let triangles: Vec<[Vec3; 3]> = slab.triangles.iter().map(|t| t.map(at)).collect();
        let occ = accel::Occluders::new(&[triangles]);
        let (mut in_runs, mut answered) = (0, 0);
        for res in [64, 20] {
            for (p, n) in [
                (Vec3::ZERO, Vec3::Y),
                (Vec3::new(2.5, 0.0, 1.0), Vec3::Y),
                (Vec3::new(-0.4, 0.3, 0.2), Vec3::new(0.6, 0.8, 0.0)),
                (Vec3::new(0.3, 2.0, -0.2), Vec3::NEG_Y),
            ] {
                let origin = visibility::horizon_origin(p, n);
                let beam = occ.beam(0, origin).expect("a box makes a beam");
                for f in 0..6 {
                    let runs = certain_runs(&beam, n, f, res, 0..res);
                    let in_run = |i: usize, j: usize| runs.iter().any(|(row, run)| *row == j && run.contains(&i));
                    for (j, i) in (0..res).flat_map(|j| (0..res).map(move |i| (j, i))) {
                        let centre = cubemap::face_to_dir(f, cubemap::texel_center(i, j, res));
                        let ray = visibility::texel_ray(f, i, j, n.as_dvec3(), res);
                        let d = centre.as_vec3();
                        let certain = beam.hits(d) == Some(true) && n.dot(d) > HIGH_ENOUGH;
                        answered += certain as usize;
                        if in_run(i, j) {
                            in_runs += 1;
                            let at = format!("res {res}, p {p}, n {n}: texel ({f}, {i}, {j})");
                            assert!(certain && ray == Some(centre), "{at}");
                            assert_eq!(visibility::ray_origin(origin, p, n, d), origin, "{at}");
                        }
                    }
                }
            }
        }
        assert!(in_runs * 10 > answered * 8, "{in_runs} texels in runs of {answered} certain hits");
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
