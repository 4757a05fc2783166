//! # kage-runtime
//!
//! kage at run time: what shading baked data needs, and nothing a bake needs. The math the
//! techniques share ([`math`]: SH, HSH, LTC, GGX, cube maps, polygons, sampling), materials
//! ([`material`]), lights ([`light`]), cameras ([`camera`]) and textures ([`texture`]) as the
//! shading reads them,
//! BSPVT's vertex records with their LTC shading ([`bspvt`]), PRT's per-frame shading between
//! rigid groups ([`prt`]), and asset packs' container,
//! records, integrity and ranges ([`pack`]).
//!
//! ## Design and guarantees
//! - **No bake-time dependencies**: no database, no BVH builder, no ECS, no GPU API — a game
//!   or an engine plugin links this crate alone (its dependencies: glam, rayon, rand, wide,
//!   serde, serde_json and blake3). `kage-engine` bakes and re-exports these modules, so the engine,
//!   the CLI and the editor shade through the same code.
//! - **Pure**: no I/O and no global state; results are bit-identical on any thread count.
//! - **Conventions** as `docs/conventions.md` states them: glTF frame (+Y up, right-handed),
//!   linear RGB radiance, GGX with α = roughness², one-sided lights emitting on the CCW side.

pub mod bspvt;
pub mod camera;
pub mod light;
pub mod material;
pub mod math;
pub mod pack;
pub mod prt;
pub mod texture;

#[cfg(test)]
mod tests {
    /// The crate stays free of bake-time dependencies: its `[dependencies]` are these alone
    /// (none of which pulls in a database, a BVH builder, an ECS or a GPU API).
    #[test]
    fn depends_on_nothing_a_bake_needs() {
        let manifest = include_str!("../Cargo.toml");
        let section = manifest.split("[dependencies]").nth(1).expect("a [dependencies] section");
        let section = section.split("\n[").next().unwrap_or_default();
        let names: Vec<&str> =
            section.lines().filter_map(|l| l.split(['.', '=', ' ']).next()).filter(|n| !n.is_empty()).collect();
        let allowed = ["glam", "rayon", "rand", "rand_pcg", "wide", "serde", "serde_json", "blake3"];
        assert!(!names.is_empty());
        assert!(names.iter().all(|n| allowed.contains(n)), "runtime dependencies {names:?}, allowed {allowed:?}");
    }
}
