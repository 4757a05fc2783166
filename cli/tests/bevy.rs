//! The Bevy plugin (`bevy_kage`) against `kage render --pack --gpu --indirect pack` (the
//! bounces the pack carries, as Bevy adds them) with its lights per pixel, and against kage's
//! per-vertex image (`--method bspvt`) with its lights per vertex (as on a CPU device): the
//! same pack, view and light poses, rendered headless by Bevy on the machine's Vulkan device
//! (Mesa's lavapipe in CI) into an `Rgba32Float` image (HDR, no tonemapping, no MSAA,
//! exposure 1).

use bevy::prelude::*;
use bevy_kage::headless::{Headless, Rendering, windowless};
use bevy_kage::{KageEnvironment, KageGroup, KageInstance, KageLight, KagePack, KageScene, ShadeOn};
use std::path::{Path, PathBuf};
use std::time::Duration;

mod common;

use common::{asset, kage, scratch, stderr};

/// Image size of both renders.
const SIZE: (u32, u32) = (240, 180);

/// Three packs — `cube_on_plane.gltf` (a cube on a ground under a quad light),
/// `teapot_quad_light.gltf` (a gold teapot: GGX highlights per pixel) and
/// `textured_materials.gltf` (textured, vertex-coloured and glossy dielectrics, whose diffuse
/// albedo loses what their specular layer reflects) — in kage and in Bevy, with the light
/// where it was baked and moved 0.5 m: within 5 % of each other, and the move changes both
/// images alike.
#[test]
fn bevy_shades_a_pack_as_kage_renders_it() {
    for scene in ["cube_on_plane", "teapot_quad_light", "textured_materials"] {
        compare(scene, PIXEL, &[], &["--move-light", "light=0.5,0,0"], move_light);
    }
}

/// Where the plugin shades the lights per vertex (`ShadeOn::Auto` on a CPU device), the
/// packs against kage's per-vertex image of the same pack (`--method bspvt`): the cube within
/// 5 %; the textured scene within 30 %, as the two carry a texture between vertices
/// differently — kage scales the vertices' light by the pixel's albedo over the vertices'
/// interpolated albedo, the plugin multiplies the diffuse light by the pixel's albedo and
/// shades the specular lobe with the material's factors (a floor shaded with the factors'
/// white, its texture lost, was 121 % off).
#[test]
fn bevy_shades_a_pack_per_vertex_as_kage_does() {
    for (scene, tolerance) in [("cube_on_plane", 0.05), ("textured_materials", 0.3)] {
        compare(scene, (ShadeOn::Vertex, tolerance), &[], &["--move-light", "light=0.5,0,0"], move_light);
    }
}

/// Moves the pack's first light 0.5 m along +x.
fn move_light(world: &mut World) {
    let mut lights = world.query::<(&KageLight, &mut Transform)>();
    let (_, mut t) = lights.iter_mut(world).min_by_key(|(l, _)| l.index).expect("the pack has a light");
    t.translation += Vec3::new(0.5, 0.0, 0.0);
}

/// Packs under an environment (`city.hdr`: a sky without a sun) in kage and in Bevy:
/// `cube_on_plane.gltf` (the map at 0.6 of its radiance) with the cube where it was baked and moved 0.3 m (the environment's
/// light, its self-shadowing and the shadow the cube casts on the ground, another rigid
/// group), `teapot_quad_light.gltf` with the environment as baked and turned 90° (the
/// gold teapot's reflections of it), and `cube_on_plane.gltf` under `sky.hdr`, whose sun both
/// shade apart (kage with its shadow map on the GPU, Bevy as a `DirectionalLight`), turned
/// 90° (the sun's shadow swings round): within 5 % of each other, and the change alters both
/// images alike.
#[test]
fn bevy_shades_a_packs_environment_as_kage_renders_it() {
    let city = asset("envmaps/city.hdr");
    let move_cube = |world: &mut World| {
        let mut groups = world.query_filtered::<(&Name, &mut Transform), With<KageGroup>>();
        let (_, mut t) = groups.iter_mut(world).find(|(n, _)| n.as_str() == "cube").expect("the pack has a cube");
        t.translation += Vec3::new(0.3, 0.0, 0.0);
    };
    let dim = ["--env", &city, "--env-intensity", "0.6"];
    compare("cube_on_plane", PIXEL, &dim, &["--move", "cube=0.3,0,0"], move_cube);
    let turn = |world: &mut World| {
        let mut envs = world.query::<&mut KageEnvironment>();
        let mut env = envs.single_mut(world).expect("the pack has an environment");
        env.rotation = Quat::from_rotation_y(90f32.to_radians());
    };
    compare("teapot_quad_light", PIXEL, &["--env", &city], &["--env-rotation", "90"], turn);
    let sky = ["--env", &asset("envmaps/sky.hdr")];
    compare("cube_on_plane", PIXEL, &sky, &["--env-rotation", "90"], turn);
}

/// The Cornell box, a light inside a closed room whose walls light each other: the pack's
/// bounces in Bevy as kage adds them, as baked and with the light slid 15 cm along the ceiling
/// toward the green wall (the bounces stay where they were baked in both). How far the frozen
/// bounces then are from the bounces kage computes anew for the moved light is measured too.
#[test]
fn bevy_shows_a_rooms_bounces_as_the_pack_carries_them() {
    let slide = |world: &mut World| {
        let mut lights = world.query::<(&KageLight, &mut Transform)>();
        let (_, mut t) = lights.iter_mut(world).next().expect("the pack has a light");
        t.translation.x -= 0.15;
    };
    let change = ["--move-light", "light=-0.15,0,0"];
    let (pack, bevy_moved) = compare("cornell_box", PIXEL, &[], &change, slide);
    let live = kage_image(&pack, &[&change[..], &["--gpu", "--indirect", "cache"]].concat());
    let frozen = error(&bevy_moved, &live);
    println!("cornell_box: the frozen bounces after the move, against kage's bounces for it: {:.2} %", 100.0 * frozen);
    assert!(frozen < 0.15, "{frozen}");
}

/// Bevy's own lights light a pack beside kage's: a point light added over the cube brightens
/// the image (the materials take Bevy's lighting back in), and despawned leaves the image as it
/// was (they drop it again, with nothing of it left).
#[test]
fn bevy_lights_a_pack_with_its_own_lights_too() {
    let pack = export("cube_on_plane", &["--refine-receivers", "0"], "bevy-lights");
    let mut bevy =
        Headless::open(&pack, SIZE, ShadeOn::Auto, Rendering::InStep).expect("the pack loads, with its camera");
    let settled = |bevy: &mut Headless| bevy.settled(Duration::from_secs(300)).expect("Bevy draws the pack");
    let plain = settled(&mut bevy);
    let lamp = PointLight { intensity: 200.0, range: 20.0, shadow_maps_enabled: false, ..default() };
    let lamp = bevy.app.world_mut().spawn((lamp, Transform::from_xyz(0.0, 2.5, 0.0))).id();
    let lit = settled(&mut bevy);
    bevy.app.world_mut().despawn(lamp);
    let back = settled(&mut bevy);
    let mean = |image: &[Vec4]| image.iter().map(|p| p.truncate().element_sum()).sum::<f32>() / image.len() as f32;
    println!(
        "mean pixel: {} plain, {} with Bevy's point light, {} without it again",
        mean(&plain),
        mean(&lit),
        mean(&back)
    );
    assert!(mean(&lit) > 1.2 * mean(&plain), "{} {}", mean(&lit), mean(&plain));
    let rgb = |image: &[Vec4]| image.iter().map(|p| p.truncate()).collect::<Vec<_>>();
    assert!(error(&rgb(&back), &rgb(&plain)) < 1e-4);
}

/// Lights per pixel, within the goal's 5 %.
const PIXEL: (ShadeOn, f32) = (ShadeOn::Pixel, 0.05);

/// Exports `scene` (with `export_args`), renders it in kage and in Bevy (its lights shaded as
/// `shade_on` says, kage's image shaded alike) as baked and after a change (kage's `change`
/// arguments, Bevy's `change_world`), and checks both within `tolerance` of each other and the
/// change seen alike; the pack, and Bevy's image after the change.
fn compare(
    scene: &str,
    (shade_on, tolerance): (ShadeOn, f32),
    export_args: &[&str],
    change: &[&str],
    change_world: impl FnOnce(&mut World),
) -> (PathBuf, Vec<Vec3>) {
    let pack = export(scene, export_args, &format!("{shade_on:?}").to_lowercase());
    let d = pack.parent().expect("in its scratch folder");
    let alike: &[&str] = match shade_on {
        ShadeOn::Vertex => &["--method", "bspvt"],
        _ => &["--gpu"],
    };
    let kage_at = |moves: &[&str]| kage_image(&pack, &[moves, alike, &["--indirect", "pack"]].concat());
    let (kage_still, kage_moved) = (kage_at(&[]), kage_at(change));
    let (bevy_still, bevy_moved) = render_in_bevy(&pack, shade_on, change_world);
    // Beside kage's images, for a look when this fails.
    for (name, pixels) in [("bevy0.exr", &bevy_still), ("bevy2.exr", &bevy_moved)] {
        let rgb = pixels.iter().flat_map(|p| p.to_array()).collect();
        image::Rgb32FImage::from_raw(SIZE.0, SIZE.1, rgb).unwrap().save(d.join(name)).unwrap();
    }
    let (still, after) = (error(&bevy_still, &kage_still), error(&bevy_moved, &kage_moved));
    println!(
        "{scene} {export_args:?}, {shade_on:?}: relative RMSE over surface pixels {:.2} % as baked, {:.2} % after {change:?}",
        100.0 * still,
        100.0 * after
    );
    assert!(still <= tolerance && after <= tolerance, "{scene}: {still} {after}");
    // The change is seen: what it changes in kage's image, it changes in Bevy's.
    let (kage_change, bevy_change) = (error(&kage_moved, &kage_still), error(&bevy_moved, &bevy_still));
    println!(
        "{scene}: the change alters {:.1} % of kage's image, {:.1} % of Bevy's",
        100.0 * kage_change,
        100.0 * bevy_change
    );
    assert!(
        kage_change > 0.05 && (bevy_change / kage_change - 1.0).abs() < 0.2,
        "{scene}: {kage_change} {bevy_change}"
    );
    (pack, bevy_moved)
}

/// `scene` exported with `export_args` into a scratch folder of its own for `user` (named by
/// all three, so that tests running side by side never share one): the pack's path.
fn export(scene: &str, export_args: &[&str], user: &str) -> PathBuf {
    use std::hash::{Hash, Hasher};
    let mut h = std::hash::DefaultHasher::new();
    export_args.hash(&mut h);
    let d = scratch(&format!("bevy-{user}-{scene}-{:016x}", h.finish()));
    let pack = d.join(format!("{scene}.glb"));
    let db = d.join("bake.redb");
    let args = ["export", &asset(&format!("scenes/{scene}.gltf")), "-o", p(&pack), "--db", p(&db)];
    let o = kage(&[&args[..], export_args].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    pack
}

/// `kage render --pack PACK` with `args` at [`SIZE`], beside the pack.
fn kage_image(pack: &Path, args: &[&str]) -> Vec<Vec3> {
    let name: String = args.join(" ").chars().filter(|c| c.is_alphanumeric() || "=,.- ".contains(*c)).collect();
    let exr = pack.with_file_name(format!("kage {}.exr", name.replace("--", "").trim()));
    let size = format!("{}x{}", SIZE.0, SIZE.1);
    let render = ["render", "--pack", p(pack), "--size", &size, "-o", p(&exr)];
    let o = kage(&[&render[..], args].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    image::open(&exr).unwrap().to_rgba32f().pixels().map(|p| Vec3::new(p[0], p[1], p[2])).collect()
}

/// A pack damaged after it was written fails to load with an error naming the damage; the
/// app goes on and shows the file as the plain glTF it also is.
#[test]
fn bevy_refuses_a_damaged_pack_and_shows_it_as_a_plain_gltf() {
    let d = scratch("bevy-damaged");
    let pack = d.join("cube.glb");
    let o = kage(&["export", &asset("scenes/cube_on_plane.gltf"), "-o", p(&pack), "--db", p(&d.join("bake.redb"))]);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut bytes = std::fs::read(&pack).unwrap();
    let at = bytes.len() - 100;
    bytes[at] ^= 0x40;
    std::fs::write(&pack, bytes).unwrap();
    let error =
        Headless::open(&pack, SIZE, ShadeOn::Auto, Rendering::InStep).err().expect("the damaged pack is refused");
    assert!(error.contains("cube.glb: not a kage pack") && error.contains("fails its checksum"), "{error}");
    // In an app, the scene then shows the file through Bevy's glTF loader: its meshes, unshaded
    // by kage.
    let mut app = windowless(&d, ShadeOn::Auto, Rendering::InStep);
    let handle = app.world().resource::<AssetServer>().load::<KagePack>("cube.glb");
    app.world_mut().spawn((KageScene::new(handle), Transform::default(), Visibility::default()));
    let meshes = (0..2000).find_map(|_| {
        app.update();
        std::thread::sleep(Duration::from_millis(5));
        let n = app.world_mut().query::<&Mesh3d>().iter(app.world()).count();
        (n > 0).then_some(n)
    });
    assert_eq!(meshes, Some(3), "the cube, its ground and the light's panel, as plain glTF meshes");
    assert_eq!(app.world_mut().query::<&KageInstance>().iter(app.world()).count(), 0);
}

fn p(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// Relative RMSE of `a` against `b` over surface pixels: lit in either, with every neighbour
/// lit too (silhouettes excluded), emitters (radiance above 5 in either: a light that moved)
/// excluded.
fn error(a: &[Vec3], b: &[Vec3]) -> f32 {
    let (w, h) = (SIZE.0 as usize, SIZE.1 as usize);
    let lit = |k: usize| a[k].max_element() > 0.0 || b[k].max_element() > 0.0;
    let inside = |x: usize, y: usize| {
        (y.saturating_sub(1)..=(y + 1).min(h - 1))
            .all(|j| (x.saturating_sub(1)..=(x + 1).min(w - 1)).all(|i| lit(j * w + i)))
    };
    let (mut num, mut den) = (0.0f64, 0.0f64);
    let emitter = |k: usize| a[k].max_element().max(b[k].max_element()) >= 5.0;
    for k in (0..w * h).filter(|&k| inside(k % w, k / w) && !emitter(k)) {
        num += (a[k] - b[k]).length_squared() as f64;
        den += b[k].length_squared() as f64;
    }
    (num / den).sqrt() as f32
}

/// Samples per pixel side: kage's `--gpu` image is drawn at 4× and averaged; so is Bevy's.
const FINE: u32 = 4;

/// Bevy's images of `pack` (its lights shaded as `shade_on` says) as baked and after `change`.
fn render_in_bevy(pack: &Path, shade_on: ShadeOn, change: impl FnOnce(&mut World)) -> (Vec<Vec3>, Vec<Vec3>) {
    let fine = (SIZE.0 * FINE, SIZE.1 * FINE);
    let mut bevy = Headless::open(pack, fine, shade_on, Rendering::InStep).expect("the pack loads, with its camera");
    let still = bevy.settled(Duration::from_secs(300)).expect("Bevy draws the pack");
    change(bevy.app.world_mut());
    let moved = bevy.settled(Duration::from_secs(300)).expect("Bevy draws the pack");
    (downsample(&still), downsample(&moved))
}

/// The mean of every `FINE`² block of a `FINE`× image.
fn downsample(fine: &[Vec4]) -> Vec<Vec3> {
    let (w, k) = (SIZE.0 as usize, FINE as usize);
    let block = |x: usize, y: usize| {
        let rows = (0..k).flat_map(|j| fine[(k * y + j) * k * w + k * x..][..k].iter());
        rows.map(|p| p.truncate()).sum::<Vec3>() / (k * k) as f32
    };
    (0..w * SIZE.1 as usize).map(|p| block(p % w, p / w)).collect()
}
