//! Deterministic per-item random streams: seeded from (user seed, item index), never from time
//! or thread, so results do not depend on scheduling.

use rand::SeedableRng;
use rand_pcg::Pcg64Mcg;

/// The generator every estimator uses.
pub type Rng = Pcg64Mcg;

/// SplitMix64 finaliser: decorrelates nearby indices.
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The random stream for item `index` (a pixel, a vertex, …) under `seed`.
pub fn stream(seed: u64, index: u64) -> Rng {
    let lo = mix64(seed ^ mix64(index));
    let hi = mix64(lo ^ 0xD1B5_4A32_D192_ED03);
    Rng::new(((hi as u128) << 64) | lo as u128)
}

/// A fresh stream for a named purpose, e.g. a table build.
pub fn seeded(seed: u64) -> Rng {
    Rng::seed_from_u64(seed)
}
