//! Atomic writes: every output goes to a temporary file next to its target, is fsynced,
//! then renamed over the target, so that a failed or interrupted write never leaves a
//! partial file. Outputs in progress are tracked so that a signal handler can remove them.

use std::ffi::OsString;
use std::fs::{self, File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{Error, Result};

static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Removes the temporary file on drop unless disarmed (covers errors and panics in the
/// caller's closure). While armed, the file is listed in [`PENDING_OUTPUTS`], so that an
/// interrupted run can remove it too ([`remove_pending_outputs`]).
struct TempGuard {
    path: PathBuf,
    armed: bool,
}

impl TempGuard {
    fn disarm(&mut self) {
        self.armed = false;
        forget_pending_output(&self.path);
    }
}

impl Drop for TempGuard {
    fn drop(&mut self) {
        if self.armed {
            let _ = fs::remove_file(&self.path);
            forget_pending_output(&self.path);
        }
    }
}

/// Temporary files and staging folders of outputs not yet committed (`true`: a folder).
static PENDING_OUTPUTS: std::sync::Mutex<Vec<(PathBuf, bool)>> = std::sync::Mutex::new(Vec::new());

/// Lists `path` (a temporary file, or a staging folder when `dir`) as an output in
/// progress: [`remove_pending_outputs`] removes it unless [`forget_pending_output`] was
/// called first. Destructors clean up after errors and panics; this is for a process
/// that is interrupted (Ctrl-C, `kill`), where no destructor runs.
pub fn register_pending_output(path: &Path, dir: bool) {
    let mut p = PENDING_OUTPUTS.lock().unwrap_or_else(|e| e.into_inner());
    p.push((path.to_path_buf(), dir));
}

/// The output at `path` was committed or removed: no longer listed.
pub fn forget_pending_output(path: &Path) {
    let mut p = PENDING_OUTPUTS.lock().unwrap_or_else(|e| e.into_inner());
    p.retain(|(q, _)| q != path);
}

/// Removes every output in progress (temporary files, staging folders), for a process
/// about to exit on a signal. Targets are never touched: they hold either the previous
/// file or a complete new one. Returns how many were removed.
pub fn remove_pending_outputs() -> usize {
    let p = PENDING_OUTPUTS.lock().unwrap_or_else(|e| e.into_inner());
    p.iter()
        .filter(|(path, dir)| {
            if *dir {
                fs::remove_dir_all(path).is_ok()
            } else {
                fs::remove_file(path).is_ok()
            }
        })
        .count()
}

/// Writes a file atomically: `write` fills a temporary file `.{filename}.{pid}.{n}.tmp` in
/// the target's directory, which is then flushed, fsynced and renamed over `path` (and
/// the directory is fsynced, best effort). On any error, or if `write` panics, the
/// temporary file is removed and `path` is left untouched: it never holds a partial file.
///
/// All failures are [`Error::Write`] naming `path` (an error returned by `write` that is
/// already an `Error::Write` is passed through unchanged; other errors are wrapped).
/// A symlink at `path` is followed: the file it points to is replaced. The new file gets
/// default permissions. A `path` that is not a regular file (`/dev/null`, a named pipe)
/// is written to directly, never replaced. Temporary files that a killed run left for
/// the same `path` (their process is gone) are removed.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> Result<()>,
) -> Result<()> {
    stage_file(path, write)?.commit()
}

/// A file written in full to its temporary name and fsynced, not yet renamed over its
/// target ([`stage_file`]); dropped without [`StagedFile::commit`], the temporary file is
/// removed and the target never touched.
pub struct StagedFile {
    /// `None`: the target was a stream (a device, a pipe), already written.
    temp: Option<TempGuard>,
    path: PathBuf,
    dir: PathBuf,
}

impl StagedFile {
    /// Renames the temporary file over the target (and fsyncs the directory, best
    /// effort).
    pub fn commit(mut self) -> Result<()> {
        let Some(guard) = self.temp.as_mut() else {
            return Ok(());
        };
        fs::rename(&guard.path, &self.path).map_err(|e| Error::Write {
            path: self.path.clone(),
            reason: format!("cannot rename the temporary file: {e}"),
        })?;
        guard.disarm();
        // Make the rename durable; not all platforms / file systems allow this.
        if let Ok(d) = File::open(&self.dir) {
            let _ = d.sync_all();
        }
        Ok(())
    }
}

/// Writes several files all or nothing: every one is first written to its temporary
/// name and fsynced, and only when all of them succeeded are they renamed over their
/// targets. A failure before that (disk full, a read-only directory) leaves every
/// target as it was, including those that existed before. Only a rename failing part
/// way (rare: the temporary files lie in the targets' own directories) can leave some
/// targets replaced and others not.
pub fn write_files_atomic(files: &[(&Path, &[u8])]) -> Result<()> {
    let mut staged = Vec::with_capacity(files.len());
    for &(path, bytes) in files {
        staged.push(stage_file(path, |w| {
            w.write_all(bytes).map_err(|e| Error::Write {
                path: path.to_path_buf(),
                reason: e.to_string(),
            })
        })?);
    }
    staged.into_iter().try_for_each(StagedFile::commit)
}

/// The first half of [`write_atomic`]: `write` fills the temporary file, which is
/// flushed and fsynced; [`StagedFile::commit`] renames it over `path`.
pub fn stage_file(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> Result<()>,
) -> Result<StagedFile> {
    let werr = |reason: String| Error::Write {
        path: path.to_path_buf(),
        reason,
    };
    // A link to a stream (`/dev/stdout` -> `/proc/self/fd/1` -> `pipe:[..]`, whose target
    // names no path) is written through as it is; other links are followed to the file
    // they name, which is then replaced.
    let stream = fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir());
    let resolved = if stream {
        path.to_path_buf()
    } else {
        follow_symlinks(path).map_err(werr)?
    };
    let path = resolved.as_path();

    let Some(file_name) = path.file_name() else {
        return Err(werr("the path does not name a file".into()));
    };
    if path.is_dir() {
        return Err(werr("it is a directory; give a file name".into()));
    }
    if let Ok(meta) = fs::metadata(path) {
        if !meta.is_file() {
            // A device or a pipe: a stream, not a file to replace.
            let file = OpenOptions::new()
                .write(true)
                .open(path)
                .map_err(|e| werr(format!("cannot open it for writing: {e}")))?;
            let mut w = BufWriter::new(file);
            write(&mut w).map_err(|e| match e {
                Error::Write { .. } => e,
                other => werr(other.to_string()),
            })?;
            w.into_inner().map_err(|e| werr(e.error().to_string()))?;
            return Ok(StagedFile {
                temp: None,
                path: path.to_path_buf(),
                dir: PathBuf::new(),
            });
        }
    }
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !dir.is_dir() {
        return Err(werr(if dir.exists() {
            format!("{} is not a directory", dir.display())
        } else {
            format!(
                "directory {} does not exist; create it first",
                dir.display()
            )
        }));
    }

    remove_stale_temporaries(&dir, file_name);
    let mut tmp_name = OsString::from(".");
    tmp_name.push(file_name);
    tmp_name.push(format!(
        ".{}.{}.tmp",
        std::process::id(),
        TEMP_COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let tmp_path = dir.join(tmp_name);

    // Listed before it exists, so that no interruption falls between the two.
    register_pending_output(&tmp_path, false);
    let file = OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&tmp_path)
        .map_err(|e| {
            forget_pending_output(&tmp_path);
            werr(format!(
                "cannot create a temporary file in {}: {e}",
                dir.display()
            ))
        })?;
    let guard = TempGuard {
        path: tmp_path,
        armed: true,
    };

    let mut w = BufWriter::new(file);
    write(&mut w).map_err(|e| match e {
        Error::Write { .. } => e,
        other => werr(other.to_string()),
    })?;
    let file = w.into_inner().map_err(|e| werr(e.error().to_string()))?;
    file.sync_all()
        .map_err(|e| werr(format!("fsync failed: {e}")))?;
    drop(file);
    Ok(StagedFile {
        temp: Some(guard),
        path: path.to_path_buf(),
        dir,
    })
}

/// `path` with its symlinks followed (a dangling link names the file to create).
fn follow_symlinks(path: &Path) -> std::result::Result<PathBuf, String> {
    let mut p = path.to_path_buf();
    for _ in 0..32 {
        match fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                let target = fs::read_link(&p).map_err(|e| format!("cannot read the link: {e}"))?;
                p = match p.parent() {
                    Some(dir) if target.is_relative() => dir.join(target),
                    _ => target,
                };
            }
            _ => return Ok(p),
        }
    }
    Err("too many levels of symbolic links".into())
}

/// Removes `.{file_name}.{pid}.{n}.tmp` files in `dir` whose process no longer runs
/// (left by a run that was killed while writing). Only where `/proc` tells which
/// processes run; best effort.
fn remove_stale_temporaries(dir: &Path, file_name: &std::ffi::OsStr) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let Some(name) = file_name.to_str() else {
        return;
    };
    let prefix = format!(".{name}.");
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let entry_name = entry.file_name();
        let Some(rest) = entry_name
            .to_str()
            .and_then(|n| n.strip_prefix(&prefix))
            .and_then(|n| n.strip_suffix(".tmp"))
        else {
            continue;
        };
        let Some((pid, n)) = rest.split_once('.') else {
            continue;
        };
        let (Ok(pid), Ok(_)) = (pid.parse::<u32>(), n.parse::<u64>()) else {
            continue;
        };
        if pid != std::process::id() && !Path::new(&format!("/proc/{pid}")).exists() {
            let _ = fs::remove_file(entry.path());
        }
    }
}
