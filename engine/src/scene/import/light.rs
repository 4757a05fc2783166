//! Emissive primitives → light polygons: a planar, convex primitive with one boundary loop
//! becomes one polygon; anything else becomes one polygon per triangle.

use crate::scene::Mesh;
use glam::DVec3;
use std::collections::HashMap;

/// Vertex-index loops (CCW about the emitting side) of the light polygons of `mesh`.
pub fn polygons(mesh: &Mesh) -> Vec<Vec<u32>> {
    if let Some(poly) = single_convex_polygon(mesh) {
        return vec![poly];
    }
    mesh.triangles.iter().map(|t| t.to_vec()).collect()
}

fn single_convex_polygon(mesh: &Mesh) -> Option<Vec<u32>> {
    let p = |i: u32| mesh.positions[i as usize].as_dvec3();
    let normal: DVec3 = mesh.triangles.iter().map(|t| (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0]))).sum();
    let area = 0.5 * normal.length();
    if area <= 0.0 {
        return None;
    }
    let n = normal.normalize();
    // Every triangle faces the same way (no folds) …
    if mesh.triangles.iter().any(|t| (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0])).dot(n) <= 0.0) {
        return None;
    }
    // … and every vertex lies on one plane.
    let extent = mesh.positions.iter().fold(0.0f64, |m, v| m.max((v.as_dvec3() - p(mesh.triangles[0][0])).length()));
    let origin = p(mesh.triangles[0][0]);
    if mesh.positions.iter().any(|v| (v.as_dvec3() - origin).dot(n).abs() > 1e-5 * extent.max(1e-12)) {
        return None;
    }
    let loop_ = boundary_loop(mesh)?;
    let loop_ = drop_collinear(&loop_, &p, n);
    // Convex: every corner turns the same way as the normal; area matches (no holes).
    let k = loop_.len();
    if k < 3 {
        return None;
    }
    for i in 0..k {
        let (a, b, c) = (p(loop_[i]), p(loop_[(i + 1) % k]), p(loop_[(i + 2) % k]));
        if (b - a).cross(c - b).dot(n) <= 0.0 {
            return None;
        }
    }
    let loop_area: f64 =
        (1..k - 1).map(|i| 0.5 * (p(loop_[i]) - p(loop_[0])).cross(p(loop_[i + 1]) - p(loop_[0])).dot(n)).sum();
    ((loop_area - area).abs() <= 1e-6 * area).then_some(loop_)
}

/// The single closed loop of boundary edges (edges used once), with vertices welded by position.
fn boundary_loop(mesh: &Mesh) -> Option<Vec<u32>> {
    let key = |i: u32| mesh.positions[i as usize].to_array().map(f32::to_bits);
    let mut canon: HashMap<[u32; 3], u32> = HashMap::new();
    let id: Vec<u32> = (0..mesh.positions.len() as u32).map(|i| *canon.entry(key(i)).or_insert(i)).collect();
    let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (id[t[k] as usize], id[t[(k + 1) % 3] as usize]);
            *edges.entry((a, b)).or_default() += 1;
        }
    }
    let mut next: HashMap<u32, u32> = HashMap::new();
    for (&(a, b), &count) in &edges {
        if count == 1 && !edges.contains_key(&(b, a)) && next.insert(a, b).is_some() {
            return None;
        }
    }
    let start = *next.keys().min()?;
    let mut loop_ = vec![start];
    let mut at = next[&start];
    while at != start {
        if loop_.len() > next.len() {
            return None;
        }
        loop_.push(at);
        at = *next.get(&at)?;
    }
    (loop_.len() == next.len()).then_some(loop_)
}

fn drop_collinear(loop_: &[u32], p: &impl Fn(u32) -> DVec3, n: DVec3) -> Vec<u32> {
    let k = loop_.len();
    (0..k)
        .filter(|&i| {
            let (a, b, c) = (p(loop_[(i + k - 1) % k]), p(loop_[i]), p(loop_[(i + 1) % k]));
            let turn = (b - a).cross(c - b).dot(n);
            turn.abs() > 1e-9 * (b - a).length() * (c - b).length()
        })
        .map(|i| loop_[i])
        .collect()
}

pub use kage_runtime::light::normal_area as polygon_normal_area;

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn grid_quad(n: u32) -> Mesh {
        let mut pos = vec![];
        for j in 0..=n {
            for i in 0..=n {
                pos.push(Vec3::new(i as f32 / n as f32, 0.0, -(j as f32) / n as f32));
            }
        }
        let w = n + 1;
        let mut tris = vec![];
        for j in 0..n {
            for i in 0..n {
                let a = j * w + i;
                tris.push([a, a + 1, a + w + 1]);
                tris.push([a, a + w + 1, a + w]);
            }
        }
        Mesh::new(pos, None, vec![], tris, false).unwrap().0
    }

    #[test]
    fn tessellated_quad_becomes_one_quad() {
        let polys = polygons(&grid_quad(3));
        assert_eq!(polys.len(), 1);
        assert_eq!(polys[0].len(), 4, "collinear boundary vertices removed");
        let m = grid_quad(3);
        let pts: Vec<Vec3> = polys[0].iter().map(|&i| m.positions[i as usize]).collect();
        let (n, a) = polygon_normal_area(&pts);
        assert!((n - Vec3::Y).length() < 1e-6 && (a - 1.0).abs() < 1e-5);
    }

    #[test]
    fn non_planar_or_concave_falls_back_to_triangles() {
        let mut m = grid_quad(2);
        m.positions[4].y = 0.3; // lift the centre vertex
        assert_eq!(polygons(&m).len(), 8);
        // An L shape: planar but concave.
        let mut l = grid_quad(2);
        l.triangles.truncate(6);
        assert_eq!(polygons(&l).len(), 6);
    }
}
