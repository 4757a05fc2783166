//! GGX (Trowbridge–Reitz) microfacet model in the local frame (+Z = normal), with α = roughness².
//!
//! Height-correlated Smith masking-shadowing, Schlick Fresnel `F0 + (F90 − F0)(1 − v·h)⁵`,
//! visible-normal sampling (Heitz 2018) and its pdf, and the directional-albedo tables the
//! glTF diffuse weighting needs.

use glam::{Vec2, Vec3};
use std::f32::consts::PI;
use std::sync::OnceLock;

/// Smallest α used in evaluation: below it the lobe is a numerical delta and f32 overflows.
pub const MIN_ALPHA: f32 = 1e-4;

/// α from glTF roughness, clamped to [`MIN_ALPHA`].
pub fn alpha_from_roughness(roughness: f32) -> f32 {
    let r = if roughness.is_finite() { roughness.clamp(0.0, 1.0) } else { 1.0 };
    (r * r).max(MIN_ALPHA)
}

/// Normal distribution D(h).
pub fn d(h: Vec3, alpha: f32) -> f32 {
    if h.z <= 0.0 {
        return 0.0;
    }
    let a2 = alpha * alpha;
    // sin²θ + cos²θ·α², not cos²θ(α² − 1) + 1, which cancels to 0 for tiny α.
    let t = (h.x * h.x + h.y * h.y) + h.z * h.z * a2;
    a2 / (PI * t * t)
}

/// Smith Λ(ω).
pub fn lambda(w: Vec3, alpha: f32) -> f32 {
    let cos2 = w.z * w.z;
    if cos2 <= 0.0 {
        return f32::INFINITY;
    }
    let tan2 = ((1.0 - cos2) / cos2).max(0.0);
    0.5 * ((1.0 + alpha * alpha * tan2).sqrt() - 1.0)
}

/// Smith masking G1(ω).
pub fn g1(w: Vec3, alpha: f32) -> f32 {
    1.0 / (1.0 + lambda(w, alpha))
}

/// Height-correlated masking-shadowing G2(ωo, ωi).
pub fn g2(wo: Vec3, wi: Vec3, alpha: f32) -> f32 {
    1.0 / (1.0 + lambda(wo, alpha) + lambda(wi, alpha))
}

/// Schlick Fresnel with explicit F90.
pub fn fresnel_schlick(f0: Vec3, f90: Vec3, v_dot_h: f32) -> Vec3 {
    let w = (1.0 - v_dot_h.clamp(0.0, 1.0)).powi(5);
    f0 + (f90 - f0) * w
}

/// The specular BRDF value f(ωo, ωi) (without the cosine), zero below either horizon.
pub fn eval(wo: Vec3, wi: Vec3, alpha: f32, f0: Vec3, f90: Vec3) -> Vec3 {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return Vec3::ZERO;
    }
    let h = (wo + wi).normalize_or_zero();
    if h == Vec3::ZERO {
        return Vec3::ZERO;
    }
    let f = fresnel_schlick(f0, f90, wo.dot(h));
    f * (d(h, alpha) * g2(wo, wi, alpha) / (4.0 * wo.z * wi.z))
}

/// Samples a visible normal for `wo` (Heitz 2018, "Sampling the GGX Distribution of Visible Normals").
pub fn sample_visible_normal(wo: Vec3, alpha: f32, u: Vec2) -> Vec3 {
    let phi = 2.0 * PI * u.y;
    VisibleNormals::new(wo, alpha).sample(u.x.sqrt(), phi.cos(), phi.sin())
}

/// [`sample_visible_normal`] for one view and roughness, its frame built once for many samples.
#[derive(Clone, Copy, Debug)]
pub struct VisibleNormals {
    vh: Vec3,
    t1: Vec3,
    t2: Vec3,
    alpha: f32,
}

impl VisibleNormals {
    /// The visible normals of roughness `alpha` seen from local `wo`.
    pub fn new(wo: Vec3, alpha: f32) -> Self {
        let vh = Vec3::new(alpha * wo.x, alpha * wo.y, wo.z).normalize();
        let lensq = vh.x * vh.x + vh.y * vh.y;
        let t1 = if lensq > 0.0 { Vec3::new(-vh.y, vh.x, 0.0) / lensq.sqrt() } else { Vec3::X };
        Self { vh, t1, t2: vh.cross(t1), alpha }
    }

    /// The normal of the disk point at radius `r` and angle φ (`cos φ`, `sin φ`): for `u` in
    /// [0, 1)², `r = √u.x`, `φ = 2π u.y`.
    pub fn sample(&self, r: f32, cos: f32, sin: f32) -> Vec3 {
        let (vh, alpha) = (self.vh, self.alpha);
        let p1 = r * cos;
        let s = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * sin;
        let nh = self.t1 * p1 + self.t2 * p2 + vh * (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
        Vec3::new(alpha * nh.x, alpha * nh.y, nh.z.max(1e-7)).normalize()
    }
}

/// Samples ωi by reflecting `wo` about a visible normal; `None` when it falls below the horizon.
pub fn sample(wo: Vec3, alpha: f32, u: Vec2) -> Option<Vec3> {
    if wo.z <= 0.0 {
        return None;
    }
    let h = sample_visible_normal(wo, alpha, u);
    let wi = 2.0 * wo.dot(h) * h - wo;
    (wi.z > 0.0).then_some(wi)
}

/// Solid-angle pdf of [`sample`]: G1(ωo) D(h) / (4 cos θo).
pub fn pdf(wo: Vec3, wi: Vec3, alpha: f32) -> f32 {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return 0.0;
    }
    let h = (wo + wi).normalize_or_zero();
    if h == Vec3::ZERO {
        return 0.0;
    }
    g1(wo, alpha) * d(h, alpha) / (4.0 * wo.z)
}

/// Resolution of the directional-albedo tables (cos θo × roughness).
pub const ALBEDO_N: usize = 32;

/// Directional albedo split in the two Fresnel terms: E(μ) = F0·A(μ, r) + F90·B(μ, r).
struct AlbedoTable {
    a: Vec<f32>,
    b: Vec<f32>,
}

/// The tables as shipped: [`albedo_table_bytes`], written by `cargo xtask ggx-albedo`.
/// Integrating them costs every process ~80 ms of CPU; a test checks the shipped bytes.
const SHIPPED_ALBEDO: &[u8] = include_bytes!("ggx_albedo.bin");
const _: () = assert!(SHIPPED_ALBEDO.len() == 8 * ALBEDO_N * ALBEDO_N);

fn albedo_table() -> &'static AlbedoTable {
    static TABLE: OnceLock<AlbedoTable> = OnceLock::new();
    TABLE.get_or_init(|| {
        let mut a: Vec<f32> =
            SHIPPED_ALBEDO.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
        let b = a.split_off(ALBEDO_N * ALBEDO_N);
        AlbedoTable { a, b }
    })
}

/// Directional albedo of the specular lobe for `cos θo = mu`, with F0/F90 per channel.
pub fn directional_albedo(mu: f32, roughness: f32, f0: Vec3, f90: Vec3) -> Vec3 {
    let t = albedo_table();
    let x = mu.clamp(0.0, 1.0) * (ALBEDO_N - 1) as f32;
    let y = roughness.clamp(0.0, 1.0) * (ALBEDO_N - 1) as f32;
    let (x0, y0) = ((x as usize).min(ALBEDO_N - 2), (y as usize).min(ALBEDO_N - 2));
    let (fx, fy) = (x - x0 as f32, y - y0 as f32);
    let lerp2 = |tab: &[f32]| {
        let at = |i: usize, j: usize| tab[j * ALBEDO_N + i];
        let top = at(x0, y0) * (1.0 - fx) + at(x0 + 1, y0) * fx;
        let bottom = at(x0, y0 + 1) * (1.0 - fx) + at(x0 + 1, y0 + 1) * fx;
        top * (1.0 - fy) + bottom * fy
    };
    f0 * lerp2(&t.a) + f90 * lerp2(&t.b)
}

/// The A and B tables of [`directional_albedo`], each indexed `roughness row · ALBEDO_N + μ
/// column` (for upload to the GPU).
pub fn albedo_tables() -> [&'static [f32]; 2] {
    let t = albedo_table();
    [&t.a, &t.b]
}

/// ∫ f cos over the hemisphere for `cos θo = mu`, with F split into (1 − w) and w (the A and B
/// terms), by stratified visible-normal sampling: the generator of the shipped tables.
pub fn integrate_albedo(mu: f32, alpha: f32) -> (f32, f32) {
    const S: usize = 48;
    let wo = Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
    let (mut sa, mut sb) = (0.0f64, 0.0f64);
    for i in 0..S {
        for j in 0..S {
            let u = Vec2::new((i as f32 + 0.5) / S as f32, (j as f32 + 0.5) / S as f32);
            let h = sample_visible_normal(wo, alpha, u);
            let wi = 2.0 * wo.dot(h) * h - wo;
            if wi.z <= 0.0 {
                continue;
            }
            // f·cos/pdf = F · G2/G1(ωo) for visible-normal sampling.
            let weight = (g2(wo, wi, alpha) / g1(wo, alpha)) as f64;
            let w = (1.0 - wo.dot(h).clamp(0.0, 1.0)).powi(5) as f64;
            sa += weight * (1.0 - w);
            sb += weight * w;
        }
    }
    let n = (S * S) as f64;
    ((sa / n) as f32, (sb / n) as f32)
}

/// The directional-albedo tables integrated anew, as shipped: roughness-major over the
/// [`ALBEDO_N`]² grid, all of A then all of B, little-endian f32.
pub fn albedo_table_bytes() -> Vec<u8> {
    let (a, b): (Vec<f32>, Vec<f32>) = (0..ALBEDO_N * ALBEDO_N)
        .map(|k| {
            let (ri, mi) = (k / ALBEDO_N, k % ALBEDO_N);
            let alpha = alpha_from_roughness(ri as f32 / (ALBEDO_N - 1) as f32);
            integrate_albedo((mi as f32 / (ALBEDO_N - 1) as f32).max(1e-3), alpha)
        })
        .unzip();
    a.iter().chain(&b).flat_map(|v| v.to_le_bytes()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{rng, sampling};
    use rand::Rng;

    #[test]
    fn the_shipped_albedo_tables_are_their_integrals() {
        let integrated = albedo_table_bytes();
        let floats =
            |b: &[u8]| b.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect::<Vec<_>>();
        let (shipped, integrated) = (floats(SHIPPED_ALBEDO), floats(&integrated));
        assert_eq!(shipped.len(), integrated.len());
        for (s, i) in shipped.iter().zip(&integrated) {
            // Bit for bit where the platform's sine and cosine round like the generator's.
            assert!((s - i).abs() <= 1e-6, "{s} vs {i} (regenerate: cargo xtask ggx-albedo)");
        }
        assert!(shipped.iter().any(|v| *v > 0.5), "the table holds values, not zeros");
    }

    fn dir(theta: f32, phi: f32) -> Vec3 {
        Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
    }

    #[test]
    fn d_is_normalised_over_projected_area() {
        // ∫ D(h) cos θh dh = 1, by uniform hemisphere quadrature in (cos θ, φ).
        for alpha in [0.05f32, 0.3, 1.0] {
            let n = 400_000;
            let mut s = 0.0f64;
            for i in 0..n {
                let c = (i as f64 + 0.5) / n as f64;
                let h = Vec3::new((1.0 - c * c).sqrt() as f32, 0.0, c as f32);
                s += (d(h, alpha) as f64) * c * 2.0 * std::f64::consts::PI / n as f64;
            }
            assert!((s - 1.0).abs() < 1e-3, "alpha {alpha}: {s}");
        }
    }

    #[test]
    fn sampled_pdf_matches_histogram_free_estimate() {
        // E[f·cos/pdf] by sampling equals the same integral by uniform sphere quadrature.
        let mut r = rng::seeded(3);
        for (alpha, theta) in [(0.2f32, 0.4f32), (0.6, 1.2), (1.0, 0.1)] {
            let wo = dir(theta, 0.3);
            let n = 100_000;
            let (mut by_sampling, mut by_uniform) = (0.0f64, 0.0f64);
            for _ in 0..n {
                let u = Vec2::new(r.random(), r.random());
                if let Some(wi) = sample(wo, alpha, u) {
                    let p = pdf(wo, wi, alpha);
                    by_sampling += (eval(wo, wi, alpha, Vec3::ONE, Vec3::ONE).x * wi.z / p) as f64;
                }
                let wi = sampling::uniform_sphere(Vec2::new(r.random(), r.random()));
                by_uniform +=
                    (eval(wo, wi, alpha, Vec3::ONE, Vec3::ONE).x * wi.z.max(0.0)) as f64 * 4.0 * std::f64::consts::PI;
            }
            let (a, b) = (by_sampling / n as f64, by_uniform / n as f64);
            assert!((a - b).abs() < 0.02 * b.max(0.1), "alpha {alpha}: {a} vs {b}");
        }
    }

    #[test]
    fn pdf_integrates_to_at_most_one() {
        let wo = dir(1.3, 0.0);
        let mut r = rng::seeded(4);
        let n = 200_000;
        let s: f64 = (0..n)
            .map(|_| pdf(wo, sampling::uniform_sphere(Vec2::new(r.random(), r.random())), 0.5) as f64)
            .sum::<f64>()
            * 4.0
            * std::f64::consts::PI
            / n as f64;
        assert!(s <= 1.01 && s > 0.85, "{s}");
    }

    #[test]
    fn white_furnace_albedo_is_at_most_one() {
        for r in [0.0f32, 0.2, 0.5, 1.0] {
            for mu in [1e-3f32, 0.2, 0.7, 1.0] {
                let e = directional_albedo(mu, r, Vec3::ONE, Vec3::ONE).x;
                assert!(e <= 1.0 + 1e-3 && e > 0.3, "r {r} mu {mu}: {e}");
            }
        }
        // Smooth surfaces lose almost nothing to masking.
        assert!(directional_albedo(1.0, 0.0, Vec3::ONE, Vec3::ONE).x > 0.99);
    }

    #[test]
    fn extreme_roughness_and_grazing_views_stay_finite() {
        for alpha in [MIN_ALPHA, 1e-3, 1.0] {
            for c in [1e-4f32, 0.5, 1.0] {
                let wo = Vec3::new((1.0 - c * c).sqrt(), 0.0, c);
                for u in [Vec2::ZERO, Vec2::splat(0.5), Vec2::splat(0.999_999)] {
                    if let Some(wi) = sample(wo, alpha, u) {
                        assert!(pdf(wo, wi, alpha).is_finite());
                        assert!(eval(wo, wi, alpha, Vec3::ONE, Vec3::ONE).is_finite());
                    }
                }
            }
        }
        assert_eq!(alpha_from_roughness(f32::NAN), 1.0);
    }
}
