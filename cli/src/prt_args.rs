//! PRT options shared by `render` and `report`: explicit parameters, or a plan from an error
//! budget (the default).

use kage_engine::prt::{self, lighting::Window};
use kage_engine::scene::{FlatScene, Scene};

/// PRT parameters; without --sh-order, --regions and --sh-window they come from the plan.
#[derive(clap::Args, Debug, Clone)]
pub struct PrtArgs {
    /// SH order n (n² coefficients per vertex); default: chosen from the error budget.
    #[arg(long, value_parser = within(prt::ORDERS))]
    pub sh_order: Option<u32>,
    /// Environment regions for shadows between groups; default: chosen from the error budget.
    #[arg(long, value_parser = within(prt::REGION_COUNTS))]
    pub regions: Option<u32>,
    /// Window against SH ringing; default: chosen from the error budget.
    #[arg(long, value_parser = crate::named_arg::named::<Window>())]
    pub sh_window: Option<Window>,
    /// Transfer directions per vertex (stratified; rounded down to a square).
    #[arg(long, default_value_t = 1024, value_parser = within(prt::DIRECTION_COUNTS))]
    pub directions: u32,
}

/// A parser for a count within `r`.
fn within(r: std::ops::RangeInclusive<usize>) -> clap::builder::RangedU64ValueParser<u32> {
    clap::builder::RangedU64ValueParser::new().range(*r.start() as u64..=*r.end() as u64)
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
            window: self.sh_window.unwrap_or(base.window),
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

    /// [`PrtArgs::settings`], with the choices kept in the bake database
    /// ([`kage_bake_db::prt_budget`]), so that a cached scene plans fast and every command bakes
    /// with the same parameters.
    pub fn settings_cached(
        &self,
        store: &kage_bake_db::Store,
        scene: &Scene,
        flat: &FlatScene,
        budget: Option<f64>,
    ) -> anyhow::Result<prt::Settings> {
        if let Some(s) = self.explicit() {
            return Ok(s);
        }
        let budget = budget.unwrap_or(DEFAULT_BUDGET);
        let note = &mut |line: String| crate::emit(&format!("plan: {line}\n"));
        Ok(kage_bake_db::prt_budget::choose(store, scene, flat, budget, &self.base(), note)?)
    }

    /// The settings given on the command line, else the parameter plan `base` records (an error
    /// naming what to run when it has none).
    pub fn settings_recorded(
        &self,
        base: Option<&kage_bake_db::Store>,
        scene: &Scene,
        flat: &FlatScene,
        budget: Option<f64>,
    ) -> anyhow::Result<prt::Settings> {
        if let Some(s) = self.explicit() {
            return Ok(s);
        }
        let budget = budget.unwrap_or(DEFAULT_BUDGET);
        let recorded = match base {
            Some(b) => kage_bake_db::prt_budget::recorded(b, scene, flat, budget, &self.base())?,
            None => None,
        };
        recorded.ok_or_else(|| {
            let at = base.map_or("BASE.redb".into(), |b| b.path().display().to_string());
            anyhow::anyhow!(
                "the scene has an environment and {at} holds no PRT parameter plan for it: run `kage bake SCENE --db {at} --dry-run` once before the shards and pass --base {at} to each (or give --sh-order, --regions and --sh-window)"
            )
        })
    }
}
