//! Output paths, checked before any work: a writable directory, a file name, not one of
//! the command's inputs, not given twice.

use std::path::{Path, PathBuf};

use super::{fail, CliResult};

/// Checks, before any work, that `path` can be created: `dir`, where it is to be
/// written, is an existing directory. (The file itself is only written, atomically, once
/// the work has succeeded.) Every output goes through here, so `path` is also listed as
/// an output of this run: an interrupted run removes its unfinished pieces
/// ([`super::interrupt::register_output`]).
pub fn check_parent_dir(path: &Path, dir: &Path) -> CliResult<()> {
    if dir.is_dir() {
        super::interrupt::register_output(path);
        return Ok(());
    }
    Err(fail(if dir.exists() {
        format!(
            "cannot write {}: {} is not a directory",
            path.display(),
            dir.display()
        )
    } else {
        format!(
            "cannot write {}: directory {} does not exist; create it first",
            path.display(),
            dir.display()
        )
    }))
}

/// An output that must be a named file or folder: `-` (standard output for `synth`'s
/// image) is refused rather than taken for a file named `-`.
pub fn parse_named_output(s: &str) -> Result<PathBuf, String> {
    if s == "-" {
        return Err(
            "`-` (standard output) is only for synth's image; give a file or folder \
                    name (./- for one named `-`)"
                .into(),
        );
    }
    Ok(PathBuf::from(s))
}

/// Checks, before any work, that the file `path` can be written: it names a file, not a
/// folder or a dangling link, in a directory that takes new files.
pub fn check_output_dir(path: &Path) -> CliResult<()> {
    if path.file_name().is_none() {
        return Err(fail(format!(
            "cannot write {}: the path does not name a file",
            path.display()
        )));
    }
    if path.is_dir() {
        return Err(fail(format!(
            "cannot write {}: it is a directory; give a file name",
            path.display()
        )));
    }
    if std::fs::symlink_metadata(path).is_ok() && !path.exists() {
        return Err(fail(format!(
            "cannot write {}: it is a symbolic link to a missing path; remove it or give \
             another name",
            path.display()
        )));
    }
    // A device or pipe (`-o /dev/null`) is written to as it is, not replaced (opening a
    // pipe now would wait for its reader: the write reports any error).
    if std::fs::metadata(path).is_ok_and(|m| !m.is_file()) {
        return Ok(());
    }
    // A symlink names the file it points to (which is replaced), in that file's directory.
    let resolved;
    let path = match std::fs::canonicalize(path) {
        Ok(p) if std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink()) => {
            resolved = p;
            resolved.as_path()
        }
        _ => path,
    };
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    check_parent_dir(path, &dir)?;
    // Probe that the directory takes new files (read-only mounts, /proc, permissions):
    // failing now costs nothing, failing after the work would leave other outputs half
    // written.
    takes_new_files(&dir).map_err(|e| {
        fail(format!(
            "cannot write {}: the directory {} does not take new files ({e}); choose a \
             writable folder",
            path.display(),
            dir.display()
        ))
    })
}

/// Whether `dir` takes new files: a probe file is created and removed.
pub fn takes_new_files(dir: &Path) -> std::io::Result<()> {
    let probe = dir.join(format!(".texsyn-probe-{}", std::process::id()));
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// Refuses two outputs of one command that name the same file (the later write would
/// silently replace the earlier one).
pub fn check_distinct_outputs(paths: &[&Path]) -> CliResult<()> {
    let key = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    for (i, a) in paths.iter().enumerate() {
        for b in &paths[..i] {
            if key(a) == key(b) {
                return Err(fail(format!(
                    "{} is given for two outputs; give each output its own file",
                    a.display()
                )));
            }
        }
    }
    Ok(())
}

/// Refuses an output that names one of the command's own inputs: the output would
/// silently replace it (an exemplar, a coordinate map, a mesh). Inputs are labelled for
/// the message, e.g. `("exemplar", path)`. An output that does not exist yet cannot be
/// an input; existing files are compared as files (links and `./x` vs `x` included).
pub fn check_outputs_not_inputs(outputs: &[&Path], inputs: &[(&str, &Path)]) -> CliResult<()> {
    for out in outputs {
        let Ok(out_meta) = std::fs::metadata(out) else {
            continue;
        };
        for (what, input) in inputs {
            let Ok(in_meta) = std::fs::metadata(input) else {
                continue;
            };
            if same_file(out, &out_meta, input, &in_meta) {
                return Err(fail(format!(
                    "{} is also the {what}, an input: writing it would replace the input; \
                     give the output another name",
                    out.display()
                )));
            }
        }
    }
    Ok(())
}

#[cfg(unix)]
fn same_file(_: &Path, a: &std::fs::Metadata, _: &Path, b: &std::fs::Metadata) -> bool {
    use std::os::unix::fs::MetadataExt;
    a.dev() == b.dev() && a.ino() == b.ino()
}

#[cfg(not(unix))]
fn same_file(a: &Path, _: &std::fs::Metadata, b: &Path, _: &std::fs::Metadata) -> bool {
    matches!((std::fs::canonicalize(a), std::fs::canonicalize(b)), (Ok(x), Ok(y)) if x == y)
}
