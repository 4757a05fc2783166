//! The `KAGE_baked_shadows` extension's records as typed structures, field for field as
//! `docs/KAGE_baked_shadows.md` specifies them. Reading a pack deserialises into these, so a
//! missing or mistyped field is an error that names it.

use serde::{Deserialize, Serialize};

/// `extensions.KAGE_baked_shadows` on the glTF root.
#[derive(Debug, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Root {
    /// The extension's version.
    pub version: u64,
    /// Stops applied to the preview `COLOR_0`.
    pub preview_exposure: f32,
    /// Present when the pack has BSPVT data.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bspvt: Option<BspvtHeader>,
    /// Present when the pack has PRT data.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prt: Option<PrtHeader>,
    /// The scene's environment light, if it has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub environment: Option<Environment>,
    /// Digests of the buffer views and the JSON (version 4 on).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub integrity: Option<super::integrity::Integrity>,
}

/// The BSPVT bake's settings.
#[derive(Debug, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct BspvtHeader {
    /// Cube-face texels per side.
    pub face_resolution: u64,
    /// Split threshold ε of the trees.
    pub epsilon: f64,
    /// Record layout version.
    pub format: u32,
}

/// The PRT bake's settings and the environment's projection.
#[derive(Debug, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct PrtHeader {
    /// SH order n.
    pub order: u64,
    /// Transfer directions per vertex.
    pub directions: u64,
    /// Transfer algorithm version.
    pub algorithm: u32,
    /// Window applied to the lighting and the transfer.
    pub window: Window,
    /// Texels per side of the other-group silhouettes.
    pub silhouette_resolution: u64,
    /// The environment's radiance in SH (n² RGB triples, world frame).
    pub lighting: Vec<[f64; 3]>,
    /// The environment's regions.
    pub regions: Vec<Region>,
    /// The same of the environment without its sun, when its map has one (version 5 on): what
    /// a reader that lights the sun apart shades the rest with.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sunless: Option<Sunless>,
}

/// An environment's lighting and regions without its sun.
#[derive(Debug, Serialize, Deserialize)]
pub struct Sunless {
    /// The radiance in SH (n² RGB triples, world frame).
    pub lighting: Vec<[f64; 3]>,
    /// The regions.
    pub regions: Vec<Region>,
}

/// A window against SH ringing, by name.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Window {
    /// No window.
    None,
    /// Hanning.
    Hanning,
    /// Lanczos σ factors.
    Lanczos,
}

/// One environment region.
#[derive(Debug, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Region {
    /// ∫ L dω over the region (RGB).
    pub power: [f64; 3],
    /// Power-weighted centroid direction (unit, world).
    pub direction: [f32; 3],
    /// The region's solid angle.
    pub solid_angle: f64,
    /// The power's angular extent as a solid angle.
    pub spread: f64,
}

/// The environment map, exactly.
#[derive(Debug, Serialize, Deserialize)]
pub struct Environment {
    /// Map width in texels.
    pub width: u64,
    /// Map height in texels.
    pub height: u64,
    /// Buffer view of width × height × 3 f32 (row 0 = +Y).
    pub texels: u32,
    /// Radiance multiplier.
    pub intensity: f32,
    /// Rotation about +Y, radians.
    pub rotation: f32,
}

/// A mesh instance's record.
#[derive(Debug, Serialize, Deserialize)]
pub struct Instance {
    /// Its index in the snapshot.
    pub instance: u64,
    /// The real material (the preview replaced it).
    pub material: Material,
    /// Buffer view of the preview's linear radiance (f32 × 3 per vertex).
    pub radiance: u32,
    /// Buffer view of the bounces' light at the bake's placement: irradiance over π (f32 × 3
    /// per vertex; version 5 on).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bounce: Option<u32>,
    /// Buffer view of the vertices that lie inside geometry (u32 indices, ascending; version 6
    /// on, only when there are some): a pixel leaves them out of its lights' visible fractions.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inside: Option<u32>,
    /// The instance's visibility trees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bspvt: Option<BspvtData>,
    /// The instance's transfer.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prt: Option<PrtData>,
}

/// A material's factors and texture slots.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Material {
    /// Linear base colour.
    pub base_color: [f32; 3],
    /// Metalness.
    pub metallic: f32,
    /// Perceptual roughness.
    pub roughness: f32,
    /// `KHR_materials_specular` factor.
    pub specular: f32,
    /// Base-colour texture (sRGB PNG).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base_color_texture: Option<TextureSlot>,
    /// Metallic-roughness texture (linear; roughness in G, metalness in B).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub metallic_roughness_texture: Option<TextureSlot>,
    /// Where the surface is cut out (`alphaMode: MASK`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cutout: Option<Cutout>,
}

/// A cut-out: alpha = factor × the texture's alpha, absent below the cutoff.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Cutout {
    /// `baseColorFactor`'s alpha.
    pub factor: f32,
    /// `alphaCutoff`.
    pub cutoff: f32,
    /// The alpha texture: a PNG whose alpha channel is the mask (RGB white), which the
    /// preview material also reads.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alpha_texture: Option<TextureSlot>,
}

/// A texture slot: which core texture, which UV set, which UV transform.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct TextureSlot {
    /// Index into the core `textures`.
    pub index: u32,
    /// The UV set (0 or 1).
    pub tex_coord: u32,
    /// Column-major 2×2 matrix, then the offset.
    pub transform: [f32; 6],
}

/// Buffer views of an instance's visibility trees.
#[derive(Debug, Serialize, Deserialize)]
pub struct BspvtData {
    /// u32 × (vertices + 1) record offsets.
    pub offsets: u32,
    /// The records.
    pub records: u32,
}

/// Buffer view of an instance's transfer.
#[derive(Debug, Serialize, Deserialize)]
pub struct PrtData {
    /// f32 × n² per vertex.
    pub transfer: u32,
}

/// A polygonal light's exact values.
#[derive(Debug, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Light {
    /// Emitted radiance.
    pub light_radiance: [f32; 3],
    /// The polygon in the light's frame (3 numbers per corner).
    pub light_polygon: Vec<f32>,
    /// The world-space box the light stays inside: min, then max.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub light_reach: Option<[f32; 6]>,
    /// Texture coordinates per corner (textured lights only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub light_uvs: Option<Vec<f32>>,
}
