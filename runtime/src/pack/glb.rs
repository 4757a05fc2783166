//! Binary glTF containers: split into their JSON and binary chunks with every length checked
//! against the bytes present (a damaged header is an error, never a panic or a huge
//! allocation), and joined back.

/// A GLB's chunks, borrowed from its bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Glb<'a> {
    /// The JSON chunk (padded with spaces to 4 bytes).
    pub json: &'a [u8],
    /// The binary chunk (empty when there is none).
    pub bin: &'a [u8],
}

const JSON: u32 = 0x4E4F_534A;
const BIN: u32 = 0x004E_4942;

/// The chunks of `bytes`, a GLB (glTF 2.0 binary) file.
pub fn split(bytes: &[u8]) -> Result<Glb<'_>, String> {
    let word = |at: usize| bytes.get(at..at + 4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]));
    if !bytes.starts_with(b"glTF") {
        return Err("not a binary glTF (GLB) file".into());
    }
    if word(4) != Some(2) {
        return Err(format!("GLB version {:?}, not 2", word(4)));
    }
    let length = word(8).ok_or("a truncated GLB header")? as usize;
    if length > bytes.len() || length < 20 {
        return Err(format!("the GLB header declares {length} bytes; the file has {}", bytes.len()));
    }
    let chunk = |at: usize| -> Result<Option<(u32, &[u8])>, String> {
        if at >= length {
            return Ok(None);
        }
        let (len, kind) =
            (word(at).ok_or("a truncated chunk header")?, word(at + 4).ok_or("a truncated chunk header")?);
        let data = (at + 8).checked_add(len as usize).filter(|&end| end <= length).map(|end| &bytes[at + 8..end]);
        Ok(Some((kind, data.ok_or_else(|| format!("a GLB chunk of {len} bytes runs past the file's end"))?)))
    };
    let Some((JSON, json)) = chunk(12)? else { return Err("the GLB's first chunk is not JSON".into()) };
    let bin = match chunk(20 + json.len())? {
        Some((BIN, bin)) => bin,
        Some((kind, _)) => return Err(format!("the GLB's second chunk is of type {kind:#x}, not BIN")),
        None => &[],
    };
    Ok(Glb { json, bin })
}

/// A GLB of `json` (padded with spaces) and `bin` (padded with zeros).
pub fn join(json: &[u8], bin: &[u8]) -> Vec<u8> {
    let padded = |data: &[u8], pad: u8| {
        let mut v = data.to_vec();
        v.resize(data.len().next_multiple_of(4), pad);
        v
    };
    let chunk =
        |kind: u32, data: Vec<u8>| [&(data.len() as u32).to_le_bytes()[..], &kind.to_le_bytes(), &data].concat();
    let mut body = chunk(JSON, padded(json, b' '));
    if !bin.is_empty() {
        body.extend(chunk(BIN, padded(bin, 0)));
    }
    [&b"glTF"[..], &2u32.to_le_bytes(), &(12 + body.len() as u32).to_le_bytes(), &body].concat()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `join` and `split` are each other's inverse (up to padding), and every truncation or
    /// damaged length of a GLB is an error.
    #[test]
    fn split_inverts_join_and_refuses_damage() {
        let bytes = join(br#"{"asset":{"version":"2.0"}}"#, &[1, 2, 3, 4, 5]);
        let glb = split(&bytes).unwrap();
        assert_eq!(glb.json.trim_ascii_end(), br#"{"asset":{"version":"2.0"}}"#);
        assert_eq!(&glb.bin[..5], &[1, 2, 3, 4, 5]);
        for cut in 0..bytes.len() {
            assert!(split(&bytes[..cut]).is_err(), "truncated to {cut} bytes");
        }
        for at in [8, 12, 20 + glb.json.len()] {
            let mut damaged = bytes.clone();
            damaged[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
            assert!(split(&damaged).is_err(), "length at {at}");
        }
    }
}
