//! BSPVT: shadows from polygonal lights with BSP visibility trees (Okuno & Iwasaki;
//! `docs/references.md`, `docs/bspvt.md`).
//!
//! - [`visibility`]: per-vertex visibility cube maps (faces aligned to world axes), cast only
//!   above the horizon;
//! - [`tree`]: per face, a fixed grid of tiles and inside each the BSP tree of Algorithm 1 with
//!   the paper's algorithm with two corrections (docs/bspvt.md) ([`split`]; tiles make re-bakes local); [`grid`]: the tile
//!   grid's lines and corner directions;
//! - [`memo`]: tile subtrees already built, shared by a bake's workers and kept between bakes,
//!   one per orbit of the face's eight [`symmetry`] images;
//! - [`rebake`]: warm re-bakes after an edit, with [`dirty`]: which tiles and texels an edit
//!   inside a box can change;
//! - [`reach`]: which tiles the lights can be seen through (the rest bake as occluded, uncast);
//! - [`depth`]: how far the occluders are, as planes beside the trees, so that what lies
//!   behind a light (a ceiling) does not hide it;
//! - [`layout`]: the compact versioned byte layout (≈2 bytes per node);
//! - [`shade`]: per vertex and light, the light polygon clipped by face frusta and tree planes
//!   (planes through the vertex) and integrated with LTC, weighted by the leaves' visibility;
//!   the same code runs `ltc-exact-vis` (per visible texel) and `ltc-unshadowed`.
//!
//! Baking depends only on the occluders' geometry (lights are not occluders: they move freely
//! at run time, within their declared [`reach::Reach`]), the face resolution and ε; it is
//! parallel over vertices and deterministic.

pub mod budget;
pub mod dirty;
pub mod grid;
pub mod memo;
pub mod pixel;
pub mod reach;
pub mod rebake;
pub mod split;
pub mod symmetry;
pub mod tree;
pub mod visibility;

pub use kage_runtime::bspvt::{BakedInstance, depth, layout, node, shade};

use crate::accel::Occluders;
use crate::scene::FlatScene;
use crate::scene::VertexValues;
use memo::SubtreeMemo;
use rayon::prelude::*;
use reach::Reach;
pub use rebake::{Change, rebake_vertex};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

/// Version of the bake algorithm, part of every bake key: bumped whenever the same inputs
/// would give different trees (2: trees start with the tile grid of [`node::TILE`]; 3: the
/// split search's looser Nelder–Mead tolerance and fused sums, see [`split`]; 4: a tile's
/// subtree is its orbit's, mapped, see [`symmetry`], and the search's own sine and cosine; 5: three
/// single-precision searches without restarts, see [`split`]; 6: what touches a ray's start does
/// not block it, see [`crate::accel::touching_distance`]; 7: an occluder of many triangles is
/// asked in pieces, see [`crate::accel::Occluders`] — the same texels on every level measured,
/// but a ray grazing a piece's box may round otherwise than through the whole BVH's boxes; 8:
/// with declared light reach, a ray ends where it leaves the farthest reach box it meets, see
/// [`reach::Reach::ray_end`]; 9: closest hits (rooms' depth planes) search an occluder's pieces
/// nearest first, see [`crate::accel::Occluders::closest`] — where two pieces' triangles meet
/// at an edge, a ray along it may now find the nearer of two hits that round apart); 10: a ray
/// lifted above the horizon asks its tile's pieces listed for lifted rays (the list made for
/// the tile's centred rays could leave out a piece such a ray meets), and closest hits ask the
/// tile's pieces too, see [`visibility`].
pub const ALGORITHM_VERSION: u32 = 10;

/// Bake parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Cube-face resolution (texels per side).
    pub res: usize,
    /// Split clusters while their error (in mean-texel units) exceeds this.
    pub epsilon: f64,
}

impl Default for Settings {
    fn default() -> Self {
        Self { res: 64, epsilon: 2.0 }
    }
}

pub use layout::FACE_RESOLUTIONS;

impl Settings {
    /// Checks the settings against [`FACE_RESOLUTIONS`] and a finite, non-negative ε (a pack
    /// may declare any numbers; work is sized by them).
    pub fn check(&self) -> Result<(), String> {
        if !FACE_RESOLUTIONS.contains(&self.res) {
            return Err(format!("face resolution {} is outside {FACE_RESOLUTIONS:?}", self.res));
        }
        if !(self.epsilon.is_finite() && self.epsilon >= 0.0) {
            return Err(format!("split threshold {} is not a finite number ≥ 0", self.epsilon));
        }
        Ok(())
    }
}

/// Statistics of a bake.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stats {
    /// Vertices baked.
    pub vertices: usize,
    /// Leaves over all faces and vertices.
    pub leaves: usize,
    /// Nodes (leaves + splits).
    pub nodes: usize,
    /// Bytes of all records.
    pub bytes: usize,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// A bake of every receiver instance of a scene snapshot.
#[derive(Clone, Debug)]
pub struct Bake {
    /// Parameters used.
    pub settings: Settings,
    /// Per instance, in [`FlatScene::instances`] order.
    pub instances: Vec<BakedInstance>,
    /// Statistics.
    pub stats: Stats,
}

/// Everything that casts shadows on polygonal-light receivers (not the lights), one BVH per
/// instance (see [`Occluders`]: an edit cannot change rays against the other instances).
pub fn occluder_bvh(flat: &FlatScene) -> Occluders {
    Occluders::with(&occluder_triangles(flat), &occluder_holes(flat), |_, t| crate::accel::SceneBvh::new(t))
}

/// Each instance's occluding triangles (its own, lights excepted; a flat refinement's source
/// triangles, see [`FlatScene::occluder_mesh`]), by instance index: what [`occluder_bvh`]
/// builds its BVHs over.
pub fn occluder_triangles(flat: &FlatScene) -> Vec<Vec<[glam::Vec3; 3]>> {
    (0..flat.instances.len()).map(|i| flat.occluder_triangles(i)).collect()
}

/// The holes of [`occluder_triangles`]' lists, by instance.
pub fn occluder_holes(flat: &FlatScene) -> Vec<crate::scene::Holes> {
    (0..flat.instances.len()).map(|i| flat.occluder_holes(i)).collect()
}

/// One vertex's bake: its record and what a warm re-bake of it needs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VertexBake {
    /// The record (see [`layout`]).
    pub record: Vec<u8>,
    /// The visible-texel masks of its mixed tiles, by tile index `f · tiles_per_side² + tile`
    /// (see [`tree::FaceTree::masks`]).
    pub masks: tree::Masks,
    /// Rays cast.
    pub rays: usize,
    /// Mixed tiles whose subtrees were made anew (by Algorithm 1, or from the subtree memo).
    pub built: usize,
}

/// Bakes one vertex with `tiles`' settings, its subtrees from (and added to) `tiles`, for
/// lights within `reach`. Faces entirely below the horizon, entirely occluded or out of reach
/// store no tree: they contribute nothing.
pub fn bake_vertex(
    occluders: &Occluders,
    p: glam::Vec3,
    n: glam::Vec3,
    tiles: &SubtreeMemo,
    reach: &Reach,
) -> VertexBake {
    rebake_vertex(occluders, p, n, (tiles, reach), &VertexBake::default(), &[])
}

/// Tiles per face side at face resolution `res` (see [`node::TILE`]).
pub fn tiles_per_side(res: usize) -> usize {
    res.div_ceil(node::TILE)
}

/// Bakes every receiver vertex, in parallel; `progress` gets the number of vertices done.
/// With no polygonal light in the scene nothing can be reached: every record is empty.
pub fn bake(flat: &FlatScene, s: &Settings, progress: &(dyn Fn(usize) + Sync)) -> Bake {
    let start = Instant::now();
    let occluders = occluder_bvh(flat);
    let tiles = SubtreeMemo::new(s);
    let reach = Reach::of_scene(flat);
    let done = AtomicUsize::new(0);
    let mut stats = Stats::default();
    let instances = (0..flat.instances.len())
        .map(|i| {
            let n = flat.vertex_count(i);
            let records: Vec<Vec<u8>> = (0..n)
                .into_par_iter()
                .map(|v| {
                    let (p, normal) = flat.vertex(i, v);
                    let r = if flat.lights.is_empty() {
                        layout::encode_vertex(&Default::default())
                    } else {
                        bake_vertex(&occluders, p, normal, &tiles, &reach).record
                    };
                    progress(done.fetch_add(1, Ordering::Relaxed) + 1);
                    r
                })
                .collect();
            let mut offsets = vec![0u32];
            let mut data = Vec::new();
            for rec in records {
                data.extend_from_slice(&rec);
                offsets.push(data.len() as u32);
                let (leaves, nodes) = layout::tree_counts(&rec);
                stats.leaves += leaves;
                stats.nodes += nodes;
            }
            stats.vertices += n;
            stats.bytes += data.len();
            BakedInstance { offsets, data }
        })
        .collect();
    stats.seconds = start.elapsed().as_secs_f64();
    Bake { settings: *s, instances, stats }
}

/// Which shadows the per-vertex shading computes: from baked trees, from visibility cast at
/// shading time, or none.
#[derive(Clone, Copy, Debug)]
pub enum Shadows<'a> {
    /// Baked BSP visibility trees.
    Trees(&'a Bake),
    /// The raw visibility cube map, cast at shading time (the tree's ground truth).
    Exact {
        /// Texels per cube-face side.
        res: usize,
    },
    /// No visibility.
    Unshadowed,
}

/// Outgoing radiance toward `eye` from the polygonal lights at every receiver vertex, per
/// instance in [`FlatScene::instances`] order.
pub fn shade_vertices(flat: &FlatScene, shadows: Shadows, eye: glam::Vec3) -> VertexValues {
    let exact = match shadows {
        Shadows::Exact { res } => Some((occluder_bvh(flat), res)),
        _ => None,
    };
    let trees = match shadows {
        Shadows::Trees(bake) => Some(bake),
        _ => None,
    };
    (0..flat.instances.len())
        .map(|i| {
            let n = flat.vertex_count(i);
            (0..n)
                .into_par_iter()
                .map(|v| match &exact {
                    Some((occluders, res)) => {
                        let (p, normal) = flat.vertex(i, v);
                        let cube = visibility::cast_with_hits(occluders, p, normal, *res);
                        let table = crate::math::ltc::table();
                        shade::PointShader::new(&table, p, normal, eye, &flat.vertex_material(i, v))
                            .shade(&flat.lights, shade::Visibility::Exact(&cube))
                    }
                    None => shade_vertex(flat, trees, i, v, eye),
                })
                .collect()
        })
        .collect()
}

/// Outgoing radiance toward `eye` from the polygonal lights at the point of one of instance
/// `i`'s triangles (its `corners`) with barycentrics `bary`: LTC at that point and normal,
/// shadowed by the trees of the nearest corner (`None`: unshadowed). The indirect term lights
/// glossy hits so: the view-dependent lobe is evaluated where the ray hit; visibility, which
/// varies more slowly, is the nearest vertex's (as accurate as weighting all three corners' on
/// the test scene, in half the time).
pub fn shade_point(
    flat: &FlatScene,
    bake: Option<&Bake>,
    i: usize,
    corners: [usize; 3],
    bary: [f32; 3],
    eye: glam::Vec3,
) -> glam::Vec3 {
    let (mut p, mut n) = (glam::Vec3::ZERO, glam::Vec3::ZERO);
    for (&v, &b) in corners.iter().zip(&bary) {
        let (pv, nv) = flat.vertex(i, v);
        p += b * pv;
        n += b * nv;
    }
    let nearest = corners[(0..3).max_by(|&x, &y| bary[x].total_cmp(&bary[y])).unwrap_or(0)];
    let material = flat.material_at(i, corners, bary);
    shade_at(flat, bake.map(|b| (b.instances[i].record(nearest), b.settings.res)), &material, p, n, eye)
}

/// Outgoing radiance toward `eye` from the polygonal lights at vertex `v` of instance `i`,
/// shadowed by `bake`'s trees (`None`: unshadowed LTC).
pub fn shade_vertex(flat: &FlatScene, bake: Option<&Bake>, i: usize, v: usize, eye: glam::Vec3) -> glam::Vec3 {
    let (p, n) = flat.vertex(i, v);
    shade_at(flat, bake.map(|b| (b.instances[i].record(v), b.settings.res)), &flat.vertex_material(i, v), p, n, eye)
}

/// LTC shading of `material` at `p` (normal `n`) toward `eye`, shadowed by a vertex record's
/// trees at its face resolution (`None`: unshadowed).
fn shade_at(
    flat: &FlatScene,
    record: Option<(&[u8], usize)>,
    material: &crate::scene::Material,
    p: glam::Vec3,
    n: glam::Vec3,
    eye: glam::Vec3,
) -> glam::Vec3 {
    let shader = shade::PointShader::new(&crate::math::ltc::table(), p, n, eye, material);
    let vis = record.map_or(shade::Visibility::Unshadowed, |(r, res)| shade::Visibility::Tree(r, res));
    shader.shade(&flat.lights, vis)
}

/// Share of its unshadowed light below which [`unseen_lights`] names a light.
pub const UNSEEN_SHARE: f64 = 1e-4;

/// The lights (indices into `flat.lights`) that `bake`'s trees let the receivers see almost
/// nothing of: over every vertex, the diffuse lobe's integral over the light through the trees
/// is at most [`UNSEEN_SHARE`] of the unshadowed integral (which is positive: some vertex faces
/// the light). Such a light is shut in (a closed shade, behind a wall); what an image shows of
/// it is then its bounce metered up, which commands warn about.
pub fn unseen_lights(flat: &FlatScene, bake: &Bake) -> Vec<usize> {
    let table = crate::math::ltc::table();
    let white = crate::scene::Material::lambertian(glam::Vec3::ONE);
    let vertices: Vec<(usize, usize)> = flat.vertex_ids().collect();
    let zero = || vec![[0.0; 2]; flat.lights.len()];
    let sums = vertices
        .par_iter()
        .fold(zero, |mut acc, &(i, v)| {
            let (p, n) = flat.vertex(i, v);
            let shader = shade::PointShader::new(&table, p, n, p + n, &white);
            let through = shader
                .lobe_integrals(&flat.lights, shade::Visibility::Tree(bake.instances[i].record(v), bake.settings.res));
            let open = shader.lobe_integrals(&flat.lights, shade::Visibility::Unshadowed);
            for (a, (t, o)) in acc.iter_mut().zip(through.iter().zip(&open)) {
                *a = [a[0] + t[0], a[1] + o[0]];
            }
            acc
        })
        .reduce(zero, |a, b| a.iter().zip(&b).map(|(x, y)| [x[0] + y[0], x[1] + y[1]]).collect());
    (0..sums.len()).filter(|&l| sums[l][1] > 0.0 && sums[l][0] <= UNSEEN_SHARE * sums[l][1]).collect()
}

/// What to tell a user about [`unseen_lights`] in `scene` (snapshot `flat`): the lights named
/// and the likely cause; `None` when every light is seen.
pub fn unseen_warning(scene: &crate::scene::Scene, flat: &FlatScene, bake: &Bake) -> Option<String> {
    let unseen = unseen_lights(flat, bake);
    if unseen.is_empty() {
        return None;
    }
    let name = |l: usize| scene.name_of(flat.light_entities[l]).unwrap_or_else(|| format!("#{l}"));
    let names: Vec<String> = unseen.iter().map(|&l| format!("'{}'", name(l))).collect();
    Some(format!(
        "{}: the baked visibility lets almost no receiver see {} of {} light(s) ({}): less than {UNSEEN_SHARE} of \
         their unshadowed light. Such a light is shut in — in a closed box or shade, behind a wall, under the \
         floor, facing a wall it touches — so the image shows little but its bounce",
        scene.source,
        unseen.len(),
        flat.lights.len(),
        names.join(", "),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn from_records(records: &[Vec<u8>]) -> BakedInstance {
        let mut offsets = vec![0u32];
        records.iter().for_each(|r| offsets.push(offsets[offsets.len() - 1] + r.len() as u32));
        BakedInstance { offsets, data: records.concat() }
    }

    #[test]
    fn splicing_records_equals_building_from_them() {
        let records: Vec<Vec<u8>> = (0..7u8).map(|v| vec![v; 1 + (v as usize * 3) % 5]).collect();
        let mut inst = BakedInstance::unshadowed(7);
        assert_eq!(inst.vertices(), 7);
        inst.splice(4, &records[4..]);
        inst.splice(0, &records[..2]);
        inst.splice(2, &records[2..4]);
        assert_eq!(inst, from_records(&records));
        inst.splice(3, &[vec![9; 12]]);
        let mut edited = records.clone();
        edited[3] = vec![9; 12];
        assert_eq!(inst, from_records(&edited));
    }

    #[test]
    fn the_placeholder_shades_like_unshadowed_ltc() {
        let scene = crate::scene::default_scene();
        let flat = crate::scene::flatten(&scene);
        let s = Settings { res: 8, epsilon: 2.0 };
        let instances = (0..flat.instances.len()).map(|i| BakedInstance::unshadowed(flat.vertex_count(i))).collect();
        let bake = Bake { settings: s, instances, stats: Stats::default() };
        let eye = glam::Vec3::new(0.0, 2.0, 5.0);
        let placeholder = shade_vertices(&flat, Shadows::Trees(&bake), eye);
        let open = shade_vertices(&flat, Shadows::Unshadowed, eye);
        for (a, b) in placeholder.iter().flatten().zip(open.iter().flatten()) {
            assert!((*a - *b).abs().max_element() <= 1e-4 * b.max_element().max(1.0), "{a} vs {b}");
        }
    }
}
