//! Build script: preprocess (`#include`), parse and validate every shader with naga, and
//! generate the Rust that `src/gpu/shaders.rs` includes:
//!
//! * `shaders/*.wgsl` are compute passes (exactly one `@compute` entry point each):
//!   `$OUT_DIR/shaders.rs`, one `ShaderSource` constant per pass plus `ALL`;
//! * `shaders/render/*.wgsl` are render shaders (exactly one `@vertex` and one
//!   `@fragment` entry point each): `$OUT_DIR/render_shaders.rs`, one
//!   `RenderShaderSource` constant per shader plus `ALL`, in module `shaders::render`.
//!
//! Every `#include` path is relative to `shaders/`, for both kinds. A WGSL error fails the
//! build with `shaders/<file>:<line>:<col>: error: ...` (`shaders/render/<file>:...` for a
//! render shader), located in the original file (an included one where that is where the
//! error is).
//!
//! It also checks that every struct Rust uploads and a shader reads
//! ([`SHARED_STRUCTS`]) has the same fields at the same offsets with the same sizes on
//! both sides; a mismatch fails the build naming the struct and field.

#[path = "src/shader_preprocess.rs"]
mod shader_preprocess;

use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

use shader_preprocess::{preprocess, Preprocessed};

/// The shader directory, relative to the crate root; also the prefix of reported paths.
const SHADER_DIR: &str = "shaders";
/// The render shaders' subdirectory of [`SHADER_DIR`].
const RENDER_SUBDIR: &str = "render";

fn main() {
    let manifest_dir =
        PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").expect("CARGO_MANIFEST_DIR"));
    let out_dir = PathBuf::from(std::env::var_os("OUT_DIR").expect("OUT_DIR"));
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=src/shader_preprocess.rs");
    println!("cargo:rerun-if-changed={SHADER_DIR}");
    println!("cargo:rerun-if-changed={SHADER_DIR}/{RENDER_SUBDIR}");

    let shader_dir = manifest_dir.join(SHADER_DIR);
    let preprocessed_dir = out_dir.join("shaders");
    let compute = build_shaders(&shader_dir, SHADER_DIR, &preprocessed_dir, Kind::Compute);
    let render = build_shaders(&shader_dir, SHADER_DIR, &preprocessed_dir, Kind::Render);
    for file in compute.read.union(&render.read) {
        println!("cargo:rerun-if-changed={SHADER_DIR}/{file}");
    }
    let errors: Vec<&String> = compute.errors.iter().chain(&render.errors).collect();
    if !errors.is_empty() {
        let report = errors
            .iter()
            .map(|e| e.as_str())
            .collect::<Vec<_>>()
            .join("\n");
        for line in report.lines() {
            println!("cargo:warning={line}");
        }
        panic!(
            "{} shader error(s) in {SHADER_DIR}/:\n{report}",
            errors.len()
        );
    }
    let shaders: Vec<ShaderModule> = compute.modules.into_iter().chain(render.modules).collect();
    let (rust_files, mismatches) = check_shared_structs(&manifest_dir, &shaders);
    for file in &rust_files {
        println!("cargo:rerun-if-changed={file}");
    }
    if !mismatches.is_empty() {
        for line in &mismatches {
            println!("cargo:warning={line}");
        }
        panic!(
            "{} host/shader struct layout mismatch(es):\n{}",
            mismatches.len(),
            mismatches.join("\n")
        );
    }
    for (name, code) in [
        ("shaders.rs", compute.code),
        ("render_shaders.rs", render.code),
    ] {
        let generated = out_dir.join(name);
        fs::write(&generated, code)
            .unwrap_or_else(|e| panic!("cannot write {}: {e}", generated.display()));
    }
}

/// Which shaders [`build_shaders`] handles.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// `shaders/*.wgsl`: compute passes.
    Compute,
    /// `shaders/render/*.wgsl`: vertex + fragment shaders.
    Render,
}

/// What [`build_shaders`] produced.
struct BuildResult {
    /// The generated Rust (meaningful only when `errors` is empty).
    code: String,
    /// Every file read, relative to the shader directory (for rerun-if-changed).
    read: BTreeSet<String>,
    /// One formatted diagnostic (possibly several lines) per error.
    errors: Vec<String>,
    /// Every validated shader.
    modules: Vec<ShaderModule>,
}

/// The entry points of a validated shader.
enum Entries {
    Compute {
        entry_point: String,
        workgroup_size: [u32; 3],
    },
    Render {
        vertex_entry: String,
        fragment_entry: String,
    },
}

/// A validated shader.
struct Pass {
    const_name: String,
    /// The file stem.
    name: String,
    /// The root relative to the shader directory (`upsample.wgsl`, `render/mesh.wgsl`).
    root: String,
    file: String,
    source: String,
    entries: Entries,
}

/// The `*.wgsl` files directly in `dir`, sorted, as paths relative to the shader
/// directory (`prefix` is the subdirectory, or empty).
fn list_roots(dir: &Path, prefix: &str, errors: &mut Vec<String>) -> Vec<String> {
    let mut roots = Vec::new();
    match fs::read_dir(dir) {
        Ok(entries) => {
            for entry in entries.flatten() {
                let path = entry.path();
                let is_file =
                    entry.file_type().map(|t| t.is_file()).unwrap_or(false) || path.is_file();
                if is_file && path.extension().is_some_and(|e| e == "wgsl") {
                    match path.file_name().and_then(|n| n.to_str()) {
                        Some(name) if prefix.is_empty() => roots.push(name.to_string()),
                        Some(name) => roots.push(format!("{prefix}/{name}")),
                        None => errors.push(format!(
                            "{}: error: shader file names must be UTF-8",
                            path.display()
                        )),
                    }
                }
            }
        }
        // No shader directory: nothing to embed, `ALL` is empty.
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(e) => errors.push(format!(
            "{}: error: cannot list shaders: {e}",
            dir.display()
        )),
    }
    roots.sort();
    roots
}

/// Preprocess and validate every `*.wgsl` directly in `shader_dir` (compute passes) or in
/// `shader_dir/render` (render shaders); write each preprocessed shader to
/// `preprocessed_dir` (`preprocessed_dir/render` for render shaders) and return the
/// generated code. `display_dir` prefixes file names in diagnostics and in the constants'
/// `file`.
fn build_shaders(
    shader_dir: &Path,
    display_dir: &str,
    preprocessed_dir: &Path,
    kind: Kind,
) -> BuildResult {
    let mut result = BuildResult {
        code: String::new(),
        read: BTreeSet::new(),
        errors: Vec::new(),
        modules: Vec::new(),
    };
    let roots = match kind {
        Kind::Compute => list_roots(shader_dir, "", &mut result.errors),
        Kind::Render => list_roots(
            &shader_dir.join(RENDER_SUBDIR),
            RENDER_SUBDIR,
            &mut result.errors,
        ),
    };

    let mut passes: Vec<Pass> = Vec::new();
    for root in &roots {
        let display = |file: &str| format!("{display_dir}/{file}");
        let pre = preprocess(root, |path| {
            result.read.insert(path.to_string());
            fs::read_to_string(shader_dir.join(path)).map_err(|e| e.to_string())
        });
        let pre = match pre {
            Ok(pre) => pre,
            Err(e) => {
                let location = match e.line {
                    Some(line) => format!("{}:{line}:1", display(&e.file)),
                    None => display(&e.file),
                };
                result
                    .errors
                    .push(format!("{location}: error: {}", e.message));
                continue;
            }
        };
        let entries = validate_module(root, &pre, display_dir).and_then(|module| {
            let entries = match kind {
                Kind::Compute => compute_entry(&module, root, display_dir),
                Kind::Render => render_entries(&module, root, display_dir),
            }?;
            Ok((entries, module))
        });
        match entries {
            Ok((entries, module)) => {
                let stem = root.rsplit('/').next().unwrap_or(root);
                let name = stem.trim_end_matches(".wgsl").to_string();
                passes.push(Pass {
                    const_name: const_name(&name),
                    file: display(root),
                    root: root.clone(),
                    name,
                    source: pre.text.clone(),
                    entries,
                });
                result.modules.push(ShaderModule { pre, module });
            }
            Err(e) => result.errors.push(e),
        }
    }

    for (i, pass) in passes.iter().enumerate() {
        let clash = passes[..i].iter().find(|p| p.const_name == pass.const_name);
        if let Some(other) = clash {
            result.errors.push(format!(
                "{}: error: constant name {} is also used by {}; rename one of the files",
                pass.file, pass.const_name, other.file
            ));
        } else if pass.const_name == "ALL" {
            result.errors.push(format!(
                "{}: error: a shader may not be called `all` (clashes with `ALL`)",
                pass.file
            ));
        }
    }
    if !result.errors.is_empty() {
        return result;
    }

    let code = &mut result.code;
    match kind {
        Kind::Compute => {
            code.push_str("// @generated by build.rs from shaders/*.wgsl. Do not edit.\n\n")
        }
        Kind::Render => {
            code.push_str("// @generated by build.rs from shaders/render/*.wgsl. Do not edit.\n\n")
        }
    }
    for pass in &passes {
        // `upsample.wgsl` -> `$OUT_DIR/shaders/upsample.wgsl`,
        // `render/mesh.wgsl` -> `$OUT_DIR/shaders/render/mesh.wgsl`.
        let preprocessed = preprocessed_dir.join(&pass.root);
        if let Some(parent) = preprocessed.parent() {
            if let Err(e) = fs::create_dir_all(parent) {
                result
                    .errors
                    .push(format!("{}: error: cannot create: {e}", parent.display()));
                return result;
            }
        }
        if let Err(e) = fs::write(&preprocessed, &pass.source) {
            result.errors.push(format!(
                "{}: error: cannot write {}: {e}",
                pass.file,
                preprocessed.display()
            ));
            continue;
        }
        let preprocessed = preprocessed.to_str().map(str::to_string);
        let source = match &preprocessed {
            // Embed the written copy so the generated file stays small and readable.
            Some(path) if !path.contains('"') => format!("include_str!({path:?})"),
            _ => format!("{:?}", pass.source),
        };
        match &pass.entries {
            Entries::Compute {
                entry_point,
                workgroup_size,
            } => {
                let [x, y, z] = *workgroup_size;
                let _ = write!(
                    code,
                    "/// `{file}` (preprocessed), entry point `{entry}`, workgroup size {x}x{y}x{z}.\n\
                     pub const {cname}: ShaderSource = ShaderSource {{\n    \
                     name: {name:?},\n    \
                     file: {file:?},\n    \
                     source: {source},\n    \
                     entry_point: {entry:?},\n    \
                     workgroup_size: [{x}, {y}, {z}],\n\
                     }};\n\n",
                    file = pass.file,
                    entry = entry_point,
                    cname = pass.const_name,
                    name = pass.name,
                );
            }
            Entries::Render {
                vertex_entry,
                fragment_entry,
            } => {
                let _ = write!(
                    code,
                    "/// `{file}` (preprocessed), entry points `{vertex}` (@vertex) and \
                     `{fragment}` (@fragment).\n\
                     pub const {cname}: RenderShaderSource = RenderShaderSource {{\n    \
                     name: {name:?},\n    \
                     file: {file:?},\n    \
                     source: {source},\n    \
                     vertex_entry: {vertex:?},\n    \
                     fragment_entry: {fragment:?},\n\
                     }};\n\n",
                    file = pass.file,
                    vertex = vertex_entry,
                    fragment = fragment_entry,
                    cname = pass.const_name,
                    name = pass.name,
                );
            }
        }
    }
    let all: Vec<&str> = passes.iter().map(|p| p.const_name.as_str()).collect();
    let _ = match kind {
        Kind::Compute => writeln!(
            code,
            "/// Every pass shader, sorted by file name.\npub const ALL: &[ShaderSource] = &[{}];",
            all.join(", ")
        ),
        Kind::Render => writeln!(
            code,
            "/// Every render shader, sorted by file name.\n\
             pub const ALL: &[RenderShaderSource] = &[{}];",
            all.join(", ")
        ),
    };
    result
}

/// `upsample` -> `UPSAMPLE`, `my-pass` -> `MY_PASS`, `2x` -> `_2X`.
fn const_name(stem: &str) -> String {
    let mut name: String = stem
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() {
                c.to_ascii_uppercase()
            } else {
                '_'
            }
        })
        .collect();
    if name.is_empty() || name.starts_with(|c: char| c.is_ascii_digit()) {
        name.insert(0, '_');
    }
    name
}

/// The single `@compute` entry point of a pass shader: its name and workgroup size.
fn compute_entry(module: &naga::Module, root: &str, display_dir: &str) -> Result<Entries, String> {
    let computes: Vec<&naga::EntryPoint> = module
        .entry_points
        .iter()
        .filter(|ep| ep.stage == naga::ShaderStage::Compute)
        .collect();
    let at_root = |message: String| format!("{display_dir}/{root}: error: {message}");
    match computes.as_slice() {
        [] => Err(at_root(
            "no @compute entry point; every shaders/*.wgsl is a compute pass \
             (put shared code in shaders/shared/ and #include it)"
                .to_string(),
        )),
        [ep] if ep.workgroup_size_overrides.is_some() => Err(at_root(format!(
            "the @workgroup_size of entry point `{}` uses pipeline overrides; \
             use literals or `const`s so the host knows the dispatch size",
            ep.name
        ))),
        [ep] => Ok(Entries::Compute {
            entry_point: ep.name.clone(),
            workgroup_size: ep.workgroup_size,
        }),
        many => Err(at_root(format!(
            "{} @compute entry points ({}); a pass shader must have exactly one",
            many.len(),
            many.iter()
                .map(|ep| ep.name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        ))),
    }
}

/// The `@vertex` and `@fragment` entry points of a render shader (exactly one of each,
/// and no other).
fn render_entries(module: &naga::Module, root: &str, display_dir: &str) -> Result<Entries, String> {
    let at_root = |message: String| format!("{display_dir}/{root}: error: {message}");
    let of = |stage: naga::ShaderStage| -> Vec<&str> {
        module
            .entry_points
            .iter()
            .filter(|ep| ep.stage == stage)
            .map(|ep| ep.name.as_str())
            .collect()
    };
    let others: Vec<&str> = module
        .entry_points
        .iter()
        .filter(|ep| {
            !matches!(
                ep.stage,
                naga::ShaderStage::Vertex | naga::ShaderStage::Fragment
            )
        })
        .map(|ep| ep.name.as_str())
        .collect();
    if !others.is_empty() {
        return Err(at_root(format!(
            "entry point(s) {} are neither @vertex nor @fragment; a render shader \
             (shaders/{RENDER_SUBDIR}/*.wgsl) has exactly one @vertex and one @fragment \
             entry point (compute passes go in shaders/*.wgsl)",
            others.join(", ")
        )));
    }
    let one = |stage: naga::ShaderStage, what: &str| -> Result<String, String> {
        match of(stage).as_slice() {
            [name] => Ok(name.to_string()),
            [] => Err(at_root(format!(
                "no {what} entry point; a render shader has exactly one @vertex and one \
                 @fragment entry point"
            ))),
            many => Err(at_root(format!(
                "{} {what} entry points ({}); a render shader must have exactly one",
                many.len(),
                many.join(", ")
            ))),
        }
    };
    Ok(Entries::Render {
        vertex_entry: one(naga::ShaderStage::Vertex, "@vertex")?,
        fragment_entry: one(naga::ShaderStage::Fragment, "@fragment")?,
    })
}

/// Parse and validate a preprocessed shader; return the module, or a formatted
/// diagnostic located in the original files.
fn validate_module(
    root: &str,
    pre: &Preprocessed,
    display_dir: &str,
) -> Result<naga::Module, String> {
    let source = pre.text.as_str();
    let module = naga::front::wgsl::parse_str(source).map_err(|e| {
        let labels: Vec<(naga::Span, String)> = e
            .labels()
            .map(|(span, label)| (span, label.to_string()))
            .collect();
        let notes: Vec<String> = e.notes().map(str::to_string).collect();
        diagnostic(root, pre, display_dir, e.message(), &labels, &notes)
    })?;

    let mut validator = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        // What wgpu grants a device created without optional features.
        naga::valid::Capabilities::default(),
    );
    validator.validate(&module).map_err(|e| {
        let mut message = e.as_inner().to_string();
        let mut cause: Option<&dyn std::error::Error> = std::error::Error::source(e.as_inner());
        while let Some(c) = cause {
            let _ = write!(message, ": {c}");
            cause = c.source();
        }
        let mut labels: Vec<(naga::Span, String)> = e.spans().cloned().collect();
        if labels.is_empty() {
            // naga keeps no span for entry points: point at `fn <name>` instead.
            let function = match e.as_inner() {
                naga::valid::ValidationError::EntryPoint { name, .. }
                | naga::valid::ValidationError::Function { name, .. } => Some(name.as_str()),
                _ => None,
            };
            if let Some(span) = function.and_then(|name| find_fn(source, name)) {
                labels.push((span, "in this function".to_string()));
            }
        }
        diagnostic(root, pre, display_dir, &message, &labels, &[])
    })?;
    Ok(module)
}

/// The span of the name in the first `fn <name>` of `source`.
fn find_fn(source: &str, name: &str) -> Option<naga::Span> {
    let is_ident = |c: char| c.is_alphanumeric() || c == '_';
    let mut from = 0;
    while let Some(found) = source[from..].find(name) {
        let start = from + found;
        let end = start + name.len();
        from = end;
        let before = source[..start].trim_end_matches([' ', '\t', '\r', '\n']);
        let after_ok = !source[end..].starts_with(is_ident);
        let fn_ok = before.ends_with("fn")
            && !before[..before.len() - 2].ends_with(is_ident)
            && before.len() < start;
        if after_ok && fn_ok {
            return Some(naga::Span::from(start..end));
        }
    }
    None
}

/// Format an error at its labelled spans, mapped to the original files:
///
/// ```text
/// shaders/shared/common.wgsl:42:7: error: <message>
///    42 |     let y = x x;
///       |           ^^^ <label>
/// shaders/upsample.wgsl:10:3: note: <secondary label>
///   = note: <note>
/// ```
fn diagnostic(
    root: &str,
    pre: &Preprocessed,
    display_dir: &str,
    message: &str,
    labels: &[(naga::Span, String)],
    notes: &[String],
) -> String {
    let source = pre.text.as_str();
    let mut out = String::new();
    let mut located = labels.iter().filter(|(span, _)| span.is_defined());
    match located.next() {
        Some((span, label)) => {
            let _ = writeln!(out, "{}: error: {message}", locate(pre, display_dir, *span));
            excerpt(&mut out, source, *span, label);
        }
        None => {
            let _ = writeln!(out, "{display_dir}/{root}: error: {message}");
        }
    }
    for (span, label) in located {
        let _ = writeln!(out, "{}: note: {label}", locate(pre, display_dir, *span));
        excerpt(&mut out, source, *span, "");
    }
    for note in notes {
        let _ = writeln!(out, "  = note: {note}");
    }
    out.trim_end().to_string()
}

/// `shaders/<file>:<line>:<col>` of a span of the preprocessed text.
fn locate(pre: &Preprocessed, display_dir: &str, span: naga::Span) -> String {
    let source = pre.text.as_str();
    let offset = clamp_offset(source, span.to_range().map_or(0, |r| r.start));
    let line = source[..offset].matches('\n').count() + 1;
    let line_start = source[..offset].rfind('\n').map_or(0, |i| i + 1);
    let column = source[line_start..offset].chars().count() + 1;
    match pre.origin(u32::try_from(line).unwrap_or(u32::MAX)) {
        Some((file, line)) => format!("{display_dir}/{file}:{line}:{column}"),
        None => format!("{display_dir}/{}", pre.files[0]),
    }
}

/// `offset` within `source`; an offset at the very end (an "unexpected end of input")
/// moves back onto the last line.
fn clamp_offset(source: &str, offset: usize) -> usize {
    let mut offset = offset.min(source.len());
    if offset == source.len() && source.ends_with('\n') {
        offset -= 1;
    }
    while !source.is_char_boundary(offset) {
        offset -= 1;
    }
    offset
}

/// The source line holding `span`, with the span underlined and labelled.
fn excerpt(out: &mut String, source: &str, span: naga::Span, label: &str) {
    let Some(range) = span.to_range() else { return };
    let start = clamp_offset(source, range.start);
    let line_start = source[..start].rfind('\n').map_or(0, |i| i + 1);
    let line_end = source[start..]
        .find('\n')
        .map_or(source.len(), |i| start + i);
    let line = &source[line_start..line_end];
    let pad = source[line_start..start].chars().count();
    let width = source[start..range.end.min(line_end).max(start)]
        .chars()
        .count()
        .max(1);
    let _ = writeln!(out, "    | {line}");
    let _ = writeln!(
        out,
        "    | {}{} {label}",
        " ".repeat(pad),
        "^".repeat(width)
    );
}

// ---------------------------------------------------------------------------------------
// Host/shader struct layouts.
//
// A uniform or storage struct is written by Rust (`#[repr(C)]` + `bytemuck::Pod`, uploaded
// as bytes) and read by WGSL, whose layout rules differ (a `vec3` aligns to 16, a
// uniform array's stride to 16, ...). Nothing at run time notices a field that is off by
// four bytes: the shader reads the neighbouring value. So every pair below is compared
// field by field (names, types, offsets, sizes, total size) and a difference fails the
// build. The Rust side is parsed from the source text (build.rs cannot see the crate's
// types) and laid out by the `repr(C)` rules; the WGSL side comes from naga's layouter.
// ---------------------------------------------------------------------------------------

/// A struct that Rust uploads and a shader reads.
struct SharedStruct {
    /// Where the Rust struct is expected; only consulted when several `#[repr(C)]`
    /// structs of that name exist (a struct that moves to another file is still found).
    rust_file: &'static str,
    rust: &'static str,
    /// The shader file defining the WGSL struct, relative to `shaders/` (a shared
    /// file is checked through any shader that includes it).
    wgsl_file: &'static str,
    wgsl: &'static str,
}

/// Every struct shared by host and shaders.
const SHARED_STRUCTS: &[SharedStruct] = &[
    // The uniform block of every compute pass.
    SharedStruct {
        rust_file: "src/passes/common.rs",
        rust: "PassParams",
        wgsl_file: "shared/common.wgsl",
        wgsl: "Params",
    },
    // The mesh renderer's uniform blocks.
    SharedStruct {
        rust_file: "src/surface/render.rs",
        rust: "Params",
        wgsl_file: "render/mesh.wgsl",
        wgsl: "Params",
    },
    SharedStruct {
        rust_file: "src/surface/render.rs",
        rust: "ViewUniform",
        wgsl_file: "render/mesh.wgsl",
        wgsl: "View",
    },
];

/// A validated shader, kept for the layout check.
struct ShaderModule {
    pre: Preprocessed,
    module: naga::Module,
}

/// A field type of a `#[repr(C)]` struct, as written in the source.
#[derive(Clone, Debug)]
enum RustType {
    /// `u32`, `i32`, `f32`, ...: kind (`'u'`, `'i'`, `'f'`) and width in bytes.
    Scalar(char, u32),
    /// `[T; N]`.
    Array(Box<RustType>, u32),
    /// Another `#[repr(C)]` struct, by name.
    Struct(String),
}

/// A `#[repr(C)]` struct parsed from `src/`.
#[derive(Clone, Debug)]
struct RustStruct {
    /// The file, relative to the crate root.
    file: String,
    /// `repr` arguments other than `C` (`align(16)`, `packed`), which the layout below
    /// does not model.
    unsupported_repr: Option<String>,
    /// (name, type, type as written).
    fields: Vec<(String, RustType, String)>,
}

/// Size and alignment of a `repr(C)` type.
#[derive(Clone, Copy)]
struct RustLayout {
    size: u32,
    align: u32,
}

/// Every `*.rs` file under `dir`, sorted, relative to `root`.
fn rust_files(root: &Path, dir: &Path, out: &mut Vec<String>) {
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    let mut paths: Vec<PathBuf> = entries.flatten().map(|e| e.path()).collect();
    paths.sort();
    for path in paths {
        if path.is_dir() {
            rust_files(root, &path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            if let Ok(rel) = path.strip_prefix(root) {
                out.push(rel.to_string_lossy().replace('\\', "/"));
            }
        }
    }
}

/// `source` with comments and the contents of string and char literals replaced by
/// spaces (lengths and newlines kept), so that only code is searched.
fn code_only(source: &str) -> String {
    let b = source.as_bytes();
    let mut out = b.to_vec();
    let blank = |out: &mut Vec<u8>, from: usize, to: usize| {
        for c in &mut out[from..to] {
            if *c != b'\n' {
                *c = b' ';
            }
        }
    };
    let mut i = 0;
    while i < b.len() {
        match b[i] {
            b'/' if b.get(i + 1) == Some(&b'/') => {
                let end = source[i..].find('\n').map_or(b.len(), |n| i + n);
                blank(&mut out, i, end);
                i = end;
            }
            b'/' if b.get(i + 1) == Some(&b'*') => {
                let (mut depth, mut j) = (1, i + 2);
                while j < b.len() && depth > 0 {
                    if b[j..].starts_with(b"/*") {
                        depth += 1;
                        j += 2;
                    } else if b[j..].starts_with(b"*/") {
                        depth -= 1;
                        j += 2;
                    } else {
                        j += 1;
                    }
                }
                blank(&mut out, i, j);
                i = j;
            }
            b'r' if matches!(b.get(i + 1), Some(b'"' | b'#'))
                && (i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_')) =>
            {
                // Raw string r"..." / r#"..."#.
                let hashes = b[i + 1..].iter().take_while(|&&c| c == b'#').count();
                if b.get(i + 1 + hashes) != Some(&b'"') {
                    i += 1;
                    continue;
                }
                let close = format!("\"{}", "#".repeat(hashes));
                let start = i + 2 + hashes;
                let end = source[start..]
                    .find(&close)
                    .map_or(b.len(), |n| start + n + close.len());
                blank(&mut out, start, end.saturating_sub(close.len()).max(start));
                i = end;
            }
            b'"' => {
                let mut j = i + 1;
                while j < b.len() && b[j] != b'"' {
                    j += if b[j] == b'\\' { 2 } else { 1 };
                }
                blank(&mut out, i + 1, j.min(b.len()));
                i = j + 1;
            }
            b'\'' => {
                // A char literal ('x', '\n', '\u{..}'), or a lifetime ('a).
                if b.get(i + 1) == Some(&b'\\') {
                    let end = source[i + 2..].find('\'').map_or(b.len(), |n| i + 2 + n);
                    blank(&mut out, i + 1, end);
                    i = end + 1;
                } else if let Some(c) = source[i + 1..].chars().next() {
                    let after = i + 1 + c.len_utf8();
                    if b.get(after) == Some(&b'\'') {
                        blank(&mut out, i + 1, after);
                        i = after + 1;
                    } else {
                        i += 1;
                    }
                } else {
                    i += 1;
                }
            }
            _ => i += 1,
        }
    }
    String::from_utf8(out).unwrap_or_default()
}

/// The index just past the bracket that closes the one opening at `open`.
fn matching_close(code: &str, open: usize) -> Option<usize> {
    let mut depth = 0i32;
    for (i, c) in code[open..].char_indices() {
        match c {
            '{' | '[' | '(' | '<' => depth += 1,
            '}' | ']' | ')' | '>' => {
                depth -= 1;
                if depth == 0 {
                    return Some(open + i + 1);
                }
            }
            _ => {}
        }
    }
    None
}

/// `text` split at the commas outside brackets.
fn split_top_level(text: &str, sep: char) -> Vec<&str> {
    let (mut parts, mut depth, mut start) = (Vec::new(), 0i32, 0);
    for (i, c) in text.char_indices() {
        match c {
            '{' | '[' | '(' | '<' => depth += 1,
            '}' | ']' | ')' | '>' => depth -= 1,
            c if c == sep && depth == 0 => {
                parts.push(&text[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    parts.push(&text[start..]);
    parts
}

fn parse_rust_type(text: &str) -> Result<RustType, String> {
    let t = text.trim();
    if let Some(inner) = t.strip_prefix('[').and_then(|s| s.strip_suffix(']')) {
        let parts = split_top_level(inner, ';');
        let [elem, count] = parts.as_slice() else {
            return Err(format!("`{t}`: a slice is not a field type"));
        };
        let count: u32 = count.trim().replace('_', "").parse().map_err(|_| {
            format!(
                "`{t}`: array length `{}` is not an integer literal",
                count.trim()
            )
        })?;
        return Ok(RustType::Array(Box::new(parse_rust_type(elem)?), count));
    }
    let scalar = |kind, width| Ok(RustType::Scalar(kind, width));
    match t {
        "u8" => scalar('u', 1),
        "i8" => scalar('i', 1),
        "u16" => scalar('u', 2),
        "i16" => scalar('i', 2),
        "u32" => scalar('u', 4),
        "i32" => scalar('i', 4),
        "f32" => scalar('f', 4),
        "u64" => scalar('u', 8),
        "i64" => scalar('i', 8),
        "f64" => scalar('f', 8),
        _ if t.chars().all(|c| c.is_alphanumeric() || c == '_') && !t.is_empty() => {
            Ok(RustType::Struct(t.to_string()))
        }
        _ => Err(format!(
            "`{t}`: unsupported field type (scalars, arrays and #[repr(C)] structs only)"
        )),
    }
}

/// Every `#[repr(C)]` struct with named fields in `code` (see [`code_only`]), by name.
/// A field the parser does not understand is kept as an error, reported only if the
/// struct is one of [`SHARED_STRUCTS`] or nested in one.
fn parse_repr_c_structs(
    file: &str,
    code: &str,
    out: &mut Vec<(String, Result<RustStruct, String>)>,
) {
    let is_ident = |c: char| c.is_alphanumeric() || c == '_';
    let mut from = 0;
    while let Some(found) = code[from..].find("struct") {
        let at = from + found;
        from = at + "struct".len();
        if code[..at].ends_with(is_ident) || code[from..].starts_with(is_ident) {
            continue;
        }
        // The attributes: everything back to the previous item.
        let item_start = code[..at].rfind([';', '}', '{']).map_or(0, |i| i + 1);
        let attrs: String = code[item_start..at]
            .chars()
            .filter(|c| !c.is_whitespace())
            .collect();
        let Some(repr) = attrs
            .split("#[repr(")
            .skip(1)
            .find_map(|r| r.split(")]").next())
        else {
            continue;
        };
        let args: Vec<&str> = repr.split(',').collect();
        if !args.contains(&"C") {
            continue;
        }
        let rest = &code[from..];
        let name_len = rest.trim_start().find(|c: char| !is_ident(c)).unwrap_or(0);
        let name_start = from + (rest.len() - rest.trim_start().len());
        let name = &code[name_start..name_start + name_len];
        let after = code[name_start + name_len..].trim_start();
        if name.is_empty() || !after.starts_with('{') {
            continue; // Tuple, unit or generic struct: never shared with a shader.
        }
        let open = code.len() - after.len();
        let Some(close) = matching_close(code, open) else {
            continue;
        };
        let body = &code[open + 1..close - 1];
        let others: Vec<&str> = args.iter().copied().filter(|a| *a != "C").collect();
        let parsed = split_top_level(body, ',')
            .into_iter()
            .map(|field| {
                // Drop field attributes and visibility.
                let mut f = field.trim();
                while f.starts_with("#[") {
                    let end = matching_close(f, 1).unwrap_or(f.len());
                    f = f[end..].trim_start();
                }
                if let Some(r) = f.strip_prefix("pub") {
                    f = r.trim_start();
                    if f.starts_with('(') {
                        f = f[matching_close(f, 0).unwrap_or(f.len())..].trim_start();
                    }
                }
                f
            })
            .filter(|f| !f.is_empty())
            .map(|f| {
                let (fname, ty) = f
                    .split_once(':')
                    .ok_or_else(|| format!("cannot parse field `{f}`"))?;
                let fname = fname.trim().trim_start_matches("r#").to_string();
                let ty_text: String = ty.split_whitespace().collect::<Vec<_>>().join(" ");
                let ty = parse_rust_type(&ty_text).map_err(|e| format!("field {fname}: {e}"))?;
                Ok((fname, ty, ty_text))
            })
            .collect::<Result<Vec<_>, String>>()
            .map(|fields| RustStruct {
                file: file.to_string(),
                unsupported_repr: (!others.is_empty()).then(|| others.join(", ")),
                fields,
            });
        out.push((name.to_string(), parsed));
    }
}

/// The `#[repr(C)]` structs of `src/`: name -> every definition.
struct RustStructs {
    by_name: Vec<(String, Result<RustStruct, String>)>,
}

impl RustStructs {
    /// The struct `name`: the only one, or the one in `prefer_file`.
    fn find(&self, name: &str, prefer_file: &str) -> Result<&RustStruct, String> {
        let all: Vec<&(String, Result<RustStruct, String>)> =
            self.by_name.iter().filter(|(n, _)| n == name).collect();
        let file_of = |s: &Result<RustStruct, String>| match s {
            Ok(s) => s.file.clone(),
            Err(_) => String::new(),
        };
        let chosen = match all.as_slice() {
            [] => {
                return Err(format!(
                    "no #[repr(C)] struct {name} with named fields in src/ (expected in \
                     {prefer_file}; update SHARED_STRUCTS in build.rs if it was renamed)"
                ))
            }
            [one] => &one.1,
            many => match many.iter().find(|(_, s)| file_of(s) == prefer_file) {
                Some(one) => &one.1,
                None => {
                    return Err(format!(
                        "several #[repr(C)] structs named {name} in src/, none in {prefer_file}; \
                         update SHARED_STRUCTS in build.rs"
                    ))
                }
            },
        };
        let s = chosen
            .as_ref()
            .map_err(|e| format!("Rust struct {name}: {e}"))?;
        match &s.unsupported_repr {
            Some(r) => Err(format!(
                "Rust struct {name} ({}): #[repr({r})] is not modelled by the layout check",
                s.file
            )),
            None => Ok(s),
        }
    }

    /// Size and alignment of `ty` by the `repr(C)` rules; `file` resolves nested
    /// structs of ambiguous name.
    fn layout(&self, ty: &RustType, file: &str, depth: u32) -> Result<RustLayout, String> {
        match ty {
            RustType::Scalar(_, w) => Ok(RustLayout {
                size: *w,
                align: *w,
            }),
            RustType::Array(elem, n) => {
                let e = self.layout(elem, file, depth)?;
                Ok(RustLayout {
                    size: e.size * n,
                    align: e.align,
                })
            }
            RustType::Struct(name) if depth < 8 => {
                let s = self.find(name, file)?;
                Ok(self.field_offsets(s, depth + 1)?.1)
            }
            RustType::Struct(name) => Err(format!("struct {name} nests too deeply")),
        }
    }

    /// Offsets of the fields of `s`, and its layout.
    fn field_offsets(&self, s: &RustStruct, depth: u32) -> Result<(Vec<u32>, RustLayout), String> {
        let (mut offset, mut align, mut offsets) = (0u32, 1u32, Vec::new());
        for (_, ty, _) in &s.fields {
            let l = self.layout(ty, &s.file, depth)?;
            offset = offset.next_multiple_of(l.align);
            offsets.push(offset);
            offset += l.size;
            align = align.max(l.align);
        }
        Ok((
            offsets,
            RustLayout {
                size: offset.next_multiple_of(align),
                align,
            },
        ))
    }
}

/// A WGSL type as written (`vec2<i32>`, `array<u32, 4>`, `mat4x4<f32>`).
fn wgsl_type_name(module: &naga::Module, ty: naga::Handle<naga::Type>) -> String {
    use naga::TypeInner as T;
    let scalar = |s: naga::Scalar| {
        let k = match s.kind {
            naga::ScalarKind::Sint => "i",
            naga::ScalarKind::Uint => "u",
            naga::ScalarKind::Float => "f",
            naga::ScalarKind::Bool => return "bool".to_string(),
            _ => "abstract",
        };
        format!("{k}{}", s.width as u32 * 8)
    };
    let t = &module.types[ty];
    match &t.inner {
        T::Scalar(s) => scalar(*s),
        T::Atomic(s) => format!("atomic<{}>", scalar(*s)),
        T::Vector { size, scalar: s } => format!("vec{}<{}>", *size as u32, scalar(*s)),
        T::Matrix {
            columns,
            rows,
            scalar: s,
        } => format!("mat{}x{}<{}>", *columns as u32, *rows as u32, scalar(*s)),
        T::Array { base, size, .. } => match size {
            naga::ArraySize::Constant(n) => {
                format!("array<{}, {n}>", wgsl_type_name(module, *base))
            }
            _ => format!("array<{}>", wgsl_type_name(module, *base)),
        },
        T::Struct { .. } => t.name.clone().unwrap_or_else(|| "struct".to_string()),
        other => format!("{other:?}"),
    }
}

/// Whether WGSL `ty` and Rust `r` hold the same values (same scalar kinds and widths,
/// same shape); sizes and offsets are compared by the caller. Nested structs are
/// compared field by field into `errors`.
#[allow(clippy::too_many_arguments)]
fn same_shape(
    module: &naga::Module,
    layouter: &naga::proc::Layouter,
    ty: naga::Handle<naga::Type>,
    r: &RustType,
    rust: &RustStructs,
    file: &str,
    paths: (&str, &str),
    errors: &mut Vec<String>,
) -> Result<bool, String> {
    use naga::TypeInner as T;
    let scalar_eq = |s: &naga::Scalar, r: &RustType| match r {
        RustType::Scalar(kind, width) => {
            let k = match s.kind {
                naga::ScalarKind::Sint => 'i',
                naga::ScalarKind::Uint => 'u',
                naga::ScalarKind::Float => 'f',
                _ => '?',
            };
            k == *kind && s.width as u32 == *width
        }
        _ => false,
    };
    Ok(match (&module.types[ty].inner, r) {
        (T::Scalar(s) | T::Atomic(s), _) => scalar_eq(s, r),
        (T::Vector { size, scalar }, RustType::Array(e, n)) => {
            *size as u32 == *n && scalar_eq(scalar, e)
        }
        (
            T::Matrix {
                columns,
                rows,
                scalar,
            },
            RustType::Array(col, c),
        ) => match &**col {
            RustType::Array(e, r) => {
                *columns as u32 == *c && *rows as u32 == *r && scalar_eq(scalar, e)
            }
            _ => false,
        },
        (
            T::Array {
                base,
                size: naga::ArraySize::Constant(n),
                stride,
            },
            RustType::Array(e, m),
        ) => {
            n.get() == *m
                && rust.layout(e, file, 0)?.size == *stride
                && same_shape(module, layouter, *base, e, rust, file, paths, errors)?
        }
        (T::Struct { members, .. }, RustType::Struct(name)) => {
            let s = rust.find(name, file)?;
            compare_struct(module, layouter, members, rust, s, paths, errors)?;
            true
        }
        _ => false,
    })
}

/// Compare WGSL struct `members` with Rust struct `s` field by field; `paths` are the
/// two structs' names as messages give them (`Params`, `View.light`).
fn compare_struct(
    module: &naga::Module,
    layouter: &naga::proc::Layouter,
    members: &[naga::StructMember],
    rust: &RustStructs,
    s: &RustStruct,
    (wgsl, rs): (&str, &str),
    errors: &mut Vec<String>,
) -> Result<(), String> {
    let (offsets, _) = rust.field_offsets(s, 0)?;
    let mut shifted = 0;
    for (i, (m, ((name, ty, ty_text), offset))) in members
        .iter()
        .zip(s.fields.iter().zip(&offsets))
        .enumerate()
    {
        let m_name = m.name.as_deref().unwrap_or("?");
        if m_name != name {
            // Everything after a renamed, missing or extra field is misaligned: stop.
            errors.push(format!(
                "shader struct {wgsl} field {i} is `{m_name}` but Rust {rs} field {i} is `{name}`"
            ));
            return Ok(());
        }
        let (wf, rf) = (format!("{wgsl}.{m_name}"), format!("{rs}.{name}"));
        if !same_shape(
            module,
            layouter,
            m.ty,
            ty,
            rust,
            &s.file,
            (&wf, &rf),
            errors,
        )? {
            errors.push(format!(
                "shader struct {wf} is {} but Rust {rf} is {ty_text}",
                wgsl_type_name(module, m.ty)
            ));
        }
        if m.offset != *offset {
            // One field out of place shifts all that follow: report the first.
            if shifted == 0 {
                errors.push(format!(
                    "shader struct {wf} at offset {} but Rust {rf} at {offset}",
                    m.offset
                ));
            }
            shifted += 1;
        }
        let (w_size, r_size) = (layouter[m.ty].size, rust.layout(ty, &s.file, 0)?.size);
        if w_size != r_size {
            errors.push(format!(
                "shader struct {wf} is {w_size} bytes but Rust {rf} is {r_size}"
            ));
        }
    }
    if shifted > 1 {
        errors.push(format!(
            "shader struct {wgsl}: {} later fields are at other offsets too",
            shifted - 1
        ));
    }
    let (nw, nr) = (members.len(), s.fields.len());
    if nw != nr {
        let first = |names: &mut dyn Iterator<Item = &str>| {
            names.nth(nw.min(nr)).unwrap_or("?").to_string()
        };
        errors.push(if nw > nr {
            format!(
                "shader struct {wgsl} has {nw} fields but Rust {rs} {nr}; Rust lacks `{}` and after",
                first(&mut members.iter().map(|m| m.name.as_deref().unwrap_or("?")))
            )
        } else {
            format!(
                "shader struct {wgsl} has {nw} fields but Rust {rs} {nr}; the shader lacks `{}` and after",
                first(&mut s.fields.iter().map(|f| f.0.as_str()))
            )
        });
    }
    Ok(())
}

/// Check every [`SHARED_STRUCTS`] pair; return the Rust files read (for
/// rerun-if-changed) and one message per mismatch.
fn check_shared_structs(
    manifest_dir: &Path,
    shaders: &[ShaderModule],
) -> (Vec<String>, Vec<String>) {
    let mut files = Vec::new();
    rust_files(manifest_dir, &manifest_dir.join("src"), &mut files);
    let mut by_name = Vec::new();
    for file in &files {
        if let Ok(text) = fs::read_to_string(manifest_dir.join(file)) {
            parse_repr_c_structs(file, &code_only(&text), &mut by_name);
        }
    }
    let rust = RustStructs { by_name };
    let mut errors = Vec::new();
    for pair in SHARED_STRUCTS {
        let context = |s: Option<&RustStruct>| {
            format!(
                "Rust {} ({}) vs shader struct {} ({SHADER_DIR}/{})",
                pair.rust,
                s.map_or(pair.rust_file, |s| s.file.as_str()),
                pair.wgsl,
                pair.wgsl_file
            )
        };
        let s = match rust.find(pair.rust, pair.rust_file) {
            Ok(s) => s,
            Err(e) => {
                errors.push(format!("{}: {e}", context(None)));
                continue;
            }
        };
        // The WGSL struct: in any shader, defined in `wgsl_file`.
        let found = shaders.iter().find_map(|sh| {
            sh.module.types.iter().find_map(|(handle, ty)| {
                let naga::TypeInner::Struct { members, .. } = &ty.inner else {
                    return None;
                };
                let span = sh.module.types.get_span(handle).to_range()?;
                let (file, _) = sh.pre.origin_of_offset(span.start)?;
                (ty.name.as_deref() == Some(pair.wgsl) && file == pair.wgsl_file)
                    .then_some((sh, handle, members))
            })
        });
        let Some((sh, handle, members)) = found else {
            errors.push(format!(
                "{}: no shader defines struct {} in {SHADER_DIR}/{} (renamed or moved? \
                 update SHARED_STRUCTS in build.rs)",
                context(Some(s)),
                pair.wgsl,
                pair.wgsl_file
            ));
            continue;
        };
        let mut layouter = naga::proc::Layouter::default();
        if let Err(e) = layouter.update(sh.module.to_ctx()) {
            errors.push(format!(
                "{}: naga cannot lay out the shader: {e}",
                context(Some(s))
            ));
            continue;
        }
        let mut mismatches = Vec::new();
        let result = compare_struct(
            &sh.module,
            &layouter,
            members,
            &rust,
            s,
            (pair.wgsl, pair.rust),
            &mut mismatches,
        )
        .and_then(|()| {
            let w = layouter[handle].size;
            let r = rust.field_offsets(s, 0)?.1.size;
            if w != r {
                mismatches.push(format!(
                    "shader struct {} is {w} bytes but Rust {} is {r}",
                    pair.wgsl, pair.rust
                ));
            }
            Ok(())
        });
        if let Err(e) = result {
            mismatches.push(e);
        }
        for m in mismatches {
            errors.push(format!("{}: {m}", context(Some(s))));
        }
    }
    (files, errors)
}
