//! A face's fixed tile grid (see [`super::node::TILE`]) seen from the cube's centre: the planes
//! of its grid lines and the unit directions of its corners. They depend on the resolution
//! alone and every vertex of a bake needs them, so each thread keeps the last resolution's.

use super::{node, tiles_per_side};
use crate::math::cubemap;
use glam::{DVec2, DVec3};
use std::ops::Range;

/// A face's tile grid, which depends on the resolution alone.
pub struct FaceGrid {
    /// Unit normals of the planes of the grid lines s = edge(t), then t = edge(t), for
    /// t = 0..=k (positive side: larger s or t).
    pub lines: Vec<DVec3>,
    /// Unit directions of the grid's (k + 1)² corners, row-major.
    pub corners: Vec<DVec3>,
}

impl FaceGrid {
    /// The indices in [`Self::corners`] of tile `t`'s four corners (`k` tiles per side).
    pub fn tile_corners(t: usize, k: usize) -> [usize; 4] {
        let at = t / k * (k + 1) + t % k;
        [at, at + 1, at + k + 1, at + k + 2]
    }

    /// Inward unit normals of the four planes through the cube's centre that bound the block of
    /// tiles (i, j), `i` in `columns` and `j` in `rows` (`k` tiles per side): every direction
    /// through the block is on their positive sides.
    pub fn block_sides(&self, columns: Range<usize>, rows: Range<usize>, k: usize) -> [DVec3; 4] {
        let l = &self.lines;
        [l[columns.start], -l[columns.end], l[k + 1 + rows.start], -l[k + 1 + rows.end]]
    }

    fn new(f: usize, res: usize) -> Self {
        let k = tiles_per_side(res);
        let edge = |t: usize| 2.0 * (t * node::TILE).min(res) as f64 / res as f64 - 1.0;
        let line = |a: f64, b: f64| (0..=k).map(move |t| cubemap::line_plane(f, a, b, -edge(t)).normalize());
        let lines = line(1.0, 0.0).chain(line(0.0, 1.0)).collect();
        let corner = |x: usize| cubemap::face_to_dir(f, DVec2::new(edge(x % (k + 1)), edge(x / (k + 1))));
        Self { lines, corners: (0..(k + 1) * (k + 1)).map(corner).collect() }
    }
}

/// Runs `f` on the six faces' grids at resolution `res`.
pub fn with_grids<R>(res: usize, f: impl FnOnce(&[FaceGrid]) -> R) -> R {
    GRIDS.with_borrow_mut(|(at, grids)| {
        if *at != res {
            (*at, *grids) = (res, (0..6).map(|f| FaceGrid::new(f, res)).collect());
        }
        f(grids)
    })
}

thread_local! {
    /// The six faces' grids at the last resolution this thread used (per thread rather than one
    /// lazily built shared table, because a rayon worker blocked in a shared initialiser can
    /// deadlock).
    static GRIDS: std::cell::RefCell<(usize, Vec<FaceGrid>)> = const { std::cell::RefCell::new((0, Vec::new())) };
}
