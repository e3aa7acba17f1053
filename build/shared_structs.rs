//! The host/shader struct layout check of `build.rs` (see [`super::SHARED_STRUCTS`]).
//!
//! A uniform or storage struct is written by Rust (`#[repr(C)]` + `bytemuck::Pod`,
//! uploaded as bytes) and read by WGSL, whose layout rules differ (a `vec3` aligns to 16,
//! a uniform array's stride to 16, ...). Nothing at run time notices a field that is off
//! by four bytes: the shader reads the neighbouring value. So each pair is compared field
//! by field (names, types, offsets, sizes, total size). The Rust side is parsed from the
//! source text (a build script cannot see the crate's types) and laid out by the
//! `repr(C)` rules; the WGSL side comes from naga's layouter.

use std::fs;
use std::path::{Path, PathBuf};

use super::{ShaderModule, SHADER_DIR, SHARED_STRUCTS};

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
pub(crate) fn check(manifest_dir: &Path, shaders: &[ShaderModule]) -> (Vec<String>, Vec<String>) {
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
