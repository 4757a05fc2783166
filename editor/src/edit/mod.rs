//! `kage edit`: the scene editor with live preview.
//!
//! - [`state`]: the model (scene ECS world, view, bakes, results) and the edits;
//! - [`systems`]: the per-frame schedule — hot reload, poses, environment, bakes, reference,
//!   shading — plain functions over the state, none of which blocks on long work;
//! - [`bake_job`]: BSPVT and PRT bakes in parallel in the background, through the database;
//! - [`viewport`]: the wgpu preview; [`ui`]: the egui panels; [`reload`]: file watching;
//!   [`camera`]: the orbit camera; [`files`]: save and export.

pub mod bake_job;
pub mod camera;
pub mod files;
pub mod reload;
pub mod state;
pub mod systems;
pub mod ui;
pub mod viewport;
mod worker;

use crate::db_args::DbArgs;
use crate::scene_args::SceneArgs;
use anyhow::{Context, Result};
use eframe::egui_wgpu::{WgpuConfiguration, WgpuSetup, WgpuSetupCreateNew};
use kage_engine::{bspvt, prt};
use std::path::PathBuf;
use std::sync::Arc;

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
    /// Where polygonal lights shade: auto (the GPU unless it is a CPU emulation), gpu, cpu.
    #[arg(long, value_enum, default_value = "auto")]
    shade_on: state::ShadeOn,
    /// Window size as WxH.
    #[arg(long, default_value = "1280x800", value_parser = crate::commands::render::parse_size)]
    size: (usize, usize),
}

impl Args {
    /// The editor's options from the command line.
    pub fn options(&self) -> Result<state::Options> {
        let shader_dir = self.shaders.clone().or_else(|| Some(PathBuf::from("shaders")).filter(|d| d.is_dir()));
        if let Some(d) = &shader_dir {
            anyhow::ensure!(d.is_dir(), "{}: no such shader folder", d.display());
        }
        anyhow::ensure!((4..=1024).contains(&self.face_res), "--face-res must be in 4..=1024");
        Ok(state::Options {
            scene_path: self.scene.scene.clone(),
            env_path: self.scene.env.clone(),
            shader_dir,
            db_path: self.db.path(&self.scene),
            bspvt: bspvt::Settings { res: self.face_res, epsilon: self.epsilon },
            prt: prt::Settings::default(),
            cache: Default::default(),
            bake_on_start: !self.no_bake,
            shade_on: self.shade_on,
        })
    }
}

/// `setup` asking for the device limits kage's shaders need ([`kage_gpu::Gpu::descriptor`];
/// egui's default asks a GL adapter for WebGL 2 limits, which bind no storage buffers).
pub fn with_kage_limits(setup: WgpuSetupCreateNew) -> WgpuSetup {
    WgpuSetup::CreateNew(WgpuSetupCreateNew { device_descriptor: Arc::new(kage_gpu::Gpu::descriptor), ..setup })
}

/// Opens the editor window (eframe with the wgpu renderer).
pub fn run(args: &Args) -> Result<()> {
    let scene = args.scene.load()?;
    let options = args.options()?;
    let native = eframe::NativeOptions {
        renderer: eframe::Renderer::Wgpu,
        viewport: eframe::egui::ViewportBuilder::default()
            .with_inner_size([args.size.0 as f32, args.size.1 as f32])
            .with_title(format!("kage — {}", scene.source)),
        wgpu_options: WgpuConfiguration {
            wgpu_setup: with_kage_limits(WgpuSetupCreateNew::without_display_handle()),
            ..Default::default()
        },
        ..Default::default()
    };
    eframe::run_native(
        "kage",
        native,
        Box::new(move |cc| {
            let rs = cc.wgpu_render_state.as_ref().context("eframe started without its wgpu renderer")?;
            let gpu = kage_gpu::Gpu::from_parts(rs.device.clone(), rs.queue.clone(), rs.adapter.get_info());
            let ctx = cc.egui_ctx.clone();
            let editor = state::Editor::new(scene, options, gpu, Arc::new(move || ctx.request_repaint()));
            Ok(Box::new(ui::App::new(editor)))
        }),
    )
    .map_err(|e| anyhow::anyhow!("the editor window failed: {e}"))
}
