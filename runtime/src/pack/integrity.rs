//! A pack's integrity (version 4 on): a blake3 digest per buffer view and one of the glTF JSON,
//! so that a pack damaged in transit — a flipped bit in a transfer, an edited number — is
//! refused with the part that changed named, instead of shading garbage.
//!
//! The JSON digest covers the JSON chunk without its trailing padding spaces, with the digest's
//! own 64 hex digits written as `0`s: the writer seals with a placeholder, hashes, and writes
//! the digest in its place; the reader undoes exactly that.

use super::glb;
use serde::{Deserialize, Serialize};

/// `extensions.KAGE_baked_shadows.integrity` on the glTF root.
#[derive(Debug, Serialize, Deserialize)]
pub struct Integrity {
    /// blake3 of each buffer view's bytes, lower-case hex, in `bufferViews` order.
    pub views: Vec<String>,
    /// blake3 of the JSON chunk (see the module doc), lower-case hex.
    pub json: String,
}

/// The placeholder the JSON digest is computed over.
const UNSEALED: &str = "0000000000000000000000000000000000000000000000000000000000000000";

/// A buffer view's place in the binary chunk, as the glTF JSON gives it.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct View {
    /// Offset into the binary chunk.
    #[serde(default)]
    pub byte_offset: u64,
    /// Length in bytes.
    pub byte_length: u64,
}

/// The `bufferViews` of a glTF JSON document (the rest is not read).
pub fn buffer_views(json: &[u8]) -> Result<Vec<View>, String> {
    #[derive(Deserialize)]
    #[serde(rename_all = "camelCase")]
    struct Doc {
        #[serde(default)]
        buffer_views: Vec<View>,
    }
    serde_json::from_slice::<Doc>(json).map(|d| d.buffer_views).map_err(|e| format!("bufferViews: {e}"))
}

/// An [`Integrity`] record with the buffer views' digests and the JSON's placeholder.
pub fn unsealed(views: &[View], bin: &[u8]) -> Integrity {
    let views = (0..views.len()).map(|i| blake3::hash(view(views, bin, i).unwrap_or_default()).to_hex().to_string());
    Integrity { views: views.collect(), json: UNSEALED.into() }
}

/// Writes the JSON's digest over its placeholder (`json` holds exactly one).
pub fn seal(json: &mut [u8]) {
    let at = find(json, UNSEALED.as_bytes()).expect("the integrity record is written unsealed");
    let digest = blake3::hash(json);
    json[at..at + UNSEALED.len()].copy_from_slice(digest.to_hex().as_bytes());
}

/// Checks the JSON chunk against `record.json`.
pub fn check_json(json: &[u8], record: &Integrity) -> Result<(), String> {
    let text = json.trim_ascii_end();
    let digest = record.json.as_bytes();
    let at = find(text, digest).filter(|_| digest.len() == UNSEALED.len());
    let Some(at) = at else { return Err("its integrity record's JSON digest is malformed".into()) };
    let mut unsealed = text.to_vec();
    unsealed[at..at + UNSEALED.len()].copy_from_slice(UNSEALED.as_bytes());
    if blake3::hash(&unsealed).to_hex().as_bytes() != digest {
        return Err("the glTF JSON fails its checksum (edited or damaged since kage wrote it)".into());
    }
    Ok(())
}

/// Checks every buffer view against its digest; `name` says what a view holds, for the error.
pub fn check_views(
    views: &[View],
    bin: &[u8],
    record: &Integrity,
    name: impl Fn(usize) -> String,
) -> Result<(), String> {
    if record.views.len() != views.len() {
        return Err(format!("{} view checksums for {} buffer views", record.views.len(), views.len()));
    }
    for (i, expected) in record.views.iter().enumerate() {
        let bytes = view(views, bin, i).ok_or_else(|| format!("buffer view {i} lies outside the binary chunk"))?;
        if blake3::hash(bytes).to_hex().as_str() != expected {
            return Err(format!("{} (buffer view {i}) fails its checksum: the data is damaged", name(i)));
        }
    }
    Ok(())
}

/// A pack (GLB bytes) with its integrity record computed afresh: for tools that change a pack
/// on purpose (and tests that write one wrong); the data is not checked.
pub fn reseal(bytes: &[u8]) -> Result<Vec<u8>, String> {
    let g = glb::split(bytes)?;
    let record = unsealed(&buffer_views(g.json)?, g.bin);
    let mut doc: serde_json::Value = serde_json::from_slice(g.json).map_err(|e| e.to_string())?;
    let extension = doc.pointer_mut(&format!("/extensions/{}", super::EXTENSION)).ok_or("not a kage pack")?;
    extension["integrity"] = serde_json::to_value(record).map_err(|e| e.to_string())?;
    let mut json = serde_json::to_vec(&doc).map_err(|e| e.to_string())?;
    seal(&mut json);
    Ok(glb::join(&json, g.bin))
}

/// The bytes of buffer view `index`, if it lies inside `bin`.
pub fn view<'a>(views: &[View], bin: &'a [u8], index: usize) -> Option<&'a [u8]> {
    let v = views.get(index)?;
    let end = v.byte_offset.checked_add(v.byte_length)?;
    bin.get(usize::try_from(v.byte_offset).ok()?..usize::try_from(end).ok()?)
}

/// The first position of `needle` in `hay`, when it occurs exactly once.
fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    let mut at = hay.windows(needle.len()).enumerate().filter(|(_, w)| *w == needle).map(|(i, _)| i);
    let first = at.next()?;
    at.next().is_none().then_some(first)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sealed_json_checks_and_any_changed_byte_fails() {
        let mut json = format!(r#"{{"a":1.5,"integrity":{{"views":[],"json":"{UNSEALED}"}}}}"#).into_bytes();
        seal(&mut json);
        let text = std::str::from_utf8(&json).unwrap();
        let digest = text.split("\"json\":\"").nth(1).unwrap()[..64].to_string();
        let record = Integrity { views: vec![], json: digest };
        let mut padded = json.clone();
        padded.extend_from_slice(b"   ");
        assert_eq!(check_json(&padded, &record), Ok(()));
        let mut edited = json.clone();
        edited[5] = b'7';
        assert!(check_json(&edited, &record).unwrap_err().contains("fails its checksum"));
    }
}
