//! A BSPVT slot's lineage: the previous artefact's key, the occluders it saw, its vertices'
//! mixed-tile masks, positions and normals — encoded after a bake, decoded for a warm one —
//! and which occluders changed since.

use super::*;
use std::sync::Arc;

/// The previous bake of each of a chunk's vertices (`None`: the vertex is new) with the
/// occluders that changed since that bake.
pub(super) type Lineage = Vec<Option<(bspvt::VertexBake, Arc<[bspvt::Change]>)>>;

/// A slot's previous vertex bakes by their position and normal bits, each with the occluders
/// that changed since.
pub(super) type Held = HashMap<[u32; 6], (bspvt::VertexBake, Arc<[bspvt::Change]>)>;

/// Which slot of an instance held each of its vertices (by their bits) last time.
pub(super) type Holders = HashMap<[u32; 6], Key>;

/// First bytes of a slot list (see [`crate::plan::Plan::slot_lists`]), then 32-byte slot keys.
const SLOT_LIST_MAGIC: &[u8; 4] = b"kgs1";

/// A slot list's entry.
pub(super) fn encode_slot_list(slots: &[Key]) -> Vec<u8> {
    SLOT_LIST_MAGIC.iter().copied().chain(slots.iter().flat_map(|k| *k.as_bytes())).collect()
}

/// The slots of a slot list's entry (`None` when malformed).
pub(super) fn decode_slot_list(entry: &[u8]) -> Option<Vec<Key>> {
    let keys = entry.strip_prefix(SLOT_LIST_MAGIC)?;
    keys.len().is_multiple_of(32).then(|| keys.chunks_exact(32).map(Key::from_slice).collect())
}

/// First bytes of a lineage entry (its layout's version): entries of an older layout (before
/// masks, or before vertices were kept) lack it, and their chunks bake cold once.
pub(super) const LINEAGE_MAGIC: &[u8; 4] = b"kgl3";

/// Every occluder added, removed or changed between two snapshots, with its old and new
/// bounds (padded: rays' offset origins differ from the vertex) and its index in `now` (the
/// flattened scene's instance order, as [`Occluders`] has it).
pub fn changes(then: &[Occluder], now: &[Occluder]) -> Vec<bspvt::Change> {
    let old: HashMap<[u32; 3], &Occluder> = then.iter().map(|o| (o.id, o)).collect();
    let new: HashMap<[u32; 3], (usize, &Occluder)> = now.iter().enumerate().map(|(i, o)| (o.id, (i, o))).collect();
    let bounds = |o: &Occluder| {
        let (lo, hi) = (Vec3::from_slice(&o.bounds[..3]), Vec3::from_slice(&o.bounds[3..]));
        (lo - padding(o), hi + padding(o))
    };
    let mut ids: Vec<[u32; 3]> = old.keys().chain(new.keys()).copied().collect();
    ids.sort_unstable();
    ids.dedup();
    ids.into_iter()
        .filter(|id| old.get(id).copied() != new.get(id).map(|n| n.1))
        .map(|id| bspvt::Change {
            before: old.get(&id).map(|o| bounds(o)),
            after: new.get(&id).map(|&(i, o)| (bounds(o), i)),
        })
        .collect()
}

/// How far a changed occluder's boxes are grown: rays' offset origins differ from the vertex.
pub(super) fn padding(o: &Occluder) -> Vec3 {
    let (lo, hi) = (Vec3::from_slice(&o.bounds[..3]), Vec3::from_slice(&o.bounds[3..]));
    Vec3::splat(1e-4 * (hi - lo).length() + 1e-5)
}

/// Appends a vertex's masks to a lineage entry: u32 count, then (u32 tile, u64 mask) pairs.
pub(super) fn encode_masks(masks: &[(u32, u64)], out: &mut Vec<u8>) {
    out.extend_from_slice(&(masks.len() as u32).to_le_bytes());
    for (tile, mask) in masks {
        out.extend_from_slice(&tile.to_le_bytes());
        out.extend_from_slice(&mask.to_le_bytes());
    }
}

/// What a lineage entry remembers of a chunk's last bake.
pub(super) struct Then {
    /// The artefact's key.
    pub(super) key: Key,
    /// The occluder snapshot it saw.
    pub(super) occluders: Vec<Occluder>,
    /// Its vertices' position and normal bits ([`crate::plan::vertex_bits`]).
    pub(super) vertices: Vec<[u32; 6]>,
    /// Its vertices' visible-texel masks.
    pub(super) masks: Vec<bspvt::tree::Masks>,
}

/// A lineage entry: magic, artefact key, occluder snapshot (u32 length, then its bytes),
/// u32 vertex count, each vertex's bits, then each vertex's masks (`None` when malformed or
/// of an older layout).
pub(super) fn decode_lineage(entry: &[u8]) -> Option<Then> {
    let rest = entry.strip_prefix(LINEAGE_MAGIC)?;
    let key = Key::from_slice(rest.get(..32)?);
    let len = u32::from_le_bytes(rest.get(32..36)?.try_into().ok()?) as usize;
    let occluders = decode_occluders(rest.get(36..36usize.checked_add(len)?)?)?;
    let mut at = &rest[36 + len..];
    let mut take = |n: usize| -> Option<&[u8]> {
        let (head, tail) = at.split_at_checked(n)?;
        at = tail;
        Some(head)
    };
    let count = u32::from_le_bytes(take(4)?.try_into().ok()?) as usize;
    let bits = take(count.checked_mul(24)?)?;
    let vertices = bits.chunks_exact(24).map(bytemuck::pod_read_unaligned::<[u32; 6]>).collect();
    let mut masks = Vec::with_capacity(count);
    for _ in 0..count {
        let n = u32::from_le_bytes(take(4)?.try_into().ok()?) as usize;
        let pairs = take(n.checked_mul(12)?)?;
        masks.push(
            pairs
                .chunks_exact(12)
                .map(|c| {
                    (
                        u32::from_le_bytes(c[..4].try_into().expect("4")),
                        u64::from_le_bytes(c[4..].try_into().expect("8")),
                    )
                })
                .collect(),
        );
    }
    at.is_empty().then_some(Then { key, occluders, vertices, masks })
}
