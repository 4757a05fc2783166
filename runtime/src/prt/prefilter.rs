//! The environment's reflection in a GGX lobe by filtered importance sampling (Křivánek &
//! Colbert 2008, "Real-time Shading with Filtered Importance Sampling"): a fixed set of
//! visible-normal samples of the actual lobe (view and roughness as they are, Heitz 2018), each
//! reading the level of a mip chain of the map whose texels match the sample's solid angle —
//! so a bright small source (a sun) is spread over the lobe instead of aliasing, and the lobe
//! keeps its true shape at grazing views, where the split-sum form (a lobe prefiltered around
//! `n = v = r`) loses a fifth of the light on a rough metal (measured: docs/baked.md).
//! The chain averages texels by solid angle, so a coarse texel holds the energy of its
//! directions; level 0 is the map itself.

use crate::math::equirect::{self, dir_to_uv};
use crate::math::frame::Frame;
use crate::math::{ggx, trig};
use glam::{Quat, Vec2, Vec3};
use std::f32::consts::PI;
use std::sync::Arc;

/// GGX samples per reflection.
pub const SAMPLES: usize = 32;

/// Width of the coarsest mip.
const MIN_WIDTH: usize = 16;

/// An equirectangular RGB image (row 0 = +Y), looked up bilinearly with `u` wrapping.
#[derive(Clone, Debug)]
struct Image {
    width: usize,
    height: usize,
    texels: Vec<Vec3>,
}

impl Image {
    fn bilinear(&self, uv: Vec2) -> Vec3 {
        equirect::bilinear(self.width, self.height, &self.texels, uv)
    }

    /// The texel `uv` falls in (how the reference reads a map).
    fn nearest(&self, uv: Vec2) -> Vec3 {
        let i = ((uv.x * self.width as f32) as usize).min(self.width - 1);
        let j = ((uv.y * self.height as f32) as usize).min(self.height - 1);
        self.texels[j * self.width + i]
    }

    /// Half the size: each texel the mean radiance over its four children, weighted by their
    /// solid angle (sin θ of their rows), so that a coarse texel holds the energy its directions
    /// receive; an odd last row or column averages what it has.
    fn halved(&self) -> Self {
        let (w, h) = ((self.width / 2).max(1), (self.height / 2).max(1));
        let sin = |j: usize| (PI * (j as f32 + 0.5) / self.height as f32).sin();
        let texels = (0..w * h)
            .map(|k| {
                let (x, y) = (k % w, k / w);
                let xs = [2 * x, (2 * x + 1).min(self.width - 1)];
                let ys = [2 * y, (2 * y + 1).min(self.height - 1)];
                let (mut sum, mut weight) = (Vec3::ZERO, 0.0);
                for &j in &ys {
                    for &i in &xs {
                        sum += self.texels[j * self.width + i] * sin(j);
                        weight += sin(j);
                    }
                }
                sum / weight
            })
            .collect();
        Self { width: w, height: h, texels }
    }
}

/// An equirectangular map (row 0 = +Y) as a mip chain, with its intensity and placement, for
/// GGX reflection by filtered importance sampling.
#[derive(Clone, Debug)]
pub struct Prefiltered {
    /// Levels 0.. (level 0 is the map), halved down to [`MIN_WIDTH`] texels wide.
    mips: Arc<Vec<Image>>,
    intensity: f32,
    /// Map-from-world rotation.
    to_map: Quat,
}

impl Prefiltered {
    /// The mip chain of a `width × height` map's `texels`, scaled by `intensity` and turned by
    /// `rotation` radians about +Y at lookup.
    pub fn new(width: usize, height: usize, texels: Vec<Vec3>, intensity: f32, rotation: f32) -> Self {
        let mut mips = vec![Image { width, height, texels }];
        // Coarser mips than MIN_WIDTH wide would smear a bright source across latitudes.
        while mips.last().is_some_and(|m| m.width / 2 >= MIN_WIDTH) {
            let next = mips.last().expect("non-empty").halved();
            mips.push(next);
        }
        Self { mips: Arc::new(mips), intensity, to_map: Quat::from_rotation_y(-rotation) }
    }

    /// The same chain (not built again) looked up through map-from-world rotation `to_map` and
    /// scaled by `intensity`.
    pub fn placed(&self, to_map: Quat, intensity: f32) -> Self {
        Self { mips: self.mips.clone(), intensity, to_map }
    }

    /// The chain's levels as (width, height, texels), level 0 the map itself (for upload to the
    /// GPU; [`Self::lookup`] reads level 0 by nearest texel, the others bilinearly).
    pub fn levels(&self) -> impl Iterator<Item = (usize, usize, &[Vec3])> {
        self.mips.iter().map(|m| (m.width, m.height, m.texels.as_slice()))
    }

    /// Map-from-world rotation and intensity (applied at lookup).
    pub fn placement(&self) -> (Quat, f32) {
        (self.to_map, self.intensity)
    }

    /// True when `other` holds the same chain (built once, shared by clones).
    pub fn same_chain(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.mips, &other.mips)
    }

    /// Radiance of mip level `lod` (fractional: linear between levels) along world `dir`;
    /// level 0 reads texels as the reference does.
    pub fn lookup(&self, dir: Vec3, lod: f32) -> Vec3 {
        let lod = lod.clamp(0.0, (self.mips.len() - 1) as f32);
        let k = (lod.floor() as usize).min(self.mips.len() - 1);
        let f = lod - k as f32;
        let d = self.to_map * dir;
        // Level 0 picks texels exactly as the reference; a filtered level does not need libm's
        // last bit (4e-6 rad is a thousandth of a texel).
        let uv = if k == 0 { dir_to_uv(d) } else { fast_uv(d) };
        let level = |k: usize| if k == 0 { self.mips[0].nearest(uv) } else { self.mips[k].bilinear(uv) };
        let a = level(k);
        let v = if f > 0.0 { a.lerp(level(k + 1), f) } else { a };
        v * self.intensity
    }

    /// `∫ L(ωi) f_s(ωo, ωi) cos θi dωi` over the specular GGX lobe (roughness `alpha`, Fresnel
    /// `f0`/`f90`) at normal `n` seen along `wo` (world, unit), unshadowed: [`SAMPLES`]
    /// stratified visible-normal samples weighted `F · G2 / G1`, each reading the mip of its
    /// solid angle.
    pub fn reflect(&self, n: Vec3, wo: Vec3, alpha: f32, f0: Vec3, f90: Vec3) -> Vec3 {
        let frame = Frame::from_normal(n);
        let wo_l = frame.to_local(wo);
        if wo_l.z <= 0.0 {
            return Vec3::ZERO;
        }
        let texel = 4.0 * PI / (self.mips[0].width * self.mips[0].height) as f32;
        let g1 = ggx::g1(wo_l, alpha);
        let normals = ggx::VisibleNormals::new(wo_l, alpha);
        let mut sum = Vec3::ZERO;
        for &(r, cos, sin) in DISK.iter() {
            let h = normals.sample(r, cos, sin);
            let wi = 2.0 * wo_l.dot(h) * h - wo_l;
            if wi.z <= 0.0 {
                continue;
            }
            let pdf = g1 * ggx::d(h, alpha) / (4.0 * wo_l.z);
            let lod = 0.5 * (1.0 / (SAMPLES as f32 * pdf.max(1e-12) * texel)).log2() + 1.0;
            let weight = ggx::fresnel_schlick(f0, f90, wo_l.dot(h)) * (ggx::g2(wo_l, wi, alpha) / g1);
            sum += weight * self.lookup(frame.to_world(wi), lod);
        }
        sum / SAMPLES as f32
    }
}

/// [`dir_to_uv`] with [`trig::atan2`] for libm's `atan2` and `acos`.
fn fast_uv(d: Vec3) -> Vec2 {
    let u = (trig::atan2(d.x, -d.z) / (2.0 * PI)).rem_euclid(1.0);
    let v = trig::atan2((d.x * d.x + d.z * d.z).sqrt(), d.y) / PI;
    Vec2::new(u.min(1.0 - f32::EPSILON), v)
}

/// The samples' disk points `(√u.x, cos 2πu.y, sin 2πu.y)`: `u` stratified in x and Van der
/// Corput's sequence in y (a Hammersley set), the same for every reflection.
static DISK: std::sync::LazyLock<[(f32, f32, f32); SAMPLES]> = std::sync::LazyLock::new(|| {
    std::array::from_fn(|s| {
        let u = crate::math::sampling::hammersley(s as u32, SAMPLES as u32);
        let phi = 2.0 * PI * u.y;
        (u.x.sqrt(), phi.cos(), phi.sin())
    })
});

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::equirect::uv_to_dir;

    /// Under a constant environment the reflection is the lobe's directional albedo (the
    /// table the BSDF uses) times the radiance, at every roughness and view.
    #[test]
    fn constant_environment_reflects_the_directional_albedo() {
        let p = Prefiltered::new(64, 32, vec![Vec3::new(0.5, 1.0, 2.0); 64 * 32], 1.0, 0.0);
        let (f0, f90) = (Vec3::new(0.9, 0.6, 0.3), Vec3::ONE);
        for roughness in [0.05, 0.2, 0.5, 1.0] {
            for mu in [0.2f32, 0.6, 1.0] {
                let wo = Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
                let alpha = ggx::alpha_from_roughness(roughness);
                let got = p.reflect(Vec3::Z, wo, alpha, f0, f90) / Vec3::new(0.5, 1.0, 2.0);
                let want = ggx::directional_albedo(mu, roughness, f0, f90);
                assert!((got - want).abs().max_element() < 0.03, "r {roughness} μ {mu}: {got} vs {want}");
            }
        }
    }

    /// The chain keeps a bright source's energy (sphere means of each level within 2 %), and a
    /// rough lobe toward it gathers far less than a mirror looking straight at it. (The source
    /// spans 0.13 sr: too wide to be split off as a sun.)
    /// The fast mapping is the exact one (in f64) to a thousandth of a 512-texel map's texel,
    /// poles included: θ from atan2 of the horizontal length, which keeps the precision that
    /// `acos` of a y rounded near ±1 loses (1e-4 in v there).
    #[test]
    fn fast_uv_is_the_mapping() {
        let exact = |d: Vec3| {
            let d = d.as_dvec3();
            let u = (d.x.atan2(-d.z) / std::f64::consts::TAU).rem_euclid(1.0);
            glam::DVec2::new(u, d.x.hypot(d.z).atan2(d.y) / std::f64::consts::PI)
        };
        let worst = (0..20_000).fold(0.0f64, |worst, k| {
            let d = uv_to_dir(crate::math::sampling::hammersley(k, 20_000));
            let (a, b) = (fast_uv(d).as_dvec2(), exact(d));
            let du = (a.x - b.x).abs().min(1.0 - (a.x - b.x).abs());
            worst.max(du).max((a.y - b.y).abs())
        });
        assert!(worst < 2e-6, "{worst:e}");
    }

    #[test]
    fn mips_keep_a_suns_energy() {
        let (w, h) = (128, 64);
        let sun = Vec3::new(0.3, 0.8, -0.5).normalize();
        let texels = (0..w * h)
            .map(|k| {
                let uv = Vec2::new(((k % w) as f32 + 0.5) / w as f32, ((k / w) as f32 + 0.5) / h as f32);
                if uv_to_dir(uv).dot(sun) > 0.98 { Vec3::splat(1000.0) } else { Vec3::splat(0.1) }
            })
            .collect();
        let p = Prefiltered::new(w, h, texels, 1.0, 0.0);
        assert_eq!(p.lookup(sun, 0.0), Vec3::splat(1000.0), "level 0 reads the map's texel");
        let mean = |lod: f32| {
            let (gw, gh) = (512, 256);
            let (mut sum, mut weight) = (0.0f64, 0.0f64);
            for k in 0..gw * gh {
                let uv = Vec2::new(((k % gw) as f32 + 0.5) / gw as f32, ((k / gw) as f32 + 0.5) / gh as f32);
                let s = (PI * uv.y).sin() as f64;
                sum += p.lookup(uv_to_dir(uv), lod).x as f64 * s;
                weight += s;
            }
            (sum / weight) as f32
        };
        let m0 = mean(0.0);
        for lod in 1..p.mips.len() {
            let m = mean(lod as f32);
            assert!((m / m0 - 1.0).abs() < 0.02, "level {lod}: {m0} → {m}");
        }
        let mirror = p.reflect(sun, sun, 1e-4, Vec3::ONE, Vec3::ONE).x;
        let rough = p.reflect(sun, sun, 1.0, Vec3::ONE, Vec3::ONE).x;
        assert!(rough < 0.2 * mirror, "mirror {mirror}, rough {rough}");
    }
}
