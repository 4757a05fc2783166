//! The frame cost of a pack in Bevy without a window: `cargo run --release -p bevy_kage
//! --example frame_cost -- PACK.glb [WIDTHxHEIGHT] [--bevy-light] [--still]` (default
//! 800x600). The pack's first light circles 0.2 m about where it was baked, so every frame
//! shades again; after the pipelines are ready, 60 frames are timed: the whole frame, and the
//! plugin's per-vertex shading on the CPU. `--bevy-light` adds a dim Bevy point light, so that
//! the materials run Bevy's own lighting too; `--still` leaves the light where it is, so the
//! frames show Bevy's own cost, with no per-vertex work. `KAGE_SHADE_ON=pixel|vertex`
//! overrides where the lights are shaded (`ShadeOn::Auto`).

use bevy::prelude::*;
use bevy_kage::headless::{Headless, Rendering};
use bevy_kage::{KageLight, KageStats, ShadeOn};
use std::path::PathBuf;
use std::time::{Duration, Instant};

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let flag = |args: &mut Vec<String>, name: &str| {
        let set = args.iter().any(|a| a == name);
        args.retain(|a| a != name);
        set
    };
    let (bevy_light, still) = (flag(&mut args, "--bevy-light"), flag(&mut args, "--still"));
    let mut args = args.into_iter();
    let Some(path) = args.next().map(PathBuf::from) else {
        eprintln!("usage: frame_cost PACK.glb [WIDTHxHEIGHT] [--bevy-light] [--still]");
        std::process::exit(2);
    };
    let size = args.next().and_then(|s| s.split_once('x').and_then(|(w, h)| Some((w.parse().ok()?, h.parse().ok()?))));
    let size = size.unwrap_or((800, 600));
    let path = path.canonicalize().unwrap_or(path);
    let shade_on = match std::env::var("KAGE_SHADE_ON").as_deref() {
        Ok("pixel") => ShadeOn::Pixel,
        Ok("vertex") => ShadeOn::Vertex,
        _ => ShadeOn::Auto,
    };
    let mut bevy = Headless::open(&path, size, shade_on, Rendering::Pipelined).unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(1);
    });
    if bevy_light {
        let lamp = PointLight { intensity: 10.0, shadow_maps_enabled: false, ..default() };
        bevy.app.world_mut().spawn((lamp, Transform::from_xyz(0.0, 3.0, 0.0)));
    }
    bevy.settled(Duration::from_secs(300)).expect("the pack is drawn");
    let world = bevy.app.world_mut();
    let mut lights = world.query::<(&KageLight, &Transform)>();
    let home = lights.iter(world).min_by_key(|(l, _)| l.index).map(|(_, t)| t.translation).filter(|_| !still);
    let (frames, mut total, mut shade) = (60, Duration::ZERO, Duration::ZERO);
    for k in 0..frames {
        if let Some(home) = home {
            let world = bevy.app.world_mut();
            let mut lights = world.query::<(&KageLight, &mut Transform)>();
            if let Some((_, mut t)) = lights.iter_mut(world).min_by_key(|(l, _)| l.index) {
                let turn = k as f32 * std::f32::consts::TAU / frames as f32;
                t.translation = home + 0.2 * Vec3::new(turn.cos(), 0.0, turn.sin());
            }
        }
        let (start, before) = (Instant::now(), bevy.app.world().resource::<KageStats>().shaded_frames);
        bevy.app.update();
        total += start.elapsed();
        // The stats keep the last shading's time: counted for the frames that shaded.
        let stats = bevy.app.world().resource::<KageStats>();
        if stats.shaded_frames > before {
            shade += stats.shade;
        }
    }
    let stats = *bevy.app.world().resource::<KageStats>();
    let ms = |d: Duration| 1000.0 * d.as_secs_f64() / frames as f64;
    println!(
        "{}: {}x{}, {shade_on:?}{}{}, {} vertices: frame {:.1} ms ({:.1} fps), of it per-vertex shading {:.1} ms",
        path.display(),
        size.0,
        size.1,
        if bevy_light { ", with a Bevy light" } else { "" },
        if still { ", the light still" } else { "" },
        stats.vertices,
        ms(total),
        frames as f64 / total.as_secs_f64(),
        ms(shade)
    );
}
