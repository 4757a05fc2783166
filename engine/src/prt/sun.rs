//! The environment map's sun at bake and render time: the runtime's split
//! ([`kage_runtime::prt::sun`]) over kage's maps and lights, and how many shadow rays the
//! baked look casts toward a soft one.

use crate::scene::{EnvMap, EnvironmentLight};
use glam::Quat;
pub use kage_runtime::prt::sun::{MAX_SOLID_ANGLE, MIN_SHARE, SOFT_RADIUS, Sun};
use std::sync::Arc;

/// Shadow rays toward a sun wider than [`SOFT_RADIUS`] per vertex.
pub const VERTEX_RAYS: usize = 16;
/// Shadow rays toward a sun wider than [`SOFT_RADIUS`] per image sample or gather hit: a
/// pixel's samples (16 in `kage render`'s images) and a record's hits each turn the pattern
/// their own way, and average.
pub const SAMPLE_RAYS: usize = 4;

/// Splits `map` into its sun and the residual map (`None`: no patch qualifies as a sun).
pub fn split(map: &EnvMap) -> Option<(Sun, EnvMap)> {
    let (sun, texels) = kage_runtime::prt::sun::split(map.width, map.height, &map.texels)?;
    Some((sun, EnvMap::new(map.width, map.height, texels, map.source.clone()).ok()?))
}

/// `env` without its sun (a light of the residual map), and the sun in world space.
pub fn split_light(env: &EnvironmentLight) -> Option<(Sun, EnvironmentLight)> {
    let (sun, residual) = split(&env.map)?;
    let rest = EnvironmentLight { map: Arc::new(residual), ..env.clone() };
    Some((sun.placed(Quat::from_rotation_y(env.rotation), env.intensity), rest))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::luminance;
    use crate::scene::environment::dir_to_uv;
    use glam::Vec3;

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
        map.texels
            .iter()
            .enumerate()
            .map(|(i, t)| {
                *t * crate::scene::environment::texel_solid_angle(i / map.width, map.width, map.height) as f32
            })
            .sum()
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

    /// A sun whose 3×3 core holds nearly all its power spreads less than its patch, which a
    /// dim rim out to 5×5 texels widens: its shadows follow the core.
    #[test]
    fn a_dim_rim_widens_the_patch_but_not_the_spread() {
        let dir = Vec3::new(0.3, 0.8, -0.5).normalize();
        let core = split(&sky_with_sun(dir, 5e4)).expect("a sun").0;
        let (w, h) = (128, 64);
        let mut rimmed = sky_with_sun(dir, 5e4);
        let uv = dir_to_uv(dir);
        let (cx, cy) = ((uv.x * w as f32) as isize, (uv.y * h as f32) as isize);
        for (i, t) in rimmed.texels.iter_mut().enumerate() {
            let (x, y) = ((i % w) as isize, (i / w) as isize);
            if (x - cx).abs().max((y - cy).abs()) == 2 {
                *t += Vec3::splat(1e3);
            }
        }
        let sun = split(&rimmed).expect("a sun").0;
        assert!(sun.angular_radius > 1.5 * core.angular_radius, "{} vs {}", sun.angular_radius, core.angular_radius);
        assert!(sun.spread < 0.75 * sun.angular_radius, "{} vs {}", sun.spread, sun.angular_radius);
        assert!((core.spread / core.angular_radius - 1.0).abs() < 0.25, "a uniform patch: {core:?}");
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
