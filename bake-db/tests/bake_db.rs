//! The bake database end to end: caching, bit-identical artefacts, incremental re-bake after
//! edits (exact counts), and bad database files.

use glam::{Affine3A, Quat, Vec3};
use kage_bake_db::plan::Kind;
use kage_bake_db::run::RunStats;
use kage_bake_db::{DbError, Hooks, Store, load, plan, run};
use kage_engine::scene::{EnvMap, EnvironmentLight, Material, Scene, flatten, shapes};
use kage_engine::{bspvt, prt};
use std::path::{Path, PathBuf};

/// `bake.redb` in a fresh folder for test `name` under Cargo's `target/tmp` (the next run
/// replaces it; `cargo clean` removes it).
fn scratch(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("kage-db").join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d.join("bake.redb")
}

const BSPVT: bspvt::Settings = bspvt::Settings { res: 16, epsilon: 2.0 };

fn prt_settings() -> prt::Settings {
    prt::Settings { order: 3, directions: 256, ..prt::Settings::default() }
}

/// A ground (2 chunks), two boxes and a sphere, a quad light and a sky.
fn scene(edit: &str) -> Scene {
    let mut s = Scene::new("test:edits");
    let d = |c: f32| Material::lambertian(Vec3::splat(c));
    // "fine": a ground of 3200 triangles, BSPVT occluder pieces of at most 2048.
    let (edit, cells) = edit.strip_prefix("fine ").map_or((edit, 20), |e| (e, 40));
    s.add_object("ground", shapes::grid(8.0, cells), d(0.8), Affine3A::IDENTITY);
    let a_pose = if edit == "move" { Vec3::new(-0.5, 0.5, 0.4) } else { Vec3::new(-1.5, 0.5, 0.0) };
    let a_mesh = if edit == "mesh" { shapes::sphere(0.5, 12, 6) } else { shapes::cuboid(Vec3::splat(0.5)) };
    s.add_object("box a", a_mesh, d(0.5), Affine3A::from_translation(a_pose));
    if edit != "remove" {
        s.add_object(
            "box b",
            shapes::cuboid(Vec3::new(0.3, 0.8, 0.3)),
            d(0.5),
            Affine3A::from_translation(Vec3::new(1.5, 0.8, -1.0)),
        );
    }
    if edit == "add" {
        s.add_object(
            "sphere",
            shapes::sphere(0.4, 12, 6),
            d(0.6),
            Affine3A::from_translation(Vec3::new(0.0, 0.4, 2.0)),
        );
    }
    let h = 0.5;
    let quad = vec![Vec3::new(-h, 0.0, -h), Vec3::new(h, 0.0, -h), Vec3::new(h, 0.0, h), Vec3::new(-h, 0.0, h)];
    let light = s.add_light("light", quad, Vec3::splat(10.0), Affine3A::from_translation(Vec3::new(0.0, 3.5, 0.0)));
    // The light is not an occluder of BSPVT visibility: moving it must not re-bake anything.
    if edit == "light" {
        s.pose_group(light, Quat::from_rotation_x(0.3), Vec3::new(0.7, 0.0, 0.0));
    }
    s.with_environment(EnvironmentLight::new(EnvMap::procedural_sky(64, 32, Vec3::new(0.3, 0.8, 0.2))))
}

/// Plans and runs; returns the stats and every artefact's bytes in plan order.
fn bake(store: &Store, scene: &Scene) -> (RunStats, Vec<Vec<u8>>, Vec<usize>) {
    let flat = flatten(scene);
    let p = plan(store, scene, &flat, Some(BSPVT), Some(prt_settings())).unwrap();
    let out = run(store, scene, &flat, &p, &|_| {}).unwrap();
    let bytes = p.jobs.iter().map(|j| store.get::<u8>(&j.key).unwrap().expect("stored")).collect();
    // Chunks per instance and kind, for the expected counts.
    let chunks = p.jobs.iter().map(|j| j.instance).collect();
    (out.stats, bytes, chunks)
}

#[test]
fn a_second_bake_does_no_work_and_matches_a_fresh_one_and_the_engine() {
    let path = scratch("twice");
    let store = Store::open(&path).unwrap();
    let s = scene("");
    let (first, bytes, _) = bake(&store, &s);
    assert!(first.cold > 0 && first.cached == 0 && first.warm == 0);
    let (second, again, _) = bake(&store, &s);
    assert_eq!((second.cold, second.warm, second.vertices_baked), (0, 0, 0), "{second:?}");
    assert_eq!(second.cached, first.cold);
    assert!(bytes == again);
    // A fresh database, on one thread: the same bytes.
    let fresh = Store::open(&scratch("twice-fresh")).unwrap();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let (_, single, _) = pool.install(|| bake(&fresh, &s));
    assert!(bytes == single, "artefacts differ between 2 threads and 1");
    // The assembled bakes equal the engine's in-memory bakes.
    let flat = flatten(&s);
    let p = plan(&store, &s, &flat, Some(BSPVT), Some(prt_settings())).unwrap();
    let out = run(&store, &s, &flat, &p, &|_| {}).unwrap();
    assert_eq!(out.bspvt.unwrap().instances, bspvt::bake(&flat, &BSPVT, &|_| {}).instances);
    assert!(out.prt.unwrap().instances == prt::bake(&s, &flat, &prt_settings(), &|_| {}).instances);
}

#[test]
fn fresh_and_stored_chunks_assemble_alike_and_cached_runs_and_loads_write_nothing() {
    let path = scratch("mixed");
    let store = Store::open(&path).unwrap();
    bake(&store, &scene(""));
    let edited = scene("move");
    let flat = flatten(&edited);
    let planned = || plan(&store, &edited, &flat, Some(BSPVT), Some(prt_settings())).unwrap();
    assert!(load(&store, &flat, &planned()).unwrap().is_none(), "a plan with misses loads nothing");
    let mixed = run(&store, &edited, &flat, &planned(), &|_| {}).unwrap();
    assert!(mixed.stats.cached > 0 && mixed.stats.cold + mixed.stats.warm > 0, "{:?}", mixed.stats);
    let file = std::fs::read(&path).unwrap();
    let p = planned();
    let cached = run(&store, &edited, &flat, &p, &|_| {}).unwrap();
    assert_eq!(cached.stats.cached, p.jobs.len());
    assert!(std::fs::read(&path).unwrap() == file, "planning and running a fully cached scene commit nothing");
    // Loading reads the same bakes and writes nothing, not even a plan of part of the scene
    // as the scene's references.
    let loaded = load(&store, &flat, &p).unwrap().expect("all cached");
    let prt_only = plan(&store, &edited, &flat, None, Some(prt_settings())).unwrap();
    let prt = load(&store, &flat, &prt_only).unwrap().expect("all cached").prt.unwrap();
    assert!(std::fs::read(&path).unwrap() == file, "loading commits nothing");
    assert_eq!(loaded.bspvt.unwrap().instances, cached.bspvt.as_ref().unwrap().instances);
    assert!(prt.instances == cached.prt.as_ref().unwrap().instances);
    assert_eq!(mixed.bspvt.unwrap().instances, cached.bspvt.unwrap().instances, "chunks in plan order");
    assert!(mixed.prt.unwrap().instances == cached.prt.unwrap().instances);
}

#[test]
fn edits_rebake_exactly_what_they_affect_and_match_cold_bakes() {
    // Chunks: ground 2 (441 vertices), each box or sphere 1, per technique.
    // (edit, BSPVT chunks baked cold, BSPVT chunks re-baked warm, PRT chunks baked).
    let cases = [
        ("move", 1, 3, 0),   // box a moved: its own trees (new receiver); its PRT transfer is kept
        ("add", 1, 4, 1),    // the new sphere; every other receiver may now see it
        ("remove", 0, 3, 0), // box b gone: the others re-bake the faces that saw it
        ("mesh", 1, 3, 1),   // box a's mesh replaced
        ("light", 0, 0, 0),  // lights are not occluders: nothing to do
    ];
    for (edit, bspvt_cold, bspvt_warm, prt_cold) in cases {
        let store = Store::open(&scratch(&format!("edit-{edit}"))).unwrap();
        let (first, _, _) = bake(&store, &scene(""));
        assert_eq!(first.cold, 8, "{edit}: 4 chunks per technique");
        let edited = scene(edit);
        let (warm, bytes, owners) = bake(&store, &edited);
        let fresh = Store::open(&scratch(&format!("edit-{edit}-fresh"))).unwrap();
        let (cold, cold_bytes, _) = bake(&fresh, &edited);
        assert!(bytes == cold_bytes, "{edit}: a warm re-bake must give a cold bake's bytes");
        assert_eq!((warm.cold, warm.warm), (bspvt_cold + prt_cold, bspvt_warm), "{edit}: {warm:?}");
        assert_eq!(warm.cached, owners.len() - warm.cold - warm.warm, "{edit}");
        if bspvt_warm > 0 {
            // Only rays that can meet what changed are cast, only tiles that changed are built.
            assert!(4 * warm.rays_cast < cold.rays_cast, "{edit}: {warm:?} vs {cold:?}");
            assert!(warm.tiles_built < cold.tiles_built, "{edit}: {warm:?} vs {cold:?}");
        }
    }
}

/// `scene(edit)` with its light declaring that it stays inside `reach`.
fn within(edit: &str, reach: [Vec3; 2]) -> Scene {
    let mut s = scene(edit);
    s.world.query_mut::<&mut kage_engine::scene::PolygonLight>().into_iter().for_each(|l| l.reach = Some(reach));
    s
}

#[test]
fn a_declared_light_reach_is_keyed_rebakes_warm_and_moves_inside_it_cost_nothing() {
    let room = [Vec3::new(-1.5, 3.0, -1.5), Vec3::new(1.5, 4.0, 1.5)];
    let store = Store::open(&scratch("reach")).unwrap();
    let (roaming, roaming_bytes, _) = bake(&store, &scene(""));
    let (first, bytes, _) = bake(&store, &within("", room));
    assert_eq!((first.cold, first.cached), (4, 4), "new BSPVT keys, the same PRT ones: {first:?}");
    assert!(first.rays_cast < roaming.rays_cast / 2, "{first:?} vs {roaming:?}");
    let size = |b: &[Vec<u8>]| b.iter().map(Vec::len).sum::<usize>();
    assert!(size(&bytes) < size(&roaming_bytes), "{} vs {} bytes", size(&bytes), size(&roaming_bytes));
    // An occluder moved: warm, with a cold bake's bytes.
    let (warm, warm_bytes, _) = bake(&store, &within("move", room));
    let (_, cold_bytes, _) = bake(&Store::open(&scratch("reach-fresh")).unwrap(), &within("move", room));
    assert!(warm_bytes == cold_bytes, "a warm re-bake must give a cold bake's bytes");
    assert_eq!((warm.cold, warm.warm), (1, 3), "{warm:?}");
    // The light moved inside its reach: nothing to do; out of it: the reach grows, all re-baked.
    let (inside, ..) = bake(&store, &within("light", room));
    assert_eq!((inside.cold, inside.warm), (0, 0), "{inside:?}");
    let (outside, ..) = bake(&store, &within("light", [Vec3::new(-1.0, 3.0, -1.0), Vec3::new(1.0, 4.0, 1.0)]));
    assert_eq!((outside.cold, outside.warm), (4, 0), "{outside:?}");
}

#[test]
fn bad_database_files_give_clear_errors() {
    // Garbage.
    let garbage = scratch("garbage");
    std::fs::write(&garbage, b"this is not a redb file, just some text that goes on for a while........").unwrap();
    let e = Store::open(&garbage).err().expect("garbage is rejected");
    assert!(matches!(e, DbError::Corrupted { .. }) && e.to_string().contains("garbage"), "{e}");
    // Truncated: a real database cut in half.
    let path = scratch("truncated");
    {
        let store = Store::open(&path).unwrap();
        bake(&store, &scene(""));
    }
    let full = std::fs::read(&path).unwrap();
    std::fs::write(&path, &full[..full.len() / 2]).unwrap();
    match Store::open(&path) {
        Err(e) => assert!(e.to_string().contains("truncated"), "{e}"),
        Ok(mut s) => {
            // redb may repair what it can; whatever survives must check clean or report damage.
            let _ = s.check();
        }
    }
    // Locked: a second open of a database in use.
    let locked = scratch("locked");
    let _first = Store::open(&locked).unwrap();
    let e = Store::open(&locked).err().expect("a database in use is refused");
    assert!(matches!(e, DbError::Locked(_)) && e.to_string().contains("in use"), "{e}");
    // Schema mismatch.
    let old = scratch("schema");
    {
        let db = redb::Database::create(&old).unwrap();
        let t = db.begin_write().unwrap();
        t.open_table(redb::TableDefinition::<&str, &[u8]>::new("meta"))
            .unwrap()
            .insert("schema_version", 99u32.to_le_bytes().as_slice())
            .unwrap();
        t.commit().unwrap();
    }
    let e = Store::open(&old).err().expect("another schema is refused");
    assert!(matches!(e, DbError::Schema { found: 99, .. }) && e.to_string().contains("schema version 99"), "{e}");
    // A symbolic link, dangling or not, is refused: nothing is created at its target.
    #[cfg(unix)]
    for target in [scratch("link-target"), old.clone()] {
        let link = scratch("link").with_file_name("link.redb");
        let _ = std::fs::remove_file(&link);
        std::os::unix::fs::symlink(&target, &link).unwrap();
        let existed = target.exists();
        let e = Store::open(&link).err().expect("a symlink is refused").to_string();
        assert!(e.contains("symbolic link") && e.contains("link.redb"), "{e}");
        assert!(Store::open_read_only(&link).is_err());
        assert_eq!(target.exists(), existed, "nothing created at the link's target");
    }
}

/// The PRT budget's pilot is cached bit for bit, survives moves (it is group-local), and a damaged
/// entry is baked again, never used.
#[test]
fn the_pilot_is_cached_exactly_survives_moves_and_a_damaged_entry_is_baked_again() {
    let store = Store::open(&scratch("pilot")).unwrap();
    let base = prt_settings();
    let pilot = |s: &Scene| kage_bake_db::memo::pilot::pilot(&store, s, &flatten(s), &base).unwrap().instances;
    let entries = || store.memos().unwrap().into_iter().filter(|(n, _)| n.starts_with("prt pilot")).collect::<Vec<_>>();
    let s = scene("");
    let fresh = prt::budget::pilot(&s, &flatten(&s), &base).instances;
    assert!(pilot(&s) == fresh && entries().len() == 1, "baked and stored");
    assert!(pilot(&s) == fresh, "read back bit for bit");
    let moved = scene("move");
    assert!(pilot(&moved) == fresh && entries().len() == 1, "a move reads the same entry");
    let (name, _) = entries().remove(0);
    let mut damaged = store.memo(&name).unwrap().unwrap();
    damaged[100] ^= 1;
    store.put_memos(&[(name.clone(), damaged.clone())]).unwrap();
    assert!(pilot(&s) == fresh, "a damaged entry is baked again");
    assert!(store.memo(&name).unwrap().unwrap() != damaged, "and replaced");
    assert!(pilot(&scene("mesh")) != fresh && entries().len() == 2, "a changed mesh has its own pilot");
}

/// A process killed while creating a database must not leave a half-written file behind: the
/// file appears whole (with the header it keeps) or not at all, and abandoned temporary files
/// are swept.
#[test]
fn a_new_database_appears_whole_and_abandoned_partials_are_swept() {
    for round in 0..20 {
        let path = scratch(&format!("appears-{round}"));
        let watched = path.clone();
        let first_seen = std::thread::spawn(move || {
            loop {
                if let Ok(bytes) = std::fs::read(&watched) {
                    return bytes;
                }
                std::hint::spin_loop();
            }
        });
        drop(Store::open(&path).unwrap());
        // What a process killed at that instant would have left: it must open as it is.
        let copy = path.with_extension("seen");
        std::fs::write(&copy, first_seen.join().unwrap()).unwrap();
        let opened = Store::open(&copy);
        assert!(opened.is_ok(), "round {round}: the file appeared unfinished: {}", opened.err().unwrap());
    }
    let path = scratch("partials");
    let dir = path.parent().unwrap();
    let (stale, fresh, other) =
        (dir.join(".bake.redb.x1.partial"), dir.join(".bake.redb.x2.partial"), dir.join("keep.partial"));
    for p in [&stale, &fresh, &other] {
        std::fs::write(p, b"half").unwrap();
    }
    let old = std::time::SystemTime::now() - std::time::Duration::from_secs(3600);
    for p in [&stale, &other] {
        std::fs::File::options().write(true).open(p).unwrap().set_modified(old).unwrap();
    }
    drop(Store::open(&path).unwrap());
    assert!(!stale.exists(), "an abandoned partial is swept");
    assert!(fresh.exists(), "a partial that may still be in progress is kept");
    assert!(other.exists(), "files that are not this database's partials are kept");
    let left: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(left.len(), 3, "creating the database left nothing else behind: {left:?}");
}

/// `bake` (what `kage bake` runs) commits what `run` commits, cold and warm, with the same
/// counts, without assembling the bakes.
#[test]
fn bake_commits_what_run_commits() {
    let (only, full) = (Store::open(&scratch("bake-only")).unwrap(), Store::open(&scratch("bake-full")).unwrap());
    for edit in ["", "move"] {
        let s = scene(edit);
        let flat = flatten(&s);
        let p = plan(&only, &s, &flat, Some(BSPVT), Some(prt_settings())).unwrap();
        let stats = kage_bake_db::bake(&only, &s, &flat, &p, &|_| {}).unwrap();
        let (expected, bytes, _) = bake(&full, &s);
        let counts = |r: &RunStats| (r.cached, r.cold, r.warm, r.vertices_baked, r.rays_cast, r.tiles_built);
        assert_eq!(counts(&stats), counts(&expected), "{edit:?}");
        let stored: Vec<Vec<u8>> = p.jobs.iter().map(|j| only.get::<u8>(&j.key).unwrap().expect("stored")).collect();
        assert!(stored == bytes, "{edit:?}: the same artefacts");
    }
}

/// The estimate bakes a sample of both techniques' misses, writes nothing (every chunk is still
/// missing after it, and the bake that follows equals one never estimated), and has nothing
/// to measure once everything is cached.
#[test]
fn the_estimate_samples_both_techniques_and_writes_nothing() {
    let (store, plain) = (Store::open(&scratch("estimate")).unwrap(), Store::open(&scratch("no-estimate")).unwrap());
    let s = scene("");
    let flat = flatten(&s);
    let p = plan(&store, &s, &flat, Some(BSPVT), Some(prt_settings())).unwrap();
    let e = kage_bake_db::estimate::estimate(&store, &s, &flat, &p).unwrap();
    assert_eq!(e.rates.iter().map(|r| r.0).collect::<Vec<_>>(), ["bspvt", "prt"]);
    assert!(e.rates.iter().all(|r| r.1 > 0.0 && r.2 > 0.0) && e.total(2) > 0.0, "{e:?}");
    let sampled: usize = [Kind::Bspvt, Kind::Prt]
        .iter()
        .flat_map(|&k| kage_bake_db::estimate::sample(&p.misses().filter(|j| j.kind == k).collect::<Vec<_>>()))
        .map(|j| j.vertices.len())
        .sum();
    assert_eq!(e.sampled, sampled);
    assert!(store.contains_all(&p.keys()).unwrap().iter().all(|c| !c), "the sample was not stored");
    let (_, estimated, _) = bake(&store, &s);
    let (_, fresh, _) = bake(&plain, &s);
    assert!(estimated == fresh, "the bake after an estimate equals one without");
    let p = plan(&store, &s, &flat, Some(BSPVT), Some(prt_settings())).unwrap();
    assert_eq!(kage_bake_db::estimate::estimate(&store, &s, &flat, &p).unwrap(), Default::default());

    // After an edit, the misses with lineage are timed warm, apart, at their lower rate.
    let moved = scene("move");
    let flat = flatten(&moved);
    let p = plan(&store, &moved, &flat, Some(BSPVT), Some(prt_settings())).unwrap();
    let e = kage_bake_db::estimate::estimate(&store, &moved, &flat, &p).unwrap();
    assert_eq!(e.rates.iter().map(|r| r.0).collect::<Vec<_>>(), ["bspvt", "bspvt warm"], "{e:?}");
    assert_eq!(e.warm.len(), 3, "the three receivers that did not move re-bake warm");
    assert!(e.rates[1].2 < e.rates[0].2, "warm re-bakes cost less per vertex: {e:?}");
}

/// The names of the occluder BVHs `store` keeps.
fn bvhs(store: &Store) -> Vec<String> {
    store.memos().unwrap().into_iter().map(|c| c.0).filter(|n| n.starts_with("bvh ")).collect()
}

/// Bakes `scene(edit)` into `store`, which re-bakes some chunks warm, and into a fresh store
/// named `fresh`, and checks that the bytes are equal; returns the fresh store.
fn warm_as_cold(store: &Store, edit: &str, fresh: &str) -> Store {
    let (warm, bytes, _) = bake(store, &scene(edit));
    let fresh = Store::open(&scratch(fresh)).unwrap();
    let (_, cold, _) = bake(&fresh, &scene(edit));
    assert!(warm.warm > 0 && bytes == cold, "{warm:?}");
    fresh
}

/// The occluders' BVHs are stored by a run for the instances with enough triangles (here the
/// ground alone) and restored by the next; a damaged entry is built and stored again, and the
/// bytes are a cold bake's either way.
#[test]
fn occluder_bvhs_outlive_runs_and_damage_costs_only_time() {
    let store = Store::open(&scratch("bvhs")).unwrap();
    bake(&store, &scene(""));
    let names = bvhs(&store);
    assert_eq!(names.len(), 1, "{names:?}");
    let good = store.memo(&names[0]).unwrap().unwrap();
    let mut damaged = good.clone();
    damaged[good.len() / 2] ^= 0x04;
    store.put_memos(&[(names[0].clone(), damaged)]).unwrap();
    let fresh = warm_as_cold(&store, "move", "bvhs-fresh");
    assert_eq!(store.memo(&names[0]).unwrap(), Some(good.clone()), "built and stored again");
    assert_eq!(bvhs(&store), names, "the moved box has too few triangles for an entry");
    assert_eq!(fresh.memo(&names[0]).unwrap(), Some(good), "the same build in another database");
    store.gc().unwrap();
    assert!(bvhs(&store).is_empty(), "gc drops them with the other caches");
}

/// A merge carries no memo: each baker rebuilds them as it goes.
#[test]
fn a_merge_carries_no_memo() {
    let (shard, merged) =
        (Store::open(&scratch("memos-shard")).unwrap(), Store::open(&scratch("memos-merged")).unwrap());
    let memos = [("bvh of something", 4), ("tiles of some settings", 5)].map(|(n, b)| (n.to_string(), vec![b]));
    shard.put_memos(&memos).unwrap();
    merged.merge_from(&shard).unwrap();
    assert!(merged.memos().unwrap().is_empty());
}

/// An occluder of more triangles than a piece keeps one BVH per piece, and a warm re-bake
/// that restores them gives a cold bake's bytes.
#[test]
fn a_large_occluder_keeps_a_bvh_per_piece() {
    let store = Store::open(&scratch("pieces")).unwrap();
    bake(&store, &scene("fine "));
    let names = bvhs(&store);
    assert_eq!(names.len(), 2, "3200 ground triangles in two pieces: {names:?}");
    warm_as_cold(&store, "fine move", "pieces-fresh");
    assert_eq!(bvhs(&store), names, "the same pieces, the moved box too small for an entry");
}

/// The BSPVT subtree memo is stored by a run and used by the next; a damaged one only costs
/// time (the re-bake still gives a cold bake's bytes, and stores a good cache again); `gc`
/// drops it.
#[test]
fn the_tile_cache_outlives_runs_and_damage_costs_only_time() {
    let store = Store::open(&scratch("tiles")).unwrap();
    let name = run::tiles_name(&BSPVT);
    let (first, ..) = bake(&store, &scene(""));
    let stored = store.memo(&name).unwrap().expect("a cold bake stores its tiles");
    let caches = store.memos().unwrap();
    assert!(caches.contains(&(name.clone(), stored.len())), "{caches:?}");
    assert_eq!(caches.len(), 2, "the tiles and the ground's BVH: {caches:?}");
    let cache = bspvt::memo::SubtreeMemo::from_bytes(&BSPVT, &stored).expect("a well-formed cache");
    // Every tile built is a stored entry or a hit — or, rarely, a second worker's build of a
    // tile another was building at the same moment (neither a hit nor a new entry).
    assert!(cache.len() > 10 && first.tiles_from_memo > 0, "{first:?}");
    assert!(cache.len() + first.tiles_from_memo <= first.tiles_built, "{first:?}");
    let mut damaged = stored.clone();
    damaged[stored.len() / 2] ^= 0x10;
    store.put_memos(&[(name.clone(), damaged)]).unwrap();
    let (_, bytes, _) = bake(&store, &scene("move"));
    let (_, cold, _) = bake(&Store::open(&scratch("tiles-fresh")).unwrap(), &scene("move"));
    assert!(bytes == cold, "a re-bake past a damaged cache gives a cold bake's bytes");
    let again = store.memo(&name).unwrap().expect("stored again");
    // Started afresh: only the tiles the re-bake built.
    assert!(
        bspvt::memo::SubtreeMemo::from_bytes(&BSPVT, &again).is_some_and(|c| !c.is_empty() && c.len() < cache.len())
    );
    store.gc().unwrap();
    assert_eq!(store.memo(&name).unwrap(), None, "gc drops caches");
    assert_eq!(store.memos().unwrap(), vec![]);
}

#[test]
fn check_finds_damaged_artefacts_and_gc_drops_unreferenced_ones() {
    let path = scratch("gc");
    let mut store = Store::open(&path).unwrap();
    bake(&store, &scene(""));
    let (n0, ..) = store.counts().unwrap();
    let report = store.check().unwrap();
    assert!(report.bad.is_empty() && report.ok as u64 == n0);
    // After an edit the scene references new keys; the old ones are garbage.
    bake(&store, &scene("move"));
    let (n1, ..) = store.counts().unwrap();
    let dropped = store.gc().unwrap();
    let (n2, ..) = store.counts().unwrap();
    assert!(dropped > 0 && n2 == n1 - dropped as u64 && n2 == n0, "{n0} {n1} {dropped} {n2}");
    // Still fully cached after gc.
    let (again, ..) = bake(&store, &scene("move"));
    assert_eq!((again.cold, again.warm), (0, 0));
}

#[test]
fn a_cancelled_run_keeps_what_it_committed_and_the_next_run_finishes_the_rest() {
    use std::sync::atomic::{AtomicBool, Ordering};
    let store = Store::open(&scratch("cancel")).unwrap();
    let s = scene("");
    let flat = flatten(&s);
    let p = plan(&store, &s, &flat, Some(BSPVT), Some(prt_settings())).unwrap();
    let cancel = AtomicBool::new(false);
    // Cancel once the first chunk reports: later jobs are never started.
    let hooks = Hooks { progress: &|_| cancel.store(true, Ordering::Relaxed), cancel: &cancel, chunk: None };
    let e = kage_bake_db::run_cancellable(&store, &s, &flat, &p, hooks).err().expect("the run was cancelled");
    let DbError::Cancelled { done } = e else { panic!("{e}") };
    let total: usize = p.misses().map(|j| j.vertices.len()).sum();
    assert!(done > 0 && done < total, "committed {done} of {total} vertices");
    let again = plan(&store, &s, &flat, Some(BSPVT), Some(prt_settings())).unwrap();
    let left: usize = again.misses().map(|j| j.vertices.len()).sum();
    assert_eq!(left, total - done, "what was committed is cached");
    let out = run(&store, &s, &flat, &again, &|_| {}).unwrap();
    assert_eq!(out.bspvt.unwrap().instances, bspvt::bake(&flat, &BSPVT, &|_| {}).instances);
}

/// The workers take the missing chunks largest first (in plan order, the ground's chunks, the
/// boxes' and then PRT's alternate large and small): on one worker the chunks land in that order.
#[test]
fn a_run_bakes_its_largest_chunks_first() {
    use std::sync::Mutex;
    use std::sync::atomic::AtomicBool;
    let store = Store::open(&scratch("largest first")).unwrap();
    let s = scene("");
    let flat = flatten(&s);
    let p = plan(&store, &s, &flat, Some(BSPVT), Some(prt_settings())).unwrap();
    let sizes: Vec<usize> = p.jobs.iter().map(|j| j.vertices.len()).collect();
    assert!(sizes.windows(2).any(|w| w[0] < w[1]), "the plan's order is not already largest first: {sizes:?}");
    let landed: Mutex<Vec<usize>> = Mutex::default();
    let record = |c: kage_bake_db::Chunk| landed.lock().unwrap().push(c.job.vertices.len());
    let hooks = Hooks { progress: &|_| {}, cancel: &AtomicBool::new(false), chunk: Some(&record) };
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    one.install(|| kage_bake_db::run_cancellable(&store, &s, &flat, &p, hooks)).unwrap();
    let landed = landed.into_inner().unwrap();
    assert_eq!(landed.len(), p.jobs.len());
    assert!(landed.windows(2).all(|w| w[0] >= w[1]), "largest first: {landed:?}");
}

#[test]
fn every_chunk_streams_once_cached_first_and_the_chunks_assemble_into_the_outcome() {
    use kage_bake_db::plan::Kind;
    use std::sync::Mutex;
    use std::sync::atomic::AtomicBool;
    let store = Store::open(&scratch("stream")).unwrap();
    let s = scene("");
    let flat = flatten(&s);
    let p = plan(&store, &s, &flat, Some(BSPVT), Some(prt_settings())).unwrap();
    run(&store, &s, &flat, &p, &|_| {}).unwrap();
    // Move a box: PRT of the other groups stays cached, BSPVT is re-baked (warm).
    let moved = scene("move");
    let flat = flatten(&moved);
    let p = plan(&store, &moved, &flat, Some(BSPVT), Some(prt_settings())).unwrap();
    let cached = p.jobs.iter().filter(|j| j.cached).count();
    assert!(cached > 0 && cached < p.jobs.len(), "{cached} of {}", p.jobs.len());
    let seen: Mutex<Vec<(usize, bool, Vec<u8>)>> = Mutex::default();
    let record = |c: kage_bake_db::Chunk| {
        let index = p.jobs.iter().position(|j| j.key == c.job.key).expect("a job of the plan");
        seen.lock().unwrap().push((index, c.job.cached, c.bytes.to_vec()));
    };
    let hooks = Hooks { progress: &|_| {}, cancel: &AtomicBool::new(false), chunk: Some(&record) };
    let out = kage_bake_db::run_cancellable(&store, &moved, &flat, &p, hooks).unwrap();
    let seen = seen.into_inner().unwrap();
    let mut order: Vec<usize> = seen.iter().map(|c| c.0).collect();
    order.sort();
    assert_eq!(order, (0..p.jobs.len()).collect::<Vec<_>>(), "every chunk once");
    assert!(seen[..cached].iter().all(|c| c.1) && seen[cached..].iter().all(|c| !c.1), "cached chunks first");
    let (trees, transfer) = (out.bspvt.unwrap(), out.prt.unwrap());
    for (index, _, bytes) in seen {
        let job = &p.jobs[index];
        let chunk = kage_bake_db::Chunk { job, bytes: &bytes };
        match job.kind {
            Kind::Bspvt => {
                let inst = &trees.instances[job.instance];
                let expected: Vec<Vec<u8>> = job.vertices.clone().map(|v| inst.record(v).to_vec()).collect();
                assert_eq!(chunk.bspvt_records(), Some(expected), "chunk {index}");
            }
            Kind::Prt => {
                let n = transfer.order * transfer.order;
                let expected = &transfer.instances[job.instance][job.vertices.start * n..job.vertices.end * n];
                assert_eq!(chunk.prt_transfer().as_deref(), Some(expected), "chunk {index}");
            }
        }
    }
}

fn cache_settings() -> kage_engine::cache::Settings {
    kage_engine::cache::Settings { rays: 64, accuracy: 0.5, ..kage_engine::cache::Settings::default() }
}

/// The scene's renderer and a per-vertex "direct" light: an unshadowed falloff from the light's
/// centre (cheap, exact input for the radiance cache).
fn lit(scene: &Scene) -> (kage_engine::reference::Renderer, Vec<Vec<Vec3>>) {
    let r = kage_engine::reference::Renderer::new(scene);
    let c = r.flat.lights[0].points.iter().sum::<Vec3>() / r.flat.lights[0].points.len() as f32;
    let direct: Vec<Vec<Vec3>> = (0..r.flat.instances.len())
        .map(|i| {
            let falloff = |(p, n): (Vec3, Vec3)| n.dot(c - p).max(0.0) / (c - p).length().powi(3);
            (0..r.mesh(i).positions.len()).map(|v| Vec3::splat(falloff(r.vertex(i, v)))).collect()
        })
        .collect();
    (r, direct)
}

/// Cache records are made outside the bake plan: a re-bake of the same geometry and `gc` keep
/// them (for every lighting), a bake of edited geometry lets `gc` drop them.
#[test]
fn gc_keeps_cache_records_until_the_geometry_changes() {
    use kage_bake_db::memo::records::load_or_place;
    use kage_engine::cache::record::{Glossy, Source};
    let store = Store::open(&scratch("gc-records")).unwrap();
    bake(&store, &scene(""));
    let mut keys = Vec::new();
    for edit in ["", "light"] {
        let sc = scene(edit);
        let (r, d) = lit(&sc);
        let src = Source { renderer: &r, direct: &d, glossy: Glossy::PerVertex };
        load_or_place(&store, &sc, &src, &cache_settings()).unwrap();
        keys.push(kage_bake_db::memo::records::key(&src, &cache_settings()));
    }
    let stored = |store: &Store| keys.iter().filter(|k| store.get::<u8>(k).unwrap().is_some()).count();
    bake(&store, &scene("light"));
    store.gc().unwrap();
    assert_eq!(stored(&store), 2, "same geometry: both lightings' records stay");
    bake(&store, &scene("move"));
    store.gc().unwrap();
    assert_eq!(stored(&store), 0, "after a geometry edit gc drops them");
}

#[test]
fn a_refreshed_cache_is_stored_under_the_new_lightings_key_with_a_cold_placements_bytes() {
    use kage_bake_db::memo::records::{load_or_place, store_refreshed};
    use kage_engine::cache::{self, record::Change, record::Glossy, record::Source};
    let s = cache_settings();
    let (before, moved) = (scene(""), scene("light"));
    let ((r0, d0), (r1, d1)) = (lit(&before), lit(&moved));
    let src0 = Source { renderer: &r0, direct: &d0, glossy: Glossy::PerVertex };
    let src1 = Source { renderer: &r1, direct: &d1, glossy: Glossy::PerVertex };
    let store = Store::open(&scratch("refreshed")).unwrap();
    let (mut c, from_db) = load_or_place(&store, &before, &src0, &s).unwrap();
    assert!(!from_db);
    let lights = cache::moved_lights(&r0.flat.lights, &r1.flat.lights);
    c.refresh(&src1, &Change { old_direct: Some(&d0), moved: &lights });
    let key = kage_bake_db::memo::records::key(&src1, &s);
    store_refreshed(&store, &moved, &src1, &key, &c, 0.0).unwrap();
    let (loaded, from_db) = load_or_place(&store, &moved, &src1, &s).unwrap();
    assert!(from_db && loaded.records == c.records, "the next session loads the refreshed records");
    let cold = Store::open(&scratch("refreshed-cold")).unwrap();
    load_or_place(&cold, &moved, &src1, &s).unwrap();
    assert!(store.get::<u8>(&key).unwrap() == cold.get::<u8>(&key).unwrap(), "same key, same bytes");
}

/// Bakes the test scene, lets `damage` change the stored bytes of its first chunk of `kind`
/// (the chunk's first vertex given), stores them under a checksum that matches (as a buggy or
/// crafted writer would), and returns the error loading then gives.
fn load_error_after(name: &str, kind: Kind, damage: impl FnOnce(&mut Vec<u8>) -> usize) -> (String, usize) {
    let store = Store::open(&scratch(name)).unwrap();
    let s = scene("");
    bake(&store, &s);
    let flat = flatten(&s);
    let p = plan(&store, &s, &flat, Some(BSPVT), Some(prt_settings())).unwrap();
    let job = p.jobs.iter().find(|j| j.kind == kind).unwrap();
    let mut bytes = store.get::<u8>(&job.key).unwrap().unwrap();
    let vertex = job.vertices.start + damage(&mut bytes);
    let checksum = *blake3::hash(&bytes).as_bytes();
    let info =
        kage_bake_db::store::Info { kind: String::new(), params: String::new(), seconds: 0.0, vertices: 0, checksum };
    store.put_batch(&[(job.key, bytes, info)], &[]).unwrap();
    let Err(e) = run(&store, &s, &flat, &p, &|_| {}) else { panic!("{name}: a damaged artefact loaded") };
    (e.to_string(), vertex)
}

#[test]
fn a_truncated_prt_artefact_is_a_clear_error_not_a_panic() {
    // One vertex's coefficients short (shading would slice past the end).
    let (e, _) = load_error_after("damaged-prt", Kind::Prt, |bytes| {
        bytes.truncate(bytes.len() - 4 * 9);
        0
    });
    assert!(e.contains("PRT artefact") && e.contains("malformed") && e.contains("vertices need"), "{e}");
}

#[test]
fn a_damaged_tree_in_a_stored_artefact_is_a_clear_error_not_a_panic() {
    let (e, vertex) = load_error_after("damaged-tree", Kind::Bspvt, |bytes| {
        // The chunk: vertex count, offsets, records; cut short the first record holding a tree
        // by turning its last byte (a leaf) into a split with no children. The layout stays
        // intact.
        let count = u32::from_le_bytes(bytes[..4].try_into().unwrap()) as usize;
        let offsets: Vec<u32> = bytemuck::pod_collect_to_vec(&bytes[4..8 + 4 * count]);
        let data = 8 + 4 * count;
        let v = offsets.windows(2).position(|w| w[1] - w[0] > 12).unwrap();
        bytes[data + offsets[v + 1] as usize - 1] = 0xFF;
        v
    });
    assert!(e.contains("malformed") && e.contains(&format!("vertex {vertex}")), "{e}");
}

/// redb's page size.
const PAGE: usize = 4096;

/// Damaged pages anywhere in the file never crash a load: every bit flip either loads (redb
/// did not read that page, or the damage was in unused space), or gives an error naming the
/// file. A panic inside the storage library is contained at the store's boundary.
#[test]
fn damaged_pages_give_errors_never_panics() {
    let path = scratch("damaged-pages");
    let scene = scene("");
    bake(&Store::open(&path).unwrap(), &scene);
    let clean = std::fs::read(&path).unwrap();
    let damaged = path.with_file_name("damaged.redb");
    let flat = flatten(&scene);
    let (mut loaded, mut refused) = (0, 0);
    // Every 97th byte of the file's written pages (a prime stride reaches every page and
    // offset class); a flip in the all-zero pages redb grew the file by loaded every time
    // (8,572 of 8,572), as nothing reads them.
    let written =
        |at: &usize| clean[at / PAGE * PAGE..((at / PAGE + 1) * PAGE).min(clean.len())].iter().any(|b| *b != 0);
    for at in (0..clean.len()).step_by(97).filter(written) {
        let mut bytes = clean.clone();
        bytes[at] ^= 0x5A;
        std::fs::write(&damaged, &bytes).unwrap();
        let outcome = std::panic::catch_unwind(|| {
            let store = Store::open(&damaged)?;
            let p = plan(&store, &scene, &flat, Some(BSPVT), Some(prt_settings()))?;
            load(&store, &flat, &p).map(|_| ())
        });
        match outcome.unwrap_or_else(|_| panic!("a flip at byte {at} of {} panicked", clean.len())) {
            Ok(()) => loaded += 1,
            Err(e) => {
                assert!(e.to_string().contains("damaged.redb"), "the error names the file: {e}");
                refused += 1;
            }
        }
    }
    assert!(loaded + refused > 100 && refused > 0, "{loaded} loaded, {refused} refused");
}

/// One flipped mantissa bit inside a stored artefact (redb's pages intact, every range check
/// passing) is caught by the artefact's checksum on load: a load reports the plan as not
/// cached, and a run bakes that chunk again and shades the same bytes as before the damage.
#[test]
fn a_flipped_bit_in_a_stored_artefact_is_baked_again_never_shaded() {
    let path = scratch("flipped-bit");
    let s = scene("");
    let flat = flatten(&s);
    let (_, bytes, _) = bake(&Store::open(&path).unwrap(), &s);
    let p = plan(&Store::open(&path).unwrap(), &s, &flat, Some(BSPVT), Some(prt_settings())).unwrap();
    let k = p.jobs.iter().position(|j| j.kind == Kind::Prt).expect("a PRT chunk");
    // Find the chunk's bytes in the file and flip one bit of a coefficient's mantissa.
    let mut file = std::fs::read(&path).unwrap();
    let needle = &bytes[k][..64];
    let at = file.windows(needle.len()).position(|w| w == needle).expect("the artefact is stored contiguously");
    file[at + 16 + 1] ^= 0x04;
    std::fs::write(&path, &file).unwrap();

    let store = Store::open(&path).unwrap();
    let p = plan(&store, &s, &flat, Some(BSPVT), Some(prt_settings())).unwrap();
    assert!(p.misses().next().is_none(), "the plan still finds every key");
    assert!(load(&store, &flat, &p).unwrap().is_none(), "a load does not shade the damaged chunk");
    let out = run(&store, &s, &flat, &p, &|_| {}).unwrap();
    assert_eq!((out.stats.cold, out.stats.cached), (1, p.jobs.len() - 1), "only the damaged chunk is baked again");
    assert_eq!(store.get::<u8>(&p.jobs[k].key).unwrap().unwrap(), bytes[k], "the same bytes as before the damage");
    assert!(load(&store, &flat, &p).unwrap().is_some(), "loads again once replaced");
}

/// Every artefact of a database as (key, kind, parameters, checksum, size): what a merge must
/// reproduce (timings recorded beside them may differ).
fn contents(path: &std::path::Path) -> Vec<(kage_bake_db::Key, String, String, [u8; 32], usize)> {
    let store = Store::open_read_only(path).unwrap();
    store.artefacts().unwrap().into_iter().map(|(k, i, n)| (k, i.kind, i.params, i.checksum, n)).collect()
}

/// Shards split the misses (each chunk in exactly one shard, loads balanced); their databases
/// merged equal a single-machine bake artefact for artefact; a missing shard leaves exactly its
/// chunks to bake; merging again adds nothing.
#[test]
fn shards_merged_equal_a_single_machine_bake() {
    use kage_bake_db::shard::{self, Shard};
    let s = scene("");
    let flat = flatten(&s);
    let single = scratch("shard-single");
    bake(&Store::open(&single).unwrap(), &s);
    let probe = Store::open(&scratch("shard-probe")).unwrap();
    let p = plan(&probe, &s, &flat, Some(BSPVT), Some(prt_settings())).unwrap();
    let n = 3;
    let split = shard::split(&p, &flat, n);
    assert!(split.owner.iter().all(|o| o.is_some_and(|i| i < n)), "every chunk in exactly one shard");
    let (lo, hi) = split.load.iter().fold((f64::MAX, 0f64), |(lo, hi), l| (lo.min(*l), hi.max(*l)));
    // Greedy dealing, costliest first: no shard exceeds another by more than one chunk's cost.
    let costliest = p.jobs.iter().map(|j| p.default_seconds_per_vertex(j.kind) * p.work(&flat, j)).fold(0.0, f64::max);
    assert!(hi - lo <= costliest, "balanced: {:?}, costliest chunk {costliest}", split.load);
    assert_eq!(split, shard::split(&p, &flat, n), "deterministic");
    let shards: Vec<PathBuf> = (0..n).map(|i| scratch(&format!("shard-{i}"))).collect();
    for (index, path) in shards.iter().enumerate() {
        let mine = p.shard(&split, Shard { index, count: n });
        assert_eq!(mine.misses().count(), split.owner.iter().filter(|o| **o == Some(index)).count());
        kage_bake_db::bake(&Store::open(path).unwrap(), &s, &flat, &mine, &|_| {}).unwrap();
    }
    let merged_path = scratch("shard-merged");
    let merged = Store::open(&merged_path).unwrap();
    for path in &shards[..n - 1] {
        merged.merge_from(&Store::open_read_only(path).unwrap()).unwrap();
    }
    // Shard n−1 missing: the merged plan reports exactly its chunks.
    let after = plan(&merged, &s, &flat, Some(BSPVT), Some(prt_settings())).unwrap();
    let last = split.owner.iter().filter(|o| **o == Some(n - 1)).count();
    assert_eq!(after.misses().count(), last);
    let stats = merged.merge_from(&Store::open_read_only(&shards[n - 1]).unwrap()).unwrap();
    assert_eq!(stats.added, last);
    let again = merged.merge_from(&Store::open_read_only(&shards[0]).unwrap()).unwrap();
    assert_eq!((again.added, again.bytes), (0, 0), "merging is idempotent");
    drop(merged);
    assert!(contents(&merged_path) == contents(&single), "the merge equals the single-machine bake");
}

/// A merge refuses, naming both files, a key whose bytes differ; refuses artefacts of another
/// algorithm version or damaged ones; a read-only database refuses writes.
#[test]
fn merges_refuse_conflicting_foreign_and_damaged_artefacts() {
    use kage_bake_db::store::Info;
    let key = kage_bake_db::key::KeyHasher::new("test").u64("n", 1).finish();
    let info = |bytes: &[u8], algorithm: u32| Info {
        kind: "prt".into(),
        params: format!("order 3, 256 directions, algorithm {algorithm}"),
        seconds: 0.1,
        vertices: 1,
        checksum: *blake3::hash(bytes).as_bytes(),
    };
    let db = |name: &str, bytes: &[u8], algorithm: u32, checksum_of: &[u8]| {
        let path = scratch(name);
        let store = Store::open(&path).unwrap();
        let info = Info { checksum: *blake3::hash(checksum_of).as_bytes(), ..info(bytes, algorithm) };
        store.put_batch(&[(key, bytes.to_vec(), info)], &[]).unwrap();
        path
    };
    let v = prt::ALGORITHM_VERSION;
    let (a, b) = (db("merge-a", b"one", v, b"one"), db("merge-b", b"two", v, b"two"));
    let out = Store::open(&a).unwrap();
    let e = out.merge_from(&Store::open_read_only(&b).unwrap()).unwrap_err().to_string();
    assert!(e.contains("merge-a") && e.contains("merge-b") && e.contains("same bake key"), "{e}");
    let old = db("merge-old", b"two", v + 1, b"two");
    let e = out.merge_from(&Store::open_read_only(&old).unwrap()).unwrap_err().to_string();
    assert!(e.contains("merge-old") && e.contains(&format!("algorithm {}", v + 1)), "{e}");
    let damaged = db("merge-damaged", b"two", v, b"tw0");
    let e = out.merge_from(&Store::open_read_only(&damaged).unwrap()).unwrap_err().to_string();
    assert!(e.contains("merge-damaged") && e.contains("checksum"), "{e}");
    drop(out);
    assert_eq!(contents(&a).len(), 1, "nothing of a refused batch was merged");
    let ro = Store::open_read_only(&a).unwrap();
    let e = ro.put_meta("x", b"y").unwrap_err().to_string();
    assert!(e.contains("read-only"), "{e}");
    let e = Store::open_read_only(&scratch("merge-none")).err().unwrap().to_string();
    assert!(e.contains("no bake database"), "{e}");
    // A truncated shard is refused when opened, naming the file.
    let cut = scratch("merge-truncated");
    bake(&Store::open(&cut).unwrap(), &scene(""));
    let full = std::fs::read(&cut).unwrap();
    std::fs::write(&cut, &full[..full.len() / 2]).unwrap();
    match Store::open_read_only(&cut) {
        Err(e) => assert!(e.to_string().contains("merge-truncated"), "{e}"),
        // Whatever redb can still read must merge cleanly or be refused by its checksums.
        Ok(input) => {
            let out = Store::open(&scratch("merge-truncated-out")).unwrap();
            if let Err(e) = out.merge_from(&input) {
                assert!(e.to_string().contains("merge-truncated"), "{e}");
            }
        }
    }
}

/// Receiver refinement is kept in the memos, one entry per instance: read back, it is the
/// computed refinement byte for byte (the same refined meshes); a moved box re-refines only
/// the instances it can shadow; a damaged entry is refined again and replaced; a read-only
/// store reads but keeps nothing.
#[test]
fn a_kept_refinement_equals_the_computed_one_and_a_damaged_entry_is_refined_again() {
    use kage_bake_db::memo::refinement::refine;
    use kage_engine::receivers::{self, Settings};
    let path = scratch("refinement");
    let store = Store::open(&path).unwrap();
    let settings = Settings { budget: 800, ..Settings::default() };
    let hashes = |s: &Scene| {
        let flat = flatten(s);
        flat.instances.iter().map(|i| flat.meshes[i.mesh as usize].hash).collect::<Vec<_>>()
    };
    let entries = || store.memos().unwrap().into_iter().filter(|(n, _)| n.starts_with("receiver ")).collect::<Vec<_>>();
    let mut computed = scene("");
    let report = receivers::refine(&mut computed, &settings).unwrap();
    let n = report.len();
    assert!(report.iter().any(|(b, a)| a > b), "the scene is refined: {report:?}");
    let mut first = scene("");
    assert_eq!(refine(&store, &mut first, &settings, &|_| {}).unwrap(), (report.clone(), 0), "refined and kept");
    let mut again = scene("");
    assert_eq!(refine(&store, &mut again, &settings, &|_| {}).unwrap(), (report.clone(), n), "read back");
    assert!(hashes(&first) == hashes(&computed) && hashes(&again) == hashes(&computed));
    assert_eq!(entries().len(), n, "one entry per instance");
    // Refining a refined scene through the store reads the same entries.
    assert_eq!(refine(&store, &mut again, &settings, &|_| {}).unwrap().1, n, "a refined scene reads the same entries");
    assert_eq!(hashes(&again), hashes(&computed));

    let mut moved = scene("move");
    let read = refine(&store, &mut moved, &settings, &|_| {}).unwrap().1;
    assert!(read < n && entries().len() == 2 * n - read, "a moved box re-refines what it shadows: {read} of {n} read");

    let ground = receivers::keys(&scene(""), &settings)[0];
    let name = format!("receiver {}", &ground.to_hex()[..32]);
    let mut damaged = store.memo(&name).unwrap().unwrap();
    damaged[10] ^= 1;
    store.put_memos(&[(name.clone(), damaged.clone())]).unwrap();
    let mut a = scene("");
    assert_eq!(refine(&store, &mut a, &settings, &|_| {}).unwrap().1, n - 1, "the damaged entry is refined again");
    assert!(hashes(&a) == hashes(&computed), "and equals the computed one");
    assert!(store.memo(&name).unwrap().unwrap() != damaged, "and replaced");

    drop(store);
    let read_only = Store::open_read_only(&path).unwrap();
    let before = read_only.memos().unwrap().len();
    let mut c = scene("");
    c.pose_group(c.find_group("box b").unwrap(), Quat::IDENTITY, Vec3::new(0.2, 0.0, 0.0));
    assert!(refine(&read_only, &mut c, &settings, &|_| {}).unwrap().1 < n, "a new scene is refined");
    assert_eq!(read_only.memos().unwrap().len(), before, "a read-only store keeps nothing");
}

/// With refinement on, edits re-refine through the store what they shadow and re-bake warm,
/// and every result — refined meshes, keys and artefacts — is a cold bake's of the edited
/// scene: a box moved, an object added, one deleted, the light moved (no declared reach), and
/// with a declared reach the light moved inside it (nothing is refined or baked again) and the
/// box moved 1 m.
#[test]
fn edits_with_refinement_on_give_a_cold_bakes_bytes() {
    use kage_bake_db::memo::refinement::refine;
    use kage_engine::receivers::Settings;
    let settings = Settings { budget: 1500, ..Settings::default() };
    let reach = |mut s: Scene, lo: Vec3| {
        for light in s.world.query_mut::<&mut kage_engine::scene::PolygonLight>() {
            light.reach = Some([lo, lo + Vec3::new(4.0, 1.0, 4.0)]);
        }
        s
    };
    let light_by = |mut s: Scene, by: Vec3| {
        s.pose_group(s.find_group("light").unwrap(), Quat::IDENTITY, by);
        s
    };
    let boxed = Vec3::new(-2.0, 3.0, -2.0);
    let edits: Vec<(&str, Scene, Scene)> = vec![
        ("move", scene(""), scene("move")),
        ("add", scene(""), scene("add")),
        ("remove", scene(""), scene("remove")),
        ("light", scene(""), light_by(scene(""), Vec3::new(0.6, 0.0, 0.0))),
        ("within reach", reach(scene(""), boxed), light_by(reach(scene(""), boxed), Vec3::new(1.0, -0.3, 0.5))),
        ("reach moved 1 m", reach(scene(""), boxed), reach(scene(""), boxed + Vec3::X)),
    ];
    for (what, mut before, mut after) in edits {
        let store = Store::open(&scratch(&format!("edit-refined-{what}"))).unwrap();
        refine(&store, &mut before, &settings, &|_| {}).unwrap();
        bake(&store, &before);
        let fresh = Store::open(&scratch(&format!("edit-refined-{what}-cold"))).unwrap();
        let mut cold = after.duplicate();
        let (_, read) = refine(&store, &mut after, &settings, &|_| {}).unwrap();
        refine(&fresh, &mut cold, &settings, &|_| {}).unwrap();
        let keys = |store: &Store, s: &Scene| {
            let p = plan(store, s, &flatten(s), Some(BSPVT), Some(prt_settings())).unwrap();
            p.jobs.iter().map(|j| j.key).collect::<Vec<_>>()
        };
        let (warm_jobs, cold_jobs) = (keys(&store, &after), keys(&fresh, &cold));
        let (warm, bytes, _) = bake(&store, &after);
        let (_, cold_bytes, _) = bake(&fresh, &cold);
        assert!(warm_jobs == cold_jobs, "{what}: the keys differ from a cold bake's");
        assert!(bytes == cold_bytes, "{what}: the artefacts differ from a cold bake's");
        if what == "within reach" {
            assert_eq!(read, flatten(&after).instances.len(), "{what}: every refinement is kept");
            assert_eq!((warm.cold, warm.warm), (0, 0), "{what}: nothing re-bakes: {warm:?}");
        } else {
            assert!(warm.cached > 0, "{what}: something stays cached: {warm:?}");
        }
    }
}

/// A refined ground follows a moved box's shadow, and only there: its refinement is flat, so
/// it occludes as its source (no other receiver's key changes with it), its added vertices lie
/// in spatial order and its chunks are cut by content, so the chunks away from the box keep
/// their keys — PRT's stay cached, BSPVT's re-bake warm —, those near it keep their places —
/// BSPVT re-bakes warm the vertices they still hold — and the result is a cold bake's. A
/// chunk whose place is new re-bakes warm the vertices another chunk held, from the ground's
/// slot list; without it (damaged) they bake cold, with the same bytes.
#[test]
fn a_refined_receiver_rebakes_only_near_a_moved_shadow() {
    use kage_bake_db::memo::refinement::refine;
    use kage_engine::receivers::Settings;
    use kage_engine::scene::SourceMesh;
    // Five rounds end refinement before the budget does (3.3K of 8.4K vertices): a binding
    // budget couples every place (`docs/receivers.md#edits`).
    let settings = Settings { budget: 8000, rounds: 5, ..Settings::default() };
    let refined = |by: f32| {
        let mut s = scene("");
        let g = s.find_group("box a").unwrap();
        s.pose_group(g, Quat::IDENTITY, Vec3::new(by, 0.0, 0.0));
        refine(&Store::open(&scratch(&format!("near-{by}-refine"))).unwrap(), &mut s, &settings, &|_| {}).unwrap();
        s
    };
    let (before, after) = (refined(0.0), refined(0.3));
    let ground = |s: &Scene| flatten(s).instances.iter().position(|i| i.id.node == 0).unwrap();
    let refined_instances = after.world.query::<&SourceMesh>().iter().count();
    assert!(refined_instances >= 1, "the ground is refined, and occludes as its source");
    let [store, unlisted] = ["near", "near-unlisted"].map(|n| Store::open(&scratch(n)).unwrap());
    bake(&store, &before);
    bake(&unlisted, &before);
    let flat = flatten(&after);
    let p = plan(&store, &after, &flat, Some(BSPVT), Some(prt_settings())).unwrap();
    let g = ground(&after);
    let count = |kind: Kind, keep: &dyn Fn(&kage_bake_db::plan::Job) -> bool| {
        p.jobs.iter().filter(|j| j.kind == kind && j.instance == g && keep(j)).count()
    };
    let chunks = count(Kind::Prt, &|_| true);
    let prt_kept = count(Kind::Prt, &|j| j.cached);
    let with_lineage = count(Kind::Bspvt, &|j| store.lineage(&j.slot.unwrap()).unwrap().is_some());
    assert!(chunks >= 8, "the refined ground has {chunks} chunks");
    // Measured: 9 of 12.
    assert!(2 * prt_kept >= chunks, "PRT: {prt_kept} of {chunks} ground chunks kept");
    assert!(2 * with_lineage >= chunks, "BSPVT: {with_lineage} of {chunks} ground chunks have lineage");
    assert!(prt_kept < chunks, "the ground's vertices changed near the box");
    // Measured: 8 of 9. A chunk whose vertices changed keeps its place, so its lineage: the
    // vertices it still holds re-bake warm.
    assert!(
        with_lineage > prt_kept,
        "BSPVT: {with_lineage} ground chunks have lineage, {prt_kept} kept their vertices"
    );
    let list = p.slot_lists[g].unwrap();
    assert!(store.lineage(&list).unwrap().is_some(), "the ground's slots are listed");
    unlisted.put_batch(&[], &[(list, b"kgs1 damaged".to_vec())]).unwrap();
    let (warm, bytes, _) = bake(&store, &after);
    let (without, unlisted_bytes, _) = bake(&unlisted, &after);
    let (_, cold_bytes, _) = bake(&Store::open(&scratch("near-fresh")).unwrap(), &after);
    assert!(bytes == cold_bytes && unlisted_bytes == cold_bytes, "a warm re-bake must give a cold bake's bytes");
    assert!(warm.warm >= with_lineage, "{warm:?}");
    // Measured: 42 % fewer rays (392K against 679K).
    assert!(5 * warm.rays_cast < 4 * without.rays_cast, "{warm:?} vs {without:?}");
}

/// A curved receiver refined again (here for a moved light, its refinement alone swapped in)
/// occludes as its source: nothing it casts changed, so every other receiver's BSPVT chunk
/// keeps its key, and the re-bake gives a cold bake's bytes.
#[test]
fn a_re_refined_curved_occluder_changes_no_other_receivers_shadows() {
    use kage_bake_db::memo::refinement::refine;
    use kage_engine::receivers::Settings;
    use kage_engine::scene::PrimitiveId;
    let settings = Settings { budget: 2000, ..Settings::default() };
    let refined = |by: f32| {
        let mut s = scene("add");
        // A block between the light and the sphere: its shadow on the sphere moves with the
        // light, and the sphere's refinement with it.
        let shade = Affine3A::from_translation(Vec3::new(0.0, 1.2, 1.48));
        s.add_object("shade", shapes::cuboid(Vec3::splat(0.08)), Material::lambertian(Vec3::ONE), shade);
        let light = s.find_group("light").unwrap();
        s.pose_group(light, Quat::IDENTITY, Vec3::new(by, 0.0, 0.0));
        refine(&Store::open(&scratch(&format!("curved-{by}-refine"))).unwrap(), &mut s, &settings, &|_| {}).unwrap();
        s
    };
    let sphere_at = |s: &Scene| flatten(s).instances.iter().position(|i| i.id.node == 3).unwrap();
    let sphere = |s: &Scene| {
        let flat = flatten(s);
        let inst = &flat.instances[sphere_at(s)];
        assert!(inst.mesh != inst.source && inst.occluder == inst.source, "the sphere occludes as its source");
        flat.mesh(sphere_at(s)).clone()
    };
    let before = refined(0.0);
    let mut after = before.duplicate();
    let moved = sphere(&refined(0.3));
    assert_ne!(sphere(&before).hash, moved.hash, "the moved light re-refines the sphere");
    let e = after.world.query::<(hecs::Entity, &PrimitiveId)>().iter().find(|(_, id)| id.node == 3).unwrap().0;
    after.set_refined_mesh(e, moved);
    let store = Store::open(&scratch("curved")).unwrap();
    bake(&store, &before);
    let others = |s: &Scene| {
        let p = plan(&store, s, &flatten(s), Some(BSPVT), None).unwrap();
        p.jobs.iter().filter(|j| j.instance != sphere_at(s)).map(|j| j.key).collect::<Vec<_>>()
    };
    assert_eq!(others(&before), others(&after), "no other receiver's chunk changes");
    let (_, bytes, _) = bake(&store, &after);
    let (_, cold_bytes, _) = bake(&Store::open(&scratch("curved-fresh")).unwrap(), &after);
    assert!(bytes == cold_bytes, "a warm re-bake must give a cold bake's bytes");
}
