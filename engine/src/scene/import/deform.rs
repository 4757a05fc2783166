//! Morph targets and skins, applied once at import. kage bakes rigid geometry, so a mesh is
//! imported in the shape the file shows without animation: morph targets blended with the
//! default weights (the node's `weights`, else the mesh's), and a skinned mesh posed by its
//! joints' node transforms (linear blend skinning with the inverse bind matrices — the bind
//! pose when the joints sit where they were bound). Animations are not read.

use glam::{Affine3A, Mat4, Vec3};
use gltf::accessor::{DataType, Dimensions};

/// How one node's mesh is deformed at import.
#[derive(Clone, Debug, Default)]
pub struct Deform {
    /// Morph target weights (empty: the mesh has none).
    pub weights: Vec<f32>,
    /// Per joint of the node's skin: the joint's world transform times its inverse bind
    /// matrix (empty: not skinned).
    pub joints: Vec<Affine3A>,
}

impl Deform {
    /// The node's morph weights and skin; `world` holds every node's world transform.
    pub fn of<'a, 's>(
        node: &gltf::Node<'a>,
        mesh: &gltf::Mesh<'a>,
        buffer: impl Clone + Fn(gltf::Buffer<'a>) -> Option<&'s [u8]>,
        world: &[Option<Affine3A>],
    ) -> Result<Self, String> {
        let weights = node.weights().or(mesh.weights()).unwrap_or_default().to_vec();
        if let Some(w) = weights.iter().find(|w| !w.is_finite()) {
            return Err(format!("morph weight {w} is not finite"));
        }
        let Some(skin) = node.skin() else { return Ok(Self { weights, joints: Vec::new() }) };
        let at = format!("skins[{}]", skin.index());
        let count = skin.joints().len();
        let inverse_binds: Vec<Mat4> = match skin.inverse_bind_matrices() {
            None => vec![Mat4::IDENTITY; count],
            Some(acc) => {
                if acc.dimensions() != Dimensions::Mat4 || acc.data_type() != DataType::F32 || acc.count() < count {
                    return Err(format!("{at}: inverseBindMatrices must be {count} or more float MAT4"));
                }
                let read = gltf::accessor::Iter::<[[f32; 4]; 4]>::new(acc, buffer);
                read.ok_or(format!("{at}: inverseBindMatrices has no data"))?
                    .map(|m| Mat4::from_cols_array_2d(&m))
                    .collect()
            }
        };
        let joint = |(node, ibm): (gltf::Node, Mat4)| {
            let posed = world[node.index()].map(|w| w * Affine3A::from_mat4(ibm)).filter(Affine3A::is_finite);
            posed.ok_or(format!("{at}: joint nodes[{}] has a transform that is not finite", node.index()))
        };
        let joints = skin.joints().zip(inverse_binds).map(joint).collect::<Result<_, _>>()?;
        Ok(Self { weights, joints })
    }

    /// Nothing to do: no non-zero morph weight, no skin.
    pub fn is_rigid(&self) -> bool {
        self.weights.iter().all(|w| *w == 0.0) && self.joints.is_empty()
    }

    /// Blends the morph targets into `positions` and `normals` (renormalised), then skins them.
    pub fn apply<'a, 's, F>(
        &self,
        reader: &gltf::mesh::Reader<'a, 's, F>,
        prim: &gltf::Primitive,
        positions: &mut [Vec3],
        normals: Option<&mut Vec<Vec3>>,
    ) -> Result<(), String>
    where
        F: Clone + Fn(gltf::Buffer<'a>) -> Option<&'s [u8]>,
    {
        let mut normals = normals;
        self.morph(reader, prim, positions, normals.as_deref_mut())?;
        if !self.joints.is_empty() {
            self.skin(reader, positions, normals.as_deref_mut())?;
        }
        if let Some(n) = normals {
            n.iter_mut().for_each(|n| *n = n.normalize_or_zero());
        }
        Ok(())
    }

    fn morph<'a, 's, F>(
        &self,
        reader: &gltf::mesh::Reader<'a, 's, F>,
        prim: &gltf::Primitive,
        positions: &mut [Vec3],
        mut normals: Option<&mut Vec<Vec3>>,
    ) -> Result<(), String>
    where
        F: Clone + Fn(gltf::Buffer<'a>) -> Option<&'s [u8]>,
    {
        let targets = prim.morph_targets().zip(reader.read_morph_targets());
        for (k, ((target, (dp, dn, _)), &w)) in targets.zip(&self.weights).enumerate() {
            if w == 0.0 {
                continue;
            }
            for acc in [target.positions(), target.normals()].into_iter().flatten() {
                if acc.dimensions() != Dimensions::Vec3 || acc.data_type() != DataType::F32 {
                    return Err(format!("morph target {k}: accessors[{}] must be float VEC3", acc.index()));
                }
                if acc.count() != positions.len() {
                    return Err(format!(
                        "morph target {k}: accessors[{}] has {} elements for {} vertices",
                        acc.index(),
                        acc.count(),
                        positions.len()
                    ));
                }
            }
            if let Some(dp) = dp {
                positions.iter_mut().zip(dp).for_each(|(p, d)| *p += w * Vec3::from_array(d));
            }
            if let (Some(n), Some(dn)) = (normals.as_deref_mut(), dn) {
                n.iter_mut().zip(dn).for_each(|(n, d)| *n += w * Vec3::from_array(d));
            }
        }
        Ok(())
    }

    /// Linear blend skinning over every JOINTS_n/WEIGHTS_n set.
    fn skin<'a, 's, F>(
        &self,
        reader: &gltf::mesh::Reader<'a, 's, F>,
        positions: &mut [Vec3],
        normals: Option<&mut Vec<Vec3>>,
    ) -> Result<(), String>
    where
        F: Clone + Fn(gltf::Buffer<'a>) -> Option<&'s [u8]>,
    {
        let mut blend = vec![Mat4::ZERO; positions.len()];
        let mut set = 0;
        while let (Some(joints), Some(weights)) = (reader.read_joints(set), reader.read_weights(set)) {
            for (k, (j, w)) in joints.into_u16().zip(weights.into_f32()).enumerate() {
                let m = blend.get_mut(k).ok_or(format!("JOINTS_{set} has more elements than POSITION"))?;
                for (j, w) in j.into_iter().zip(w) {
                    let joint = self.joints.get(usize::from(j)).ok_or(format!(
                        "JOINTS_{set} names joint {j}, but the skin has {} joints",
                        self.joints.len()
                    ))?;
                    *m += Mat4::from(*joint) * w;
                }
            }
            set += 1;
        }
        if set == 0 {
            return Err("a skinned mesh needs JOINTS_0 and WEIGHTS_0".into());
        }
        let blend: Vec<Affine3A> = blend.into_iter().map(Affine3A::from_mat4).collect();
        positions.iter_mut().zip(&blend).for_each(|(p, m)| *p = m.transform_point3(*p));
        if let Some(n) = normals {
            let normal_matrix = |m: &Affine3A| m.matrix3.inverse().transpose();
            n.iter_mut().zip(&blend).for_each(|(n, m)| *n = normal_matrix(m) * *n);
        }
        Ok(())
    }
}

/// Every node's world transform (parents before children; `None` for non-finite ones). The
/// node graph has been checked to be a forest.
pub fn world_transforms(doc: &gltf::Document) -> Vec<Option<Affine3A>> {
    let mut world = vec![None; doc.nodes().len()];
    let mut parent = vec![None; world.len()];
    for n in doc.nodes() {
        n.children().for_each(|c| parent[c.index()] = Some(n.index()));
    }
    let mut stack: Vec<(usize, Affine3A)> =
        (0..world.len()).filter(|&i| parent[i].is_none()).map(|i| (i, Affine3A::IDENTITY)).collect();
    let nodes: Vec<gltf::Node> = doc.nodes().collect();
    while let Some((i, above)) = stack.pop() {
        let Some(m) = super::node_matrix(&nodes[i]).map(|m| above * m).filter(Affine3A::is_finite) else { continue };
        world[i] = Some(m);
        stack.extend(nodes[i].children().map(|c| (c.index(), m)));
    }
    world
}
