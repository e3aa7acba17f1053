//! Helpers shared by several test files (`mod common;`).
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Runs tools/validate_gltf.mjs (the Khronos validator) on `file`: its exit code and
/// output, or None when the validator is not installed and not required (with
/// TEXSYN_REQUIRE_GLTF_VALIDATOR=1 a missing validator panics).
pub fn run_validator(file: &Path) -> Option<(Option<i32>, String)> {
    let required = std::env::var("TEXSYN_REQUIRE_GLTF_VALIDATOR").as_deref() == Ok("1");
    let skip = |why: String| {
        if required {
            panic!(
                "{why}, and TEXSYN_REQUIRE_GLTF_VALIDATOR=1: install it with \
                 `(cd tools && npm install --no-audit --no-fund)` (needs node and npm)"
            );
        }
        eprintln!(
            "note: {why}: skipping the Khronos glTF validator check of {} (install it with \
             `cd tools && npm install`)",
            file.display()
        );
        None
    };
    if !repo().join("tools/node_modules/gltf-validator").is_dir() {
        return skip("tools/node_modules/gltf-validator is missing".into());
    }
    let out = match Command::new("node")
        .arg(repo().join("tools/validate_gltf.mjs"))
        .arg(file)
        .current_dir(repo())
        .output()
    {
        Ok(out) => out,
        Err(e) => return skip(format!("cannot run node: {e}")),
    };
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    Some((out.status.code(), text))
}

/// The Khronos validator's report on `file` (None when skipped, see [`run_validator`]).
/// Panics when it reports errors.
pub fn khronos_validate(file: &Path) -> Option<String> {
    let (code, text) = run_validator(file)?;
    assert_eq!(
        code,
        Some(0),
        "the Khronos glTF validator rejects {}:\n{text}",
        file.display()
    );
    println!("{text}");
    Some(text)
}

/// A scratch directory removed on drop.
pub struct TempDir(pub PathBuf);

impl TempDir {
    pub fn new(tag: &str) -> Self {
        static N: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let p = std::env::temp_dir().join(format!("texsyn-{tag}-{}-{n}", std::process::id()));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).unwrap();
        Self(p)
    }
    pub fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }

    pub fn join(&self, name: &str) -> PathBuf {
        self.path(name)
    }

    /// Every file under the directory (recursively), relative names, sorted.
    pub fn files(&self) -> Vec<String> {
        fn walk(dir: &Path, base: &Path, out: &mut Vec<String>) {
            for e in std::fs::read_dir(dir).unwrap() {
                let p = e.unwrap().path();
                if p.is_dir() {
                    walk(&p, base, out);
                } else {
                    out.push(p.strip_prefix(base).unwrap().display().to_string());
                }
            }
        }
        let mut v = Vec::new();
        walk(&self.0, &self.0, &mut v);
        v.sort();
        v
    }
}

/// The top-left `size` x `size` crop of the bundled gravel exemplar (small exemplars
/// keep GPU tests fast).
pub fn gravel_crop(size: u32) -> texsyn::analysis::Exemplar {
    let full = texsyn::image_io::load_exemplar(std::path::Path::new("assets/gravel.png")).unwrap();
    let c = full.channels as usize;
    let (mut values, mut colors) = (Vec::new(), Vec::new());
    for y in 0..size as usize {
        for x in 0..size as usize {
            let i = y * full.width as usize + x;
            values.extend_from_slice(&full.values[i * c..(i + 1) * c]);
            colors.push(full.colors[i]);
        }
    }
    texsyn::analysis::Exemplar {
        width: size,
        height: size,
        channels: full.channels,
        values,
        colors,
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
