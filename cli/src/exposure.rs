//! `--exposure`: stops, or `auto` to meter the result (the default).

use glam::Vec3;
use kage_engine::math::color::metered_exposure;

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
            Self::Auto => {
                let ev = metered_exposure(values);
                crate::emit(&format!("exposure: {ev:+.2} stops (metered; --exposure sets it)\n"));
                ev
            }
        }
    }
}
