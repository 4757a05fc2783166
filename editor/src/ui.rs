//! The editor window: menu, outliner, inspector, method switches, bake panel, statistics, log,
//! and the viewport. Each frame runs the systems first, then draws.

use super::state::{Editor, Selection};
use super::systems::run_frame;
use eframe::egui;
use glam::{Quat, Vec3};
use kage_engine::named::Named;
use kage_engine::scene::{EnvironmentLight, Material, PolygonLight, Transform};
use kage_engine::shading::Method;
use kage_gpu::viewport::Viewport;
use std::sync::atomic::Ordering;
use std::time::Instant;

/// The eframe application.
pub struct App {
    /// The editor's state (public for tests).
    pub editor: Editor,
    viewport: Option<Viewport>,
    /// The viewport's texture as egui knows it.
    texture: Option<egui::TextureId>,
    /// The revision of the editor's values the viewport holds.
    values_revision: Option<u64>,
    last_frame: Option<Instant>,
    /// The last pack or save written, for the status line.
    status: String,
    /// The gizmo drag in progress.
    drag: Option<super::gizmo::Drag>,
    /// Where the viewport was drawn in the last frame (tests aim the pointer with it).
    pub viewport_rect: Option<egui::Rect>,
    /// The Save As dialog's path, while it is open.
    save_as: Option<String>,
    /// The window was asked to close with edits unsaved: the prompt is open.
    closing: bool,
    /// The user chose to close without saving.
    discard: bool,
    /// The window title last sent (it marks unsaved edits).
    title: String,
}

impl App {
    /// Wraps `editor`, building the viewport on its GPU.
    pub fn new(mut editor: Editor) -> Self {
        let viewport = match Viewport::new(editor.gpu(), editor.shaders()) {
            Ok(v) if !v.per_pixel_prt() || !v.per_pixel_lights() => {
                let what =
                    if v.per_pixel_prt() { "the lights and reflections" } else { "PRT, the lights and reflections" };
                editor.info(format!("this device binds too few storage buffers per shader stage to draw {what} per pixel: the viewport interpolates them per vertex"));
                Some(v)
            }
            Ok(v) => Some(v),
            Err(e) => {
                editor.error(format!("preview shader: {e}"));
                None
            }
        };
        Self {
            editor,
            viewport,
            texture: None,
            values_revision: None,
            last_frame: None,
            status: String::new(),
            drag: None,
            viewport_rect: None,
            save_as: None,
            closing: false,
            discard: false,
            title: String::new(),
        }
    }

    /// Advances the systems and keeps the viewport's GPU data current.
    fn step(&mut self) {
        let now = Instant::now();
        if let Some(t) = self.last_frame.replace(now) {
            self.editor.stats.frame = (now - t).as_secs_f64();
        }
        let meshes = self.editor.dirty.meshes;
        run_frame(&mut self.editor);
        let ed = &mut self.editor;
        let Some(vp) = &mut self.viewport else { return };
        if vp.generation != ed.shader_generation
            && let Err(e) = vp.reload(ed.gpu(), ed.shaders(), ed.shader_generation)
        {
            ed.error(format!("preview shader: {e}"));
            ed.shader_error = Some(e);
        }
        let mut uploaded = false;
        if meshes || ed.dirty.meshes {
            vp.upload_geometry(ed.gpu(), &ed.flat);
            ed.dirty.meshes = false;
            uploaded = true;
        }
        if ed.dirty.per_pixel {
            vp.upload_prt(ed.gpu(), &ed.flat, ed.results.per_pixel.as_ref());
            vp.upload_lights(ed.gpu(), &ed.flat, ed.results.pixel_lights.as_ref());
            vp.upload_sun(ed.gpu(), &ed.flat, ed.results.vertex_sun.as_ref());
            ed.dirty.per_pixel = false;
            uploaded = true;
        }
        // The radiance buffers hold values less the per-pixel terms: new terms re-upload them.
        if uploaded || self.values_revision != Some(ed.results.values_revision) {
            vp.upload_radiance(ed.gpu(), &ed.results.values);
            self.values_revision = Some(ed.results.values_revision);
        }
        vp.set_environment(ed.gpu(), ed.flat.environment.as_ref());
    }
}

impl eframe::App for App {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        self.step();
        self.window(ui.ctx());
        // A gesture (one drag) ends when every button is up: it was one undo step, and the
        // re-bake it asks for starts then.
        self.editor.dragging = ui.input(|i| i.pointer.any_down());
        if !self.editor.dragging {
            self.editor.doc.history.seal();
        }
        menu(ui, self);
        egui::Panel::left("outliner").resizable(true).default_size(220.0).show(ui, |ui| outliner(ui, &mut self.editor));
        egui::Panel::right("inspector").resizable(true).default_size(280.0).show(ui, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| {
                methods(ui, &mut self.editor);
                ui.separator();
                inspector(ui, &mut self.editor);
                ui.separator();
                bake_panel(ui, &mut self.editor);
                ui.separator();
                statistics(ui, &self.editor);
            });
        });
        egui::Panel::bottom("log").resizable(true).default_size(120.0).show(ui, |ui| log(ui, &self.editor));
        egui::CentralPanel::default().show(ui, |ui| self.view(ui, frame));
        // After the viewport: a click and a key that arrive in one (slow) frame act in the order
        // the user gave them — the click selects, then Delete deletes.
        if shortcuts(ui, &mut self.editor) {
            self.status = self.editor.save();
        }
        let ed = &self.editor;
        if ed.due_next_frame() {
            ui.ctx().request_repaint();
        } else if ed.backend.job.is_some() || ed.dirty.shade || super::systems::gathering(ed) {
            ui.ctx().request_repaint_after(ed.progress_interval());
        }
    }
}

impl App {
    /// Frames the viewport has drawn (one per change to what it shows; 0 without a device).
    pub fn frames_drawn(&self) -> u64 {
        self.viewport.as_ref().map_or(0, Viewport::frames_drawn)
    }

    /// The window's title (a `*` marks unsaved edits), the prompt when it is closed with edits
    /// unsaved or the scene file changed under them, and the Save As dialog.
    fn window(&mut self, ctx: &egui::Context) {
        let unsaved = self.editor.unsaved();
        let title = format!("kage — {}{}", self.editor.doc.scene.source, if unsaved { " *" } else { "" });
        if title != self.title {
            ctx.send_viewport_cmd(egui::ViewportCommand::Title(title.clone()));
            self.title = title;
        }
        if ctx.input(|i| i.viewport().close_requested()) && unsaved && !self.discard {
            ctx.send_viewport_cmd(egui::ViewportCommand::CancelClose);
            self.closing = true;
        }
        if self.closing {
            self.close_prompt(ctx);
        }
        if self.editor.outside_change {
            egui::Modal::new(egui::Id::unique("outside change")).show(ctx, |ui| {
                ui.label("The scene file changed on disk, and your edits are not saved.");
                ui.horizontal(|ui| {
                    if ui.button("Reload it (drop my edits)").clicked() {
                        super::systems::reimport_scene(&mut self.editor);
                    }
                    if ui.button("Keep my edits").clicked() {
                        self.editor.outside_change = false;
                    }
                });
            });
        }
        if let Some(mut path) = self.save_as.take() {
            let mut open = true;
            egui::Modal::new(egui::Id::unique("save as")).show(ctx, |ui| {
                ui.label("Save the scene as");
                ui.text_edit_singleline(&mut path);
                ui.horizontal(|ui| {
                    if ui.button("Save").clicked() {
                        self.status = self.editor.save_as(std::path::Path::new(path.trim()));
                        open = false;
                    }
                    open &= !ui.button("Cancel").clicked();
                });
            });
            if open {
                self.save_as = Some(path);
            }
        }
    }

    fn close_prompt(&mut self, ctx: &egui::Context) {
        egui::Modal::new(egui::Id::unique("close")).show(ctx, |ui| {
            ui.label("Save your edits before closing?");
            ui.horizontal(|ui| {
                if ui.button("Save").clicked() {
                    self.status = self.editor.save();
                    self.closing = false;
                    if !self.editor.unsaved() {
                        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                    }
                }
                if ui.button("Close without saving").clicked() {
                    self.discard = true;
                    ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                }
                if ui.button("Cancel").clicked() {
                    self.closing = false;
                }
            });
        });
    }

    fn view(&mut self, ui: &mut egui::Ui, frame: &eframe::Frame) {
        if !self.status.is_empty() {
            ui.label(&self.status);
        }
        super::interaction::toolbar(ui, &mut self.editor);
        let size = ui.available_size();
        let (rect, response) = ui.allocate_exact_size(size, egui::Sense::click_and_drag());
        self.viewport_rect = Some(rect);
        super::interaction::handle(ui, &mut self.editor, rect, &response, &mut self.drag);
        let (Some(vp), Some(rs)) = (&mut self.viewport, frame.wgpu_render_state()) else {
            ui.painter().text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                "no preview",
                Default::default(),
                ui.visuals().text_color(),
            );
            return;
        };
        let ppp = ui.ctx().pixels_per_point();
        let px = [(rect.width() * ppp) as u32, (rect.height() * ppp) as u32];
        self.editor.view.aspect = rect.width() / rect.height().max(1.0);
        let ed = &self.editor;
        let shown = vp.paint(ed.gpu(), px, &ed.view.orbit, ed.view.exposure, ed.view.overlay);
        let id = match self.texture.filter(|_| !shown.new) {
            Some(id) => id,
            None => register(&mut rs.renderer.write(), ed.gpu(), shown.view, self.texture),
        };
        self.texture = Some(id);
        self.editor.stats.draw = vp.draw_seconds();
        let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
        ui.painter().image(id, rect, uv, egui::Color32::WHITE);
        super::interaction::paint(ui, &self.editor, rect, self.drag.as_ref());
    }
}

/// Gives egui the viewport's texture `view`: under the id it had (`old`), or a new one.
fn register(
    renderer: &mut eframe::egui_wgpu::Renderer,
    gpu: &kage_gpu::Gpu,
    view: &wgpu::TextureView,
    old: Option<egui::TextureId>,
) -> egui::TextureId {
    match old {
        Some(id) => {
            renderer.update_egui_texture_from_wgpu_texture(&gpu.device, view, wgpu::FilterMode::Linear, id);
            id
        }
        None => renderer.register_native_texture(&gpu.device, view, wgpu::FilterMode::Linear),
    }
}

fn menu(ui: &mut egui::Ui, app: &mut App) {
    egui::Panel::top("menu").show(ui, |ui| {
        egui::MenuBar::new().ui(ui, |ui| {
            ui.menu_button("File", |ui| {
                if ui.add(egui::Button::new("Save").shortcut_text("Ctrl+S")).clicked() {
                    app.status = app.editor.save();
                }
                if ui.button("Save As…").clicked() {
                    let current = app.editor.options.scene_path.as_ref().map(|p| p.display().to_string());
                    app.save_as = Some(current.unwrap_or_else(|| "scene.glb".into()));
                }
                if ui.button("Export pack").clicked() {
                    app.status = app.editor.export_pack();
                }
            });
            ui.menu_button("Edit", |ui| {
                let ed = &mut app.editor;
                if ui
                    .add_enabled(ed.doc.history.undo_len() > 0, egui::Button::new("Undo").shortcut_text("Ctrl+Z"))
                    .clicked()
                {
                    ed.undo();
                }
                let redo = egui::Button::new("Redo").shortcut_text("Ctrl+Shift+Z");
                if ui.add_enabled(ed.doc.history.redo_len() > 0, redo).clicked() {
                    ed.redo();
                }
                ui.separator();
                let editable = matches!(ed.doc.selection, Selection::Group(_) | Selection::Light(_));
                if ui.add_enabled(editable, egui::Button::new("Duplicate").shortcut_text("Ctrl+D")).clicked() {
                    ed.duplicate(ed.doc.selection);
                }
                if ui.add_enabled(editable, egui::Button::new("Delete").shortcut_text("Del")).clicked() {
                    ed.delete(ed.doc.selection);
                }
            });
            ui.menu_button("Add", |ui| {
                if ui.button("Quad light").clicked() {
                    app.editor.add_light(super::entities::Shape::Quad);
                }
                if ui.button("Disc light").clicked() {
                    app.editor.add_light(super::entities::Shape::Disc);
                }
                ui.label("Drop a .gltf or .glb on the viewport to add its meshes.");
            });
            ui.menu_button("View", |ui| {
                for k in 0..app.editor.cameras.len() {
                    if ui.button(format!("Scene camera {k}")).clicked() {
                        app.editor.use_camera(k);
                    }
                }
            });
        });
    });
}

/// Ctrl+Z undoes; Ctrl+Shift+Z and Ctrl+Y redo; Ctrl+D duplicates and Delete deletes the
/// selection; true when Ctrl+S asks to save.
fn shortcuts(ui: &egui::Ui, ed: &mut Editor) -> bool {
    use egui::{Key, KeyboardShortcut, Modifiers};
    let redo = [
        KeyboardShortcut::new(Modifiers::COMMAND | Modifiers::SHIFT, Key::Z),
        KeyboardShortcut::new(Modifiers::COMMAND, Key::Y),
    ];
    // The more specific shortcut first: Ctrl+Z also matches Ctrl+Shift+Z.
    if ui.ctx().input_mut(|i| redo.iter().any(|k| i.consume_shortcut(k))) {
        ed.redo();
    } else if ui.ctx().input_mut(|i| i.consume_shortcut(&KeyboardShortcut::new(Modifiers::COMMAND, Key::Z))) {
        ed.undo();
    }
    if ui.ctx().input_mut(|i| i.consume_shortcut(&KeyboardShortcut::new(Modifiers::COMMAND, Key::D))) {
        ed.duplicate(ed.doc.selection);
    }
    // Delete in a text field edits the text.
    if !ui.ctx().text_edit_focused() && ui.input(|i| i.key_pressed(Key::Delete)) {
        ed.delete(ed.doc.selection);
    }
    ui.ctx().input_mut(|i| i.consume_shortcut(&KeyboardShortcut::new(Modifiers::COMMAND, Key::S)))
}

fn outliner(ui: &mut egui::Ui, ed: &mut Editor) {
    ui.heading("Outliner");
    egui::ScrollArea::vertical().show(ui, |ui| {
        for (sel, label, depth) in ed.outline() {
            ui.horizontal(|ui| {
                ui.add_space(16.0 * depth as f32);
                let mut row = ui.selectable_label(ed.doc.selection == sel, label);
                if ed.view.hover == sel {
                    row = row.highlight();
                }
                if row.clicked() {
                    ed.doc.selection = sel;
                }
            });
        }
    });
}

fn methods(ui: &mut egui::Ui, ed: &mut Editor) {
    ui.heading("Method");
    let mut method = ed.view.method;
    ui.horizontal_wrapped(|ui| {
        for &m in Method::ALL {
            ui.selectable_value(&mut method, m, m.name());
        }
    });
    ed.set_method(method);
    let mut overlay = ed.view.overlay;
    ui.checkbox(&mut overlay, "Error overlay (vs progressive reference)");
    ed.set_overlay(overlay);
    let mut indirect = ed.indirect;
    ui.checkbox(&mut indirect, "Indirect light (HSH radiance cache)");
    ed.set_indirect(indirect);
    if super::systems::shading(ed) {
        ui.horizontal(|ui| {
            ui.spinner();
            ui.label("shading in the background");
        });
    }
    if ed.indirect && super::systems::gathering(ed) {
        ui.horizontal(|ui| {
            ui.spinner();
            ui.label("gathering indirect light");
        });
    }
    if ed.view.overlay || ed.view.method == Method::Reference {
        ui.label(format!("reference: {} samples per vertex", ed.results.reference.passes * 4));
    }
    ui.horizontal(|ui| {
        if ui.add(egui::Slider::new(&mut ed.view.exposure, -6.0..=6.0).text("exposure (stops)")).changed() {
            ed.view.metering = false; // the user's choice stands
        }
        if ui.button("meter").on_hover_text("meter the exposure from the current result").clicked() {
            super::systems::meter_exposure(ed);
        }
    });
}

fn vec3_drag(ui: &mut egui::Ui, label: &str, v: &mut Vec3, speed: f32) -> bool {
    ui.horizontal(|ui| {
        ui.label(label);
        let mut changed = false;
        for c in [&mut v.x, &mut v.y, &mut v.z] {
            changed |= ui.add(egui::DragValue::new(c).speed(speed)).changed();
        }
        changed
    })
    .inner
}

fn inspector(ui: &mut egui::Ui, ed: &mut Editor) {
    ui.heading("Inspector");
    match ed.doc.selection {
        Selection::None => {
            ui.label("Click a group or light in the viewport, or select anything in the outliner.");
        }
        Selection::Group(g) => group_inspector(ui, ed, g),
        Selection::Instance(e) => {
            material_inspector(ui, ed, e);
            mesh_inspector(ui, ed, e);
        }
        Selection::Light(e) => light_inspector(ui, ed, e),
        Selection::Environment => environment_inspector(ui, ed),
    }
}

fn group_inspector(ui: &mut egui::Ui, ed: &mut Editor, g: hecs::Entity) {
    let at = ed.doc.scene.world.get::<&Transform>(g).map(|t| Vec3::from(t.world.translation)).unwrap_or_default();
    let mut moved = at;
    let mut turn = 0.0f32;
    if vec3_drag(ui, "position", &mut moved, 0.02) {
        ed.move_group(g, moved - at, Quat::IDENTITY);
    }
    ui.horizontal(|ui| {
        ui.label("turn about Y (deg)");
        if ui.add(egui::DragValue::new(&mut turn).speed(1.0)).changed() && turn != 0.0 {
            ed.move_group(g, Vec3::ZERO, Quat::from_rotation_y(turn.to_radians()));
        }
    });
    ui.label("PRT shading follows at once; BSPVT re-bakes incrementally in the background.");
}

fn material_inspector(ui: &mut egui::Ui, ed: &mut Editor, e: hecs::Entity) {
    let Some(mut m) = ed.doc.scene.world.get::<&Material>(e).ok().map(|m| *m) else { return };
    let before = m;
    let mut rgb = m.base_color.to_array();
    ui.horizontal(|ui| {
        ui.label("base colour");
        ui.color_edit_button_rgb(&mut rgb);
    });
    m.base_color = Vec3::from_array(rgb);
    ui.add(egui::Slider::new(&mut m.roughness, 0.0..=1.0).text("roughness"));
    ui.add(egui::Slider::new(&mut m.metallic, 0.0..=1.0).text("metallic"));
    if m != before {
        ed.set_material(e, m);
    }
}

/// Geometry edit: the instance's mesh replaced by the first mesh of a glTF file.
fn mesh_inspector(ui: &mut egui::Ui, ed: &mut Editor, e: hecs::Entity) {
    ui.separator();
    let id = egui::Id::unique(("replace mesh", e));
    let mut path = ui.data_mut(|d| d.get_temp::<String>(id)).unwrap_or_default();
    ui.horizontal(|ui| {
        let label = ui.label("glTF file");
        ui.add(egui::TextEdit::singleline(&mut path).hint_text("path/to/mesh.glb")).labelled_by(label.id);
    });
    if ui.add_enabled(!path.trim().is_empty(), egui::Button::new("Replace mesh")).clicked() {
        ed.replace_mesh_from(e, std::path::Path::new(path.trim()));
    }
    ui.data_mut(|d| d.insert_temp(id, path));
}

fn light_inspector(ui: &mut egui::Ui, ed: &mut Editor, e: hecs::Entity) {
    let Some(light) = ed.doc.scene.world.get::<&PolygonLight>(e).ok().map(|l| (*l).clone()) else { return };
    let mut offset = Vec3::ZERO;
    if vec3_drag(ui, "move by", &mut offset, 0.02) && offset != Vec3::ZERO {
        ed.move_light(e, offset, Quat::IDENTITY);
    }
    let mut tilt = 0.0f32;
    ui.horizontal(|ui| {
        ui.label("tilt about X (deg)");
        if ui.add(egui::DragValue::new(&mut tilt).speed(1.0)).changed() && tilt != 0.0 {
            ed.move_light(e, Vec3::ZERO, Quat::from_rotation_x(tilt.to_radians()));
        }
    });
    let mut radiance = light.radiance;
    let mut size = 1.0f32;
    let mut changed = vec3_drag(ui, "radiance", &mut radiance, 0.1);
    ui.horizontal(|ui| {
        ui.label("size ×");
        changed |= ui.add(egui::DragValue::new(&mut size).speed(0.01).range(0.5..=2.0)).changed();
    });
    if changed {
        ed.set_light(e, radiance.max(Vec3::ZERO), size);
    }
    match light.reach {
        Some([lo, hi]) => ui.label(format!("Moves, turns and resizes with no re-bake inside its reach {lo} … {hi}.")),
        None => ui.label("Lights move, turn and resize with no re-bake."),
    };
}

fn environment_inspector(ui: &mut egui::Ui, ed: &mut Editor) {
    let Some(env) = ed.doc.scene.world.query::<&EnvironmentLight>().iter().next().cloned() else { return };
    let (mut intensity, mut degrees) = (env.intensity, env.rotation.to_degrees());
    let a = ui.add(egui::Slider::new(&mut intensity, 0.0..=10.0).text("intensity")).changed();
    let b = ui.add(egui::Slider::new(&mut degrees, -180.0..=180.0).text("rotation (deg)")).changed();
    if a || b {
        ed.set_environment(intensity, degrees.to_radians());
    }
}

fn bake_panel(ui: &mut egui::Ui, ed: &mut Editor) {
    ui.heading("Bake");
    receivers(ui, ed);
    if let Some(job) = &ed.backend.job {
        for (name, t) in [("BSPVT", &job.bspvt), ("PRT", &job.prt)] {
            let Some(t) = t else { continue };
            let done = t.done.load(Ordering::Relaxed);
            let fraction = if t.total == 0 { 1.0 } else { done as f32 / t.total as f32 };
            let secs = job.started.elapsed().as_secs_f64();
            let eta = if done > 0 && t.running {
                format!(", ETA {:.0} s", secs * (t.total - done.min(t.total)) as f64 / done as f64)
            } else {
                String::new()
            };
            ui.label(format!("{name}: {} chunks cached, {done} / {} vertices{eta}", t.cached, t.total));
            ui.add(egui::ProgressBar::new(fraction).show_percentage());
        }
        ui.label(format!("preview updated {} times as chunks landed", ed.bakes.streamed));
        if ui.button("Cancel bake").clicked() {
            ed.cancel_bake();
        }
    } else {
        let bspvt = match (&ed.bakes.bspvt, ed.bakes.bspvt_stale) {
            _ if ed.flat.lights.is_empty() => "no polygonal light",
            (Some(_), false) => "baked",
            (Some(_), true) => "stale",
            (None, _) => "not baked",
        };
        let prt = match &ed.bakes.prt {
            _ if ed.flat.environment.is_none() => "no environment",
            Some(_) => "baked",
            None => "not baked",
        };
        ui.label(format!("BSPVT {bspvt}; PRT {prt}"));
        if ui.button("Bake").clicked() {
            ed.bake_now();
        }
    }
}

/// What receiver refinement did, and a way to redo it after lights moved.
fn receivers(ui: &mut egui::Ui, ed: &mut Editor) {
    let Some(r) = &ed.bakes.receivers else { return };
    let (before, after) = r.vertices;
    ui.label(format!("receivers refined: {before} to {after} vertices ({:.2} s)", r.seconds));
    if ed.refinement_stale() {
        ui.label("a light moved since: its shadows are as fine as the refinement where they fall");
        if ui.button("Refine again").clicked() {
            ed.refine_again();
        }
    }
}

fn statistics(ui: &mut egui::Ui, ed: &Editor) {
    ui.heading("Statistics");
    let s = ed.stats;
    ui.label(format!("frame {:.1} ms, shading {:.1} ms", 1e3 * s.frame, 1e3 * s.shading));
    ui.label(format!("edit to shaded frame {:.1} ms", 1e3 * s.edit_to_shade));
    ui.label(format!("bake: BSPVT {}, PRT {}", bake_rate(s.runs[0].as_ref()), bake_rate(s.runs[1].as_ref())));
    ui.label(format!("shader reload {:.1} ms", 1e3 * s.shader_reload));
    let verts: usize = ed.results.values.iter().map(Vec::len).sum();
    ui.label(format!("{verts} vertices, {} lights", ed.flat.lights.len()));
    if let Some(e) = &ed.shader_error {
        ui.colored_label(egui::Color32::LIGHT_RED, format!("shader error: {e}"));
    }
}

/// A technique's last bake rate, or why there is none.
fn bake_rate(run: Option<&kage_bake_db::RunStats>) -> String {
    match run {
        Some(r) if r.vertices_baked > 0 => format!("{:.0} vertices/s", r.vertices_baked as f64 / r.seconds.max(1e-9)),
        Some(_) => "all cached".into(),
        None => "—".into(),
    }
}

fn log(ui: &mut egui::Ui, ed: &Editor) {
    egui::ScrollArea::vertical().stick_to_bottom(true).show(ui, |ui| {
        for line in &ed.log {
            let text = format!("{:8.2} s  {}", line.at, line.text);
            if line.error {
                ui.colored_label(egui::Color32::LIGHT_RED, text);
            } else {
                ui.label(text);
            }
        }
    });
}
