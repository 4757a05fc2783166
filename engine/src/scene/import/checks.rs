//! Checks the `gltf` crate does not make (or makes by panicking): references it indexes
//! without bounds checks, byte ranges its readers slice without checks, and attribute formats.

use super::SUPPORTED_EXTENSIONS;
use gltf::accessor::{DataType, Dimensions};
use gltf::json;

/// Most bytes of zeros that accessors without a buffer view may stand for, in all.
pub const MAX_ZERO_BYTES: usize = 64 << 20;

/// Gives every accessor that has neither a buffer view nor sparse data — zeros, as glTF
/// defines it, though the gltf crate's validation reports it as missing data — a view into one
/// new buffer of zeros appended to the document; returns that buffer's index, if any.
pub fn zero_accessors(root: &mut json::Root) -> Result<Option<usize>, String> {
    use json::validation::{Checked, USize64};
    let mut offset = 0usize;
    let buffer = root.buffers.len();
    for (i, acc) in root.accessors.iter_mut().enumerate() {
        let (Checked::Valid(t), Checked::Valid(c)) = (&acc.type_, &acc.component_type) else { continue };
        if acc.buffer_view.is_some() || acc.sparse.is_some() {
            continue;
        }
        let bytes = usize::try_from(acc.count.0).ok().and_then(|n| n.checked_mul(t.multiplicity() * c.0.size()));
        let end = bytes.and_then(|b| offset.checked_add(b)).filter(|&end| end <= MAX_ZERO_BYTES);
        let end = end.ok_or_else(|| {
            format!(
                "accessors[{i}]: {} elements of zeros (no bufferView) exceed kage's limit of {MAX_ZERO_BYTES} bytes",
                acc.count.0
            )
        })?;
        let view = json::buffer::View {
            buffer: json::Index::new(buffer as u32),
            byte_length: USize64((end - offset) as u64),
            byte_offset: Some(USize64(offset as u64)),
            byte_stride: None,
            name: None,
            target: None,
            extensions: None,
            extras: Default::default(),
        };
        acc.buffer_view = Some(json::Index::push(&mut root.buffer_views, view));
        acc.byte_offset = None;
        offset = end.next_multiple_of(4);
    }
    if offset == 0 && root.buffer_views.iter().all(|v| v.buffer.value() != buffer) {
        return Ok(None);
    }
    let zeros = json::Buffer {
        byte_length: USize64(offset.max(4) as u64),
        name: None,
        uri: None,
        extensions: None,
        extras: Default::default(),
    };
    root.buffers.push(zeros);
    Ok(Some(buffer))
}

/// References that `gltf`'s own validation dereferences unchecked, accessor counts and image
/// sources its readers assume, the node graph, and required extensions.
pub fn references(root: &json::Root) -> Result<(), String> {
    if let Some(ext) = root.extensions_required.iter().find(|e| !SUPPORTED_EXTENSIONS.contains(&e.as_str())) {
        return Err(format!("requires extension {ext}, which kage does not support"));
    }
    node_graph(root)?;
    // The gltf crate's readers compute `count − 1` and unwrap an image's URI or MIME type.
    if let Some(i) = root.accessors.iter().position(|a| a.count.0 == 0) {
        return Err(format!("accessors[{i}]: count is 0 (glTF requires at least 1)"));
    }
    for (i, image) in root.images.iter().enumerate() {
        match (&image.uri, &image.buffer_view, &image.mime_type) {
            (Some(_), None, _) | (None, Some(_), Some(_)) => {}
            (None, Some(_), None) => return Err(format!("images[{i}]: a bufferView image needs a mimeType")),
            _ => return Err(format!("images[{i}]: needs exactly one of uri and bufferView")),
        }
    }
    let n = root.accessors.len();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let targets = prim.targets.iter().flatten().flat_map(|t| [&t.positions, &t.normals, &t.tangents]).flatten();
            let bad = prim.attributes.values().chain(prim.indices.iter()).chain(targets).find(|i| i.value() >= n);
            if let Some(i) = bad {
                return Err(format!(
                    "meshes[{m}].primitives[{p}]: accessor {} does not exist ({n} accessors)",
                    i.value()
                ));
            }
        }
    }
    Ok(())
}

/// The 12-byte GLB header: the `gltf` crate underflows (panics) on a length below 12.
pub fn glb_header(bytes: &[u8]) -> Result<(), String> {
    if !bytes.starts_with(b"glTF") {
        return Ok(());
    }
    let word = |i: usize| bytes.get(i..i + 4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]));
    match (word(4), word(8)) {
        (Some(2), Some(len)) if (12..=bytes.len() as u64).contains(&(len as u64)) => Ok(()),
        (Some(2), Some(len)) => Err(format!("GLB header declares {len} bytes but the file has {}", bytes.len())),
        (Some(v), Some(_)) => Err(format!("GLB version {v} is not supported (glTF 2.0 uses version 2)")),
        _ => Err("GLB header is truncated".into()),
    }
}

/// Each node has at most one parent and the node graph has no cycle.
fn node_graph(root: &json::Root) -> Result<(), String> {
    let n = root.nodes.len();
    let mut parent = vec![None; n];
    for (i, node) in root.nodes.iter().enumerate() {
        for c in node.children.iter().flatten().map(|c| c.value()) {
            if c >= n {
                return Err(format!("nodes[{i}].children: node {c} does not exist ({n} nodes)"));
            }
            if let Some(p) = parent[c].replace(i) {
                return Err(format!("nodes[{c}] has two parents (nodes[{p}] and nodes[{i}])"));
            }
        }
    }
    // With single parents, exactly the nodes on or below a cycle are unreachable from the roots.
    let mut reached = vec![false; n];
    let mut stack: Vec<usize> = (0..n).filter(|&i| parent[i].is_none()).collect();
    while let Some(i) = stack.pop() {
        reached[i] = true;
        stack.extend(root.nodes[i].children.iter().flatten().map(|c| c.value()));
    }
    match reached.iter().position(|r| !r) {
        Some(i) => Err(format!("the node graph has a cycle through nodes[{i}]")),
        None => Ok(()),
    }
}

/// Every accessor's bytes lie inside its buffer view, and every view inside its buffer.
pub fn byte_ranges(doc: &gltf::Document, buffers: &[gltf::buffer::Data]) -> Result<(), String> {
    let view_ok = |view: &gltf::buffer::View| {
        let len = buffers.get(view.buffer().index()).map_or(0, |b| b.len());
        view.offset().checked_add(view.length()).is_some_and(|end| end <= len)
    };
    // A buffer without data (no URI in a .gltf) is legal until a used accessor reads it, which
    // then fails cleanly: the readers get no bytes for it.
    let dataless = |view: &gltf::buffer::View| buffers.get(view.buffer().index()).is_some_and(|b| b.is_empty());
    for acc in doc.accessors() {
        let at = || format!("accessors[{}]", acc.index());
        let sparse_views = acc.sparse().map(|s| [s.indices().view(), s.values().view()]);
        if acc.view().iter().chain(sparse_views.iter().flatten()).any(dataless) {
            continue;
        }
        if let Some(view) = acc.view() {
            if !view_ok(&view) {
                return Err(format!("{}: bufferViews[{}] extends past the end of its buffer", at(), view.index()));
            }
            let stride = view.stride().unwrap_or(acc.size());
            if stride < acc.size() {
                // The gltf crate's readers assert on this.
                return Err(format!(
                    "{}: bufferViews[{}].byteStride {stride} is smaller than one element ({} bytes)",
                    at(),
                    view.index(),
                    acc.size()
                ));
            }
            let need = match acc.count() {
                0 => Some(0),
                c => stride.checked_mul(c - 1).and_then(|b| b.checked_add(acc.offset() + acc.size())),
            };
            if need.is_none_or(|need| need > view.length()) {
                return Err(format!("{}: {} elements do not fit in bufferViews[{}]", at(), acc.count(), view.index()));
            }
        }
        if let Some(sparse) = acc.sparse() {
            let (iv, vv) = (sparse.indices().view(), sparse.values().view());
            let index_size = sparse.indices().index_type().size();
            let fits = |view: &gltf::buffer::View, offset: usize, size: usize| {
                view_ok(view) && sparse.count().checked_mul(size).is_some_and(|b| offset + b <= view.length())
            };
            if !fits(&iv, sparse.indices().offset(), index_size) || !fits(&vv, sparse.values().offset(), acc.size()) {
                return Err(format!("{}: sparse data does not fit in its buffer views", at()));
            }
        }
    }
    Ok(())
}

/// The attribute types kage reads: POSITION/NORMAL float VEC3, TEXCOORD_n VEC2, JOINTS_n and
/// WEIGHTS_n VEC4 (one per vertex), scalar indices.
pub fn attribute_formats(prim: &gltf::Primitive) -> Result<(), String> {
    use gltf::Semantic;
    let vertices = prim.get(&Semantic::Positions).map_or(0, |p| p.count());
    for (sem, acc) in prim.attributes() {
        if matches!(sem, Semantic::Joints(_) | Semantic::Weights(_)) && acc.count() != vertices {
            return Err(format!("attribute {sem:?} has {} elements for {vertices} vertices", acc.count()));
        }
        let ok = match sem {
            Semantic::Positions | Semantic::Normals => {
                acc.dimensions() == Dimensions::Vec3 && acc.data_type() == DataType::F32
            }
            Semantic::TexCoords(_) => {
                acc.dimensions() == Dimensions::Vec2
                    && matches!(acc.data_type(), DataType::F32 | DataType::U8 | DataType::U16)
            }
            Semantic::Joints(_) => {
                acc.dimensions() == Dimensions::Vec4 && matches!(acc.data_type(), DataType::U8 | DataType::U16)
            }
            Semantic::Weights(_) => {
                acc.dimensions() == Dimensions::Vec4
                    && matches!(acc.data_type(), DataType::F32 | DataType::U8 | DataType::U16)
            }
            _ => true,
        };
        if !ok {
            return Err(format!(
                "attribute {sem:?} has type {:?} {:?}, which glTF does not allow",
                acc.dimensions(),
                acc.data_type()
            ));
        }
    }
    if let Some(acc) = prim.indices()
        && (acc.dimensions() != Dimensions::Scalar
            || !matches!(acc.data_type(), DataType::U8 | DataType::U16 | DataType::U32))
    {
        return Err(format!(
            "indices have type {:?} {:?}; glTF requires unsigned integer scalars",
            acc.dimensions(),
            acc.data_type()
        ));
    }
    Ok(())
}

/// Largest world-space coordinate kage accepts (metres): far beyond any level, and small
/// enough that squared extents (BVH surface areas) stay finite in f32.
pub const MAX_WORLD_COORDINATE: f32 = 1e12;

/// Every instance's and light's world-space points are finite and within
/// [`MAX_WORLD_COORDINATE`] (a node scaled by 1e20 would overflow the BVH build).
pub fn world_extent(scene: &crate::scene::Scene) -> Result<(), String> {
    use crate::scene::{MeshRef, NodeId, PolygonLight, PrimitiveId, Transform};
    let check = |node: u32, world: &glam::Affine3A, points: &[glam::Vec3]| {
        let far = points
            .iter()
            .map(|p| world.transform_point3(*p))
            .find(|p| !p.is_finite() || p.abs().max_element() > MAX_WORLD_COORDINATE);
        far.map_or(Ok(()), |p| {
            Err(format!(
                "nodes[{node}]: a world-space point at {p} lies beyond kage's limit of ±{MAX_WORLD_COORDINATE:e} m (check its scale)"
            ))
        })
    };
    for (id, t, m) in scene.world.query::<(&PrimitiveId, &Transform, &MeshRef)>().iter() {
        check(id.node, &t.world, &scene.meshes[m.index as usize].positions)?;
    }
    for (node, t, l) in scene.world.query::<(&NodeId, &Transform, &PolygonLight)>().iter() {
        check(node.0, &t.world, &l.points)?;
    }
    Ok(())
}

/// The file places at most [`super::MAX_LIGHTS`] emissive primitives (each at least one light
/// polygon), counted before any mesh is read: a file of a million placed lights is refused at
/// once, naming its count.
pub fn light_count(doc: &gltf::Document) -> Result<(), String> {
    let emissive = |p: &gltf::Primitive| super::emission(&p.material()).max_element() > 0.0;
    let per_mesh: Vec<usize> = doc.meshes().map(|m| m.primitives().filter(emissive).count()).collect();
    let placed: usize = doc.nodes().filter_map(|n| n.mesh()).map(|m| per_mesh[m.index()]).sum();
    match placed > super::MAX_LIGHTS {
        true => Err(format!(
            "the file places {placed} emissive primitives, more than kage's limit of {} light polygons (every light is shaded at every vertex and pixel)",
            super::MAX_LIGHTS
        )),
        false => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn root(accessors: &str) -> json::Root {
        json::Root::from_str(&format!(r#"{{"asset": {{"version": "2.0"}}, "accessors": [{accessors}]}}"#)).unwrap()
    }

    /// Accessors without a buffer view read zeros from one new buffer, 4-byte aligned; a count
    /// beyond the limit is an error naming the accessor.
    #[test]
    fn accessors_without_a_buffer_view_become_zeros_within_a_limit() {
        let mut r = root(
            r#"{"componentType": 5126, "count": 3, "type": "VEC2"}, {"componentType": 5121, "count": 3, "type": "SCALAR"}"#,
        );
        assert_eq!(zero_accessors(&mut r).unwrap(), Some(0));
        let views: Vec<(u64, u64)> =
            r.buffer_views.iter().map(|v| (v.byte_offset.unwrap().0, v.byte_length.0)).collect();
        assert_eq!(views, vec![(0, 24), (24, 3)]);
        assert_eq!(r.buffers[0].byte_length.0, 28);
        assert!(r.accessors.iter().all(|a| a.buffer_view.is_some()));
        let mut none = root(r#"{"componentType": 5126, "count": 3, "type": "VEC2", "bufferView": 0}"#);
        assert_eq!(zero_accessors(&mut none).unwrap(), None);
        let mut huge = root(r#"{"componentType": 5126, "count": 100000000, "type": "VEC3"}"#);
        let e = zero_accessors(&mut huge).unwrap_err();
        assert!(e.contains("accessors[0]") && e.contains("limit"), "{e}");
    }
}
