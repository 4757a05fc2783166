//! Morton (Z-order) codes: points quantised to a 2²¹ grid over a box, their bits interleaved,
//! so that sorting by code keeps points that lie close together mostly close in the order.

use glam::Vec3;

/// Grid cells per axis minus one (21 bits: three axes fit in a `u64`).
const MAX: u32 = (1 << 21) - 1;

/// The grid cell of `p` in the box `[lo, hi]` (clamped to it; a flat axis maps to cell 0).
pub fn quantize(p: Vec3, lo: Vec3, hi: Vec3) -> [u32; 3] {
    let extent = hi - lo;
    std::array::from_fn(|k| {
        if extent[k] > 0.0 { (((p[k] - lo[k]) / extent[k]).clamp(0.0, 1.0) * MAX as f32).round() as u32 } else { 0 }
    })
}

/// The code of a cell: bit i of axis k becomes bit 3i + k.
pub fn encode(cell: [u32; 3]) -> u64 {
    cell.iter().enumerate().map(|(k, &c)| spread(c.min(MAX)) << k).fold(0, |a, b| a | b)
}

/// The cell of a code (the inverse of [`encode`]).
pub fn decode(code: u64) -> [u32; 3] {
    std::array::from_fn(|k| compact(code >> k))
}

/// Bits 0..21 of `x` moved to bits 0, 3, 6, …
fn spread(x: u32) -> u64 {
    let mut x = x as u64 & 0x1F_FFFF;
    x = (x | x << 32) & 0x1F_0000_0000_FFFF;
    x = (x | x << 16) & 0x1F_0000_FF00_00FF;
    x = (x | x << 8) & 0x100F_00F0_0F00_F00F;
    x = (x | x << 4) & 0x10C3_0C30_C30C_30C3;
    (x | x << 2) & 0x1249_2492_4924_9249
}

/// Bits 0, 3, 6, … of `x` gathered into bits 0..21 (the inverse of [`spread`]).
fn compact(x: u64) -> u32 {
    let mut x = x & 0x1249_2492_4924_9249;
    x = (x | x >> 2) & 0x10C3_0C30_C30C_30C3;
    x = (x | x >> 4) & 0x100F_00F0_0F00_F00F;
    x = (x | x >> 8) & 0x1F_0000_FF00_00FF;
    x = (x | x >> 16) & 0x1F_0000_0000_FFFF;
    ((x | x >> 32) & 0x1F_FFFF) as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_round_trip_and_interleave() {
        for cell in [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [MAX, MAX, MAX], [12345, 999_999, 7], [MAX, 0, 3]] {
            assert_eq!(decode(encode(cell)), cell);
        }
        assert_eq!(encode([1, 0, 0]), 1);
        assert_eq!(encode([0, 1, 0]), 2);
        assert_eq!(encode([0, 0, 1]), 4);
        assert_eq!(encode([2, 0, 0]), 8);
        assert_eq!(encode([MAX, MAX, MAX]), (1u64 << 63) - 1);
        let mut rng = crate::math::rng::stream(7, 0);
        for _ in 0..1000 {
            let cell: [u32; 3] = std::array::from_fn(|_| rand::Rng::random_range(&mut rng, 0..=MAX));
            assert_eq!(decode(encode(cell)), cell);
        }
    }

    #[test]
    fn quantize_spans_the_box_and_clamps_outside_it() {
        let (lo, hi) = (Vec3::new(-1.0, 0.0, 2.0), Vec3::new(1.0, 0.0, 4.0));
        assert_eq!(quantize(lo, lo, hi), [0, 0, 0]);
        assert_eq!(quantize(hi, lo, hi), [MAX, 0, MAX]);
        assert_eq!(quantize(Vec3::new(5.0, 3.0, -9.0), lo, hi), [MAX, 0, 0]);
        // Points in order along an axis keep their order in code.
        let codes: Vec<u64> =
            (0..10).map(|i| encode(quantize(Vec3::new(-1.0 + 0.2 * i as f32, 0.0, 3.0), lo, hi))).collect();
        assert!(codes.windows(2).all(|w| w[0] < w[1]));
    }
}
