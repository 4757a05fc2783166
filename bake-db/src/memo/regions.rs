//! Where a re-refined occluder changed. Receiver refinement run again after an edit gives a
//! curved receiver (lifted off its source, so it occludes as refined: see
//! [`kage_engine::scene::SourceMesh`]) another mesh that differs only where the shadows on it
//! changed. A warm BSPVT re-bake then need not look again at every texel that sees the whole
//! occluder, only at those that see the triangles that changed: at most [`MAX_REGIONS`] boxes
//! around them. The triangles of every such mesh are kept in the store's memos, named by the
//! occluder's hash, so that the next edit can compare its own with them.
//!
//! Like every memo they cost only time: an entry checks its own hash, and without one (never
//! stored, damaged, or dropped by `gc`) the occluder's whole bounds count as changed.

use super::codec::{Reader, Writer};
use crate::store::{Memo, Result, Store};
use glam::{Affine3A, Vec3};
use kage_engine::scene::FlatScene;
use std::collections::{HashMap, HashSet};

/// Most boxes a changed occluder is split into: each is one more box every vertex's re-bake
/// tests its tiles against.
pub const MAX_REGIONS: usize = 16;

/// How the names of these memos start. They are named by their content, so every database
/// that holds one holds the same bytes under it, and a merge carries them (`Store::merge_from`).
pub const PREFIX: &str = "occluder triangles ";

/// The memo name of the triangles of the occluder whose hash is `occluder`.
pub fn name(occluder: &[u8; 32]) -> String {
    let hex: String = occluder.iter().map(|b| format!("{b:02x}")).collect();
    format!("{PREFIX}{hex}")
}

/// Whether instance `i` occludes with a refinement of its mesh that lifted vertices, solid (a
/// cut-out's mask can change what it occludes without any triangle changing).
fn lifted(flat: &FlatScene, i: usize) -> bool {
    let inst = &flat.instances[i];
    inst.mesh != inst.source && inst.occluder == inst.mesh && inst.maps.cutout.is_none()
}

/// The memos to keep for `flat`: the triangles (mesh frame) of every lifted occluder the store
/// lacks.
pub fn memos(store: &Store, flat: &FlatScene) -> Result<Vec<Memo>> {
    let mut out: Vec<Memo> = Vec::new();
    for i in (0..flat.instances.len()).filter(|&i| lifted(flat, i)) {
        let n = name(&flat.occluder_hash(i));
        if out.iter().any(|(m, _)| *m == n) || store.has_memo(&n)? {
            continue;
        }
        out.push((n, to_bytes(&local_triangles(flat, i))));
    }
    Ok(out)
}

/// The boxes (world frame, padded by `pad`) that hold what changed between the occluder whose
/// hash was `old` and instance `i` of `flat`, placed by `world` both times; `None` when the
/// store lacks the old triangles or instance `i` is not a lifted occluder.
pub fn changed(
    store: &Store,
    flat: &FlatScene,
    (old, i): (&[u8; 32], usize),
    world: &Affine3A,
    pad: Vec3,
) -> Result<Option<Vec<(Vec3, Vec3)>>> {
    if !lifted(flat, i) {
        return Ok(None);
    }
    let Some(before) = store.memo(&name(old))?.and_then(|b| from_bytes(&b)) else { return Ok(None) };
    Ok(Some(regions(&before, &local_triangles(flat, i), world, pad)))
}

/// Instance `i`'s occluding triangles in its mesh's frame, winding as stored.
fn local_triangles(flat: &FlatScene, i: usize) -> Vec<[Vec3; 3]> {
    let mesh = flat.occluder_mesh(i);
    mesh.triangles.iter().map(|t| t.map(|v| mesh.positions[v as usize])).collect()
}

/// At most [`MAX_REGIONS`] boxes, placed by `world` and padded by `pad`, holding every
/// triangle of `a` not in `b` and of `b` not in `a` (the same corners, from any one of them):
/// one box per connected patch of changed triangles (sharing a corner), the two whose merged
/// box is smallest merged while there are too many — a moved shadow's patch stays one tight
/// box, and a few triangles changed far away (where the budget's cut moved) their own.
pub fn regions(a: &[[Vec3; 3]], b: &[[Vec3; 3]], world: &Affine3A, pad: Vec3) -> Vec<(Vec3, Vec3)> {
    let (in_a, in_b): (HashSet<_>, HashSet<_>) = (a.iter().map(canonical).collect(), b.iter().map(canonical).collect());
    let changed: Vec<&[Vec3; 3]> = a
        .iter()
        .filter(|t| !in_b.contains(&canonical(t)))
        .chain(b.iter().filter(|t| !in_a.contains(&canonical(t))))
        .collect();
    let mut boxes = patches(&changed, world);
    while boxes.len() > MAX_REGIONS {
        let merged = |(i, j): (usize, usize)| union(boxes[i], boxes[j]);
        let pairs = (0..boxes.len()).flat_map(|i| (i + 1..boxes.len()).map(move |j| (i, j)));
        let (i, j) = pairs
            .min_by(|&x, &y| {
                let size = |p| {
                    let (lo, hi) = merged(p);
                    (hi - lo).length()
                };
                size(x).total_cmp(&size(y))
            })
            .expect("more than one box");
        boxes[i] = merged((i, j));
        boxes.swap_remove(j);
    }
    boxes.into_iter().map(|(lo, hi)| (lo - pad, hi + pad)).collect()
}

/// The world bounds of each connected patch of `triangles` (triangles sharing a corner, bit
/// for bit), in a fixed order.
fn patches(triangles: &[&[Vec3; 3]], world: &Affine3A) -> Vec<(Vec3, Vec3)> {
    let mut parent: Vec<usize> = (0..triangles.len()).collect();
    fn root(parent: &mut [usize], mut k: usize) -> usize {
        while parent[k] != k {
            parent[k] = parent[parent[k]];
            k = parent[k];
        }
        k
    }
    let mut first: HashMap<[u32; 3], usize> = HashMap::new();
    for (k, t) in triangles.iter().enumerate() {
        for p in t.iter() {
            let other = *first.entry(p.to_array().map(f32::to_bits)).or_insert(k);
            let (x, y) = (root(&mut parent, k), root(&mut parent, other));
            parent[x.max(y)] = x.min(y);
        }
    }
    let mut by_root: HashMap<usize, (Vec3, Vec3)> = HashMap::new();
    for (k, t) in triangles.iter().enumerate() {
        let w = t.map(|p| world.transform_point3(p));
        let tri = (w[0].min(w[1]).min(w[2]), w[0].max(w[1]).max(w[2]));
        let r = root(&mut parent, k);
        by_root.entry(r).and_modify(|b| *b = union(*b, tri)).or_insert(tri);
    }
    let mut boxes: Vec<(Vec3, Vec3)> = by_root.into_values().collect();
    boxes.sort_by_key(|(lo, hi)| (lo.to_array().map(f32::to_bits), hi.to_array().map(f32::to_bits)));
    boxes
}

/// The box holding two boxes.
fn union(a: (Vec3, Vec3), b: (Vec3, Vec3)) -> (Vec3, Vec3) {
    (a.0.min(b.0), a.1.max(b.1))
}

/// A triangle as its corners' bits, starting at its smallest corner (winding kept): the same
/// triangle listed from another corner is the same key.
fn canonical(t: &[Vec3; 3]) -> [[u32; 3]; 3] {
    let c = t.map(|p| p.to_array().map(f32::to_bits));
    let first = (0..3).min_by_key(|&k| c[k]).expect("three corners");
    std::array::from_fn(|k| c[(first + k) % 3])
}

/// Triangles as their f32 corners, sealed ([`super::codec`]).
fn to_bytes(triangles: &[[Vec3; 3]]) -> Vec<u8> {
    Writer::default().pod(triangles).seal()
}

/// The inverse of [`to_bytes`]; `None` when the hash does not hold.
fn from_bytes(bytes: &[u8]) -> Option<Vec<[Vec3; 3]>> {
    let mut r = Reader::open(bytes)?;
    let triangles = r.rest()?;
    r.end(triangles)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An n × n grid of unit cells, two triangles each, its vertices at height `lift(x, z)`.
    fn grid(n: usize, lift: impl Fn(usize, usize) -> f32) -> Vec<[Vec3; 3]> {
        let p = |x: usize, z: usize| Vec3::new(x as f32, lift(x, z), z as f32);
        let mut out = Vec::new();
        for (x, z) in (0..n).flat_map(|x| (0..n).map(move |z| (x, z))) {
            out.push([p(x, z), p(x + 1, z), p(x + 1, z + 1)]);
            out.push([p(x, z), p(x + 1, z + 1), p(x, z + 1)]);
        }
        out
    }

    /// Only the triangles that changed are boxed, wherever they are in the lists and from
    /// whichever corner they are listed; the boxes hold them all.
    #[test]
    fn regions_hold_exactly_what_changed() {
        let before = grid(20, |_, _| 0.0);
        let bump = |x: usize, z: usize| if (3..6).contains(&x) && (14..17).contains(&z) { 0.5 } else { 0.0 };
        let mut after = grid(20, bump);
        after.reverse();
        after.iter_mut().step_by(3).for_each(|t| t.rotate_left(1));
        let world = Affine3A::from_translation(Vec3::new(10.0, 0.0, 0.0));
        let boxes = regions(&before, &after, &world, Vec3::ZERO);
        assert!(!boxes.is_empty() && boxes.len() <= MAX_REGIONS);
        let (lo, hi) = boxes.iter().copied().reduce(|x, y| (x.0.min(y.0), x.1.max(y.1))).unwrap();
        // The bumped vertices' triangles reach one cell around them.
        assert_eq!((lo, hi), (Vec3::new(12.0, 0.0, 13.0), Vec3::new(16.0, 0.5, 17.0)));
        assert!(regions(&before, &before, &world, Vec3::ZERO).is_empty());
        // Two patches far apart are two boxes: the ground between them is not re-baked.
        let two = grid(20, |x, z| if (x, z) == (2, 2) || (x, z) == (17, 17) { 0.5 } else { 0.0 });
        let boxes = regions(&before, &two, &Affine3A::IDENTITY, Vec3::ZERO);
        assert_eq!(boxes.len(), 2, "{boxes:?}");
        assert!(boxes.iter().all(|(lo, hi)| (*hi - *lo).max_element() <= 2.0), "{boxes:?}");
    }

    #[test]
    fn triangles_round_trip_and_damage_is_refused() {
        let t = grid(3, |x, z| (x * z) as f32);
        let mut bytes = to_bytes(&t);
        assert_eq!(from_bytes(&bytes), Some(t));
        bytes[5] ^= 1;
        assert_eq!(from_bytes(&bytes), None);
        assert_eq!(from_bytes(&bytes[..10]), None);
    }
}
