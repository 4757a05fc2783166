//! The PRT budget's pilot transfer ([`prt::budget::pilot`]: every instance at the reference order),
//! kept in the store's memos so that planning the order again — after a group turns,
//! which turns the environment in its frame — reads it instead of baking it. The pilot is
//! group-local like every PRT bake, so its name hashes the keys the PRT artefacts at the
//! reference order would have; a cached pilot is the baked one bit for bit.
//!
//! Like every memo it costs only time: an entry checks its own checksum and shape when read
//! (a damaged one is baked again), and `gc` drops it.

use super::codec::{Reader, Writer};
use crate::key::KeyHasher;
use crate::store::Result;
use crate::{Store, plan};
use kage_engine::prt;
use kage_engine::scene::{FlatScene, Scene};

/// The pilot for `base`'s directions, from the store when it holds a sound one, else baked and
/// stored.
pub fn pilot(store: &Store, scene: &Scene, flat: &FlatScene, base: &prt::Settings) -> Result<prt::Bake> {
    let reference = prt::Settings { order: prt::budget::REFERENCE_ORDER, ..*base };
    let keys: Vec<u8> =
        plan(store, scene, flat, None, Some(reference))?.keys().iter().flat_map(|k| *k.as_bytes()).collect();
    let name = format!("prt pilot {}", KeyHasher::new("prt pilot").bytes("keys", &keys).finish().short());
    if let Some(bake) = store.memo(&name)?.and_then(|b| from_bytes(&b, flat)) {
        return Ok(bake);
    }
    let bake = prt::budget::pilot(scene, flat, base);
    store.put_memos(&[(name, to_bytes(&bake))])?;
    Ok(bake)
}

/// Order, instance count, per-instance lengths, the coefficients, sealed ([`super::codec`]).
fn to_bytes(b: &prt::Bake) -> Vec<u8> {
    let mut w = Writer::default();
    w.count(b.order).count(b.instances.len());
    b.instances.iter().for_each(|t| _ = w.count(t.len()));
    b.instances.iter().for_each(|t| _ = w.pod(t));
    w.seal()
}

/// The pilot in `bytes` when its hash holds and its shape fits the scene; `None` otherwise.
fn from_bytes(bytes: &[u8], flat: &FlatScene) -> Option<prt::Bake> {
    let mut r = Reader::open(bytes)?;
    let (order, count) = (r.count()?, r.count()?);
    let coeffs = kage_engine::math::sh::num_coeffs(order);
    if order != prt::budget::REFERENCE_ORDER || count != flat.instances.len() {
        return None;
    }
    let lengths = (0..count).map(|_| r.count()).collect::<Option<Vec<usize>>>()?;
    let expected = flat.instances.iter().map(|i| coeffs * flat.meshes[i.mesh as usize].positions.len());
    if !lengths.iter().copied().eq(expected) {
        return None;
    }
    let instances = lengths.iter().map(|&n| r.pod::<f32>(n)).collect::<Option<Vec<_>>>()?;
    let instances = r.end(instances)?;
    let stats = prt::Stats {
        vertices: lengths.iter().sum::<usize>() / coeffs,
        bytes: 4 * lengths.iter().sum::<usize>(),
        seconds: 0.0,
    };
    Some(prt::Bake { order, instances, stats })
}
