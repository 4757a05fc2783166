//! WGSL sources and their validation.
//!
//! The shaders live in the repository's `shaders/` folder. The binary embeds them, so `kage`
//! runs from anywhere; the editor reads them from a folder instead and rebuilds pipelines when a
//! file changes. Every source is parsed and validated by naga before it reaches the device:
//! a broken file yields a [`ShaderError`] naming the file and line, and the caller keeps its last
//! good pipeline.

use std::path::{Path, PathBuf};

/// The shaders kage ships, with their embedded sources.
const EMBEDDED: [(&str, &str); 3] = [
    ("bspvt.wgsl", include_str!("../../shaders/bspvt.wgsl")),
    ("prt.wgsl", include_str!("../../shaders/prt.wgsl")),
    ("preview.wgsl", include_str!("../../shaders/preview.wgsl")),
];

/// A shader that failed to load, parse or validate.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{file}:{line}: {message}")]
pub struct ShaderError {
    /// The file (or embedded name).
    pub file: String,
    /// 1-based line of the first error (0 when unknown).
    pub line: u32,
    /// The compiler's message.
    pub message: String,
    /// The full diagnostic with the source excerpt.
    pub report: String,
}

/// Where shader sources come from.
#[derive(Clone, Debug, Default)]
pub struct Shaders {
    dir: Option<PathBuf>,
}

impl Shaders {
    /// The sources embedded in the binary.
    pub fn embedded() -> Self {
        Self { dir: None }
    }

    /// Sources read from `dir` at every load (for hot reload).
    pub fn from_dir(dir: impl Into<PathBuf>) -> Self {
        Self { dir: Some(dir.into()) }
    }

    /// The folder sources are read from, if any.
    pub fn dir(&self) -> Option<&Path> {
        self.dir.as_deref()
    }

    /// The source of shader `name` and the label errors carry (its path or name).
    pub fn source(&self, name: &str) -> Result<(String, String), ShaderError> {
        match &self.dir {
            Some(dir) => {
                let path = dir.join(name);
                let label = path.display().to_string();
                let text = std::fs::read_to_string(&path).map_err(|e| ShaderError {
                    file: label.clone(),
                    line: 0,
                    message: e.to_string(),
                    report: format!("{label}: {e}"),
                })?;
                Ok((label, text))
            }
            None => {
                let text = EMBEDDED.iter().find(|(n, _)| *n == name).map(|(_, t)| t.to_string());
                let text = text.ok_or_else(|| ShaderError {
                    file: name.into(),
                    line: 0,
                    message: "no such shader".into(),
                    report: format!("{name}: no such shader"),
                })?;
                Ok((name.to_string(), text))
            }
        }
    }

    /// Loads, validates and creates shader module `name` on `device`.
    pub fn module(&self, device: &wgpu::Device, name: &str) -> Result<wgpu::ShaderModule, ShaderError> {
        let (label, text) = self.source(name)?;
        validate(&label, &text)?;
        Ok(device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(name),
            source: wgpu::ShaderSource::Wgsl(text.into()),
        }))
    }
}

/// Parses and validates WGSL `text` (labelled `file` in errors) as the device would.
pub fn validate(file: &str, text: &str) -> Result<(), ShaderError> {
    use wgpu::naga;
    let module = naga::front::wgsl::parse_str(text).map_err(|e| ShaderError {
        file: file.into(),
        line: e.location(text).map_or(0, |l| l.line_number),
        message: e.message().to_string(),
        report: e.emit_to_string_with_path(text, file),
    })?;
    let mut validator =
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::empty());
    validator.validate(&module).map_err(|e| ShaderError {
        file: file.into(),
        line: e.location(text).map_or(0, |l| l.line_number),
        message: e.as_inner().to_string(),
        report: e.emit_to_string_with_path(text, file),
    })?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_shipped_shader_validates() {
        for (name, text) in EMBEDDED {
            validate(name, text).unwrap_or_else(|e| panic!("{}", e.report));
        }
    }

    #[test]
    fn a_broken_shader_names_file_and_line() {
        let text = "@compute @workgroup_size(1)\nfn main() {\n    let x = ;\n}\n";
        let e = validate("shaders/broken.wgsl", text).unwrap_err();
        assert_eq!((e.file.as_str(), e.line), ("shaders/broken.wgsl", 3), "{e:?}");
        assert!(e.report.contains("shaders/broken.wgsl:3"), "{}", e.report);
    }

    #[test]
    fn a_type_error_is_caught_before_the_device() {
        let text = "@compute @workgroup_size(1)\nfn main() {\n    let x: f32 = 1u;\n}\n";
        let e = validate("t.wgsl", text).unwrap_err();
        assert_eq!(e.line, 3, "{e:?}");
    }
}
