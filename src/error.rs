//! One error type for the library; every message says what went wrong and, where it
//! helps, what to do about it. The CLI prints it and exits non-zero.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("cannot read {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path} is not a readable image: {reason}")]
    BadImage { path: PathBuf, reason: String },
    #[error("exemplar is {width}x{height}; texsyn needs at least {min}x{min} pixels")]
    ExemplarTooSmall { width: u32, height: u32, min: u32 },
    #[error("{what} is {width}x{height}, larger than this device allows ({limit}); {hint}")]
    TooLarge {
        what: &'static str,
        width: u32,
        height: u32,
        limit: String,
        hint: &'static str,
    },
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    #[error("{path}: {reason}")]
    BadAnalysisFile { path: PathBuf, reason: String },
    /// A mesh file (glTF / GLB) that cannot be used: unreadable structure, missing
    /// buffers, no triangles, out-of-range data.
    #[error("{path}: {reason}")]
    BadMesh { path: PathBuf, reason: String },
    #[error("cannot write {path}: {reason}")]
    Write { path: PathBuf, reason: String },
    #[error("no GPU adapter: {0}. On a machine without a GPU install Mesa's lavapipe (Debian: apt-get install mesa-vulkan-drivers libvulkan1)")]
    NoAdapter(String),
    #[error("GPU error: {0}")]
    Gpu(String),
}

pub type Result<T> = std::result::Result<T, Error>;
