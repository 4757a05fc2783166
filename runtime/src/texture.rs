//! Linear-RGB textures with bilinear filtering (emissive textures of polygonal lights).

use glam::{Vec2, Vec3};

/// How texture coordinates outside [0, 1] are handled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wrap {
    /// Clamp to the edge texel.
    Clamp,
    /// Repeat (glTF's default).
    Repeat,
    /// Mirrored repeat.
    Mirror,
}

impl Wrap {
    fn apply(self, i: i64, n: usize) -> usize {
        let n = n as i64;
        let r = match self {
            Wrap::Clamp => i.clamp(0, n - 1),
            Wrap::Repeat => i.rem_euclid(n),
            Wrap::Mirror => {
                let m = i.rem_euclid(2 * n);
                if m < n { m } else { 2 * n - 1 - m }
            }
        };
        r as usize
    }
}

/// A texture of linear radiance multipliers.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    /// Width in texels.
    pub width: usize,
    /// Height in texels.
    pub height: usize,
    /// Row-major linear RGB, row 0 at v = 0 (glTF's top).
    pub texels: Vec<Vec3>,
    /// Wrap modes along u and v.
    pub wrap: [Wrap; 2],
    /// Prefiltered levels 1, 2, … (each half the size, 2×2 box filter), down to 1×1; empty in a
    /// level itself. Textured lights read these at a footprint-dependent level, as in the LTC
    /// paper.
    pub mips: Vec<Texture>,
}

impl Texture {
    /// A texture with its prefiltered chain.
    pub fn new(width: usize, height: usize, texels: Vec<Vec3>, wrap: [Wrap; 2]) -> Self {
        let mut mips = Vec::new();
        let (mut w, mut h, mut cur) = (width, height, texels.clone());
        while w > 1 || h > 1 {
            let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
            let at = |x: usize, y: usize| cur[y.min(h - 1) * w + x.min(w - 1)];
            let next: Vec<Vec3> = (0..nw * nh)
                .map(|k| {
                    let (x, y) = (2 * (k % nw), 2 * (k / nw));
                    (at(x, y) + at(x + 1, y) + at(x, y + 1) + at(x + 1, y + 1)) * 0.25
                })
                .collect();
            mips.push(Texture { width: nw, height: nh, texels: next.clone(), wrap, mips: Vec::new() });
            (w, h, cur) = (nw, nh, next);
        }
        Self { width, height, texels, wrap, mips }
    }

    /// Trilinear lookup at level `lod` (0 = full resolution; clamped to the chain).
    pub fn sample_lod(&self, uv: Vec2, lod: f32) -> Vec3 {
        let lod = if lod.is_finite() { lod.clamp(0.0, self.mips.len() as f32) } else { 0.0 };
        let (l0, f) = (lod.floor() as usize, lod.fract());
        let level = |l: usize| if l == 0 { self } else { &self.mips[(l - 1).min(self.mips.len() - 1)] };
        let a = level(l0).sample(uv);
        if f == 0.0 || l0 >= self.mips.len() { a } else { a.lerp(level(l0 + 1).sample(uv), f) }
    }

    /// Bilinear lookup at `uv` (texel centres at (i + 0.5)/N).
    pub fn sample(&self, uv: Vec2) -> Vec3 {
        let x = uv.x * self.width as f32 - 0.5;
        let y = uv.y * self.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let at = |i: f32, j: f32| {
            let i = self.wrap[0].apply(i as i64, self.width);
            let j = self.wrap[1].apply(j as i64, self.height);
            self.texels[j * self.width + i]
        };
        let top = at(x0, y0).lerp(at(x0 + 1.0, y0), fx);
        let bottom = at(x0, y0 + 1.0).lerp(at(x0 + 1.0, y0 + 1.0), fx);
        top.lerp(bottom, fy)
    }

    /// Mean texel value (used to pick lights by power).
    pub fn mean(&self) -> Vec3 {
        self.texels.iter().copied().sum::<Vec3>() / self.texels.len().max(1) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_hits_texel_centres_and_wraps() {
        let t = Texture::new(2, 1, vec![Vec3::ZERO, Vec3::ONE], [Wrap::Clamp, Wrap::Clamp]);
        assert_eq!(t.sample(Vec2::new(0.25, 0.5)), Vec3::ZERO);
        assert_eq!(t.sample(Vec2::new(0.75, 0.5)), Vec3::ONE);
        assert!((t.sample(Vec2::new(0.5, 0.5)) - Vec3::splat(0.5)).length() < 1e-6);
        assert_eq!(t.sample(Vec2::new(5.0, 0.5)), Vec3::ONE);
        assert_eq!(Wrap::Repeat.apply(-1, 4), 3);
        assert_eq!(Wrap::Mirror.apply(4, 4), 3);
        // The chain ends in the mean.
        assert_eq!(t.mips.len(), 1);
        assert!((t.sample_lod(Vec2::new(0.1, 0.5), 10.0) - Vec3::splat(0.5)).length() < 1e-6);
        assert!((t.sample_lod(Vec2::new(0.75, 0.5), 0.5) - Vec3::splat(0.75)).length() < 1e-6);
    }
}
