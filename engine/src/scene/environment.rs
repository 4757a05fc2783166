//! Environment lights: equirectangular radiance maps (`.hdr`, `.exr`) with luminance importance
//! sampling, and a procedural sky for the built-in scene.
//!
//! Mapping (docs/conventions.md): `u = frac(atan2(d.x, −d.z) / 2π)`, `v = acos(d.y) / π`, row 0 = +Y;
//! the user rotation turns the map by `rotation` radians about +Y (counter-clockwise seen from above).
//! Lighting lookups are nearest-texel so that the sampling pdf is exact; what a camera sees
//! behind the geometry is filtered bilinearly ([`EnvironmentLight::background`]), as a texture
//! is, so a 512-texel map does not show its texels as blocks.

use crate::math::distribution::Distribution2D;
use crate::math::luminance;
use crate::{Error, Result};
use glam::{Quat, Vec2, Vec3};
use std::f32::consts::PI;
use std::path::Path;
use std::sync::Arc;

/// An equirectangular radiance map with its sampling distribution.
#[derive(Clone, Debug)]
pub struct EnvMap {
    /// Width in texels.
    pub width: usize,
    /// Height in texels.
    pub height: usize,
    /// Row-major linear RGB radiance, row 0 = +Y.
    pub texels: Vec<Vec3>,
    /// Where it came from (a path or `procedural:sky`).
    pub source: String,
    distribution: Distribution2D,
}

pub use kage_runtime::math::equirect::{bilinear, dir_to_uv, texel_solid_angle, uv_to_dir};

/// The most texels an environment map may have (8192 × 4096): a file's header is checked
/// against it before decoding, so that a few bytes cannot claim gigabytes.
pub const MAX_TEXELS: u64 = 8192 * 4096;

/// An EXR's display window (the image the decoder allocates) must be no larger than its data
/// window (the pixels the file holds): a damaged header cannot claim memory its data lacks.
fn exr_windows(bytes: &[u8]) -> std::result::Result<(), String> {
    let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false)
        .map_err(|e| format!("cannot decode: {e}"))?;
    let header = meta.headers.first().ok_or("cannot decode: the file has no header")?;
    let (display, data) = (header.shared_attributes.display_window.size, header.layer_size);
    if display.area() > data.area() {
        return Err(format!(
            "its display window ({}×{}) is larger than its data window ({}×{}); an environment map's pixels must cover it",
            display.width(),
            display.height(),
            data.width(),
            data.height()
        ));
    }
    Ok(())
}

impl EnvMap {
    /// Builds a map from texels; NaN, infinite or negative radiance is rejected.
    pub fn new(width: usize, height: usize, texels: Vec<Vec3>, source: String) -> Result<Self> {
        if width < 2 || height < 1 || texels.len() != width * height {
            return Err(Error::image(
                &source,
                format!("environment map must be at least 2×1 texels, got {width}×{height}"),
            ));
        }
        if let Some(i) = texels.iter().position(|t| !t.is_finite()) {
            return Err(Error::image(&source, format!("texel ({}, {}) is NaN or infinite", i % width, i / width)));
        }
        if let Some(i) = texels.iter().position(|t| t.min_element() < 0.0) {
            return Err(Error::image(&source, format!("texel ({}, {}) has negative radiance", i % width, i / width)));
        }
        // Luminance × sin θ: the row's solid angle per texel.
        let weights: Vec<f32> = texels
            .iter()
            .enumerate()
            .map(|(i, t)| luminance(*t) * (PI * ((i / width) as f32 + 0.5) / height as f32).sin())
            .collect();
        let distribution = Distribution2D::new(&weights, width, height);
        Ok(Self { width, height, texels, source, distribution })
    }

    /// Loads a Radiance `.hdr` or OpenEXR `.exr` equirectangular map.
    pub fn load(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        let format = image::ImageFormat::from_path(path)
            .ok()
            .filter(|f| matches!(f, image::ImageFormat::Hdr | image::ImageFormat::OpenExr))
            .ok_or_else(|| Error::image(path, "environment maps must be .hdr or .exr"))?;
        let decode_error = |e: image::ImageError| Error::image(path, format!("cannot decode: {e}"));
        let reader = || image::ImageReader::with_format(std::io::Cursor::new(&bytes), format);
        // The header's size is checked before the decoder allocates for it.
        let (w, h) = reader().into_dimensions().map_err(decode_error)?;
        if u64::from(w) * u64::from(h) > MAX_TEXELS {
            let limit = "8192×4096 texels: downsample the map";
            return Err(Error::image(path, format!("the map declares {w}×{h} texels, more than the limit of {limit}")));
        }
        if format == image::ImageFormat::OpenExr {
            exr_windows(&bytes).map_err(|m| Error::image(path, m))?;
        }
        let mut limited = reader();
        let mut limits = image::Limits::default();
        limits.max_alloc = Some(MAX_TEXELS * 16);
        limited.limits(limits);
        let img = limited.decode().map_err(decode_error)?.into_rgb32f();
        let (w, h) = (img.width() as usize, img.height() as usize);
        let texels = img.pixels().map(|p| Vec3::from_array(p.0)).collect();
        Self::new(w, h, texels, path.display().to_string())
    }

    /// A procedural sky: a blue zenith fading to a bright horizon, a warm sun glow, and a dim
    /// ground below the horizon. Smooth, so that it is an easy case for every method.
    pub fn procedural_sky(width: usize, height: usize, sun: Vec3) -> Self {
        let sun = sun.normalize();
        let texels = (0..width * height)
            .map(|i| {
                let uv =
                    Vec2::new(((i % width) as f32 + 0.5) / width as f32, ((i / width) as f32 + 0.5) / height as f32);
                let d = uv_to_dir(uv);
                if d.y < 0.0 {
                    return Vec3::new(0.18, 0.16, 0.14) * (1.0 + d.y).max(0.3);
                }
                let zenith = Vec3::new(0.25, 0.45, 0.9);
                let horizon = Vec3::new(0.9, 0.95, 1.0);
                let sky = horizon.lerp(zenith, d.y.powf(0.5));
                let glow = Vec3::new(1.0, 0.85, 0.6) * 4.0 * d.dot(sun).max(0.0).powi(64);
                sky + glow
            })
            .collect();
        Self::new(width, height, texels, "procedural:sky".into()).expect("procedural sky is finite and non-negative")
    }

    /// Radiance of the texel containing `uv`.
    pub fn lookup(&self, uv: Vec2) -> Vec3 {
        let i = ((uv.x * self.width as f32) as usize).min(self.width - 1);
        let j = ((uv.y * self.height as f32) as usize).min(self.height - 1);
        self.texels[j * self.width + i]
    }

    /// Radiance at `uv` interpolated bilinearly between texel centres, wrapping around in u
    /// and clamped at the poles in v.
    pub fn bilinear(&self, uv: Vec2) -> Vec3 {
        bilinear(self.width, self.height, &self.texels, uv)
    }

    /// Solid-angle pdf of sampling `uv`'s direction: pdf_uv / (2π² sin θ).
    fn pdf_uv(&self, uv: Vec2) -> f32 {
        let sin_theta = (PI * uv.y).sin();
        if sin_theta <= 0.0 {
            return 0.0;
        }
        self.distribution.pdf(uv) / (2.0 * PI * PI * sin_theta)
    }
}

/// An environment light: a map, an intensity multiplier and a rotation about +Y.
#[derive(Clone, Debug)]
pub struct EnvironmentLight {
    /// The radiance map.
    pub map: Arc<EnvMap>,
    /// Radiance multiplier.
    pub intensity: f32,
    /// Rotation about +Y in radians.
    pub rotation: f32,
}

/// A direction sampled from an environment light.
#[derive(Clone, Copy, Debug)]
pub struct EnvSample {
    /// World direction towards the environment.
    pub dir: Vec3,
    /// Radiance arriving from it.
    pub radiance: Vec3,
    /// Solid-angle pdf.
    pub pdf: f32,
}

impl EnvironmentLight {
    /// An unrotated light with intensity 1.
    pub fn new(map: EnvMap) -> Self {
        Self { map: Arc::new(map), intensity: 1.0, rotation: 0.0 }
    }

    fn to_map(&self, world: Vec3) -> Vec3 {
        Quat::from_rotation_y(-self.rotation) * world
    }

    /// Radiance arriving from world direction `dir`.
    pub fn radiance(&self, dir: Vec3) -> Vec3 {
        self.map.lookup(dir_to_uv(self.to_map(dir))) * self.intensity
    }

    /// What a camera sees along world direction `dir`: the map filtered bilinearly
    /// ([`EnvMap::bilinear`]); lighting uses [`Self::radiance`].
    pub fn background(&self, dir: Vec3) -> Vec3 {
        self.map.bilinear(dir_to_uv(self.to_map(dir))) * self.intensity
    }

    /// Solid-angle pdf of [`Self::sample`] producing `dir`.
    pub fn pdf(&self, dir: Vec3) -> f32 {
        self.map.pdf_uv(dir_to_uv(self.to_map(dir)))
    }

    /// Importance-samples a direction by luminance.
    pub fn sample(&self, u: Vec2) -> Option<EnvSample> {
        let (uv, _) = self.map.distribution.sample(u);
        let pdf = self.map.pdf_uv(uv);
        if pdf <= 0.0 {
            return None;
        }
        let dir = Quat::from_rotation_y(self.rotation) * uv_to_dir(uv);
        Some(EnvSample { dir, radiance: self.map.lookup(uv) * self.intensity, pdf })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{rng, sampling};
    use rand::Rng;

    #[test]
    fn mapping_matches_the_convention_and_round_trips() {
        assert!((dir_to_uv(Vec3::Z) - Vec2::new(0.5, 0.5)).length() < 1e-6, "image centre is +Z");
        assert!((dir_to_uv(Vec3::X) - Vec2::new(0.25, 0.5)).length() < 1e-6, "u = 0.25 is +X");
        assert!(dir_to_uv(Vec3::Y).y < 1e-6, "top row is +Y");
        let mut r = rng::seeded(1);
        for _ in 0..1000 {
            let d = sampling::uniform_sphere(Vec2::new(r.random(), r.random()));
            assert!((uv_to_dir(dir_to_uv(d)) - d).length() < 1e-4);
        }
    }

    #[test]
    fn sampling_pdf_is_consistent_and_integrates_radiance() {
        let map = EnvMap::procedural_sky(64, 32, Vec3::new(0.3, 0.6, 0.2));
        let mut light = EnvironmentLight::new(map);
        light.rotation = 0.7;
        let mut r = rng::seeded(2);
        let n = 100_000;
        let (mut by_importance, mut by_uniform) = (Vec3::ZERO.as_dvec3(), Vec3::ZERO.as_dvec3());
        let mut disagree = 0;
        for _ in 0..n {
            let s = light.sample(Vec2::new(r.random(), r.random())).unwrap();
            // The direction's round trip may land in the neighbouring texel at a texel edge.
            if (s.pdf - light.pdf(s.dir)).abs() > 1e-3 * s.pdf {
                disagree += 1;
            }
            assert!((s.radiance - light.radiance(s.dir)).length() < 1e-5);
            by_importance += (s.radiance / s.pdf).as_dvec3();
            let d = sampling::uniform_sphere(Vec2::new(r.random(), r.random()));
            by_uniform += (light.radiance(d) * 4.0 * PI).as_dvec3();
        }
        assert!(disagree < n / 1000, "pdf disagrees with the sample {disagree} times");
        let (a, b) = (by_importance / n as f64, by_uniform / n as f64);
        assert!(((a - b).length() / b.length()) < 0.01, "{a} vs {b}");
    }

    #[test]
    fn the_background_is_the_texel_at_its_centre_and_blends_between_centres() {
        let texels = (0..8).map(|k| Vec3::splat(k as f32)).collect();
        let map = EnvMap::new(4, 2, texels, "test".into()).unwrap();
        let centre = |i: f32, j: f32| Vec2::new((i + 0.5) / 4.0, (j + 0.5) / 2.0);
        for j in 0..2 {
            for i in 0..4 {
                let uv = centre(i as f32, j as f32);
                assert_eq!(map.bilinear(uv), map.lookup(uv), "texel ({i}, {j})");
            }
        }
        assert_eq!(map.bilinear(centre(1.5, 0.0)), Vec3::splat(1.5), "halfway along a row");
        assert_eq!(map.bilinear(centre(0.0, 0.5)), Vec3::splat(2.0), "halfway down a column");
        assert_eq!(map.bilinear(centre(3.5, 1.0)), Vec3::splat(5.5), "across the seam at u = 1");
        assert_eq!(map.bilinear(Vec2::new(0.125, 0.0)), Vec3::splat(0.0), "clamped at the pole");
    }

    #[test]
    fn bad_texels_are_rejected() {
        assert!(EnvMap::new(2, 1, vec![Vec3::ONE, Vec3::NAN], "x".into()).is_err());
        assert!(EnvMap::new(2, 1, vec![Vec3::ONE, -Vec3::ONE], "x".into()).is_err());
        assert!(EnvMap::new(2, 2, vec![Vec3::ONE], "x".into()).is_err());
    }
}
