//! What the pointer and keys do in the viewport: a click picks, hovering highlights, dragging a
//! gizmo handle moves or turns the selection, dragging elsewhere orbits (secondary or middle:
//! pans), the wheel zooms, Escape clears the selection, W, E and R switch the gizmo between
//! moving, turning and scaling, a glTF file dropped on the window is added as a new group. Outlines and handles
//! are painted over the rendered image.

use super::gizmo::{Drag, Edit, Mode, Placement, Space, View};
use super::state::{Editor, Selection};
use eframe::egui;
use glam::{Affine3A, Quat, Vec2, Vec3};
use kage_engine::scene::{InGroup, Transform};

const HOVER: egui::Color32 = egui::Color32::from_rgb(220, 220, 220);
const SELECTED: egui::Color32 = egui::Color32::from_rgb(255, 160, 40);
const AXES: [egui::Color32; 3] =
    [egui::Color32::from_rgb(230, 60, 60), egui::Color32::from_rgb(80, 200, 80), egui::Color32::from_rgb(70, 120, 240)];
const ACTIVE: egui::Color32 = egui::Color32::from_rgb(255, 230, 0);

/// Handles the viewport's input for one frame; `rect` is the viewport on screen, `drag` the
/// gizmo drag in progress (kept by the caller between frames).
pub fn handle(ui: &egui::Ui, ed: &mut Editor, rect: egui::Rect, response: &egui::Response, drag: &mut Option<Drag>) {
    let to_view = |p: egui::Pos2| Vec2::new(p.x - rect.min.x, p.y - rect.min.y);
    let size = Vec2::new(rect.width(), rect.height());
    let orbit = ed.view.orbit;
    let view = View { orbit: &orbit, size };
    keys(ui, ed);
    for path in ui.input(|i| i.raw.dropped_files.iter().map(|f| f.path().to_path_buf()).collect::<Vec<_>>()) {
        if let Err(e) = ed.add_file(&path) {
            ed.error(e);
        }
    }
    if response.drag_started_by(egui::PointerButton::Primary) {
        let from = ui.input(|i| i.pointer.press_origin()).map(to_view);
        let mode = ed.view.gizmo.mode;
        *drag = placement(ed, ed.doc.selection)
            .zip(from)
            .and_then(|(at, from)| at.grab(mode, &view, from).map(|axis| Drag::new(at, mode, axis, from)));
    }
    match drag {
        Some(d) if response.dragged_by(egui::PointerButton::Primary) => {
            let settings = ed.view.gizmo;
            let edit = response.interact_pointer_pos().and_then(|p| d.step(&view, to_view(p), &settings));
            if let Some(edit) = edit {
                apply(ed, ed.doc.selection, edit);
            }
        }
        _ => orbit_drag(ui, ed, rect, response),
    }
    if response.drag_stopped() {
        *drag = None;
    }
    let uv = |p: egui::Pos2| to_view(p) / size.max(Vec2::ONE);
    let aspect = size.x / size.y.max(1.0);
    if response.clicked()
        && let Some(p) = response.interact_pointer_pos()
    {
        ed.doc.selection = ed.pick(uv(p), aspect);
    }
    let idle = !ui.input(|i| i.pointer.any_down());
    ed.view.hover = match response.hover_pos() {
        Some(p) if idle => ed.pick(uv(p), aspect),
        Some(_) => ed.view.hover,
        None => Selection::None,
    };
}

fn keys(ui: &egui::Ui, ed: &mut Editor) {
    // Keys typed into a text or number field are not commands.
    if ui.ctx().text_edit_focused() {
        return;
    }
    let pressed = |k: egui::Key| ui.input(|i| i.key_pressed(k));
    if pressed(egui::Key::Escape) {
        ed.doc.selection = Selection::None;
    }
    for (key, mode) in [(egui::Key::W, Mode::Translate), (egui::Key::E, Mode::Rotate), (egui::Key::R, Mode::Scale)] {
        if pressed(key) {
            ed.view.gizmo.mode = mode;
        }
    }
}

fn orbit_drag(ui: &egui::Ui, ed: &mut Editor, rect: egui::Rect, response: &egui::Response) {
    let mut orbit = ed.view.orbit;
    if response.dragged_by(egui::PointerButton::Primary) {
        let d = response.drag_delta();
        orbit.rotate(d.x * 0.01, d.y * 0.01);
    }
    if response.dragged_by(egui::PointerButton::Secondary) || response.dragged_by(egui::PointerButton::Middle) {
        let d = response.drag_delta() / rect.height().max(1.0);
        orbit.pan(d.x, d.y);
    }
    if response.hovered() {
        let scroll = ui.input(|i| i.smooth_scroll_delta.y);
        if scroll != 0.0 {
            orbit.zoom((-scroll * 0.002).exp());
        }
    }
    ed.set_orbit(orbit);
}

/// Where the gizmo of `sel` stands: a group at its origin, a light at its polygon's centre, with
/// the world's axes or the selection's own ([`Editor::gizmo`]'s space).
pub fn placement(ed: &Editor, sel: Selection) -> Option<Placement> {
    let w = &ed.doc.scene.world;
    let (origin, frame) = match sel {
        Selection::Group(g) => {
            let pose = w.get::<&Transform>(g).ok()?.world;
            (Vec3::from(pose.translation), pose)
        }
        Selection::Light(e) => {
            let light = ed.flat.lights_of(e).next()?;
            let centre = light.points.iter().copied().sum::<Vec3>() / light.points.len() as f32;
            (centre, w.get::<&Transform>(e).ok()?.world)
        }
        _ => return None,
    };
    let axes = match ed.view.gizmo.space {
        Space::World => [Vec3::X, Vec3::Y, Vec3::Z],
        Space::Local => [frame.x_axis, frame.y_axis, frame.z_axis].map(|a| Vec3::from(a).normalize_or(Vec3::X)),
    };
    Some(Placement { origin, axes })
}

/// Applies a gizmo edit to `sel` through the editor's edits (so it re-shades, re-bakes and
/// undoes like the inspector's).
pub fn apply(ed: &mut Editor, sel: Selection, edit: Edit) {
    match (sel, edit) {
        (Selection::Group(g), Edit::Move(v)) => ed.move_group(g, v, Quat::IDENTITY),
        (Selection::Group(g), Edit::Turn(q)) => ed.move_group(g, Vec3::ZERO, q),
        (Selection::Group(g), Edit::Scale(f)) => ed.scale_group(g, f),
        (Selection::Light(e), Edit::Move(v)) => ed.move_light(e, v, Quat::IDENTITY),
        (Selection::Light(e), Edit::Scale(f)) => {
            let radiance = ed.doc.scene.world.get::<&kage_engine::scene::PolygonLight>(e).map(|l| l.radiance);
            if let Ok(radiance) = radiance {
                ed.set_light(e, radiance, f);
            }
        }
        (Selection::Light(e), Edit::Turn(q)) => {
            // A light turns in its group's frame: the world rotation seen from there.
            let group = ed.doc.scene.world.get::<&InGroup>(e).map(|m| m.group).ok();
            let pose = group.and_then(|g| ed.doc.scene.world.get::<&Transform>(g).ok().map(|t| t.world));
            let (_, turn, _) = pose.unwrap_or(Affine3A::IDENTITY).to_scale_rotation_translation();
            ed.move_light(e, Vec3::ZERO, turn.inverse() * q * turn);
        }
        _ => {}
    }
}

/// Paints the hovered and selected outlines and the gizmo over the viewport.
pub fn paint(ui: &egui::Ui, ed: &Editor, rect: egui::Rect, drag: Option<&Drag>) {
    let painter = ui.painter_at(rect);
    let orbit = ed.view.orbit;
    let view = View { orbit: &orbit, size: Vec2::new(rect.width(), rect.height()) };
    let at = |p: Vec2| rect.min + egui::vec2(p.x, p.y);
    for (sel, colour, width) in [(ed.view.hover, HOVER, 1.0), (ed.doc.selection, SELECTED, 2.0)] {
        if sel == Selection::None || (sel == ed.doc.selection && colour == HOVER) {
            continue;
        }
        if let Some([lo, hi]) = super::pick::bounds(&ed.doc.scene, &ed.flat, sel) {
            for (a, b) in box_edges(lo, hi) {
                if let (Some(a), Some(b)) = (view.pixel(a), view.pixel(b)) {
                    painter.line_segment([at(a), at(b)], egui::Stroke::new(width, colour));
                }
            }
        }
    }
    let Some(place) = placement(ed, ed.doc.selection) else { return };
    let handles = place.handles(ed.view.gizmo.mode, &view);
    for (k, line) in handles.iter().enumerate() {
        let colour = if drag.is_some_and(|d| d.axis == k) { ACTIVE } else { AXES[k] };
        let points: Vec<egui::Pos2> = line.iter().map(|p| at(*p)).collect();
        painter.add(egui::Shape::line(points.clone(), egui::Stroke::new(3.0, colour)));
        match (ed.view.gizmo.mode, points.last()) {
            (Mode::Translate, Some(tip)) => {
                painter.circle_filled(*tip, 5.0, colour);
            }
            (Mode::Scale, Some(tip)) => {
                painter.rect_filled(egui::Rect::from_center_size(*tip, egui::vec2(9.0, 9.0)), 0.0, colour);
            }
            _ => {}
        }
    }
}

/// The twelve edges of the box (lo, hi).
fn box_edges(lo: Vec3, hi: Vec3) -> impl Iterator<Item = (Vec3, Vec3)> {
    let corner = move |k: usize| {
        Vec3::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        )
    };
    (0..8).flat_map(move |k| {
        [1usize, 2, 4].into_iter().filter(move |bit| k & bit == 0).map(move |bit| (corner(k), corner(k | bit)))
    })
}

/// The gizmo's options above the viewport: mode, axes, snapping.
pub fn toolbar(ui: &mut egui::Ui, ed: &mut Editor) {
    ui.horizontal(|ui| {
        let g = &mut ed.view.gizmo;
        ui.selectable_value(&mut g.mode, Mode::Translate, "Move (W)");
        ui.selectable_value(&mut g.mode, Mode::Rotate, "Turn (E)");
        ui.selectable_value(&mut g.mode, Mode::Scale, "Scale (R)");
        ui.separator();
        ui.selectable_value(&mut g.space, Space::World, "World");
        ui.selectable_value(&mut g.space, Space::Local, "Local");
        ui.separator();
        ui.checkbox(&mut g.snap, "Snap");
        ui.add(egui::DragValue::new(&mut g.grid).speed(0.01).range(0.001..=100.0).suffix(" m"));
        ui.add(egui::DragValue::new(&mut g.angle).speed(1.0).range(1.0..=90.0).suffix("°"));
    });
}

#[cfg(test)]
mod tests {
    use super::box_edges;
    use glam::Vec3;

    #[test]
    fn a_box_has_twelve_unit_edges_along_the_axes() {
        let edges: Vec<_> = box_edges(Vec3::ZERO, Vec3::ONE).collect();
        assert_eq!(edges.len(), 12);
        assert!(edges.iter().all(|(a, b)| ((*b - *a).length() - 1.0).abs() < 1e-6));
    }
}
