//! What every BSPVT module shares: a tree node, the tile, and the quantised split lines. It
//! depends on no other BSPVT module, so the rest form no import cycle through it.

use std::f64::consts::{SQRT_2, TAU};

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

/// Texels per side of a tile. A face's tree starts with a fixed grid of tiles (axis-aligned
/// splits on tile boundaries, halving the tiles of the longer side) and Algorithm 1 runs inside
/// each tile, so an edit that changes the visibility seen through a few tiles rebuilds only
/// their subtrees (incremental re-bake). Sibling regions that are both uniformly visible or both
/// uniformly occluded merge back into one leaf: the grid costs nodes only where the visibility
/// changes.
pub const TILE: usize = 8;

/// A tile's key: its index in the face (row-major tiles), its live and its visible texel masks.
pub type TileKey = (u32, u64, u64);

/// Angle codes per turn (11 bits).
const ANGLE_STEPS: f64 = 2048.0;
/// Offsets are `(q − 2047) / 2047 · √2`, q ∈ [0, 4094]: symmetric, with 0 exact.
const OFFSET_HALF: f64 = 2047.0;

/// Quantises a line to (11-bit angle code, 12-bit offset code).
pub fn quantise_line(theta: f64, c: f64) -> (u16, u16) {
    let a = ((theta.rem_euclid(TAU) / TAU * ANGLE_STEPS).round() as i64).rem_euclid(ANGLE_STEPS as i64) as u16;
    let o = (c.clamp(-SQRT_2, SQRT_2) / SQRT_2 * OFFSET_HALF + OFFSET_HALF).round() as u16;
    (a, o)
}

/// The line a code pair stands for: its unit normal (cos θ, sin θ) and offset c. The normal
/// comes from the code's first-octant image by exact sign changes and swaps, so mirror-image
/// codes give mirror-image normals to the bit (see `kage_engine::bspvt::symmetry`).
pub fn dequantise_line(a: u16, o: u16) -> ((f64, f64), f64) {
    const QUARTER: u16 = ANGLE_STEPS as u16 / 4;
    let octant = |r: u16| {
        let (sin, cos) = (r as f64 / ANGLE_STEPS * TAU).sin_cos();
        // The octant's edge is its own mirror image: cos π/4 = sin π/4 exactly.
        if r == QUARTER / 2 { (cos, cos) } else { (cos, sin) }
    };
    let a = a % ANGLE_STEPS as u16;
    let r = a % QUARTER;
    let (cos, sin) = if r <= QUARTER / 2 {
        octant(r)
    } else {
        let (cos, sin) = octant(QUARTER - r);
        (sin, cos)
    };
    // Quarter turns.
    let normal = match a / QUARTER {
        0 => (cos, sin),
        1 => (-sin, cos),
        2 => (-cos, -sin),
        _ => (sin, -cos),
    };
    (normal, (o as f64 - OFFSET_HALF) / OFFSET_HALF * SQRT_2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_round_trip_within_a_quantum() {
        assert_eq!(dequantise_line(0, 2047), ((1.0, 0.0), 0.0), "offset 0 is exact");
        for (t, c) in [(0.0, 0.0), (1.0, -0.5), (6.2, 1.3), (3.3, -1.41)] {
            let (a, o) = quantise_line(t, c);
            let ((cos, sin), c2) = dequantise_line(a, o);
            let t2 = sin.atan2(cos);
            assert!((cos.hypot(sin) - 1.0).abs() < 1e-15, "a unit normal");
            let dt = (t2 - t).rem_euclid(TAU);
            assert!(dt.min(TAU - dt) <= TAU / ANGLE_STEPS / 2.0 + 1e-12);
            assert!((c2 - c).abs() <= SQRT_2 / OFFSET_HALF / 2.0 + 1e-12);
            assert_eq!(quantise_line(t2, c2), (a, o), "codes are fixed points");
        }
    }
}
