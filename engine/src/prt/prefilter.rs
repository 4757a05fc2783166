//! The environment light's reflection in a GGX lobe: the run time's mip chain and filtered
//! importance sampling ([`kage_runtime::prt::prefilter`]) over the light's map without its sun
//! (the baked look shades a sun on its own), kept with the light's map so that a change of
//! intensity or rotation alone reuses the chain.

use crate::scene::EnvironmentLight;
use crate::scene::environment::EnvMap;
use glam::{Quat, Vec3};
use kage_runtime::prt::prefilter::Prefiltered as Chain;
pub use kage_runtime::prt::prefilter::SAMPLES;
use std::sync::Arc;

/// An environment light's map as a mip chain, with its intensity and rotation, for GGX
/// reflection by filtered importance sampling.
#[derive(Clone, Debug)]
pub struct Prefiltered {
    /// The light's map, for [`Self::for_light`]'s identity test.
    source: Arc<EnvMap>,
    /// The chain of the map without its sun ([`super::sun`]).
    chain: Chain,
}

impl Prefiltered {
    /// The mip chain of `env`'s map without its sun (its intensity and rotation are applied at
    /// lookup).
    pub fn new(env: &EnvironmentLight) -> Self {
        let map = super::sun::split(&env.map).map_or_else(|| env.map.clone(), |(_, rest)| Arc::new(rest));
        let chain = Chain::new(map.width, map.height, map.texels.clone(), env.intensity, env.rotation);
        Self { source: env.map.clone(), chain }
    }

    /// This chain for `env` without building it again when it shows the same map (only its
    /// intensity or rotation changed, e.g. a drag in the editor); else built anew.
    pub fn for_light(&self, env: &EnvironmentLight) -> Self {
        if Arc::ptr_eq(&self.source, &env.map) {
            let chain = self.chain.placed(Quat::from_rotation_y(-env.rotation), env.intensity);
            Self { source: self.source.clone(), chain }
        } else {
            Self::new(env)
        }
    }

    /// The chain's levels as (width, height, texels), level 0 the map without its sun.
    pub fn levels(&self) -> impl Iterator<Item = (usize, usize, &[Vec3])> {
        self.chain.levels()
    }

    /// Map-from-world rotation and intensity (applied at lookup).
    pub fn placement(&self) -> (Quat, f32) {
        self.chain.placement()
    }

    /// True when `other` holds the same chain (built once, shared by clones).
    pub fn same_chain(&self, other: &Self) -> bool {
        self.chain.same_chain(&other.chain)
    }

    /// Names this chain for a memo's key: the map it was built from (by identity: hold a
    /// clone of `self` while the key is kept) with its intensity and rotation.
    pub fn hash_into(&self, h: &mut blake3::Hasher) {
        let (to_map, intensity) = self.chain.placement();
        h.update(&(Arc::as_ptr(&self.source) as usize as u64).to_le_bytes());
        h.update(bytemuck::cast_slice(&[intensity]));
        h.update(bytemuck::cast_slice(&to_map.to_array()));
    }

    /// Radiance of mip level `lod` along world `dir` ([`Chain::lookup`]).
    pub fn lookup(&self, dir: Vec3, lod: f32) -> Vec3 {
        self.chain.lookup(dir, lod)
    }

    /// The unshadowed reflection of the specular GGX lobe ([`Chain::reflect`]).
    pub fn reflect(&self, n: Vec3, wo: Vec3, alpha: f32, f0: Vec3, f90: Vec3) -> Vec3 {
        self.chain.reflect(n, wo, alpha, f0, f90)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::environment::dir_to_uv;

    /// A sun is left out of the chain: the baked look shades it on its own.
    #[test]
    fn the_chain_leaves_out_the_sun() {
        let (w, h) = (128, 64);
        let sun = Vec3::new(0.3, 0.8, -0.5).normalize();
        let uv_sun = dir_to_uv(sun);
        let (cx, cy) = ((uv_sun.x * w as f32) as usize, (uv_sun.y * h as f32) as usize);
        let mut texels = vec![Vec3::splat(0.1); w * h];
        texels[cy * w + cx] = Vec3::splat(1e5);
        let p = Prefiltered::new(&EnvironmentLight::new(EnvMap::new(w, h, texels, "sun".into()).unwrap()));
        assert!((p.lookup(sun, 0.0) - Vec3::splat(0.1)).abs().max_element() < 1e-6, "{}", p.lookup(sun, 0.0));
    }
}
