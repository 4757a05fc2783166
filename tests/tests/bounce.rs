//! The baked look's indirect light per pixel: the look (BSPVT + LTC per pixel, and the radiance
//! cache's bounces, as many as the error budget chooses) against the reference with as many
//! bounces, over the surfaces the camera sees (emitters excluded) — in closed rooms lit from
//! inside, and across sharp edges.

use glam::Vec3;
use kage_engine::cache::{self, Bounces, record::Glossy, record::Source};
use kage_engine::math::relative_rmse;
use kage_engine::reference::{Renderer, Settings as RefSettings};
use kage_engine::scene::Scene;
use kage_engine::scene::import::{ImportOptions, import};
use kage_engine::shading::baked::{Bakes, Look};
use kage_engine::{bspvt, prt, raster, receivers};
use kage_tests::{CORNELL_POSES, LightMove, asset, move_lights};

const SIZE: (usize, usize) = (96, 96);

/// Samples per pixel of the look, as `kage render` draws it: with fewer, a silhouette's
/// pixels read their coverage in quarters against the reference's hundreds of samples.
const LOOK_SPP: u32 = 16;

/// `rel` imported and its receivers refined as `kage render` refines them by default.
fn room(rel: &str) -> Scene {
    let mut scene = import(&asset(rel), ImportOptions::default()).unwrap();
    receivers::refine(&mut scene, &receivers::Settings { budget: 6000, ..Default::default() }).unwrap();
    scene
}

/// The baked look's images of `scene` through its camera from one bake, for each run: its
/// lights moved by the run's move (no re-bake), with the run's bounces; with how many bounces
/// each was, and the scene as shaded.
fn looks(scene: &Scene, runs: &[(LightMove, Bounces)]) -> Vec<(Vec<Vec3>, usize, Scene)> {
    let camera = scene.first_camera().unwrap();
    let trees = bspvt::bake(&Renderer::new(scene).flat, &bspvt::Settings::default(), &|_| {});
    runs.iter()
        .map(|&(mv, bounces)| {
            let mut moved = scene.duplicate();
            move_lights(&mut moved, mv);
            let r = Renderer::new(&moved);
            assert!(bspvt::unseen_lights(&r.flat, &trees).is_empty());
            let bakes = Bakes { bspvt: Some(&trees), prt: None, prefiltered: None };
            let look = Look::prepare(&moved, &r.flat, bakes, camera.eye(), &mut prt::SilhouetteMemo::default());
            let toward = |i, corners, bary, to| look.toward(i, corners, bary, to);
            let src = Source { renderer: &r, direct: look.direct_vertices(), glossy: Glossy::Toward(&toward) };
            let records = cache::place_at_vertices(&src, &cache::Settings::default());
            let (indirect, bounced) = cache::bounce(&src, &records, camera.eye(), bounces);
            eprintln!("{}: {bounced}", scene.source);
            let look = Look::prepare(&moved, &r.flat, bakes, camera.eye(), &mut prt::SilhouetteMemo::default());
            let image = look.with_indirect(indirect).render(&r, &camera, SIZE.0, SIZE.1, LOOK_SPP);
            (image, bounced.count, moved)
        })
        .collect()
}

/// No move.
const AS_BUILT: LightMove = |_| {};

/// The reference's image of `scene` with `bounces` bounces at `spp`, which pixels to compare
/// (those whose samples, and their neighbours', all see receivers: one sample on an emitter
/// outweighs the rest of a pixel) and its relative standard error over them.
fn reference(scene: &Scene, bounces: usize, spp: u32) -> (Vec<Vec3>, Vec<bool>, f64) {
    reference_where(scene, bounces, spp, &|_| true)
}

/// [`reference`], comparing the pixels whose samples, and their neighbours', all see
/// receivers where `keep` holds.
fn reference_where(
    scene: &Scene,
    bounces: usize,
    spp: u32,
    keep: &(dyn Fn(&raster::SurfaceHit) -> bool + Sync),
) -> (Vec<Vec3>, Vec<bool>, f64) {
    let r = Renderer::new(scene);
    let camera = scene.first_camera().unwrap();
    let settings = RefSettings { spp, seed: 11, max_bounces: bounces as u32, min_bounces: 0 };
    let image = r.render_image(&camera, SIZE.0, SIZE.1, &settings, &|_| {});
    let kept = raster::shade_image(&r, &camera, SIZE.0, SIZE.1, 16, &|h| Vec3::splat(f32::from(keep(h))));
    // A pixel next to one with an emitter sample is left out too: the reference's jittered
    // samples reach past the mask's 16, and one of them on the light outweighs the rest.
    let (w, h) = SIZE;
    let near = |k: usize| {
        let (x, y) = (k % w, k / w);
        (y.saturating_sub(1)..(y + 2).min(h))
            .all(|b| (x.saturating_sub(1)..(x + 2).min(w)).all(|a| kept[b * w + a] == Vec3::ONE))
    };
    let surface: Vec<bool> = (0..w * h).map(near).collect();
    let counted: Vec<_> = image.iter().zip(&surface).filter(|(_, s)| **s).map(|(e, _)| *e).collect();
    let noise = kage_engine::reference::relative_standard_error(&counted);
    eprintln!("{}: reference, {bounces} bounces at {spp} spp, relative standard error {noise:.4}", scene.source);
    (image.iter().map(|e| e.mean).collect(), surface, noise)
}

/// Relative RMSE of `ours` against `truth` over the `surface` pixels.
fn over(surface: &[bool], ours: &[Vec3], truth: &[Vec3]) -> f64 {
    let pick = |v: &[Vec3]| v.iter().zip(surface).filter(|(_, s)| **s).map(|(v, _)| *v).collect::<Vec<_>>();
    relative_rmse(&pick(ours), &pick(truth))
}

/// The Cornell box: white walls carry most of its light from bounce to bounce. The budget
/// (2 %) chooses the bounces; the look then matches the reference with as many bounces, and
/// one with 8. One bounce alone is far darker.
#[test]
fn the_cornell_box_gets_the_bounces_it_needs() {
    let scene = room("scenes/cornell_box.gltf");
    let runs = [(AS_BUILT, Bounces::default()), (AS_BUILT, Bounces::Fixed(1))];
    let [(image, count, _), (one, ..)]: [_; 2] = looks(&scene, &runs).try_into().ok().unwrap();
    let (truth, surface, _) = reference(&scene, count, 512);
    let (eight, ..) = reference(&scene, 8, 512);
    let (same, deep, single) =
        (over(&surface, &image, &truth), over(&surface, &image, &eight), over(&surface, &one, &eight));
    eprintln!(
        "Cornell box per pixel: {count} bounces {same:.4} from the reference's {count}, {deep:.4} from 8; one bounce {single:.4} from 8"
    );
    assert!((3..=12).contains(&count), "{count} bounces");
    // Measured: 6 bounces, 3.56 % (the reference's own noise 3.0 %), 3.83 % from 8 bounces;
    // one bounce 23.8 % from 8.
    assert!(same < 0.05, "{same}");
    assert!(deep < 0.08, "{deep}");
    assert!(single > 3.0 * deep, "one bounce {single}, {count} bounces {deep}");
}

/// The Cornell box's light moved with no re-bake (receivers refined for it as built): 15 cm
/// toward the red wall and turned 20° about its normal, and lowered 15 cm and tilted 20°. The
/// look with its bounces still follows the reference beyond the reference's own noise (an
/// error e against a reference of relative standard error σ reads √(e² + σ²)).
#[test]
fn the_cornell_box_light_moves_with_no_re_bake() {
    let scene = room("scenes/cornell_box.gltf");
    let [turned, tilted, _] = CORNELL_POSES;
    for (k, (image, count, moved)) in
        looks(&scene, &[(turned, Bounces::default()), (tilted, Bounces::default())]).into_iter().enumerate()
    {
        let (truth, surface, noise) = reference(&moved, count, 512);
        let error = over(&surface, &image, &truth);
        let beyond_noise = (error * error - noise * noise).max(0.0).sqrt();
        eprintln!(
            "Cornell box, light pose {}: {count} bounces, {error:.4} per pixel, {beyond_noise:.4} beyond the reference's noise",
            k + 1
        );
        // Measured: turned 4.61 % (the reference's noise 3.3 %), 3.22 % beyond the noise;
        // tilted 8.48 % (its noise 7.7 %: the block's top 5 cm under the light is lit
        // brightly, and paths off it are rare), 3.51 % beyond it. Against 8192 paths a pixel
        // the tilted pose reads 4.37 % (noise 1.93 %): 3.92 % beyond (5.09 % with every
        // record at 256 rays: the records that read the bright top through few rays gather
        // a denser grid, `cache::Settings::noise`; docs/benchmarks.md).
        assert!(error < [0.06, 0.10][k], "pose {}: {error}", k + 1);
        assert!(beyond_noise < 0.05, "pose {}: {beyond_noise} beyond the reference's noise {noise}", k + 1);
    }
}

/// A box of 24 vertices (flat normals) on a two-triangle floor, its −x face turned away from
/// the light: that face sees only the floor's bounce, and the records of the faces around it
/// (90° away) must not light it.
#[test]
fn a_face_turned_away_gets_only_its_own_bounce() {
    let scene = room("scenes/lowpoly_box.gltf");
    let [(image, count, _)] = looks(&scene, &[(AS_BUILT, Bounces::default())]).try_into().ok().unwrap();
    let (truth, face, _) =
        reference_where(&scene, count, 2048, &|h| (h.position.x + 0.5).abs() < 1e-3 && h.position.y > 1e-3);
    let pixels = face.iter().filter(|f| **f).count();
    let error = over(&face, &image, &truth);
    eprintln!("low-poly box, the face turned away ({pixels} pixels): {count} bounces, {error:.4} from the reference");
    assert!(pixels > 500, "{pixels}");
    // Measured: 6.72 % (the reference's own noise there 5.3 %); 11.3 % without neighbour
    // clamping at contacts, when records from higher up reached the face's foot past the dark
    // records gathered there (blotches along the edge). A record used across the 90° edge would put it
    // at 2.8×.
    assert!(error < 0.10, "{error}");
}

/// A closed room of half-extents `h` seen from inside: a cuboid with its faces turned in,
/// refined to `vertices` vertices.
fn inward_room(h: Vec3, vertices: usize) -> kage_engine::scene::Mesh {
    let outward = kage_engine::scene::shapes::cuboid(h);
    let normals = outward.normals.iter().map(|n| -*n).collect();
    let triangles = outward.triangles.iter().map(|t| [t[0], t[2], t[1]]).collect();
    let (room, _) =
        kage_engine::scene::Mesh::new(outward.positions.clone(), Some(normals), vec![], triangles, false).unwrap();
    kage_engine::scene::refine::refine(&room, vertices).unwrap()
}

/// Two rooms side by side, a 2 cm wall between them (each room's own wall), a panel light
/// under the first room's ceiling: the second room gets no light, direct or bounced (but for
/// the trees' trace below), while the first is lit.
#[test]
fn the_light_in_one_room_does_not_reach_the_next() {
    use glam::Affine3A;
    use kage_engine::scene::{Material, Scene};
    let mut scene = Scene::new("test:two rooms");
    let white = Material::lambertian(Vec3::splat(0.8));
    let h = Vec3::new(0.5, 0.5, 0.5);
    scene.add_object("lit", inward_room(h, 600), white, Affine3A::from_translation(Vec3::new(-0.51, 0.5, 0.0)));
    scene.add_object("dark", inward_room(h, 600), white, Affine3A::from_translation(Vec3::new(0.51, 0.5, 0.0)));
    let q = 0.15;
    let panel = vec![Vec3::new(-q, 0.0, -q), Vec3::new(q, 0.0, -q), Vec3::new(q, 0.0, q), Vec3::new(-q, 0.0, q)];
    scene.add_light("panel", panel, Vec3::splat(20.0), Affine3A::from_translation(Vec3::new(-0.51, 0.999, 0.0)));
    let r = Renderer::new(&scene);
    let eye = Vec3::new(0.0, 0.5, 0.3);
    let trees = bspvt::bake(&r.flat, &bspvt::Settings::default(), &|_| {});
    let bakes = Bakes { bspvt: Some(&trees), prt: None, prefiltered: None };
    let look = Look::prepare(&scene, &r.flat, bakes, eye, &mut prt::SilhouetteMemo::default());
    let toward = |i, corners, bary, to| look.toward(i, corners, bary, to);
    let src = Source { renderer: &r, direct: look.direct_vertices(), glossy: Glossy::Toward(&toward) };
    let records = cache::place_at_vertices(&src, &cache::Settings::default());
    let (indirect, bounced) = cache::bounce(&src, &records, eye, Bounces::default());
    let total = |values: &[Vec3]| values.iter().map(|v| v.element_sum()).sum::<f32>();
    let (lit, dark) = (0, 1);
    eprintln!(
        "two rooms, {bounced}: lit room direct {:.3}, bounced {:.3}; the next room {} and {}",
        total(&src.direct[lit]),
        total(&indirect[lit]),
        total(&src.direct[dark]),
        total(&indirect[dark])
    );
    assert!(total(&src.direct[lit]) > 0.0 && total(&indirect[lit]) > 0.0);
    // Per texel (`ltc-exact-vis`) the next room gets exactly nothing. The trees (ε 2) leave
    // it a trace, 10⁻⁵ of the lit room's light: a leaf of its far wall's cube map holds a few
    // texels grazing the wall's own horizon (open: nothing cast there) among thousands of
    // occluded ones, and its visibility rounds to 1 or 2 of 127, which the light's piece there
    // takes whole; with ε 0.25 it is exactly 0 too.
    let exact = bspvt::shade_vertices(&r.flat, bspvt::Shadows::Exact { res: 64 }, eye);
    assert_eq!(total(&exact[dark]), 0.0);
    let lit_mean = total(&src.direct[lit]) / src.direct[lit].len() as f32;
    let brightest = |values: &[Vec3]| values.iter().map(|v| v.max_element()).fold(0.0, f32::max);
    assert!(brightest(&src.direct[dark]) < 1e-3 * lit_mean, "{}", brightest(&src.direct[dark]));
    assert!(total(&src.direct[dark]) < 1e-4 * total(&src.direct[lit]));
    assert!(total(&indirect[dark]) < 1e-4 * total(&indirect[lit]));
}

/// A furnished closed room (`scripts/make_furnished_room.py`): two panel lights under the
/// ceiling, a table on legs, a sofa, shelves; the look with the bounces the budget chooses
/// against the reference with as many.
#[test]
fn a_furnished_room_matches_the_reference() {
    let scene = room("scenes/furnished_room.gltf");
    let [(image, count, _)] = looks(&scene, &[(AS_BUILT, Bounces::default())]).try_into().ok().unwrap();
    let (truth, surface, _) = reference(&scene, count, 512);
    let error = over(&surface, &image, &truth);
    eprintln!("furnished room per pixel: {count} bounces, {error:.4} from the reference's {count}");
    assert!(error < 0.06, "{error}");
}
