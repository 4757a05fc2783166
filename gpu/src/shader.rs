//! WGSL sources and their validation.
//!
//! The shaders live in the repository's `shaders/` folder. The binary embeds them, so `kage`
//! runs from anywhere; the editor reads them from a folder instead and rebuilds pipelines when a
//! file changes. Every source is parsed and validated by naga before it reaches the device:
//! a broken file yields a [`ShaderError`] naming the file and line, and the caller keeps its last
//! good pipeline.
//!
//! WGSL has no includes; kage's loader has one: a line `// #include "name.wgsl"` is replaced by
//! that file's text (one level deep), so shaders share code (the silhouette lookups of
//! `silhouette.wgsl`, the polygon clipping and LTC integral of `ltc.wgsl`) without copies. Errors are mapped back to the file and line they are in.

use std::path::{Path, PathBuf};

/// The shaders kage ships, with their embedded sources.
const EMBEDDED: [(&str, &str); 6] = [
    ("bspvt.wgsl", include_str!("../../shaders/bspvt.wgsl")),
    ("prt.wgsl", include_str!("../../shaders/prt.wgsl")),
    ("preview.wgsl", include_str!("../../shaders/preview.wgsl")),
    ("silhouette.wgsl", include_str!("../../shaders/silhouette.wgsl")),
    ("ltc.wgsl", include_str!("../../shaders/ltc.wgsl")),
    ("pixel_lights.wgsl", include_str!("../../shaders/pixel_lights.wgsl")),
];

/// The include directive, up to the quoted file name.
const INCLUDE: &str = "// #include \"";

/// The file a line includes, if it is an include directive.
fn included(line: &str) -> Option<&str> {
    line.trim().strip_prefix(INCLUDE)?.strip_suffix('"')
}

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

/// A shader's source with its includes expanded.
struct Expanded {
    /// The label errors carry (the file's path or embedded name).
    label: String,
    /// The expanded text.
    text: String,
    /// For every line of `text`, the (file label, 1-based line) it came from.
    origin: Vec<(String, u32)>,
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

    /// The shaders that must be rebuilt when file `name` changes: itself, or (for a file others
    /// include) every shader that includes it.
    pub fn dependents(&self, name: &str) -> Vec<String> {
        let mut names: Vec<String> = match &self.dir {
            Some(dir) => std::fs::read_dir(dir)
                .into_iter()
                .flatten()
                .flatten()
                .filter_map(|e| e.file_name().into_string().ok())
                .filter(|n| n.ends_with(".wgsl"))
                .collect(),
            None => EMBEDDED.iter().map(|(n, _)| n.to_string()).collect(),
        };
        names.sort();
        names.retain(|n| self.raw(n).is_ok_and(|(_, t)| t.lines().any(|l| included(l) == Some(name))));
        if names.is_empty() { vec![name.to_string()] } else { names }
    }

    /// The source of shader `name` with its includes expanded, and the label errors carry.
    pub fn source(&self, name: &str) -> Result<(String, String), ShaderError> {
        self.expanded(name).map(|e| (e.label, e.text))
    }

    /// The source with its includes expanded, and where every line came from.
    fn expanded(&self, name: &str) -> Result<Expanded, ShaderError> {
        let (label, raw) = self.raw(name)?;
        let (mut text, mut origin) = (String::new(), Vec::new());
        for (k, line) in raw.lines().enumerate() {
            match included(line) {
                Some(part) => {
                    let (part_label, part_text) = self.raw(part).map_err(|e| ShaderError {
                        file: label.clone(),
                        line: k as u32 + 1,
                        message: format!("cannot include {part}: {}", e.message),
                        report: format!("{label}:{}: cannot include {part}: {}", k + 1, e.report),
                    })?;
                    for (j, l) in part_text.lines().enumerate() {
                        text.push_str(l);
                        text.push('\n');
                        origin.push((part_label.clone(), j as u32 + 1));
                    }
                }
                None => {
                    text.push_str(line);
                    text.push('\n');
                    origin.push((label.clone(), k as u32 + 1));
                }
            }
        }
        Ok(Expanded { label, text, origin })
    }

    /// One file's text as stored, and its label (its path or name).
    fn raw(&self, name: &str) -> Result<(String, String), ShaderError> {
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

    /// Loads, expands, validates and creates shader module `name` on `device`.
    pub fn module(&self, device: &wgpu::Device, name: &str) -> Result<wgpu::ShaderModule, ShaderError> {
        let text = self.checked(name)?;
        Ok(device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(name),
            source: wgpu::ShaderSource::Wgsl(text.into()),
        }))
    }

    /// The expanded source of `name`, validated; an error names the file and line it is in,
    /// included files too.
    pub fn checked(&self, name: &str) -> Result<String, ShaderError> {
        let Expanded { label, text, origin } = self.expanded(name)?;
        validate(&label, &text).map_err(|e| match origin.get((e.line as usize).wrapping_sub(1)) {
            Some((file, line)) if *file != label => ShaderError {
                report: format!("{file}:{line}: {} (included by {label})\n{}", e.message, e.report),
                file: file.clone(),
                line: *line,
                ..e
            },
            Some((_, line)) => ShaderError { line: *line, ..e },
            None => e,
        })?;
        Ok(text)
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
    fn every_shipped_shader_validates_with_its_includes() {
        let shaders = Shaders::embedded();
        let mains: Vec<String> = EMBEDDED.iter().flat_map(|(n, _)| shaders.dependents(n)).collect();
        assert!(mains.contains(&"preview.wgsl".into()) && !mains.contains(&"silhouette.wgsl".into()), "{mains:?}");
        for name in mains {
            shaders.checked(&name).unwrap_or_else(|e| panic!("{}", e.report));
        }
    }

    #[test]
    fn an_error_in_an_included_file_names_that_file_and_line() {
        let scratch = tempfile::tempdir().unwrap();
        let dir = scratch.path();
        let main = "fn f() -> f32 {\n    return g();\n}\n// #include \"lib.wgsl\"\n";
        std::fs::write(dir.join("main.wgsl"), main).unwrap();
        std::fs::write(dir.join("lib.wgsl"), "// a library\nfn g() -> f32 {\n    return 1u;\n}\n").unwrap();
        let shaders = Shaders::from_dir(dir);
        assert_eq!(shaders.dependents("lib.wgsl"), ["main.wgsl"]);
        assert_eq!(shaders.dependents("main.wgsl"), ["main.wgsl"]);
        let e = shaders.checked("main.wgsl").unwrap_err();
        // naga places a bad return at its function, line 2 of lib.wgsl (line 5 of the whole).
        assert!(e.file.ends_with("lib.wgsl") && e.line == 2, "{e:?}");
        assert!(e.report.contains("included by"), "{}", e.report);
        std::fs::write(dir.join("lib.wgsl"), "fn g() -> f32 {\n    return 1.0;\n}\n").unwrap();
        std::fs::write(dir.join("main.wgsl"), "fn f() -> f32 {\n    return g() + ;\n}\n// #include \"lib.wgsl\"\n")
            .unwrap();
        let e = shaders.checked("main.wgsl").unwrap_err();
        assert!(e.file.ends_with("main.wgsl") && e.line == 2, "{e:?}");
        std::fs::write(dir.join("main.wgsl"), "// #include \"missing.wgsl\"\n").unwrap();
        let e = shaders.checked("main.wgsl").unwrap_err();
        assert!(e.file.ends_with("main.wgsl") && e.line == 1 && e.message.contains("missing.wgsl"), "{e:?}");
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
