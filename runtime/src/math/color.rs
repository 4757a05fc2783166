//! Colour: the sRGB transfer function, luminance and exposure metering.

use glam::Vec3;

/// sRGB transfer function → linear.
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

/// Linear → sRGB transfer function, the inverse of [`srgb_to_linear`] on [0, 1].
pub fn linear_to_srgb(c: f32) -> f32 {
    if c <= 0.0031308 { c * 12.92 } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 }
}

/// Luminance of a linear Rec.709 colour.
pub fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// Middle grey: the log-average luminance [`metered_exposure`] maps the scene to.
const KEY: f32 = 0.18;
/// The share of values [`metered_exposure`] lets clip at 1 (the brightest 5 %, e.g. lights).
const CLIPPED: f32 = 0.05;
/// Where the brightest value that must not clip lands.
const HEADROOM: f32 = 0.9;

/// The exposure in stops that shows `values` well on a display clamped to [0, 1], as a
/// camera's averaging meter does: the log-average luminance maps to middle grey (Reinhard et
/// al. 2002's key of 0.18), lowered so that at most the brightest 5 % clip. Non-finite and
/// negative values are ignored; 0 stops when nothing is lit.
pub fn metered_exposure(values: impl IntoIterator<Item = Vec3>) -> f32 {
    let values: Vec<Vec3> = values.into_iter().collect();
    metered_exposure_keeping(&values, &values)
}

/// [`metered_exposure`] with the clipping judged on part of the values: `values`' log-average
/// luminance maps to middle grey, lowered so that at most the brightest 5 % of `kept` clip (an
/// image's surfaces among its pixels: a small object under a dark sky keeps its highlights).
pub fn metered_exposure_keeping(values: &[Vec3], kept: &[Vec3]) -> f32 {
    let lit = |values: &[Vec3]| -> Vec<f32> {
        values.iter().copied().map(luminance).filter(|l| l.is_finite() && *l > 0.0).collect()
    };
    let (values, mut kept) = (lit(values), lit(kept));
    if values.is_empty() || kept.is_empty() {
        return 0.0;
    }
    let log_average = (values.iter().map(|l| f64::from(*l).ln()).sum::<f64>() / values.len() as f64).exp() as f32;
    let k = ((kept.len() - 1) as f32 * (1.0 - CLIPPED)).round() as usize;
    let bright = *kept.select_nth_unstable_by(k, f32::total_cmp).1;
    (KEY / log_average).log2().min((HEADROOM / bright).log2()).clamp(-32.0, 32.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn metering_maps_a_uniform_image_to_middle_grey_and_ignores_scale() {
        for radiance in [1e-3f32, 0.18, 40.0] {
            let ev = metered_exposure(vec![Vec3::splat(radiance); 100]);
            assert!((radiance * ev.exp2() - KEY).abs() < 1e-4, "{radiance}: {ev}");
        }
        assert_eq!(metered_exposure(vec![Vec3::ZERO, Vec3::NAN, Vec3::splat(-1.0)]), 0.0);
    }

    /// A bright object on 6 % of a dark image: metered alike, most of it clips; keeping it,
    /// 5 % of it at most; keeping everything is plain metering.
    #[test]
    fn metering_keeps_the_kept_values_highlights() {
        let object: Vec<Vec3> = (0..60).map(|k| Vec3::splat(1.0 + k as f32 / 60.0)).collect();
        let image: Vec<Vec3> = object.iter().copied().chain(std::iter::repeat_n(Vec3::splat(0.01), 940)).collect();
        let clipped = |ev: f32| object.iter().filter(|v| luminance(**v) * ev.exp2() > 1.0).count();
        assert!(clipped(metered_exposure(image.iter().copied())) > 30);
        assert!(clipped(metered_exposure_keeping(&image, &object)) <= 3);
        assert_eq!(metered_exposure_keeping(&image, &image), metered_exposure(image.iter().copied()));
    }

    #[test]
    fn metering_keeps_all_but_the_brightest_values_from_clipping() {
        // Half the image at 0.01, half at 1.5: the log-average alone would clip the bright half.
        let values: Vec<Vec3> = (0..200).map(|k| Vec3::splat(if k % 2 == 0 { 0.01 } else { 1.5 })).collect();
        let scale = metered_exposure(values).exp2();
        assert!((1.5 * scale - HEADROOM).abs() < 1e-4, "{scale}");
        // A small bright light does not darken the rest.
        let mut lamp: Vec<Vec3> = vec![Vec3::splat(0.5); 99];
        lamp.push(Vec3::splat(1e5));
        assert!((0.5 * metered_exposure(lamp).exp2() - 0.18).abs() < 0.05);
    }

    #[test]
    fn every_8_bit_srgb_value_round_trips_through_linear() {
        for b in 0..=255u8 {
            let linear = srgb_to_linear(b as f32 / 255.0);
            assert_eq!((linear_to_srgb(linear) * 255.0).round() as u8, b, "byte {b}");
        }
        for x in [0.0f32, 1e-4, 0.0031308, 0.2, 0.5, 1.0] {
            assert!((srgb_to_linear(linear_to_srgb(x)) - x).abs() <= 1e-6, "{x}");
        }
    }

    #[test]
    fn srgb_endpoints() {
        assert_eq!(linear_to_srgb(0.0), 0.0);
        assert!((linear_to_srgb(1.0) - 1.0).abs() < 1e-6);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
    }
}
