//! The engine's error type: every variant names the file (when there is one) and the problem.

use std::path::PathBuf;

/// Result with the engine's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// An error that the user can act on.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What the OS said.
        source: std::io::Error,
    },
    /// A glTF file is malformed or uses something kage does not support.
    #[error("{path}: {message}")]
    Gltf {
        /// The file.
        path: PathBuf,
        /// What is wrong, with the glTF path of the offending element.
        message: String,
    },
    /// An image (environment map, texture) could not be decoded or is unusable.
    #[error("{path}: {message}")]
    Image {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A parameter or a scene is not valid for the requested computation.
    #[error("{0}")]
    Invalid(String),
}

impl Error {
    /// A glTF error for `path`.
    pub fn gltf(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Self::Gltf { path: path.into(), message: message.into() }
    }

    /// An image error for `path`.
    pub fn image(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Self::Image { path: path.into(), message: message.into() }
    }

    /// An I/O error for `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io { path: path.into(), source }
    }
}

/// The message a caught panic carried (empty when it was not a string): for turning a panic
/// inside a third-party library into an error that says what happened.
pub fn panic_message(panic: &(dyn std::any::Any + Send)) -> String {
    panic
        .downcast_ref::<String>()
        .cloned()
        .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
        .unwrap_or_default()
}
