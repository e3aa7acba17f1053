//! The WGSL `#include` preprocessor, shared by `build.rs` (which validates and embeds the
//! pass shaders) and the library (which declares it so the unit tests below run).
//!
//! A line of the form `#include "shared/common.wgsl"` (optionally indented, optionally
//! followed by a `//` comment) is replaced by the preprocessed contents of that file.
//! Every path, the root's included, is relative to the shader directory (`shaders/`), not
//! to the including file, so `shared/a.wgsl` includes `shared/b.wgsl` as
//! `#include "shared/b.wgsl"`. Each file is included at most once per root shader: a
//! second `#include` of the same file (or of the root itself) expands to nothing, which
//! also makes include cycles harmless.
//!
//! The output keeps every original line verbatim (only `\r\n` becomes `\n`), so columns
//! are unchanged and [`Preprocessed::origin`] maps a preprocessed line back to the file
//! and line it came from.
//!
//! The module is pure: files are read through a caller-supplied closure, which is how
//! `build.rs` reads `shaders/` and how the tests below use an in-memory map.

// build.rs and the library each use a different subset of this module.
#![allow(dead_code)]

use std::fmt;

/// A preprocessed shader and the origin of each of its lines.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Preprocessed {
    /// The preprocessed WGSL; every line ends with `\n`.
    pub text: String,
    /// Every file that contributed lines, root first, in the order they were included.
    pub files: Vec<String>,
    /// `lines[i]` is the origin of preprocessed line `i + 1`: (index into `files`,
    /// 1-based line in that file).
    pub lines: Vec<(usize, u32)>,
}

impl Preprocessed {
    /// The (file, 1-based line) that 1-based preprocessed line `line` came from.
    pub fn origin(&self, line: u32) -> Option<(&str, u32)> {
        let index = usize::try_from(line).ok()?.checked_sub(1)?;
        let &(file, original) = self.lines.get(index)?;
        Some((self.files[file].as_str(), original))
    }

    /// The (file, 1-based line) of the preprocessed text at byte `offset`.
    pub fn origin_of_offset(&self, offset: usize) -> Option<(&str, u32)> {
        let offset = offset.min(self.text.len());
        let line = self.text.as_bytes()[..offset]
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
            + 1;
        self.origin(u32::try_from(line).ok()?)
    }
}

/// Why preprocessing failed, located in the original sources.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PreprocessError {
    /// The file holding the offending `#include` (or the root, if it cannot be read).
    pub file: String,
    /// 1-based line of the offending `#include`; `None` when the root cannot be read.
    pub line: Option<u32>,
    /// What went wrong.
    pub message: String,
}

impl fmt::Display for PreprocessError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(line) => write!(f, "{}:{}:1: error: {}", self.file, line, self.message),
            None => write!(f, "{}: error: {}", self.file, self.message),
        }
    }
}

impl std::error::Error for PreprocessError {}

/// Expand the `#include`s of `root`.
///
/// `read` is called with a normalised path relative to the shader directory (no `.`
/// or `..` components, `/` separators) and returns the file's text or a reason it cannot.
/// Each file is read at most once.
pub fn preprocess<F>(root: &str, mut read: F) -> Result<Preprocessed, PreprocessError>
where
    F: FnMut(&str) -> Result<String, String>,
{
    let root = normalize(root).map_err(|message| PreprocessError {
        file: root.to_string(),
        line: None,
        message,
    })?;
    let text = read(&root).map_err(|reason| PreprocessError {
        file: root.clone(),
        line: None,
        message: format!("cannot read shader: {reason}"),
    })?;
    let mut out = Preprocessed {
        text: String::with_capacity(text.len()),
        files: vec![root],
        lines: Vec::new(),
    };
    expand(0, &text, &mut read, &mut out)?;
    Ok(out)
}

/// Append file `files[file]`, whose contents are `text`, to `out`.
fn expand<F>(
    file: usize,
    text: &str,
    read: &mut F,
    out: &mut Preprocessed,
) -> Result<(), PreprocessError>
where
    F: FnMut(&str) -> Result<String, String>,
{
    for (index, line) in text.lines().enumerate() {
        let line_number = u32::try_from(index + 1).unwrap_or(u32::MAX);
        let error = |message: String| PreprocessError {
            file: out.files[file].clone(),
            line: Some(line_number),
            message,
        };
        match parse_include(line) {
            None => {
                out.text.push_str(line);
                out.text.push('\n');
                out.lines.push((file, line_number));
            }
            Some(Err(message)) => return Err(error(message)),
            Some(Ok(path)) => {
                let path = normalize(path).map_err(&error)?;
                if out.files.contains(&path) {
                    continue; // included at most once per shader
                }
                let included = read(&path)
                    .map_err(|reason| error(format!("cannot include \"{path}\": {reason}")))?;
                out.files.push(path);
                expand(out.files.len() - 1, &included, read, out)?;
            }
        }
    }
    Ok(())
}

/// `None`: not a directive. `Some(Ok(path))`: an include. `Some(Err(_))`: a malformed one.
fn parse_include(line: &str) -> Option<Result<&str, String>> {
    let rest = line.trim_start().strip_prefix("#include")?;
    let malformed = || {
        Err(format!(
            "malformed include `{}`; expected `#include \"path/relative/to/shaders.wgsl\"`",
            line.trim()
        ))
    };
    if !rest.starts_with([' ', '\t']) {
        return Some(malformed());
    }
    let Some(rest) = rest.trim_start().strip_prefix('"') else {
        return Some(malformed());
    };
    let Some((path, tail)) = rest.split_once('"') else {
        return Some(malformed());
    };
    let tail = tail.trim();
    if path.is_empty() || !(tail.is_empty() || tail.starts_with("//")) {
        return Some(malformed());
    }
    Some(Ok(path))
}

/// Normalise an include path: `/` separators, no `.`/`..`/empty components, not absolute,
/// not escaping the shader directory.
fn normalize(path: &str) -> Result<String, String> {
    if path.starts_with('/') || path.contains('\\') || path.contains(':') {
        return Err(format!(
            "include path \"{path}\" must be relative to shaders/ and use '/' separators"
        ));
    }
    let mut parts: Vec<&str> = Vec::new();
    for part in path.split('/') {
        match part {
            "" | "." => {}
            ".." => {
                if parts.pop().is_none() {
                    return Err(format!(
                        "include path \"{path}\" leaves the shaders/ directory"
                    ));
                }
            }
            _ => parts.push(part),
        }
    }
    if parts.is_empty() {
        return Err(format!("include path \"{path}\" names no file"));
    }
    Ok(parts.join("/"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    /// Preprocess `root` from an in-memory file set, recording which files were read.
    fn run(
        files: &[(&str, &str)],
        root: &str,
    ) -> (Result<Preprocessed, PreprocessError>, Vec<String>) {
        let files: HashMap<&str, &str> = files.iter().copied().collect();
        let mut reads = Vec::new();
        let result = preprocess(root, |path| {
            reads.push(path.to_string());
            files
                .get(path)
                .map(|text| text.to_string())
                .ok_or_else(|| "no such file".to_string())
        });
        (result, reads)
    }

    #[test]
    fn no_includes_is_identity_with_trailing_newline() {
        let (out, _) = run(&[("a.wgsl", "x\r\ny")], "a.wgsl");
        let out = out.unwrap();
        assert_eq!(out.text, "x\ny\n");
        assert_eq!(out.origin(1), Some(("a.wgsl", 1)));
        assert_eq!(out.origin(2), Some(("a.wgsl", 2)));
        assert_eq!(out.origin(3), None);
        assert_eq!(out.origin(0), None);
    }

    #[test]
    fn include_is_expanded_once() {
        let files = [
            (
                "pass.wgsl",
                "#include \"shared/common.wgsl\"\nfn main() {}\n#include \"shared/common.wgsl\"\n",
            ),
            ("shared/common.wgsl", "const A: u32 = 1u;\n"),
        ];
        let (out, reads) = run(&files, "pass.wgsl");
        let out = out.unwrap();
        assert_eq!(out.text, "const A: u32 = 1u;\nfn main() {}\n");
        assert_eq!(reads, ["pass.wgsl", "shared/common.wgsl"]);
        assert_eq!(out.files, ["pass.wgsl", "shared/common.wgsl"]);
    }

    #[test]
    fn nested_include_and_diamond() {
        let files = [
            (
                "pass.wgsl",
                "#include \"shared/a.wgsl\"\n  #include \"./shared//b.wgsl\" // b too\nmain\n",
            ),
            ("shared/a.wgsl", "a1\n#include \"shared/b.wgsl\"\na2\n"),
            (
                "shared/b.wgsl",
                "b1\n#include \"shared/a.wgsl\"\n#include \"pass.wgsl\"\n",
            ),
        ];
        let (out, _) = run(&files, "pass.wgsl");
        let out = out.unwrap();
        // b is pulled in by a; the cycle back to a and to the root and the second
        // include of b in the root all expand to nothing.
        assert_eq!(out.text, "a1\nb1\na2\nmain\n");
        assert_eq!(out.origin(1), Some(("shared/a.wgsl", 1)));
        assert_eq!(out.origin(2), Some(("shared/b.wgsl", 1)));
        assert_eq!(out.origin(3), Some(("shared/a.wgsl", 3)));
        assert_eq!(out.origin(4), Some(("pass.wgsl", 3)));
    }

    #[test]
    fn missing_include_names_the_including_line() {
        let files = [
            ("pass.wgsl", "fn f() {}\n#include \"shared/common.wgsl\"\n"),
            (
                "shared/common.wgsl",
                "x\n\n#include \"shared/missing.wgsl\"\n",
            ),
        ];
        let (out, _) = run(&files, "pass.wgsl");
        let err = out.unwrap_err();
        assert_eq!(err.file, "shared/common.wgsl");
        assert_eq!(err.line, Some(3));
        assert!(err.message.contains("shared/missing.wgsl"), "{err}");
        assert!(err.message.contains("no such file"), "{err}");
        assert!(
            err.to_string()
                .starts_with("shared/common.wgsl:3:1: error: "),
            "{err}"
        );
    }

    #[test]
    fn missing_root_and_bad_directives() {
        let (out, _) = run(&[], "pass.wgsl");
        let err = out.unwrap_err();
        assert_eq!((err.file.as_str(), err.line), ("pass.wgsl", None));

        for bad in [
            "#include shared/a.wgsl",
            "#include \"shared/a.wgsl",
            "#include\"shared/a.wgsl\"",
            "#include \"shared/a.wgsl\" junk",
            "#include \"\"",
            "#include \"../outside.wgsl\"",
            "#include \"/abs.wgsl\"",
            "#includes \"a.wgsl\"",
        ] {
            let text = format!("x\n{bad}\n");
            let (out, _) = run(
                &[("pass.wgsl", &text), ("shared/a.wgsl", "a\n")],
                "pass.wgsl",
            );
            let err = out.expect_err(bad);
            assert_eq!(
                (err.file.as_str(), err.line),
                ("pass.wgsl", Some(2)),
                "{bad}"
            );
        }
    }

    #[test]
    fn line_mapping_through_includes() {
        let common: String = (1..=50).map(|i| format!("// common {i}\n")).collect();
        let files = [
            (
                "upsample.wgsl",
                "// header\n#include \"shared/common.wgsl\"\nfn main() {}\n",
            ),
            ("shared/common.wgsl", common.as_str()),
        ];
        let (out, _) = run(&files, "upsample.wgsl");
        let out = out.unwrap();
        assert_eq!(out.lines.len(), 52);
        assert_eq!(out.origin(1), Some(("upsample.wgsl", 1)));
        assert_eq!(out.origin(2), Some(("shared/common.wgsl", 1)));
        assert_eq!(out.origin(43), Some(("shared/common.wgsl", 42)));
        assert_eq!(out.origin(52), Some(("upsample.wgsl", 3)));
        let offset = out.text.find("// common 42\n").unwrap() + 3;
        assert_eq!(
            out.origin_of_offset(offset),
            Some(("shared/common.wgsl", 42))
        );
        assert_eq!(out.text.lines().nth(42), Some("// common 42"));
    }
}
