//! The complete baked look (`--method baked`): every light a scene has, each through its
//! technique, summed —
//!
//! - polygonal lights: BSPVT trees and LTC (GGX): LTC per pixel in images, the trees'
//!   visibility carried from the vertices ([`bspvt::pixel`]);
//! - the environment: PRT's diffuse transfer with self- and other-group shadows (other groups
//!   evaluated per pixel in images), plus its specular term on glossy and metal surfaces
//!   ([`crate::prt::glossy`]) per pixel — without the map's sun, if it has one
//!   ([`crate::prt::sun`]), which is shaded as a directional light with a shadow ray;
//! - one bounce of indirect light from the HSH radiance cache, per vertex, lit by the sum.
//!
//! Each part is present only where the scene has its light. Images show the environment
//! behind the geometry.

use crate::accel::{SceneBvh, offset_ray_origin};
use crate::bspvt;
use crate::material::albedo;
use crate::material::detail::Detail;
use crate::math::frame::Frame;
use crate::prt::{self, glossy::Lobe, glossy::Specular, prefilter::Prefiltered, sun, sun::Sun};
use crate::raster::{self, SurfaceHit};
use crate::reference::Renderer;
use crate::scene::{Camera, FlatScene, VertexValues};
use glam::Vec3;
use rayon::prelude::*;

/// The GGX α the sun's highlight has at least, per radian of the sun's angular radius.
pub const SUN_ALPHA_FLOOR: f32 = 0.125;

/// The polygonal lights' part: per-vertex radiance toward the eye and the trees it came from.
pub struct Polygonal<'a> {
    /// The trees (`None`: the scene's lights are unshadowed).
    pub bake: Option<&'a bspvt::Bake>,
    /// Per instance and vertex: LTC radiance toward the eye.
    pub values: VertexValues,
    /// The lobes' visible fractions for per-pixel shading (`None`: images interpolate `values`).
    pub lobes: Option<bspvt::pixel::Lobes>,
}

/// The environment's part: PRT's posed frame and what its specular term reads.
pub struct Environment<'a> {
    frame: prt::Frame,
    bake: &'a prt::Bake,
    /// `None`: no map to reflect (a pack written before packs carried it): diffuse only.
    prefiltered: Option<&'a Prefiltered>,
    lobe: Lobe,
    /// The map's sun, shaded apart (the frame and `prefiltered` hold the rest).
    sun: Option<Sun>,
}

impl<'a> Environment<'a> {
    /// The environment's part from a `frame` of the transfer `bake` posed under
    /// `lighting.split_sun().1` (the sun apart), with the environment `prefiltered`.
    pub fn new(
        frame: prt::Frame,
        bake: &'a prt::Bake,
        lighting: &prt::Lighting,
        prefiltered: Option<&'a Prefiltered>,
    ) -> Self {
        let (sun, rest) = lighting.split_sun();
        let lobe = Lobe::new(frame.posed().order, rest.window);
        Self { frame, bake, prefiltered, lobe, sun }
    }

    fn specular<'s>(&'s self, flat: &'s FlatScene) -> Option<Specular<'s>> {
        Some(Specular::new(self.prefiltered?, self.bake, self.frame.posed(), &self.lobe, flat))
    }
}

/// One frame of the baked look, seen from `eye`.
pub struct Look<'a> {
    flat: &'a FlatScene,
    eye: Vec3,
    polygonal: Option<Polygonal<'a>>,
    environment: Option<Environment<'a>>,
    /// Per instance and vertex: the environment's diffuse radiance and open fraction.
    environment_vertices: Option<(VertexValues, Vec<Vec<f32>>)>,
    /// Per instance and vertex: the direct radiance toward the eye (computed once per frame).
    direct: VertexValues,
    indirect: Option<VertexValues>,
    /// The sun and what its shadow rays are cast against (the whole snapshot, lights included).
    sun: Option<(Sun, SceneBvh)>,
}

/// What the look is shaded from: each part's bake, where the scene has its light.
#[derive(Clone, Copy, Default)]
pub struct Bakes<'a> {
    /// BSPVT trees (the scene has polygonal lights).
    pub bspvt: Option<&'a bspvt::Bake>,
    /// PRT transfer with its lighting and settings (the scene has an environment).
    pub prt: Option<prt::Parts<'a>>,
    /// The environment prefiltered for the specular term (`None`: diffuse only).
    pub prefiltered: Option<&'a Prefiltered>,
}

impl<'a> Look<'a> {
    /// Shades the direct parts on the CPU from `bakes` (posed from `scene`, reusing
    /// silhouettes from `memo`).
    pub fn prepare(
        scene: &crate::scene::Scene,
        flat: &'a FlatScene,
        bakes: Bakes<'a>,
        eye: Vec3,
        memo: &mut prt::SilhouetteMemo,
    ) -> Self {
        let polygonal = bakes.bspvt.map(|b| {
            let mut inside = bspvt::pixel::Inside::default();
            let (lobes, values) = bspvt::pixel::Lobes::at_vertices(flat, Some(b), eye, inside.flags(flat));
            Polygonal { bake: Some(b), values, lobes: Some(lobes) }
        });
        let environment = bakes.prt.map(|parts| {
            let rest = prt::Parts { lighting: parts.lighting.split_sun().1, ..parts };
            let frame = prt::Frame::prepare_cached(scene, flat, rest, prt::Shadows::WithOthers, eye, memo);
            Environment::new(frame, parts.bake, parts.lighting, bakes.prefiltered)
        });
        Self::new(flat, eye, polygonal, environment)
    }

    /// The direct parts of one frame (add the bounce with [`Look::with_indirect`]).
    pub fn new(
        flat: &'a FlatScene,
        eye: Vec3,
        polygonal: Option<Polygonal<'a>>,
        environment: Option<Environment<'a>>,
    ) -> Self {
        Self::with_environment_direct(flat, eye, polygonal, environment).0
    }

    /// [`Look::new`], and the environment's part per vertex (the sun apart) it summed.
    fn with_environment_direct(
        flat: &'a FlatScene,
        eye: Vec3,
        polygonal: Option<Polygonal<'a>>,
        environment: Option<Environment<'a>>,
    ) -> (Self, Option<EnvironmentVertices>) {
        let environment_vertices = environment.as_ref().map(|e| {
            let both = e.frame.vertex_values_open(flat);
            let radiance = both.iter().map(|v| v.iter().map(|x| x.0).collect()).collect();
            (radiance, both.iter().map(|v| v.iter().map(|x| x.1).collect()).collect())
        });
        let sun = environment.as_ref().and_then(|e| e.sun).map(|sun| (sun, SceneBvh::quick_over(flat)));
        let mut look =
            Self { flat, eye, polygonal, environment, environment_vertices, direct: Vec::new(), indirect: None, sun };
        let environment = look.environment.as_ref().map(|_| look.environment_direct());
        look.direct = look.shade_direct(environment.as_ref().map(|e| &e.values));
        (look, environment)
    }

    /// [`Look::new`]'s direct radiance per vertex ([`Look::into_direct`]), the environment's
    /// part taken from `memo` when nothing it reads changed since the frame that kept it (a
    /// polygonal light moved: PRT is not posed nor the lobes sampled again), else shaded
    /// (reusing `silhouettes`) and kept. `environment`: the transfer, its lighting and the
    /// prefiltered map, where the scene has an environment.
    pub fn direct_reusing(
        scene: &crate::scene::Scene,
        flat: &'a FlatScene,
        eye: Vec3,
        polygonal: Option<Polygonal<'a>>,
        environment: Option<(prt::Parts<'a>, Option<&'a Prefiltered>)>,
        memo: &mut EnvironmentMemo,
        silhouettes: &mut prt::SilhouetteMemo,
    ) -> VertexValues {
        let Some((parts, prefiltered)) = environment else {
            return Self::new(flat, eye, polygonal, None).into_direct();
        };
        let key = EnvironmentMemo::key(flat, eye, parts, prefiltered);
        if let Some(kept) = memo.kept.as_ref().filter(|k| k.key == key) {
            memo.reused += 1;
            let sun = parts.lighting.split_sun().0.map(|sun| (sun, SceneBvh::quick_over(flat)));
            let look = Self {
                flat,
                eye,
                polygonal,
                environment: None,
                environment_vertices: None,
                direct: Vec::new(),
                indirect: None,
                sun,
            };
            return look.shade_direct(Some(&kept.environment.values));
        }
        let rest = prt::Parts { lighting: parts.lighting.split_sun().1, ..parts };
        let frame = prt::Frame::prepare_cached(scene, flat, rest, prt::Shadows::WithOthers, eye, silhouettes);
        let environment = Environment::new(frame, parts.bake, parts.lighting, prefiltered);
        let (look, environment) = Self::with_environment_direct(flat, eye, polygonal, Some(environment));
        let environment = environment.expect("an environment part was given");
        memo.kept = Some(Kept { key, _prefiltered: prefiltered.cloned(), environment });
        look.into_direct()
    }

    /// Adds one bounce of indirect light per vertex.
    pub fn with_indirect(mut self, indirect: VertexValues) -> Self {
        self.indirect = Some(indirect);
        self
    }

    /// Per instance and vertex: the direct radiance toward the eye (what the indirect term is
    /// lit by, for Lambertian hits).
    pub fn direct_vertices(&self) -> &VertexValues {
        &self.direct
    }

    /// The direct radiance per vertex, the look consumed (the editor's per-vertex preview).
    pub fn into_direct(self) -> VertexValues {
        self.direct
    }

    /// Per vertex: the polygonal part plus `environment`'s (diffuse and specular) and the sun's.
    fn shade_direct(&self, environment: Option<&VertexValues>) -> VertexValues {
        (0..self.flat.instances.len())
            .map(|i| {
                (0..self.flat.vertex_count(i))
                    .into_par_iter()
                    .map(|v| {
                        let poly = self.polygonal.as_ref().map_or(Vec3::ZERO, |poly| poly.values[i][v]);
                        let env = environment.map_or(Vec3::ZERO, |e| {
                            let (p, _) = self.flat.vertex(i, v);
                            e[i][v] + self.sun_at(i, [v; 3], [1.0, 0.0, 0.0], p, self.eye, sun::VERTEX_RAYS)
                        });
                        poly + env
                    })
                    .collect()
            })
            .collect()
    }

    /// Per vertex: the environment's diffuse and specular terms toward the eye, the sun apart,
    /// and the specular term's factors.
    fn environment_direct(&self) -> EnvironmentVertices {
        let (mut values, mut specular, mut weights) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..self.flat.instances.len() {
            let parts: Vec<(Vec3, Vec3, f32)> = (0..self.flat.vertex_count(i))
                .into_par_iter()
                .map(|v| {
                    let (p, _) = self.flat.vertex(i, v);
                    let (diffuse, (reflected, weight)) =
                        self.environment_parts(i, [v; 3], [1.0, 0.0, 0.0], p, self.eye);
                    (diffuse + reflected * weight, reflected * weight, weight)
                })
                .collect();
            values.push(parts.iter().map(|x| x.0).collect());
            specular.push(parts.iter().map(|x| x.1).collect());
            weights.push(parts.iter().map(|x| x.2).collect());
        }
        EnvironmentVertices { values, specular: SpecularVertices { values: specular, weights } }
    }

    /// Per instance and vertex: direct plus indirect radiance toward the eye.
    pub fn vertex_values(&self) -> VertexValues {
        let mut values = self.direct.clone();
        if let Some(indirect) = &self.indirect {
            values.iter_mut().flatten().zip(indirect.iter().flatten()).for_each(|(d, e)| *d += *e);
        }
        values
    }

    /// Direct radiance leaving a point of one of instance `i`'s triangles (`corners`,
    /// barycentrics `bary`) toward `to`, the view-dependent lobes evaluated at the point: what a
    /// gather ray's glossy hit sends back to a cache record.
    pub fn toward(&self, i: usize, corners: [usize; 3], bary: [f32; 3], to: Vec3) -> Vec3 {
        let p = (0..3).map(|c| self.flat.vertex(i, corners[c]).0 * bary[c]).sum();
        let poly = self
            .polygonal
            .as_ref()
            .map_or(Vec3::ZERO, |poly| bspvt::shade_point(self.flat, poly.bake, i, corners, bary, to));
        poly + self.environment_at(i, corners, bary, p, to)
    }

    /// The environment's diffuse term (interpolated), specular term (at `p`, toward `to`) and
    /// sun.
    fn environment_at(&self, i: usize, corners: [usize; 3], bary: [f32; 3], p: Vec3, to: Vec3) -> Vec3 {
        if self.environment.is_none() {
            return Vec3::ZERO;
        }
        self.environment_without_sun(i, corners, bary, p, to) + self.sun_at(i, corners, bary, p, to, sun::SAMPLE_RAYS)
    }

    /// [`Self::environment_at`] without the sun.
    fn environment_without_sun(&self, i: usize, corners: [usize; 3], bary: [f32; 3], p: Vec3, to: Vec3) -> Vec3 {
        let (diffuse, (reflected, weight)) = self.environment_parts(i, corners, bary, p, to);
        diffuse + reflected * weight
    }

    /// [`Self::environment_without_sun`] as the diffuse term and the specular term's factors
    /// ([`prt::glossy::Specular::parts`]).
    fn environment_parts(
        &self,
        i: usize,
        corners: [usize; 3],
        bary: [f32; 3],
        p: Vec3,
        to: Vec3,
    ) -> (Vec3, (Vec3, f32)) {
        let (Some(env), Some((diffuse, open))) = (&self.environment, &self.environment_vertices) else {
            return (Vec3::ZERO, (Vec3::ZERO, 0.0));
        };
        let o = (0..3).map(|c| open[i][corners[c]] * bary[c]).sum::<f32>();
        let d = (0..3).map(|c| diffuse[i][corners[c]] * bary[c]).sum::<Vec3>();
        (d, env.specular(self.flat).map_or((Vec3::ZERO, 0.0), |s| s.parts(i, corners, bary, p, to, o)))
    }

    /// The sun's light leaving a point toward `to` ([`sun_light`], `rays` toward a soft sun).
    fn sun_at(&self, i: usize, corners: [usize; 3], bary: [f32; 3], p: Vec3, to: Vec3, rays: usize) -> Vec3 {
        let light = |(sun, bvh): &(Sun, SceneBvh)| sun_light(self.flat, sun, bvh, (i, corners, bary), p, to, rays).0;
        self.sun.as_ref().map_or(Vec3::ZERO, light)
    }

    /// A `width × height` image with `spp` samples per pixel through `camera`: the material per
    /// sample (textures, vertex colours), the polygonal lights' LTC, the environment's shadows
    /// between groups and its specular term per sample, the lights' visibility and the
    /// environment's diffuse light carried from the vertices, the indirect term interpolated
    /// (scaled by the sample's diffuse albedo over the vertices' where the material varies), the
    /// environment behind the geometry.
    pub fn render(&self, r: &Renderer, camera: &Camera, width: usize, height: usize, spp: u32) -> Vec<Vec3> {
        let (grid, side) = raster::primary_grid(r, camera, width, height, spp);
        let detail = self.indirect.as_ref().map(|_| Detail::new(self.flat, self.eye));
        let interpolated = |hit: &SurfaceHit, albedo: Vec3| {
            let poly = self.polygonal.as_ref().map_or(Vec3::ZERO, |p| match &p.lobes {
                Some(lobes) => lobes.shade(self.flat, hit, self.eye),
                None => hit.interpolate(&p.values[hit.instance]),
            });
            let indirect = self
                .indirect
                .as_ref()
                .zip(detail.as_ref())
                .map_or(Vec3::ZERO, |(v, d)| hit.interpolate(&v[hit.instance]) * d.scale_for(hit, albedo));
            poly + indirect
        };
        let values = match &self.environment {
            Some(env) => {
                let specular = env.specular(self.flat);
                env.frame.shade_grid(&grid, width * side, &|hit, light, open| {
                    let s = specular.as_ref().map_or(Vec3::ZERO, |s| {
                        s.at(hit.instance, hit.corners, hit.weights, hit.position, self.eye, open)
                    });
                    let albedo = albedo::at_hit(self.flat, hit, self.eye);
                    let sun =
                        self.sun_at(hit.instance, hit.corners, hit.weights, hit.position, self.eye, sun::SAMPLE_RAYS);
                    albedo * light + interpolated(hit, albedo) + s + sun
                })
            }
            None => grid
                .par_iter()
                .map(|p| match p {
                    raster::Primary::Miss(l) | raster::Primary::Emitter(l) => *l,
                    raster::Primary::Surface(hit) => interpolated(hit, albedo::at_hit(self.flat, hit, self.eye)),
                })
                .collect(),
        };
        raster::downsample(&values, width, height, side)
    }
}

/// The sun's light leaving a point of instance `i`'s triangle (`corners`, barycentrics) at `p`
/// toward `to`: the material's BSDF times the sun's irradiance, where a shadow ray through
/// `bvh` reaches it; and whether it does (false below the point's horizon). The GGX roughness
/// is at least √([`SUN_ALPHA_FLOOR`] × the sun's angular radius), so that a near-mirror's
/// highlight stays finite; chosen by measurement (docs/baked.md: a wider floor spread a
/// near-mirror's highlight too far).
pub fn sun_light(
    flat: &FlatScene,
    sun: &Sun,
    bvh: &SceneBvh,
    at: (usize, [usize; 3], [f32; 3]),
    p: Vec3,
    to: Vec3,
    rays: usize,
) -> (Vec3, bool) {
    let (open, seen) = sun_parts(flat, sun, bvh, at, p, to, rays);
    (open * seen, seen > 0.0)
}

/// [`sun_light`] with nothing in the way (zero below the point's horizon), and the share of the
/// sun seen: of its shadow rays ([`Sun::shadow_directions`], turned by a hash of `p`), those
/// above the point's horizon that escape.
fn sun_parts(
    flat: &FlatScene,
    sun: &Sun,
    bvh: &SceneBvh,
    (i, corners, bary): (usize, [usize; 3], [f32; 3]),
    p: Vec3,
    to: Vec3,
    rays: usize,
) -> (Vec3, f32) {
    let n = (0..3).map(|c| flat.vertex(i, corners[c]).1 * bary[c]).sum::<Vec3>().normalize_or_zero();
    let frame = Frame::from_normal(n);
    let wi = frame.to_local(sun.direction);
    if wi.z <= 0.0 {
        return (Vec3::ZERO, 0.0);
    }
    let seen = sun_seen(sun, bvh, p, n, rays);
    let mut material = flat.material_at(i, corners, bary);
    material.roughness = material.roughness.max((SUN_ALPHA_FLOOR * sun.angular_radius).sqrt());
    let wo = frame.to_local((to - p).normalize_or_zero());
    (crate::material::Bsdf::new(&material, wo).eval(wo, wi) * wi.z * sun.irradiance, seen)
}

/// The share of `sun` a point `p` (normal `n`) sees past `bvh`: its shadow rays turned by a
/// hash of the point's position, so that neighbouring pixels and vertices average the
/// pattern's offsets into a penumbra. A ray below the point's horizon is blocked by the
/// surface itself.
fn sun_seen(sun: &Sun, bvh: &SceneBvh, p: Vec3, n: Vec3, rays: usize) -> f32 {
    let bits = p.to_array().iter().fold(0u64, |h, c| crate::math::rng::mix64(h ^ c.to_bits() as u64));
    let turn = (bits >> 40) as f32 / (1u64 << 24) as f32;
    let (mut seen, mut cast) = (0, 0);
    for d in sun.shadow_directions(rays, turn) {
        cast += 1;
        let escapes = d.dot(n) > 0.0 && !bvh.occluded_past_touching(offset_ray_origin(p, n, d), d, f32::INFINITY);
        seen += escapes as u32;
    }
    seen as f32 / cast as f32
}

/// Per instance and vertex: the sun's light toward `eye` as the look adds it, and as it would
/// be with nothing in the way — what the editor's viewport takes out of the vertices' radiance
/// and puts back per pixel under its depth map.
pub fn sun_vertices(flat: &FlatScene, sun: &Sun, eye: Vec3) -> (VertexValues, VertexValues) {
    let bvh = SceneBvh::quick_over(flat);
    (0..flat.instances.len())
        .map(|i| {
            let at = |v: usize| {
                let at = (i, [v; 3], [1.0, 0.0, 0.0]);
                let (open, seen) = sun_parts(flat, sun, &bvh, at, flat.vertex(i, v).0, eye, sun::VERTEX_RAYS);
                (open * seen, open)
            };
            let both: Vec<(Vec3, Vec3)> = (0..flat.vertex_count(i)).into_par_iter().map(at).collect();
            both.into_iter().unzip::<_, _, Vec<Vec3>, Vec<Vec3>>()
        })
        .unzip()
}

/// The environment's per-vertex terms (diffuse and specular, the sun apart) of the last frame
/// [`Look::direct_reusing`] shaded, with a hash of everything they read: the eye; every
/// vertex's position, normal and material (textures and vertex colours as sampled there) and
/// group; the occluders' triangles; the transfer, its lighting and settings; the prefiltered map
/// (by identity, which the memo holds on to so that no other map can take its address).
#[derive(Default)]
pub struct EnvironmentMemo {
    kept: Option<Kept>,
    reused: u64,
}

struct Kept {
    key: blake3::Hash,
    /// Held so that the map's address, which the key names, stays its own.
    _prefiltered: Option<Prefiltered>,
    environment: EnvironmentVertices,
}

/// The environment's part per vertex, the sun apart.
struct EnvironmentVertices {
    /// Diffuse plus specular radiance toward the eye.
    values: VertexValues,
    /// The specular term and its factors.
    specular: SpecularVertices,
}

/// The environment's specular term per vertex (`R · w`) and its weight `w = V_lobe · O`
/// ([`prt::glossy::Specular::parts`]): the editor draws `R` per pixel times the interpolated `w`.
#[derive(Clone, Debug, Default)]
pub struct SpecularVertices {
    /// Per instance and vertex: the specular radiance toward the eye.
    pub values: VertexValues,
    /// Per instance and vertex: the lobe's visible fraction times the other groups' open one.
    pub weights: Vec<Vec<f32>>,
}

impl EnvironmentMemo {
    /// The specular term of the frame [`Look::direct_reusing`] shaded or reused last (read it
    /// right after that call, which keeps it only where the scene has an environment).
    pub fn specular(&self) -> Option<&SpecularVertices> {
        self.kept.as_ref().map(|k| &k.environment.specular)
    }

    /// How many frames reused the kept values (the editor's statistics; tests).
    pub fn reused(&self) -> u64 {
        self.reused
    }

    fn key(flat: &FlatScene, eye: Vec3, parts: prt::Parts, prefiltered: Option<&Prefiltered>) -> blake3::Hash {
        let mut h = blake3::Hasher::new();
        h.update(bytemuck::bytes_of(&eye));
        for (i, instance) in flat.instances.iter().enumerate() {
            h.update(&instance.group.to_bits().get().to_le_bytes());
            h.update(&(flat.vertex_count(i) as u64).to_le_bytes());
            for v in 0..flat.vertex_count(i) {
                let ((p, n), m) = (flat.vertex(i, v), flat.vertex_material(i, v));
                h.update(bytemuck::cast_slice(&[p, n, m.base_color]));
                h.update(bytemuck::cast_slice(&[m.metallic, m.roughness, m.specular]));
            }
        }
        for (t, r) in flat.triangles.iter().zip(&flat.refs).filter(|(_, r)| r.light == crate::scene::NO_LIGHT) {
            h.update(bytemuck::cast_slice(t));
            h.update(&r.owner.to_le_bytes());
        }
        h.update(&(parts.bake.order as u64).to_le_bytes());
        for t in &parts.bake.instances {
            h.update(bytemuck::cast_slice(t));
        }
        h.update(format!("{:?} {:?}", parts.lighting, parts.settings).as_bytes());
        if let Some(p) = prefiltered {
            p.hash_into(&mut h);
        }
        h.finalize()
    }
}
