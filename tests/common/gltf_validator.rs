//! The Khronos glTF validator (tools/validate_gltf.mjs, installed with `cd tools && npm install`).

use std::path::Path;
use std::process::Command;

use super::repo;

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
