//! A vertex's visibility cube map as data: what exact visibility shades with, and what the
//! baker casts (`kage_engine::bspvt::visibility`) and builds the trees from.

use super::depth;

/// Texel state: blocked.
pub const OCCLUDED: u8 = 0;
/// Texel state: the light would be seen.
pub const VISIBLE: u8 = 1;
/// Texel state: below the horizon, not cast ("don't care").
pub const BELOW: u8 = 2;
/// Texel state: above the horizon but not cast (an incremental re-bake keeps its old result).
pub const SKIPPED: u8 = 3;

/// A visibility cube map: 6 faces of `res × res` texels, row-major per face.
#[derive(Clone, Debug, PartialEq)]
pub struct CubeVisibility {
    /// Face resolution.
    pub res: usize,
    /// `6·res²` texel states.
    pub texels: Vec<u8>,
    /// Per texel, an occluded one's first hit (`None` for the others, or when not cast for).
    pub hits: Vec<Option<depth::Hit>>,
}

impl CubeVisibility {
    /// The texels of face `f`.
    pub fn face(&self, f: usize) -> &[u8] {
        let n = self.res * self.res;
        &self.texels[f * n..(f + 1) * n]
    }
}
