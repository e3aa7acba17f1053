//! glTF 2.0 input and output for surface synthesis: [`load_mesh`] reads a `.gltf` (with
//! external or embedded buffers) or a `.glb` into one world-space [`Mesh`];
//! [`write_glb`] writes a textured mesh as a self-contained binary glTF.
//!
//! Loading instantiates every mesh primitive reachable from the default scene (from the
//! root nodes of every scene when there is no default scene, from every parentless node
//! when there are no scenes), with the full node hierarchy applied: positions by the
//! world matrix, normals by its inverse transpose, tangents by its linear part (`w`
//! flipped, and triangle winding reversed, under a mirroring transform, as the glTF
//! specification requires). Skins and morph targets are ignored (the rest pose is used).
//!
//! Documented repairs, counted in [`LoadReport`]: triangle strips and fans become
//! triangle lists; points and lines primitives are skipped (an error when nothing else
//! is left); attributes that only some primitives have (`TEXCOORD_0`, `TANGENT`) are
//! dropped from the merged mesh, and normals are recomputed when any primitive lacks
//! them ([`Mesh::validate_and_repair`]).
//!
//! Every problem in a file is an [`Error::BadMesh`] naming the file and, where it helps,
//! what to do; the parser never panics on bad input: the GLB container, buffer sources
//! and every accessor's byte range are checked before any data is read.

use std::collections::BTreeMap;

use std::path::{Path, PathBuf};

use glam::{Mat3, Mat4, Vec2, Vec3, Vec4};
use gltf::accessor::{DataType, Dimensions};
use gltf::json;
use gltf::mesh::Mode;
use gltf::Semantic;
use image::{ImageEncoder, RgbaImage};

use crate::error::{Error, Result};
use crate::surface::mesh::{Mesh, RepairReport};

/// What [`load_mesh`] found and changed.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LoadReport {
    /// Triangle primitives loaded (a mesh instanced by several nodes counts once per
    /// node).
    pub primitives: usize,
    /// Points and lines primitives skipped.
    pub skipped_non_triangle: usize,
    /// Of [`primitives`](Self::primitives), the triangle strips and fans converted to
    /// triangle lists.
    pub converted_strips_fans: usize,
    /// What [`Mesh::validate_and_repair`] changed.
    pub repair: RepairReport,
}

/// Textures to embed as a glTF PBR metallic-roughness material. Each is an RGBA8 image;
/// images whose alpha is 255 everywhere are stored as RGB PNGs.
#[derive(Clone, Debug)]
pub struct MaterialImages {
    /// `baseColorTexture` (sRGB).
    pub base_color: RgbaImage,
    /// `normalTexture`: tangent-space normal map (linear, +Y up as glTF defines it).
    pub normal: Option<RgbaImage>,
    /// `metallicRoughnessTexture`: roughness in G, metalness in B (linear). Without it the
    /// material is a non-metal with roughness 1.
    pub metallic_roughness: Option<RgbaImage>,
    /// `occlusionTexture`: ambient occlusion in R (linear).
    pub occlusion: Option<RgbaImage>,
}

// ---------------------------------------------------------------------------------------
// Loading
// ---------------------------------------------------------------------------------------

/// Loads every triangle primitive of the default scene (or of all scenes' root nodes if
/// there is no default scene), with node transforms (full hierarchy, matrix or TRS)
/// applied to positions, normals (inverse transpose) and tangents, merged into one mesh
/// and passed through [`Mesh::validate_and_repair`].
///
/// A file that cannot be read is [`Error::Io`]; anything wrong with its content (or with
/// the buffers it references) is [`Error::BadMesh`].
pub fn load_mesh(path: &Path) -> Result<(Mesh, LoadReport)> {
    let bytes = crate::image_io::read_file_capped(
        path,
        crate::image_io::MAX_MESH_FILE_BYTES,
        "mesh files",
    )?;
    let bad = |reason: String| Error::BadMesh {
        path: path.to_path_buf(),
        reason,
    };
    let (json_bytes, bin) = split_container(&bytes).map_err(bad)?;
    let document = parse_document(json_bytes, bytes.starts_with(GLB_MAGIC)).map_err(bad)?;
    let buffers = load_buffers(&document, path, bin).map_err(bad)?;
    let (mut mesh, mut report) = assemble(&document, &buffers).map_err(bad)?;
    report.repair = mesh.validate_and_repair().map_err(|e| match e {
        Error::BadMesh { reason, .. } => bad(reason),
        Error::InvalidParameter(reason) => bad(reason),
        other => other,
    })?;
    Ok((mesh, report))
}

const GLB_MAGIC: &[u8; 4] = b"glTF";
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

fn read_u32(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Splits a file into its glTF JSON and, for GLB, the BIN chunk. Checks every length in
/// the GLB container against the file, so truncated files are reported as such.
fn split_container(bytes: &[u8]) -> std::result::Result<(&[u8], Option<&[u8]>), String> {
    const TRUNCATED: &str = "the file is truncated (cut off during a copy or download?); \
                             export or copy it again";
    if bytes.is_empty() {
        return Err("the file is empty; expected glTF (.gltf JSON or binary .glb)".into());
    }
    if !bytes.starts_with(GLB_MAGIC) {
        // glTF JSON; a UTF-8 byte order mark is tolerated.
        let json = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
        let first = json.iter().find(|b| !b.is_ascii_whitespace());
        if first != Some(&b'{') {
            return Err(
                "not a glTF file: neither binary glTF (.glb, starting with 'glTF') nor glTF \
                 JSON (.gltf, a JSON object)"
                    .into(),
            );
        }
        return Ok((json, None));
    }
    if bytes.len() < 12 {
        return Err(format!(
            "binary glTF header is incomplete ({} of 12 bytes): {TRUNCATED}",
            bytes.len()
        ));
    }
    let version = read_u32(bytes, 4);
    if version != 2 {
        return Err(format!(
            "binary glTF version {version}; only glTF 2.0 is supported (convert the file to \
             glTF 2.0)"
        ));
    }
    let total = read_u32(bytes, 8) as usize;
    if total > bytes.len() {
        return Err(format!(
            "the GLB header declares {total} bytes but the file has {}: {TRUNCATED}",
            bytes.len()
        ));
    }
    if total < 12 {
        return Err(format!(
            "the GLB header declares a total length of {total} bytes, less than the header itself"
        ));
    }
    let data = &bytes[..total];

    let mut at = 12;
    let mut json = None;
    let mut bin = None;
    let mut chunk = 0;
    while at < data.len() {
        if data.len() - at < 8 {
            return Err(format!(
                "GLB chunk {chunk} header at byte {at} is incomplete: {TRUNCATED}"
            ));
        }
        let len = read_u32(data, at) as usize;
        let ty = read_u32(data, at + 4);
        let start = at + 8;
        if len > data.len() - start {
            return Err(format!(
                "GLB chunk {chunk} declares {len} bytes but only {} remain: {TRUNCATED}",
                data.len() - start
            ));
        }
        let body = &data[start..start + len];
        match (chunk, ty) {
            (0, CHUNK_JSON) => json = Some(body),
            (0, _) => {
                return Err(format!(
                    "the first GLB chunk has type 0x{ty:08X}, not JSON: not a valid .glb"
                ))
            }
            (1, CHUNK_BIN) => bin = Some(body),
            // Unknown chunk types are to be ignored (glTF 2.0, GLB file format).
            _ => {}
        }
        at = start + len;
        chunk += 1;
    }
    match json {
        Some(json) => Ok((json, bin)),
        None => Err(format!("the GLB has no JSON chunk: {TRUNCATED}")),
    }
}

/// Parses and validates the glTF JSON (structure, types, references).
fn parse_document(json_bytes: &[u8], glb: bool) -> std::result::Result<gltf::Document, String> {
    let root: json::Root = json::deserialize::from_slice(json_bytes).map_err(|e| {
        let chunk = if glb {
            " (in the GLB's JSON chunk)"
        } else {
            ""
        };
        format!("invalid glTF JSON{chunk}: {e}")
    })?;
    // gltf's validation indexes the accessor of every POSITION attribute without a bounds
    // check; reject dangling accessor references first (they would panic there).
    let n = root.accessors.len();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let attrs = prim.attributes.iter().map(|(s, i)| {
                let name = match s {
                    json::validation::Checked::Valid(s) => s.to_string(),
                    json::validation::Checked::Invalid => "?".into(),
                };
                (name, i.value())
            });
            let indices = prim.indices.map(|i| ("indices".to_string(), i.value()));
            for (what, index) in attrs.chain(indices) {
                if index >= n {
                    return Err(format!(
                        "meshes[{m}].primitives[{p}] {what} refers to accessor {index}, but \
                         the file has {n} accessors"
                    ));
                }
            }
        }
    }
    gltf::Document::from_json(root).map_err(|e| match e {
        gltf::Error::Validation(errors) => {
            const SHOWN: usize = 8;
            let mut list: Vec<String> = errors
                .iter()
                .take(SHOWN)
                .map(|(path, e)| format!("{path}: {e}"))
                .collect();
            if errors.len() > SHOWN {
                list.push(format!("and {} more", errors.len() - SHOWN));
            }
            let hint = if errors
                .iter()
                .any(|(_, e)| *e == json::validation::Error::Unsupported)
            {
                " (the file requires a glTF extension texsyn does not support, such as Draco \
                 or meshopt compression or mesh quantization: export it without them)"
            } else {
                ""
            };
            format!("invalid glTF: {}{hint}", list.join("; "))
        }
        other => format!("invalid glTF: {other}"),
    })
}

/// Reads the data of every buffer: the GLB BIN chunk, a `data:` URI or a file relative to
/// the glTF file.
fn load_buffers(
    doc: &gltf::Document,
    gltf_path: &Path,
    mut bin: Option<&[u8]>,
) -> std::result::Result<Vec<Vec<u8>>, String> {
    let base = match gltf_path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let file_name = gltf_path
        .file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut out = Vec::with_capacity(doc.buffers().len());
    for buffer in doc.buffers() {
        let i = buffer.index();
        let (data, source): (Vec<u8>, String) = match buffer.source() {
            gltf::buffer::Source::Bin => match bin.take() {
                Some(b) => (b.to_vec(), "the GLB binary chunk".into()),
                None => {
                    return Err(format!(
                        "buffer {i} has no uri, so it must be the binary chunk of a .glb, and \
                         this file has none (truncated or broken export?)"
                    ))
                }
            },
            gltf::buffer::Source::Uri(uri) => read_buffer_uri(i, uri, &base, &file_name)?,
        };
        if data.len() < buffer.length() {
            return Err(format!(
                "buffer {i} declares {} bytes but {source} holds only {}; the data is \
                 truncated: export or copy it again",
                buffer.length(),
                data.len()
            ));
        }
        out.push(data);
    }
    Ok(out)
}

fn read_buffer_uri(
    i: usize,
    uri: &str,
    base: &Path,
    gltf_name: &str,
) -> std::result::Result<(Vec<u8>, String), String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let Some((_, payload)) = rest.split_once(";base64,") else {
            return Err(format!(
                "buffer {i} is a data: URI without base64 encoding, which glTF does not allow"
            ));
        };
        let data = decode_base64(payload)
            .ok_or_else(|| format!("buffer {i} is a data: URI with invalid base64"))?;
        return Ok((data, format!("the data: URI of buffer {i}")));
    }
    let relative = match uri_scheme(uri) {
        Some(s) if s.eq_ignore_ascii_case("file") => {
            let rest = &uri[s.len() + 1..];
            rest.strip_prefix("//").unwrap_or(rest)
        }
        Some(s) => {
            return Err(format!(
                "buffer {i} is at '{uri}' ({s}: URI); texsyn reads only files next to the glTF \
                 and data: URIs: download it and refer to it by a relative path, or convert \
                 the model to a self-contained .glb"
            ))
        }
        None => uri,
    };
    let decoded = percent_decode(relative)
        .ok_or_else(|| format!("buffer {i} has a malformed uri '{uri}' (invalid UTF-8)"))?;
    let file = base.join(&decoded);
    match crate::image_io::read_file_capped(&file, crate::image_io::MAX_MESH_FILE_BYTES, "buffers")
    {
        Ok(data) => Ok((data, format!("'{}'", file.display()))),
        Err(Error::Io { source: e, .. }) if e.kind() == std::io::ErrorKind::NotFound => {
            Err(format!(
            "buffer {i} is stored in the external file '{decoded}' ({}), which does not exist: \
             copy it next to {gltf_name}, or export the model as a self-contained .glb",
            file.display()
        ))
        }
        Err(Error::Io { source: e, .. }) => Err(format!(
            "cannot read buffer {i} from the external file '{}': {e}",
            file.display()
        )),
        Err(e) => Err(e.to_string()),
    }
}

/// The scheme of an absolute URI (`http` in `http://..`), None for a relative reference.
/// Single letters are not taken as schemes (Windows drive letters).
fn uri_scheme(uri: &str) -> Option<&str> {
    let (scheme, _) = uri.split_once(':')?;
    let mut chars = scheme.chars();
    let first = chars.next()?;
    (scheme.len() > 1
        && first.is_ascii_alphabetic()
        && chars.all(|c| c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.')))
    .then_some(scheme)
}

/// `%XX` escapes decoded; a `%` not followed by two hex digits is kept as is.
fn percent_decode(s: &str) -> Option<String> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = |c: u8| (c as char).to_digit(16);
        if b[i] == b'%' && i + 2 < b.len() {
            if let (Some(h), Some(l)) = (hex(b[i + 1]), hex(b[i + 2])) {
                out.push((h * 16 + l) as u8);
                i += 3;
                continue;
            }
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8(out).ok()
}

/// Standard (and URL-safe) base64, padding optional.
fn decode_base64(s: &str) -> Option<Vec<u8>> {
    let s = s.trim_end_matches('=');
    let mut out = Vec::with_capacity(s.len() / 4 * 3 + 3);
    let mut acc: u32 = 0;
    let mut bits = 0;
    for c in s.bytes() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            _ => return None,
        };
        acc = (acc << 6) | v as u32;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    // One leftover character (6 bits) cannot encode a byte.
    (bits < 6).then_some(out)
}

/// One primitive, in world space.
struct Part {
    positions: Vec<Vec3>,
    normals: Option<Vec<Vec3>>,
    uvs: Option<Vec<Vec2>>,
    tangents: Option<Vec<Vec4>>,
    triangles: Vec<[u32; 3]>,
}

/// Instantiates the scene's primitives and merges them.
fn assemble(
    doc: &gltf::Document,
    buffers: &[Vec<u8>],
) -> std::result::Result<(Mesh, LoadReport), String> {
    let parent = node_parents(doc)?;
    let roots: Vec<gltf::Node> = match doc.default_scene() {
        Some(scene) => scene.nodes().collect(),
        None if doc.scenes().len() > 0 => doc.scenes().flat_map(|s| s.nodes()).collect(),
        None => doc
            .nodes()
            .filter(|n| parent[n.index()].is_none())
            .collect(),
    };

    let mut report = LoadReport::default();
    let mut parts = Vec::new();
    let mut visited = vec![false; parent.len()];
    let mut stack: Vec<(gltf::Node, Mat4)> = roots
        .into_iter()
        .rev()
        .map(|n| (n, Mat4::IDENTITY))
        .collect();
    while let Some((node, parent_world)) = stack.pop() {
        // A node listed twice (in two scenes, or as a root and as a descendant) is
        // instantiated once.
        if std::mem::replace(&mut visited[node.index()], true) {
            continue;
        }
        let local = Mat4::from_cols_array_2d(&node.transform().matrix());
        if !local.is_finite() {
            return Err(format!(
                "node {} has a transform with NaN or infinite values",
                node.index()
            ));
        }
        let world = parent_world * local;
        if let Some(mesh) = node.mesh() {
            for prim in mesh.primitives() {
                let what = match mesh.name() {
                    Some(name) => format!(
                        "mesh {} ('{name}') primitive {}",
                        mesh.index(),
                        prim.index()
                    ),
                    None => format!("mesh {} primitive {}", mesh.index(), prim.index()),
                };
                match prim.mode() {
                    Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip => {
                        report.skipped_non_triangle += 1;
                        continue;
                    }
                    Mode::TriangleStrip | Mode::TriangleFan => report.converted_strips_fans += 1,
                    Mode::Triangles => {}
                }
                report.primitives += 1;
                parts.push(read_primitive(&prim, buffers, world, &what)?);
            }
        }
        for child in node.children().collect::<Vec<_>>().into_iter().rev() {
            stack.push((child, world));
        }
    }

    if report.primitives == 0 {
        return Err(if report.skipped_non_triangle > 0 {
            format!(
                "no triangles: the scene has only points or lines primitives ({} of them); \
                 texsyn needs a triangle mesh (export surfaces, not curves or point clouds)",
                report.skipped_non_triangle
            )
        } else {
            "no triangles: the scene contains no mesh (is it the right file, and is the mesh \
             attached to a node of the scene?)"
                .into()
        });
    }
    let mesh = merge(parts)?;
    if mesh.triangles.is_empty() {
        return Err("no triangles: every triangle primitive is empty".into());
    }
    Ok((mesh, report))
}

/// Parent of every node; errors when the hierarchy is not a forest (glTF requires one:
/// a node with two parents could otherwise be instantiated exponentially often, and a
/// cycle forever).
fn node_parents(doc: &gltf::Document) -> std::result::Result<Vec<Option<usize>>, String> {
    let n = doc.nodes().len();
    let mut parent: Vec<Option<usize>> = vec![None; n];
    for node in doc.nodes() {
        for child in node.children() {
            let c = child.index();
            if c == node.index() {
                return Err(format!("node {c} is its own child"));
            }
            if let Some(p) = parent[c] {
                return Err(format!(
                    "node {c} is a child of both node {p} and node {}; glTF node hierarchies \
                     must be trees",
                    node.index()
                ));
            }
            parent[c] = Some(node.index());
        }
    }
    // Walk up from every node; a walk meeting itself is a cycle. 0 = unknown,
    // usize::MAX = reaches a root, s + 1 = on the walk started at node s.
    let mut state = vec![0usize; n];
    for start in 0..n {
        let mut cur = start;
        while state[cur] != usize::MAX {
            if state[cur] == start + 1 {
                return Err(format!(
                    "the node hierarchy has a cycle through node {cur}; glTF node hierarchies \
                     must be trees"
                ));
            }
            state[cur] = start + 1;
            match parent[cur] {
                Some(p) => cur = p,
                None => break,
            }
        }
        let mut cur = start;
        while state[cur] == start + 1 {
            state[cur] = usize::MAX;
            match parent[cur] {
                Some(p) => cur = p,
                None => break,
            }
        }
    }
    Ok(parent)
}

fn dims_name(d: Dimensions) -> &'static str {
    match d {
        Dimensions::Scalar => "SCALAR",
        Dimensions::Vec2 => "VEC2",
        Dimensions::Vec3 => "VEC3",
        Dimensions::Vec4 => "VEC4",
        Dimensions::Mat2 => "MAT2",
        Dimensions::Mat3 => "MAT3",
        Dimensions::Mat4 => "MAT4",
    }
}

fn type_name(t: DataType) -> &'static str {
    match t {
        DataType::I8 => "BYTE",
        DataType::U8 => "UNSIGNED_BYTE",
        DataType::I16 => "SHORT",
        DataType::U16 => "UNSIGNED_SHORT",
        DataType::U32 => "UNSIGNED_INT",
        DataType::F32 => "FLOAT",
    }
}

/// Checks an accessor's type and that every byte it reads (dense and sparse) lies inside
/// its buffer view and buffer, so gltf's reader neither panics nor comes up short.
fn check_accessor(
    acc: &gltf::Accessor,
    buffers: &[Vec<u8>],
    what: &str,
    dims: Dimensions,
    types: &[DataType],
) -> std::result::Result<(), String> {
    let i = acc.index();
    let (d, t) = (acc.dimensions(), acc.data_type());
    if d != dims || !types.contains(&t) {
        let expected: Vec<&str> = types.iter().map(|&t| type_name(t)).collect();
        return Err(format!(
            "{what}: accessor {i} is {} of {}; texsyn reads {} of {}",
            dims_name(d),
            type_name(t),
            dims_name(dims),
            expected.join(" or ")
        ));
    }
    if t != DataType::F32 && d != Dimensions::Scalar && !acc.normalized() {
        return Err(format!(
            "{what}: accessor {i} holds unnormalized integers, which glTF does not allow here"
        ));
    }
    let count = acc.count();
    if count == 0 {
        return Err(format!("{what}: accessor {i} has count 0"));
    }
    let elem = acc.size();
    match (acc.view(), acc.sparse()) {
        (Some(view), _) => check_range(&view, acc.offset(), count, elem, buffers, what, i)?,
        (None, None) => return Err(format!("{what}: accessor {i} has no bufferView")),
        (None, Some(_)) => {}
    }
    if let Some(sparse) = acc.sparse() {
        let n = sparse.count();
        if n == 0 || n > count {
            return Err(format!(
                "{what}: sparse accessor {i} has {n} sparse values for {count} elements"
            ));
        }
        let indices = sparse.indices();
        check_range(
            &indices.view(),
            indices.offset(),
            n,
            indices.index_type().size(),
            buffers,
            what,
            i,
        )?;
        let values = sparse.values();
        check_range(&values.view(), values.offset(), n, elem, buffers, what, i)?;
    }
    Ok(())
}

/// `count` elements of `elem` bytes at `offset` in `view` (with its stride).
fn check_range(
    view: &gltf::buffer::View,
    offset: usize,
    count: usize,
    elem: usize,
    buffers: &[Vec<u8>],
    what: &str,
    accessor: usize,
) -> std::result::Result<(), String> {
    let v = view.index();
    let b = view.buffer().index();
    let buffer_len = buffers[b].len();
    if view
        .offset()
        .checked_add(view.length())
        .is_none_or(|end| end > buffer_len)
    {
        return Err(format!(
            "{what}: bufferView {v} (bytes {}..+{}) lies outside buffer {b} ({buffer_len} bytes)",
            view.offset(),
            view.length()
        ));
    }
    let stride = view.stride().unwrap_or(elem);
    if stride < elem {
        return Err(format!(
            "{what}: bufferView {v} has byteStride {stride}, smaller than the {elem}-byte \
             elements of accessor {accessor}"
        ));
    }
    let need = stride
        .checked_mul(count - 1)
        .and_then(|x| x.checked_add(elem))
        .and_then(|x| x.checked_add(offset));
    match need {
        Some(need) if need <= view.length() => Ok(()),
        _ => Err(format!(
            "{what}: accessor {accessor} ({count} elements from byte {offset}) reads past the \
             end of bufferView {v} ({} bytes): index or count out of range",
            view.length()
        )),
    }
}

fn read_primitive(
    prim: &gltf::Primitive,
    buffers: &[Vec<u8>],
    world: Mat4,
    what: &str,
) -> std::result::Result<Part, String> {
    let Some(pos_acc) = prim.get(&Semantic::Positions) else {
        return Err(format!("{what} has no POSITION attribute"));
    };
    check_accessor(
        &pos_acc,
        buffers,
        &format!("{what} POSITION"),
        Dimensions::Vec3,
        &[DataType::F32],
    )?;
    let n = pos_acc.count();
    if u32::try_from(n).is_err() {
        return Err(format!("{what} has {n} vertices, more than 2^32"));
    }
    let attribute = |sem: Semantic, name: &str, dims, types: &[DataType]| {
        prim.get(&sem)
            .map(|acc| {
                let label = format!("{what} {name}");
                check_accessor(&acc, buffers, &label, dims, types)?;
                if acc.count() != n {
                    return Err(format!(
                        "{label}: accessor {} has {} elements, POSITION has {n}",
                        acc.index(),
                        acc.count()
                    ));
                }
                Ok(())
            })
            .transpose()
            .map(|o| o.is_some())
    };
    let has_normals = attribute(
        Semantic::Normals,
        "NORMAL",
        Dimensions::Vec3,
        &[DataType::F32],
    )?;
    let has_tangents = attribute(
        Semantic::Tangents,
        "TANGENT",
        Dimensions::Vec4,
        &[DataType::F32],
    )?;
    let has_uvs = attribute(
        Semantic::TexCoords(0),
        "TEXCOORD_0",
        Dimensions::Vec2,
        &[DataType::F32, DataType::U8, DataType::U16],
    )?;
    if let Some(acc) = prim.indices() {
        check_accessor(
            &acc,
            buffers,
            &format!("{what} indices"),
            Dimensions::Scalar,
            &[DataType::U8, DataType::U16, DataType::U32],
        )?;
    }

    let reader = prim.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
    let short = |name: &str| format!("{what}: {name} could not be read (data out of range)");
    let exact = |len: usize, name: &str| {
        if len == n {
            Ok(())
        } else {
            Err(short(name))
        }
    };

    // Linear part for directions; cofactor matrix (= det * inverse transpose, defined
    // even for singular transforms) for normals.
    let linear = Mat3::from_mat4(world);
    let det = linear.determinant();
    let mirror = det < 0.0;
    let sign = if mirror { -1.0 } else { 1.0 };
    let normal_matrix = Mat3::from_cols(
        linear.y_axis.cross(linear.z_axis),
        linear.z_axis.cross(linear.x_axis),
        linear.x_axis.cross(linear.y_axis),
    ) * sign;

    let positions: Vec<Vec3> = reader
        .read_positions()
        .ok_or_else(|| short("POSITION"))?
        .map(|p| world.transform_point3(Vec3::from(p)))
        .collect();
    exact(positions.len(), "POSITION")?;
    let normals = if has_normals {
        let v: Vec<Vec3> = reader
            .read_normals()
            .ok_or_else(|| short("NORMAL"))?
            .map(|v| (normal_matrix * Vec3::from(v)).normalize_or_zero())
            .collect();
        exact(v.len(), "NORMAL")?;
        Some(v)
    } else {
        None
    };
    let tangents = if has_tangents {
        let v: Vec<Vec4> = reader
            .read_tangents()
            .ok_or_else(|| short("TANGENT"))?
            .map(|t| {
                let xyz = (linear * Vec3::new(t[0], t[1], t[2])).normalize_or_zero();
                let w = if t[3] < 0.0 { -sign } else { sign };
                xyz.extend(w)
            })
            .collect();
        exact(v.len(), "TANGENT")?;
        Some(v)
    } else {
        None
    };
    let uvs = if has_uvs {
        let v: Vec<Vec2> = reader
            .read_tex_coords(0)
            .ok_or_else(|| short("TEXCOORD_0"))?
            .into_f32()
            .map(Vec2::from)
            .collect();
        exact(v.len(), "TEXCOORD_0")?;
        Some(v)
    } else {
        None
    };

    let indices: Vec<u32> = match prim.indices() {
        Some(acc) => {
            let v: Vec<u32> = reader
                .read_indices()
                .ok_or_else(|| short("indices"))?
                .into_u32()
                .collect();
            if v.len() != acc.count() {
                return Err(short("indices"));
            }
            if let Some((k, &bad)) = v.iter().enumerate().find(|(_, &i)| i as usize >= n) {
                return Err(format!(
                    "{what}: index {bad} (entry {k} of accessor {}) is out of range: the \
                     primitive has {n} vertices",
                    acc.index()
                ));
            }
            v
        }
        None => (0..n as u32).collect(),
    };

    let mut triangles: Vec<[u32; 3]> = match prim.mode() {
        Mode::Triangles => {
            if !indices.len().is_multiple_of(3) {
                return Err(format!(
                    "{what}: {} vertex indices is not a multiple of 3 (mode TRIANGLES)",
                    indices.len()
                ));
            }
            indices
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect()
        }
        // glTF 2.0 section 3.7.2.1: p_i = {v_i, v_(i+(1+i%2)), v_(i+(2-i%2))}.
        Mode::TriangleStrip => indices
            .windows(3)
            .enumerate()
            .map(|(i, w)| {
                if i % 2 == 0 {
                    [w[0], w[1], w[2]]
                } else {
                    [w[0], w[2], w[1]]
                }
            })
            .collect(),
        // p_i = {v_(i+1), v_(i+2), v_0}.
        Mode::TriangleFan => indices
            .windows(2)
            .skip(1)
            .map(|w| [w[0], w[1], indices[0]])
            .collect(),
        _ => unreachable!("non-triangle modes are skipped by the caller"),
    };
    if mirror {
        // A negative determinant turns the winding clockwise; restore counter-clockwise.
        for t in &mut triangles {
            t.swap(1, 2);
        }
    }

    Ok(Part {
        positions,
        normals,
        uvs,
        tangents,
        triangles,
    })
}

/// Concatenates the parts (indices offset); an attribute missing from any part is
/// dropped from the result (normals: left empty, to be computed).
fn merge(parts: Vec<Part>) -> std::result::Result<Mesh, String> {
    let total: usize = parts.iter().map(|p| p.positions.len()).sum();
    if u32::try_from(total).is_err() {
        return Err(format!("{total} vertices in all, more than 2^32"));
    }
    let all_normals = parts.iter().all(|p| p.normals.is_some());
    let all_uvs = parts.iter().all(|p| p.uvs.is_some());
    let all_tangents = parts.iter().all(|p| p.tangents.is_some());
    let mut mesh = Mesh::default();
    mesh.positions.reserve(total);
    let mut uvs = Vec::with_capacity(if all_uvs { total } else { 0 });
    let mut tangents = Vec::with_capacity(if all_tangents { total } else { 0 });
    for part in parts {
        let base = mesh.positions.len() as u32;
        mesh.positions.extend(part.positions);
        if all_normals {
            mesh.normals.extend(part.normals.unwrap_or_default());
        }
        if all_uvs {
            uvs.extend(part.uvs.unwrap_or_default());
        }
        if all_tangents {
            tangents.extend(part.tangents.unwrap_or_default());
        }
        mesh.triangles
            .extend(part.triangles.iter().map(|t| t.map(|i| i + base)));
    }
    mesh.uvs = all_uvs.then_some(uvs);
    mesh.tangents = all_tangents.then_some(tangents);
    Ok(mesh)
}

// ---------------------------------------------------------------------------------------
// Writing
// ---------------------------------------------------------------------------------------

/// Writes a binary glTF (.glb): one mesh with one primitive (POSITION with min/max,
/// NORMAL, TEXCOORD_0, TANGENT when there are tangents (below), u32 indices), one node,
/// one scene, and a PBR material whose textures are `material`'s images, embedded as PNG
/// in buffer views and sampled with LINEAR_MIPMAP_LINEAR / LINEAR filtering and
/// CLAMP_TO_EDGE wrapping.
///
/// `mesh.uvs` must be `Some` and every attribute must have one entry per position.
/// Normals and tangents are written normalized (a zero normal becomes +Z, a zero tangent
/// +X; tangent `w` becomes +-1), as glTF requires. TANGENT is written when the mesh has
/// tangents, or when there is a normal map: then it is computed from the uvs (direction
/// of increasing u; the bitangent `cross(normal, tangent) * w` points up the image), so
/// that viewers do not each generate their own tangent frame.
///
/// The file is written to a temporary file in the same directory and renamed over
/// `path`: `path` never holds a partial file.
///
/// Errors: [`Error::InvalidParameter`] for an unusable mesh or image (nothing is written),
/// [`Error::Write`] when the file cannot be written.
pub fn write_glb(path: &Path, mesh: &Mesh, material: &MaterialImages) -> Result<()> {
    let bytes = encode_glb(mesh, material)?;
    crate::image_io::write_files_atomic(&[(path, &bytes)])
}

fn invalid(msg: String) -> Error {
    Error::InvalidParameter(format!("write_glb: {msg}"))
}

/// The binary glTF of `mesh` and `material`, in memory (what [`write_glb`] writes).
pub fn encode_glb(mesh: &Mesh, material: &MaterialImages) -> Result<Vec<u8>> {
    use json::validation::{Checked::Valid, USize64};

    let n = mesh.positions.len();
    if n == 0 || mesh.triangles.is_empty() {
        return Err(invalid("the mesh is empty".into()));
    }
    if u32::try_from(n).is_err() {
        return Err(invalid(format!("{n} vertices, more than 2^32")));
    }
    let Some(uvs) = mesh.uvs.as_ref() else {
        return Err(invalid(
            "the mesh has no texture coordinates (uvs); generate an atlas first".into(),
        ));
    };
    let check_len = |len: usize, what: &str| {
        if len == n {
            Ok(())
        } else {
            Err(invalid(format!(
                "the mesh has {len} {what} for {n} positions (run validate_and_repair first)"
            )))
        }
    };
    check_len(mesh.normals.len(), "normals")?;
    check_len(uvs.len(), "uvs")?;
    if let Some(t) = &mesh.tangents {
        check_len(t.len(), "tangents")?;
    }
    if let Some(k) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return Err(invalid(format!("position {k} is not finite")));
    }
    if let Some(k) = uvs.iter().position(|p| !p.is_finite()) {
        return Err(invalid(format!("uv {k} is not finite")));
    }
    if let Some((t, _)) = mesh
        .triangles
        .iter()
        .enumerate()
        .find(|(_, t)| t.iter().any(|&i| i as usize >= n))
    {
        return Err(invalid(format!(
            "triangle {t} has a vertex index out of range ({n} vertices)"
        )));
    }

    let mut root = json::Root {
        asset: json::Asset {
            generator: Some(format!("texsyn {}", env!("CARGO_PKG_VERSION"))),
            ..Default::default()
        },
        ..Default::default()
    };
    let buffer_index = json::Index::<json::Buffer>::new(0);
    let mut bin: Vec<u8> = Vec::new();

    // Appends `bytes` as a buffer view (4-byte aligned, so every accessor is aligned).
    let add_view = |root: &mut json::Root,
                    bin: &mut Vec<u8>,
                    bytes: &[u8],
                    target: Option<json::buffer::Target>| {
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let offset = bin.len();
        bin.extend_from_slice(bytes);
        root.push(json::buffer::View {
            buffer: buffer_index,
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            name: None,
            target: target.map(Valid),
            extensions: None,
            extras: Default::default(),
        })
    };
    let accessor = |view, count: usize, ct, ty, min, max| json::Accessor {
        buffer_view: Some(view),
        byte_offset: None,
        count: USize64::from(count),
        component_type: Valid(json::accessor::GenericComponentType(ct)),
        extensions: None,
        extras: Default::default(),
        type_: Valid(ty),
        min,
        max,
        name: None,
        normalized: false,
        sparse: None,
    };
    let floats =
        |v: &mut dyn Iterator<Item = f32>| -> Vec<u8> { v.flat_map(f32::to_le_bytes).collect() };
    use json::accessor::{ComponentType, Type};
    use json::buffer::Target;

    // Attributes.
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for &p in &mesh.positions {
        lo = lo.min(p);
        hi = hi.max(p);
    }
    let view = add_view(
        &mut root,
        &mut bin,
        &floats(&mut mesh.positions.iter().flat_map(|p| p.to_array())),
        Some(Target::ArrayBuffer),
    );
    let position = root.push(accessor(
        view,
        n,
        ComponentType::F32,
        Type::Vec3,
        Some(json::Value::from(lo.to_array().to_vec())),
        Some(json::Value::from(hi.to_array().to_vec())),
    ));
    let unit_normal = |v: Vec3| match v.try_normalize() {
        Some(u) => u,
        None => Vec3::Z,
    };
    let normals: Vec<Vec3> = mesh.normals.iter().map(|&v| unit_normal(v)).collect();
    let view = add_view(
        &mut root,
        &mut bin,
        &floats(&mut normals.iter().flat_map(|v| v.to_array())),
        Some(Target::ArrayBuffer),
    );
    let normal = root.push(accessor(
        view,
        n,
        ComponentType::F32,
        Type::Vec3,
        None,
        None,
    ));
    let view = add_view(
        &mut root,
        &mut bin,
        &floats(&mut uvs.iter().flat_map(|v| v.to_array())),
        Some(Target::ArrayBuffer),
    );
    let texcoord = root.push(accessor(
        view,
        n,
        ComponentType::F32,
        Type::Vec2,
        None,
        None,
    ));
    // A normal map needs a tangent frame; without one in the mesh, viewers would each
    // generate their own. Write the frame the uvs define instead (see `uv_tangents`).
    let tangents: Option<Vec<Vec4>> = match (&mesh.tangents, &material.normal) {
        (Some(t), _) => Some(
            t.iter()
                .map(|t| {
                    let xyz = t.truncate().try_normalize().unwrap_or(Vec3::X);
                    xyz.extend(if t.w < 0.0 { -1.0 } else { 1.0 })
                })
                .collect(),
        ),
        (None, Some(_)) => Some(uv_tangents(&mesh.positions, &normals, uvs, &mesh.triangles)),
        (None, None) => None,
    };
    let tangent = match &tangents {
        Some(t) => {
            let view = add_view(
                &mut root,
                &mut bin,
                &floats(&mut t.iter().flat_map(|t| t.to_array())),
                Some(Target::ArrayBuffer),
            );
            Some(root.push(accessor(
                view,
                n,
                ComponentType::F32,
                Type::Vec4,
                None,
                None,
            )))
        }
        None => None,
    };
    let index_bytes: Vec<u8> = mesh
        .triangles
        .iter()
        .flatten()
        .flat_map(|i| i.to_le_bytes())
        .collect();
    let view = add_view(
        &mut root,
        &mut bin,
        &index_bytes,
        Some(Target::ElementArrayBuffer),
    );
    let indices = root.push(accessor(
        view,
        mesh.triangles.len() * 3,
        ComponentType::U32,
        Type::Scalar,
        None,
        None,
    ));

    // Textures: one sampler, one PNG image and texture each.
    let sampler = root.push(json::texture::Sampler {
        mag_filter: Some(Valid(json::texture::MagFilter::Linear)),
        min_filter: Some(Valid(json::texture::MinFilter::LinearMipmapLinear)),
        wrap_s: Valid(json::texture::WrappingMode::ClampToEdge),
        wrap_t: Valid(json::texture::WrappingMode::ClampToEdge),
        ..Default::default()
    });
    let add_texture = |root: &mut json::Root,
                       bin: &mut Vec<u8>,
                       img: &RgbaImage,
                       name: &str|
     -> Result<json::Index<json::Texture>> {
        let png = encode_png(img, name)?;
        let view = add_view(root, bin, &png, None);
        let image = root.push(json::Image {
            buffer_view: Some(view),
            mime_type: Some(json::image::MimeType("image/png".into())),
            name: Some(name.into()),
            uri: None,
            extensions: None,
            extras: Default::default(),
        });
        Ok(root.push(json::Texture {
            name: Some(name.into()),
            sampler: Some(sampler),
            source: image,
            extensions: None,
            extras: Default::default(),
        }))
    };
    let info = |index| json::texture::Info {
        index,
        tex_coord: 0,
        extensions: None,
        extras: Default::default(),
    };
    let base_color = add_texture(&mut root, &mut bin, &material.base_color, "base_color")?;
    let metallic_roughness = match &material.metallic_roughness {
        Some(img) => Some(add_texture(&mut root, &mut bin, img, "metallic_roughness")?),
        None => None,
    };
    let normal_texture = match &material.normal {
        Some(img) => Some(json::material::NormalTexture {
            index: add_texture(&mut root, &mut bin, img, "normal")?,
            scale: 1.0,
            tex_coord: 0,
            extensions: None,
            extras: Default::default(),
        }),
        None => None,
    };
    let occlusion_texture = match &material.occlusion {
        Some(img) => Some(json::material::OcclusionTexture {
            index: add_texture(&mut root, &mut bin, img, "occlusion")?,
            strength: json::material::StrengthFactor(1.0),
            tex_coord: 0,
            extensions: None,
            extras: Default::default(),
        }),
        None => None,
    };
    let material_index = root.push(json::Material {
        name: Some("texsyn".into()),
        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
            base_color_texture: Some(info(base_color)),
            // Without a metallic-roughness texture: a rough dielectric.
            metallic_factor: json::material::StrengthFactor(if metallic_roughness.is_some() {
                1.0
            } else {
                0.0
            }),
            roughness_factor: json::material::StrengthFactor(1.0),
            metallic_roughness_texture: metallic_roughness.map(info),
            ..Default::default()
        },
        normal_texture,
        occlusion_texture,
        ..Default::default()
    });

    // Mesh, node, scene.
    let mut attributes = BTreeMap::new();
    attributes.insert(Valid(json::mesh::Semantic::Positions), position);
    attributes.insert(Valid(json::mesh::Semantic::Normals), normal);
    attributes.insert(Valid(json::mesh::Semantic::TexCoords(0)), texcoord);
    if let Some(t) = tangent {
        attributes.insert(Valid(json::mesh::Semantic::Tangents), t);
    }
    let mesh_index = root.push(json::Mesh {
        extensions: None,
        extras: Default::default(),
        name: Some("texsyn".into()),
        primitives: vec![json::mesh::Primitive {
            attributes,
            extensions: None,
            extras: Default::default(),
            indices: Some(indices),
            material: Some(material_index),
            mode: Valid(json::mesh::Mode::Triangles),
            targets: None,
        }],
        weights: None,
    });
    let node = root.push(json::Node {
        mesh: Some(mesh_index),
        name: Some("texsyn".into()),
        ..Default::default()
    });
    let scene = root.push(json::Scene {
        extensions: None,
        extras: Default::default(),
        name: None,
        nodes: vec![node],
    });
    root.scene = Some(scene);

    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    root.push(json::Buffer {
        byte_length: USize64::from(bin.len()),
        name: None,
        uri: None,
        extensions: None,
        extras: Default::default(),
    });

    let mut json_bytes = json::serialize::to_vec(&root)
        .map_err(|e| invalid(format!("cannot serialize the glTF JSON: {e}")))?;
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    let total = 12 + 8 + json_bytes.len() + 8 + bin.len();
    let Ok(total32) = u32::try_from(total) else {
        return Err(invalid(format!(
            "the file would be {total} bytes; binary glTF is limited to 4 GiB (use smaller \
             textures)"
        )));
    };
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(GLB_MAGIC);
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&total32.to_le_bytes());
    out.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_JSON.to_le_bytes());
    out.extend_from_slice(&json_bytes);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_BIN.to_le_bytes());
    out.extend_from_slice(&bin);
    Ok(out)
}

/// Per-vertex tangents from the uv parameterization, for meshes written with a normal
/// map but without tangents: `xyz` is the direction of increasing u (area-weighted over
/// the vertex's triangles, made orthogonal to the unit `normals`), and `w` makes
/// `cross(normal, xyz) * w` point up the image (decreasing v, glTF's convention for the
/// green channel of normal maps). Vertices without a usable uv gradient get an arbitrary
/// tangent perpendicular to the normal.
fn uv_tangents(
    positions: &[Vec3],
    normals: &[Vec3],
    uvs: &[Vec2],
    triangles: &[[u32; 3]],
) -> Vec<Vec4> {
    let mut du = vec![Vec3::ZERO; positions.len()];
    let mut dv = vec![Vec3::ZERO; positions.len()];
    for &[a, b, c] in triangles {
        let (a, b, c) = (a as usize, b as usize, c as usize);
        let (e1, e2) = (positions[b] - positions[a], positions[c] - positions[a]);
        let (t1, t2) = (uvs[b] - uvs[a], uvs[c] - uvs[a]);
        let r = t1.x * t2.y - t2.x * t1.y;
        let area = e1.cross(e2).length();
        if r.abs() < 1e-20 || area == 0.0 {
            continue;
        }
        // dP/du and dP/dv of the triangle, normalized, weighted by its area.
        let su = ((e1 * t2.y - e2 * t1.y) / r).normalize_or_zero() * area;
        let sv = ((e2 * t1.x - e1 * t2.x) / r).normalize_or_zero() * area;
        for v in [a, b, c] {
            du[v] += su;
            dv[v] += sv;
        }
    }
    normals
        .iter()
        .zip(du.iter().zip(&dv))
        .map(|(&n, (&u, &v))| {
            let t = (u - n * n.dot(u))
                .try_normalize()
                .unwrap_or_else(|| n.any_orthonormal_vector());
            let w = if n.cross(t).dot(-v) < 0.0 { -1.0 } else { 1.0 };
            t.extend(w)
        })
        .collect()
}

/// PNG bytes of `img`: RGB when it is opaque everywhere, RGBA otherwise.
fn encode_png(img: &RgbaImage, what: &str) -> Result<Vec<u8>> {
    let (w, h) = img.dimensions();
    if w == 0 || h == 0 {
        return Err(invalid(format!("the {what} image is empty ({w}x{h})")));
    }
    let mut out = Vec::new();
    let encoder = image::codecs::png::PngEncoder::new(&mut out);
    let result = if img.pixels().all(|p| p[3] == 255) {
        let rgb: Vec<u8> = img.pixels().flat_map(|p| [p[0], p[1], p[2]]).collect();
        encoder.write_image(&rgb, w, h, image::ExtendedColorType::Rgb8)
    } else {
        encoder.write_image(img.as_raw(), w, h, image::ExtendedColorType::Rgba8)
    };
    result.map_err(|e| invalid(format!("cannot encode the {what} image as PNG: {e}")))?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_round_trip() {
        assert_eq!(decode_base64("").unwrap(), b"");
        assert_eq!(decode_base64("Zg==").unwrap(), b"f");
        assert_eq!(decode_base64("Zm8=").unwrap(), b"fo");
        assert_eq!(decode_base64("Zm9v").unwrap(), b"foo");
        assert_eq!(decode_base64("Zm9vYg").unwrap(), b"foob");
        assert!(decode_base64("Z").is_none());
        assert!(decode_base64("Zm9v!").is_none());
    }

    #[test]
    fn percent_and_scheme() {
        assert_eq!(percent_decode("a%20b.bin").unwrap(), "a b.bin");
        assert_eq!(percent_decode("100%").unwrap(), "100%");
        assert_eq!(percent_decode("%4").unwrap(), "%4");
        assert!(percent_decode("%FF").is_none());
        assert_eq!(uri_scheme("http://x/y.bin"), Some("http"));
        assert_eq!(uri_scheme("file:///tmp/a.bin"), Some("file"));
        assert_eq!(uri_scheme("C:/a.bin"), None);
        assert_eq!(uri_scheme("mesh.bin"), None);
    }

    #[test]
    fn glb_container_errors() {
        assert!(split_container(b"").is_err());
        assert!(split_container(b"glTF\x02\x00")
            .unwrap_err()
            .contains("truncated"));
        assert!(split_container(b"not gltf").is_err());
        assert!(split_container(b" {\"asset\":{}}").is_ok());
    }
}
