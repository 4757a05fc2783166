//! A [`SceneBvh`] as bytes, so that a caller can keep BVHs between runs (the bake database
//! does, keyed by the triangles: an edit that moves one instance rebuilds that instance's BVH
//! alone).
//!
//! obvhs' build is deterministic, so a restored BVH is the one a build would give and answers
//! every ray exactly as it would. Restoring trusts nothing it reads: the bytes end with a
//! blake3 hash of themselves, and every index traversal follows is checked to stay inside its
//! array, so damaged bytes give `None` (build again), never a panic or a wrong answer from a
//! walk outside the tree.

use super::SceneBvh;
use glam::Vec3;
use obvhs::aabb::Aabb;
use obvhs::cwbvh::{CwBvh, node::CwBvhNode};

/// First bytes (the layout's version).
const MAGIC: &[u8; 4] = b"kbv1";

/// obvhs' traversal stack holds this many node groups; a deeper tree would overwrite its top.
const TRAVERSAL_STACK: usize = 32;

/// Fixed-size head: magic, node count, primitive-index count, spatial-split flag, bounds.
const HEAD: usize = 4 + 4 + 4 + 4 + size_of::<Aabb>();

impl SceneBvh {
    /// The BVH as bytes that [`Self::from_bytes`] restores exactly, given the same triangles.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = MAGIC.to_vec();
        out.extend_from_slice(&(self.bvh.nodes.len() as u32).to_le_bytes());
        out.extend_from_slice(&(self.bvh.primitive_indices.len() as u32).to_le_bytes());
        out.extend_from_slice(&u32::from(self.bvh.uses_spatial_splits).to_le_bytes());
        out.extend_from_slice(bytemuck::bytes_of(&self.bvh.total_aabb));
        out.extend_from_slice(bytemuck::cast_slice(&self.bvh.nodes));
        out.extend_from_slice(bytemuck::cast_slice(&self.bvh.primitive_indices));
        let hash = blake3::hash(&out);
        out.extend_from_slice(hash.as_bytes());
        out
    }

    /// The BVH [`Self::to_bytes`] wrote for a build over `triangles`; `None` when the bytes are
    /// damaged, of another layout, or not a tree over that many triangles that traversal can
    /// walk. The caller keys the bytes by the triangles: these are only counted here.
    pub fn from_bytes(triangles: &[[Vec3; 3]], bytes: &[u8]) -> Option<Self> {
        let (body, hash) = bytes.split_at_checked(bytes.len().checked_sub(32)?)?;
        if blake3::hash(body).as_bytes() != hash || body.get(..4)? != MAGIC || body.len() < HEAD {
            return None;
        }
        let word = |at: usize| u32::from_le_bytes(body[at..at + 4].try_into().expect("4 bytes")) as usize;
        let (nodes, indices, splits) = (word(4), word(8), word(12));
        let node_bytes = nodes.checked_mul(size_of::<CwBvhNode>())?;
        let (nodes, rest) = body[HEAD..].split_at_checked(node_bytes)?;
        if rest.len() != indices.checked_mul(4)? || splits > 1 {
            return None;
        }
        let bvh = CwBvh {
            nodes: bytemuck::pod_collect_to_vec(nodes),
            primitive_indices: bytemuck::pod_collect_to_vec(rest),
            total_aabb: bytemuck::pod_read_unaligned(&body[16..HEAD]),
            exact_node_aabbs: None,
            uses_spatial_splits: splits == 1,
        };
        walkable(&bvh, triangles.len()).then(|| Self::from_parts(bvh, triangles))
    }
}

/// Whether traversal stays inside `bvh`'s arrays: every primitive index names one of
/// `triangles`, every node is reached once from the root (a tree: no cycle), no deeper than
/// obvhs' traversal stack, with its internal children inside the node array and its leaves'
/// primitives inside the index array (at offsets below 24, where their hit bits live).
fn walkable(bvh: &CwBvh, triangles: usize) -> bool {
    if bvh.nodes.is_empty() || bvh.primitive_indices.iter().any(|&i| i as usize >= triangles) {
        return false;
    }
    let mut seen = vec![false; bvh.nodes.len()];
    let mut stack = vec![(0usize, 1usize)];
    while let Some((i, depth)) = stack.pop() {
        if depth >= TRAVERSAL_STACK || std::mem::replace(&mut seen[i], true) {
            return false;
        }
        let node = &bvh.nodes[i];
        let first = node.child_base_idx as usize;
        let internal = node.imask.count_ones() as usize;
        if first.checked_add(internal).is_none_or(|end| end > bvh.nodes.len()) {
            return false;
        }
        for c in (0..8).filter(|&c| !node.is_child_empty(c)) {
            let meta = node.child_meta[c];
            if node.imask & (1 << c) != 0 {
                if meta & 0b11111 < 24 {
                    return false;
                }
            } else {
                let (offset, count) = ((meta & 0b11111) as usize, (meta >> 5).count_ones() as usize);
                let end = node.primitive_base_idx as usize + offset + count;
                if offset + count > 24 || end > bvh.primitive_indices.len() {
                    return false;
                }
            }
        }
        stack.extend((first..first + internal).map(|child| (child, depth + 1)));
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::Rng as _;

    /// A bumpy grid of `n × n` quads: enough triangles for a tree of several levels.
    fn terrain(n: usize) -> Vec<[Vec3; 3]> {
        crate::accel::grid_triangles(n, |i, j| Vec3::new(i as f32, ((i * 7 + j * 13) % 5) as f32 * 0.2, j as f32))
    }

    /// The round trip restores the same tree, and it answers random rays as the build does.
    #[test]
    fn restored_bvh_equals_the_built_one() {
        let tris = terrain(40);
        let built = SceneBvh::new(&tris);
        let restored = SceneBvh::from_bytes(&tris, &built.to_bytes()).expect("round trip");
        assert!(built.bvh.nodes == restored.bvh.nodes && built.bvh.primitive_indices == restored.bvh.primitive_indices);
        assert!(built.tris == restored.tris && built.bvh.total_aabb == restored.bvh.total_aabb);
        assert_eq!(restored.to_bytes(), built.to_bytes());
        let mut rng = crate::math::rng::seeded(11);
        for _ in 0..2000 {
            let o = Vec3::new(rng.random_range(-5.0..45.0), 3.0, rng.random_range(-5.0..45.0));
            let d = Vec3::new(rng.random_range(-1.0..1.0), -1.0, rng.random_range(-1.0..1.0)).normalize();
            assert_eq!(built.closest_hit(o, d, 100.0), restored.closest_hit(o, d, 100.0));
            assert_eq!(built.occluded(o, d, 100.0), restored.occluded(o, d, 100.0));
        }
    }

    /// Damaged bytes, bytes for fewer triangles, and trees traversal could not walk are refused.
    #[test]
    fn damaged_or_foreign_bytes_are_refused() {
        let tris = terrain(12);
        let bvh = SceneBvh::new(&tris);
        let bytes = bvh.to_bytes();
        for cut in [0, 20, bytes.len() / 2, bytes.len() - 1] {
            assert!(SceneBvh::from_bytes(&tris, &bytes[..cut]).is_none(), "cut at {cut}");
        }
        let mut flipped = bytes.clone();
        flipped[HEAD + 3] ^= 1;
        assert!(SceneBvh::from_bytes(&tris, &flipped).is_none());
        assert!(SceneBvh::from_bytes(&tris[..tris.len() / 2], &bytes).is_none(), "indices past the triangles");
        // Well hashed but unwalkable: a child outside the node array, a cycle, a leaf past
        // the indices.
        let rehashed = |bvh: CwBvh| {
            SceneBvh::from_bytes(&tris, &SceneBvh { bvh, tris: Vec::new(), holes: Default::default() }.to_bytes())
        };
        let mut far = bvh.bvh.clone();
        far.nodes[0].child_base_idx = far.nodes.len() as u32;
        assert!(rehashed(far).is_none());
        let mut cycle = bvh.bvh.clone();
        cycle.nodes[0].child_base_idx = 0;
        assert!(rehashed(cycle).is_none());
        let mut leaf = bvh.bvh.clone();
        let has_leaf = |n: &CwBvhNode| (0..8).any(|c| !n.is_child_empty(c) && n.imask & (1 << c) == 0);
        let at = leaf.nodes.iter().position(has_leaf).expect("a node with a leaf child");
        leaf.nodes[at].primitive_base_idx = leaf.primitive_indices.len() as u32;
        assert!(rehashed(leaf).is_none());
        assert!(rehashed(bvh.bvh.clone()).is_some(), "the unchanged tree rehashed is accepted");
    }
}
