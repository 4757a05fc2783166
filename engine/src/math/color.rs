//! Colour: the sRGB transfer function and luminance.

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

#[cfg(test)]
mod tests {
    use super::*;

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
