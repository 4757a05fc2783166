//! One receiver's refinement as bytes (little-endian, ending in a blake3 hash of the rest), as
//! the bake database keeps it.

use super::Receiver;

impl Receiver {
    /// The refinement as bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        let word = |out: &mut Vec<u8>, n: usize| out.extend((n as u32).to_le_bytes());
        word(&mut out, self.before);
        match &self.refined {
            None => word(&mut out, 0),
            Some(m) => {
                word(&mut out, 1);
                for n in [m.positions.len(), m.uvs.len(), m.uvs1.len(), m.colors.len(), m.triangles.len()] {
                    word(&mut out, n);
                }
                out.extend_from_slice(bytemuck::cast_slice(&m.positions));
                out.extend_from_slice(bytemuck::cast_slice(&m.normals));
                out.extend_from_slice(bytemuck::cast_slice(&m.uvs));
                out.extend_from_slice(bytemuck::cast_slice(&m.uvs1));
                out.extend_from_slice(bytemuck::cast_slice(&m.colors));
                out.extend_from_slice(bytemuck::cast_slice(&m.triangles));
            }
        }
        let hash = *blake3::hash(&out).as_bytes();
        out.extend(hash);
        out
    }

    /// The refinement in `bytes` when its hash holds and its mesh is sound; `None` otherwise
    /// (a damaged entry is refined again).
    pub fn from_bytes(bytes: &[u8]) -> Option<Self> {
        let (body, hash) = bytes.split_at_checked(bytes.len().checked_sub(32)?)?;
        if blake3::hash(body).as_bytes() != hash {
            return None;
        }
        let mut r = Reader { body, at: 0 };
        let (before, refined) = (r.word()?, r.word()?);
        let refined = match refined {
            0 => None,
            1 => {
                let [p, uv, uv1, c, t] = [r.word()?, r.word()?, r.word()?, r.word()?, r.word()?];
                let mut mesh = crate::scene::Mesh {
                    positions: r.pods(p)?,
                    normals: r.pods(p)?,
                    uvs: r.pods(uv)?,
                    uvs1: r.pods(uv1)?,
                    colors: r.pods(c)?,
                    triangles: r.pods(t)?,
                    hash: crate::scene::MeshHash([0; 32]),
                };
                if mesh.triangles.iter().flatten().any(|&i| i as usize >= p) {
                    return None;
                }
                mesh.hash = mesh.compute_hash();
                Some(mesh)
            }
            _ => return None,
        };
        (r.at == body.len()).then_some(Self { before, refined })
    }
}

/// Reads [`Receiver::to_bytes`]'s fields in order; `None` past the end.
struct Reader<'a> {
    body: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn bytes(&mut self, n: usize) -> Option<&[u8]> {
        let s = self.body.get(self.at..self.at.checked_add(n)?)?;
        self.at += n;
        Some(s)
    }

    fn word(&mut self) -> Option<usize> {
        self.bytes(4).map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]) as usize)
    }

    /// `n` values of `T`, copied (the bytes need not be aligned).
    fn pods<T: bytemuck::Pod>(&mut self, n: usize) -> Option<Vec<T>> {
        self.bytes(n.checked_mul(std::mem::size_of::<T>())?).map(bytemuck::pod_collect_to_vec)
    }
}
