//! Atomic writes: every output goes to a temporary file next to its target, is fsynced,
//! then renamed over the target, so that a failed or interrupted write never leaves a
//! partial file. [`remove_temporaries`] lets a signal handler remove the temporary files
//! of an interrupted run.

use std::ffi::OsString;
use std::fs::{self, File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{Error, Result};

static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Removes the temporary file on drop unless disarmed (covers errors and panics in the
/// caller's closure).
struct TempGuard {
    path: PathBuf,
    armed: bool,
}

impl TempGuard {
    fn disarm(&mut self) {
        self.armed = false;
    }
}

impl Drop for TempGuard {
    fn drop(&mut self) {
        if self.armed {
            let _ = fs::remove_file(&self.path);
        }
    }
}

/// Removes the temporary files that this process is writing for the output `path` (the
/// `.{name}.{pid}.{n}.tmp` files of [`write_atomic`] and [`stage_file`]), for a process
/// about to exit on a signal (Ctrl-C, `kill`), where no destructor runs. The output
/// itself is never touched: it holds either the previous file or a complete new one.
/// Returns how many were removed.
///
/// ```no_run
/// // In a signal handler's thread, for each output the program was writing:
/// let removed = texsyn::image_io::remove_temporaries("out.png".as_ref());
/// # let _ = removed;
/// ```
pub fn remove_temporaries(path: &Path) -> usize {
    if fs::metadata(path).is_ok_and(|m| !m.is_file()) {
        // A stream (written through) or a folder: no temporary file.
        return 0;
    }
    let Ok(path) = follow_symlinks(path) else {
        return 0;
    };
    let (Some(dir), Some(name)) = (parent_dir(&path), path.file_name()) else {
        return 0;
    };
    let own = std::process::id();
    temporaries(&dir, name)
        .filter(|(_, pid)| *pid == own)
        .filter(|(p, _)| fs::remove_file(p).is_ok())
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
    let dir = parent_dir(path).expect("a path that names a file has a parent");
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

    let file = OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&tmp_path)
        .map_err(|e| {
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

/// The directory `path` lies in (`.` for a bare file name).
fn parent_dir(path: &Path) -> Option<PathBuf> {
    path.file_name()?;
    Some(match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    })
}

/// The temporary files `.{file_name}.{pid}.{n}.tmp` in `dir`, with their process ids.
fn temporaries(dir: &Path, file_name: &std::ffi::OsStr) -> impl Iterator<Item = (PathBuf, u32)> {
    let prefix = file_name.to_str().map(|name| format!(".{name}."));
    let entries = prefix.as_ref().and_then(|_| fs::read_dir(dir).ok());
    entries
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(move |entry| {
            let entry_name = entry.file_name();
            let rest = entry_name
                .to_str()?
                .strip_prefix(prefix.as_deref()?)?
                .strip_suffix(".tmp")?;
            let (pid, n) = rest.split_once('.')?;
            n.parse::<u64>().ok()?;
            Some((entry.path(), pid.parse::<u32>().ok()?))
        })
}

/// Removes `.{file_name}.{pid}.{n}.tmp` files in `dir` whose process no longer runs
/// (left by a run that was killed while writing). Only where `/proc` tells which
/// processes run; best effort.
fn remove_stale_temporaries(dir: &Path, file_name: &std::ffi::OsStr) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    for (path, pid) in temporaries(dir, file_name) {
        if pid != std::process::id() && !Path::new(&format!("/proc/{pid}")).exists() {
            let _ = fs::remove_file(path);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn remove_temporaries_takes_only_this_process_s() {
        let dir = std::env::temp_dir().join(format!("texsyn-atomic-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let own = dir.join(format!(".out.png.{}.3.tmp", std::process::id()));
        let other = dir.join(".out.png.1.3.tmp");
        let unrelated = dir.join(format!(".other.png.{}.0.tmp", std::process::id()));
        for p in [&own, &other, &unrelated] {
            fs::write(p, b"x").unwrap();
        }
        assert_eq!(remove_temporaries(&dir.join("out.png")), 1);
        assert!(!own.exists() && other.exists() && unrelated.exists());
        fs::remove_dir_all(&dir).unwrap();
    }
}
