//! BSP visibility trees (Algorithm 1 of the seed, with its two corrections): per cube face, a
//! priority queue of pixel clusters by error; the worst cluster is split by the oriented line
//! minimising E(P, l) = Σ w (H(d(p)) − V(p))² while any cluster's own error Σ w (V − v̄)²
//! exceeds ε. Weights w are texel solid angles relative to the face's mean texel, so errors
//! are in "pixels". A leaf keeps the solid-angle-weighted mean visibility.
//!
//! Lines are `cos θ · s + sin θ · t = c` in face coordinates; the positive side
//! (`cos θ s + sin θ t − c > 0`) is the first child. Line parameters are quantised *before*
//! pixels are partitioned, so leaf means match the geometry the shader sees.

use super::layout::{dequantise_line, quantise_line};
use super::visibility::{BELOW, VISIBLE};
use crate::math::{cubemap, nelder_mead};
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// A node in pre-order: a split line, or a leaf with its mean visibility.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Node {
    /// Split by the quantised line (angle code, offset code); the positive side comes first.
    Split {
        /// 11-bit angle code.
        angle: u16,
        /// 12-bit offset code.
        offset: u16,
    },
    /// Mean visibility in [0, 1].
    Leaf(f32),
}

struct Pixel {
    s: f64,
    t: f64,
    w: f64,
    v: f64,
}

struct Cluster {
    pixels: Vec<u32>,
    mean: f64,
    error: f64,
}

/// Solid-angle-weighted mean and within-cluster error Σ w (V − v̄)² of a pixel set.
fn mean_and_error(pixels: &[u32], all: &[Pixel]) -> (f64, f64) {
    let (sw, sv) = pixels
        .iter()
        .fold((0.0, 0.0), |(sw, sv), &i| (sw + all[i as usize].w, sv + all[i as usize].w * all[i as usize].v));
    let mean = if sw > 0.0 { sv / sw } else { 0.0 };
    // V ∈ {0, 1}: Σ w (V − m)² = Σ w V − m Σ w V.
    (mean, (sv - mean * sv).max(0.0))
}

fn cluster(pixels: Vec<u32>, all: &[Pixel]) -> Cluster {
    let (mean, error) = mean_and_error(&pixels, all);
    Cluster { pixels, mean, error }
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

/// Builds the tree of one face from its texel states; `None` when no texel is above the horizon.
pub fn build(face: &[u8], res: usize, epsilon: f64) -> Option<Vec<Node>> {
    let mean_w = 4.0 * std::f64::consts::PI / (6 * res * res) as f64;
    let mut all = Vec::new();
    for (k, &state) in face.iter().enumerate() {
        if state != BELOW {
            let st = cubemap::texel_center(k % res, k / res, res);
            let w = cubemap::texel_solid_angle(k % res, k / res, res) / mean_w;
            all.push(Pixel { s: st.x, t: st.y, w, v: if state == VISIBLE { 1.0 } else { 0.0 } });
        }
    }
    if all.is_empty() {
        return None;
    }
    let mut arena: Vec<(Built, Option<Cluster>)> = Vec::new();
    let root = cluster((0..all.len() as u32).collect(), &all);
    let mut queue = BinaryHeap::new();
    queue.push(Queued(root.error, 0));
    arena.push((Built::Leaf(root.mean), Some(root)));
    while let Some(Queued(error, id)) = queue.pop() {
        if error <= epsilon {
            break;
        }
        let c = arena[id].1.take().expect("queued clusters keep their pixels");
        let Some(Split { angle, offset, pos, neg }) = split(&c, &all, res) else { continue };
        let (pos, neg) = (cluster(pos, &all), cluster(neg, &all));
        let (ip, ineg) = (arena.len(), arena.len() + 1);
        queue.push(Queued(pos.error, ip));
        queue.push(Queued(neg.error, ineg));
        arena.push((Built::Leaf(pos.mean), Some(pos)));
        arena.push((Built::Leaf(neg.mean), Some(neg)));
        arena[id].0 = Built::Split { angle, offset, pos: ip, neg: ineg };
    }
    let mut out = Vec::new();
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
    Some(out)
}

/// A chosen split: the quantised line and the pixels on its positive and negative sides.
struct Split {
    angle: u16,
    offset: u16,
    pos: Vec<u32>,
    neg: Vec<u32>,
}

/// A line `cos θ · s + sin θ · t = c` with its sine and cosine evaluated once.
#[derive(Clone, Copy)]
struct Line {
    cos: f64,
    sin: f64,
    c: f64,
}

impl Line {
    fn new(theta: f64, c: f64) -> Self {
        Self { cos: theta.cos(), sin: theta.sin(), c }
    }

    /// Signed distance of a pixel centre.
    fn side(&self, p: &Pixel) -> f64 {
        self.cos * p.s + self.sin * p.t - self.c
    }
}

/// E(P, l) with the exact Heaviside.
fn seed_error(c: &Cluster, all: &[Pixel], theta: f64, off: f64) -> f64 {
    let line = Line::new(theta, off);
    c.pixels
        .iter()
        .map(|&i| {
            let p = &all[i as usize];
            let h = if line.side(p) > 0.0 { 1.0 } else { 0.0 };
            p.w * (h - p.v).powi(2)
        })
        .sum()
}

/// The best quantised line for cluster `c` and the two pixel sets it makes; `None` when no
/// line separates anything (then the cluster stays a leaf).
///
/// Nelder–Mead minimises E(P, l) (with a one-texel linear ramp for H, so the simplex sees a
/// slope) from the two best initial lines; among the resulting and the initial lines, after
/// quantisation, the one whose two children have the least within-cluster error wins. E alone
/// can prefer leaving a small visible blob on the negative side (no split at all); the
/// children's error cannot.
fn split(c: &Cluster, all: &[Pixel], res: usize) -> Option<Split> {
    let tau = 0.5 * 2.0 / res as f64;
    let soft = |x: &[f64]| -> f64 {
        let line = Line::new(x[0], x[1]);
        c.pixels
            .iter()
            .map(|&i| {
                let p = &all[i as usize];
                // A linear ramp one texel wide: cheap, and smooth enough for the simplex.
                let h = (0.5 + line.side(p) / (2.0 * tau)).clamp(0.0, 1.0);
                p.w * (h - p.v).powi(2)
            })
            .sum()
    };
    let mut starts = initial_lines(c, all);
    starts.sort_by(|a, b| seed_error(c, all, a.0, a.1).total_cmp(&seed_error(c, all, b.0, b.1)));
    let opts = nelder_mead::Options { max_evals: 80, tolerance: 1e-6, restarts: 1 };
    let mut candidates = starts.clone();
    for &(theta, off) in starts.iter().take(2) {
        let m = nelder_mead::minimize(soft, &[theta, off], &[0.2, 2.0 / res as f64], opts);
        candidates.push((m.x[0], m.x[1]));
    }
    let mut best: Option<(f64, Split)> = None;
    for (t, o) in candidates {
        let o = max_margin_offset(c, all, t, o);
        let (qa, qo) = quantise_line(t, o);
        let (t, o) = dequantise_line(qa, qo);
        let line = Line::new(t, o);
        let (pos, neg): (Vec<u32>, Vec<u32>) = c.pixels.iter().partition(|&&i| line.side(&all[i as usize]) > 0.0);
        if pos.is_empty() || neg.is_empty() {
            continue;
        }
        let e = mean_and_error(&pos, all).1 + mean_and_error(&neg, all).1;
        if best.as_ref().is_none_or(|b| e < b.0) {
            best = Some((e, Split { angle: qa, offset: qo, pos, neg }));
        }
    }
    best.map(|(_, split)| split)
}

/// Moves a line parallel to itself to the middle of the gap between the pixel centres on its
/// two sides, so a boundary between texels is placed on the texel edge (as the raw cube map
/// has it) rather than anywhere in the gap.
fn max_margin_offset(c: &Cluster, all: &[Pixel], theta: f64, off: f64) -> f64 {
    let (mut below, mut above) = (f64::NEG_INFINITY, f64::INFINITY);
    let line = Line::new(theta, off);
    for &i in &c.pixels {
        let d = line.side(&all[i as usize]);
        if d > 0.0 {
            above = above.min(d);
        } else {
            below = below.max(d);
        }
    }
    if below.is_finite() && above.is_finite() { off + 0.5 * (below + above) } else { off }
}

/// Candidate lines: the principal axis of the visibility boundary (both orientations), and
/// axis-aligned lines through the centroid of the visible pixels.
fn initial_lines(c: &Cluster, all: &[Pixel]) -> Vec<(f64, f64)> {
    let vis: Vec<&Pixel> = c.pixels.iter().map(|&i| &all[i as usize]).filter(|p| p.v > 0.5).collect();
    let occ: Vec<&Pixel> = c.pixels.iter().map(|&i| &all[i as usize]).filter(|p| p.v <= 0.5).collect();
    let centroid = |ps: &[&Pixel]| {
        let n = ps.len().max(1) as f64;
        (ps.iter().map(|p| p.s).sum::<f64>() / n, ps.iter().map(|p| p.t).sum::<f64>() / n)
    };
    let (vc, oc) = (centroid(&vis), centroid(&occ));
    let mid = ((vc.0 + oc.0) * 0.5, (vc.1 + oc.1) * 0.5);
    let mut lines = Vec::new();
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

/// Index (in `nodes`) of the leaf containing face point (s, t).
pub fn leaf_index(nodes: &[Node], s: f64, t: f64) -> usize {
    let mut i = 0;
    loop {
        match nodes[i] {
            Node::Leaf(_) => return i,
            Node::Split { angle, offset } => {
                let (th, c) = dequantise_line(angle, offset);
                let line = Line::new(th, c);
                i = if line.side(&Pixel { s, t, w: 0.0, v: 0.0 }) > 0.0 { i + 1 } else { skip(nodes, i + 1) };
            }
        }
    }
}

/// Index just past the subtree starting at `i`.
pub fn skip(nodes: &[Node], mut i: usize) -> usize {
    let mut pending = 1;
    while pending > 0 {
        pending -= 1;
        if let Node::Split { .. } = nodes[i] {
            pending += 2;
        }
        i += 1;
    }
    i
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bspvt::visibility::OCCLUDED;

    fn face_from(res: usize, f: impl Fn(f64, f64) -> u8) -> Vec<u8> {
        (0..res * res)
            .map(|k| {
                let st = cubemap::texel_center(k % res, k / res, res);
                f(st.x, st.y)
            })
            .collect()
    }

    /// Every valid pixel lands in exactly one leaf and each leaf holds its pixels' mean.
    fn check_invariants(face: &[u8], res: usize, nodes: &[Node]) {
        let mean_w = 4.0 * std::f64::consts::PI / (6 * res * res) as f64;
        let mut sums: std::collections::HashMap<usize, (f64, f64)> = Default::default();
        for (k, &state) in face.iter().enumerate() {
            if state == BELOW {
                continue;
            }
            let st = cubemap::texel_center(k % res, k / res, res);
            let leaf = leaf_index(nodes, st.x, st.y);
            let w = cubemap::texel_solid_angle(k % res, k / res, res) / mean_w;
            let e = sums.entry(leaf).or_default();
            e.0 += w;
            e.1 += w * if state == VISIBLE { 1.0 } else { 0.0 };
        }
        for (leaf, (w, v)) in sums {
            let Node::Leaf(stored) = nodes[leaf] else { panic!("not a leaf") };
            assert!((stored as f64 - v / w).abs() < 1e-6, "leaf {leaf}: {stored} vs {}", v / w);
        }
        let leaves = nodes.iter().filter(|n| matches!(n, Node::Leaf(_))).count();
        assert_eq!(nodes.len(), 2 * leaves - 1, "a full binary tree");
        assert_eq!(skip(nodes, 0), nodes.len());
    }

    #[test]
    fn uniform_faces_are_single_leaves() {
        let res = 16;
        assert_eq!(build(&vec![VISIBLE; res * res], res, 0.0), Some(vec![Node::Leaf(1.0)]));
        assert_eq!(build(&vec![OCCLUDED; res * res], res, 0.0), Some(vec![Node::Leaf(0.0)]));
        assert_eq!(build(&vec![BELOW; res * res], res, 0.0), None);
    }

    #[test]
    fn a_half_plane_is_one_split() {
        let res = 32;
        let face = face_from(res, |s, t| if 0.6 * s + 0.8 * t > 0.1 { VISIBLE } else { OCCLUDED });
        let nodes = build(&face, res, 0.5).unwrap();
        check_invariants(&face, res, &nodes);
        assert!(nodes.len() <= 5, "{} nodes for a straight boundary", nodes.len());
    }

    #[test]
    fn disk_and_checker_terminate_with_epsilon_zero() {
        let res = 24;
        let disk = face_from(res, |s, t| {
            if s * s + t * t < 0.3 {
                OCCLUDED
            } else if t < -0.8 {
                BELOW
            } else {
                VISIBLE
            }
        });
        let checker =
            face_from(
                res,
                |s, t| if ((s * 3.0).floor() + (t * 3.0).floor()) as i64 % 2 == 0 { VISIBLE } else { OCCLUDED },
            );
        for face in [&disk, &checker] {
            let exact = build(face, res, 0.0).unwrap();
            check_invariants(face, res, &exact);
            let coarse = build(face, res, 4.0).unwrap();
            check_invariants(face, res, &coarse);
            assert!(coarse.len() < exact.len());
        }
    }
}
