//! Bake keys: blake3 hashes of everything a result depends on, fed field by field in a fixed
//! order with explicit tags, so two different inputs cannot produce the same byte stream.

use glam::Affine3A;

/// A 32-byte bake key.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Key([u8; 32]);

impl Key {
    /// The raw bytes.
    pub fn as_bytes(&self) -> &[u8; 32] {
        &self.0
    }

    /// A key from 32 bytes (shorter input is zero-padded).
    pub fn from_slice(b: &[u8]) -> Self {
        let mut k = [0u8; 32];
        let n = b.len().min(32);
        k[..n].copy_from_slice(&b[..n]);
        Self(k)
    }

    /// The first 16 hex digits, for messages.
    pub fn short(&self) -> String {
        self.0[..8].iter().map(|b| format!("{b:02x}")).collect()
    }

    /// All 32 bytes in hex.
    pub fn hex(&self) -> String {
        self.0.iter().map(|b| format!("{b:02x}")).collect()
    }
}

/// Builds a key from tagged fields.
#[derive(Clone)]
pub struct KeyHasher(blake3::Hasher);

impl KeyHasher {
    /// Starts a key of a kind (e.g. `"bspvt"`).
    pub fn new(kind: &str) -> Self {
        let mut h = blake3::Hasher::new();
        h.update(b"kage-bake-key\0");
        h.update(kind.as_bytes());
        h.update(b"\0");
        Self(h)
    }

    /// Adds a tagged field of raw bytes (length-prefixed).
    pub fn bytes(mut self, tag: &str, b: &[u8]) -> Self {
        self.0.update(tag.as_bytes());
        self.0.update(&(b.len() as u64).to_le_bytes());
        self.0.update(b);
        self
    }

    /// Adds an integer.
    pub fn u64(self, tag: &str, v: u64) -> Self {
        self.bytes(tag, &v.to_le_bytes())
    }

    /// Adds a float by its bits.
    pub fn f64(self, tag: &str, v: f64) -> Self {
        self.bytes(tag, &v.to_bits().to_le_bytes())
    }

    /// Adds a transform by the bits of its 12 floats.
    pub fn affine(self, tag: &str, a: &Affine3A) -> Self {
        self.bytes(tag, bytemuck::cast_slice(&a.to_cols_array()))
    }

    /// Adds where the instances' materials vary — each texture slot's texels, UV set and
    /// transform, and each mesh's vertex colours — for the instances that have any, so keys of
    /// scenes with plain materials stay what they were.
    pub fn material_variation(mut self, flat: &kage_engine::scene::FlatScene) -> Self {
        for (i, inst) in flat.instances.iter().enumerate().filter(|(i, _)| flat.varies(*i)) {
            self = self
                .u64("varying instance", i as u64)
                .bytes("vertex colours", bytemuck::cast_slice(&flat.mesh(i).colors));
            for slot in [inst.maps.base_color, inst.maps.metallic_roughness] {
                self = match slot {
                    Some(s) => {
                        let t = &flat.textures[s.texture as usize];
                        self.u64("texture size", (t.width as u64) << 32 | t.height as u64)
                            .bytes("texels", bytemuck::cast_slice(&t.texels))
                            .bytes("wrap", &t.wrap.map(|w| w as u8))
                            .u64("texcoord", s.texcoord as u64)
                            .bytes("uv transform", bytemuck::cast_slice(&s.transform.to_cols_array()))
                    }
                    None => self.u64("no texture", 0),
                };
            }
        }
        self
    }

    /// The key.
    pub fn finish(self) -> Key {
        Key(*self.0.finalize().as_bytes())
    }
}
