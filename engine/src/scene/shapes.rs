//! Procedural meshes: the built-in scene's shapes, also used by tests and benchmarks.

use crate::scene::Mesh;
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

fn build(positions: Vec<Vec3>, normals: Option<Vec<Vec3>>, uvs: Vec<Vec2>, triangles: Vec<[u32; 3]>) -> Mesh {
    // Shapes are generated without zero-area triangles; pole caps drop theirs.
    Mesh::new(positions, normals, uvs, triangles, true).expect("procedural shapes are valid").0
}

/// A `size × size` ground in the XZ plane facing +Y, tessellated `n × n`.
pub fn grid(size: f32, n: u32) -> Mesh {
    let w = n + 1;
    let mut pos = Vec::new();
    let mut uvs = Vec::new();
    for j in 0..w {
        for i in 0..w {
            let uv = Vec2::new(i as f32 / n as f32, j as f32 / n as f32);
            pos.push(Vec3::new((uv.x - 0.5) * size, 0.0, (uv.y - 0.5) * size));
            uvs.push(uv);
        }
    }
    let mut tris = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let a = j * w + i;
            tris.push([a, a + w, a + 1]);
            tris.push([a + 1, a + w, a + w + 1]);
        }
    }
    build(pos, Some(vec![Vec3::Y; (w * w) as usize]), uvs, tris)
}

/// Parametric surface on a `(u, v)` grid, with wrap-around seams.
fn lathe(nu: u32, nv: u32, f: impl Fn(f32, f32) -> (Vec3, Vec3)) -> Mesh {
    let (mut pos, mut nor, mut uvs) = (Vec::new(), Vec::new(), Vec::new());
    for j in 0..=nv {
        for i in 0..=nu {
            let (u, v) = (i as f32 / nu as f32, j as f32 / nv as f32);
            let (p, n) = f(u, v);
            pos.push(p);
            nor.push(n);
            uvs.push(Vec2::new(u, v));
        }
    }
    let w = nu + 1;
    let mut tris = Vec::new();
    for j in 0..nv {
        for i in 0..nu {
            let a = j * w + i;
            tris.push([a, a + 1, a + w]);
            tris.push([a + 1, a + w + 1, a + w]);
        }
    }
    build(pos, Some(nor), uvs, tris)
}

/// A torus around +Y with major radius `r1`, minor radius `r2`.
pub fn torus(r1: f32, r2: f32, nu: u32, nv: u32) -> Mesh {
    lathe(nu, nv, |u, v| {
        let (phi, theta) = (2.0 * PI * u, 2.0 * PI * v);
        let ring = Vec3::new(phi.cos(), 0.0, -phi.sin());
        let n = ring * theta.cos() + Vec3::Y * theta.sin();
        (ring * r1 + n * r2, n)
    })
}

/// A UV sphere of radius `r`.
pub fn sphere(r: f32, nu: u32, nv: u32) -> Mesh {
    lathe(nu, nv, |u, v| {
        let (phi, theta) = (2.0 * PI * u, PI * (1.0 - v));
        let n = Vec3::new(theta.sin() * phi.cos(), theta.cos(), -theta.sin() * phi.sin());
        (n * r, n)
    })
}

/// An axis-aligned box with half extents `h`, flat-shaded (split normals).
pub fn cuboid(h: Vec3) -> Mesh {
    let (mut pos, mut nor, mut tris) = (Vec::new(), Vec::new(), Vec::new());
    for axis in 0..3 {
        for sign in [1.0f32, -1.0] {
            let n = Vec3::AXES[axis] * sign;
            let t = Vec3::AXES[(axis + 1) % 3] * sign;
            let b = n.cross(t);
            let base = pos.len() as u32;
            for (s, q) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                pos.push((n + t * s + b * q) * h);
                nor.push(n);
            }
            tris.push([base, base + 1, base + 2]);
            tris.push([base, base + 2, base + 3]);
        }
    }
    build(pos, Some(nor), vec![], tris)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Closed shapes: Σ area-weighted normals ≈ 0 and normals agree with the winding.
    fn check_closed(m: &Mesh) {
        let mut sum = Vec3::ZERO;
        for t in &m.triangles {
            let p = t.map(|i| m.positions[i as usize]);
            let face = (p[1] - p[0]).cross(p[2] - p[0]);
            sum += face;
            let avg_n = t.iter().map(|&i| m.normals[i as usize]).sum::<Vec3>();
            assert!(face.dot(avg_n) > 0.0, "winding agrees with normals");
        }
        assert!(sum.length() < 1e-3 * m.area(), "closed: {sum}");
    }

    #[test]
    fn shapes_are_closed_and_outward() {
        check_closed(&torus(1.0, 0.3, 32, 16));
        check_closed(&sphere(1.0, 32, 16));
        check_closed(&cuboid(Vec3::new(1.0, 2.0, 0.5)));
        assert!((cuboid(Vec3::ONE).area() - 24.0).abs() < 1e-4);
        assert!((grid(2.0, 4).area() - 4.0).abs() < 1e-5);
    }
}
