//! PRT parameters chosen from an error budget ([`prt::budget`]), kept in the store's `meta`
//! table so that choosing them for a cached scene stays fast, and so that every caller —
//! `kage bake`, `kage render`, the editor — bakes with the same parameters.
//!
//! The order and window are keyed on what they read, which no move of a group changes (a
//! rotation chooses them again, from the cached [`pilot`](crate::memo::pilot)); the region count also
//! on where everything is, and after a move it is measured again with the transfer the
//! database holds (a truncated bake at a lower order is that order's bake bit for bit), so a
//! choice never depends on what was cached.

use crate::key::KeyHasher;
use crate::store::{Result, Store};
use kage_engine::prt::{self, lighting::Window};
use kage_engine::scene::{EnvironmentLight, FlatScene, Scene};

/// The settings to bake `scene` with under its environment: `base` (directions and defaults)
/// with the order, window and region count chosen from `budget`, reading and writing the
/// choices in `store`. Each choice is reported through `note` (with "(cached plan)" when read).
/// A scene without an environment gets `base`.
pub fn choose(
    store: &Store,
    scene: &Scene,
    flat: &FlatScene,
    budget: f64,
    base: &prt::Settings,
    note: &mut dyn FnMut(String),
) -> Result<prt::Settings> {
    let Some(env) = &flat.environment else {
        note(prt::budget::NO_ENVIRONMENT.into());
        return Ok(*base);
    };
    let (s, pilot) = order(store, scene, flat, env, budget, base, note)?;
    let name = regions_name(scene, flat, budget, &s);
    if let Some(&[q]) = store.meta(&name)?.as_deref() {
        note(format!("{q} regions (cached plan)"));
        return Ok(prt::Settings { regions: q as usize, ..s });
    }
    let transfer = match pilot {
        Some(high) => high.truncated(s.order),
        None => stored_transfer(store, scene, flat, &s)?.unwrap_or_else(|| prt::bake(scene, flat, &s, &|_| {})),
    };
    let (s, why) = prt::budget::choose_regions(scene, flat, env, &transfer, budget, &s);
    note(why);
    store.put_meta(&name, &[s.regions as u8])?;
    Ok(s)
}

/// The settings [`choose`] recorded in `store` for `scene`, without choosing any (what every
/// shard of a sharded bake reads from the base database); `None` when not all are recorded.
pub fn recorded(
    store: &Store,
    scene: &Scene,
    flat: &FlatScene,
    budget: f64,
    base: &prt::Settings,
) -> Result<Option<prt::Settings>> {
    if flat.environment.is_none() {
        return Ok(Some(*base));
    }
    let Some(&[order, w]) = store.meta(&order_name(scene, flat, budget, base))?.as_deref() else { return Ok(None) };
    let Some(&window) = WINDOWS.get(w as usize) else { return Ok(None) };
    let s = prt::Settings { order: order as usize, window, ..*base };
    Ok(match store.meta(&regions_name(scene, flat, budget, &s))?.as_deref() {
        Some(&[q]) => Some(prt::Settings { regions: q as usize, ..s }),
        _ => None,
    })
}

/// The metadata name of the order and window chosen for `scene`.
fn order_name(scene: &Scene, flat: &FlatScene, budget: f64, base: &prt::Settings) -> String {
    format!("prt-order/{}", key(scene, flat, budget, base.directions, false).finish().short())
}

/// The metadata name of the region count chosen for `scene` at the order and window of `s`.
fn regions_name(scene: &Scene, flat: &FlatScene, budget: f64, s: &prt::Settings) -> String {
    let key = key(scene, flat, budget, s.directions, true)
        .u64("order", s.order as u64)
        .u64("window", window_index(s.window) as u64);
    format!("prt-regions/{}", key.finish().short())
}

/// The chosen order and window, from the store or measured (then also the pilot).
fn order(
    store: &Store,
    scene: &Scene,
    flat: &FlatScene,
    env: &EnvironmentLight,
    budget: f64,
    base: &prt::Settings,
    note: &mut dyn FnMut(String),
) -> Result<(prt::Settings, Option<prt::Bake>)> {
    let name = order_name(scene, flat, budget, base);
    if let Some(&[order, w]) = store.meta(&name)?.as_deref()
        && let Some(&window) = WINDOWS.get(w as usize)
    {
        note(format!("SH order {order}, {window:?} window (cached plan)"));
        return Ok((prt::Settings { order: order as usize, window, ..*base }, None));
    }
    let high = crate::memo::pilot::pilot(store, scene, flat, base)?;
    let (s, why) = prt::budget::choose_order(scene, flat, env, budget, base, &high);
    note(why);
    store.put_meta(&name, &[s.order as u8, window_index(s.window)])?;
    Ok((s, Some(high)))
}

/// The windows, in the order the store keeps them.
const WINDOWS: [Window; 3] = [Window::None, Window::Hanning, Window::Lanczos];

fn window_index(w: Window) -> u8 {
    WINDOWS.iter().position(|x| *x == w).unwrap_or(0) as u8
}

/// The PRT transfer for `s` when the store holds all of it.
fn stored_transfer(store: &Store, scene: &Scene, flat: &FlatScene, s: &prt::Settings) -> Result<Option<prt::Bake>> {
    let plan = crate::plan(store, scene, flat, None, Some(*s))?;
    Ok(crate::load(store, flat, &plan)?.and_then(|o| o.prt))
}

/// A key of everything the PRT budget reads: each instance's mesh, material, group and
/// transform within it, its orientation, and the environment; with `placed`, where each
/// instance is too.
fn key(scene: &Scene, flat: &FlatScene, budget: f64, directions: usize, placed: bool) -> KeyHasher {
    let mut h = KeyHasher::new("prt-plan")
        .u64("algorithm", prt::ALGORITHM_VERSION as u64)
        .f64("budget", budget)
        .u64("directions", directions as u64);
    let locals = prt::local_transforms(scene, flat);
    let mut groups = Vec::new();
    for (inst, local) in flat.instances.iter().zip(&locals) {
        let m = inst.material;
        let material = [m.base_color.x, m.base_color.y, m.base_color.z, m.metallic, m.roughness, m.specular];
        let group = groups.iter().position(|g| *g == inst.group).unwrap_or_else(|| {
            groups.push(inst.group);
            groups.len() - 1
        });
        let world = if placed { inst.world } else { glam::Affine3A { translation: glam::Vec3A::ZERO, ..inst.world } };
        h = h
            .bytes("mesh", &flat.meshes[inst.mesh as usize].hash.0)
            .u64("group", group as u64)
            .affine("local", local)
            .affine("world", &world)
            .bytes("material", bytemuck::cast_slice(&material));
    }
    if let Some(env) = &flat.environment {
        h = h
            .bytes("env", bytemuck::cast_slice(&env.map.texels))
            .u64("width", env.map.width as u64)
            .f64("intensity", env.intensity as f64)
            .f64("rotation", env.rotation as f64);
    }
    h
}
