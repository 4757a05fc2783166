//! Algorithm 1 inside one tile (at most 64 texels; see [`super::node::TILE`]): a priority queue
//! of pixel clusters by error; the worst cluster is split by the oriented line minimising
//! E(P, l) = Σ w (H(d(p)) − V(p))² while any cluster's own error Σ w (V − v̄)² exceeds ε.
//! Weights w are texel solid angles relative to the face's mean texel, so errors are in
//! "pixels". A leaf keeps the solid-angle-weighted mean visibility.
//!
//! A cluster is a bit mask over the tile's pixels, so splitting allocates nothing; the split
//! search gathers a cluster's pixels into arrays once, evaluates its objective eight pixels at a
//! time in single precision (`Ramp`) and judges each candidate line four pixels at a time in
//! double precision (`Pixels::divide`).

use super::node::{Node, dequantise_line, quantise_line};
use crate::math::{nelder_mead, trig};
use std::cmp::Ordering;
use std::collections::BinaryHeap;
use wide::f64x4;

/// Pixels per tile at most (a cluster is a mask over them).
pub const MAX_PIXELS: usize = 64;

/// A line `cos θ · s + sin θ · t = c` in face coordinates, its sine and cosine evaluated once.
/// Its positive side (`cos θ s + sin θ t − c > 0`) is a split's first child.
#[derive(Clone, Copy)]
pub struct Line {
    cos: f64,
    sin: f64,
    c: f64,
}

impl Line {
    /// The line of angle `theta` and offset `c`, its sine and cosine to within 1e-12 (enough to
    /// steer the search; lines the tree keeps are [`Self::dequantised`]).
    #[inline]
    pub fn new(theta: f64, c: f64) -> Self {
        let (sin, cos) = trig::sin_cos(theta);
        Self { cos, sin, c }
    }

    /// The line a quantised code pair stands for.
    pub fn dequantised(angle: u16, offset: u16) -> Self {
        let ((cos, sin), c) = dequantise_line(angle, offset);
        Self { cos, sin, c }
    }

    /// Signed distance of face point (s, t).
    #[inline]
    pub fn side(&self, s: f64, t: f64) -> f64 {
        self.cos * s + self.sin * t - self.c
    }
}

/// A tile's pixels above the horizon, by index: face coordinates, weight and visibility (0 or
/// 1). Padded with zero-weight pixels to a multiple of four.
pub struct Pixels {
    len: usize,
    s: [[f64; 4]; MAX_PIXELS / 4],
    t: [[f64; 4]; MAX_PIXELS / 4],
    w: [[f64; 4]; MAX_PIXELS / 4],
    v: [[f64; 4]; MAX_PIXELS / 4],
}

impl Pixels {
    /// No pixels; every lane zero.
    const EMPTY: Self = Self {
        len: 0,
        s: [[0.0; 4]; MAX_PIXELS / 4],
        t: [[0.0; 4]; MAX_PIXELS / 4],
        w: [[0.0; 4]; MAX_PIXELS / 4],
        v: [[0.0; 4]; MAX_PIXELS / 4],
    };

    /// Pixels from `(s, t, weight, visible)` in index order; at most [`MAX_PIXELS`].
    pub fn new(pixels: impl IntoIterator<Item = (f64, f64, f64, bool)>) -> Self {
        let mut out = Self::EMPTY;
        for (s, t, w, visible) in pixels {
            out.push(s, t, w, if visible { 1.0 } else { 0.0 });
        }
        out
    }

    fn push(&mut self, s: f64, t: f64, w: f64, v: f64) {
        let (q, l) = (self.len / 4, self.len % 4);
        (self.s[q][l], self.t[q][l], self.w[q][l], self.v[q][l]) = (s, t, w, v);
        self.len += 1;
    }

    /// Pixel `i`'s (s, t, w, v).
    #[inline]
    fn get(&self, i: usize) -> (f64, f64, f64, f64) {
        let (q, l) = (i / 4, i % 4);
        (self.s[q][l], self.t[q][l], self.w[q][l], self.v[q][l])
    }

    /// The mask of every pixel.
    fn all(&self) -> u64 {
        if self.len == MAX_PIXELS { u64::MAX } else { (1 << self.len) - 1 }
    }

    /// The pixels of `mask`, in index order (the padding's zero weights vanish from every sum).
    fn gather(&self, mask: u64) -> Self {
        let mut out = Self::EMPTY;
        for i in bits(mask) {
            let (s, t, w, v) = self.get(i);
            out.push(s, t, w, v);
        }
        out
    }

    /// Solid-angle-weighted mean and within-cluster error Σ w (V − v̄)² of the pixels of `mask`.
    fn mean_and_error(&self, mask: u64) -> (f64, f64) {
        mean_and_error(bits(mask).fold((0.0, 0.0), |sums, i| add(sums, self.get(i))))
    }

    /// Per group of four pixels, the signed distances to `line` (as [`Line::side`] computes
    /// them) and which lanes hold pixels rather than padding.
    fn sides(&self, line: &Line) -> impl Iterator<Item = (usize, f64x4, f64x4)> {
        let (cos, sin, c) = (f64x4::splat(line.cos), f64x4::splat(line.sin), f64x4::splat(line.c));
        let lanes = f64x4::new([0.0, 1.0, 2.0, 3.0]);
        (0..self.len.div_ceil(4).min(MAX_PIXELS / 4)).map(move |q| {
            let d = cos * f64x4::new(self.s[q]) + sin * f64x4::new(self.t[q]) - c;
            (q, d, (lanes + f64x4::splat((4 * q) as f64)).simd_lt(f64x4::splat(self.len as f64)))
        })
    }

    /// Its pixels on the positive side of `line` (a mask over its indices) and the error the
    /// two sides keep, Σ w (V − v̄)² within each (summed four lanes at a time).
    fn divide(&self, line: &Line) -> (u64, f64) {
        let zero = f64x4::ZERO;
        let (mut positive, mut sums) = (0, [zero; 4]);
        for (q, d, _) in self.sides(line) {
            let (w, v, side) = (f64x4::new(self.w[q]), f64x4::new(self.v[q]), d.simd_gt(zero));
            positive |= u64::from(side.to_bitmask()) << (4 * q);
            let wv = w * v;
            // The padding weighs nothing, whichever side it falls on.
            let [pw, pv, nw, nv] = sums;
            sums = [
                pw + side.select(w, zero),
                pv + side.select(wv, zero),
                nw + side.select(zero, w),
                nv + side.select(zero, wv),
            ];
        }
        let [pw, pv, nw, nv] = sums.map(f64x4::reduce_add);
        (positive & self.all(), mean_and_error((pw, pv)).1 + mean_and_error((nw, nv)).1)
    }

    /// Σ w (H − V)² over every pixel, H the line's side through `h(signed distance)`: four
    /// pixels at a time, in four partial sums (the padding weighs nothing).
    #[inline]
    fn objective(&self, line: &Line, h: impl Fn(f64) -> f64) -> f64 {
        let quads = self.len.div_ceil(4);
        let mut sum = [0.0; 4];
        for q in 0..quads.min(MAX_PIXELS / 4) {
            let (s, t, w, v) = (&self.s[q], &self.t[q], &self.w[q], &self.v[q]);
            // Fused: the sums only steer the search (partitions use `Line::side`).
            let e: [f64; 4] =
                std::array::from_fn(|l| h(line.cos.mul_add(s[l], line.sin.mul_add(t[l], -line.c))) - v[l]);
            sum = std::array::from_fn(|l| (w[l] * e[l]).mul_add(e[l], sum[l]));
        }
        (sum[0] + sum[1]) + (sum[2] + sum[3])
    }
}

/// The split search's soft side of a line at signed distance `d`: a linear ramp 1/`slope` wide.
#[cfg(test)]
fn ramp(d: f64, slope: f64) -> f64 {
    (0.5 + d * slope).clamp(0.0, 1.0)
}

/// The set bits of `mask`, lowest first.
pub(crate) fn bits(mut mask: u64) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (mask != 0).then(|| {
            let i = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            i
        })
    })
}

/// Weight and weighted visibility sums `(Σ w, Σ w V)` with pixel `(s, t, w, v)` added.
#[inline]
fn add((sw, sv): (f64, f64), (_, _, w, v): (f64, f64, f64, f64)) -> (f64, f64) {
    (sw + w, sv + w * v)
}

/// The weighted mean and the error Σ w (V − v̄)² of pixels with sums `(Σ w, Σ w V)`.
fn mean_and_error((sw, sv): (f64, f64)) -> (f64, f64) {
    let mean = if sw > 0.0 { sv / sw } else { 0.0 };
    // V ∈ {0, 1}: Σ w (V − m)² = Σ w V − m Σ w V.
    (mean, (sv - mean * sv).max(0.0))
}

/// The bits of `mask` that gathered mask `picked` picks: bit k of `picked` stands for the k-th
/// set bit of `mask` (see [`Pixels::gather`]).
fn scatter(mut picked: u64, mask: u64) -> u64 {
    bits(mask).fold(0, |out, i| {
        let bit = picked & 1;
        picked >>= 1;
        out | bit << i
    })
}

/// A cluster's pixels for the split search's objective, eight per single-precision vector: the
/// objective only steers the search (partitions and errors are computed in double precision),
/// and eight lanes take fewer instructions per evaluation than four in double precision.
struct Ramp {
    /// Groups of eight holding pixels.
    groups: usize,
    s: [wide::f32x8; MAX_PIXELS / 8],
    t: [wide::f32x8; MAX_PIXELS / 8],
    w: [wide::f32x8; MAX_PIXELS / 8],
    v: [wide::f32x8; MAX_PIXELS / 8],
}

impl Ramp {
    /// The lanes of gathered `pixels` (zero-weight padding stays zero).
    fn new(pixels: &Pixels) -> Self {
        use wide::f32x8;
        let lanes = |a: &[[f64; 4]; MAX_PIXELS / 4]| -> [f32x8; MAX_PIXELS / 8] {
            std::array::from_fn(|q| f32x8::new(std::array::from_fn(|l| a[2 * q + l / 4][l % 4] as f32)))
        };
        Self {
            groups: pixels.len.div_ceil(8),
            s: lanes(&pixels.s),
            t: lanes(&pixels.t),
            w: lanes(&pixels.w),
            v: lanes(&pixels.v),
        }
    }

    /// Σ w (H − V)² with the search's soft side H(d) = clamp(1/2 + d · slope, 0, 1) of the
    /// signed distance d to `line`: a linear ramp 1/`slope` wide, so the simplex sees a slope.
    #[inline]
    fn objective(&self, line: &Line, slope: f32) -> f64 {
        use wide::f32x8;
        let (cos, sin, minus_c) =
            (f32x8::splat(line.cos as f32), f32x8::splat(line.sin as f32), f32x8::splat(-line.c as f32));
        let (slope, half) = (f32x8::splat(slope), f32x8::splat(0.5));
        let mut sum = f32x8::ZERO;
        for q in 0..self.groups.min(MAX_PIXELS / 8) {
            let d = cos.mul_add(self.s[q], sin.mul_add(self.t[q], minus_c));
            let h = (half + d * slope).fast_max(f32x8::ZERO).fast_min(f32x8::ONE);
            let e = h - self.v[q];
            sum = (self.w[q] * e).mul_add(e, sum);
        }
        sum.reduce_add() as f64
    }
}

#[derive(Clone, Copy)]
struct Cluster {
    mask: u64,
    mean: f64,
    error: f64,
}

impl Cluster {
    fn new(mask: u64, all: &Pixels) -> Self {
        let (mean, error) = all.mean_and_error(mask);
        Self { mask, mean, error }
    }
}

/// Arena node while building.
enum Built {
    Leaf(f64),
    Split { angle: u16, offset: u16, pos: usize, neg: usize },
}

#[derive(PartialEq)]
struct Queued(f64, usize);
impl Eq for Queued {}
impl PartialOrd for Queued {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Queued {
    // Largest error first; ties by creation order, for determinism.
    fn cmp(&self, o: &Self) -> Ordering {
        self.0.total_cmp(&o.0).then(o.1.cmp(&self.1))
    }
}

/// The subtree (in pre-order) splitting the cluster of all pixels while some cluster's error
/// exceeds ε; `res` is the face resolution (texel size 2/res).
pub fn clusters(all: &Pixels, res: usize, epsilon: f64) -> Vec<Node> {
    let root = Cluster::new(all.all(), all);
    let mut arena = vec![(Built::Leaf(root.mean), root)];
    let mut queue = BinaryHeap::from([Queued(root.error, 0)]);
    while let Some(Queued(error, id)) = queue.pop() {
        if error <= epsilon {
            break;
        }
        let Some((angle, offset, pos)) = split(&arena[id].1, all, res) else { continue };
        let (pos, neg) = (Cluster::new(pos, all), Cluster::new(arena[id].1.mask & !pos, all));
        let (ip, ineg) = (arena.len(), arena.len() + 1);
        queue.push(Queued(pos.error, ip));
        queue.push(Queued(neg.error, ineg));
        arena.push((Built::Leaf(pos.mean), pos));
        arena.push((Built::Leaf(neg.mean), neg));
        arena[id].0 = Built::Split { angle, offset, pos: ip, neg: ineg };
    }
    let mut out = Vec::with_capacity(arena.len());
    let mut stack = vec![0usize];
    while let Some(i) = stack.pop() {
        match arena[i].0 {
            Built::Leaf(v) => out.push(Node::Leaf(v as f32)),
            Built::Split { angle, offset, pos, neg } => {
                out.push(Node::Split { angle, offset });
                stack.push(neg);
                stack.push(pos);
            }
        }
    }
    out
}

/// The best quantised line for cluster `c` (angle code, offset code) and the mask of the pixels
/// on its positive side; `None` when no line separates anything (then the cluster stays a leaf).
///
/// Nelder–Mead minimises E(P, l) (with a one-texel linear ramp for H, so the simplex sees a
/// slope) from each of the three best initial lines in turn; among the resulting and the
/// initial lines, after quantisation, the first one whose two children have the least
/// within-cluster error wins. E alone can prefer leaving a small visible blob on the negative
/// side (no split at all); the children's error cannot. Once some line leaves both children
/// without error the search stops: no later line could win.
fn split(c: &Cluster, all: &Pixels, res: usize) -> Option<(u16, u16, u64)> {
    let pixels = all.gather(c.mask);
    // A linear ramp one texel (2/res) wide: cheap, and smooth enough for the simplex.
    let slope = res as f64 / 2.0;
    let lanes = Ramp::new(&pixels);
    let soft = |x: &[f64; 2]| lanes.objective(&Line::new(x[0], x[1]), slope as f32);
    let seed_error = |(theta, off)| pixels.objective(&Line::new(theta, off), |d| if d > 0.0 { 1.0 } else { 0.0 });
    let mut ranked: Vec<(f64, (f64, f64))> =
        initial_lines(c.mask, all).into_iter().map(|line| (seed_error(line), line)).collect();
    ranked.sort_by(|a, b| a.0.total_cmp(&b.0));
    let starts: Vec<(f64, f64)> = ranked.into_iter().map(|(_, line)| line).collect();
    // Three starts without restarts, stopped at a spread of 3e-4, build fewer leaves with less
    // error than two starts restarted once at 1e-4, in less time (docs/bspvt.md, "Split search quality and speed").
    let opts = nelder_mead::Options { max_evals: 80, tolerance: 3e-4, restarts: 0 };
    // A line's split after quantisation (a mask over the gathered pixels) and the error its
    // children would keep.
    let every = pixels.all();
    let judge = |(t, o): (f64, f64)| {
        let (qa, qo) = quantise_line(t, max_margin_offset(&pixels, t, o));
        let (pos, e) = pixels.divide(&Line::dequantised(qa, qo));
        (pos != 0 && pos != every).then_some((e, (qa, qo, pos)))
    };
    // The first of equally good lines wins.
    let better = |best: Option<(f64, _)>, next: Option<(f64, _)>| match (best, next) {
        (Some(b), Some(n)) if n.0 >= b.0 => Some(b),
        (b, None) => b,
        (_, n) => n,
    };
    let mut best = starts.iter().map(|&line| judge(line)).fold(None, better);
    for &(theta, off) in starts.iter().take(3) {
        if best.is_some_and(|b| b.0 == 0.0) {
            break;
        }
        let m = nelder_mead::minimize(soft, [theta, off], [0.2, 2.0 / res as f64], opts);
        best = better(best, judge((m.x[0], m.x[1])));
    }
    best.map(|(_, (qa, qo, pos))| (qa, qo, scatter(pos, c.mask)))
}

/// Moves a line parallel to itself to the middle of the gap between the pixel centres of
/// `pixels` on its two sides, so a boundary between texels is placed on the texel edge (as the
/// raw cube map has it) rather than anywhere in the gap.
fn max_margin_offset(pixels: &Pixels, theta: f64, off: f64) -> f64 {
    let (inf, zero) = (f64x4::splat(f64::INFINITY), f64x4::ZERO);
    let (mut below, mut above) = (-inf, inf);
    for (_, d, pixel) in pixels.sides(&Line::new(theta, off)) {
        let positive = d.simd_gt(zero);
        above = above.min((pixel & positive).select(d, inf));
        below = below.max((pixel & !positive).select(d, -inf));
    }
    let below = below.to_array().into_iter().fold(f64::NEG_INFINITY, f64::max);
    let above = above.to_array().into_iter().fold(f64::INFINITY, f64::min);
    if below.is_finite() && above.is_finite() { off + 0.5 * (below + above) } else { off }
}

/// Candidate lines: the principal axis of the visibility boundary (both orientations), and
/// axis-aligned lines through the centroid of the visible pixels.
fn initial_lines(mask: u64, all: &Pixels) -> Vec<(f64, f64)> {
    let centroid = |visible: bool| {
        let (n, s, t) = bits(mask)
            .map(|i| all.get(i))
            .filter(|p| (p.3 > 0.5) == visible)
            .fold((0usize, 0.0, 0.0), |(n, s, t), p| (n + 1, s + p.0, t + p.1));
        let n = n.max(1) as f64;
        (s / n, t / n)
    };
    let (vc, oc) = (centroid(true), centroid(false));
    let mid = ((vc.0 + oc.0) * 0.5, (vc.1 + oc.1) * 0.5);
    let mut lines = Vec::with_capacity(5);
    // The direction from the occluded centroid to the visible one is the boundary's normal.
    let (dx, dy) = (vc.0 - oc.0, vc.1 - oc.1);
    if dx != 0.0 || dy != 0.0 {
        let theta = dy.atan2(dx).rem_euclid(std::f64::consts::TAU);
        lines.push((theta, theta.cos() * mid.0 + theta.sin() * mid.1));
    }
    for k in 0..4 {
        let theta = k as f64 * std::f64::consts::FRAC_PI_2;
        lines.push((theta, theta.cos() * mid.0 + theta.sin() * mid.1));
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tile's worth of pixels on a jittered grid, visible on one side of a wavy boundary.
    fn pixels(n: usize) -> Pixels {
        Pixels::new((0..n).map(|i| {
            let (s, t) = ((i % 8) as f64 / 8.0 + 0.01 * (i as f64).sin(), (i / 8) as f64 / 8.0);
            (s, t, 1.0 + 0.1 * (i as f64).cos(), s + 0.2 * (5.0 * t).sin() > 0.45)
        }))
    }

    #[test]
    fn bits_lists_set_bits_lowest_first() {
        assert_eq!(bits(0).count(), 0);
        assert_eq!(bits(0b1010_0001).collect::<Vec<_>>(), [0, 5, 7]);
        assert_eq!(bits(u64::MAX).collect::<Vec<_>>(), (0..64).collect::<Vec<_>>());
    }

    /// The four-lane objective over gathered pixels equals the plain sum over the mask's pixels
    /// (the zero-weight padding adds nothing), for clusters of 1 to 64 pixels; the search's
    /// eight-lane single-precision objective is within its rounding of it (each signed distance
    /// is off by a few units in the last place of single precision, times the ramp's slope).
    #[test]
    fn gathered_objective_equals_the_plain_sum() {
        let all = pixels(64);
        let line = Line::new(0.7, 0.3);
        let ramp = |d: f64| super::ramp(d, 8.0);
        for mask in [1u64, 0b111, 0x5555_5555_5555_5555, 0xFFFF_0000_0000_0001, u64::MAX] {
            let gathered = all.gather(mask);
            assert_eq!(gathered.len, mask.count_ones() as usize);
            let plain: f64 = bits(mask)
                .map(|i| {
                    let (s, t, w, v) = all.get(i);
                    w * (ramp(line.side(s, t)) - v).powi(2)
                })
                .sum();
            let fast = gathered.objective(&line, ramp);
            assert!((fast - plain).abs() <= 1e-12 * (1.0 + plain), "mask {mask:#x}: {fast} vs {plain}");
            let (lanes, weight) = (Ramp::new(&gathered), bits(mask).map(|i| all.get(i).2).sum::<f64>());
            for k in 0..300 {
                let (theta, c, slope) = (k as f64 * 0.37, 0.3 * (k as f64).sin(), [10.0, 25.3, 1e3 / 3.0][k % 3]);
                let line = Line::new(theta, c);
                let exact = gathered.objective(&line, |d| super::ramp(d, slope));
                let single = lanes.objective(&line, slope as f32);
                let bound = 1e-6 * (slope * weight + exact);
                assert!((single - exact).abs() <= bound, "mask {mask:#x}, line {k}: {single} vs {exact}");
            }
        }
    }

    /// `divide` splits gathered pixels as `Line::side` does and keeps the children's error
    /// within rounding of the per-side sums; the largest-margin offset sits halfway between the
    /// nearest pixels on either side, for clusters of 1 to 64 pixels (the padding ignored).
    #[test]
    fn divide_and_margin_agree_with_one_pixel_at_a_time() {
        let all = pixels(64);
        for mask in [1u64, 0b111, 0x5555_5555_5555_5555, 0xFFFF_0000_0000_0001, u64::MAX] {
            let gathered = all.gather(mask);
            for k in 0..300 {
                let (theta, c) = (k as f64 * 0.37, 0.6 * (k as f64).sin());
                let line = Line::new(theta, c);
                let d: Vec<f64> = (0..gathered.len).map(|i| line.side(gathered.get(i).0, gathered.get(i).1)).collect();
                let positive = (0..gathered.len).filter(|&i| d[i] > 0.0).fold(0u64, |m, i| m | 1 << i);
                let error = gathered.mean_and_error(positive).1 + gathered.mean_and_error(gathered.all() & !positive).1;
                let (fast, fast_error) = gathered.divide(&line);
                assert_eq!(fast, positive, "mask {mask:#x}, line {k}");
                assert!((fast_error - error).abs() <= 1e-12 * (1.0 + error), "{fast_error} vs {error}");
                let above = d.iter().copied().filter(|&d| d > 0.0).fold(f64::INFINITY, f64::min);
                let below = d.iter().copied().filter(|&d| d <= 0.0).fold(f64::NEG_INFINITY, f64::max);
                let margin = if above.is_finite() && below.is_finite() { c + 0.5 * (below + above) } else { c };
                assert_eq!(max_margin_offset(&gathered, theta, c), margin, "mask {mask:#x}, line {k}");
            }
        }
        assert_eq!(scatter(0b101, 0b1011_0000), 0b1001_0000);
    }

    /// Every pixel lands in exactly one leaf, leaves hold their pixels' weighted means, splits
    /// stop at ε, and a build is deterministic; fewer than 64 pixels work too.
    #[test]
    fn clusters_partition_the_pixels_and_hold_their_means() {
        for n in [64, 37] {
            let all = pixels(n);
            let nodes = clusters(&all, 64, 0.5);
            assert_eq!(nodes, clusters(&all, 64, 0.5));
            assert!(nodes.len() > 1, "a boundary is split");
            let mut sums = std::collections::HashMap::<usize, (f64, f64)>::new();
            for i in 0..n {
                let (s, t, w, v) = all.get(i);
                let e = sums.entry(super::super::tree::leaf_index(&nodes, s, t)).or_default();
                (e.0, e.1) = (e.0 + w, e.1 + w * v);
            }
            let leaves = nodes.iter().filter(|n| matches!(n, Node::Leaf(_))).count();
            assert_eq!(sums.len(), leaves, "every leaf holds a pixel");
            let mut error = 0.0;
            for (leaf, (w, wv)) in sums {
                let Node::Leaf(stored) = nodes[leaf] else { panic!("not a leaf") };
                assert!((stored as f64 - wv / w).abs() < 1e-6);
                error += wv - wv * wv / w;
            }
            assert!(error <= 0.5 * leaves as f64, "each leaf's error is at most ε: {error}");
            assert_eq!(clusters(&all, 64, f64::INFINITY), vec![Node::Leaf(all.mean_and_error(all.all()).0 as f32)]);
        }
    }
}
