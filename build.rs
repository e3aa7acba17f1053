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
#[path = "build/shared_structs.rs"]
mod shared_structs;

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
    println!("cargo:rerun-if-changed=build/shared_structs.rs");
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
    let (rust_files, mismatches) = shared_structs::check(&manifest_dir, &shaders);
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
            "/// Every pass shader, sorted by file name (for tests and tools).\n#[allow(dead_code)]\npub const ALL: &[ShaderSource] = &[{}];",
            all.join(", ")
        ),
        Kind::Render => writeln!(
            code,
            "/// Every render shader, sorted by file name (for tests and tools).\n\
             #[allow(dead_code)]\n\
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

// Host/shader struct layouts: the pairs that `shared_structs` checks.

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

/// Every struct shared by host and shaders: Rust uploads it as bytes (uniform or
/// storage), a shader reads it. Add a pair here when a new one appears.
const SHARED_STRUCTS: &[SharedStruct] = &[
    // The uniform block of every compute pass.
    SharedStruct {
        rust_file: "src/passes/common.rs",
        rust: "PassParams",
        wgsl_file: "shared/common.wgsl",
        wgsl: "Params",
    },
    // The velocity quantization's uniform block (advection).
    SharedStruct {
        rust_file: "src/passes/velocity.rs",
        rust: "VelocityParams",
        wgsl_file: "shared/velocity.wgsl",
        wgsl: "VelocityParams",
    },
    // The mesh renderer's uniform blocks.
    SharedStruct {
        rust_file: "src/surface/render/inputs.rs",
        rust: "Params",
        wgsl_file: "render/mesh.wgsl",
        wgsl: "Params",
    },
    SharedStruct {
        rust_file: "src/surface/render/inputs.rs",
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
