//! Cube maps: faces +X, −X, +Y, −Y, +Z, −Z with the OpenGL/Vulkan orientation, texel centres
//! at (i + 0.5)/N, exact texel solid angles, and the planes through the origin that 2D lines on
//! a face stand for.
//!
//! A face is described by its centre axis C and the axes S, T of its (s, t) ∈ [−1, 1]²
//! coordinates: the point (s, t) is the direction `C + s S + t T`, and texel (i, j) has
//! s = 2(i + 0.5)/N − 1, t = 2(j + 0.5)/N − 1 (row j = 0 at the top, t = −1).

use glam::{DVec2, DVec3};

/// The six faces in storage order.
pub const FACES: usize = 6;

/// (C, S, T) of face `f`.
pub fn face_basis(f: usize) -> (DVec3, DVec3, DVec3) {
    match f {
        0 => (DVec3::X, DVec3::NEG_Z, DVec3::NEG_Y),
        1 => (DVec3::NEG_X, DVec3::Z, DVec3::NEG_Y),
        2 => (DVec3::Y, DVec3::X, DVec3::Z),
        3 => (DVec3::NEG_Y, DVec3::X, DVec3::NEG_Z),
        4 => (DVec3::Z, DVec3::X, DVec3::NEG_Y),
        5 => (DVec3::NEG_Z, DVec3::NEG_X, DVec3::NEG_Y),
        _ => panic!("cube face {f} out of range"),
    }
}

/// Face and (s, t) ∈ [−1, 1]² of direction `d` (any length > 0). A zero or non-finite `d`
/// maps to the centre of face +X (documented clamp: never NaN out).
pub fn dir_to_face(d: DVec3) -> (usize, DVec2) {
    if !d.is_finite() || d == DVec3::ZERO {
        return (0, DVec2::ZERO);
    }
    let a = d.abs();
    let f = if a.x >= a.y && a.x >= a.z {
        if d.x >= 0.0 { 0 } else { 1 }
    } else if a.y >= a.z {
        if d.y >= 0.0 { 2 } else { 3 }
    } else if d.z >= 0.0 {
        4
    } else {
        5
    };
    let (c, s, t) = face_basis(f);
    let ma = d.dot(c);
    (f, DVec2::new(d.dot(s) / ma, d.dot(t) / ma))
}

/// Unit direction of face `f` at (s, t) — inverse of [`dir_to_face`].
pub fn face_to_dir(f: usize, st: DVec2) -> DVec3 {
    let (c, s, t) = face_basis(f);
    (c + s * st.x + t * st.y).normalize()
}

/// (s, t) of the centre of texel (i, j) on an N×N face.
pub fn texel_center(i: usize, j: usize, n: usize) -> DVec2 {
    DVec2::new(2.0 * (i as f64 + 0.5) / n as f64 - 1.0, 2.0 * (j as f64 + 0.5) / n as f64 - 1.0)
}

/// Texel (i, j) containing (s, t) on an N×N face.
pub fn texel_of(st: DVec2, n: usize) -> (usize, usize) {
    let idx = |v: f64| (((v + 1.0) * 0.5 * n as f64) as usize).min(n - 1);
    (idx(st.x), idx(st.y))
}

/// Solid angle of the face rectangle [s0, s1] × [t0, t1], exactly (∫∫ (1 + s² + t²)^{-3/2}).
pub fn rect_solid_angle(s0: f64, t0: f64, s1: f64, t1: f64) -> f64 {
    let a = |x: f64, y: f64| (x * y).atan2((x * x + y * y + 1.0).sqrt());
    a(s1, t1) - a(s0, t1) - a(s1, t0) + a(s0, t0)
}

/// Exact solid angle of texel (i, j) on an N×N face.
pub fn texel_solid_angle(i: usize, j: usize, n: usize) -> f64 {
    let e = |k: usize| 2.0 * k as f64 / n as f64 - 1.0;
    rect_solid_angle(e(i), e(j), e(i + 1), e(j + 1))
}

/// Normal of the plane through the origin that the face line `a s + b t + c = 0` stands for;
/// directions on the line's positive side (a s + b t + c > 0) have `n · d > 0`.
pub fn line_plane(f: usize, a: f64, b: f64, c: f64) -> DVec3 {
    let (cc, s, t) = face_basis(f);
    cc * c + s * a + t * b
}

/// The four planes (normals pointing inwards) bounding the frustum of face `f`.
pub fn face_frustum(f: usize) -> [DVec3; 4] {
    [
        line_plane(f, -1.0, 0.0, 1.0),
        line_plane(f, 1.0, 0.0, 1.0),
        line_plane(f, 0.0, -1.0, 1.0),
        line_plane(f, 0.0, 1.0, 1.0),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn orientation_matches_opengl() {
        // OpenGL: +X face: sc = −z, tc = −y; +Y: sc = +x, tc = +z; −Z: sc = −x, tc = −y.
        let (f, st) = dir_to_face(DVec3::new(1.0, 0.2, -0.3));
        assert_eq!(f, 0);
        assert!((st - DVec2::new(0.3, -0.2)).length() < 1e-15);
        let (f, st) = dir_to_face(DVec3::new(0.1, 1.0, 0.4));
        assert_eq!(f, 2);
        assert!((st - DVec2::new(0.1, 0.4)).length() < 1e-15);
        let (f, st) = dir_to_face(DVec3::new(0.5, 0.25, -1.0));
        assert_eq!(f, 5);
        assert!((st - DVec2::new(-0.5, -0.25)).length() < 1e-15);
    }

    #[test]
    fn face_and_texel_round_trips() {
        let n = 16;
        for f in 0..FACES {
            let (c, s, t) = face_basis(f);
            assert!((s.cross(t) + c).length() < 1e-15 || (s.cross(t) - c).length() < 1e-15);
            for j in 0..n {
                for i in 0..n {
                    let st = texel_center(i, j, n);
                    let (f2, st2) = dir_to_face(face_to_dir(f, st) * 3.0);
                    assert_eq!(f2, f);
                    assert!((st2 - st).length() < 1e-12);
                    assert_eq!(texel_of(st2, n), (i, j));
                }
            }
        }
    }

    #[test]
    fn bad_directions_are_clamped() {
        assert_eq!(dir_to_face(DVec3::NAN), (0, DVec2::ZERO));
        assert_eq!(dir_to_face(DVec3::ZERO), (0, DVec2::ZERO));
        let (f, st) = dir_to_face(DVec3::new(f64::INFINITY, 1.0, 0.0));
        assert!(st.is_finite() && f == 0);
    }

    #[test]
    fn texel_solid_angles_sum_to_four_pi() {
        for n in [1, 7, 64] {
            let total: f64 =
                (0..FACES).map(|_| (0..n * n).map(|k| texel_solid_angle(k % n, k / n, n)).sum::<f64>()).sum();
            assert!((total - 4.0 * PI).abs() < 1e-9, "N = {n}: {total}");
        }
    }

    #[test]
    fn line_planes_separate_like_the_2d_line() {
        let (a, b, c) = (0.3, -0.8, 0.1);
        for f in 0..FACES {
            let n = line_plane(f, a, b, c);
            for k in 0..50 {
                let st = DVec2::new((k as f64 * 0.37).sin(), (k as f64 * 0.91).cos());
                let side = a * st.x + b * st.y + c;
                let d = face_to_dir(f, st);
                assert_eq!(side > 0.0, n.dot(d) > 0.0, "face {f} st {st}");
            }
        }
        // Frustum planes contain exactly the face's own directions.
        for f in 0..FACES {
            let inside = |d: DVec3| face_frustum(f).iter().all(|p| p.dot(d) >= 0.0);
            assert!(inside(face_to_dir(f, DVec2::new(0.9, -0.9))));
            assert!(!inside(face_to_dir((f + 2) % FACES, DVec2::ZERO)));
        }
    }
}
