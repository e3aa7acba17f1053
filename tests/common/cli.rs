//! Running the `texsyn` binary: its exit status, stdout and stderr, and the checks that a
//! run succeeded or failed cleanly.

use std::path::Path;
use std::process::{Command, Output};

use super::TempDir;

/// The binary Cargo built for these tests.
pub const BIN: &str = env!("CARGO_BIN_EXE_texsyn");

/// The bundled gravel exemplar, by absolute path (runs happen in scratch directories).
pub const GRAVEL: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/gravel.png");

/// The bundled bunny mesh, by absolute path.
pub const BUNNY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/meshes/bunny.glb");

/// A `texsyn` command ready to run in `dir`.
pub fn command(dir: &Path) -> Command {
    let mut c = Command::new(BIN);
    c.current_dir(dir);
    c
}

/// Runs `texsyn args...` in `dir`.
pub fn texsyn(dir: &TempDir, args: &[&str]) -> Output {
    texsyn_in(dir.root(), args)
}

/// Runs `texsyn args...` in the folder `dir` (the repository for relative asset paths).
pub fn texsyn_in(dir: &Path, args: &[&str]) -> Output {
    command(dir)
        .args(args)
        .output()
        .expect("cannot run the texsyn binary")
}

/// Runs `texsyn args...` in the repository root (asset paths such as
/// `assets/gravel.png` relative).
pub fn texsyn_at_repo(args: &[&str]) -> Output {
    texsyn_in(&super::repo(), args)
}

/// Bytes as text, invalid UTF-8 replaced.
pub fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// Runs and asserts success; returns stdout.
pub fn ok(dir: &TempDir, args: &[&str]) -> String {
    let out = texsyn(dir, args);
    assert!(
        out.status.success(),
        "texsyn {args:?} failed ({:?}):\n{}",
        out.status,
        text(&out.stderr)
    );
    text(&out.stdout)
}

/// Runs, asserts failure with exit code `code` and a stderr line `error: ...` containing
/// `needle` (case-insensitive), no panic, and that the directory holds exactly what it
/// held before (no output, no temporary file).
pub fn fails(dir: &TempDir, args: &[&str], code: i32, needle: &str) {
    let before = dir.entries();
    let out = texsyn(dir, args);
    let stderr = text(&out.stderr);
    assert_eq!(
        out.status.code(),
        Some(code),
        "texsyn {args:?}: stderr:\n{stderr}"
    );
    let error_line = stderr
        .lines()
        .find(|l| l.starts_with("error: ") && l.to_lowercase().contains(&needle.to_lowercase()));
    assert!(
        error_line.is_some(),
        "texsyn {args:?}: no `error: ...{needle}...` line in stderr:\n{stderr}"
    );
    assert!(
        !stderr.contains("panicked"),
        "texsyn {args:?} panicked:\n{stderr}"
    );
    assert_eq!(dir.entries(), before, "texsyn {args:?} left files behind");
}

/// Owned arguments as the `&str`s [`texsyn`] takes.
pub fn strs(args: &[String]) -> Vec<&str> {
    args.iter().map(String::as_str).collect()
}
