//! The indirect term in the background: one bounce from the HSH radiance cache, lit by the
//! view's direct result — refreshed from the last cache when only the lighting changed over the
//! same receivers, else loaded from the bake database or gathered — off the UI thread. Knows
//! nothing of the editor's state: [`super::systems`] starts jobs and takes in what lands.

use glam::Vec3;
use kage_bake_db::Key;
use kage_bake_db::memo::records::{self, load_or_place_unless, store_refreshed};
use kage_engine::bspvt;
use kage_engine::cache::{
    self,
    record::{Glossy, GlossyDirect, Source},
};
use kage_engine::prt::{self, prefilter::Prefiltered};
use kage_engine::reference::Renderer;
use kage_engine::scene::{FlatScene, Scene, VertexValues};
use kage_engine::shading::baked::{Bakes, Look};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// A landed indirect term.
pub struct Indirect {
    /// Per instance and vertex.
    pub values: VertexValues,
    /// Per instance and vertex: the light the bounces bring (irradiance over π, what an
    /// exported pack carries); `None` for a refresh's intermediate landing.
    pub light: Option<VertexValues>,
    /// For the log.
    pub what: String,
    /// The cache and what lit it; `None` for a refresh's intermediate landing.
    pub base: Option<Box<IndirectBase>>,
}

/// A radiance cache with the inputs it was lit by: a later lighting change over the same
/// receivers refreshes it ([`cache::Cache::refresh`]) instead of gathering again.
pub struct IndirectBase {
    cache: cache::Cache,
    settings: cache::Settings,
    direct: VertexValues,
    lights: Vec<kage_engine::scene::FlatLight>,
    receivers: Vec<(u32, glam::Affine3A, bool)>,
    /// The key of its records ([`records::key`]): everything they depend on.
    key: Key,
}

impl IndirectBase {
    /// The base when `renderer`'s receivers and `settings` are those it was made for.
    fn fits(self: Box<Self>, renderer: &Renderer, settings: &cache::Settings) -> Option<Box<Self>> {
        (self.settings == *settings && self.receivers == receivers(renderer, settings)).then_some(self)
    }
}

/// What a cache's record placement depends on besides lighting: each receiver's mesh, pose and
/// whether it reads the cache (a glossy receiver made rough would have no records).
fn receivers(renderer: &Renderer, s: &cache::Settings) -> Vec<(u32, glam::Affine3A, bool)> {
    let instances = renderer.flat.instances.iter().enumerate();
    instances.map(|(k, i)| (i.mesh, i.world, cache::falls_back(renderer, s, k))).collect()
}
/// How gather rays' glossy hits are lit: as the view's method lit the direct result.
pub enum HitLight {
    /// As one of the engine's methods offers.
    Method(GlossyDirect),
    /// As the baked look lights them, the environment's diffuse, reflection and sun included
    /// ([`Look::toward`]): what `kage render` does, so the two store the same records.
    Baked(Box<BakedParts>),
}

/// What the baked look is shaded from, owned by the worker.
pub struct BakedParts {
    /// BSPVT trees (unshadowed placeholders while they bake), where the scene has polygonal lights.
    pub bspvt: Option<Arc<bspvt::Bake>>,
    /// PRT transfer, its lighting and settings.
    pub prt: (prt::Bake, prt::Lighting, prt::Settings),
    /// The environment prefiltered for its reflection.
    pub prefiltered: Prefiltered,
}

impl HitLight {
    /// Runs `f` with the [`Glossy`] this stands for in `scene` (snapshot `flat`) seen from `eye`.
    fn with<R>(&self, scene: &Scene, flat: &FlatScene, eye: Vec3, f: impl FnOnce(Glossy) -> R) -> R {
        match self {
            Self::Method(direct) => direct.with(flat, f),
            Self::Baked(b) => {
                let (bake, lighting, settings) = &b.prt;
                let bakes = Bakes {
                    bspvt: b.bspvt.as_deref(),
                    prt: Some(prt::Parts { bake, lighting, settings }),
                    prefiltered: Some(&b.prefiltered),
                };
                let look = Look::prepare(scene, flat, bakes, eye, &mut prt::SilhouetteMemo::default());
                f(Glossy::Toward(&|i, corners, bary, to| look.toward(i, corners, bary, to)))
            }
        }
    }
}

/// Records re-lit per landing of a progressive refresh.
const REFRESH_BATCH: usize = 64;

/// One background indirect computation and what it needs.
pub struct Job {
    /// The scene lit as the view's method lights it.
    pub scene: Scene,
    /// How glossy gather hits are lit, as the direct result was.
    pub glossy: HitLight,
    /// The direct result per instance and vertex.
    pub direct: VertexValues,
    /// Where the view looks from.
    pub eye: Vec3,
    /// The cache's parameters.
    pub settings: cache::Settings,
    /// Where records are loaded from and stored.
    pub store: Option<Arc<kage_bake_db::Store>>,
    /// The last cache, refreshed instead of gathered again when it fits.
    pub base: Option<Box<IndirectBase>>,
}

impl Job {
    /// Refreshes the base cache when it fits (sending each batch's landing, storing the result),
    /// else loads or gathers one; sends the final term with its base. Stops quietly when the
    /// worker is dropped (an edit outdated it) during a refresh, a gather or the bounces: what
    /// it made is discarded, and its rays no longer take the cores the next bake needs.
    pub fn run(self, stop: &AtomicBool, send: &dyn Fn(Indirect)) {
        let start = Instant::now();
        let Self { scene, glossy, direct, eye, settings: s, store, base } = self;
        let renderer = Renderer::new(&scene);
        let stopped = &|| stop.load(Ordering::Relaxed);
        let landed = glossy.with(&scene, &renderer.flat, eye, |glossy| {
            let src = Source { renderer: &renderer, direct: &direct, glossy };
            let gather = || cache::place_at_vertices_unless(&src, &s, stopped);
            let key = records::key(&src, &s);
            let base = base.and_then(|b| b.fits(&renderer, &s));
            // Stored under this lighting, loading costs less than a refresh, which would also
            // gather anew every record the base loaded without its hits. (A store that cannot
            // be read is reported when the refresh is stored.)
            let stored = base
                .as_ref()
                .filter(|b| b.key != key)
                .and_then(|_| store.as_deref().and_then(|st| records::load(st, &scene, &src, &s, &key).ok().flatten()));
            let (cache, note) = match (base, stored) {
                // A re-shade that gave the same direct light (a bake landing, a method switched
                // back): the records are those a refresh would make, and it would gather again
                // every record loaded without its hits.
                (Some(b), _) if b.key == key => (b.cache, "unchanged".to_string()),
                (Some(_), Some(cache)) => (cache, "from the bake database".to_string()),
                (Some(b), None) => {
                    let partial = |c: &cache::Cache| {
                        let values = cache::shade_vertices(&src, c, eye);
                        send(Indirect { values, light: None, what: String::new(), base: None })
                    };
                    let (cache, note) = refreshed(*b, &src, stop, &partial)?;
                    let stored = match store
                        .as_deref()
                        .map(|st| store_refreshed(st, &scene, &src, &key, &cache, start.elapsed().as_secs_f64()))
                    {
                        Some(Ok(_)) => ", stored".to_string(),
                        Some(Err(e)) => format!(" (not stored: {e})"),
                        None => String::new(),
                    };
                    (cache, format!("{note}{stored}"))
                }
                (None, _) => match store.as_deref().map(|st| load_or_place_unless(st, &scene, &src, &s, stopped)) {
                    Some(Ok(placed)) => {
                        let (cache, stored) = placed?;
                        (cache, if stored { "from the bake database" } else { "gathered" }.to_string())
                    }
                    Some(Err(e)) => (gather()?, format!("gathered (not stored: {e})")),
                    None => (gather()?, "gathered".to_string()),
                },
            };
            let (values, light, bounced) =
                cache::bounce_with_light(&src, &cache, (eye, cache::Bounces::default()), stopped)?;
            Some((cache, format!("{note}, {bounced}"), values, light, key))
        });
        let Some((cache, note, values, light, key)) = landed else { return };
        let what = format!("{} records {note}, {:.2} s", cache.records.len(), start.elapsed().as_secs_f64());
        let base = IndirectBase {
            cache,
            settings: s,
            direct,
            lights: renderer.flat.lights.clone(),
            receivers: receivers(&renderer, &s),
            key,
        };
        send(Indirect { values, light: Some(light), what, base: Some(Box::new(base)) });
    }
}

/// `base`'s cache re-lit for `src` (same receivers), batch by batch: only records that see
/// changed light; `partial` sees the cache after each batch but the last. `None` when `stop`
/// was set before the end.
fn refreshed(
    mut base: IndirectBase,
    src: &Source,
    stop: &AtomicBool,
    partial: &dyn Fn(&cache::Cache),
) -> Option<(cache::Cache, String)> {
    let moved = cache::moved_lights(&base.lights, &src.renderer.flat.lights);
    let change = cache::record::Change { old_direct: Some(&base.direct), moved: &moved };
    let done = base.cache.refresh_progressively(src, &change, REFRESH_BATCH, &mut |c, so_far| {
        if stop.load(Ordering::Relaxed) {
            return false;
        }
        if so_far.visited < c.records.len() {
            partial(c);
        }
        true
    });
    (done.visited == base.cache.records.len()).then(|| {
        let (relit, gathered, recast) = (done.relit, done.gathered, done.recast);
        let note = format!(
            "refreshed: {relit} re-lit, {gathered} gathered anew, {recast} of {} rays re-cast",
            base.cache.rays()
        );
        (base.cache, note)
    })
}
