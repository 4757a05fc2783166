//! Per-vertex shading from polygonal lights: LTC (GGX specular with Fresnel, plus diffuse)
//! over the light polygon clipped by cube-face frusta and BSP planes — all planes through the
//! vertex, so every split is exact 3D polygon clipping — weighted by visibility. The light is
//! first clipped at the receiver's horizon: below it the trees hold guesses, not visibility.

use super::cube::{CubeVisibility, VISIBLE};
use super::depth;
use super::layout::{skip_encoded, split_codes, vertex_depths, vertex_faces};
use super::node::dequantise_line;
use crate::light::FlatLight;
use crate::material::Bsdf;
use crate::material::Material;
use crate::math::{cubemap, ltc, polygon};
use glam::{DMat3, DVec3, Vec3};

/// How visibility enters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Visibility<'a> {
    /// BSP visibility trees: a baked vertex record, at a face resolution.
    Tree(&'a [u8], usize),
    /// The raw cube map, the light clipped exactly per visible texel (and, where the map has
    /// its occluded texels' first hits, per occluded texel in front of its hit's plane).
    Exact(&'a CubeVisibility),
    /// No shadows.
    Unshadowed,
}

/// Everything LTC shading needs at one vertex for one view.
pub struct PointShader {
    /// Shading point.
    pub p: DVec3,
    /// Unit normal.
    pub n: DVec3,
    /// World → local frame (x toward the view), the diffuse lobe's space.
    pub frame: DMat3,
    /// World → the specular LTC's cosine space (`M⁻¹ · frame`).
    pub spec_inv: DMat3,
    /// Diffuse albedo (RGB).
    pub diffuse: DVec3,
    /// Specular weight `F0 (magnitude − fresnel) + F90 fresnel` (zero without a specular lobe
    /// or with the view below the surface).
    pub spec: DVec3,
}

impl PointShader {
    /// Prepares shading at `p` (normal `n`) for material `m` seen from `eye`.
    pub fn new(table: &ltc::Table, p: Vec3, n: Vec3, eye: Vec3, m: &Material) -> Self {
        let (pd, nd) = (p.as_dvec3(), n.as_dvec3().normalize());
        let v = (eye.as_dvec3() - pd).normalize_or(nd);
        let frame = ltc::view_frame(nd, v);
        // The diffuse lobe is reported whatever the view side; specular needs the view above.
        let wo_local = (frame * v).as_vec3();
        let bsdf = Bsdf::new(m, wo_local);
        let lut = table.lookup(m.roughness as f64, v.dot(nd));
        let spec = if v.dot(nd) > 0.0 && bsdf.has_specular() {
            bsdf.f0().as_dvec3() * (lut.magnitude - lut.fresnel) + bsdf.f90().as_dvec3() * lut.fresnel
        } else {
            DVec3::ZERO
        };
        Self { p: pd, n: nd, frame, spec_inv: lut.inv * frame, diffuse: bsdf.diffuse_albedo().as_dvec3(), spec }
    }

    /// Adds `weight` × the outgoing radiance per unit light radiance from a polygon piece
    /// (points relative to p) to `sum`, per lobe.
    fn piece(&self, piece: &[DVec3], tex: Option<&TexturedLight>, weight: f64, sum: &mut Sum) {
        let lobe = |m: &DMat3, space: usize| -> (f64, DVec3) {
            let t: Vec<DVec3> = piece.iter().map(|q| *m * *q).collect();
            let scalar = ltc::integrate(&t);
            match tex {
                Some(tex) if scalar != 0.0 => (scalar, scalar * tex.colour(space, &t).as_dvec3()),
                _ => (scalar, DVec3::splat(scalar)),
            }
        };
        let (d, colour) = lobe(&self.frame, 0);
        sum.lobes[0] += weight * d;
        sum.light += weight * colour;
        sum.radiance[0] += weight * self.diffuse * colour;
        if self.spec != DVec3::ZERO {
            let (s, colour) = lobe(&self.spec_inv, 1);
            sum.lobes[1] += weight * s;
            sum.radiance[1] += weight * self.spec * colour;
        }
        sum.pieces += 1;
    }

    /// Outgoing radiance from all `lights` with the given visibility.
    pub fn shade(&self, lights: &[FlatLight], vis: Visibility) -> Vec3 {
        self.shade_counted(lights, vis).0
    }

    /// [`Self::shade`], and how many light pieces were integrated with LTC.
    pub fn shade_counted(&self, lights: &[FlatLight], vis: Visibility) -> (Vec3, usize) {
        let (total, pieces, _) = self.shade_all(lights, vis);
        (total, pieces)
    }

    /// [`Self::shade`], and per light the diffuse and specular lobes' integrals over the light
    /// (cosine-space form factors, no colour) with the given visibility — what per-pixel
    /// shading carries from the vertices as shadowed/unshadowed pairs.
    pub fn shade_with_lobes(&self, lights: &[FlatLight], vis: Visibility) -> (Vec3, Vec<[f64; 2]>) {
        let (total, _, lobes) = self.shade_all(lights, vis);
        (total, lobes)
    }

    /// [`Self::shade`] in two parts: the diffuse lobe's light before the diffuse albedo
    /// multiplies it (a pixel multiplies it by its own albedo: a texture's detail between
    /// vertices), and the specular lobe's radiance.
    pub fn shade_parts(&self, lights: &[FlatLight], vis: Visibility) -> (Vec3, Vec3) {
        let (mut diffuse, mut specular) = (DVec3::ZERO, DVec3::ZERO);
        for light in lights {
            let sum = self.light(light, vis);
            diffuse += light.radiance.as_dvec3() * sum.light;
            specular += light.radiance.as_dvec3() * sum.radiance[1];
        }
        (diffuse.as_vec3(), specular.as_vec3())
    }

    /// The lobes' integrals alone (see [`Self::shade_with_lobes`]).
    pub fn lobe_integrals(&self, lights: &[FlatLight], vis: Visibility) -> Vec<[f64; 2]> {
        self.shade_all(lights, vis).2
    }

    /// The radiance from `lights` through `vis`, and per light the diffuse and the specular
    /// lobe's (shadowed, unshadowed) integrals: what per-pixel shading carries from the
    /// vertices, a pixel's visible fraction of a lobe being the ratio of the two interpolated.
    pub fn lobe_pairs(&self, lights: &[FlatLight], vis: Visibility) -> (Vec3, Vec<[[f32; 2]; 2]>) {
        let (radiance, shut) = self.shade_with_lobes(lights, vis);
        let open = match vis {
            Visibility::Unshadowed => shut.clone(),
            _ => self.lobe_integrals(lights, Visibility::Unshadowed),
        };
        let pair = |s: f64, o: f64| [s as f32, o as f32];
        (radiance, shut.iter().zip(&open).map(|(s, o)| [pair(s[0], o[0]), pair(s[1], o[1])]).collect())
    }

    /// [`Self::lobe_pairs`] at a vertex: one inside geometry (under a box resting on a floor)
    /// takes no part in its pixels' fractions, so its pairs are zero — its occluded lobes
    /// would darken what is seen.
    pub fn vertex_lobe_pairs(&self, lights: &[FlatLight], vis: Visibility, inside: bool) -> (Vec3, Vec<[[f32; 2]; 2]>) {
        let (radiance, mut pairs) = self.lobe_pairs(lights, vis);
        if inside {
            pairs.iter_mut().flatten().flatten().for_each(|x| *x = 0.0);
        }
        (radiance, pairs)
    }

    /// Radiance, LTC pieces integrated, and per light the lobes' integrals.
    fn shade_all(&self, lights: &[FlatLight], vis: Visibility) -> (Vec3, usize, Vec<[f64; 2]>) {
        let mut total = DVec3::ZERO;
        let mut pieces = 0;
        let mut lobes = Vec::with_capacity(lights.len());
        for light in lights {
            let sum = self.light(light, vis);
            total += light.radiance.as_dvec3() * (sum.radiance[0] + sum.radiance[1]);
            pieces += sum.pieces;
            lobes.push(sum.lobes);
        }
        (total.as_vec3(), pieces, lobes)
    }

    /// Outgoing radiance per unit light radiance from all of `light`, with its lobes' integrals.
    fn light(&self, light: &FlatLight, vis: Visibility) -> Sum {
        let mut sum = Sum::default();
        let rel: Vec<DVec3> = light.points.iter().map(|q| q.as_dvec3() - self.p).collect();
        // One-sided lights, and lights entirely below the horizon, contribute nothing.
        if light.normal.as_dvec3().dot(-rel[0]) <= 0.0 || rel.iter().all(|q| q.dot(self.n) <= 0.0) {
            return sum;
        }
        let tex = TexturedLight::new(light, &rel, [&self.frame, &self.spec_inv]);
        let tex = tex.as_ref();
        let tiles = tex.map(|t| t.tiles(&rel));
        for part in tiles.as_deref().unwrap_or(std::slice::from_ref(&rel)) {
            // No light arrives from below the receiver's horizon, but the specular LTC
            // clips at its own transformed horizon and would gather some: clip here, so
            // that the texels there (never cast, "don't care" to the trees) cannot matter.
            let part = polygon::clip(part, self.n);
            if part.len() < 3 {
                continue;
            }
            match vis {
                Visibility::Unshadowed => self.piece(&part, tex, 1.0, &mut sum),
                Visibility::Tree(record, res) => self.through_trees((record, res), &part, tex, &mut sum),
                Visibility::Exact(cube) => self.through_texels(cube, &part, tex, &mut sum),
            }
        }
        sum
    }

    /// Unshadowed radiance from all `lights`, each light's diffuse and specular lobes scaled
    /// by `ratios(light index)` (visible fractions carried from elsewhere).
    pub fn shade_scaled(&self, lights: &[FlatLight], ratios: impl Fn(usize) -> [f64; 2]) -> Vec3 {
        let mut total = DVec3::ZERO;
        for (k, light) in lights.iter().enumerate() {
            let sum = self.light(light, Visibility::Unshadowed);
            let [d, s] = ratios(k);
            total += light.radiance.as_dvec3() * (d * sum.radiance[0] + s * sum.radiance[1]);
        }
        total.as_vec3()
    }

    fn through_trees(&self, (record, res): (&[u8], usize), rel: &[DVec3], tex: Option<&TexturedLight>, acc: &mut Sum) {
        let (trees, depths) = (vertex_faces(record), vertex_depths(record));
        for f in 0..cubemap::FACES {
            if trees[f].is_empty() && depths[f].is_empty() {
                continue;
            }
            let piece = clip_all(rel, &cubemap::face_frustum(f));
            if piece.is_empty() {
                continue;
            }
            let leaf = Leaf { face: f, depth: depths[f], res };
            if trees[f].is_empty() {
                // No tree: every texel above the horizon is occluded.
                self.leaf(&leaf, 0.0, &piece, tex, acc);
            } else {
                self.walk(trees[f], 0, &leaf, piece, tex, acc);
            }
        }
    }

    /// A piece of a light at a leaf of visibility `v`: the share `v` of the texels see it
    /// whole; the occluded rest see the parts of it in front of their occluders' depth.
    fn leaf(&self, leaf: &Leaf, v: f64, piece: &[DVec3], tex: Option<&TexturedLight>, acc: &mut Sum) {
        if v > 0.0 {
            self.piece(piece, tex, v, acc);
        }
        if v < 1.0 {
            depth::front(leaf.depth, leaf.face, leaf.res, piece, &mut |part| self.piece(part, tex, 1.0 - v, acc));
        }
    }

    /// Descends the pre-order tree from byte `i`, splitting `piece`; returns the next index.
    fn walk(
        &self,
        bytes: &[u8],
        i: usize,
        leaf: &Leaf,
        piece: Vec<DVec3>,
        tex: Option<&TexturedLight>,
        acc: &mut Sum,
    ) -> usize {
        if piece.is_empty() {
            return skip_encoded(bytes, i);
        }
        if bytes[i] & 0x80 == 0 {
            self.leaf(leaf, bytes[i] as f64 / 127.0, &piece, tex, acc);
            return i + 1;
        }
        let (angle, offset) = split_codes(bytes, i);
        let ((cos, sin), c) = dequantise_line(angle, offset);
        let (pos, neg) = polygon::split(piece, cubemap::line_plane(leaf.face, cos, sin, -c));
        let next = self.walk(bytes, i + 3, leaf, pos, tex, acc);
        self.walk(bytes, next, leaf, neg, tex, acc)
    }

    fn through_texels(&self, cube: &CubeVisibility, rel: &[DVec3], tex: Option<&TexturedLight>, acc: &mut Sum) {
        let n = cube.res;
        let edge = |k: usize| 2.0 * k as f64 / n as f64 - 1.0;
        for f in 0..cubemap::FACES {
            let piece = clip_all(rel, &cubemap::face_frustum(f));
            if piece.is_empty() {
                continue;
            }
            // Only texels under the piece's (s, t) bounding box.
            let (c, s_ax, t_ax) = cubemap::face_basis(f);
            let (mut lo, mut hi) = (glam::DVec2::splat(1.0), glam::DVec2::splat(-1.0));
            for q in &piece {
                let st = glam::DVec2::new(q.dot(s_ax), q.dot(t_ax)) / q.dot(c);
                lo = lo.min(st);
                hi = hi.max(st);
            }
            let (i0, j0) = cubemap::texel_of(lo, n);
            let (i1, j1) = cubemap::texel_of(hi, n);
            let face = cube.face(f);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    // An occluded texel sees the part of the light in front of its hit's plane.
                    let hit = cube.hits.get((f * n + j) * n + i).copied().flatten();
                    if face[j * n + i] != VISIBLE && hit.is_none() {
                        continue;
                    }
                    let planes = [
                        cubemap::line_plane(f, 1.0, 0.0, -edge(i)),
                        cubemap::line_plane(f, -1.0, 0.0, edge(i + 1)),
                        cubemap::line_plane(f, 0.0, 1.0, -edge(j)),
                        cubemap::line_plane(f, 0.0, -1.0, edge(j + 1)),
                    ];
                    let mut texel_piece = clip_all(&piece, &planes);
                    if let Some(h) = hit.filter(|_| face[j * n + i] != VISIBLE) {
                        let normal = h.n.as_dvec3();
                        texel_piece = polygon::clip_below(&texel_piece, normal, normal.dot(h.q.as_dvec3()));
                    }
                    if texel_piece.len() >= 3 {
                        self.piece(&texel_piece, tex, 1.0, acc);
                    }
                }
            }
        }
    }
}

/// A face being descended: its index, its depth bytes, the face resolution.
struct Leaf<'a> {
    face: usize,
    depth: &'a [u8],
    res: usize,
}

/// What the pieces integrated so far add up to, and their count.
#[derive(Default)]
struct Sum {
    /// Weighted radiance of the diffuse and the specular lobe.
    radiance: [DVec3; 2],
    /// The diffuse lobe's weighted light, before the diffuse albedo multiplies it.
    light: DVec3,
    /// The diffuse and specular lobes' integrals (no colour).
    lobes: [f64; 2],
    pieces: usize,
}

/// A textured light with a prefiltered texture (Heitz et al. 2016, §5.3), fetched per piece:
/// a piece's vector form factor in the lobe's space picks the point of the light plane the
/// lobe looks at through that piece; the level comes from the lobe's footprint on the plane,
/// a quarter of the plane's distance relative to the whole light's size (a property of the
/// lobe, not of the piece). Pieces (texels of exact visibility, tree leaves) so see the part of
/// the texture they expose, instead of one colour for the whole light.
pub struct TexturedLight {
    texture: std::sync::Arc<crate::texture::Texture>,
    /// Per lobe (diffuse, specular): the light's first corner, two edges and normal in the
    /// lobe's space.
    basis: [(DVec3, DVec3, DVec3, DVec3); 2],
    /// Per lobe: the mip level of the lobe's footprint.
    lod: [f32; 2],
    /// Texture coordinates of the first three corners.
    uvs: [glam::DVec2; 3],
}

impl TexturedLight {
    fn new(light: &FlatLight, rel: &[DVec3], spaces: [&DMat3; 2]) -> Option<Self> {
        let texture = light.texture.clone()?;
        if light.uvs.len() < 3 {
            return None;
        }
        let basis = spaces.map(|m| {
            let (c0, c1, c2) = (*m * rel[0], *m * rel[1], *m * rel[2]);
            let (e1, e2) = (c1 - c0, c2 - c0);
            (c0, e1, e2, e1.cross(e2))
        });
        let lod = [0, 1].map(|k| {
            let moved: Vec<DVec3> = rel.iter().map(|q| *spaces[k] * *q).collect();
            let (c0, _, _, n) = basis[k];
            let dist = n.normalize_or_zero().dot(c0).abs();
            let footprint = (0.25 * dist / polygon_area(&moved).sqrt().max(1e-30)).min(1.0);
            (footprint * texture.width.max(texture.height) as f64).max(1.0).log2() as f32
        });
        Some(Self { texture, basis, lod, uvs: [0, 1, 2].map(|k| light.uvs[k].as_dvec2()) })
    }

    /// The light (a quad; other polygons stay whole) cut into k × k tiles, k the number of
    /// texels across at the sharper lobe's level (at most [`MAX_TILES`]): each piece the
    /// visibility cuts is then at most a tile, so a large tree leaf fetches the texture per
    /// tile instead of once, as the texel pieces of exact visibility do.
    fn tiles(&self, rel: &[DVec3]) -> Vec<Vec<DVec3>> {
        let lod = self.lod[0].min(self.lod[1]);
        let texels = self.texture.width.max(self.texture.height) as f32 / lod.exp2();
        let k = (texels.round() as usize).clamp(1, MAX_TILES);
        if rel.len() != 4 || k == 1 {
            return vec![rel.to_vec()];
        }
        let at = |u: f64, v: f64| {
            let (a, b) = (rel[0].lerp(rel[1], u), rel[3].lerp(rel[2], u));
            a.lerp(b, v)
        };
        let t = |i: usize| i as f64 / k as f64;
        (0..k * k)
            .map(|n| {
                let (i, j) = (n % k, n / k);
                vec![at(t(i), t(j)), at(t(i + 1), t(j)), at(t(i + 1), t(j + 1)), at(t(i), t(j + 1))]
            })
            .collect()
    }

    /// The filtered radiance multiplier for a piece of the light (points in lobe `lobe`'s space).
    fn colour(&self, lobe: usize, moved: &[DVec3]) -> Vec3 {
        let (c0, e1, e2, n) = self.basis[lobe];
        let f = ltc::form_factor_vector(moved);
        let denom = n.dot(f);
        // Along f to the plane; a grazing f falls back to the point nearest the origin.
        let p = if denom.abs() > 1e-12 * n.length() * f.length() {
            f * (n.dot(c0) / denom)
        } else {
            n * (n.dot(c0) / n.length_squared())
        };
        let r = p - c0;
        let (a11, a12, a22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
        let det = a11 * a22 - a12 * a12;
        let (x, y) = if det > 0.0 {
            ((r.dot(e1) * a22 - r.dot(e2) * a12) / det, (r.dot(e2) * a11 - r.dot(e1) * a12) / det)
        } else {
            (0.5, 0.5)
        };
        let uv = self.uvs[0] + (self.uvs[1] - self.uvs[0]) * x + (self.uvs[2] - self.uvs[0]) * y;
        self.texture.sample_lod(uv.as_vec2(), self.lod[lobe])
    }
}

/// Most tiles per side a textured light is cut into.
const MAX_TILES: usize = 8;

fn polygon_area(poly: &[DVec3]) -> f64 {
    (1..poly.len().saturating_sub(1)).map(|k| 0.5 * (poly[k] - poly[0]).cross(poly[k + 1] - poly[0]).length()).sum()
}

fn clip_all(poly: &[DVec3], planes: &[DVec3]) -> Vec<DVec3> {
    planes.iter().fold(poly.to_vec(), |p, n| if p.is_empty() { p } else { polygon::clip(&p, *n) })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Affine3A, Vec2};

    /// The diffuse part times the diffuse albedo, plus the specular part, is the whole
    /// radiance: for a glossy dielectric (both lobes), a metal (no diffuse albedo, yet the
    /// diffuse lobe's light is there for a pixel whose texture makes it dielectric) and a
    /// matte surface, lit by a tilted quad.
    #[test]
    fn the_parts_add_up_to_the_radiance() {
        let table = ltc::table();
        // Wound to face down, toward the point below it.
        let quad = [
            Vec3::new(-0.5, 0.0, -0.5),
            Vec3::new(0.5, 0.0, -0.5),
            Vec3::new(0.5, 0.0, 0.5),
            Vec3::new(-0.5, 0.0, 0.5),
        ];
        let to = Affine3A::from_rotation_translation(glam::Quat::from_rotation_x(0.4), Vec3::new(0.3, 2.0, 0.1));
        let uvs = [Vec2::ZERO; 4];
        let light = FlatLight::placed(&quad, &uvs, &to, Vec3::new(4.0, 3.0, 2.0)).expect("a quad has area");
        let lights = std::slice::from_ref(&light);
        let materials = [
            Material { base_color: Vec3::new(0.8, 0.5, 0.2), metallic: 0.0, roughness: 0.3, specular: 1.0 },
            Material { base_color: Vec3::new(1.0, 0.78, 0.34), metallic: 1.0, roughness: 0.4, specular: 1.0 },
            Material::lambertian(Vec3::splat(0.7)),
        ];
        for m in &materials {
            let shader = PointShader::new(&table, Vec3::new(0.2, 0.0, -0.1), Vec3::Y, Vec3::new(1.0, 1.5, 2.0), m);
            let whole = shader.shade(lights, Visibility::Unshadowed);
            let (diffuse, specular) = shader.shade_parts(lights, Visibility::Unshadowed);
            let sum = shader.diffuse.as_vec3() * diffuse + specular;
            assert!((sum - whole).length() <= 1e-5 * whole.length(), "{m:?}: {sum} against {whole}");
            assert!(diffuse.min_element() > 0.0, "{m:?}: the diffuse lobe sees the light");
        }
    }
}
