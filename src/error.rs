//! One error type for the library; every message says what went wrong and, where it
//! helps, what to do about it. The CLI prints it and exits non-zero.

use std::path::PathBuf;

/// Every error texsyn returns. The `Display` text is a complete message for the user.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file (exemplar, analysis file, mesh, tangent field, ...) could not be opened or
    /// read: missing, a directory, no permission. Check the path.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file that could not be read.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// A file was read but is not an image the decoder accepts: empty, truncated, corrupt
    /// or an unsupported format.
    #[error("{path} is not a readable image: {reason}")]
    BadImage {
        /// The offending file.
        path: PathBuf,
        /// The decoder's explanation.
        reason: String,
    },
    /// The exemplar is smaller than [`crate::analysis::MIN_EXEMPLAR_SIZE`] pixels on
    /// either side. Use a larger exemplar (or upscale it).
    #[error("exemplar is {width}x{height}; texsyn needs at least {min}x{min} pixels")]
    ExemplarTooSmall {
        /// Exemplar width in pixels.
        width: u32,
        /// Exemplar height in pixels.
        height: u32,
        /// The minimum side length in pixels.
        min: u32,
    },
    /// An output or intermediate buffer would exceed a limit of the GPU device (texture
    /// dimension or storage-buffer size). Ask for a smaller size; `hint` says how.
    #[error("{what} is {width}x{height}, larger than this device allows ({limit}); {hint}")]
    TooLarge {
        /// What is too large (e.g. "output").
        what: &'static str,
        /// Requested width in pixels.
        width: u32,
        /// Requested height in pixels.
        height: u32,
        /// The device limit that was exceeded, in words.
        limit: String,
        /// What to do instead.
        hint: &'static str,
    },
    /// A parameter or option is out of range or inconsistent (size, seed window, field,
    /// flow, pass counts, ...); the message names it and the accepted values (the message is
    /// the whole text, with no prefix).
    #[error("{0}")]
    InvalidParameter(String),
    /// An analysis file (from `texsyn analyze`) that cannot be decoded: wrong magic or
    /// format version, truncated, checksum mismatch, invalid content. Re-run `texsyn analyze`.
    #[error("{path}: {reason}")]
    BadAnalysisFile {
        /// The analysis file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// A mesh file (glTF / GLB) that cannot be used: unreadable structure, missing
    /// buffers, no triangles, out-of-range data.
    #[error("{path}: {reason}")]
    BadMesh {
        /// The mesh file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// An output file (image, EXR, analysis file, glTF, animation) could not be encoded or
    /// written. Check that the directory exists and is writable.
    #[error("cannot write {path}: {reason}")]
    Write {
        /// The file being written.
        path: PathBuf,
        /// The encoder's or operating system's explanation.
        reason: String,
    },
    /// No usable GPU adapter was found, none matched the requested adapter, or the chosen
    /// one lacks compute shaders. Install a Vulkan driver (lavapipe without a GPU).
    #[error("no GPU adapter: {0}. On a machine without a GPU install Mesa's lavapipe (Debian: apt-get install mesa-vulkan-drivers libvulkan1)")]
    NoAdapter(String),
    /// The device could not be created, or wgpu reported an error (validation, out of
    /// memory, a failed read-back) while running the passes.
    #[error("GPU error: {0}")]
    Gpu(String),
}

/// `std::result::Result` with texsyn's [`Error`].
pub type Result<T> = std::result::Result<T, Error>;

/// So that an embedder creating its own adapter can use `?` in a function returning
/// [`Result`].
impl From<wgpu::RequestAdapterError> for Error {
    fn from(e: wgpu::RequestAdapterError) -> Self {
        Error::NoAdapter(e.to_string())
    }
}

/// So that an embedder creating its own device can use `?` in a function returning
/// [`Result`].
impl From<wgpu::RequestDeviceError> for Error {
    fn from(e: wgpu::RequestDeviceError) -> Self {
        Error::Gpu(format!("the device could not be created: {e}"))
    }
}

thread_local! {
    /// Set while [`catch_quietly`] runs its closure on this thread.
    static QUIET_PANICS: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Runs `f` (third-party decoder code on untrusted bytes), turning a panic into `Err(())`
/// without the panic message on stderr: the caller reports it as a bad file, and a
/// "thread panicked" line above that error would read as a crash. The hook installed for
/// this stays silent only for panics inside `f` on this thread and hands every other
/// panic to the hook that was there before (a host application's included).
pub(crate) fn catch_quietly<T>(f: impl FnOnce() -> T) -> std::result::Result<T, ()> {
    static INSTALL: std::sync::Once = std::sync::Once::new();
    INSTALL.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !QUIET_PANICS.with(|q| q.get()) {
                previous(info);
            }
        }));
    });
    let was = QUIET_PANICS.with(|q| q.replace(true));
    let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
    QUIET_PANICS.with(|q| q.set(was));
    r.map_err(|_| ())
}

#[cfg(test)]
mod tests {
    use super::catch_quietly;

    #[test]
    fn a_caught_panic_becomes_an_error_and_other_panics_still_reach_the_hook() {
        assert_eq!(catch_quietly(|| 7), Ok(7));
        assert_eq!(catch_quietly(|| -> u32 { panic!("corrupt data") }), Err(()));
        // Nested: the inner catch restores the outer quiet state.
        assert_eq!(
            catch_quietly(|| catch_quietly(|| -> u8 { panic!("inner") }).is_err()),
            Ok(true)
        );
        // Outside the closure panics are loud again (the flag is cleared).
        assert!(!super::QUIET_PANICS.with(|q| q.get()));
        assert!(std::panic::catch_unwind(|| panic!("loud")).is_err());
    }
}
