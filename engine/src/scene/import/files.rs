//! The one gateway through which an import reads the files a scene refers to (buffers and
//! images). A scene may come from someone you do not trust, so it reads only:
//!
//! - `data:` URIs (base64), or relative URI references, percent-decoded;
//! - regular files (no devices, FIFOs or folders) whose real path — symlinks resolved — lies
//!   inside the scene's root: the scene file's folder, or a wider folder the user allowed;
//! - never more bytes than declared: a buffer's `byteLength`, an image's size limit.
//!
//! Anything else is an error naming the URI and the rule it broke. Absolute paths, `file:`
//! and other schemes, and `..` escapes (also percent-encoded) are refused; so is a file whose
//! real path leaves the root through a symlink.

use base64::Engine as _;
use std::io::Read;
use std::path::{Path, PathBuf};

/// Largest image file an import reads (bytes).
pub const MAX_IMAGE_BYTES: u64 = 64 << 20;

/// Where a scene's files may come from.
#[derive(Clone, Debug)]
pub struct Root {
    dir: PathBuf,
}

impl Root {
    /// The root for a scene file: `allow` when given (a folder the user trusts), else the
    /// scene file's own folder; symlinks resolved.
    pub fn for_scene(scene: &Path, allow: Option<&Path>) -> Result<Self, String> {
        let dir = match allow {
            Some(dir) => dir.to_path_buf(),
            None => scene.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new(".")).to_path_buf(),
        };
        let dir = dir.canonicalize().map_err(|e| format!("the scene's folder {}: {e}", dir.display()))?;
        Ok(Self { dir })
    }

    /// The bytes `uri` names, exactly `len` of them (a buffer: a longer file is read up to
    /// `len`, a shorter one is an error).
    pub fn read_exact(&self, base: &Path, uri: &str, len: u64) -> Result<Vec<u8>, String> {
        let bytes = self.read(base, uri, len)?;
        if (bytes.len() as u64) < len {
            return Err(format!("URI '{}': {} bytes where {len} are declared", short(uri), bytes.len()));
        }
        Ok(bytes)
    }

    /// The bytes `uri` names, at most `limit` of them; `base` is the folder relative URIs
    /// start from (the scene file's).
    pub fn read(&self, base: &Path, uri: &str, limit: u64) -> Result<Vec<u8>, String> {
        if let Some(data) = uri.strip_prefix("data:") {
            return decode_data_uri(data, limit);
        }
        let path = self.resolve(base, uri)?;
        let file = std::fs::File::open(&path).map_err(|e| format!("URI '{}': {e}", short(uri)))?;
        let mut bytes = Vec::new();
        file.take(limit).read_to_end(&mut bytes).map_err(|e| format!("URI '{}': {e}", short(uri)))?;
        Ok(bytes)
    }

    /// The real path of the regular file inside the root that relative URI `uri` names (`base`
    /// as in [`Self::read`]), or why it is refused.
    pub fn resolve(&self, base: &Path, uri: &str) -> Result<PathBuf, String> {
        let refuse = |rule: &str| Err(format!("URI '{}' refused: {rule}", short(uri)));
        if has_scheme(uri) {
            return refuse("only data: URIs and relative paths inside the scene's folder are read");
        }
        let Ok(decoded) = percent_encoding::percent_decode_str(uri).decode_utf8() else {
            return refuse("its percent-encoding is not UTF-8");
        };
        let relative = Path::new(&*decoded);
        if decoded.contains('\0') || relative.is_absolute() || decoded.starts_with('\\') {
            return refuse("absolute paths are not read");
        }
        let real = base.join(relative).canonicalize().map_err(|e| format!("URI '{}': {e}", short(uri)))?;
        if !real.starts_with(&self.dir) {
            return refuse(&format!(
                "it leads outside {} (allow a wider folder with --allow-root)",
                self.dir.display()
            ));
        }
        if !std::fs::metadata(&real).is_ok_and(|m| m.is_file()) {
            return refuse("not a regular file");
        }
        Ok(real)
    }
}

/// True when `uri` starts with a scheme (`name:`), which a relative reference cannot.
fn has_scheme(uri: &str) -> bool {
    let name = uri.split(':').next().unwrap_or_default();
    uri.contains(':')
        && name.starts_with(|c: char| c.is_ascii_alphabetic())
        && name.chars().all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c))
}

/// The bytes of a `data:` URI's payload (after `data:`), at most `limit`.
fn decode_data_uri(data: &str, limit: u64) -> Result<Vec<u8>, String> {
    let (_, payload) = data.split_once(";base64,").ok_or("data: URI refused: only base64 payloads are read")?;
    // Base64 packs 3 bytes in 4 characters: a longer payload cannot fit the limit.
    if payload.len() as u64 / 4 * 3 > limit.saturating_add(3) {
        return Err(format!("data: URI of {} characters is longer than the {limit} bytes declared", payload.len()));
    }
    let lenient = base64::engine::GeneralPurposeConfig::new()
        .with_decode_padding_mode(base64::engine::DecodePaddingMode::Indifferent);
    base64::engine::GeneralPurpose::new(&base64::alphabet::STANDARD, lenient)
        .decode(payload.trim_end())
        .map_err(|e| format!("data: URI: {e}"))
}

/// A URI as errors quote it: at most 80 characters (data URIs can be megabytes).
fn short(uri: &str) -> String {
    if uri.chars().count() <= 80 { uri.to_string() } else { format!("{}…", uri.chars().take(80).collect::<String>()) }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A folder (removed when dropped) with `scene/sub/ok.bin` and, outside `scene`, `secret.bin`.
    fn scratch() -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir_all(d.join("scene/sub")).unwrap();
        std::fs::write(d.join("scene/sub/ok.bin"), [1u8, 2, 3, 4, 5, 6]).unwrap();
        std::fs::write(d.join("secret.bin"), [9u8; 8]).unwrap();
        dir
    }

    #[test]
    fn relative_files_inside_the_root_are_read_up_to_their_declared_length() {
        let dir = scratch();
        let d = dir.path();
        let (scene, base) = (d.join("scene/a.gltf"), d.join("scene"));
        let root = Root::for_scene(&scene, None).unwrap();
        assert_eq!(root.read_exact(&base, "sub/ok.bin", 4).unwrap(), [1, 2, 3, 4]);
        assert_eq!(root.read_exact(&base, "sub%2Fok.bin", 6).unwrap(), [1, 2, 3, 4, 5, 6]);
        assert!(root.read_exact(&base, "sub/ok.bin", 7).unwrap_err().contains("6 bytes where 7"));
        assert_eq!(root.read(&base, "data:application/octet-stream;base64,AQID", 3).unwrap(), [1, 2, 3]);
        assert_eq!(root.read(&base, "data:;base64,AQI", 2).unwrap(), [1, 2], "padding optional");
        assert!(root.read(&base, "data:;base64,AQIDBAUG", 2).unwrap_err().contains("longer than"));
    }

    #[test]
    fn escapes_schemes_and_special_files_are_refused_with_the_rule() {
        let dir = scratch();
        let d = dir.path();
        let (scene, base) = (d.join("scene/a.gltf"), d.join("scene"));
        let root = Root::for_scene(&scene, None).unwrap();
        let secret = d.join("secret.bin");
        std::os::unix::fs::symlink(&secret, d.join("scene/link.bin")).unwrap();
        for (uri, rule) in [
            ("../secret.bin", "leads outside"),
            ("%2e%2e/secret.bin", "leads outside"),
            ("sub/../../secret.bin", "leads outside"),
            ("link.bin", "leads outside"),
            (&secret.display().to_string(), "absolute paths"),
            (&format!("file://{}", secret.display()), "only data: URIs"),
            ("http://example.invalid/x.bin", "only data: URIs"),
            ("sub", "not a regular file"),
            ("data:text/plain,hello", "only base64"),
        ] {
            let e = root.read(&base, uri, 8).unwrap_err();
            assert!(e.contains(rule) && e.contains("URI"), "{uri}: {e}");
        }
        // A wider root the user allowed reads the file the symlink names.
        let wide = Root::for_scene(&scene, Some(d)).unwrap();
        assert_eq!(wide.read(&base, "link.bin", 8).unwrap(), [9u8; 8]);
        assert_eq!(wide.read(&base, "../secret.bin", 8).unwrap(), [9u8; 8]);
    }

    #[test]
    fn devices_and_fifos_are_never_opened() {
        let dir = scratch();
        let d = dir.path();
        let base = d.join("scene");
        std::os::unix::fs::symlink("/dev/zero", base.join("zero.bin")).unwrap();
        let fifo = base.join("pipe.bin");
        assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
        let root = Root::for_scene(&base.join("a.gltf"), Some(Path::new("/"))).unwrap();
        assert!(root.read(&base, "zero.bin", 8).unwrap_err().contains("not a regular file"));
        assert!(root.read(&base, "pipe.bin", 8).unwrap_err().contains("not a regular file"), "no blocking open");
    }
}
