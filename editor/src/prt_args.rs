//! PRT options shared by `render` and `report`: explicit parameters, or a plan from an error
//! budget (the default).

use kage_engine::prt::{self, lighting::Window};
use kage_engine::scene::{EnvironmentLight, FlatScene, Scene};

/// Window choices on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum WindowArg {
    /// No window.
    None,
    /// Hanning window.
    Hanning,
    /// Lanczos σ factors.
    Lanczos,
}

impl From<WindowArg> for Window {
    fn from(w: WindowArg) -> Self {
        match w {
            WindowArg::None => Window::None,
            WindowArg::Hanning => Window::Hanning,
            WindowArg::Lanczos => Window::Lanczos,
        }
    }
}

/// PRT parameters; without --sh-order, --regions and --sh-window they come from the plan.
#[derive(clap::Args, Debug, Clone)]
pub struct PrtArgs {
    /// SH order n (n² coefficients per vertex); default: chosen from the error budget.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=16))]
    pub sh_order: Option<u32>,
    /// Environment regions for shadows between groups; default: chosen from the error budget.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=256))]
    pub regions: Option<u32>,
    /// Window against SH ringing; default: chosen from the error budget.
    #[arg(long, value_enum)]
    pub sh_window: Option<WindowArg>,
    /// Transfer directions per vertex (stratified; rounded down to a square).
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(4..=65536))]
    pub directions: u32,
}

/// The budget PRT chooses its parameters with when none is given.
pub const DEFAULT_BUDGET: f64 = 0.02;

impl PrtArgs {
    fn base(&self) -> prt::Settings {
        prt::Settings { directions: self.directions as usize, ..prt::Settings::default() }
    }

    /// The settings given on the command line, if any PRT parameter was.
    fn explicit(&self) -> Option<prt::Settings> {
        let base = self.base();
        (self.sh_order.is_some() || self.regions.is_some() || self.sh_window.is_some()).then(|| prt::Settings {
            order: self.sh_order.map_or(base.order, |n| n as usize),
            regions: self.regions.map_or(base.regions, |q| q as usize),
            window: self.sh_window.map_or(base.window, Window::from),
            ..base
        })
    }

    /// The settings to bake and shade with, printing the plan when one is made.
    pub fn settings(&self, scene: &Scene, flat: &FlatScene, budget: Option<f64>) -> prt::Settings {
        if let Some(s) = self.explicit() {
            return s;
        }
        let (s, why) = prt::budget::choose(scene, flat, budget.unwrap_or(DEFAULT_BUDGET), &self.base());
        for line in why {
            crate::emit(&format!("plan: {line}\n"));
        }
        s
    }

    /// [`PrtArgs::settings`], with the plan's choices kept in the bake database so that planning
    /// a cached scene stays fast. The order and window are keyed on what they read, which no
    /// move of a group changes (a rotation plans them again, from the cached pilot); the region
    /// count also on where everything is, and after a move it is measured again with the
    /// transfer the database holds (a truncated bake at a lower order is that order's bake bit
    /// for bit), so a plan never depends on what was cached.
    pub fn settings_cached(
        &self,
        store: &kage_bake_db::Store,
        scene: &Scene,
        flat: &FlatScene,
        budget: Option<f64>,
    ) -> anyhow::Result<prt::Settings> {
        let (Some(env), None) = (&flat.environment, self.explicit()) else {
            return Ok(self.settings(scene, flat, budget));
        };
        let budget = budget.unwrap_or(DEFAULT_BUDGET);
        let (s, pilot) = self.cached_order(store, scene, flat, env, budget)?;
        let name = format!(
            "prt-regions/{}",
            plan_key(scene, flat, budget, self.directions, true)
                .u64("order", s.order as u64)
                .u64("window", window_index(s.window) as u64)
                .finish()
                .short()
        );
        if let Some(&[q]) = store.meta(&name)?.as_deref() {
            crate::emit(&format!("plan: {q} regions (cached plan)\n"));
            return Ok(prt::Settings { regions: q as usize, ..s });
        }
        let transfer = match pilot {
            Some(high) => high.truncated(s.order),
            None => stored_transfer(store, scene, flat, &s)?.unwrap_or_else(|| prt::bake(scene, flat, &s, &|_| {})),
        };
        let (s, why) = prt::budget::choose_regions(scene, flat, env, &transfer, budget, &s);
        crate::emit(&format!("plan: {why}\n"));
        store.put_meta(&name, &[s.regions as u8])?;
        Ok(s)
    }

    /// The planned order and window, from the database or measured (then also the pilot).
    fn cached_order(
        &self,
        store: &kage_bake_db::Store,
        scene: &Scene,
        flat: &FlatScene,
        env: &EnvironmentLight,
        budget: f64,
    ) -> anyhow::Result<(prt::Settings, Option<prt::Bake>)> {
        let name = format!("prt-order/{}", plan_key(scene, flat, budget, self.directions, false).finish().short());
        if let Some(&[order, w]) = store.meta(&name)?.as_deref()
            && let Some(&window) = WINDOWS.get(w as usize)
        {
            crate::emit(&format!("plan: SH order {order}, {window:?} window (cached plan)\n"));
            return Ok((prt::Settings { order: order as usize, window, ..self.base() }, None));
        }
        let high = kage_bake_db::pilot::pilot(store, scene, flat, &self.base())?;
        let (s, why) = prt::budget::choose_order(scene, flat, env, budget, &self.base(), &high);
        crate::emit(&format!("plan: {why}\n"));
        store.put_meta(&name, &[s.order as u8, window_index(s.window)])?;
        Ok((s, Some(high)))
    }
}

/// The windows, in the order the database stores them.
const WINDOWS: [Window; 3] = [Window::None, Window::Hanning, Window::Lanczos];

fn window_index(w: Window) -> u8 {
    WINDOWS.iter().position(|x| *x == w).unwrap_or(0) as u8
}

/// The PRT transfer for `s` when the database holds all of it.
fn stored_transfer(
    store: &kage_bake_db::Store,
    scene: &Scene,
    flat: &FlatScene,
    s: &prt::Settings,
) -> anyhow::Result<Option<prt::Bake>> {
    let plan = kage_bake_db::plan(store, scene, flat, None, Some(*s))?;
    Ok(kage_bake_db::load(store, scene, flat, &plan)?.and_then(|o| o.prt))
}

/// A key of everything the PRT budget reads: each instance's mesh, material, group and transform
/// within it, its orientation, and the environment; with `placed`, where each instance is too.
fn plan_key(
    scene: &Scene,
    flat: &FlatScene,
    budget: f64,
    directions: u32,
    placed: bool,
) -> kage_bake_db::key::KeyHasher {
    let mut h =
        kage_bake_db::key::KeyHasher::new("prt-plan").f64("budget", budget).u64("directions", directions as u64);
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
            .bytes("mesh", &scene.meshes[inst.mesh as usize].hash.0)
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
