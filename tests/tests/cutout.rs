//! Cut-out occluders (glTF `alphaMode: MASK`): imported, open to every ray and silhouette the
//! bakes and the reference cast, and part of the bake keys. The scene is
//! `assets/scenes/cutout_lattice.gltf` (`scripts/make_cutout_lattice.py`): a lattice card of
//! two triangles over a low-poly floor under a small quad light.

use glam::Vec3;
use kage_engine::accel::SceneBvh;
use kage_engine::math::relative_rmse;
use kage_engine::prt;
use kage_engine::raster;
use kage_engine::reference::{Renderer, Settings};
use kage_engine::scene::import::{ImportOptions, import};
use kage_engine::scene::{EnvMap, EnvironmentLight, MaterialMaps, Name, Scene, flatten};
use kage_engine::{bspvt, receivers};
use kage_tests::{asset, with_baked_look};

fn scene() -> Scene {
    let s = import(&asset("scenes/cutout_lattice.gltf"), ImportOptions::default()).unwrap();
    s.with_environment(EnvironmentLight::new(EnvMap::load(&asset("envmaps/sky.hdr")).unwrap()))
}

/// The lattice's entity.
fn lattice(s: &Scene) -> hecs::Entity {
    s.world.query::<(hecs::Entity, &Name, &MaterialMaps)>().iter().find(|(_, n, _)| n.0 == "lattice").unwrap().0
}

/// The lattice's rigid group (its own top-level node).
fn lattice_group(s: &Scene) -> hecs::Entity {
    s.world.get::<&kage_engine::scene::InGroup>(lattice(s)).unwrap().group
}

/// `s` with the lattice's cutoff set to `cutoff` (`None`: solid, the mask ignored).
fn with_cutoff(s: &Scene, cutoff: Option<f32>) -> Scene {
    let mut out = s.duplicate();
    let e = lattice(&out);
    let mut maps = *out.world.get::<&MaterialMaps>(e).unwrap();
    maps.cutout = cutoff.and_then(|c| maps.cutout.map(|m| kage_engine::scene::Cutout { cutoff: c, ..m }));
    out.world.insert_one(e, maps).unwrap();
    out
}

#[test]
fn a_mask_material_is_a_cutout_with_the_textures_alpha() {
    let s = scene();
    let cutout = s.world.get::<&MaterialMaps>(lattice(&s)).unwrap().cutout.unwrap();
    assert_eq!((cutout.factor, cutout.cutoff), (1.0, 0.5));
    let alpha = &s.textures[cutout.alpha.unwrap().texture as usize];
    // 17² texels: a bar every 4 texels (alpha 1), openings between (alpha 0).
    assert_eq!((alpha.width, alpha.texels[0], alpha.texels[17 + 1]), (17, Vec3::ONE, Vec3::ZERO));
    // A ray down through an opening's centre passes; one through a bar stops. The lattice is
    // 1.6 m wide at y = 1.2, its texels 1.6/17 m.
    let bvh = SceneBvh::over(&flatten(&s));
    let texel = 1.6 / 17.0;
    let down = |x: f32, z: f32| bvh.closest_hit(Vec3::new(x, 3.0, z), Vec3::NEG_Y, f32::INFINITY).unwrap().t;
    let opening = -0.8 + 2.5 * texel;
    assert!((down(opening, opening) - 3.0).abs() < 1e-4, "through the opening to the floor");
    assert!((down(-0.8 + 4.5 * texel, opening) - 1.8).abs() < 1e-4, "stopped by a bar");
}

/// The baked look (polygonal light through BSPVT trees, `sky.hdr` through PRT — the lattice is
/// its own group, so its shadow is a silhouette — and the sky's sun by a ray) against the
/// reference (160×90, 128 spp, direct light), per pixel over geometry. The floor is refined to
/// 3,000 vertices so the openings' light resolves. Measured: 5.5 % with the cut-out; the same
/// bakes of a solid lattice are 18.0 % from the reference's image, and the reference's own
/// images of the two differ by 17.6 % (the lattice's shadow is a small part of the image).
#[test]
fn light_falls_through_the_openings_in_the_bakes_and_the_reference_alike() {
    let mut s = scene();
    s.refine_instances("floor", 3000).unwrap();
    let camera = s.first_camera().unwrap();
    let (w, h) = (160, 90);
    let settings = Settings { spp: 128, seed: 5, max_bounces: 0, min_bounces: 0 };
    let truth = |s: &Scene| -> Vec<Vec3> {
        Renderer::new(s).render_image(&camera, w, h, &settings, &|_| {}).iter().map(|e| e.mean).collect()
    };
    let cut = truth(&s);
    let hits = raster::shade_image(&Renderer::new(&s), &camera, w, h, 4, &|_| Vec3::ONE);
    let pick =
        |v: &[Vec3]| -> Vec<Vec3> { v.iter().zip(&hits).filter(|(_, m)| **m == Vec3::ONE).map(|(p, _)| *p).collect() };
    let baked = |scene: &Scene| {
        with_baked_look(scene, camera.eye(), |look, _| pick(&look.render(&Renderer::new(scene), &camera, w, h, 4)))
    };
    let solid = with_cutoff(&s, None);
    let error = relative_rmse(&baked(&s), &pick(&cut));
    let solid_error = relative_rmse(&baked(&solid), &pick(&cut));
    let references_differ = relative_rmse(&pick(&truth(&solid)), &pick(&cut));
    assert!(error < 0.08, "cut-out baked against its reference: {error:.4}");
    assert!(solid_error > 2.5 * error, "a solid lattice's bakes: {solid_error:.4}");
    assert!(references_differ > 2.5 * error, "the reference sees the holes: {references_differ:.4}");
}

/// What a cut-out is part of every key it changes: the BSPVT occluder snapshot, the PRT group
/// geometry (through the plan's keys) and the receiver refinement.
#[test]
fn bake_keys_follow_the_cutout() {
    let s = scene();
    let dir = tempfile::tempdir().unwrap();
    let store = kage_bake_db::Store::open(&dir.path().join("bake.redb")).unwrap();
    let keys = |s: &Scene| {
        let flat = flatten(s);
        let plan =
            kage_bake_db::plan(&store, s, &flat, Some(bspvt::Settings::default()), Some(prt::Settings::default()))
                .unwrap();
        let lattice = flat.instances.iter().position(|i| i.group == lattice_group(s)).unwrap();
        // Per job: its kind, whether it is the lattice's, its key.
        let jobs: Vec<_> = plan.jobs.iter().map(|j| (j.kind, j.instance == lattice, j.key)).collect();
        (jobs, receivers::keys(s, &receivers::Settings::default()))
    };
    let (a, b, solid) = (keys(&s), keys(&with_cutoff(&s, Some(0.6))), keys(&with_cutoff(&s, None)));
    assert_eq!(a, keys(&s.duplicate()), "keys are a function of the scene");
    for other in [&b, &solid] {
        assert_ne!(a.1, other.1, "refinement");
        for ((kind, on_lattice, key), (_, _, again)) in a.0.iter().zip(&other.0) {
            // Every BSPVT chunk sees the lattice; PRT chunks see their own group only.
            let changes = *kind == kage_bake_db::plan::Kind::Bspvt || *on_lattice;
            assert_eq!(key != again, changes, "{kind:?}, on the lattice: {on_lattice}");
        }
    }
    drop(store);
    std::fs::remove_dir_all(dir).unwrap();
}

/// The hole test reads the mask at the hit's interpolated UVs: a cutoff between two texels'
/// alphas moves the edge of an opening as bilinear filtering says.
#[test]
fn the_cutoff_moves_an_openings_edge_bilinearly() {
    let s = scene();
    let texel = 1.6 / 17.0;
    // Between a bar's texel centre (alpha 1, u = 4.5/17) and an opening's (alpha 0, 5.5/17)
    // alpha falls linearly: the edge is at u = (4.5 + 1 − cutoff)/17.
    for cutoff in [0.25, 0.5, 0.75] {
        let bvh = SceneBvh::over(&flatten(&with_cutoff(&s, Some(cutoff))));
        let edge = -0.8 + (5.5 - cutoff) * texel;
        let z = -0.8 + 2.5 * texel;
        let blocked = |x: f32| bvh.occluded(Vec3::new(x, 3.0, z), Vec3::NEG_Y, 2.5);
        assert!(blocked(edge - 0.02 * texel) && !blocked(edge + 0.02 * texel), "cutoff {cutoff}");
    }
}
