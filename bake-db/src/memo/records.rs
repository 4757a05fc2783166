//! Radiance-cache records in the database, keyed by everything they depend on: the scene's
//! geometry (the occluder snapshot and the lights, which block gather rays), the receivers'
//! meshes (which the records are placed on and gathers read their light from), their
//! materials (which decide where records are placed), the per-vertex direct light the gathers
//! saw, and the cache settings. A light that moves changes the direct light and so the key.

use crate::key::{Key, KeyHasher};
use crate::plan::{Snapshot, encode_occluders};
use crate::store::{Info, Result, Store};
use kage_engine::cache::record::{Glossy, GradientForm, Record, Source};
use kage_engine::cache::{self, Cache, Settings};
use kage_engine::scene::Scene;

/// Version of the record layout and placement: part of every key. (2: record spacing and
/// radius bounds ignore the lights, so a refreshed cache is the cold placement; 3: gather rays
/// pass what touches their start, see [`kage_engine::accel::touching_distance`]; 4: the
/// receivers' meshes join the key, since the occluder snapshot names a flat refinement's
/// source; 5: a gather ray that enters a surface touching its start, such as a box's foot
/// into the floor it rests on, meets it there; 6: such a hit reads the floor's corners outside
/// the object, as pixels do; 7: neighbour clamping of the records' radii at contacts; 8: a record
/// that reads its light noisily gathers a denser grid, `Settings::noise`.)
pub const VERSION: u32 = 8;

/// The key of the records a cache built from `src` with `s` would hold.
pub fn key(src: &Source, s: &Settings) -> Key {
    let flat = &src.renderer.flat;
    let snapshot = Snapshot::of(flat);
    let materials: Vec<f32> = flat
        .instances
        .iter()
        .flat_map(|i| {
            let m = i.material;
            [m.base_color.x, m.base_color.y, m.base_color.z, m.metallic, m.roughness, m.specular]
        })
        .collect();
    let lights: Vec<f32> = flat.lights.iter().flat_map(|l| l.points.iter().flat_map(|p| p.to_array())).collect();
    let direct: Vec<f32> = src.direct.iter().flatten().flat_map(|v| v.to_array()).collect();
    let receivers: Vec<u8> = (0..flat.instances.len()).flat_map(|i| flat.mesh(i).hash.0).collect();
    let mut hasher = KeyHasher::new("hsh-cache");
    // Only the numerical form joins the key, so records stored before it existed stay valid.
    if s.gradient_form == GradientForm::Numerical {
        hasher = hasher.u64("numerical gradients", 1);
    }
    hasher = hasher
        .u64("version", VERSION as u64)
        .u64("order", s.order as u64)
        .u64("rays", s.side().pow(2) as u64)
        .f64("accuracy", s.accuracy as f64)
        .u64("gradients", s.gradients as u64)
        .f64("r_min", s.radius_bounds.0 as f64)
        .f64("r_max", s.radius_bounds.1 as f64)
        .f64("glossy_fallback", s.glossy_fallback as f64)
        .f64("noise", s.noise as f64);
    // Keys of records lit by the reference stay those stored before the other modes existed.
    hasher = match src.glossy {
        Glossy::Reference(spp) => hasher.u64("glossy_spp", spp as u64),
        Glossy::Toward(_) => hasher.u64("glossy_spp", 0).u64("glossy toward the record", 1),
        Glossy::PerVertex => hasher.u64("glossy_spp", 0),
    };
    hasher
        .bytes("occluders", &encode_occluders(&snapshot.occluders))
        .bytes("receivers", &receivers)
        .bytes("lights", bytemuck::cast_slice(&lights))
        .bytes("materials", bytemuck::cast_slice(&materials))
        .bytes("direct", bytemuck::cast_slice(&direct))
        .material_variation(flat)
        .finish()
}

/// The cache from the store when its records are there, else placed now and stored; and
/// whether it came from the store. The scene's extras gain the key (kept by `gc`).
pub fn load_or_place(store: &Store, scene: &Scene, src: &Source, s: &Settings) -> Result<(Cache, bool)> {
    Ok(load_or_place_unless(store, scene, src, s, &|| false)?.expect("never stopped"))
}

/// [`load_or_place`], `Ok(None)` (nothing stored) once `stopped()` answers true during the
/// placement ([`cache::place_at_vertices_unless`]).
pub fn load_or_place_unless(
    store: &Store,
    scene: &Scene,
    src: &Source,
    s: &Settings,
    stopped: &dyn Fn() -> bool,
) -> Result<Option<(Cache, bool)>> {
    let key = key(src, s);
    if let Some(cache) = load(store, scene, src, s, &key)? {
        return Ok(Some((cache, true)));
    }
    let start = std::time::Instant::now();
    let Some(cache) = cache::place_at_vertices_unless(src, s, stopped) else { return Ok(None) };
    put(store, key, &cache, start.elapsed().as_secs_f64())?;
    Ok(Some((cache, false)))
}

/// The cache from the store when its records, under `key` = [`key`]`(src, s)`, are there
/// (without their hits, see [`Cache::refresh`]). The scene's extras gain the key (kept by `gc`).
pub fn load(store: &Store, scene: &Scene, src: &Source, s: &Settings, key: &Key) -> Result<Option<Cache>> {
    debug_assert!(*key == self::key(src, s), "the key of src's records");
    add_to_scene(store, scene, src, key)?;
    let records = store.get::<f64>(key)?.and_then(|d| Record::from_f64s(&d, s.order));
    Ok(records.map(|records| cache::from_records(src, s, records)))
}

/// Stores `cache` — refreshed ([`Cache::refresh`]) from a cache placed over the same receivers
/// with the same settings — under the key of `src`'s lighting: its records are those a cold
/// placement would gather there (record places depend on the receivers alone), so the next
/// [`load_or_place`] under this lighting loads them. `key` is [`key`]`(src, cache.settings())`.
pub fn store_refreshed(
    store: &Store,
    scene: &Scene,
    src: &Source,
    key: &Key,
    cache: &Cache,
    seconds: f64,
) -> Result<()> {
    debug_assert!(*key == self::key(src, cache.settings()), "the key of src's records");
    add_to_scene(store, scene, src, key)?;
    put(store, *key, cache, seconds)
}

/// Records `key` among the scene's extras for its current geometry (kept by `gc` until the
/// geometry changes and is re-baked).
fn add_to_scene(store: &Store, scene: &Scene, src: &Source, key: &Key) -> Result<()> {
    store.add_extra(&scene.source, key, &Snapshot::of(&src.renderer.flat).hash)
}

fn put(store: &Store, key: Key, cache: &Cache, seconds: f64) -> Result<()> {
    let s = cache.settings();
    let bytes: Vec<u8> =
        cache.records.iter().flat_map(|r| bytemuck::cast_slice::<f64, u8>(&r.to_f64s()).to_vec()).collect();
    let info = Info {
        kind: "hsh-cache".into(),
        params: format!("order {}, {} rays, a {}, layout {VERSION}", s.order, s.side().pow(2), s.accuracy),
        seconds,
        vertices: 0,
        checksum: *blake3::hash(&bytes).as_bytes(),
    };
    store.put_batch(&[(key, bytes, info)], &[])
}
