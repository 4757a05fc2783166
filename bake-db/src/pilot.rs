//! The PRT budget's pilot transfer ([`prt::budget::pilot`]: every instance at the reference order),
//! kept in the store's memos so that planning the order again — after a group turns,
//! which turns the environment in its frame — reads it instead of baking it. The pilot is
//! group-local like every PRT bake, so its name hashes the keys the PRT artefacts at the
//! reference order would have; a cached pilot is the baked one bit for bit.
//!
//! Like every memo it costs only time: an entry checks its own checksum and shape when read
//! (a damaged one is baked again), and `gc` drops it.

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

/// Order, instance count, per-instance lengths, the coefficients (little-endian u32 and f32),
/// then a blake3 hash of all that.
fn to_bytes(b: &prt::Bake) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend((b.order as u32).to_le_bytes());
    out.extend((b.instances.len() as u32).to_le_bytes());
    out.extend(b.instances.iter().flat_map(|t| (t.len() as u32).to_le_bytes()));
    out.extend(b.instances.iter().flatten().flat_map(|v| v.to_le_bytes()));
    let hash = *blake3::hash(&out).as_bytes();
    out.extend(hash);
    out
}

/// The pilot in `bytes` when its hash holds and its shape fits the scene; `None` otherwise.
fn from_bytes(bytes: &[u8], flat: &FlatScene) -> Option<prt::Bake> {
    let (body, hash) = bytes.split_at_checked(bytes.len().checked_sub(32)?)?;
    if blake3::hash(body).as_bytes() != hash {
        return None;
    }
    let mut words = body.chunks_exact(4).map(|w| [w[0], w[1], w[2], w[3]]);
    let mut word = || words.next().map(u32::from_le_bytes).map(|w| w as usize);
    let (order, count) = (word()?, word()?);
    let coeffs = kage_engine::math::sh::num_coeffs(order);
    if order != prt::budget::REFERENCE_ORDER || count != flat.instances.len() {
        return None;
    }
    let lengths = (0..count).map(|_| word()).collect::<Option<Vec<usize>>>()?;
    let expected = flat.instances.iter().map(|i| coeffs * flat.meshes[i.mesh as usize].positions.len());
    if !lengths.iter().copied().eq(expected) {
        return None;
    }
    let mut values = words.map(f32::from_le_bytes);
    let instances: Vec<Vec<f32>> = lengths.iter().map(|&n| values.by_ref().take(n).collect()).collect();
    if values.next().is_some() || instances.iter().zip(&lengths).any(|(t, &n)| t.len() != n) {
        return None;
    }
    let stats = prt::Stats {
        vertices: lengths.iter().sum::<usize>() / coeffs,
        bytes: 4 * lengths.iter().sum::<usize>(),
        seconds: 0.0,
    };
    Some(prt::Bake { order, instances, stats })
}
