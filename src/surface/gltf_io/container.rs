//! The glTF container: a `.glb`'s header and chunks checked against the file's length,
//! and the JSON document parsed and validated.

use gltf::json;

pub(super) const GLB_MAGIC: &[u8; 4] = b"glTF";
pub(super) const CHUNK_JSON: u32 = 0x4E4F_534A;
pub(super) const CHUNK_BIN: u32 = 0x004E_4942;

fn read_u32(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Splits a file into its glTF JSON and, for GLB, the BIN chunk. Checks every length in
/// the GLB container against the file, so truncated files are reported as such.
pub(super) fn split_container(bytes: &[u8]) -> std::result::Result<(&[u8], Option<&[u8]>), String> {
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
pub(super) fn parse_document(
    json_bytes: &[u8],
    glb: bool,
) -> std::result::Result<gltf::Document, String> {
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

#[cfg(test)]
mod tests {
    use super::*;

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
