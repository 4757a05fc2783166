//! Tile subtrees already built, shared by a bake's workers and kept between bakes.
//!
//! Algorithm 1 inside a tile (see [`super::node::TILE`]) is a pure function of the tile's place
//! in its face, which of its texels are above the horizon and visible, the face resolution and
//! ε — and the same patterns recur across thousands of vertices (a shadow edge crosses an 8×8
//! tile in few ways): on the shipped scenes only 10–50 % of the mixed tiles a bake meets are
//! distinct. The memo maps a tile's key to its subtree; a hit returns exactly what a build
//! would, so a bake's bytes never depend on what the memo held (determinism), only its time.
//! Mirror images of a tile share one entry (see [`super::symmetry`]): the memo holds each
//! orbit's least key and maps its subtree to the tile asked for (`tree::memoised_subtree`).
//! The bake database stores the memo between runs (see [`SubtreeMemo::to_bytes`]): a re-bake
//! after an edit finds most of the tiles the edit changed already built.

use super::node::{Node, TILE, TileKey};
use super::symmetry::{Symmetric, Symmetry};
use super::{ALGORITHM_VERSION, Settings};
use crate::math::cubemap;
use std::collections::HashMap;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Entries at most (a subtree has at most 127 nodes of 8 bytes, so memory stays bounded): a
/// bigger bake just stops adding entries.
const CAPACITY: usize = 1 << 20;

/// First bytes of [`SubtreeMemo::to_bytes`] (its layout's version).
const MAGIC: &[u8; 4] = b"kgt1";

/// Subtrees by tile key, for one (face resolution, ε) and [`ALGORITHM_VERSION`], and the texel
/// weights every build needs.
#[derive(Debug)]
pub struct SubtreeMemo {
    settings: Settings,
    /// Per texel of a face (row-major), its solid angle relative to the face's mean texel:
    /// computed once, as each costs four arc tangents.
    weights: Vec<f64>,
    symmetric: Symmetric,
    map: Mutex<HashMap<TileKey, Vec<Node>>>,
    added: AtomicUsize,
    hits: AtomicUsize,
}

impl SubtreeMemo {
    /// An empty memo for bakes with `settings`.
    pub fn new(settings: &Settings) -> Self {
        let res = settings.res;
        let mean = 4.0 * std::f64::consts::PI / (6 * res * res) as f64;
        let weights = (0..res * res).map(|k| cubemap::texel_solid_angle(k % res, k / res, res) / mean).collect();
        Self {
            settings: *settings,
            weights,
            symmetric: Symmetric::of(res),
            map: Mutex::default(),
            added: AtomicUsize::new(0),
            hits: AtomicUsize::new(0),
        }
    }

    /// Texel (i, j)'s solid angle relative to the face's mean texel.
    pub fn weight(&self, i: usize, j: usize) -> f64 {
        self.weights[j * self.settings.res + i]
    }

    /// The settings its subtrees were built with.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// The least key of `key`'s orbit under the face's symmetries, and the symmetry that maps
    /// that key's subtree to `key`'s.
    pub fn orbit(&self, key: TileKey) -> (TileKey, Symmetry) {
        let (canonical, to) = self.symmetric.canonical(key, self.settings.res.div_ceil(TILE));
        (canonical, to.inverse())
    }

    /// `read` of the subtree of `key`: memoised (read under the memo's lock, not copied), or
    /// made by `build` (and memoised).
    pub fn with_subtree<R>(
        &self,
        key: TileKey,
        build: impl FnOnce() -> Vec<Node>,
        read: impl FnOnce(&[Node]) -> R,
    ) -> R {
        if let Some(nodes) = self.lock().get(&key) {
            self.hits.fetch_add(1, Ordering::Relaxed);
            return read(nodes);
        }
        // Built outside the lock: two workers may build the same tile once each, to equal results.
        let nodes = build();
        let answer = read(&nodes);
        let mut map = self.lock();
        if map.len() < CAPACITY && map.insert(key, nodes).is_none() {
            self.added.fetch_add(1, Ordering::Relaxed);
        }
        answer
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<TileKey, Vec<Node>>> {
        // A worker that panicked mid-insert left a valid map: entries are inserted whole.
        self.map.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The keys held, sorted.
    pub fn keys(&self) -> Vec<TileKey> {
        let mut keys: Vec<TileKey> = self.lock().keys().copied().collect();
        keys.sort_unstable();
        keys
    }

    /// Entries held.
    pub fn len(&self) -> usize {
        self.lock().len()
    }

    /// Whether it holds nothing.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Entries added since it was made or loaded (whether storing it again is worth it).
    pub fn added(&self) -> usize {
        self.added.load(Ordering::Relaxed)
    }

    /// Lookups answered from the memo since it was made or loaded.
    pub fn hits(&self) -> usize {
        self.hits.load(Ordering::Relaxed)
    }

    /// The byte form, entries sorted by key: magic, algorithm version, resolution and ε, entry
    /// count, then per entry the key (u32, u64, u64), the node count (u16) and the nodes (u32
    /// each: a split is `1 << 31 | angle << 12 | offset`, a leaf its non-negative f32's bits),
    /// all little-endian; a blake3 hash of everything before ends it.
    pub fn to_bytes(&self) -> Vec<u8> {
        let map = self.lock();
        let mut entries: Vec<(&TileKey, &Vec<Node>)> = map.iter().collect();
        entries.sort_unstable_by_key(|e| *e.0);
        let mut out = MAGIC.to_vec();
        out.extend_from_slice(&ALGORITHM_VERSION.to_le_bytes());
        out.extend_from_slice(&(self.settings.res as u32).to_le_bytes());
        out.extend_from_slice(&self.settings.epsilon.to_le_bytes());
        out.extend_from_slice(&(entries.len() as u32).to_le_bytes());
        for (&(tile, live, visible), nodes) in entries {
            out.extend_from_slice(&tile.to_le_bytes());
            out.extend_from_slice(&live.to_le_bytes());
            out.extend_from_slice(&visible.to_le_bytes());
            out.extend_from_slice(&(nodes.len() as u16).to_le_bytes());
            nodes.iter().for_each(|n| out.extend_from_slice(&encode_node(n).to_le_bytes()));
        }
        let hash = blake3::hash(&out);
        out.extend_from_slice(hash.as_bytes());
        out
    }

    /// Reads [`Self::to_bytes`] back; `None` (an unusable memo: start empty) when the bytes
    /// are damaged or were made for other settings or another algorithm version.
    pub fn from_bytes(settings: &Settings, bytes: &[u8]) -> Option<Self> {
        let (body, hash) = bytes.split_at_checked(bytes.len().checked_sub(32)?)?;
        if blake3::hash(body).as_bytes() != hash {
            return None;
        }
        let mut r = Reader(body);
        let header_ok = r.take(4)? == MAGIC
            && r.u32()? == ALGORITHM_VERSION
            && r.u32()? as usize == settings.res
            && f64::from_bits(r.u64()?) == settings.epsilon;
        if !header_ok {
            return None;
        }
        let count = r.u32()? as usize;
        let mut map = HashMap::with_capacity(count.min(CAPACITY));
        for _ in 0..count {
            let key = (r.u32()?, r.u64()?, r.u64()?);
            let len = u16::from_le_bytes(r.take(2)?.try_into().ok()?) as usize;
            let nodes = (0..len).map(|_| r.u32().map(decode_node)).collect::<Option<Vec<Node>>>()?;
            map.insert(key, nodes);
        }
        let memo = Self::new(settings);
        *memo.lock() = map;
        r.0.is_empty().then_some(memo)
    }
}

fn encode_node(n: &Node) -> u32 {
    match *n {
        Node::Split { angle, offset } => 1 << 31 | (angle as u32) << 12 | offset as u32,
        Node::Leaf(v) => v.to_bits(),
    }
}

/// The inverse of [`encode_node`].
fn decode_node(bits: u32) -> Node {
    if bits >> 31 == 1 {
        Node::Split { angle: ((bits >> 12) & 0x7FF) as u16, offset: (bits & 0xFFF) as u16 }
    } else {
        Node::Leaf(f32::from_bits(bits))
    }
}

/// Little-endian fields off the front of a byte slice.
struct Reader<'a>(&'a [u8]);

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let (head, rest) = self.0.split_at_checked(n)?;
        self.0 = rest;
        Some(head)
    }

    fn u32(&mut self) -> Option<u32> {
        Some(u32::from_le_bytes(self.take(4)?.try_into().ok()?))
    }

    fn u64(&mut self) -> Option<u64> {
        Some(u64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn filled(s: &Settings) -> SubtreeMemo {
        let memo = SubtreeMemo::new(s);
        let subtree = vec![Node::Split { angle: 2047, offset: 4094 }, Node::Leaf(0.0), Node::Leaf(0.37)];
        memo.with_subtree((3, u64::MAX, 0x0F0F), || subtree, |_| ());
        let other = || vec![Node::Split { angle: 0, offset: 0 }, Node::Leaf(1.0), Node::Leaf(0.5)];
        memo.with_subtree((0, 0xFF, 0x1), other, |_| ());
        memo
    }

    /// A second lookup is a hit returning the first build; the build closure is not run.
    #[test]
    fn a_hit_returns_what_was_built() {
        let memo = filled(&Settings::default());
        let again = memo.with_subtree((3, u64::MAX, 0x0F0F), || panic!("a hit must not build"), <[Node]>::to_vec);
        assert_eq!(again[2], Node::Leaf(0.37));
        assert_eq!((memo.len(), memo.added(), memo.hits()), (2, 2, 1));
    }

    /// Bytes round-trip exactly; damage, other settings or a truncated file give `None`.
    #[test]
    fn bytes_round_trip_and_reject_damage() {
        let s = Settings::default();
        let memo = filled(&s);
        let bytes = memo.to_bytes();
        let back = SubtreeMemo::from_bytes(&s, &bytes).expect("round trip");
        assert_eq!(*back.lock(), *memo.lock());
        assert_eq!((back.added(), back.to_bytes()), (0, bytes.clone()));
        let mut flipped = bytes.clone();
        flipped[30] ^= 1;
        assert!(SubtreeMemo::from_bytes(&s, &flipped).is_none(), "a flipped bit");
        assert!(SubtreeMemo::from_bytes(&s, &bytes[..bytes.len() - 1]).is_none(), "truncated");
        assert!(SubtreeMemo::from_bytes(&s, &[]).is_none(), "empty");
        assert!(SubtreeMemo::from_bytes(&Settings { epsilon: 1.0, ..s }, &bytes).is_none(), "other ε");
        assert!(SubtreeMemo::from_bytes(&Settings { res: 32, ..s }, &bytes).is_none(), "other resolution");
    }
}
