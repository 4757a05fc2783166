//! Plain-data ECS components (conventions: `docs/conventions.md`).

use glam::{Affine2, Affine3A, Mat3, Quat, Vec2, Vec3};

/// A human-readable name (glTF node name, or a generated one).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Name(pub String);

/// The glTF node index an entity came from (built-in scenes number their own nodes).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct NodeId(pub u32);

/// World-from-local transform.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    /// The matrix (may be mirrored; see [`Transform::is_mirrored`]).
    pub world: Affine3A,
}

/// A similarity transform split into parts: `world = T · R · s · (mirror ? diag(1, 1, −1) : I)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigidParts {
    /// Uniform scale (> 0).
    pub scale: f32,
    /// Rotation.
    pub rotation: Quat,
    /// Translation.
    pub translation: Vec3,
    /// True when the transform mirrors (a uniform mirror is still rigid enough).
    pub mirrored: bool,
}

impl RigidParts {
    /// The transform these parts describe.
    pub fn to_affine(&self) -> Affine3A {
        let mirror = if self.mirrored { Vec3::new(1.0, 1.0, -1.0) } else { Vec3::ONE };
        let m = Mat3::from_quat(self.rotation) * Mat3::from_diagonal(mirror * self.scale);
        Affine3A::from_mat3_translation(m, self.translation)
    }
}

/// Relative tolerance for "uniform" scale and "orthogonal" axes.
const RIGID_TOLERANCE: f32 = 1e-4;

impl Transform {
    /// True when the matrix flips handedness, so triangle winding flips too.
    pub fn is_mirrored(&self) -> bool {
        self.world.matrix3.determinant() < 0.0
    }

    /// Splits a rotation + uniform scale (+ optional mirror) + translation; shear or
    /// non-uniform scale is an error saying which.
    pub fn rigid_parts(&self) -> Result<RigidParts, String> {
        let m = Mat3::from(self.world.matrix3);
        let cols = [m.x_axis, m.y_axis, m.z_axis];
        let len = cols.map(Vec3::length);
        let (lo, hi) = (len.iter().copied().fold(f32::MAX, f32::min), len.iter().copied().fold(0.0, f32::max));
        if !(lo > 0.0 && lo.is_finite() && hi.is_finite()) {
            return Err("the transform is singular or not finite".into());
        }
        if hi / lo - 1.0 > RIGID_TOLERANCE {
            return Err(format!("non-uniform scale ({:.4}, {:.4}, {:.4})", len[0], len[1], len[2]));
        }
        for (i, j) in [(0, 1), (1, 2), (0, 2)] {
            if cols[i].dot(cols[j]).abs() > RIGID_TOLERANCE * len[i] * len[j] {
                return Err(format!("shear between axes {i} and {j}"));
            }
        }
        let scale = (len[0] * len[1] * len[2]).cbrt();
        let mirrored = m.determinant() < 0.0;
        let unmirror = if mirrored { Vec3::new(1.0, 1.0, -1.0) } else { Vec3::ONE };
        let r = Mat3::from_cols(cols[0] / len[0], cols[1] / len[1], cols[2] / len[2] * unmirror.z);
        Ok(RigidParts {
            scale,
            rotation: Quat::from_mat3(&r).normalize(),
            translation: self.world.translation.into(),
            mirrored,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rigid_parts_round_trip_and_reject_shear() {
        let q = Quat::from_euler(glam::EulerRot::XYZ, 0.3, -1.2, 2.0);
        for mirror in [false, true] {
            let parts =
                RigidParts { scale: 2.5, rotation: q, translation: Vec3::new(1.0, -2.0, 3.0), mirrored: mirror };
            let t = Transform { world: parts.to_affine() };
            let back = t.rigid_parts().unwrap();
            assert_eq!(back.mirrored, mirror);
            assert!(back.to_affine().abs_diff_eq(parts.to_affine(), 1e-5));
        }
        // glTF's scale (1, −1, 1) mirror is valid.
        let m = Transform { world: Affine3A::from_scale(Vec3::new(1.0, -1.0, 1.0)) };
        assert!(m.rigid_parts().unwrap().mirrored);
        let shear = Transform {
            world: Affine3A::from_cols_array(&[1.0, 0.0, 0.0, 0.6, 0.8, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]),
        };
        assert!(shear.rigid_parts().unwrap_err().contains("shear"));
        let squash = Transform { world: Affine3A::from_scale(Vec3::new(1.0, 2.0, 1.0)) };
        assert!(squash.rigid_parts().unwrap_err().contains("non-uniform scale"));
    }
}

/// A rigid group: a top-level glTF node with its subtree. Its [`Transform`] is the group pose.
#[derive(Clone, Debug, PartialEq)]
pub struct RigidGroup {
    /// Index of the group among the scene's groups, in import order.
    pub index: u32,
}

/// Membership of an instance or light in a rigid group, with its pose relative to the group.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InGroup {
    /// The group entity.
    pub group: hecs::Entity,
    /// Group-from-local transform.
    pub local: Affine3A,
}

/// Where a mesh instance came from in the glTF file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PrimitiveId {
    /// glTF node index.
    pub node: u32,
    /// glTF mesh index.
    pub mesh: u32,
    /// Primitive index within the mesh.
    pub primitive: u32,
}

/// Where a polygonal light came from in the glTF file: its emissive primitive (a primitive whose
/// outline is not one convex polygon gives several lights, `polygon` numbering them).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Emitter {
    /// The primitive.
    pub id: PrimitiveId,
    /// Which of the primitive's polygons.
    pub polygon: u32,
}

/// A reference to a shared mesh, keyed by its content hash.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MeshRef {
    /// Index into [`crate::scene::Scene::meshes`].
    pub index: u32,
    /// Content hash of that mesh.
    pub hash: crate::scene::MeshHash,
}

/// The mesh an instance had before receiver refinement replaced it: refinement always starts
/// again from it, and a saved file still refers to it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SourceMesh {
    /// The source mesh.
    pub mesh: MeshRef,
}

impl SourceMesh {
    /// The mesh that occludes for an instance showing `shown` and refined from `source` (if
    /// it was): the source. Re-refining an instance (another shadow to follow) then changes
    /// nothing it casts, nor any key that hashes what occludes; refinement lifts vertices only
    /// outward so that their rays start outside it (see [`crate::scene::refine`]).
    pub fn occluder(shown: MeshRef, source: Option<&SourceMesh>) -> MeshRef {
        source.map_or(shown, |s| s.mesh)
    }
}

pub use kage_runtime::material::Material;

/// A material texture as a glTF `textureInfo` names it: the texture, the UV set it reads and
/// its `KHR_texture_transform`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TextureSlot {
    /// Index into [`crate::scene::Scene::textures`].
    pub texture: u32,
    /// The UV set (0: `TEXCOORD_0`, 1: `TEXCOORD_1`).
    pub texcoord: u32,
    /// Texture-from-mesh UV transform (identity without `KHR_texture_transform`).
    pub transform: Affine2,
}

impl TextureSlot {
    /// The texture coordinate this slot reads from a mesh's `uv0` and `uv1` at a point.
    pub fn uv(&self, uv0: Vec2, uv1: Vec2) -> Vec2 {
        self.transform.transform_point2(if self.texcoord == 1 { uv1 } else { uv0 })
    }
}

/// Where a material's factors vary over a surface: glTF's base-colour texture (sRGB, decoded to
/// linear) and metallic-roughness texture (linear; roughness in G, metalness in B). Vertex
/// colours live in the mesh ([`crate::scene::Mesh::colors`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MaterialMaps {
    /// Multiplies [`Material::base_color`].
    pub base_color: Option<TextureSlot>,
    /// Multiplies [`Material::roughness`] (G) and [`Material::metallic`] (B).
    pub metallic_roughness: Option<TextureSlot>,
    /// Where the surface is absent (`alphaMode: MASK`).
    pub cutout: Option<super::Cutout>,
}

impl MaterialMaps {
    /// True when nothing varies (the factors alone are the material, and it is solid).
    pub fn is_empty(&self) -> bool {
        self.base_color.is_none() && self.metallic_roughness.is_none() && self.cutout.is_none()
    }
}

/// A one-sided polygonal light with constant (or textured) radiance, emitting on its CCW side.
#[derive(Clone, Debug, PartialEq)]
pub struct PolygonLight {
    /// Convex polygon vertices in the light's local frame (see [`InGroup::local`]).
    pub points: Vec<Vec3>,
    /// Texture coordinates per vertex (empty when untextured).
    pub uvs: Vec<Vec2>,
    /// Radiance: emissiveFactor × emissive strength (multiplied by the texture when present).
    pub radiance: Vec3,
    /// Emissive texture index into [`crate::scene::Scene::textures`].
    pub texture: Option<u32>,
    /// The world-space box (min, max) the light promises to stay inside however it is moved
    /// (`extras.kage.light_reach`), or `None`: it may go anywhere.
    pub reach: Option<[Vec3; 2]>,
}

impl PolygonLight {
    /// Whether `points` (this light's polygon, or a resized one) placed by `world` stay inside
    /// the reach box it declared (none declared: anywhere); the error says why not.
    pub fn within_reach(&self, world: Affine3A, points: &[Vec3]) -> Result<(), String> {
        let Some(reach) = self.reach else { return Ok(()) };
        let at = points.iter().map(|p| world.transform_point3(*p));
        if super::import::reach::contains(reach, at.fold([Vec3::MAX, Vec3::MIN], |[lo, hi], p| [lo.min(p), hi.max(p)]))
        {
            return Ok(());
        }
        Err(format!(
            "the light would leave its reach box {} … {} (extras.kage.light_reach), which its shadows were baked for",
            reach[0], reach[1]
        ))
    }
}

pub use kage_runtime::camera::{Camera, Projection};
