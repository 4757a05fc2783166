//! The environment split into q regions that act as area lights for shadows cast between
//! groups (after Kollig & Keller 2003): well-spread seed directions placed by importance, then
//! relaxed by Lloyd iterations into a centroidal Voronoi partition of the sphere.
//!
//! Importance is `Ω · √luminance`: a sun 10⁵ times brighter than its sky gets a region of its
//! own (a sharp shadow) without swallowing every region, which plain luminance would do.

use super::lighting::texels;
use crate::scene::EnvironmentLight;
use glam::DVec3;

pub use kage_runtime::prt::Region;

/// Lloyd iterations of the relaxation.
const LLOYD_ITERATIONS: usize = 16;
/// Cells of the coarse grid the relaxation runs on (longitude × latitude).
const CELLS: (usize, usize) = (128, 64);

/// Splits the environment into at most `q` regions (fewer only if seeds end up empty).
pub fn decompose(env: &EnvironmentLight, q: usize) -> Vec<Region> {
    let all = texels(env);
    let cells = coarse_cells(&all, env.map.width, env.map.height);
    let mut seeds = initial_seeds(&cells, q.max(1));
    for _ in 0..LLOYD_ITERATIONS {
        let mut sums = vec![DVec3::ZERO; seeds.len()];
        for (d, w) in &cells {
            sums[nearest(&seeds, *d)] += *d * *w;
        }
        for (s, sum) in seeds.iter_mut().zip(&sums) {
            if sum.length_squared() > 0.0 {
                *s = sum.normalize();
            }
        }
    }
    let mut acc = vec![(DVec3::ZERO, DVec3::ZERO, DVec3::ZERO, 0.0); seeds.len()];
    for (d, omega, l) in &all {
        let a = &mut acc[nearest(&seeds, *d)];
        a.0 += *l * *omega;
        a.1 += *d * (luminance(*l) * omega);
        a.2 += *d * *omega;
        a.3 += omega;
    }
    let mut regions: Vec<Region> = acc
        .into_iter()
        .filter(|a| a.3 > 0.0)
        .map(|(power, lum_dir, dir, solid_angle)| {
            let centroid = if lum_dir.length_squared() > 1e-30 { lum_dir } else { dir };
            Region { power, dir: centroid.normalize_or(DVec3::Y).as_vec3(), solid_angle, spread: 0.0 }
        })
        .collect();
    // Second pass: the power's angular spread about each centroid.
    let dirs: Vec<DVec3> = regions.iter().map(|r| r.dir.as_dvec3()).collect();
    let seed_of: Vec<usize> = all.iter().map(|t| nearest(&seeds, t.0)).collect();
    let kept: Vec<usize> =
        (0..seeds.len()).filter(|&i| all.iter().zip(&seed_of).any(|(t, s)| *s == i && t.1 > 0.0)).collect();
    let mut spread = vec![(0.0, 0.0, 0.0); regions.len()];
    for ((d, omega, l), s) in all.iter().zip(&seed_of) {
        let r = kept.binary_search(s).expect("every texel's region is kept");
        let w = luminance(*l) * omega;
        let e = &mut spread[r];
        e.0 += w * (*d - dirs[r]).length_squared();
        e.1 += w;
        e.2 += omega * (*d - dirs[r]).length_squared();
    }
    for (r, (m, w, geo)) in regions.iter_mut().zip(spread) {
        // Without light in the region, its geometric extent stands in.
        r.spread = 2.0 * std::f64::consts::PI * if w > 0.0 { m / w } else { geo / r.solid_angle };
    }
    regions
}

fn luminance(c: DVec3) -> f64 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// Index of the seed closest to `d` (largest dot product; ties to the lowest index).
pub(crate) fn nearest(seeds: &[DVec3], d: DVec3) -> usize {
    let mut best = (0, f64::NEG_INFINITY);
    for (i, s) in seeds.iter().enumerate() {
        let c = s.dot(d);
        if c > best.1 {
            best = (i, c);
        }
    }
    best.0
}

/// Texels pooled into a coarse grid: (mean direction, importance) per non-empty cell.
fn coarse_cells(all: &[(DVec3, f64, DVec3)], w: usize, h: usize) -> Vec<(DVec3, f64)> {
    let (cw, ch) = (CELLS.0.min(w), CELLS.1.min(h));
    let mean_lum = all.iter().map(|t| luminance(t.2) * t.1).sum::<f64>() / (4.0 * std::f64::consts::PI);
    let floor = 1e-3 * mean_lum.max(1e-30);
    let mut cells = vec![(DVec3::ZERO, 0.0); cw * ch];
    for (i, (d, omega, l)) in all.iter().enumerate() {
        let c = &mut cells[(i / w) * ch / h * cw + (i % w) * cw / w];
        c.0 += *d * *omega;
        c.1 += omega * (luminance(*l) + floor).sqrt();
    }
    cells.into_iter().filter(|c| c.1 > 0.0).map(|(d, w)| (d.normalize(), w)).collect()
}

/// `q` distinct seeds: one per stratum of the cells' cumulative importance; strata that fall
/// in an already-taken cell (a bright sun) are refilled by farthest-point selection.
fn initial_seeds(cells: &[(DVec3, f64)], q: usize) -> Vec<DVec3> {
    let total: f64 = cells.iter().map(|c| c.1).sum();
    let target = |j: usize| (j as f64 + 0.5) * total / q as f64;
    let mut seeds: Vec<DVec3> = Vec::with_capacity(q);
    let (mut cum, mut next) = (0.0, 0usize);
    for (d, w) in cells {
        cum += w;
        if next < q && target(next) <= cum {
            seeds.push(*d);
            while next < q && target(next) <= cum {
                next += 1;
            }
        }
    }
    while seeds.len() < q.min(cells.len()) {
        let closeness = |d: &DVec3| seeds.iter().map(|s| s.dot(*d)).fold(f64::NEG_INFINITY, f64::max);
        let far = cells.iter().map(|c| c.0).min_by(|a, b| closeness(a).total_cmp(&closeness(b))).expect("cells");
        seeds.push(far);
    }
    seeds
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::EnvMap;
    use glam::Vec3;

    fn sun_sky(ratio: f32) -> EnvironmentLight {
        let (w, h) = (256, 128);
        let mut t = vec![Vec3::splat(1.0); w * h];
        for y in 30..32 {
            for x in 100..102 {
                t[y * w + x] = Vec3::splat(ratio);
            }
        }
        EnvironmentLight::new(EnvMap::new(w, h, t, "sun".into()).unwrap())
    }

    #[test]
    fn regions_partition_the_sphere_and_its_power() {
        let env = sun_sky(1e5);
        let all = texels(&env);
        let total: DVec3 = all.iter().map(|t| t.2 * t.1).sum();
        for q in [1, 8, 32, 64] {
            let r = decompose(&env, q);
            assert_eq!(r.len(), q, "q = {q}");
            let omega: f64 = r.iter().map(|r| r.solid_angle).sum();
            let power: DVec3 = r.iter().map(|r| r.power).sum();
            assert!((omega - 4.0 * std::f64::consts::PI).abs() < 1e-9);
            assert!((power - total).length() < 1e-9 * total.length());
        }
    }

    #[test]
    fn a_bright_sun_gets_a_small_region_of_its_own() {
        let env = sun_sky(1e5);
        let sun = crate::scene::environment::uv_to_dir(glam::Vec2::new(101.0 / 256.0, 31.0 / 128.0));
        let r = decompose(&env, 32);
        let best = r.iter().max_by(|a, b| a.power.x.total_cmp(&b.power.x)).unwrap();
        assert!(best.dir.dot(sun) > 0.999, "{:?}", best.dir);
        assert!(best.spread < 0.01, "{}", best.spread);
        // The other regions share the sky rather than crowding the sun.
        let small = r.iter().filter(|r| r.solid_angle < 0.05).count();
        assert!(small <= 4, "{small} tiny regions");
    }

    #[test]
    fn q_one_is_the_whole_sphere() {
        let r = decompose(&sun_sky(10.0), 1);
        assert_eq!(r.len(), 1);
        assert!((r[0].solid_angle - 4.0 * std::f64::consts::PI).abs() < 1e-9);
    }
}
