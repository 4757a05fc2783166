//! Fast trigonometry where libm's correctly rounded calls dominate a hot loop.

/// sin x and cos x to within 1e-12 for |x| < 1e5: reduced by quarter turns (π/2 in two parts,
/// Cody–Waite), then Taylor polynomials on [−π/4, π/4] to the 13th and 14th powers. The BSPVT split
/// search calls it at every step, where libm's `sin_cos` (correct to the last bit, not inlined) was a
/// fifth of the search's time.
#[inline]
pub fn sin_cos(x: f64) -> (f64, f64) {
    use std::f64::consts::{FRAC_2_PI, FRAC_PI_2};
    // π/2 − FRAC_PI_2.
    const PIO2_LO: f64 = 6.123_233_995_736_766e-17;
    let q = (x * FRAC_2_PI).round();
    let r = (-q).mul_add(PIO2_LO, (-q).mul_add(FRAC_PI_2, x));
    let r2 = r * r;
    // 1/n! for the odd and even powers.
    let odd = [-1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0, 1.0 / 362_880.0, -1.0 / 39_916_800.0, 1.0 / 6_227_020_800.0];
    let even = [
        -0.5,
        1.0 / 24.0,
        -1.0 / 720.0,
        1.0 / 40_320.0,
        -1.0 / 3_628_800.0,
        1.0 / 479_001_600.0,
        -1.0 / 87_178_291_200.0,
    ];
    let horner = |k: &[f64]| k.iter().rev().fold(0.0_f64, |acc, &c| acc.mul_add(r2, c));
    let sin = (r * r2).mul_add(horner(&odd), r);
    let cos = r2.mul_add(horner(&even), 1.0);
    match (q as i64).rem_euclid(4) {
        0 => (sin, cos),
        1 => (cos, -sin),
        2 => (-sin, -cos),
        _ => (-cos, sin),
    }
}

/// atan2(y, x) to within 4e-6 rad, in (−π, π]: the odd minimax polynomial of atan on
/// [−1, 1] (Abramowitz & Stegun 4.4.49's form, 11th degree) and the octant's symmetries. The
/// filtered environment lookups call it for every GGX sample, where libm's `atan2f` was a
/// tenth of re-shading a frame; 4e-6 rad is a thousandth of a 512-texel map's texel.
#[inline]
pub fn atan2(y: f32, x: f32) -> f32 {
    use std::f32::consts::{FRAC_PI_2, PI};
    let (ax, ay) = (x.abs(), y.abs());
    let (lo, hi) = (ax.min(ay), ax.max(ay));
    if hi == 0.0 {
        return if x.is_sign_negative() { PI.copysign(y) } else { 0.0f32.copysign(y) };
    }
    let t = lo / hi;
    let t2 = t * t;
    let k = [-0.011_721_2, 0.052_653_32, -0.116_432_87, 0.193_543_46, -0.332_623_47, 0.999_977_26];
    let mut a = t * k.iter().fold(0.0f32, |acc, &c| acc.mul_add(t2, c));
    if ay > ax {
        a = FRAC_PI_2 - a;
    }
    if x < 0.0 {
        a = PI - a;
    }
    a.copysign(y)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Within 4e-6 rad of libm's over the circle (both signs of zero included), and it inverts
    /// polar coordinates: (r cos a, r sin a) gives back a.
    #[test]
    fn atan2_is_close_to_libm_and_inverts_polar_coordinates() {
        let mut worst = 0.0f32;
        for k in 0..100_000 {
            let a = -std::f32::consts::PI + (k as f32 + 0.5) * std::f32::consts::TAU / 100_000.0;
            let (y, x) = (2.5 * a.sin(), 2.5 * a.cos());
            worst = worst.max((atan2(y, x) - y.atan2(x)).abs()).max((atan2(y, x) - a).abs());
        }
        assert!(worst < 4e-6, "{worst:e}");
        for (y, x) in [(0.0, 1.0), (-0.0, 1.0), (0.0, -1.0), (-0.0, -1.0), (1.0, 0.0), (-1.0, 0.0), (0.0, 0.0)] {
            assert!((atan2(y, x) - f32::atan2(y, x)).abs() < 1e-6, "atan2({y}, {x})");
            assert_eq!(atan2(y, x).is_sign_negative(), f32::atan2(y, x).is_sign_negative(), "atan2({y}, {x})");
        }
    }

    /// Within 1e-12 of libm's, across many turns either way.
    #[test]
    fn sin_cos_is_close_to_libm() {
        let worst = (-200_000..=200_000).map(|k| k as f64 * 1e-3 + 1e-7 * (k as f64).sin()).fold(0.0f64, |worst, x| {
            let (s, c) = sin_cos(x);
            worst.max((s - x.sin()).abs()).max((c - x.cos()).abs())
        });
        assert!(worst < 1e-12, "{worst:e}");
        assert_eq!(sin_cos(0.0), (0.0, 1.0));
    }
}
