//! Reading input files safely: regular files only (never a device or a pipe), with a
//! size cap.

use std::fs::{self, File};
use std::path::Path;

use crate::error::{Error, Result};

/// Opens `path` for reading if it is a regular file. The type is checked before the
/// open, since opening a named pipe blocks until something writes to it; a device such as
/// `/dev/zero` could fill the memory. The error says what the path is instead.
pub fn open_regular(path: &Path) -> std::io::Result<File> {
    let meta = fs::metadata(path)?;
    if meta.is_dir() {
        return Err(std::io::Error::other("it is a directory, not a file"));
    }
    if !meta.is_file() {
        return Err(std::io::Error::other(
            "it is not a regular file (a device or a pipe); give a file",
        ));
    }
    File::open(path)
}

/// Reads the whole file at `path`, refusing files of more than `max` bytes and anything
/// that is not a regular file (a device such as `/dev/zero` or a pipe could fill the
/// memory). Errors are [`Error::Io`] naming `path`; `what` names the input in the
/// message.
pub fn read_file_capped(path: &Path, max: u64, what: &str) -> Result<Vec<u8>> {
    use std::io::Read;
    let io = |source| Error::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = open_regular(path).map_err(io)?;
    let meta = file.metadata().map_err(io)?;
    let too_large = |n: u64| {
        io(std::io::Error::other(format!(
            "{} MiB; texsyn reads {what} of at most {} MiB",
            n >> 20,
            max >> 20
        )))
    };
    if meta.len() > max {
        return Err(too_large(meta.len()));
    }
    let mut bytes = Vec::new();
    file.take(max + 1).read_to_end(&mut bytes).map_err(io)?;
    if bytes.len() as u64 > max {
        // It grew while it was read.
        return Err(too_large(bytes.len() as u64));
    }
    Ok(bytes)
}

/// The most bytes a mesh file (or one of its external buffers) may have.
pub const MAX_MESH_FILE_BYTES: u64 = 2 << 30;
