//! An occluder group's silhouette seen along a region direction `w`, on the plane perpendicular
//! to `w` through its bounding sphere, with a summed-area table so that every receiver filters
//! it with its own box width `s = √Ω · R` (√Ω is the region's angular width; Soler & Sillion's convolution, two 1D passes in one
//! table), and the occluder's far depth per texel for receivers inside its bounding slab.
//!
//! `R` is the distance from the receiver to the plane that touches the occluder's bounding
//! sphere on the receiver's side, measured per receiver point (the paper measures it from the
//! receiving group's centre; per point is the same at the centre and stays right for large
//! receivers such as a ground plane). **`R ≤ 0`** — the point lies inside the occluder's
//! bounding slab (touching or nested groups) — gives a hard shadow with a depth test: occluded
//! when the silhouette covers the point's texel and some of the occluder lies beyond the point
//! along `w`. At `R → 0⁺` the box shrinks to one texel, so the two cases meet continuously.

use crate::math::frame::Frame;
use glam::{Vec2, Vec3};
use wide::f32x8;

/// Where a list of triangles is open (cut out by a mask): the silhouette leaves those texels
/// uncovered, as rays pass there.
pub trait Openings: Sync {
    /// Whether triangle `t` has openings at all (most are solid: one branch).
    fn cuts(&self, t: usize) -> bool;
    /// Whether triangle `t` is open at barycentrics `b` = (b1, b2) of its corners.
    fn open(&self, t: usize, b: Vec2) -> bool;
}

/// Triangles without openings.
pub struct Solid;

impl Openings for Solid {
    fn cuts(&self, _: usize) -> bool {
        false
    }

    fn open(&self, _: usize, _: Vec2) -> bool {
        false
    }
}

/// A silhouette's lookup parameters (see [`Silhouette::params`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Params {
    /// The region direction the silhouette is seen along.
    pub w: Vec3,
    /// Texel-space u axis (world units × texels per unit).
    pub u_axis: Vec3,
    /// Texel-space v axis.
    pub v_axis: Vec3,
    /// Texel-space offset.
    pub offset: Vec2,
    /// Depth of the plane touching the bounding sphere on the receivers' side.
    pub plane: f32,
    /// Texels per world unit.
    pub texels_per_unit: f32,
    /// Texels per side.
    pub res: u32,
    /// Texel-space bounds of the covered texels.
    pub covered: (Vec2, Vec2),
}

/// A rasterised silhouette with its summed-area table.
#[derive(Clone, Debug)]
pub struct Silhouette {
    frame: Frame,
    centre: Vec3,
    radius: f32,
    res: usize,
    /// Summed-area table, (res + 1)², row-major: `sat[y][x]` = covered texels in [0,x)×[0,y)
    /// (integer counts, exact in f32 up to 4096² texels).
    sat: Vec<f32>,
    /// Per texel, the largest depth `x·w` of the occluder (−∞ where uncovered).
    far: Vec<f32>,
    /// Depth `x·w` of the plane touching the bounding sphere on the receivers' side.
    plane: f32,
    /// Texel-space bounds of the covered texels (empty: min > max), for early outs.
    covered: (Vec2, Vec2),
    /// Texels per world unit on the plane.
    texels_per_unit: f32,
    /// `texel_coords(p) = (p·u_axis, p·v_axis) + offset`.
    u_axis: Vec3,
    v_axis: Vec3,
    offset: Vec2,
}

impl Silhouette {
    /// Rasterises `triangles` (world; open where `holes` says) seen along unit `w`, on a `res²`
    /// grid covering the bounding sphere (`centre`, `radius`).
    pub fn build(
        triangles: &[[Vec3; 3]],
        holes: &dyn Openings,
        centre: Vec3,
        radius: f32,
        w: Vec3,
        res: usize,
    ) -> Self {
        let frame = Frame::from_normal(w);
        let radius = radius.max(1e-6);
        let res = res.clamp(2, 4096);
        let scale = res as f32 / (2.0 * radius);
        let mut s = Self {
            frame,
            centre,
            radius,
            res,
            sat: vec![0.0; (res + 1) * (res + 1)],
            far: vec![f32::NEG_INFINITY; res * res],
            plane: centre.dot(w) - radius,
            covered: (Vec2::MAX, Vec2::MIN),
            texels_per_unit: scale,
            u_axis: frame.t * scale,
            v_axis: frame.b * scale,
            offset: Vec2::new(radius - centre.dot(frame.t), radius - centre.dot(frame.b)) * scale,
        };
        for (k, t) in triangles.iter().enumerate() {
            s.rasterise(t, holes.cuts(k).then_some((holes, k)));
        }
        s.build_sat();
        s
    }

    /// The lookup's parameters as plain numbers (the GPU shaders repeat [`Self::occlusion`]).
    pub fn params(&self) -> Params {
        Params {
            w: self.frame.n,
            u_axis: self.u_axis,
            v_axis: self.v_axis,
            offset: self.offset,
            plane: self.plane,
            texels_per_unit: self.texels_per_unit,
            res: self.res as u32,
            covered: self.covered,
        }
    }

    /// The summed-area table, (res + 1)² row-major.
    pub fn sat(&self) -> &[f32] {
        &self.sat
    }

    /// The far depth per texel, res² row-major (−∞ where uncovered).
    pub fn far(&self) -> &[f32] {
        &self.far
    }

    /// Plane coordinates of `p` in texels.
    #[inline]
    fn texel_coords(&self, p: Vec3) -> Vec2 {
        Vec2::new(p.dot(self.u_axis), p.dot(self.v_axis)) + self.offset
    }

    /// Keeps the largest depth of `t` at the centre of every texel it covers (barycentric
    /// coordinates all ≥ 0) and where it is not open (`cut`: its holes and index), eight
    /// texels of a row at a time. The projection is affine, so the plane's barycentrics are
    /// the triangle's.
    fn rasterise(&mut self, t: &[Vec3; 3], cut: Option<(&dyn Openings, usize)>) {
        let q = t.map(|p| self.texel_coords(p));
        let z = t.map(|p| f32x8::splat(p.dot(self.frame.n)));
        let area = (q[1] - q[0]).perp_dot(q[2] - q[0]);
        if area.abs() < 1e-12 {
            return;
        }
        let lo = q[0].min(q[1]).min(q[2]).floor().max(Vec2::ZERO);
        let hi = q[0].max(q[1]).max(q[2]).ceil().min(Vec2::splat(self.res as f32));
        let (e1, e2, area) = (q[1] - q[0], q[2] - q[0], f32x8::splat(area));
        let centres = f32x8::from([0.5, 1.5, 2.5, 3.5, 4.5, 5.5, 6.5, 7.5]);
        let (x0, x1) = (lo.x as usize, hi.x as usize);
        for y in lo.y as usize..hi.y as usize {
            // The scalar operations of `(c − q0)·perp` lane by lane, so every lane rounds as
            // one texel computed alone would.
            let dy = f32x8::splat(y as f32 + 0.5 - q[0].y);
            let row = &mut self.far[y * self.res..(y + 1) * self.res];
            for start in (x0..x1).step_by(8) {
                let dx = f32x8::splat(start as f32) + centres - f32x8::splat(q[0].x);
                let b1 = (dx * f32x8::splat(e2.y) - dy * f32x8::splat(e2.x)) / area;
                let b2 = (f32x8::splat(e1.x) * dy - f32x8::splat(e1.y) * dx) / area;
                let b0 = f32x8::ONE - b1 - b2;
                let zero = f32x8::ZERO;
                // `≥ 0` where the scalar test was `!(< 0)`: they differ only for NaN, whose
                // depth is NaN too and never kept.
                let inside = b0.simd_ge(zero) & b1.simd_ge(zero) & b2.simd_ge(zero);
                let mut depth = b0 * z[0] + b1 * z[1] + b2 * z[2];
                if let Some((holes, k)) = cut {
                    let (b1, b2, mut d) = (b1.to_array(), b2.to_array(), depth.to_array());
                    for j in 0..8 {
                        if holes.open(k, Vec2::new(b1[j], b2[j])) {
                            d[j] = f32::NEG_INFINITY;
                        }
                    }
                    depth = f32x8::from(d);
                }
                let texels = &mut row[start..x1.min(start + 8)];
                let mut far = [f32::NEG_INFINITY; 8];
                far[..texels.len()].copy_from_slice(texels);
                let far = f32x8::from(far);
                let kept = (depth.simd_gt(far) & inside).select(depth, far).to_array();
                texels.copy_from_slice(&kept[..texels.len()]);
            }
        }
    }

    /// The table and the covered texels' bounds, from the far depths.
    fn build_sat(&mut self) {
        let (n, w) = (self.res, self.res + 1);
        for y in 0..n {
            let mut row = 0.0;
            let (mut first, mut last) = (n, 0);
            for x in 0..n {
                let covered = self.far[y * n + x] > f32::NEG_INFINITY;
                if covered {
                    first = first.min(x);
                    last = x + 1;
                }
                row += f32::from(u8::from(covered));
                self.sat[(y + 1) * w + x + 1] = self.sat[y * w + x + 1] + row;
            }
            if first < n {
                self.covered = (
                    self.covered.0.min(Vec2::new(first as f32, y as f32)),
                    self.covered.1.max(Vec2::new(last as f32, (y + 1) as f32)),
                );
            }
        }
    }

    /// ∫ of the coverage over the box [a, b] in texel units. The table is exact at texel
    /// corners and bilinear inside a texel, so the fractional box is integrated exactly.
    #[inline]
    fn box_integral(&self, a: Vec2, b: Vec2) -> f32 {
        let n = self.res as f32;
        let axis = |v: f32| {
            let v = v.clamp(0.0, n);
            let i = (v as usize).min(self.res - 1);
            (i, v - i as f32)
        };
        let (xa, xb, ya, yb) = (axis(a.x), axis(b.x), axis(a.y), axis(b.y));
        let w = self.res + 1;
        let row = |y: usize, (x, f): (usize, f32)| {
            let (l, r) = (self.sat[y * w + x], self.sat[y * w + x + 1]);
            l + (r - l) * f
        };
        let at = |(y, f): (usize, f32), x: (usize, f32)| {
            let lo = row(y, x);
            lo + (row(y + 1, x) - lo) * f
        };
        at(yb, xb) - at(yb, xa) - at(ya, xb) + at(ya, xa)
    }

    /// False when no point within `radius` of `centre` can be shadowed by this occluder for a
    /// region of angular width `width` = √Ω (a conservative test, for culling whole image tiles).
    pub fn reaches(&self, centre: Vec3, radius: f32, width: f32) -> bool {
        let along = (centre - self.centre).dot(self.frame.n);
        if along >= self.radius + radius {
            return false; // every point lies beyond the whole occluder along w
        }
        // The filter box of any point in the sphere, grown by the sphere, must meet the
        // covered texels.
        let tpu = self.texels_per_unit;
        let r_max = (self.plane - (centre.dot(self.frame.n) - radius)).max(0.0);
        let half = (0.5 * width * r_max * tpu).max(0.5) + radius * tpu + 1.0;
        let c = self.texel_coords(centre);
        let (lo, hi) = self.covered;
        c.x + half > lo.x && c.y + half > lo.y && c.x - half < hi.x && c.y - half < hi.y
    }

    /// Fraction of a region of angular width `width` = √Ω around `w` that the occluder hides
    /// from `p`.
    #[inline]
    pub fn occlusion(&self, p: Vec3, width: f32) -> f32 {
        let c = self.texel_coords(p);
        let r = self.plane - p.dot(self.frame.n);
        let (lo, hi) = self.covered;
        if r <= 0.0 {
            let (x, y) = (c.x.floor(), c.y.floor());
            if x < lo.x || y < lo.y || x >= hi.x || y >= hi.y {
                return 0.0;
            }
            let far = self.far[y as usize * self.res + x as usize];
            return if far > p.dot(self.frame.n) { 1.0 } else { 0.0 };
        }
        let half = (0.5 * width * r * self.texels_per_unit).max(0.5);
        let (a, b) = (c - half, c + half);
        if b.x <= lo.x || b.y <= lo.y || a.x >= hi.x || a.y >= hi.y {
            return 0.0;
        }
        let covered = self.box_integral(a, b);
        (covered * (0.25 / (half * half))).clamp(0.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit square at height y = 1 (normal ±Y), centred over the origin.
    fn square() -> Vec<[Vec3; 3]> {
        let p = [
            Vec3::new(-0.5, 1.0, -0.5),
            Vec3::new(0.5, 1.0, -0.5),
            Vec3::new(0.5, 1.0, 0.5),
            Vec3::new(-0.5, 1.0, 0.5),
        ];
        vec![[p[0], p[1], p[2]], [p[0], p[2], p[3]]]
    }

    fn sil(w: Vec3) -> Silhouette {
        // Radius 1 at 128² puts the square's edges on texel boundaries.
        Silhouette::build(&square(), &Solid, Vec3::new(0.0, 1.0, 0.0), 1.0, w, 128)
    }

    #[test]
    fn a_point_under_the_square_is_shadowed_and_one_beside_it_is_not() {
        let s = sil(Vec3::Y);
        assert_eq!(s.occlusion(Vec3::new(0.0, 0.0, 0.0), 1e-3), 1.0);
        assert_eq!(s.occlusion(Vec3::new(2.0, 0.0, 0.0), 1e-3), 0.0);
        // Light from below: the same point is in front of the occluder.
        let below = sil(Vec3::NEG_Y);
        assert_eq!(below.occlusion(Vec3::new(0.0, 0.0, 0.0), 1e-3), 0.0);
    }

    #[test]
    fn the_penumbra_widens_with_distance_and_solid_angle() {
        let s = sil(Vec3::Y);
        let edge = |y: f32, omega: f32| s.occlusion(Vec3::new(0.5, y, 0.0), omega.sqrt());
        // On the shadow's edge a symmetric box sees half the square.
        // (The touching plane is y = 0 here: R = −y.)
        assert!((edge(-0.5, 0.01) - 0.5).abs() < 1e-3, "{}", edge(-0.5, 0.01));
        let (near, far) = (
            s.occlusion(Vec3::new(0.56, -0.2, 0.0), 0.05f32.sqrt()),
            s.occlusion(Vec3::new(0.56, -1.0, 0.0), 0.05f32.sqrt()),
        );
        assert!(near < far, "a farther receiver has a wider penumbra: {near} vs {far}");
        assert!(s.occlusion(Vec3::new(0.0, -0.5, 0.0), 0.05f32.sqrt()) > 0.99);
    }

    #[test]
    fn culling_never_drops_a_shadowed_point() {
        let s = sil(Vec3::new(0.3, 1.0, -0.2).normalize());
        let mut r = crate::math::rng::seeded(5);
        for _ in 0..20_000 {
            use rand::Rng;
            let p = Vec3::new(r.random_range(-3.0..3.0), r.random_range(-2.0..3.0), r.random_range(-3.0..3.0));
            let width = r.random_range(0.0f32..0.5).sqrt();
            if s.occlusion(p, width) > 0.0 {
                assert!(s.reaches(p, 0.0, width), "{p} {width}");
                assert!(s.reaches(p + Vec3::X * 0.1, 0.2, width), "{p} {width}");
            }
        }
        assert!(!s.reaches(Vec3::new(5.0, -1.0, 5.0), 0.5, 0.1));
    }

    /// The rasteriser one texel at a time, as it was written first.
    fn rasterise_scalar(s: &mut Silhouette, t: &[Vec3; 3]) {
        let q = t.map(|p| s.texel_coords(p));
        let z = t.map(|p| p.dot(s.frame.n));
        let area = (q[1] - q[0]).perp_dot(q[2] - q[0]);
        if area.abs() < 1e-12 {
            return;
        }
        let lo = q[0].min(q[1]).min(q[2]).floor().max(Vec2::ZERO);
        let hi = q[0].max(q[1]).max(q[2]).ceil().min(Vec2::splat(s.res as f32));
        for y in lo.y as usize..hi.y as usize {
            for x in lo.x as usize..hi.x as usize {
                let c = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let b1 = (c - q[0]).perp_dot(q[2] - q[0]) / area;
                let b2 = (q[1] - q[0]).perp_dot(c - q[0]) / area;
                let b0 = 1.0 - b1 - b2;
                if b0 < 0.0 || b1 < 0.0 || b2 < 0.0 {
                    continue;
                }
                let depth = b0 * z[0] + b1 * z[1] + b2 * z[2];
                let f = &mut s.far[y * s.res + x];
                *f = f.max(depth);
            }
        }
    }

    #[test]
    fn the_eight_lane_rasteriser_matches_the_scalar_one_bit_for_bit() {
        use rand::Rng;
        let mut r = crate::math::rng::seeded(11);
        let mut p = || Vec3::new(r.random_range(-1.0..1.0), r.random_range(-1.0..1.0), r.random_range(-1.0..1.0));
        // Small, large, sliver and degenerate triangles.
        let mut tris: Vec<[Vec3; 3]> = (0..300).map(|_| [p(), p(), p()]).collect();
        tris.extend((0..100).map(|_| {
            let (a, b) = (p(), p());
            [a, b, a + (b - a) * 0.5 + Vec3::splat(1e-3)]
        }));
        tris.push([Vec3::ZERO, Vec3::X, 2.0 * Vec3::X]);
        for (w, res) in [(Vec3::Y, 128), (Vec3::new(0.3, 1.0, -0.2).normalize(), 61)] {
            let fast = Silhouette::build(&tris, &Solid, Vec3::ZERO, 1.5, w, res);
            let mut slow = Silhouette::build(&[], &Solid, Vec3::ZERO, 1.5, w, res);
            for t in &tris {
                rasterise_scalar(&mut slow, t);
            }
            let bits = |s: &Silhouette| s.far.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
            assert!(bits(&fast) == bits(&slow), "res {res}");
            assert!(fast.far.iter().filter(|f| f.is_finite()).count() > res * res / 4);
        }
    }

    #[test]
    fn the_covered_bounds_are_those_of_the_covered_texels() {
        let tilted = sil(Vec3::new(0.3, 1.0, -0.2).normalize());
        let empty = Silhouette::build(&[], &Solid, Vec3::ZERO, 1.0, Vec3::Y, 16);
        assert_eq!(empty.covered, (Vec2::MAX, Vec2::MIN), "nothing covered: an empty box");
        for s in [sil(Vec3::Y), tilted] {
            let n = s.res;
            let texels: Vec<Vec2> = (0..n * n)
                .filter(|k| s.far[*k] > f32::NEG_INFINITY)
                .map(|k| Vec2::new((k % n) as f32, (k / n) as f32))
                .collect();
            let lo = texels.iter().fold(Vec2::MAX, |a, t| a.min(*t));
            let hi = texels.iter().fold(Vec2::MIN, |a, t| a.max(*t + 1.0));
            assert!(texels.len() > 100 && s.covered == (lo, hi), "{:?} vs {:?}", s.covered, (lo, hi));
        }
    }

    #[test]
    fn inside_the_slab_the_depth_decides() {
        // A box-like occluder spanning y ∈ [1, 2]: a point at y = 1.5 under its top face is
        // inside the bounding slab (R ≤ 0) and still shadowed by the top.
        let mut tris = square();
        tris.extend(square().iter().map(|t| t.map(|p| p + Vec3::Y)));
        let s = Silhouette::build(&tris, &Solid, Vec3::new(0.0, 1.5, 0.0), 0.9, Vec3::Y, 64);
        assert_eq!(s.occlusion(Vec3::new(0.0, 1.5, 0.0), 0.3), 1.0);
        assert_eq!(s.occlusion(Vec3::new(0.0, 2.2, 0.0), 0.3), 0.0, "above every occluder");
        assert_eq!(s.occlusion(Vec3::new(0.8, 1.5, 0.0), 0.3), 0.0, "beside it");
    }
}
