//! Every number a pack's extension holds, checked finite and in the range kage writes, each
//! error naming its field: checksums catch damage, these catch packs written wrong (or by hand)
//! whose numbers would shade as infinities or NaNs.

use super::schema;
use crate::bspvt::layout::FACE_RESOLUTIONS;
use std::f64::consts::PI;

type Checked = Result<(), String>;

/// The SH orders kage bakes and reads.
pub const ORDERS: std::ops::RangeInclusive<usize> = 1..=16;
/// The environment region counts kage bakes and reads.
pub const REGION_COUNTS: std::ops::RangeInclusive<usize> = 1..=256;
/// The transfer direction counts kage bakes and reads.
pub const DIRECTION_COUNTS: std::ops::RangeInclusive<usize> = 4..=65536;
/// The silhouette resolutions kage reads (it bakes at 128).
pub const SILHOUETTE_RESOLUTIONS: std::ops::RangeInclusive<usize> = 8..=512;

/// Checks PRT's settings against their documented ranges (work and memory are sized by them).
pub fn prt_settings(order: usize, regions: usize, directions: usize, silhouette: usize) -> Checked {
    let ranges = [
        ("SH order", order, &ORDERS),
        ("region count", regions, &REGION_COUNTS),
        ("direction count", directions, &DIRECTION_COUNTS),
        ("silhouette resolution", silhouette, &SILHOUETTE_RESOLUTIONS),
    ];
    match ranges.into_iter().find(|(_, v, r)| !r.contains(v)) {
        Some((what, v, r)) => Err(format!("PRT: {what} {v} is outside {r:?}")),
        None => Ok(()),
    }
}

/// The root record: the bakes' settings, the preview's exposure, the PRT lighting and
/// regions, the environment.
pub fn root(r: &schema::Root) -> Checked {
    finite("previewExposure", &[r.preview_exposure as f64])?;
    if let Some(b) = &r.bspvt {
        finite("bspvt.epsilon", &[b.epsilon])?;
        let res = usize::try_from(b.face_resolution).unwrap_or(usize::MAX);
        if !FACE_RESOLUTIONS.contains(&res) {
            return Err(format!("BSPVT: face resolution {res} is outside {FACE_RESOLUTIONS:?}"));
        }
    }
    if let Some(p) = &r.prt {
        let count = |n: u64| usize::try_from(n).unwrap_or(usize::MAX);
        prt_settings(count(p.order), p.regions.len(), count(p.directions), count(p.silhouette_resolution))?;
        lighting("prt.", &p.lighting, &p.regions)?;
        if let Some(s) = &p.sunless {
            prt_settings(count(p.order), s.regions.len(), count(p.directions), count(p.silhouette_resolution))?;
            lighting("prt.sunless.", &s.lighting, &s.regions)?;
        }
    }
    if let Some(e) = &r.environment {
        within("environment.intensity", &[e.intensity as f64], 0.0, f64::MAX)?;
        finite("environment.rotation", &[e.rotation as f64])?;
    }
    Ok(())
}

/// An environment's SH `light` and `regions`, their fields named after `prefix`.
fn lighting(prefix: &str, light: &[[f64; 3]], regions: &[schema::Region]) -> Checked {
    finite(&format!("{prefix}lighting"), &light.concat())?;
    for (i, g) in regions.iter().enumerate() {
        let field = |f: &str| format!("{prefix}regions[{i}].{f}");
        within(&field("power"), &g.power, 0.0, f64::MAX)?;
        let d = g.direction.map(f64::from);
        finite(&field("direction"), &d)?;
        if ((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() - 1.0).abs() > 1e-3 {
            return Err(format!("{} is not a unit vector", field("direction")));
        }
        within(&field("solidAngle"), &[g.solid_angle], f64::MIN_POSITIVE, SPHERE)?;
        within(&field("spread"), &[g.spread], 0.0, SPHERE)?;
    }
    Ok(())
}

/// The mesh records: materials and lights (the bakes' data is checked where it is read).
pub fn records(instances: &[schema::Instance], lights: &[schema::Light]) -> Checked {
    for (k, r) in instances.iter().enumerate() {
        let m = &r.material;
        let field = |f: &str| format!("instance {k}'s material.{f}");
        finite(&field("baseColor"), &m.base_color.map(f64::from))?;
        within(&field("metallic"), &[m.metallic as f64], 0.0, 1.0)?;
        within(&field("roughness"), &[m.roughness as f64], 0.0, 1.0)?;
        within(&field("specular"), &[m.specular as f64], 0.0, f64::MAX)?;
    }
    for (k, l) in lights.iter().enumerate() {
        let field = |f: &str| format!("light {k}'s {f}");
        within(&field("lightRadiance"), &l.light_radiance.map(f64::from), 0.0, f64::MAX)?;
        finite(&field("lightPolygon"), &l.light_polygon.iter().map(|&x| x as f64).collect::<Vec<_>>())?;
        let uvs: Vec<f64> = l.light_uvs.iter().flatten().map(|&x| x as f64).collect();
        finite(&field("lightUvs"), &uvs)?;
    }
    Ok(())
}

/// The largest a diffuse transfer coefficient of band `l` can be: each of the N transfer
/// directions adds at most (4π/N)/π · |Y_lm| and |Y_lm| ≤ √((2l+1)/4π) (Unsöld), so
/// |T_lm| ≤ 4 √((2l+1)/4π), with a part in a thousand for rounding.
pub fn transfer_bound(l: usize) -> f32 {
    (4.0 * ((2 * l + 1) as f64 / (4.0 * PI)).sqrt() * 1.001) as f32
}

/// Checks an instance's transfer (n² coefficients per vertex, `k = l(l+1)+m`).
pub fn transfer(instance: usize, order: usize, t: &[f32]) -> Checked {
    let bounds: Vec<f32> = (0..order).flat_map(|l| std::iter::repeat_n(transfer_bound(l), 2 * l + 1)).collect();
    for (i, (x, b)) in t.iter().zip(bounds.iter().cycle()).enumerate() {
        if x.is_nan() || x.abs() > *b {
            return Err(format!(
                "instance {instance}'s prt.transfer: vertex {}, coefficient {} is {x}, beyond ±{b}",
                i / bounds.len(),
                i % bounds.len()
            ));
        }
    }
    Ok(())
}

/// The whole sphere's solid angle, with a part in a thousand for rounding.
const SPHERE: f64 = 4.0 * PI * 1.001;

fn finite(field: &str, xs: &[f64]) -> Checked {
    within(field, xs, f64::MIN, f64::MAX)
}

fn within(field: &str, xs: &[f64], lo: f64, hi: f64) -> Checked {
    match xs.iter().find(|x| !(lo..=hi).contains(*x)) {
        None => Ok(()),
        Some(x) if x.is_finite() => Err(format!("{field} holds {x}, outside [{lo}, {hi}]")),
        Some(x) => Err(format!("{field} holds {x}: not a finite number")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Transfers within the bound pass (the packs kage writes are read in the pack tests); a
    /// flipped exponent bit lands far outside it, and the error names the coefficient.
    #[test]
    fn the_transfer_bound_refuses_a_flipped_exponent_and_names_the_coefficient() {
        let good = [0.88f32, 0.5, -0.7, 0.3];
        assert_eq!(transfer(0, 2, &good), Ok(()));
        let mut bad = good;
        bad[2] = f32::from_bits(bad[2].to_bits() ^ (1 << 30));
        let e = transfer(3, 2, &bad).unwrap_err();
        assert!(e.contains("instance 3's prt.transfer: vertex 0, coefficient 2"), "{e}");
        assert!(transfer(0, 2, &[f32::NAN, 0.0, 0.0, 0.0]).is_err());
    }

    #[test]
    fn a_radiance_beyond_f32_is_refused_naming_the_field() {
        let light = schema::Light {
            light_radiance: [f32::INFINITY, 1.0, 1.0],
            light_polygon: vec![0.0; 9],
            light_reach: None,
            light_uvs: None,
        };
        let e = records(&[], &[light]).unwrap_err();
        assert!(e.contains("light 0's lightRadiance") && e.contains("not a finite number"), "{e}");
    }
}
