//! A mesh instance's baked vertex records, as a bake stores them and a pack carries them.

use super::{layout, node};

/// Baked trees of one mesh instance: vertex `v`'s record is `data[offsets[v]..offsets[v + 1]]`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BakedInstance {
    /// Record offsets (one more than vertices).
    pub offsets: Vec<u32>,
    /// Concatenated vertex records (see [`layout`]).
    pub data: Vec<u8>,
}

impl BakedInstance {
    /// The record of vertex `v`.
    pub fn record(&self, v: usize) -> &[u8] {
        &self.data[self.offsets[v] as usize..self.offsets[v + 1] as usize]
    }

    /// Vertices held.
    pub fn vertices(&self) -> usize {
        self.offsets.len() - 1
    }

    /// An instance of `vertices` records that all see their whole hemisphere: what unshadowed
    /// LTC computes, the placeholder while the trees bake.
    pub fn unshadowed(vertices: usize) -> Self {
        let open = layout::encode_vertex(&std::array::from_fn(|_| Some(vec![node::Node::Leaf(1.0)])));
        Self { offsets: (0..=vertices).map(|v| (v * open.len()) as u32).collect(), data: open.repeat(vertices) }
    }

    /// Replaces the records of vertices `first..first + records.len()` (which must exist).
    pub fn splice(&mut self, first: usize, records: &[Vec<u8>]) {
        let end = first + records.len();
        let (a, b) = (self.offsets[first] as usize, self.offsets[end] as usize);
        let fresh: Vec<u8> = records.concat();
        let shift = fresh.len() as i64 - (b - a) as i64;
        self.data.splice(a..b, fresh);
        let mut at = a as u32;
        for (k, r) in records.iter().enumerate() {
            self.offsets[first + k] = at;
            at += r.len() as u32;
        }
        self.offsets[end..].iter_mut().for_each(|o| *o = (*o as i64 + shift) as u32);
    }
}
