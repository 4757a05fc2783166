//! `--exposure`: stops, or `auto` to meter the result (the default).

use glam::Vec3;
use kage_engine::math::color::{metered_exposure, metered_exposure_keeping};

/// How bright displayed results are: a fixed number of stops, or metered from the values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Exposure {
    /// Metered: the log-average maps to middle grey, at most the brightest 5 % clip.
    Auto,
    /// Radiance × 2^stops.
    Stops(f32),
}

impl std::str::FromStr for Exposure {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        if s.eq_ignore_ascii_case("auto") {
            return Ok(Self::Auto);
        }
        match s.parse::<f32>() {
            Ok(ev) if ev.is_finite() && ev.abs() <= 64.0 => Ok(Self::Stops(ev)),
            _ => Err(format!("expected 'auto' or stops between -64 and 64, got '{s}'")),
        }
    }
}

impl Exposure {
    /// The stops to apply to `values`, printed when metered so that a run can be repeated.
    pub fn stops(self, values: impl IntoIterator<Item = Vec3>) -> f32 {
        match self {
            Self::Stops(ev) => ev,
            Self::Auto => printed(metered_exposure(values)),
        }
    }

    /// The stops to apply to an image's `pixels`: metered on all of them, with at most 5 % of
    /// those that show a surface (`surfaces`, asked only when metering; every pixel when none
    /// does) clipping — a small bright object under a dark sky is not blown out.
    pub fn image_stops(self, pixels: &[Vec3], surfaces: impl FnOnce() -> Vec<bool>) -> f32 {
        match self {
            Self::Stops(ev) => ev,
            Self::Auto => {
                let on: Vec<Vec3> = pixels.iter().zip(surfaces()).filter(|(_, s)| *s).map(|(p, _)| *p).collect();
                printed(metered_exposure_keeping(pixels, if on.is_empty() { pixels } else { &on }))
            }
        }
    }
}

/// Prints metered stops so that a run can be repeated with them.
fn printed(ev: f32) -> f32 {
    crate::emit(&format!("exposure: {ev:+.2} stops (metered; --exposure sets it)\n"));
    ev
}
