//! BSPVT against its own comparison modes and the reference, and its hard cases.

use glam::{Affine3A, Vec3};
use kage_engine::bspvt::memo::SubtreeMemo;
use kage_engine::bspvt::shade::{PointShader, Visibility};
use kage_engine::bspvt::{self, Settings, bake_vertex, occluder_bvh, reach::Reach, visibility};
use kage_engine::math::ltc;
use kage_engine::math::relative_rmse as rel_rmse;
use kage_engine::reference::{Renderer, Settings as RefSettings, SurfacePoint};
use kage_engine::scene::import::{ImportOptions, import};
use kage_engine::scene::{Material, Mesh, Scene, flatten, shapes};
use kage_tests::{CORNELL_POSES, LightMove, asset, move_lights};

fn quad(h: f32) -> Vec<Vec3> {
    // CCW seen from below: emits towards −Y.
    vec![Vec3::new(-h, 0.0, -h), Vec3::new(h, 0.0, -h), Vec3::new(h, 0.0, h), Vec3::new(-h, 0.0, h)]
}

/// Shades vertex `v` of instance `i` with all three visibility modes.
fn three_ways(scene: &Scene, r: &Renderer, s: &Settings, i: usize, v: usize, eye: Vec3) -> [Vec3; 3] {
    let table = ltc::table();
    let occ = occluder_bvh(&r.flat);
    let (p, n) = r.vertex(i, v);
    let shader = PointShader::new(&table, p, n, eye, &r.flat.instances[i].material);
    let rec = bake_vertex(&occ, p, n, &SubtreeMemo::new(s), &Reach::of_scene(&r.flat)).record;
    let cube = visibility::cast_with_hits(&occ, p, n, s.res);
    let _ = scene;
    [
        shader.shade(&r.flat.lights, Visibility::Tree(&rec, s.res)),
        shader.shade(&r.flat.lights, Visibility::Exact(&cube)),
        shader.shade(&r.flat.lights, Visibility::Unshadowed),
    ]
}

#[test]
fn unoccluded_vertices_equal_ltc_unshadowed() {
    let mut scene = Scene::new("test:open");
    scene.add_object("ground", shapes::grid(6.0, 6), Material::lambertian(Vec3::splat(0.7)), Affine3A::IDENTITY);
    // A large light whose polygon crosses cube-face edges and corners as seen from the ground.
    let pose = Affine3A::from_rotation_translation(glam::Quat::from_rotation_z(0.6), Vec3::new(0.5, 1.0, 0.3));
    scene.add_light("light", quad(1.5), Vec3::splat(5.0), pose);
    let r = Renderer::new(&scene);
    let s = Settings { res: 16, epsilon: 0.5 };
    for v in 0..r.mesh(0).positions.len() {
        let [tree, exact, open] = three_ways(&scene, &r, &s, 0, v, Vec3::new(0.0, 4.0, 6.0));
        assert!((tree - open).length() <= 1e-6 * open.length().max(1e-9), "vertex {v}: {tree} vs {open}");
        assert!((exact - open).length() <= 1e-6 * open.length().max(1e-9), "vertex {v}: {exact} vs {open}");
    }
}

#[test]
fn cube_on_plane_umbra_is_black_and_matches_the_reference() {
    let scene = import(&asset("scenes/cube_on_plane.gltf"), ImportOptions::default()).unwrap();
    let r = Renderer::new(&scene);
    // The default configuration: 64² faces, default ε.
    let s = Settings::default();
    let eye = scene.first_camera().unwrap().eye();
    let bake = bspvt::bake(&r.flat, &s, &|_| {});
    let values = bspvt::shade_vertices(&r.flat, bspvt::Shadows::Trees(&bake), eye);
    let exact = bspvt::shade_vertices(&r.flat, bspvt::Shadows::Exact { res: s.res }, eye);
    let ground = r.flat.instances.iter().position(|i| i.material.base_color == Vec3::splat(0.8)).unwrap();
    let mut umbra = 0;
    for (v, value) in values[ground].iter().enumerate() {
        let (p, _) = r.vertex(ground, v);
        if p.x.abs() < 0.3 && p.z.abs() < 0.3 {
            umbra += 1;
            assert_eq!(*value, Vec3::ZERO, "umbra vertex {v}");
        }
    }
    assert_eq!(umbra, 9);
    let (flat_b, flat_e): (Vec<Vec3>, Vec<Vec3>) = (values.concat(), exact.concat());
    let tree_error = rel_rmse(&flat_b, &flat_e);
    eprintln!(
        "cube_on_plane, 64² faces, ε 2: tree error {tree_error:.4}, {:.1} leaves/vertex",
        bake.stats.leaves as f64 / bake.stats.vertices as f64
    );
    assert!(tree_error < 0.01, "tree error {tree_error}");
    let reference = r.render_vertices(eye, &RefSettings { spp: 512, seed: 5, max_bounces: 0, min_bounces: 0 }, &|_| {});
    let reference: Vec<Vec3> = reference.concat().iter().map(|e| e.mean).collect();
    let error = rel_rmse(&flat_b, &reference);
    eprintln!("bspvt vs reference (512 spp): {error:.4}");
    assert!(error < 0.03, "{error}");
}

/// Tree error against exact visibility and error against the reference (polygonal light only)
/// over every `step`-th vertex.
fn sampled_errors(scene: &Scene, res: usize, step: usize, spp: u32) -> (f64, f64, usize) {
    let r = Renderer::new(scene);
    let s = Settings { res, epsilon: Settings::default().epsilon };
    let eye = scene.first_camera().unwrap().eye();
    let (mut tree, mut exact, mut reference) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..r.flat.instances.len() {
        for v in (0..r.mesh(i).positions.len()).step_by(step) {
            let [t, e, _] = three_ways(scene, &r, &s, i, v, eye);
            let (p, n) = r.vertex(i, v);
            let frame = kage_engine::math::frame::Frame::from_normal(n);
            let sp = SurfacePoint { p, ng: n, frame, material: r.flat.instances[i].material };
            let settings = RefSettings { spp, seed: 9, max_bounces: 0, min_bounces: 0 };
            reference.push(r.estimate_point(&sp, (eye - p).normalize(), &settings, (i * 100_000 + v) as u64).mean);
            tree.push(t);
            exact.push(e);
        }
    }
    (rel_rmse(&tree, &exact), rel_rmse(&tree, &reference), tree.len())
}

#[test]
fn teapot_glossy_matches_the_reference_within_ltc_error() {
    let scene = import(&asset("scenes/teapot_quad_light.gltf"), ImportOptions::default()).unwrap();
    let (tree_error, error, n) = sampled_errors(&scene, 24, 17, 256);
    eprintln!("teapot ({n} vertices, 24² faces): tree error {tree_error:.4}, vs reference {error:.4}");
    assert!(tree_error < 0.01, "{tree_error}");
    assert!(error < 0.12, "LTC on GGX roughness 0.4 plus reference noise: {error}");
}

#[test]
fn default_scene_matches_the_reference() {
    let mut scene = kage_engine::scene::default_scene();
    scene.clear_environment();
    let (tree_error, error, n) = sampled_errors(&scene, 32, 23, 256);
    eprintln!("default scene ({n} vertices, 32² faces): tree error {tree_error:.4}, vs reference {error:.4}");
    assert!(tree_error < 0.02, "{tree_error}");
    assert!(error < 0.08, "{error}");
}

#[test]
fn lights_behind_the_receiver_give_nothing() {
    for (pose, what) in [
        (Affine3A::from_translation(Vec3::new(0.0, -2.0, 0.0)), "below the ground, facing down"),
        (
            Affine3A::from_rotation_translation(
                glam::Quat::from_rotation_x(std::f32::consts::PI),
                Vec3::new(0.0, -2.0, 0.0),
            ),
            "below, facing up",
        ),
        (
            Affine3A::from_rotation_translation(
                glam::Quat::from_rotation_x(std::f32::consts::PI),
                Vec3::new(0.0, 2.0, 0.0),
            ),
            "above, facing away",
        ),
    ] {
        let mut scene = Scene::new("test:behind");
        scene.add_object("ground", shapes::grid(4.0, 4), Material::lambertian(Vec3::splat(0.7)), Affine3A::IDENTITY);
        scene.add_light("light", quad(0.5), Vec3::splat(5.0), pose);
        let r = Renderer::new(&scene);
        let s = Settings { res: 8, epsilon: 0.5 };
        for v in 0..r.mesh(0).positions.len() {
            for value in three_ways(&scene, &r, &s, 0, v, Vec3::new(0.0, 3.0, 3.0)) {
                assert_eq!(value, Vec3::ZERO, "{what}: vertex {v}");
            }
        }
    }
}

#[test]
fn hard_cases_stay_finite() {
    let mut scene = Scene::new("test:hard");
    scene.add_object(
        "ground",
        shapes::grid(4.0, 4),
        Material { base_color: Vec3::ONE, metallic: 1.0, roughness: 1e-3, specular: 1.0 },
        Affine3A::IDENTITY,
    );
    scene.add_object(
        "block",
        shapes::cuboid(Vec3::splat(0.3)),
        Material { base_color: Vec3::ONE, metallic: 0.0, roughness: 1.0, specular: 1.0 },
        Affine3A::from_translation(Vec3::new(0.5, 0.3, 0.0)),
    );
    // A light touching the ground at a vertex, a sub-texel light, and a light larger than the hemisphere.
    scene.add_light(
        "touching",
        vec![Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, 1.0, 1.0), Vec3::new(0.0, 0.0, 1.0)],
        Vec3::splat(3.0),
        Affine3A::from_translation(Vec3::new(-1.0, 0.0, -0.5)),
    );
    scene.add_light("tiny", quad(1e-3), Vec3::splat(1e4), Affine3A::from_translation(Vec3::new(0.0, 3.0, 0.0)));
    scene.add_light("huge", quad(1e4), Vec3::splat(0.1), Affine3A::from_translation(Vec3::new(0.0, 50.0, 0.0)));
    let r = Renderer::new(&scene);
    let s = Settings { res: 16, epsilon: 0.0 };
    for i in 0..r.flat.instances.len() {
        for v in 0..r.mesh(i).positions.len() {
            // A grazing view from just above the ground.
            for eye in [Vec3::new(0.0, 2.0, 3.0), Vec3::new(50.0, 1e-3, 0.0)] {
                for value in three_ways(&scene, &r, &s, i, v, eye) {
                    assert!(value.is_finite() && value.min_element() >= 0.0, "instance {i} vertex {v}: {value}");
                }
            }
        }
    }
    let _ = flatten(&scene);
}

#[test]
fn the_error_budget_picks_the_cheapest_resolution_and_epsilon_within_it() {
    let scene = import(&asset("scenes/cube_on_plane.gltf"), ImportOptions::default()).unwrap();
    let flat = flatten(&scene);
    let eye = scene.first_camera().unwrap().eye();
    let (loose, why_loose) = bspvt::budget::choose(&flat, 0.2, eye);
    let (tight, why_tight) = bspvt::budget::choose(&flat, 0.01, eye);
    eprintln!("{why_loose}\n{why_tight}");
    assert!(loose.res < tight.res, "{why_loose} / {why_tight}");
    assert!(why_tight.contains("pilot on") && why_tight.contains("64²") && why_tight.contains("ε"));
    // Nothing to reach: no trees at all.
    let mut dark = Scene::new("test:dark");
    dark.add_object("ground", shapes::grid(2.0, 2), Material::lambertian(Vec3::ONE), Affine3A::IDENTITY);
    let flat = flatten(&dark);
    assert!(bspvt::budget::choose(&flat, 0.01, Vec3::Y).1.contains("nothing to bake"));
    let bake = bspvt::bake(&flat, &Settings::default(), &|_| {});
    assert_eq!((bake.stats.leaves, bake.stats.bytes), (0, 9 * 12), "six empty face lengths per vertex");
}

#[test]
fn textured_lights_use_their_prefiltered_texture() {
    use kage_engine::scene::texture::Wrap;
    use kage_engine::scene::{PolygonLight, Texture};
    use std::sync::Arc;
    let make = |texels: Vec<Vec3>| {
        let mut scene = Scene::new("test:textured");
        scene.add_object("ground", shapes::grid(4.0, 4), Material::lambertian(Vec3::splat(0.7)), Affine3A::IDENTITY);
        scene.textures.push(Arc::new(Texture::new(2, 2, texels, [Wrap::Clamp, Wrap::Clamp])));
        let group =
            scene.add_light("light", quad(0.5), Vec3::splat(4.0), Affine3A::from_translation(Vec3::new(0.0, 1.5, 0.0)));
        for light in scene
            .world
            .query_mut::<(&mut PolygonLight, &kage_engine::scene::InGroup)>()
            .into_iter()
            .filter(|(_, g)| g.group == group)
        {
            light.0.texture = Some(0);
            light.0.uvs = vec![glam::Vec2::ZERO, glam::Vec2::X, glam::Vec2::ONE, glam::Vec2::Y];
        }
        scene
    };
    let shade = |scene: &Scene| {
        let r = Renderer::new(scene);
        (0..r.mesh(0).positions.len())
            .map(|v| three_ways(scene, &r, &Settings { res: 16, epsilon: 2.0 }, 0, v, Vec3::new(0.0, 3.0, 3.0)))
            .collect::<Vec<_>>()
    };
    let white = shade(&make(vec![Vec3::ONE; 4]));
    let mut plain = make(vec![Vec3::ONE; 4]);
    for light in plain.world.query_mut::<&mut PolygonLight>() {
        light.texture = None;
    }
    let untextured = shade(&plain);
    for (w, u) in white.iter().zip(&untextured) {
        for k in 0..3 {
            assert!((w[k] - u[k]).length() <= 1e-5 * u[k].length().max(1e-9), "a white texture changes nothing");
        }
    }
    // A red/blue texture tints the result, and the tint depends on where the vertex is.
    let tinted = shade(&make(vec![Vec3::X, Vec3::Z, Vec3::X, Vec3::Z]));
    let ratios: Vec<f32> = tinted.iter().map(|t| t[2].x / t[2].z.max(1e-9)).filter(|r| r.is_finite()).collect();
    assert!(
        ratios.iter().all(|r| *r > 0.0)
            && ratios.iter().copied().fold(f32::MIN, f32::max) > 1.2 * ratios.iter().copied().fold(f32::MAX, f32::min)
    );
}

/// A light that declares its reach (`extras.kage.light_reach`): tiles it cannot be seen through
/// bake as occluded without rays, vertices it cannot reach store no tree, and shading the light
/// anywhere inside its reach gives what a bake for a roaming light gives.
/// No light arrives from below a receiver's horizon, where the trees do not care (texels there
/// are never cast), yet the specular LTC, clipped at its own transformed horizon, gathers some:
/// shading clips the light at the true horizon first. On `textured_light.gltf` the
/// stained-glass light stands half below the horizon of the teapot's lid, seen at grazing
/// angles; without the clip the trees' guesses below it showed (tree error 6.4 % over the
/// scene, the knob's top 50 % too bright while nothing occludes it).
#[test]
fn light_below_the_horizon_adds_nothing_whatever_the_trees_hold_there() {
    let scene = import(&asset("scenes/textured_light.gltf"), ImportOptions::default()).unwrap();
    let r = Renderer::new(&scene);
    let s = Settings::default();
    let eye = scene.first_camera().unwrap().eye();
    let (mut tree, mut exact) = (Vec::new(), Vec::new());
    let lid: Vec<(usize, usize)> = (0..r.flat.instances.len())
        .flat_map(|i| (0..r.mesh(i).positions.len()).map(move |v| (i, v)))
        .filter(|&(i, v)| r.vertex(i, v).0.y >= 1.2)
        .collect();
    let knob = *lid.iter().max_by(|a, b| r.vertex(a.0, a.1).0.y.total_cmp(&r.vertex(b.0, b.1).0.y)).unwrap();
    for &(i, v) in lid.iter().step_by(4).chain([&knob]) {
        let [t, e, _] = three_ways(&scene, &r, &s, i, v, eye);
        tree.push(t);
        exact.push(e);
    }
    // Nothing stands above the knob's top: its trees hold every texel visible.
    let (p, n) = r.vertex(knob.0, knob.1);
    let [t, e, open] = three_ways(&scene, &r, &s, knob.0, knob.1, eye);
    assert!(r.flat.lights[0].points.iter().any(|q| (*q - p).dot(n) < 0.0), "the light crosses the knob's horizon");
    assert_eq!(t, open, "knob at {p}");
    assert!((t - e).length() < 0.02 * e.length(), "knob at {p}: tree {t}, exact {e}");
    let error = rel_rmse(&tree, &exact);
    eprintln!("textured_light.gltf, lid ({} vertices): tree error {error:.4}", tree.len());
    assert!(error < 0.03, "tree error {error}");
}

#[test]
fn a_declared_light_reach_bakes_less_and_shades_the_same() {
    let dir = kage_tests::scratch!("light-reach");
    let reach = serde_json::json!({"kage": {"light_reach": {"min": [-1.5, 3.0, -1.5], "max": [1.5, 5.0, 1.5]}}});
    let bounded = import(
        &kage_tests::with_node_extras("scenes/cube_on_plane.gltf", &dir, "light", reach),
        ImportOptions::default(),
    )
    .unwrap();
    let roaming = import(&asset("scenes/cube_on_plane.gltf"), ImportOptions::default()).unwrap();
    let s = Settings { res: 32, epsilon: 2.0 };
    let (rb, rf) = (Renderer::new(&bounded), Renderer::new(&roaming));
    let (with, without) = (bspvt::bake(&rb.flat, &s, &|_| {}), bspvt::bake(&rf.flat, &s, &|_| {}));
    eprintln!(
        "light reach: {} bytes, {} leaves; roaming: {} bytes, {} leaves",
        with.stats.bytes, with.stats.leaves, without.stats.bytes, without.stats.leaves
    );
    assert!(with.stats.bytes < without.stats.bytes && with.stats.leaves < without.stats.leaves);
    // The cube's bottom and the ground's far side see none of the box.
    let empty = bspvt::layout::encode_vertex(&Default::default());
    let dark = with.instances.iter().flat_map(|b| (0..b.vertices()).filter(|&v| b.record(v) == empty)).count();
    let dark_before =
        without.instances.iter().flat_map(|b| (0..b.vertices()).filter(|&v| b.record(v) == empty)).count();
    assert!(dark > dark_before, "{dark} vertices without trees, {dark_before} before");
    let eye = bounded.first_camera().unwrap().eye();
    for offset in [Vec3::ZERO, Vec3::new(1.0, -0.9, 0.7), Vec3::new(-0.9, 0.9, -1.0)] {
        let mut moved = rb.flat.clone();
        moved.lights.iter_mut().flat_map(|l| l.points.iter_mut()).for_each(|p| *p += offset);
        let a = bspvt::shade_vertices(&moved, bspvt::Shadows::Trees(&with), eye).concat();
        let b = bspvt::shade_vertices(&moved, bspvt::Shadows::Trees(&without), eye).concat();
        let worst = a
            .iter()
            .zip(&b)
            .map(|(x, y)| (*x - *y).abs().max_element() / y.max_element().max(1e-3))
            .fold(0.0, f32::max);
        assert!(worst < 1e-5, "light moved by {offset}: relative difference {worst}");
    }
}

/// The Cornell box's direct light per vertex, baked once (64², ε 2), with its light where the
/// scene puts it (1 mm under the ceiling) and then moved by each of `moves` (world points in
/// place), against the reference's (2048 paths per vertex): the relative RMSE, and the
/// radiance of the ceiling's vertices.
fn cornell(name: &str, moves: &[LightMove]) -> Vec<(f64, Vec<Vec3>)> {
    // Walls of a few hundred vertices: per-vertex errors are then not those of the corners alone.
    let load = || {
        let mut scene = import(&asset(name), ImportOptions::default()).unwrap();
        for wall in ["floor", "ceiling", "back_wall", "left_wall", "right_wall"] {
            scene.refine_instances(wall, 200).unwrap();
        }
        scene
    };
    let r = Renderer::new(&load());
    let bake = bspvt::bake(&r.flat, &Settings::default(), &|_| {});
    assert!(bspvt::unseen_lights(&r.flat, &bake).is_empty());
    let eye = load().first_camera().unwrap().eye();
    let on_ceiling = |i: usize| (0..r.flat.vertex_count(i)).all(|v| (r.vertex(i, v).0.y - 0.5488).abs() < 1e-4);
    let ceiling = (0..r.flat.instances.len()).find(|&i| on_ceiling(i)).unwrap();
    let identity: LightMove = |_| {};
    std::iter::once(&identity)
        .chain(moves)
        .map(|mv| {
            let mut scene = load();
            move_lights(&mut scene, *mv);
            let moved = Renderer::new(&scene);
            let lit = bspvt::shade_vertices(&moved.flat, bspvt::Shadows::Trees(&bake), eye);
            let settings = RefSettings { spp: 2048, seed: 3, max_bounces: 0, min_bounces: 0 };
            let reference = moved.render_vertices(eye, &settings, &|_| {});
            let reference: Vec<Vec3> = reference.concat().iter().map(|e| e.mean).collect();
            (rel_rmse(&lit.concat(), &reference), lit[ceiling].clone())
        })
        .collect()
}

/// A light inside a closed room (the Cornell box, its light 1 mm under the ceiling): the trees
/// and their depth planes see the light in front of the ceiling, and the room's direct light
/// matches the reference's per vertex; the ceiling around the light (the wall it is mounted
/// on) gets none. With no re-bake, the light moved 15 cm toward the red wall and turned 20°
/// about its normal, lowered 15 cm and tilted 20°, and moved down behind the tall block, still
/// matches. Declared `"fixed"`, rays stop at the light and the depth has nothing to add.
#[test]
fn a_light_in_a_closed_room_lights_it_as_the_reference_does() {
    let undeclared = CORNELL_POSES.to_vec();
    for (name, moves) in [("scenes/cornell_box.gltf", undeclared), ("scenes/cornell_box_fixed.gltf", vec![])] {
        for (k, (error, ceiling)) in cornell(name, &moves).into_iter().enumerate() {
            eprintln!("{name}, light pose {k}: bspvt {error:.4} from the reference per vertex");
            // Down behind the block (pose 3), 5 cm from it, the penumbrae span texels: 5.5 %.
            let goal = if k == 3 { 0.08 } else { 0.05 };
            assert!(error < goal, "{name}, pose {k}: {error}");
            if k == 0 {
                assert!(ceiling.iter().all(|v| *v == Vec3::ZERO), "{ceiling:?}");
            }
        }
    }
}

/// A lamp in a box with a hole in its side: the depth puts the box's walls in front of it,
/// and the floor in front of the hole is lit as in the reference.
#[test]
fn a_lamp_in_a_box_lights_the_floor_through_its_hole() {
    let mut scene = Scene::new("test:lamp");
    scene.add_object("floor", shapes::grid(6.0, 12), Material::lambertian(Vec3::splat(0.7)), Affine3A::IDENTITY);
    // A cube floating 0.2 over the floor without its +X side; normals outward, so its own
    // vertices face away from the lamp inside.
    let centre = Vec3::new(0.0, 0.7, 0.0);
    let faces: Vec<(Vec3, [Vec3; 4])> = (0..6)
        .filter(|&k| k != 0)
        .map(|k| {
            let n = Vec3::AXES[k / 2] * if k % 2 == 0 { 1.0 } else { -1.0 };
            let (u, v) = (Vec3::AXES[(k / 2 + 1) % 3] * 0.5, Vec3::AXES[(k / 2 + 2) % 3] * 0.5);
            let c = centre + n * 0.5;
            (n, [c - u - v, c + u - v, c + u + v, c - u + v])
        })
        .collect();
    let normals: Vec<Vec3> = faces.iter().flat_map(|(n, _)| [*n; 4]).collect();
    let positions: Vec<Vec3> = faces.iter().flat_map(|(_, q)| *q).collect();
    let triangles =
        (0..faces.len() as u32).flat_map(|k| [[4 * k, 4 * k + 1, 4 * k + 2], [4 * k, 4 * k + 2, 4 * k + 3]]);
    let (box_mesh, _) = Mesh::new(positions, Some(normals), vec![], triangles.collect(), false).unwrap();
    scene.add_object("box", box_mesh, Material::lambertian(Vec3::splat(0.5)), Affine3A::IDENTITY);
    let lamp = Affine3A::from_rotation_translation(glam::Quat::from_rotation_z(-1.2), centre);
    scene.add_light("lamp", quad(0.05), Vec3::splat(200.0), lamp);
    let r = Renderer::new(&scene);
    let bake = bspvt::bake(&r.flat, &Settings::default(), &|_| {});
    let unseen = bspvt::unseen_lights(&r.flat, &bake);
    let eye = Vec3::new(3.0, 3.0, 3.0);
    let lit = bspvt::shade_vertices(&r.flat, bspvt::Shadows::Trees(&bake), eye);
    assert!(unseen.is_empty());
    let settings = RefSettings { spp: 1024, seed: 9, max_bounces: 0, min_bounces: 0 };
    let reference: Vec<Vec3> = r.render_vertices(eye, &settings, &|_| {})[0].iter().map(|e| e.mean).collect();
    let error = rel_rmse(&lit[0], &reference);
    eprintln!("a lamp in a box with a hole: the floor {error:.4} from the reference per vertex");
    assert!(error < 0.1 && lit[0].iter().any(|v| v.x > 0.0), "{error}");
}
