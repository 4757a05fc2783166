//! # kage-editor
//!
//! The scene editor behind `kage edit`: a live preview of the baked shadows (egui + wgpu) over
//! the same hecs world the CLI uses. Nothing here blocks the UI thread on long work: bakes,
//! references and exact visibility run in the background and stream their results in.
//!
//! - [`document`]: the scene's ECS world, selection, history and saved baseline, and the edits
//!   (no GPU); [`state`]: the editor around it (view, bakes, results, GPU, workers);
//! - [`systems`]: the per-frame schedule — hot reload, poses, environment, bakes, reference,
//!   shading — plain functions over the state, none of which blocks on long work;
//! - [`bake_job`]: BSPVT and PRT bakes in parallel in the background, through the database;
//! - [`ui`]: the egui panels, showing `kage_gpu::viewport`'s preview (which also draws
//!   `kage render --gpu`, and watches files: `kage_gpu::reload`); [`files`]: save and export;
//!   [`history`]: undo and redo records.
//!
//! One style for operations: what a user does to the scene or its files (edits, undo, save,
//! export, add, delete) is a method of [`state::Editor`]; the per-frame schedule is free
//! functions over it in [`systems`]; panels are free functions taking the `egui::Ui`.

pub mod bake_job;
pub mod document;
pub mod entities;
pub mod files;
pub mod gizmo;
pub mod history;
mod indirect;
pub mod interaction;
pub mod pick;
pub mod source;
pub mod state;
pub mod systems;
pub mod ui;
mod worker;

use anyhow::{Context, Result};
use eframe::egui_wgpu::{WgpuConfiguration, WgpuSetup, WgpuSetupCreateNew};
use kage_engine::scene::Scene;
use std::sync::Arc;

/// `setup` asking for the device limits kage's shaders need ([`kage_gpu::Gpu::descriptor`];
/// egui's default asks a GL adapter for WebGL 2 limits, which bind no storage buffers).
pub fn with_kage_limits(setup: WgpuSetupCreateNew) -> WgpuSetup {
    WgpuSetup::CreateNew(WgpuSetupCreateNew { device_descriptor: Arc::new(kage_gpu::Gpu::descriptor), ..setup })
}

/// Opens the editor window (eframe with the wgpu renderer) of `size` pixels on `scene`.
pub fn run(scene: Scene, options: state::Options, size: (usize, usize)) -> Result<()> {
    let native = eframe::NativeOptions {
        renderer: eframe::Renderer::Wgpu,
        viewport: eframe::egui::ViewportBuilder::default()
            .with_inner_size([size.0 as f32, size.1 as f32])
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
