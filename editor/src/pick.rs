//! Picking: the group or light under a point of the viewport. The camera ray meets the closest
//! triangle of the scene's snapshot through a BVH (light polygons included: the snapshot holds
//! their triangle fans beside the meshes'); the triangle's owner names what is picked.

use super::state::{Editor, Selection};
use glam::{Vec2, Vec3};
use kage_engine::accel::SceneBvh;
use kage_engine::raster::SurfaceHit;
use kage_engine::scene::{FlatScene, Instance, NO_LIGHT, PrimitiveId, Scene};

/// A BVH over one snapshot, for picking.
pub struct Picker {
    bvh: SceneBvh,
}

impl Picker {
    /// Builds the BVH of `flat` (the quick build: it is rebuilt after every edit).
    pub fn new(flat: &FlatScene) -> Self {
        Self { bvh: SceneBvh::quick_over(flat) }
    }

    /// The group (for a mesh) or light the ray from `origin` along `dir` (unit) meets first in
    /// `flat`, the snapshot the picker was built from.
    pub fn pick(&self, flat: &FlatScene, origin: Vec3, dir: Vec3) -> Selection {
        match self.seen(flat, origin, dir) {
            Seen::Nothing => Selection::None,
            Seen::Light(l) => Selection::Light(flat.light_entities[l]),
            Seen::Surface(hit) => Selection::Group(flat.instances[hit.instance].group),
        }
    }

    /// What the ray from `origin` along `dir` (unit) meets first in `flat`.
    pub fn seen(&self, flat: &FlatScene, origin: Vec3, dir: Vec3) -> Seen {
        let Some(hit) = self.bvh.closest_hit(origin, dir, f32::INFINITY) else { return Seen::Nothing };
        let owner = flat.refs[hit.triangle as usize];
        if owner.light != NO_LIGHT {
            return Seen::Light(owner.light as usize);
        }
        let (i, mesh) = (owner.owner as usize, flat.mesh(owner.owner as usize));
        let corners = mesh.triangles[owner.local as usize].map(|k| k as usize);
        let weights = [1.0 - hit.bary.x - hit.bary.y, hit.bary.x, hit.bary.y];
        let position = origin + dir * hit.t;
        Seen::Surface(SurfaceHit { instance: i, corners, weights, position })
    }
}

/// What a view ray meets.
pub enum Seen {
    /// Nothing: the background.
    Nothing,
    /// A light polygon (by index in the snapshot's lights).
    Light(usize),
    /// A mesh.
    Surface(SurfaceHit),
}

impl Editor {
    /// What lies under viewport point `uv` (0 to 1 across and down) of a viewport of `aspect`:
    /// a group (for its meshes), a light, or nothing.
    pub fn pick(&mut self, uv: Vec2, aspect: f32) -> Selection {
        let (eye, dir) = self.view.orbit.ray(uv, aspect);
        let picker = self.backend.memo.picker.get_or_insert_with(|| Picker::new(&self.flat));
        picker.pick(&self.flat, eye, dir)
    }
}

/// The world-space box (min, max) around what `sel` shows in `flat`, the snapshot of `scene`,
/// or `None` when it shows nothing there (the environment, an empty group).
pub fn bounds(scene: &Scene, flat: &FlatScene, sel: Selection) -> Option<[Vec3; 2]> {
    let shows = |i: &Instance| match sel {
        Selection::Group(g) => i.group == g,
        Selection::Instance(e) => scene.world.get::<&PrimitiveId>(e).is_ok_and(|id| *id == i.id),
        _ => false,
    };
    let mut points: Vec<Vec3> = Vec::new();
    for (k, i) in flat.instances.iter().enumerate().filter(|(_, i)| shows(i)) {
        let first = i.first_triangle as usize;
        points.extend(flat.triangles[first..first + flat.mesh(k).triangles.len()].iter().flatten());
    }
    if let Selection::Light(e) = sel {
        points.extend(flat.lights_of(e).flat_map(|l| l.points.iter().copied()));
    }
    (!points.is_empty()).then(|| points.iter().fold([Vec3::MAX, Vec3::MIN], |[lo, hi], p| [lo.min(*p), hi.max(*p)]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use kage_engine::accel::intersect_triangle_f64;
    use kage_engine::scene::{default_scene, flatten};

    /// Rays from just in front of every tenth triangle (and every light triangle) pick the owner of the closest triangle
    /// they meet, found by testing every triangle.
    #[test]
    fn rays_pick_the_group_or_light_they_meet_first() {
        let scene = default_scene();
        let flat = flatten(&scene);
        let picker = Picker::new(&flat);
        let owner = |t: usize| {
            let r = flat.refs[t];
            if r.light != NO_LIGHT {
                Selection::Light(flat.light_entities[r.light as usize])
            } else {
                Selection::Group(flat.instances[r.owner as usize].group)
            }
        };
        let mut lights = 0;
        let lit = (0..flat.refs.len()).filter(|&t| flat.refs[t].light != NO_LIGHT);
        for t in (0..flat.triangles.len()).step_by(10).chain(lit) {
            let tri = flat.triangles[t];
            let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize();
            let from = (tri[0] + tri[1] + tri[2]) / 3.0 + n * 1e-3;
            let hits: Vec<(f64, usize)> = (0..flat.triangles.len())
                .filter_map(|k| intersect_triangle_f64(from, -n, &flat.triangles[k]).map(|d| (d, k)))
                .collect();
            let nearest = hits.iter().map(|h| h.0).fold(f64::INFINITY, f64::min);
            // Coplanar triangles (a disc lying on the ground) tie: either owner is right.
            let owners: Vec<Selection> = hits.iter().filter(|h| h.0 <= nearest + 1e-6).map(|h| owner(h.1)).collect();
            lights += usize::from(owners.iter().any(|o| matches!(o, Selection::Light(_))));
            let picked = picker.pick(&flat, from, -n);
            assert!(owners.contains(&picked), "from triangle {t}: picked {picked:?}, nearest {owners:?}");
        }
        assert!(lights > 0, "the light's fan was tried too");
        assert_eq!(picker.pick(&flat, Vec3::new(0.0, 100.0, 0.0), Vec3::Y), Selection::None, "the sky");
    }

    #[test]
    fn bounds_enclose_what_is_selected() {
        let scene = default_scene();
        let flat = flatten(&scene);
        let light = &flat.lights[0];
        let [lo, hi] = bounds(&scene, &flat, Selection::Light(flat.light_entities[0])).unwrap();
        assert!(light.points.iter().all(|p| p.cmple(hi).all() && p.cmpge(lo).all()));
        let group = flat.instances[0].group;
        let [lo, hi] = bounds(&scene, &flat, Selection::Group(group)).unwrap();
        assert!(flat.instances.iter().filter(|i| i.group == group).all(|i| {
            let p = flat.triangles[i.first_triangle as usize][0];
            p.cmple(hi + 1e-5).all() && p.cmpge(lo - 1e-5).all()
        }));
        assert!(bounds(&scene, &flat, Selection::Environment).is_none());
    }
}
