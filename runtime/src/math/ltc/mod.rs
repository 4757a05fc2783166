//! Linearly Transformed Cosines (Heitz, Dupuy, Hill & Neubelt 2016) for GGX.
//!
//! - [`fit`]: our own fitter (Nelder–Mead on (m11, m22, m13), the error of the published fit),
//!   which `cargo xtask fit-ltc` runs to regenerate the committed table in [`table`].
//! - [`Table::lookup`]: bilinear lookup of the inverse matrix, magnitude and Fresnel terms by
//!   (roughness, cos θv).
//! - [`integrate`]: the closed-form integral of the clamped cosine over a polygon (sum over
//!   edges), in f64, stable for edges near ±1 and near the shading point.
//! - [`shade_polygon`]: GGX specular with Schlick(F0, F90) and the Lambertian form factor of a
//!   polygon seen from a shading point.

pub mod fit;
mod table;

use crate::math::polygon;
use glam::{DMat3, DVec3, Vec3};
use std::f64::consts::PI;

/// Resolution of the table along roughness and along the view parameter.
pub const TABLE_SIZE: usize = 64;

/// One fitted entry: the inverse matrix normalised by its middle element,
/// `[[a, 0, c], [0, 1, 0], [b, 0, d]]` stored as `[a, b, c, d]` (the published `g_ltc_1`
/// layout: columns (a, 0, b), (0, 1, 0), (c, 0, d)), then the BRDF's directional albedo
/// (magnitude) and its Fresnel-weighted part.
pub type Entry = [f32; 6];

/// Table coordinates of (roughness, cos θv): row `roughness·63`, column `sqrt(1 − cos θv)·63`.
pub fn table_coords(roughness: f64, cos_theta: f64) -> (f64, f64) {
    let r = if roughness.is_finite() { roughness.clamp(0.0, 1.0) } else { 1.0 };
    let c = if cos_theta.is_finite() { cos_theta.clamp(0.0, 1.0) } else { 1.0 };
    let n = (TABLE_SIZE - 1) as f64;
    (r * n, (1.0 - c).sqrt() * n)
}

/// The view direction and α the table entry (a, t) was fitted for.
pub fn entry_params(a: usize, t: usize) -> (DVec3, f64) {
    let n = (TABLE_SIZE - 1) as f64;
    let x = t as f64 / n;
    let theta = (1.0 - x * x).acos().min(1.57);
    let roughness = a as f64 / n;
    (DVec3::new(theta.sin(), 0.0, theta.cos()), (roughness * roughness).max(fit::MIN_ALPHA))
}

/// A fitted LTC table, indexed `a + t·64` (a = roughness row, t = view column).
pub struct Table<'a> {
    entries: &'a [Entry],
}

/// The committed table fitted by `cargo xtask fit-ltc`.
pub fn table() -> Table<'static> {
    Table { entries: &table::LTC_TABLE }
}

/// An LTC for one (roughness, view): inverse matrix and the two albedo terms.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lookup {
    /// M⁻¹ in the frame where the view lies in the x–z plane (x towards the view).
    pub inv: DMat3,
    /// ∫ f cos over the hemisphere (no Fresnel).
    pub magnitude: f64,
    /// ∫ f cos (1 − v·h)⁵ over the hemisphere.
    pub fresnel: f64,
}

impl<'a> Table<'a> {
    /// A table over `entries` (TABLE_SIZE² of them).
    pub fn new(entries: &'a [Entry]) -> Self {
        assert_eq!(entries.len(), TABLE_SIZE * TABLE_SIZE, "an LTC table has 64×64 entries");
        Self { entries }
    }

    /// The entries, indexed `a + t·64` (for upload to the GPU).
    pub fn entries(&self) -> &[Entry] {
        self.entries
    }

    /// Bilinear lookup (NaN or out-of-range input is clamped to the table).
    pub fn lookup(&self, roughness: f64, cos_theta: f64) -> Lookup {
        let (x, y) = table_coords(roughness, cos_theta);
        let (a0, t0) = ((x as usize).min(TABLE_SIZE - 2), (y as usize).min(TABLE_SIZE - 2));
        let (fa, ft) = (x - a0 as f64, y - t0 as f64);
        let mut e = [0.0f64; 6];
        for (da, dt, w) in
            [(0, 0, (1.0 - fa) * (1.0 - ft)), (1, 0, fa * (1.0 - ft)), (0, 1, (1.0 - fa) * ft), (1, 1, fa * ft)]
        {
            let entry = &self.entries[(a0 + da) + (t0 + dt) * TABLE_SIZE];
            e.iter_mut().zip(entry).for_each(|(e, v)| *e += w * *v as f64);
        }
        Lookup { inv: inverse_from_entry(&e), magnitude: e[4], fresnel: e[5] }
    }
}

/// The 3×3 inverse matrix of an entry `[a, b, c, d, ..]`.
pub fn inverse_from_entry(e: &[f64]) -> DMat3 {
    DMat3::from_cols(DVec3::new(e[0], 0.0, e[1]), DVec3::Y, DVec3::new(e[2], 0.0, e[3]))
}

/// ∫ over the polygon of the clamped cosine distribution max(0, z)/π: the polygon (in the
/// cosine's frame, vertices relative to the shading point) is clipped at the horizon and
/// integrated edge by edge. Polygons are one-sided lights: only one whose CCW normal faces the
/// shading point contributes (a back-facing one gives 0). Non-finite vertices give 0
/// (documented clamp).
pub fn integrate(poly: &[DVec3]) -> f64 {
    form_factor_vector(poly).z.max(0.0)
}

/// The vector form factor −Σ θ n / 2π of the horizon-clipped polygon: its z component is the
/// cosine integral ([`integrate`], before the one-sided clamp) and its direction points at the
/// polygon's irradiance-weighted centre (used to fetch textured lights). Zero for degenerate,
/// edge-on or non-finite input.
pub fn form_factor_vector(poly: &[DVec3]) -> DVec3 {
    if poly.len() < 3 || poly.iter().any(|p| !p.is_finite()) {
        return DVec3::ZERO;
    }
    // A polygon whose plane passes through the shading point is seen edge-on: nothing. (Only
    // then can an edge pass through the point, where its plane is undefined.) Just off the
    // plane the value is not small — a half-plane seen from just above its edge covers a
    // quarter sphere — so this is a genuine discontinuity, not a cut-off.
    let scale = poly.iter().fold(0.0f64, |m, p| m.max(p.length()));
    if newell_normal(poly).dot(poly[0]).abs() <= polygon::ON_PLANE * scale {
        return DVec3::ZERO;
    }
    let clipped = polygon::clip_horizon(poly);
    let sum: DVec3 = (0..clipped.len()).map(|i| edge_integral(clipped[i], clipped[(i + 1) % clipped.len()])).sum();
    // Σ θ n is opposite to the CCW normal's side: negative z when the polygon faces the origin.
    -sum / (2.0 * PI)
}

/// θ · n of one edge: θ the angle the edge subtends, n the unit normal of the plane through
/// the origin and the edge. atan2 keeps θ accurate near 0 and π (no acos of a value near ±1);
/// a zero-length edge adds nothing.
fn edge_integral(a: DVec3, b: DVec3) -> DVec3 {
    let c = a.cross(b);
    let len = c.length();
    if len == 0.0 {
        return DVec3::ZERO;
    }
    c * (len.atan2(a.dot(b)) / len)
}

fn newell_normal(poly: &[DVec3]) -> DVec3 {
    let n: DVec3 = (0..poly.len()).map(|i| poly[i].cross(poly[(i + 1) % poly.len()])).sum();
    n.normalize_or_zero()
}

/// The shading frame for normal `n` and view `v`: x towards the view in the tangent plane.
pub fn view_frame(n: DVec3, v: DVec3) -> DMat3 {
    let t1 = (v - n * v.dot(n)).normalize_or(DVec3::ZERO);
    let t1 = if t1 == DVec3::ZERO { n.any_orthonormal_vector() } else { t1 };
    let t2 = n.cross(t1);
    // Rows are the frame axes: frame * world = local.
    DMat3::from_cols(t1, t2, n).transpose()
}

/// Shading of one polygon of constant radiance 1 seen from a point: the specular
/// integral ∫_P f_GGX cos with Schlick Fresnel, and the Lambertian form factor ∫_P cos/π.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PolygonShading {
    /// ∫_P f_spec cos dω per RGB channel.
    pub specular: Vec3,
    /// ∫_P cos/π dω.
    pub form_factor: f64,
}

/// A shading point as LTC shading needs it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Surface {
    /// Position.
    pub p: DVec3,
    /// Unit normal.
    pub n: DVec3,
    /// Unit direction towards the viewer.
    pub v: DVec3,
    /// Perceptual roughness (α = roughness²).
    pub roughness: f64,
    /// Fresnel reflectance at normal incidence.
    pub f0: Vec3,
    /// Fresnel reflectance at grazing incidence.
    pub f90: Vec3,
}

/// LTC shading of polygon `points` (world positions) from `s`.
pub fn shade_polygon(table: &Table, points: &[DVec3], s: &Surface) -> PolygonShading {
    let frame = view_frame(s.n, s.v);
    let local: Vec<DVec3> = points.iter().map(|q| frame * (*q - s.p)).collect();
    let form_factor = integrate(&local);
    let lut = table.lookup(s.roughness, s.v.dot(s.n));
    let transformed: Vec<DVec3> = local.iter().map(|q| lut.inv * *q).collect();
    let spec = integrate(&transformed);
    let (f0, f90) = (s.f0.as_dvec3(), s.f90.as_dvec3());
    let specular = (f0 * (lut.magnitude - lut.fresnel) + f90 * lut.fresnel) * spec;
    PolygonShading { specular: specular.as_vec3(), form_factor }
}

#[cfg(test)]
mod tests;
