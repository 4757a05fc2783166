//! `kage edit`: opens the scene editor (`kage-editor`) on a scene.

use crate::db_args::DbArgs;
use crate::scene_args::SceneArgs;
use anyhow::Result;
use kage_editor::state;
use kage_engine::{bspvt, prt};
use std::path::PathBuf;

/// Arguments of `kage edit`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    db: DbArgs,
    /// Folder of WGSL shaders to load and hot-reload (default: `shaders/` in the working
    /// folder when it exists, else the shaders built into kage).
    #[arg(long)]
    shaders: Option<PathBuf>,
    /// BSPVT cube-face resolution.
    #[arg(long, default_value_t = 64)]
    face_res: usize,
    /// BSPVT split threshold ε.
    #[arg(long, default_value_t = 2.0)]
    epsilon: f64,
    /// Do not start baking when the editor opens.
    #[arg(long)]
    no_bake: bool,
    /// Start without the indirect term (the baked look's one bounce from the radiance cache;
    /// the view's "Indirect light" toggle turns it on).
    #[arg(long)]
    no_indirect: bool,
    /// Where polygonal lights shade: auto (the GPU unless it is a CPU emulation), gpu (per
    /// pixel in the viewport), cpu (per vertex).
    #[arg(long, default_value = "auto", value_parser = crate::named_arg::named::<state::ShadeOn>())]
    shade_on: state::ShadeOn,
    /// Scenes with more receiver vertices than this re-shade on the CPU in the background,
    /// keeping the last shading on screen meanwhile (the UI stays responsive on large levels).
    #[arg(long, value_name = "VERTICES", default_value_t = 200_000)]
    background_shading: usize,
    /// Window size as WxH.
    #[arg(long, default_value = "1280x800", value_parser = super::render::parse_size)]
    size: (usize, usize),
}

impl Args {
    /// The editor's options from the command line.
    pub fn options(&self) -> Result<state::Options> {
        let shader_dir = self.shaders.clone().or_else(|| Some(PathBuf::from("shaders")).filter(|d| d.is_dir()));
        if let Some(d) = &shader_dir {
            anyhow::ensure!(d.is_dir(), "{}: no such shader folder", d.display());
        }
        let bspvt = bspvt::Settings { res: self.face_res, epsilon: self.epsilon };
        bspvt.check().map_err(|e| anyhow::anyhow!("--face-res/--epsilon: {e}"))?;
        Ok(state::Options {
            scene_path: self.scene.scene.clone(),
            env_path: self.scene.env.clone(),
            import: self.scene.import_options(),
            shader_dir,
            db_path: self.db.path(&self.scene),
            bspvt,
            prt: prt::Settings::default(),
            cache: Default::default(),
            prt_budget: Some(crate::prt_args::DEFAULT_BUDGET),
            refine: self.scene.receiver_settings()?,
            bake_on_start: !self.no_bake,
            indirect: !self.no_indirect,
            shade_on: self.shade_on,
            background_shading: self.background_shading,
            preview_spacing: kage_editor::state::PREVIEW_SPACING,
        })
    }
}

/// Opens the editor window.
pub fn run(args: &Args) -> Result<()> {
    kage_editor::run(args.scene.load_unrefined()?, args.options()?, args.size)
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Edit {
        #[command(flatten)]
        args: Args,
    }

    /// The editor opens on the baked look with its bounce, unless told otherwise.
    #[test]
    fn the_editor_starts_with_the_indirect_term() {
        let options = |argv: &[&str]| Edit::try_parse_from(argv).unwrap().args.options().unwrap();
        assert!(options(&["edit"]).indirect);
        assert!(!options(&["edit", "--no-indirect"]).indirect);
    }
}
