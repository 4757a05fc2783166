//! The sun: a small, very bright source in an environment map, split off so that it is shaded
//! as a directional light with a shadow (kage's look casts shadow rays, `bevy_kage` lights a
//! `DirectionalLight`), while PRT and the prefiltered specular carry the rest of the sky.
//! Low-order SH cannot hold a source 10⁵ times its sky — it rings, and its shadows blur into
//! copies per region — and 32 lobe samples miss it.
//!
//! The split is exact: the residual map plus the sun's texels is the map. The sun is the
//! brightest texel's 8-connected neighbourhood of texels at least 1/100 of its luminance; it
//! counts as a sun when that patch is small (under [`MAX_SOLID_ANGLE`]) and holds at least
//! [`MIN_SHARE`] of the map's power. Its texels are replaced in the residual by the mean of the
//! texels around the patch.

use crate::math::color::luminance;
use crate::math::equirect::uv_to_dir;
use glam::{Quat, Vec2, Vec3};
use std::f32::consts::PI;

/// Largest patch that is split off as a sun (steradians; a cap of ≈ 6.5° radius).
pub const MAX_SOLID_ANGLE: f32 = 0.04;
/// Smallest share of the map's power a patch needs to be split off.
pub const MIN_SHARE: f32 = 0.2;
/// A texel belongs to the patch when its luminance is at least this fraction of the peak's.
const PATCH_FRACTION: f32 = 0.01;

/// Below this spread ([`Sun::spread`], radians, 2°) one ray through the sun's centre decides its shadow:
/// its penumbra is narrow (`sky.hdr`'s sun, 1.1°: 4 cm at 1 m). Above it the penumbra shows
/// (`studio.hdr`'s brightest lamp, 6.2°: a panel 3 m up casts a 30 cm one).
pub const SOFT_RADIUS: f32 = 0.0349;

/// A sun: in the map's frame as [`split`] finds it, in world space after [`Sun::placed`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sun {
    /// Unit direction toward the sun (power-weighted mean of its texels).
    pub direction: Vec3,
    /// Irradiance it gives a surface facing it (radiance × solid angle, summed; RGB).
    pub irradiance: Vec3,
    /// Angular radius of a disc of the patch's solid angle (radians).
    pub angular_radius: f32,
    /// Angular radius of a uniform disc whose power spreads about the direction as the
    /// patch's does (radians; √2 × the power-weighted RMS angle): what its shadows' penumbrae
    /// follow. Less than [`Sun::angular_radius`] when the patch's dim rim holds little power.
    pub spread: f32,
}

impl Sun {
    /// The tangent of the angle the sun's shadow widens by on each side of its edge, per unit
    /// of distance to the occluder: 0 for a sun under [`SOFT_RADIUS`], shadowed hard.
    pub fn softness(&self) -> f32 {
        if self.spread > SOFT_RADIUS { self.spread.tan() } else { 0.0 }
    }

    /// The directions a point's shadow rays take toward the sun: its centre for a hard sun,
    /// else `rays` over its disc at equal areas (a Vogel spiral), the spiral turned by `turn`
    /// (a fraction of a full turn, 0 to 1; chosen per point, the pattern's offsets average into
    /// a penumbra instead of drawing `rays` copies of the shadow).
    pub fn shadow_directions(&self, rays: usize, turn: f32) -> impl Iterator<Item = Vec3> + use<> {
        let softness = self.softness();
        let rays = if softness > 0.0 { rays } else { 1 };
        let (direction, frame) = (self.direction, crate::math::frame::Frame::from_normal(self.direction));
        (0..rays).map(move |k| {
            if rays == 1 {
                return direction;
            }
            let (r, angle) = vogel(k, rays, turn);
            let offset = Vec3::new(angle.cos(), angle.sin(), 0.0) * (r * softness);
            frame.to_world(Vec3::Z + offset).normalize()
        })
    }

    /// This map-frame sun as an environment turned by `rotation` (map to world) and scaled by
    /// `intensity` shows it.
    pub fn placed(self, rotation: Quat, intensity: f32) -> Self {
        Self { direction: rotation * self.direction, irradiance: self.irradiance * intensity, ..self }
    }
}

/// Point `k` of an `n`-point Vogel spiral on the unit disc turned by `turn` turns: its radius
/// and angle. Point `k` sits at the radius halving the area of its ring (`√((k + ½) / n)`), so
/// each holds an equal area.
fn vogel(k: usize, n: usize, turn: f32) -> (f32, f32) {
    const GOLDEN_ANGLE: f32 = 2.399_963;
    (((k as f32 + 0.5) / n as f32).sqrt(), k as f32 * GOLDEN_ANGLE + turn * 2.0 * PI)
}

fn texel_solid_angle(y: usize, w: usize, h: usize) -> f32 {
    crate::math::equirect::texel_solid_angle(y, w, h) as f32
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

/// Splits a `w × h` equirectangular map's `texels` into its sun and the residual texels
/// (`None`: no patch qualifies as a sun).
pub fn split(w: usize, h: usize, texels: &[Vec3]) -> Option<(Sun, Vec<Vec3>)> {
    let lum: Vec<f32> = texels.iter().map(|t| luminance(*t)).collect();
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
    let fill = ring.iter().map(|&i| texels[i]).sum::<Vec3>() / ring.len().max(1) as f32;
    let power = |i: usize, l: f32| l * texel_solid_angle(i / w, w, h);
    let total: f32 = (0..lum.len()).map(|i| power(i, lum[i])).sum();
    let (mut irradiance, mut weighted) = (Vec3::ZERO, Vec3::ZERO);
    for &i in &patch {
        let excess = (texels[i] - fill).max(Vec3::ZERO) * texel_solid_angle(i / w, w, h);
        let uv = Vec2::new(((i % w) as f32 + 0.5) / w as f32, ((i / w) as f32 + 0.5) / h as f32);
        irradiance += excess;
        weighted += uv_to_dir(uv) * luminance(excess);
    }
    if omega > MAX_SOLID_ANGLE || luminance(irradiance) < MIN_SHARE * total {
        return None;
    }
    let mut residual = texels.to_vec();
    patch.iter().for_each(|&i| residual[i] = residual[i].min(fill));
    let angular_radius = (1.0 - omega / (2.0 * PI)).clamp(-1.0, 1.0).acos();
    let direction = weighted.normalize();
    // Each texel's power about the direction: its centre's angle, plus a square texel's own
    // second moment (Ω/6).
    let (mut moment, mut weight) = (0.0, 0.0);
    for &i in &patch {
        let omega_i = texel_solid_angle(i / w, w, h);
        let p = luminance((texels[i] - fill).max(Vec3::ZERO) * omega_i);
        let uv = Vec2::new(((i % w) as f32 + 0.5) / w as f32, ((i / w) as f32 + 0.5) / h as f32);
        moment += p * (uv_to_dir(uv).angle_between(direction).powi(2) + omega_i / 6.0);
        weight += p;
    }
    let spread = (2.0 * moment / weight.max(f32::MIN_POSITIVE)).sqrt();
    Some((Sun { direction, irradiance, angular_radius, spread }, residual))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shadow_rays_cover_a_wide_suns_disc_and_a_narrow_ones_centre() {
        let sun = |degrees: f32| Sun {
            direction: Vec3::new(0.3, 0.9, -0.2).normalize(),
            irradiance: Vec3::ONE,
            angular_radius: degrees.to_radians(),
            spread: degrees.to_radians(),
        };
        let hard = sun(1.1);
        assert_eq!(hard.softness(), 0.0);
        assert_eq!(hard.shadow_directions(16, 0.37).collect::<Vec<_>>(), vec![hard.direction]);
        let wide = sun(6.2);
        for turn in [0.0, 0.25, 0.9] {
            let dirs: Vec<Vec3> = wide.shadow_directions(16, turn).collect();
            assert_eq!(dirs.len(), 16);
            let within = dirs.iter().all(|d| d.angle_between(wide.direction) <= wide.spread * 1.0001);
            let mean = dirs.iter().sum::<Vec3>().normalize();
            assert!(within && mean.angle_between(wide.direction) < 0.1 * wide.spread, "{turn}");
            // Equal areas: an edge through the centre hides half of the rays, give or take one.
            let side = wide.direction.any_orthonormal_vector();
            let hidden = dirs.iter().filter(|d| d.dot(side) > 0.0).count() as i64;
            assert!((hidden - 8).abs() <= 1, "{turn}: {hidden}");
        }
    }
}
