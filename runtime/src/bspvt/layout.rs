//! The compact, versioned binary layout of baked BSPVT data.
//!
//! Per vertex: six little-endian `u16` byte lengths (one per cube face; 0 = no tree: the face
//! is entirely below the horizon), then each face's tree in pre-order:
//! - a **leaf** is 1 byte, top bit 0: the mean visibility quantised to 7 bits (v̄ · 127);
//! - a **split** is 3 bytes, big-endian, top bit 1: 11 bits of angle θ ∈ [0, 2π) and 12 bits of
//!   offset c ∈ [−√2, √2] (code q ↦ (q − 2047)/2047 · √2) of the line `cos θ · s + sin θ · t = c`; the positive side's subtree
//!   follows, then the negative side's.
//!
//! A tree with L leaves has L − 1 splits: (L + 3(L − 1)) bytes ≈ 4 bytes per leaf, 2 bytes per
//! node on average.
//!
//! When some face holds occluders a light could be in front of, the trees are followed by six
//! more `u16` lengths and each face's depth bytes ([`super::depth`]); a record without them
//! (all depths empty, or baked before format 2) has its occluders at no known distance.

use super::node::Node;

/// Bumped whenever the layout or the baking algorithm changes what is stored (2: depth after
/// the trees).
pub const FORMAT_VERSION: u32 = 2;

/// The cube-face resolutions kage bakes and reads.
pub const FACE_RESOLUTIONS: std::ops::RangeInclusive<usize> = 4..=1024;

/// Index just past the encoded subtree that starts at byte `i` of a face's bytes.
pub fn skip_encoded(bytes: &[u8], mut i: usize) -> usize {
    let mut pending = 1;
    while pending > 0 {
        pending -= 1;
        if bytes[i] & 0x80 == 0 {
            i += 1;
        } else {
            pending += 2;
            i += 3;
        }
    }
    i
}

/// Appends one tree.
pub fn encode_tree(nodes: &[Node], out: &mut Vec<u8>) {
    for n in nodes {
        match *n {
            Node::Leaf(v) => out.push((v.clamp(0.0, 1.0) * 127.0).round() as u8),
            Node::Split { angle, offset } => {
                let bits = 0x80_0000u32 | ((angle as u32) << 12) | offset as u32;
                out.extend_from_slice(&bits.to_be_bytes()[1..]);
            }
        }
    }
}

/// The (angle, offset) codes of the split starting at byte `i` (its top bit must be set).
pub fn split_codes(bytes: &[u8], i: usize) -> (u16, u16) {
    let bits = u32::from_be_bytes([0, bytes[i], bytes[i + 1], bytes[i + 2]]);
    (((bits >> 12) & 0x7FF) as u16, (bits & 0xFFF) as u16)
}

/// Decodes one tree.
pub fn decode_tree(bytes: &[u8]) -> Vec<Node> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] & 0x80 == 0 {
            out.push(Node::Leaf(bytes[i] as f32 / 127.0));
            i += 1;
        } else {
            let (angle, offset) = split_codes(bytes, i);
            out.push(Node::Split { angle, offset });
            i += 3;
        }
    }
    out
}

/// Encodes a vertex record from its six optional face trees.
pub fn encode_vertex(faces: &[Option<Vec<Node>>; 6]) -> Vec<u8> {
    let trees: [Vec<u8>; 6] = std::array::from_fn(|f| encode_face(faces[f].as_deref()));
    join_faces(trees.each_ref().map(Vec::as_slice))
}

/// The bytes of one face's tree (empty for no tree).
pub fn encode_face(nodes: Option<&[Node]>) -> Vec<u8> {
    let mut t = Vec::new();
    if let Some(nodes) = nodes {
        encode_tree(nodes, &mut t);
    }
    t
}

/// A vertex record from six encoded face trees (the inverse of [`vertex_faces`]).
pub fn join_faces(trees: [&[u8]; 6]) -> Vec<u8> {
    let mut out = Vec::with_capacity(12 + trees.iter().map(|t| t.len()).sum::<usize>());
    for t in &trees {
        out.extend_from_slice(&(t.len() as u16).to_le_bytes());
    }
    trees.iter().for_each(|t| out.extend_from_slice(t));
    out
}

/// `record` (six face trees, [`join_faces`]) followed by six faces' depth bytes when one is
/// not empty.
pub fn with_depths(mut record: Vec<u8>, depths: [&[u8]; 6]) -> Vec<u8> {
    if depths.iter().any(|d| !d.is_empty()) {
        depths.iter().for_each(|d| record.extend_from_slice(&(d.len() as u16).to_le_bytes()));
        depths.iter().for_each(|d| record.extend_from_slice(d));
    }
    record
}

/// The six faces' depth bytes of a well-formed vertex record (all empty when it has none).
pub fn vertex_depths(record: &[u8]) -> [&[u8]; 6] {
    let trees: usize =
        12 + (0..6).map(|f| u16::from_le_bytes([record[2 * f], record[2 * f + 1]]) as usize).sum::<usize>();
    match record.get(trees..) {
        Some(rest) if rest.len() >= 12 => vertex_faces(rest),
        _ => [&record[0..0]; 6],
    }
}

/// The six face trees of a vertex record, as byte slices (empty = no tree).
pub fn vertex_faces(record: &[u8]) -> [&[u8]; 6] {
    let mut faces = [&record[0..0]; 6];
    let mut at = 12;
    for (f, face) in faces.iter_mut().enumerate() {
        let len = u16::from_le_bytes([record[2 * f], record[2 * f + 1]]) as usize;
        *face = &record[at..at + len];
        at += len;
    }
    faces
}

/// (Leaves, nodes) of a well-formed vertex record: a tree of L leaves is 4L − 3 bytes.
pub fn tree_counts(record: &[u8]) -> (usize, usize) {
    let leaves: usize = vertex_faces(record).iter().filter(|t| !t.is_empty()).map(|t| t.len().div_ceil(4)).sum();
    let trees = vertex_faces(record).iter().filter(|t| !t.is_empty()).count();
    (leaves, 2 * leaves - trees)
}

/// Deepest tree [`check_record`] accepts: a chain over every texel of a 64² face. Deeper
/// input (never baked by kage) would only exhaust the stack of the recursive descent.
pub const MAX_DEPTH: usize = 4096;

/// Checks that `record` is a well-formed vertex record at face resolution `res` (data read
/// from outside, e.g. an asset pack): a 12-byte header whose six face lengths add up to the
/// trees, each face empty or one complete pre-order tree no deeper than [`MAX_DEPTH`], then
/// nothing or six depth lengths adding up to the rest, each face's depth well-formed
/// ([`super::depth::check_face`]).
pub fn check_record(record: &[u8], res: usize) -> Result<(), String> {
    let trees = check_trees(record)?;
    let rest = &record[trees..];
    if rest.is_empty() {
        return Ok(());
    }
    let lengths = check_lengths(rest).map_err(|e| format!("depth: {e}"))?;
    let mut at = 12;
    for (f, len) in lengths.into_iter().enumerate() {
        super::depth::check_face(&rest[at..at + len], res).map_err(|e| format!("face {f} depth: {e}"))?;
        at += len;
    }
    Ok(())
}

/// The six lengths of a 12-byte header that add up to the rest of `bytes`.
fn check_lengths(bytes: &[u8]) -> Result<[usize; 6], String> {
    if bytes.len() < 12 {
        return Err(format!("{} bytes, shorter than the 12-byte header", bytes.len()));
    }
    let lengths: [usize; 6] = std::array::from_fn(|f| u16::from_le_bytes([bytes[2 * f], bytes[2 * f + 1]]) as usize);
    let total: usize = lengths.iter().sum();
    if 12 + total != bytes.len() {
        return Err(format!("the face lengths add up to {total} bytes, the record holds {}", bytes.len() - 12));
    }
    Ok(lengths)
}

/// Checks a record's header and trees; returns where they end.
fn check_trees(record: &[u8]) -> Result<usize, String> {
    let header = record.get(..12).ok_or_else(|| format!("{} bytes, shorter than the 12-byte header", record.len()))?;
    let end = 12 + (0..6).map(|f| u16::from_le_bytes([header[2 * f], header[2 * f + 1]]) as usize).sum::<usize>();
    let lengths = check_lengths(record.get(..end).unwrap_or(record))?;
    let mut at = 12;
    for (f, len) in lengths.into_iter().enumerate() {
        check_tree(&record[at..at + len]).map_err(|e| format!("face {f}: {e}"))?;
        at += len;
    }
    Ok(at)
}

/// One face's bytes: empty, or exactly one pre-order tree no deeper than [`MAX_DEPTH`].
fn check_tree(bytes: &[u8]) -> Result<(), String> {
    // Subtrees still to read: the root; each node fills one and a split opens two more.
    let mut open = isize::from(!bytes.is_empty());
    let mut i = 0;
    // Eight bytes at a time while no node in them can fail; the exact walk takes the rest.
    while let Some(eight) = bytes.get(i..i + 8) {
        let x = u64::from_le_bytes(eight.try_into().expect("eight bytes"));
        // Bit k = the top bit of byte k (the 0x80 byte mask gathered by one multiply).
        let tops = ((x & 0x8080_8080_8080_8080).wrapping_mul(0x0002_0408_1020_4081) >> 56) as usize;
        let w = WINDOWS[tops];
        if open + isize::from(w.lowest) < 1 {
            break;
        }
        open += isize::from(w.open);
        i += usize::from(w.bytes);
    }
    walk(bytes, i, open)?;
    // A tree is no deeper than it has splits: only a face long enough for MAX_DEPTH of them
    // needs its depth walked (loading checks every tree of every vertex).
    if bytes.len() >= 3 * MAX_DEPTH && depth(bytes) > MAX_DEPTH {
        return Err(format!("deeper than {MAX_DEPTH}"));
    }
    Ok(())
}

/// Checks `bytes[i..]` node by node with `open` subtrees still to read: they must fill
/// exactly.
fn walk(bytes: &[u8], mut i: usize, mut open: isize) -> Result<(), String> {
    while i < bytes.len() {
        if open == 0 {
            return Err(format!("bytes after the tree's last leaf (at {i})"));
        }
        if bytes[i] & 0x80 == 0 {
            open -= 1;
            i += 1;
        } else if i + 3 > bytes.len() {
            return Err(format!("a split cut short (at {i})"));
        } else {
            open += 1;
            i += 3;
        }
    }
    if open > 0 {
        return Err(format!("{open} subtrees missing"));
    }
    Ok(())
}

/// What the whole nodes at the start of an eight-byte window do, by the window's top bits.
#[derive(Clone, Copy)]
struct Window {
    /// Bytes they take (6 to 8: a split needs its 3 bytes inside the window).
    bytes: u8,
    /// Change in open subtrees.
    open: i8,
    /// Lowest change before any of them (each node needs an open subtree).
    lowest: i8,
}

const WINDOWS: [Window; 256] = {
    let mut table = [Window { bytes: 0, open: 0, lowest: 0 }; 256];
    let mut tops = 0;
    while tops < 256 {
        let (mut at, mut open, mut lowest) = (0u8, 0i8, 0i8);
        while at < 8 {
            let split = (tops >> at) & 1 == 1;
            if split && at + 3 > 8 {
                break;
            }
            if open < lowest {
                lowest = open;
            }
            open += if split { 1 } else { -1 };
            at += if split { 3 } else { 1 };
        }
        table[tops] = Window { bytes: at, open, lowest };
        tops += 1;
    }
    table
};

/// The most splits on one root-to-leaf path of a complete pre-order tree.
fn depth(bytes: &[u8]) -> usize {
    // Children still to read at each split on the current path.
    let mut pending: Vec<u8> = Vec::new();
    let (mut i, mut deepest) = (0, 0);
    while i < bytes.len() {
        if bytes[i] & 0x80 == 0 {
            i += 1;
            while let Some(left) = pending.last_mut() {
                *left -= 1;
                if *left > 0 {
                    break;
                }
                pending.pop();
            }
        } else {
            pending.push(2);
            deepest = deepest.max(pending.len());
            i += 3;
        }
    }
    deepest
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn baked_records_pass_the_check_and_damaged_ones_fail_with_a_reason() {
        let split = Node::Split { angle: 5, offset: 9 };
        let tree = vec![split, Node::Leaf(1.0), split, Node::Leaf(0.0), Node::Leaf(0.5)];
        let record = encode_vertex(&[Some(tree.clone()), None, Some(vec![Node::Leaf(1.0)]), None, None, Some(tree)]);
        assert_eq!(check_record(&record, 64), Ok(()));
        assert_eq!(tree_counts(&record), (3 + 1 + 3, 5 + 1 + 5));
        assert!(check_record(&record[..8], 64).unwrap_err().contains("header"));
        assert!(check_record(&record[..record.len() - 1], 64).unwrap_err().contains("add up"));
        // The first face's tree loses its last leaf but keeps its length: a subtree is missing.
        let mut cut = record.clone();
        cut[12 + 8] = 0x80;
        assert!(check_record(&cut, 64).is_err());
        // A lone leaf followed by more bytes in one face.
        let extra = join_faces([&[0x7F, 0x7F], &[], &[], &[], &[], &[]]);
        assert!(check_record(&extra, 64).unwrap_err().contains("after the tree"));
        // Chains of splits deeper than the limit, leaning left and right (a right chain keeps
        // only two subtrees open at a time), and a right chain exactly at the limit.
        let face = |t: &[u8]| check_record(&join_faces([t, &[], &[], &[], &[], &[]]), 64);
        let deep = [[0x80u8, 0, 0].repeat(MAX_DEPTH + 1), vec![0; MAX_DEPTH + 2]].concat();
        assert!(face(&deep).unwrap_err().contains("deeper"));
        let right = |splits: usize| [[0x80u8, 0, 0, 0x7F].repeat(splits), vec![0]].concat();
        assert!(face(&right(MAX_DEPTH + 1)).unwrap_err().contains("deeper"));
        assert_eq!(face(&right(MAX_DEPTH)), Ok(()));
        // Depth after the trees: checked face by face, and named when damaged.
        let tile = [super::super::depth::PLANE, 0, 0, 0, 0, 0x40, 0x20, 0];
        let mut tiles = [None; 9];
        tiles[0] = Some(&tile[..]);
        let depth = super::super::depth::join_tiles(&tiles, 24);
        let deep = with_depths(record.clone(), [&[], &depth, &[], &[], &[], &[]]);
        assert_eq!(check_record(&deep, 24), Ok(()));
        assert_eq!(vertex_depths(&deep)[1], &depth[..]);
        assert_eq!(vertex_faces(&deep), vertex_faces(&record));
        assert_eq!(with_depths(record.clone(), [&[]; 6]), record);
        assert!(check_record(&deep[..deep.len() - 1], 24).unwrap_err().contains("depth"));
        assert!(check_record(&[&deep[..], &[1]].concat(), 24).unwrap_err().contains("depth"));
        let mut wrong = deep.clone();
        // The plane's tag, after the root's split tag.
        wrong[deep.len() - depth.len() + 1] = 7;
        assert!(check_record(&wrong, 24).unwrap_err().contains("face 1 depth: tag 7"));
    }

    #[test]
    fn the_eight_byte_check_agrees_with_the_exact_walk() {
        // Random trees (leaf bytes and split bytes with any low bytes), each also cut, extended
        // and with one byte changed: the window check accepts and rejects exactly as the
        // node-by-node walk does, with the same message.
        use rand::Rng;
        let mut rng = crate::math::rng::seeded(7);
        for _ in 0..20_000 {
            let mut tree = Vec::new();
            let mut open = 1;
            while open > 0 && tree.len() < 300 {
                if rng.random::<f64>() < 0.45 {
                    tree.extend([0x80 | (rng.random::<u8>()), rng.random::<u8>(), rng.random::<u8>()]);
                    open += 1;
                } else {
                    tree.push(rng.random::<u8>() & 0x7F);
                    open -= 1;
                }
            }
            let mut cases = vec![tree.clone(), tree[..tree.len() / 2].to_vec(), [&tree[..], &[0x11, 0x80]].concat()];
            let mut changed = tree.clone();
            let k = rng.random_range(0..changed.len());
            changed[k] ^= 0x80;
            cases.push(changed);
            for c in cases {
                assert_eq!(check_tree(&c), walk(&c, 0, isize::from(!c.is_empty())), "{c:02x?}");
            }
        }
    }

    #[test]
    fn trees_and_records_round_trip() {
        let tree = vec![
            Node::Split { angle: 2047, offset: 4094 },
            Node::Leaf(1.0),
            Node::Split { angle: 0, offset: 7 },
            Node::Leaf(0.0),
            Node::Leaf(63.0 / 127.0),
        ];
        let mut bytes = Vec::new();
        encode_tree(&tree, &mut bytes);
        assert_eq!(bytes.len(), 3 + 1 + 3 + 1 + 1);
        assert_eq!(decode_tree(&bytes), tree);
        let rec = encode_vertex(&[None, Some(tree.clone()), None, None, Some(vec![Node::Leaf(1.0)]), None]);
        let faces = vertex_faces(&rec);
        assert_eq!(decode_tree(faces[1]), tree);
        assert_eq!(decode_tree(faces[4]), vec![Node::Leaf(1.0)]);
        assert!(faces[0].is_empty() && faces[5].is_empty());
    }
}
