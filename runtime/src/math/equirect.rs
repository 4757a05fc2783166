//! Equirectangular maps (the environment's): directions and texel coordinates, exact texel
//! solid angles, bilinear lookup. Row 0 is +Y; u turns about +Y from −Z toward +X.

use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// Exact solid angle of a texel of row `y` in a `w × h` map: it spans Δφ = 2π/w and
/// θ ∈ [πy/h, π(y+1)/h], so Ω = Δφ (cos θ0 − cos θ1).
pub fn texel_solid_angle(y: usize, w: usize, h: usize) -> f64 {
    use std::f64::consts::PI;
    let (t0, t1) = (PI * y as f64 / h as f64, PI * (y + 1) as f64 / h as f64);
    2.0 * PI / w as f64 * (t0.cos() - t1.cos())
}

/// Direction → (u, v) in [0,1)², map frame.
pub fn dir_to_uv(d: Vec3) -> Vec2 {
    let u = (d.x.atan2(-d.z) / (2.0 * PI)).rem_euclid(1.0);
    let v = d.y.clamp(-1.0, 1.0).acos() / PI;
    Vec2::new(u.min(1.0 - f32::EPSILON), v)
}

/// (u, v) → unit direction, map frame (inverse of [`dir_to_uv`]).
pub fn uv_to_dir(uv: Vec2) -> Vec3 {
    let (phi, theta) = (2.0 * PI * uv.x, PI * uv.y);
    Vec3::new(theta.sin() * phi.sin(), theta.cos(), -theta.sin() * phi.cos())
}

/// An equirectangular `width × height` image (row-major, row 0 = +Y) at `uv`, interpolated
/// bilinearly between texel centres, wrapping around in u and clamped at the poles in v.
pub fn bilinear(width: usize, height: usize, texels: &[Vec3], uv: Vec2) -> Vec3 {
    let x = uv.x * width as f32 - 0.5;
    let y = (uv.y * height as f32 - 0.5).clamp(0.0, (height - 1) as f32);
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let column = |i: f32| (i as i64).rem_euclid(width as i64) as usize;
    let (i0, i1) = (column(x0), column(x0 + 1.0));
    let (j0, j1) = (y0 as usize, (y0 as usize + 1).min(height - 1));
    let row = |j: usize| texels[j * width + i0].lerp(texels[j * width + i1], fx);
    row(j0).lerp(row(j1), fy)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn directions_and_uvs_round_trip() {
        for k in 0..200 {
            let uv = Vec2::new((k as f32 * 0.618_034).fract(), (k as f32 + 0.5) / 200.0);
            let back = dir_to_uv(uv_to_dir(uv));
            assert!((back - uv).abs().max_element() < 1e-4, "{uv} → {back}");
        }
    }

    #[test]
    fn texel_solid_angles_sum_to_the_sphere() {
        let total: f64 = (0..64).map(|y| 128.0 * texel_solid_angle(y, 128, 64)).sum();
        assert!((total - 4.0 * std::f64::consts::PI).abs() < 1e-9, "{total}");
    }
}
