//! The editor app under egui_kittest with its wgpu renderer (shared by the tests and the bench).

use eframe::egui;
use egui_kittest::Harness;
use kage_editor::state::{Editor, Options};
use kage_editor::ui::App;
use kage_engine::scene::Scene;
use std::sync::Arc;

/// The real app on `scene` in a 1280×800 window, on kittest's adapter (lavapipe without a GPU)
/// with the device limits `kage edit` asks for.
pub fn harness(scene: Scene, options: Options) -> Harness<'static, App> {
    let eframe::egui_wgpu::WgpuSetup::CreateNew(base) = egui_kittest::wgpu::default_wgpu_setup() else {
        unreachable!("kittest creates its own device")
    };
    Harness::builder()
        .with_size(egui::Vec2::new(1280.0, 800.0))
        .wgpu_setup(kage_editor::with_kage_limits(base))
        .build_eframe(move |cc| {
            let rs = cc.wgpu_render_state.as_ref().expect("kittest's wgpu renderer");
            let gpu = kage_gpu::Gpu::from_parts(rs.device.clone(), rs.queue.clone(), rs.adapter.get_info());
            App::new(Editor::new(scene, options, gpu, Arc::new(|| {})))
        })
}
