//! The visible fraction of a GGX lobe from a vertex's PRT transfer (`docs/baked.md`): the
//! transfer and the unoccluded clamped cosine, both reconstructed around the lobe's dominant
//! direction with the same window and a lobe-width kernel `g_l = exp(−l(l+1) α²)`, divided
//! and clamped to [0, 1] — an open sky gives exactly 1, and as the lobe widens only band 0
//! survives and the ratio becomes the diffuse visible fraction.

use crate::math::sh;
use glam::{DVec3, Vec3};

/// Below this fraction of the unoccluded cosine at the normal, the reconstruction at `d` is
/// too small to divide by: the diffuse visible fraction serves instead.
const MIN_DENOMINATOR: f64 = 0.05;

/// The most bands a lobe's visible fraction reads (the CLI's and packs' largest order); a
/// higher-order transfer contributes its first bands, which the lobe kernel weighs most.
const MAX_BANDS: usize = 16;

/// Coefficients in [`MAX_BANDS`] bands: the stack buffers' size (no allocation per point).
pub const MAX_COEFFS: usize = MAX_BANDS * MAX_BANDS;

/// What the visible fraction of a lobe needs per band at one SH order.
#[derive(Clone, Debug)]
pub struct Lobe {
    /// Per band: the reconstruction window `h_l`.
    window: Vec<f64>,
    /// Per band: the Funk–Hecke factor of the clamped cosine over π (the transfer's scale):
    /// an unoccluded vertex's transfer is `cosine_l · Y_lm(n)`.
    cosine: Vec<f64>,
}

impl Lobe {
    /// The bands of `order` reconstructed with `window`.
    pub fn new(order: usize, window: super::lighting::Window) -> Self {
        use std::f64::consts::PI;
        let zonal = sh::clamped_cosine_zonal(order);
        let cosine: Vec<f64> =
            zonal.iter().enumerate().map(|(l, k)| (4.0 * PI / (2 * l + 1) as f64).sqrt() * k / PI).collect();
        let bands = order.min(MAX_BANDS);
        Self { window: (0..bands).map(|l| window.factor(l, order)).collect(), cosine: cosine[..bands].to_vec() }
    }

    /// The coefficients the lobe reads.
    pub fn coeffs(&self) -> usize {
        sh::num_coeffs(self.window.len())
    }

    /// The visible fraction of a lobe of width `alpha` around `d` at a point with transfer `t`
    /// and normal `n` (all in the transfer's frame), in [0, 1].
    pub fn visible_fraction(&self, t: &[f64], n: DVec3, d: DVec3, alpha: f32) -> f32 {
        let order = self.window.len();
        let (mut yd, mut yn) = ([0.0; MAX_COEFFS], [0.0; MAX_COEFFS]);
        sh::eval_into(order, d, &mut yd);
        sh::eval_into(order, n, &mut yn);
        let a2 = (alpha * alpha) as f64;
        let (mut num, mut den) = (0.0, 0.0);
        for l in 0..order {
            let g = self.window[l] * (-((l * (l + 1)) as f64) * a2).exp();
            let band = l * l..(l + 1) * (l + 1);
            num += g * band.clone().map(|k| t[k] * yd[k]).sum::<f64>();
            den += g * self.cosine[l] * band.map(|k| yn[k] * yd[k]).sum::<f64>();
        }
        // The cosine's reconstruction at the normal itself (Σ_m Y_lm(n)² = (2l+1)/4π): the
        // scale the guard compares with.
        let at_normal: f64 = (0..order).map(|l| self.window[l] * self.cosine[l] * (2 * l + 1) as f64).sum::<f64>()
            / (4.0 * std::f64::consts::PI);
        let ratio = if den > MIN_DENOMINATOR * at_normal {
            num / den
        } else {
            t[0] / (self.cosine[0] * yn[0]) // band 0 alone: the diffuse visible fraction
        };
        ratio.clamp(0.0, 1.0) as f32
    }
}

/// The direction a GGX lobe around reflection `r` at normal `n` mostly gathers from
/// (Lagarde & de Rousiers 2014, "Moving Frostbite to PBR", Eq. 56's fit).
pub fn dominant_direction(n: Vec3, r: Vec3, alpha: f32) -> Vec3 {
    let a = alpha.clamp(0.0, 1.0);
    let s = (1.0 - a) * ((1.0 - a).sqrt() + a);
    n.lerp(r, s).normalize_or(n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::prt::lighting::{Window, fibonacci_direction};

    /// Transfer of visibility `v` at normal `n`, projected by quadrature (the bake's definition).
    fn transfer(order: usize, n: DVec3, v: impl Fn(DVec3) -> bool) -> Vec<f64> {
        sh::project(order, 64, |w| if v(w) { w.dot(n).max(0.0) / std::f64::consts::PI } else { 0.0 })
    }

    /// An open sky is fully visible to every lobe, at every roughness and view; a sky dimmed
    /// to a half everywhere is half visible (the ratio is exact, not saved by the clamp).
    #[test]
    fn open_sky_is_fully_visible() {
        for (order, window) in [(3, Window::Hanning), (4, Window::Lanczos), (6, Window::None)] {
            let lobe = Lobe::new(order, window);
            let n = DVec3::new(0.2, 0.3, 0.9).normalize();
            let t = transfer(order, n, |_| true);
            for k in 0..50 {
                let d = fibonacci_direction(k, 50);
                if d.dot(n) > 0.0 {
                    for alpha in [0.0025, 0.1, 0.5, 1.0] {
                        let f = lobe.visible_fraction(&t, n, d, alpha);
                        assert!((f - 1.0).abs() < 2e-3, "order {order} d {d} α {alpha}: {f}");
                        let half: Vec<f64> = t.iter().map(|c| 0.5 * c).collect();
                        let f = lobe.visible_fraction(&half, n, d, alpha);
                        assert!((f - 0.5).abs() < 1e-3, "order {order} d {d} α {alpha}: {f}");
                    }
                }
            }
        }
    }

    /// A wall over half the sky: lobes toward it see less than lobes away from it; the
    /// roughest lobe sees the diffuse visible fraction (band 0: one half here).
    #[test]
    fn a_wall_hides_the_lobes_that_face_it() {
        let lobe = Lobe::new(4, Window::Hanning);
        let n = DVec3::Z;
        let t = transfer(4, n, |w| w.x < 0.0);
        let toward = DVec3::new(0.7, 0.0, 0.7).normalize();
        let away = DVec3::new(-0.7, 0.0, 0.7).normalize();
        let (a, b) = (lobe.visible_fraction(&t, n, toward, 0.05), lobe.visible_fraction(&t, n, away, 0.05));
        // Order 4 blurs the wall's edge: a lobe toward it still sees a tenth of the sky.
        assert!(a < 0.15 && b > 0.85, "toward the wall {a}, away {b}");
        let rough = lobe.visible_fraction(&t, n, toward, 30.0);
        assert!((rough - 0.5).abs() < 0.01, "{rough}");
    }

    #[test]
    fn dominant_direction_bends_toward_the_normal() {
        let (n, r) = (Vec3::Z, Vec3::new(0.8, 0.0, 0.6));
        assert!((dominant_direction(n, r, 0.0) - r).length() < 1e-6);
        assert!((dominant_direction(n, r, 1.0) - n).length() < 1e-6);
        let mid = dominant_direction(n, r, 0.4);
        assert!(mid.z > r.z && mid.z < 1.0 && mid.is_normalized());
    }
}
