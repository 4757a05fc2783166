//! The Monte Carlo reference integrator: ground truth for every error figure.
//!
//! A path tracer with next-event estimation. Direct light from polygonal lights (area sampling
//! converted to solid angle) and from the environment (luminance importance sampling) is
//! combined with BSDF sampling by multiple importance sampling (power heuristic). With
//! `max_bounces = 0` it computes direct lighting only; each extra bounce adds one order of
//! indirect light through the same loop, so indirect references need no second implementation.
//!
//! Every pixel or vertex draws from its own random stream seeded by (seed, index), so results
//! are bit-identical on any number of threads; each estimate carries its standard error.

mod integrator;

pub use integrator::{Renderer, SurfacePoint};

use glam::Vec3;

/// Estimator settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Settings {
    /// Samples per pixel (or per vertex).
    pub spp: u32,
    /// Seed of every random stream.
    pub seed: u64,
    /// Indirect bounces after the first surface (0 = direct lighting only).
    pub max_bounces: u32,
    /// Bounces skipped before light is counted: 1 estimates the indirect light alone (the
    /// ground truth of the radiance cache), 0 everything.
    pub min_bounces: u32,
}

impl Default for Settings {
    fn default() -> Self {
        Self { spp: 64, seed: 0, max_bounces: 0, min_bounces: 0 }
    }
}

/// A Monte Carlo estimate of linear RGB radiance with its standard error.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Estimate {
    /// Sample mean.
    pub mean: Vec3,
    /// Standard error of the mean, per channel.
    pub std_error: Vec3,
}

/// The estimates' own relative standard error: RMS of their standard errors over RMS of their
/// means (0 when every mean is 0).
pub fn relative_standard_error<'a>(estimates: impl IntoIterator<Item = &'a Estimate>) -> f64 {
    let (se, mean) = estimates.into_iter().fold((0.0, 0.0), |(a, b), e| {
        (a + e.std_error.as_dvec3().length_squared(), b + e.mean.as_dvec3().length_squared())
    });
    if mean > 0.0 { (se / mean).sqrt() } else { 0.0 }
}

/// Running sums for an [`Estimate`] (f64, so long runs do not lose precision).
#[derive(Clone, Copy, Debug, Default)]
pub struct Accumulator {
    sum: glam::DVec3,
    sum_sq: glam::DVec3,
    n: u64,
}

impl Accumulator {
    /// Adds one sample; non-finite samples are counted as zero (and should never occur).
    pub fn add(&mut self, x: Vec3) {
        let x = if x.is_finite() { x.as_dvec3() } else { glam::DVec3::ZERO };
        self.sum += x;
        self.sum_sq += x * x;
        self.n += 1;
    }

    /// The mean and its standard error.
    pub fn estimate(&self) -> Estimate {
        if self.n == 0 {
            return Estimate::default();
        }
        let n = self.n as f64;
        let mean = self.sum / n;
        let var = if self.n > 1 {
            ((self.sum_sq - self.sum * mean) / (n - 1.0)).max(glam::DVec3::ZERO)
        } else {
            glam::DVec3::ZERO
        };
        Estimate { mean: mean.as_vec3(), std_error: (var / n).map(f64::sqrt).as_vec3() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accumulator_mean_and_error() {
        let mut a = Accumulator::default();
        for x in [1.0f32, 2.0, 3.0, 4.0] {
            a.add(Vec3::splat(x));
        }
        let e = a.estimate();
        assert!((e.mean.x - 2.5).abs() < 1e-6);
        // sample variance 5/3, se = sqrt(5/3/4)
        assert!((e.std_error.x - (5.0f32 / 12.0).sqrt()).abs() < 1e-6);
    }
}
