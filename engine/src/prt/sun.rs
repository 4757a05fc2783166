//! The sun: a small, very bright source in an environment map, split off so that the baked
//! look shades it as a directional light with a shadow ray, while PRT and the prefiltered
//! specular carry the rest of the sky. Low-order SH cannot hold a source 10⁵ times its sky —
//! it rings, and its shadows blur into copies per region — and 32 lobe samples miss it.
//!
//! The split is exact: the residual map plus the sun's texels is the map. The sun is the
//! brightest texel's 8-connected neighbourhood of texels at least 1/100 of its luminance; it
//! counts as a sun when that patch is small (under [`MAX_SOLID_ANGLE`]) and holds at least
//! [`MIN_SHARE`] of the map's power. Its texels are replaced in the residual by the mean of the
//! texels around the patch.

use crate::math::luminance;
use crate::scene::{EnvMap, EnvironmentLight, environment::uv_to_dir};
use glam::{Quat, Vec2, Vec3};
use std::f32::consts::PI;
use std::sync::Arc;

/// Largest patch that is split off as a sun (steradians; a cap of ≈ 6.5° radius).
pub const MAX_SOLID_ANGLE: f32 = 0.04;
/// Smallest share of the map's power a patch needs to be split off.
pub const MIN_SHARE: f32 = 0.2;
/// A texel belongs to the patch when its luminance is at least this fraction of the peak's.
const PATCH_FRACTION: f32 = 0.01;

/// A sun: in the map's frame as [`split`] finds it, in world space after [`Sun::in_world`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sun {
    /// Unit direction toward the sun (power-weighted mean of its texels).
    pub direction: Vec3,
    /// Irradiance it gives a surface facing it (radiance × solid angle, summed; RGB).
    pub irradiance: Vec3,
    /// Angular radius of a disc of the patch's solid angle (radians).
    pub angular_radius: f32,
}

impl Sun {
    /// This map-frame sun under `env`'s rotation and intensity.
    pub fn in_world(self, env: &EnvironmentLight) -> Self {
        Self {
            direction: Quat::from_rotation_y(env.rotation) * self.direction,
            irradiance: self.irradiance * env.intensity,
            ..self
        }
    }
}

fn texel_solid_angle(y: usize, w: usize, h: usize) -> f32 {
    crate::scene::environment::texel_solid_angle(y, w, h) as f32
}

/// The 8-connected neighbours of texel `i` (wrapping in longitude).
fn neighbours(i: usize, w: usize, h: usize) -> impl Iterator<Item = usize> {
    let (x, y) = ((i % w) as isize, (i / w) as isize);
    (-1..=1isize).flat_map(move |dy| (-1..=1isize).map(move |dx| (dx, dy))).filter_map(move |(dx, dy)| {
        let ny = y + dy;
        ((dx, dy) != (0, 0) && (0..h as isize).contains(&ny))
            .then(|| ny as usize * w + (x + dx).rem_euclid(w as isize) as usize)
    })
}

/// Splits `map` into its sun and the residual map (`None`: no patch qualifies as a sun).
pub fn split(map: &EnvMap) -> Option<(Sun, EnvMap)> {
    let (w, h) = (map.width, map.height);
    let lum: Vec<f32> = map.texels.iter().map(|t| luminance(*t)).collect();
    let peak = (0..lum.len()).max_by(|a, b| lum[*a].total_cmp(&lum[*b]))?;
    let threshold = lum[peak] * PATCH_FRACTION;
    let mut inside = vec![false; lum.len()];
    let (mut patch, mut stack) = (Vec::new(), vec![peak]);
    inside[peak] = true;
    while let Some(i) = stack.pop() {
        patch.push(i);
        for n in neighbours(i, w, h) {
            if !inside[n] && lum[n] >= threshold {
                inside[n] = true;
                stack.push(n);
            }
        }
    }
    patch.sort_unstable();
    let omega: f32 = patch.iter().map(|&i| texel_solid_angle(i / w, w, h)).sum();
    // The fill: the mean radiance of the texels bordering the patch.
    let mut ring: Vec<usize> = patch.iter().flat_map(|&i| neighbours(i, w, h)).filter(|&n| !inside[n]).collect();
    ring.sort_unstable();
    ring.dedup();
    let fill = ring.iter().map(|&i| map.texels[i]).sum::<Vec3>() / ring.len().max(1) as f32;
    let power = |i: usize, l: f32| l * texel_solid_angle(i / w, w, h);
    let total: f32 = (0..lum.len()).map(|i| power(i, lum[i])).sum();
    let (mut irradiance, mut weighted) = (Vec3::ZERO, Vec3::ZERO);
    for &i in &patch {
        let excess = (map.texels[i] - fill).max(Vec3::ZERO) * texel_solid_angle(i / w, w, h);
        let uv = Vec2::new(((i % w) as f32 + 0.5) / w as f32, ((i / w) as f32 + 0.5) / h as f32);
        irradiance += excess;
        weighted += uv_to_dir(uv) * luminance(excess);
    }
    if omega > MAX_SOLID_ANGLE || luminance(irradiance) < MIN_SHARE * total {
        return None;
    }
    let mut texels = map.texels.clone();
    patch.iter().for_each(|&i| texels[i] = texels[i].min(fill));
    let residual = EnvMap::new(w, h, texels, map.source.clone()).ok()?;
    let angular_radius = (1.0 - omega / (2.0 * PI)).clamp(-1.0, 1.0).acos();
    Some((Sun { direction: weighted.normalize(), irradiance, angular_radius }, residual))
}

/// `env` without its sun (a light of the residual map), and the sun in world space.
pub fn split_light(env: &EnvironmentLight) -> Option<(Sun, EnvironmentLight)> {
    let (sun, residual) = split(&env.map)?;
    let rest = EnvironmentLight { map: Arc::new(residual), ..env.clone() };
    Some((sun.in_world(env), rest))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::environment::dir_to_uv;

    /// A dim sky with a bright 3×3-texel sun toward `dir`.
    fn sky_with_sun(dir: Vec3, radiance: f32) -> EnvMap {
        let (w, h) = (128, 64);
        let uv = dir_to_uv(dir);
        let (cx, cy) = ((uv.x * w as f32) as isize, (uv.y * h as f32) as isize);
        let texels = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as isize, (i / w) as isize);
                let sky = Vec3::new(0.3, 0.5, 1.0) * (1.0 + 0.2 * (y as f32 / h as f32));
                if (x - cx).abs() <= 1 && (y - cy).abs() <= 1 { sky + Vec3::splat(radiance) } else { sky }
            })
            .collect();
        EnvMap::new(w, h, texels, "test".into()).unwrap()
    }

    fn power(map: &EnvMap) -> Vec3 {
        map.texels.iter().enumerate().map(|(i, t)| *t * texel_solid_angle(i / map.width, map.width, map.height)).sum()
    }

    #[test]
    fn the_sun_and_the_residual_add_up_to_the_map() {
        let dir = Vec3::new(0.3, 0.8, -0.5).normalize();
        let map = sky_with_sun(dir, 5e4);
        let (sun, residual) = split(&map).expect("a sun");
        let sum = power(&residual) + sun.irradiance;
        assert!((sum - power(&map)).abs().max_element() < 1e-3 * power(&map).max_element(), "{sum} vs {}", power(&map));
        assert!(sun.direction.dot(dir) > 0.999, "{}", sun.direction);
        assert!(sun.angular_radius > 0.0 && sun.angular_radius < 0.1, "{}", sun.angular_radius);
        let peak = residual.texels.iter().map(|t| luminance(*t)).fold(0.0, f32::max);
        assert!(peak < 1.0, "the residual keeps no sun: {peak}");
    }

    #[test]
    fn a_sky_without_a_dominant_source_has_no_sun() {
        assert!(split(&sky_with_sun(Vec3::Y, 0.5)).is_none(), "a faint patch is no sun");
        let uniform = EnvMap::new(8, 4, vec![Vec3::ONE; 32], "uniform".into()).unwrap();
        assert!(split(&uniform).is_none(), "a patch covering the sky is no sun");
    }

    #[test]
    fn the_light_turns_and_scales_its_sun() {
        let map = sky_with_sun(Vec3::new(0.0, 0.6, -0.8), 5e4);
        let env = EnvironmentLight { map: Arc::new(map), intensity: 2.0, rotation: 0.5 };
        let (sun, _) = split_light(&env).unwrap();
        let (plain, _) = split(&env.map).unwrap();
        assert!((sun.irradiance - plain.irradiance * 2.0).abs().max_element() < 1e-3);
        assert!(sun.direction.dot(Quat::from_rotation_y(0.5) * plain.direction) > 0.99999);
    }
}
