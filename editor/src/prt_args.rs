//! PRT options shared by `render` and `report`: explicit parameters, or a plan from an error
//! budget (the default).

use kage_engine::prt::{self, lighting::Window};
use kage_engine::scene::{FlatScene, Scene};

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

/// The budget PRT plans with when none is given.
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
    pub fn settings(&self, scene: &Scene, flat: &FlatScene, budget: Option<f64>, eye: glam::Vec3) -> prt::Settings {
        if let Some(s) = self.explicit() {
            return s;
        }
        let (s, why) = prt::plan::choose(scene, flat, budget.unwrap_or(DEFAULT_BUDGET), eye, &self.base());
        for line in why {
            crate::emit(&format!("plan: {line}\n"));
        }
        s
    }

    /// [`PrtArgs::settings`], with the plan's choice kept in the bake database under a key of
    /// everything it depends on (geometry, materials, environment, budget), so that planning a
    /// cached scene stays fast.
    pub fn settings_cached(
        &self,
        store: &kage_bake_db::Store,
        scene: &Scene,
        flat: &FlatScene,
        budget: Option<f64>,
        eye: glam::Vec3,
    ) -> anyhow::Result<prt::Settings> {
        if let Some(s) = self.explicit() {
            return Ok(s);
        }
        let budget = budget.unwrap_or(DEFAULT_BUDGET);
        let name = format!("prt-plan/{}", plan_key(scene, flat, budget, self.directions).short());
        let windows = [Window::None, Window::Hanning, Window::Lanczos];
        if let Some(v) = store.meta(&name)?
            && let [order, regions, w] = v[..]
            && let Some(&window) = windows.get(w as usize)
        {
            crate::emit(&format!("plan: SH order {order}, {regions} regions, {window:?} window (cached plan)\n"));
            return Ok(prt::Settings { order: order as usize, regions: regions as usize, window, ..self.base() });
        }
        let s = self.settings(scene, flat, Some(budget), eye);
        let w = windows.iter().position(|w| *w == s.window).unwrap_or(0) as u8;
        store.put_meta(&name, &[s.order as u8, s.regions as u8, w])?;
        Ok(s)
    }
}

/// A key of everything the PRT plan reads.
fn plan_key(scene: &Scene, flat: &FlatScene, budget: f64, directions: u32) -> kage_bake_db::Key {
    let mut h =
        kage_bake_db::key::KeyHasher::new("prt-plan").f64("budget", budget).u64("directions", directions as u64);
    for inst in &flat.instances {
        let m = inst.material;
        let material = [m.base_color.x, m.base_color.y, m.base_color.z, m.metallic, m.roughness, m.specular];
        h = h
            .bytes("mesh", &scene.meshes[inst.mesh as usize].hash.0)
            .affine("world", &inst.world)
            .bytes("material", bytemuck::cast_slice(&material));
    }
    if let Some(env) = &flat.environment {
        h = h
            .bytes("env", bytemuck::cast_slice(&env.map.texels))
            .u64("width", env.map.width as u64)
            .f64("intensity", env.intensity as f64)
            .f64("rotation", env.rotation as f64);
    }
    h.finish()
}
