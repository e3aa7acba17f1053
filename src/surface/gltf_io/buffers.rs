//! Buffer sources: the GLB BIN chunk, embedded `data:` URIs (base64) and external files
//! next to the glTF, each checked against its declared length.

use std::path::{Path, PathBuf};

use crate::error::Error;

/// Reads the data of every buffer: the GLB BIN chunk, a `data:` URI or a file relative to
/// the glTF file.
pub(super) fn load_buffers(
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
}
