//! Opens a kage pack in a window: `cargo run --release -p bevy_kage --example pack -- PACK.glb`.
//!
//! Right-drag orbits the camera about the point it looks at, the wheel zooms; left-drag moves
//! the pack's first light in its plane, with its shadows. The frame time is printed every two
//! seconds.

use bevy::input::mouse::{AccumulatedMouseMotion, AccumulatedMouseScroll};
use bevy::prelude::*;
use bevy_kage::spawn::KageCamera;
use bevy_kage::{KageLight, KagePack, KagePlugin, KageScene};
use std::path::PathBuf;

fn main() -> AppExit {
    let Some(path) = std::env::args().nth(1).map(PathBuf::from) else {
        eprintln!("usage: pack PACK.glb");
        return AppExit::error();
    };
    let Ok(path) = path.canonicalize() else {
        eprintln!("{}: no such file", path.display());
        return AppExit::error();
    };
    let folder = path.parent().expect("a file has a folder").to_string_lossy().into_owned();
    let file = path.file_name().expect("a file has a name").to_string_lossy().into_owned();
    App::new()
        .add_plugins(DefaultPlugins.set(AssetPlugin { file_path: folder, ..default() }))
        .add_plugins(KagePlugin::default())
        .insert_resource(GlobalAmbientLight::NONE)
        .insert_resource(ClearColor(Color::BLACK))
        .insert_resource(Pack(file))
        .add_systems(Startup, open)
        .add_systems(Update, (orbit, drag_light, frame_time))
        .run()
}

/// The pack's file name in its folder.
#[derive(Resource)]
struct Pack(String);

fn open(mut commands: Commands, server: Res<AssetServer>, pack: Res<Pack>) {
    let handle = server.load::<KagePack>(pack.0.clone());
    commands.spawn((KageScene::new(handle), Transform::default(), Visibility::default()));
}

/// Right-drag orbits about the point 5 m ahead (or the scene's centre line), the wheel zooms.
fn orbit(
    buttons: Res<ButtonInput<MouseButton>>,
    motion: Res<AccumulatedMouseMotion>,
    scroll: Res<AccumulatedMouseScroll>,
    mut cameras: Query<&mut Transform, (With<KageCamera>, Without<KageLight>)>,
) {
    for mut t in &mut cameras {
        let distance = t.translation.length().max(0.5);
        let target = t.translation + t.forward() * distance;
        if buttons.pressed(MouseButton::Right) && motion.delta != Vec2::ZERO {
            let yaw = Quat::from_rotation_y(-motion.delta.x * 0.005);
            let pitch = Quat::from_axis_angle(*t.right(), -motion.delta.y * 0.005);
            let offset = yaw * pitch * (t.translation - target);
            t.translation = target + offset;
            t.look_at(target, Vec3::Y);
        }
        if scroll.delta.y != 0.0 {
            let offset = (t.translation - target) * (1.0 - 0.1 * scroll.delta.y.clamp(-3.0, 3.0));
            t.translation = target + offset;
        }
    }
}

/// Left-drag moves the first light along the camera's right and forward directions, kept
/// level.
fn drag_light(
    buttons: Res<ButtonInput<MouseButton>>,
    motion: Res<AccumulatedMouseMotion>,
    cameras: Query<&GlobalTransform, With<KageCamera>>,
    mut lights: Query<(&KageLight, &mut Transform)>,
) {
    if !buttons.pressed(MouseButton::Left) || motion.delta == Vec2::ZERO {
        return;
    }
    let Some(camera) = cameras.iter().next() else { return };
    let level = |v: Vec3| Vec3::new(v.x, 0.0, v.z).normalize_or_zero();
    let (right, ahead) = (level(*camera.right()), level(*camera.forward()));
    if let Some((_, mut t)) = lights.iter_mut().min_by_key(|(l, _)| l.index) {
        t.translation += (right * motion.delta.x - ahead * motion.delta.y) * 0.005;
    }
}

/// Prints the mean frame time every two seconds.
fn frame_time(time: Res<Time>, mut frames: Local<(u32, f32)>) {
    frames.0 += 1;
    frames.1 += time.delta_secs();
    if frames.1 >= 2.0 {
        println!("frame: {:.1} ms ({:.0} fps)", 1000.0 * frames.1 / frames.0 as f32, frames.0 as f32 / frames.1);
        *frames = (0, 0.0);
    }
}
