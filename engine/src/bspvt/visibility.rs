//! Per-vertex visibility cube maps, ray-cast with the BVH. Texels entirely below the vertex's
//! horizon are never cast: LTC clips there, so their visibility cannot matter.

use super::depth;
use super::grid;
use super::node::TILE;
use super::reach::Reach;
use crate::accel::{Frustum, Occluders, offset_ray_origin};
use crate::math::cubemap;
use glam::{DVec3, Vec3};

pub use kage_runtime::bspvt::cube::{BELOW, CubeVisibility, OCCLUDED, SKIPPED, VISIBLE};

/// Casts the visibility cube map of a vertex at `p` with unit normal `n` against `occluders`.
/// A texel is below the horizon only when all four of its corners are; a texel the horizon
/// crosses is cast just above the horizon, so that grazing lights are not cut off by half a
/// texel.
pub fn cast(occluders: &Occluders, p: Vec3, n: Vec3, res: usize) -> CubeVisibility {
    let view = hemisphere(occluders, p, n, res);
    let tiles: Vec<Vec<TileBits>> = (0..cubemap::FACES)
        .map(|f| cast_face_tiles(occluders, &view, (p, n), f, res, (None, &Reach::ANYWHERE)))
        .collect();
    let texels = tiles.iter().flat_map(|t| TileBits::to_face(t, res)).collect();
    CubeVisibility { res, texels, hits: Vec::new() }
}

/// [`cast`] with every occluded texel's first hit, for exact visibility with depth.
pub fn cast_with_hits(occluders: &Occluders, p: Vec3, n: Vec3, res: usize) -> CubeVisibility {
    let mut cube = cast(occluders, p, n, res);
    let view = hemisphere(occluders, p, n, res);
    let k = res.div_ceil(TILE);
    cube.hits = vec![None; cube.texels.len()];
    for f in 0..cubemap::FACES {
        let tiles = TileBits::from_face(cube.face(f), res);
        let occluded: Vec<u64> = tiles.iter().map(|t| t.live & !t.visible & !t.skipped).collect();
        for (t, hits) in
            first_hits(occluders, (&view, p, n), f, res, (&occluded, &Reach::ANYWHERE)).into_iter().enumerate()
        {
            for (b, hit) in hits.into_iter().enumerate().filter(|(_, h)| h.is_some()) {
                let (i, j) = ((t % k) * TILE + b % TILE, (t / k) * TILE + b / TILE);
                cube.hits[(f * res + j) * res + i] = hit;
            }
        }
    }
    cube
}

/// The `res²` texel states of face `f` alone (see [`cast`]).
pub fn cast_face(occluders: &Occluders, p: Vec3, n: Vec3, f: usize, res: usize) -> Vec<u8> {
    let view = hemisphere(occluders, p, n, res);
    TileBits::to_face(&cast_face_tiles(occluders, &view, (p, n), f, res, (None, &Reach::ANYWHERE)), res)
}

/// The pieces of `occluders` that rays from a vertex at `p` (unit normal `n`) into the
/// hemisphere above its horizon may meet, from [`horizon_origin`], for [`cast_face_tiles`].
pub fn hemisphere(occluders: &Occluders, p: Vec3, n: Vec3, res: usize) -> Frustum {
    occluders.view(horizon_origin(p, n), &[n], lifted(res))
}

/// How far outside its tile's pyramid a ray through a texel the horizon crosses may go (`m · d
/// ≥ −lifted` for each side's inward unit normal `m`: about three texels): rays lifted above
/// the horizon lie within about a texel of their texel (checked ray by ray).
fn lifted(res: usize) -> f32 {
    6.0 / res as f32
}

/// [`cast_face`] as tiles: every texel above the horizon cast, except in the tiles `reached`
/// marks `false` (see [`super::reach`]), which are left as if below the horizon; each ray
/// looks for occluders up to where `reach` ends it ([`Reach::ray_end`]). `hemisphere` is the
/// vertex's [`hemisphere`].
pub fn cast_face_tiles(
    occluders: &Occluders,
    hemisphere: &Frustum,
    (p, n): (Vec3, Vec3),
    f: usize,
    res: usize,
    (reached, reach): (Option<&[bool]>, &Reach),
) -> Vec<TileBits> {
    let looks: Vec<Look> = (0..res.div_ceil(TILE).pow(2))
        .map(|t| if reached.is_none_or(|r| r[t]) { Look::Cast } else { Look::Unreached })
        .collect();
    let every = |_| Ask { ask: u64::MAX, occluded: 0 };
    let horizon = Horizon::new(n, f, res);
    if horizon.below() {
        return vec![TileBits::default(); res.div_ceil(TILE).pow(2)];
    }
    let mut pyramids = Pyramids::new(hemisphere, (p, n), f, res);
    cast_tiles(&horizon, &looks, every, |t, _, d, centred| {
        let o = ray_origin(pyramids.above, p, n, d);
        let end = reach.ray_end(o, d);
        match pyramids.among(t, o, d, centred) {
            Some(among) if occluders.occluded_among(among, d, end) => OCCLUDED,
            Some(_) => VISIBLE,
            None => cast_ray(occluders, o, d, end),
        }
    })
}

/// The pieces the rays through one face of a vertex's cube map may meet, narrowed tile by tile
/// from its [`hemisphere`]: a ray from the horizon origin whose direction lies inside its
/// tile's pyramid asks only its tile's list. A tile's texel centres lie inside its pyramid;
/// where some are below the horizon, rays lifted above it lie within about a texel of it,
/// inside the pyramids widened by [`lifted`] (checked ray by ray).
struct Pyramids {
    /// Where the rays above the horizon start ([`horizon_origin`]).
    above: Vec3,
    f: usize,
    res: usize,
    /// The face's pyramid's sides and the pieces it may meet.
    face: ([Vec3; 4], Frustum),
    /// The last tile asked for: its index, the slack its pieces were listed with, its pieces
    /// and its sides.
    tile: Option<(usize, f32, Frustum, [Vec3; 4])>,
}

impl Pyramids {
    /// Face `f` (at resolution `res`) of the vertex at `p` (unit normal `n`) whose
    /// [`hemisphere`] is `hemisphere`.
    fn new(hemisphere: &Frustum, (p, n): (Vec3, Vec3), f: usize, res: usize) -> Self {
        let k = res.div_ceil(TILE);
        let sides = grid::with_grids(res, |g| g[f].block_sides(0..k, 0..k, k)).map(|m| m.as_vec3());
        Self { above: horizon_origin(p, n), f, res, face: (sides, hemisphere.narrow(&sides, lifted(res))), tile: None }
    }

    /// The pieces a ray from `o` along `d` through a texel of tile `t` may meet, when it
    /// starts at the horizon origin and lies inside the tile's pyramid (`centred`: `d` is the
    /// texel centre's); `None` when it must ask every piece.
    fn among(&mut self, t: usize, o: Vec3, d: Vec3, centred: bool) -> Option<&Frustum> {
        let (res, k) = (self.res, self.res.div_ceil(TILE));
        let slack = if centred { 0.0 } else { lifted(res) };
        // A list narrowed for centred rays would miss what a lifted ray may meet: a lifted ray
        // widens its tile's list.
        if self.tile.as_ref().is_none_or(|s| s.0 != t || s.1 < slack) {
            let f = self.f;
            let sides = grid::with_grids(res, |g| g[f].block_sides(t % k..t % k + 1, t / k..t / k + 1, k));
            let sides = sides.map(|m| m.as_vec3());
            self.tile = Some((t, slack, self.face.1.narrow(&sides, slack), sides));
        }
        let (_, _, view, sides) = self.tile.as_ref().expect("set above");
        let within = |planes: &[Vec3]| planes.iter().all(|m| m.dot(d) >= -slack);
        (o == self.above && (centred || within(sides) && within(&self.face.0))).then_some(view)
    }
}

/// Each tile's depth subtree ([`depth::encode_tile`]) of face `f` for a vertex at `p` (unit
/// normal `n`, [`hemisphere`] `hemisphere`) from its `occluded` texels' first hits, rays as the
/// coverage cast them, ending where `reach` ends them; `None` for tiles with no occluded texel.
pub fn cast_depth(
    occluders: &Occluders,
    (hemisphere, p, n): (&Frustum, Vec3, Vec3),
    f: usize,
    res: usize,
    (occluded, reach): (&[u64], &Reach),
) -> Vec<Option<Vec<u8>>> {
    let k = res.div_ceil(TILE);
    let hits = first_hits(occluders, (hemisphere, p, n), f, res, (occluded, reach));
    hits.iter().enumerate().map(|(t, h)| depth::encode_tile(h, tile_size(t, k, res))).collect()
}

/// The texel width and height of tile `t` (`k` per side) at face resolution `res`.
fn tile_size(t: usize, k: usize, res: usize) -> (usize, usize) {
    let (i0, j0) = ((t % k) * TILE, (t / k) * TILE);
    ((i0 + TILE).min(res) - i0, (j0 + TILE).min(res) - j0)
}

/// Per tile of face `f` (row-major), the first hits of the `occluded` texels (masks as in
/// [`TileBits`], bits as their index) of a vertex at `p` (unit normal `n`, [`hemisphere`]
/// `hemisphere`), rays as the coverage cast them, ending where `reach` ends them.
pub fn first_hits(
    occluders: &Occluders,
    (hemisphere, p, n): (&Frustum, Vec3, Vec3),
    f: usize,
    res: usize,
    (occluded, reach): (&[u64], &Reach),
) -> Vec<[Option<depth::Hit>; TILE * TILE]> {
    let mut hits = vec![[None; TILE * TILE]; occluded.len()];
    let looks: Vec<Look> = occluded.iter().map(|&m| if m != 0 { Look::Cast } else { Look::Unreached }).collect();
    let asks = |t: usize| Ask { ask: occluded[t], occluded: 0 };
    let mut pyramids = Pyramids::new(hemisphere, (p, n), f, res);
    cast_tiles(&Horizon::new(n, f, res), &looks, asks, |t, bit, d, centred| {
        if occluded[t] & bit != 0 {
            let o = ray_origin(pyramids.above, p, n, d);
            let end = reach.ray_end(o, d);
            let met = match pyramids.among(t, o, d, centred) {
                Some(among) => occluders.closest_among(among, d, end),
                None => occluders.closest(o, d, end),
            };
            hits[t][bit.trailing_zeros() as usize] = Some(first_hit(met, (o, d), p));
        }
        SKIPPED
    });
    hits
}

/// The first hit `met` of the ray from `o` along `d`, relative to the vertex at `p`; a ray the
/// coverage found blocked but no closest hit confirms (rounding at a grazing edge) is met at
/// its start, so that nothing shows in front of it.
fn first_hit(met: Option<crate::accel::PlaneHit>, (o, d): (Vec3, Vec3), p: Vec3) -> depth::Hit {
    let met = met.unwrap_or(crate::accel::PlaneHit { t: 0.0, normal: d, corner: o });
    depth::Hit::new(o + d * met.t - p, met.normal, met.corner - p)
}

/// The direction cast for texel (i, j) of face `f` above the horizon of unit normal `nd`:
/// its centre, or for a texel the horizon crosses the centre's projection onto the horizon
/// lifted slightly above it; `None` when the texel is entirely below the horizon.
pub fn texel_ray(f: usize, i: usize, j: usize, nd: DVec3, res: usize) -> Option<DVec3> {
    ray_through(centre(f, i, j, res), f, i, j, nd, res)
}

/// The unit direction through the centre of texel (i, j) of face `f`.
fn centre(f: usize, i: usize, j: usize, res: usize) -> DVec3 {
    cubemap::face_to_dir(f, cubemap::texel_center(i, j, res))
}

/// [`texel_ray`] given the texel's unit centre direction.
fn ray_through(centre: DVec3, f: usize, i: usize, j: usize, nd: DVec3, res: usize) -> Option<DVec3> {
    let edge = |k: usize| 2.0 * k as f64 / res as f64 - 1.0;
    let height = centre.dot(nd);
    // A texel spans less than 2/res radians: only those near the horizon need corners.
    let crossed = || {
        [(i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1)]
            .iter()
            .any(|&(a, b)| cubemap::face_to_dir(f, glam::DVec2::new(edge(a), edge(b))).dot(nd) > 0.0)
    };
    if height <= -2.0 / res as f64 || (height <= 0.0 && !crossed()) {
        None
    } else if height > 0.0 {
        Some(centre)
    } else {
        Some(((centre - nd * centre.dot(nd)).normalize_or(centre) + nd * 1e-3).normalize())
    }
}

/// The texel states of one [`TILE`]×[`TILE`] tile as bit masks: bit `(j mod TILE)·TILE +
/// i mod TILE` is texel (i, j).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TileBits {
    /// Above the horizon (cast or not).
    pub live: u64,
    /// Cast and visible.
    pub visible: u64,
    /// Above the horizon and not cast ([`SKIPPED`]).
    pub skipped: u64,
}

impl TileBits {
    /// The tiles (row-major) of a face's `res²` texel states.
    pub fn from_face(face: &[u8], res: usize) -> Vec<TileBits> {
        let k = res.div_ceil(TILE);
        let mut tiles = vec![TileBits::default(); k * k];
        for (x, &state) in face.iter().enumerate() {
            let (t, bit) = tile_bit(x % res, x / res, k);
            let t = &mut tiles[t];
            t.live |= if state == BELOW { 0 } else { bit };
            t.visible |= if state == VISIBLE { bit } else { 0 };
            t.skipped |= if state == SKIPPED { bit } else { 0 };
        }
        tiles
    }

    /// The face's `res²` texel states (the inverse of [`Self::from_face`]).
    pub fn to_face(tiles: &[TileBits], res: usize) -> Vec<u8> {
        let k = res.div_ceil(TILE);
        (0..res * res)
            .map(|x| {
                let (t, bit) = tile_bit(x % res, x / res, k);
                match tiles[t] {
                    t if t.live & bit == 0 => BELOW,
                    t if t.skipped & bit != 0 => SKIPPED,
                    t if t.visible & bit != 0 => VISIBLE,
                    _ => OCCLUDED,
                }
            })
            .collect()
    }
}

/// Texel (i, j)'s tile index (`k` tiles per side) and bit in its tile's masks.
fn tile_bit(i: usize, j: usize, k: usize) -> (usize, u64) {
    ((j / TILE) * k + i / TILE, 1u64 << ((j % TILE) * TILE + i % TILE))
}

/// Which tiles of face `f` (row-major) have a texel above the horizon of unit normal `n` (see
/// [`Horizon::live`]).
pub fn live_tiles(n: Vec3, f: usize, res: usize) -> Vec<bool> {
    Horizon::new(n, f, res).live()
}

/// Face `f` of a vertex's visibility cube map at resolution `res`, with the heights above the
/// horizon of its unit normal `n` of the face's tile-grid corners (see [`grid`]).
pub struct Horizon {
    n: Vec3,
    f: usize,
    res: usize,
    /// Tiles per side.
    k: usize,
    /// (k + 1)² heights, row-major.
    heights: Vec<f64>,
}

impl Horizon {
    /// Face `f` at resolution `res` of a vertex with unit normal `n`.
    pub fn new(n: Vec3, f: usize, res: usize) -> Self {
        let nd = n.as_dvec3();
        let heights = grid::with_grids(res, |grids| grids[f].corners.iter().map(|c| c.dot(nd)).collect());
        Self { n, f, res, k: res.div_ceil(TILE), heights }
    }

    /// Which tiles (row-major) have a texel above the horizon: those with a corner above it
    /// (the height's sign is affine over a face, so a tile's highest point is a corner, and a
    /// texel with a corner above the horizon is cast; see [`texel_ray`]).
    pub fn live(&self) -> Vec<bool> {
        (0..self.k * self.k).map(|t| self.corners(t).iter().any(|&h| h > 0.0)).collect()
    }

    /// Whether the whole face is below the horizon: its four corners are (with a margin for
    /// rounding there).
    fn below(&self) -> bool {
        let k = self.k;
        [0, k, k * (k + 1), (k + 1) * (k + 1) - 1].iter().all(|&c| self.heights[c] < -1e-9)
    }

    /// Tile `t`'s corner heights.
    fn corners(&self, t: usize) -> [f64; 4] {
        grid::FaceGrid::tile_corners(t, self.k).map(|c| self.heights[c])
    }
}

/// The bits of every texel of tile `t` (`k` tiles per side) at face resolution `res`.
fn tile_mask(t: usize, k: usize, res: usize) -> u64 {
    let (i0, j0) = ((t % k) * TILE, (t / k) * TILE);
    let (w, h) = ((i0 + TILE).min(res) - i0, (j0 + TILE).min(res) - j0);
    let row = u64::MAX >> (64 - w);
    (0..h).fold(0, |m, j| m | row << (j * TILE))
}

/// The tiles of a vertex's `face`, asking `texel` for the state of each texel above the
/// horizon, tile by tile as `tiles` says (see [`Look`]; row-major,
/// [`TILE`]-texel tiles, the last ones narrower when `res` is not a multiple):
/// `texel(tile, bit, direction, centred)` returns [`VISIBLE`], [`OCCLUDED`] or [`SKIPPED`]
/// (`centred`: the direction is the texel centre's, not lifted above the horizon). A tile kept
/// is not looked at texel by texel: when it is live (see [`live_tiles`]) all of it is
/// `SKIPPED`. Of a cast tile, the texels `asks(tile).occluded` are `OCCLUDED` without asking;
/// in a tile whose texel centres are all above the horizon only the others in
/// `asks(tile).ask` are asked, the rest are `SKIPPED` too.
pub fn cast_tiles(
    face: &Horizon,
    tiles: &[Look],
    asks: impl Fn(usize) -> Ask,
    mut texel: impl FnMut(usize, u64, Vec3, bool) -> u8,
) -> Vec<TileBits> {
    let (f, res, k) = (face.f, face.res, face.k);
    let nd = face.n.as_dvec3();
    let mut out = vec![TileBits::default(); k * k];
    if face.below() {
        return out;
    }
    CENTRES.with_borrow_mut(|(at, centres)| {
        if *at != res {
            *at = res;
            *centres = (0..cubemap::FACES * res * res)
                .map(|k| centre(k / (res * res), k % res, k / res % res, res).as_vec3())
                .collect();
        }
        for (t, bits) in out.iter_mut().enumerate() {
            let (i0, j0) = ((t % k) * TILE, (t / k) * TILE);
            let (i1, j1) = ((i0 + TILE).min(res), (j0 + TILE).min(res));
            let all = tile_mask(t, k, res);
            match tiles[t] {
                Look::Keep if face.corners(t).iter().any(|&h| h > 0.0) => {
                    *bits = TileBits { live: all, visible: 0, skipped: all };
                    continue;
                }
                Look::Keep | Look::Unreached => continue,
                // Every corner below the horizon (with a margin for rounding): so is every
                // texel corner (the height's sign is affine over the face), and no texel is
                // cast ([`texel_ray`]) — without asking each.
                Look::Cast | Look::Blocked if face.corners(t).iter().all(|&h| h < -1e-9) => continue,
                Look::Cast | Look::Blocked => {}
            }
            // Every texel centre above the horizon (the lowest is a corner texel's: height is
            // affine over a face): every texel is cast through its centre, and only the asked
            // columns need looking at. Tiles on the horizon line of a vertex whose normal is
            // a face axis qualify, though their corners are on it.
            let centre_height = |i: usize, j: usize| centre(f, i, j, res).dot(nd);
            let above = [(i0, j0), (i1 - 1, j0), (i0, j1 - 1), (i1 - 1, j1 - 1)]
                .iter()
                .all(|&(i, j)| centre_height(i, j) > 1e-9);
            if tiles[t] == Look::Blocked && above {
                *bits = TileBits { live: all, visible: 0, skipped: 0 };
                continue;
            }
            let Ask { ask, occluded } = asks(t);
            // Occluded: live, neither visible nor skipped.
            let known = occluded & all;
            let mut asked = known;
            let mut ask = if above { ask } else { all } & all & !known;
            while ask != 0 {
                let b = ask.trailing_zeros() as usize;
                ask &= ask - 1;
                let (i, j) = (i0 + b % TILE, j0 + b / TILE);
                let d = if above {
                    centres[(f * res + j) * res + i]
                } else {
                    let Some(d) = ray_through(centre(f, i, j, res), f, i, j, nd, res) else { continue };
                    d.as_vec3()
                };
                let bit = 1u64 << b;
                asked |= bit;
                // Without branches: the outcome is data, and mispredicting it cost more than
                // the masks.
                let state = texel(t, bit, d, above);
                bits.visible |= bit & 0u64.wrapping_sub((state == VISIBLE) as u64);
                bits.skipped |= bit & 0u64.wrapping_sub((state == SKIPPED) as u64);
            }
            if above {
                bits.live = all;
                bits.skipped |= all & !asked;
            } else {
                bits.live = asked;
            }
        }
    });
    out
}

/// What [`cast_tiles`] does with a cast tile's texels (masks as in [`TileBits`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ask {
    /// The texels to ask for, when every texel centre of the tile is above the horizon (else
    /// all are asked).
    pub ask: u64,
    /// Texels known `OCCLUDED` without asking; their centres must be above the horizon.
    pub occluded: u64,
}

/// Per tile of a face at resolution `res` (row-major), the mask (as in [`TileBits`]) of the
/// texels (i, j) of the `(j, columns)` runs.
pub fn tile_masks(res: usize, runs: impl IntoIterator<Item = (usize, std::ops::Range<usize>)>) -> Vec<u64> {
    let k = res.div_ceil(TILE);
    let mut out = vec![0; k * k];
    for (j, c) in runs {
        let (start, end) = (c.start, c.end.min(res));
        if start >= end {
            continue;
        }
        for ti in start / TILE..end.div_ceil(TILE) {
            let i0 = ti * TILE;
            let (lo, hi) = (start.max(i0) - i0, end.min(i0 + TILE) - i0);
            let row = (u64::MAX >> (64 - (hi - lo))) << lo;
            out[j / TILE * k + ti] |= row << (j % TILE * TILE);
        }
    }
    out
}

/// How [`cast_tiles`] treats a tile.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Look {
    /// Not looked at: its texels above the horizon are `SKIPPED`.
    Keep,
    /// Its texels above the horizon are asked for.
    Cast,
    /// Every ray through it is known to be blocked: all `OCCLUDED` when its texel centres are
    /// all above the horizon (the texel rays through them stay inside it), else as `Cast` (rays
    /// lifted above the horizon may leave it).
    Blocked,
    /// No light can be seen through it (see [`super::reach`]): left as if below the horizon, so
    /// that the tree spends no node on it (its neighbours' leaves cover it).
    Unreached,
}

/// Whether the ray from `origin` (see [`ray_origin`]) in direction `d` meets no occluder
/// before `end` (infinite: reaches the sky).
pub fn cast_ray(occluders: &Occluders, origin: Vec3, d: Vec3, end: f32) -> u8 {
    if occluders.occluded(origin, d, end) { OCCLUDED } else { VISIBLE }
}

/// Where every ray from a vertex at `p` (unit normal `n`) into the hemisphere above its
/// horizon starts: [`offset_ray_origin`] depends on the direction only through that side.
pub fn horizon_origin(p: Vec3, n: Vec3) -> Vec3 {
    offset_ray_origin(p, n, n)
}

/// The origin of the ray from `p` (unit normal `n`) in direction `d`, given `above` =
/// [`horizon_origin`]: the same as [`offset_ray_origin`], without its cost above the horizon.
pub fn ray_origin(above: Vec3, p: Vec3, n: Vec3, d: Vec3) -> Vec3 {
    if n.dot(d) < 0.0 { offset_ray_origin(p, n, d) } else { above }
}

thread_local! {
    /// Unit centre directions of every texel (face-major) at the last resolution this thread
    /// cast, rounded to single precision as the rays take them (half the memory, so fewer
    /// cache misses): normalising them per cast was a fifth of a bake. Per thread rather than one lazily
    /// built shared table, because a rayon worker blocked in a shared initialiser can deadlock.
    static CENTRES: std::cell::RefCell<(usize, Vec<Vec3>)> = const { std::cell::RefCell::new((0, Vec::new())) };
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A kept tile is all `SKIPPED` exactly when the full cast has a texel of it above the
    /// horizon (else all `BELOW`, and [`live_tiles`] agrees); a cast one has the states `texel`
    /// gives, which it is asked for exactly above the horizon, except the known occluded ones;
    /// a blocked one entirely above the horizon is all `OCCLUDED`, else as if cast.
    #[test]
    fn selected_casts_agree_with_the_full_cast() {
        let roof = [Vec3::new(-2.0, 1.0, -2.0), Vec3::new(2.0, 1.0, -2.0), Vec3::new(0.0, 1.0, 2.0)];
        let occ = Occluders::new(&[vec![roof]]);
        // 20: the last tile of a face is narrower; 16: the horizon of +Y runs along tile edges.
        let cases = [20, 16].into_iter().flat_map(|res: usize| {
            [Vec3::Y, Vec3::new(0.6, 0.0, 0.8), Vec3::new(-0.3, -0.9, 0.3).normalize()].map(|n| (res, n))
        });
        for (res, n) in cases {
            let k = res.div_ceil(TILE);
            let flags: Vec<Look> = (0..k * k).map(|t| [Look::Keep, Look::Cast, Look::Blocked][t % 3]).collect();
            for f in 0..cubemap::FACES {
                let full = cast_face(&occ, Vec3::ZERO, n, f, res);
                let live = live_tiles(n, f, res);
                let texel = |_, _, d: Vec3, _| {
                    if d.x > 0.0 {
                        cast_ray(&occ, offset_ray_origin(Vec3::ZERO, n, d), d, f32::INFINITY)
                    } else {
                        SKIPPED
                    }
                };
                let height =
                    |i: usize, j: usize| cubemap::face_to_dir(f, cubemap::texel_center(i, j, res)).dot(n.as_dvec3());
                // Rows ask for columns [j mod 5, j mod 5 + 9): most tiles are cut by it. Columns
                // [j mod 4, j mod 4 + 3) are known occluded where their centres are above the
                // horizon, as the contract asks.
                let occluded = |j: usize| {
                    let run = j % 4..(j % 4 + 3).min(res);
                    if run.clone().all(|i| height(i, j) > 0.0) { run } else { 0..0 }
                };
                let ask = tile_masks(res, (0..res).map(|j| (j, j % 5..j % 5 + 9)));
                let known = tile_masks(res, (0..res).map(|j| (j, occluded(j))));
                let columns = |t: usize| Ask { ask: ask[t], occluded: known[t] };
                let some = TileBits::to_face(&cast_tiles(&Horizon::new(n, f, res), &flags, columns, texel), res);
                for (x, (&a, &b)) in full.iter().zip(&some).enumerate() {
                    let (i, j) = (x % res, x / res);
                    let tile = (j / TILE) * k + i / TILE;
                    let in_live_tile =
                        (0..res * res).any(|y| tile_bit(y % res, y / res, k).0 == tile && full[y] != BELOW);
                    assert_eq!(live[tile], in_live_tile, "n {n}, face {f}, tile {tile}");
                    // Every texel centre of the tile above the horizon.
                    let (i0, j0) = (i / TILE * TILE, j / TILE * TILE);
                    let above = (j0..(j0 + TILE).min(res))
                        .flat_map(|b| (i0..(i0 + TILE).min(res)).map(move |a| (a, b)))
                        .all(|(a, b)| height(a, b) > 1e-9);
                    let known = flags[tile] != Look::Keep && occluded(j).contains(&i);
                    let expected = if (flags[tile] == Look::Blocked && above) || known {
                        OCCLUDED
                    } else if flags[tile] != Look::Keep {
                        let d = texel_ray(f, i, j, n.as_dvec3(), res).map(|d| d.as_vec3());
                        let asked = !above || (j % 5..j % 5 + 9).contains(&i);
                        if d.is_none_or(|d| d.x > 0.0 && asked) { a } else { SKIPPED }
                    } else if in_live_tile {
                        SKIPPED
                    } else {
                        BELOW
                    };
                    assert_eq!(b, expected, "n {n}, face {f}, texel ({i}, {j})");
                }
            }
        }
    }

    /// The shared origin above the horizon is the per-ray offset origin, on both sides.
    #[test]
    fn ray_origin_is_the_offset_origin() {
        let mut r = crate::math::rng::seeded(5);
        for _ in 0..2000 {
            use rand::Rng;
            let mut v = || Vec3::new(r.random_range(-1.0..1.0), r.random_range(-1.0..1.0), r.random_range(-1.0..1.0));
            let (p, n, d) = (v() * 100.0, v().normalize(), v().normalize());
            assert_eq!(ray_origin(horizon_origin(p, n), p, n, d), offset_ray_origin(p, n, d), "p {p}, n {n}, d {d}");
        }
    }

    /// Asking each tile's rays only what its pyramid sees (the vertex's [`hemisphere`] cut to a
    /// face, then to the tile: [`crate::accel::Frustum::narrow`]) changes no texel: over a
    /// terrain of several pieces with stones on it, from vertices on the ground and on slopes
    /// (tiles the horizon crosses included), at a power-of-two resolution and one whose last
    /// tiles are narrower, every texel equals the ray cast against everything.
    #[test]
    fn asking_what_a_tile_sees_changes_no_texel() {
        use rand::Rng;
        let mut r = crate::math::rng::seeded(9);
        let n = 70;
        let height = |x: f32, z: f32| 0.4 * (0.5 * x).sin() * (0.3 * z).cos();
        let ground = crate::accel::grid_triangles(n, |i, j| {
            let (x, z) = (-10.0 + 20.0 * i as f32 / n as f32, -10.0 + 20.0 * j as f32 / n as f32);
            Vec3::new(x, height(x, z), z)
        });
        let mut parts: Vec<Vec<[Vec3; 3]>> = (0..80)
            .map(|_| {
                let (x, z) = (r.random_range(-9.0..9.0), r.random_range(-9.0..9.0));
                let c = Vec3::new(x, height(x, z), z);
                let s = r.random_range(0.2..0.8);
                vec![
                    [c, c + Vec3::new(s, s, 0.0), c + Vec3::new(0.0, 2.0 * s, s)],
                    [c, c + Vec3::new(-s, s, s), c + Vec3::Y * s],
                ]
            })
            .collect();
        parts.push(ground);
        let occ = Occluders::new(&parts);
        let (mut blocked, mut cast) = (0, 0);
        for res in [16usize, 20] {
            for _ in 0..12 {
                let (x, z) = (r.random_range(-8.0..8.0), r.random_range(-8.0..8.0));
                let at = Vec3::new(x, height(x, z), z);
                let n = Vec3::new(r.random_range(-0.5..0.5), 1.0, r.random_range(-0.5..0.5)).normalize();
                let above = horizon_origin(at, n);
                for f in 0..cubemap::FACES {
                    let every = |_| Ask { ask: u64::MAX, occluded: 0 };
                    let looks = vec![Look::Cast; res.div_ceil(TILE).pow(2)];
                    let full = cast_tiles(&Horizon::new(n, f, res), &looks, every, |_, _, d, _| {
                        cast_ray(&occ, ray_origin(above, at, n, d), d, f32::INFINITY)
                    });
                    let full = TileBits::to_face(&full, res);
                    assert_eq!(cast_face(&occ, at, n, f, res), full, "res {res}, vertex {at}, normal {n}, face {f}");
                    blocked += full.iter().filter(|&&s| s == OCCLUDED).count();
                    cast += full.iter().filter(|&&s| s != BELOW).count();
                }
            }
        }
        assert!(blocked > cast / 20 && blocked < cast / 2, "{blocked} of {cast} texels blocked");
    }

    /// A tile mask holds exactly the texels of the rows' column ranges inside the tile.
    #[test]
    fn tile_masks_hold_the_texels_of_the_ranges() {
        let res = 20;
        let rows = 3..17;
        let columns: Vec<std::ops::Range<usize>> = rows.clone().map(|j| j % 7..j * 3 % 23).collect();
        let masks = tile_masks(res, rows.clone().zip(columns.iter().cloned()));
        for (i, j) in (0..res * res).map(|x| (x % res, x / res)) {
            let (t, bit) = tile_bit(i, j, res.div_ceil(TILE));
            let inside = rows.contains(&j) && columns[j - rows.start].contains(&i);
            assert_eq!(masks[t] & bit != 0, inside, "texel ({i}, {j})");
        }
    }

    /// Tile bits and texel states convert both ways without loss.
    #[test]
    fn tile_bits_round_trip_texel_states() {
        let res = 20;
        let face: Vec<u8> = (0..res * res).map(|x| [OCCLUDED, VISIBLE, BELOW, SKIPPED][(x * 7 + x / 3) % 4]).collect();
        assert_eq!(TileBits::to_face(&TileBits::from_face(&face, res), res), face);
    }
}
