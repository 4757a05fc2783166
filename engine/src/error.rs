//! The engine's error type: every variant names the file (when there is one) and the problem.

use std::path::PathBuf;

/// Result with the engine's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// An error that the user can act on.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read or written.
    #[error("{path}: {error}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What the OS said: part of the message, not a cause of its own (a cause would be said
        /// twice where the error is printed with its chain).
        error: std::io::Error,
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
    pub fn io(path: impl Into<PathBuf>, error: std::io::Error) -> Self {
        Self::Io { path: path.into(), error }
    }
}

thread_local! {
    /// How many [`contain`] calls this thread is inside.
    static CONTAINING: std::cell::Cell<u32> = const { std::cell::Cell::new(0) };
}

static CONTAINED: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
static QUIET_HOOK: std::sync::Once = std::sync::Once::new();

/// Runs `f`, turning a panic inside it into `Err` with the panic's message — quietly: the
/// panic hook stays silent for it (it becomes an error kage reports, not a message and
/// backtrace on stderr). The last line of defence around third-party code that asserts on bad
/// input (the gltf parser, the storage library on a damaged page); kage validates what it
/// knows those assert, and [`contained_panics`] counts what still got through.
pub fn contain<T>(f: impl FnOnce() -> T) -> std::result::Result<T, String> {
    QUIET_HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if CONTAINING.with(|c| c.get()) > 0 {
                CONTAINED.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
            } else {
                previous(info);
            }
        }));
    });
    CONTAINING.with(|c| c.set(c.get() + 1));
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
    CONTAINING.with(|c| c.set(c.get() - 1));
    result.map_err(|panic| panic_message(&*panic))
}

/// Panics [`contain`] has turned into errors in this process so far.
pub fn contained_panics() -> usize {
    CONTAINED.load(std::sync::atomic::Ordering::SeqCst)
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
