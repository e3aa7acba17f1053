//! Opening and decoding image files: format detection by content, clean errors for
//! files that are not images (directories, devices, truncated or corrupt data, analysis
//! files), the few-channel OpenEXR fallback, and the check for non-finite samples.

use std::fs::{self, File};
use std::io::BufReader;
use std::path::Path;

use image::{DynamicImage, ImageFormat};

use super::exr::{channel_base, exr_channel_names, read_few_channel_exr, FewChannelExr};
use crate::error::{Error, Result};

/// Opens and decodes an image, deciding the format by content (any format and pixel
/// type; for auxiliary inputs such as fields and masks). Missing / unreadable
/// file: `Error::Io`; anything the decoder rejects: `Error::BadImage`.
///
/// OpenEXRs with 1 or 2 channels (which the `image` crate refuses) are read with the
/// `exr` crate (the first non-deep layer, largest resolution level, display window) and
/// returned as float RGB:
/// * 1 channel (`Y`, or any single channel) `v`: `(v, v, v)`, like a grey image;
/// * 2 channels: `(first, second, 0)`, where the pair is `R`, `G` when the channels are
///   named so; otherwise, when one channel is alpha (`A`), the other channel then `A`;
///   otherwise the two channels in alphabetical (byte) order of their names, e.g. `X`,
///   `Y` or `U`, `V`. Names are compared after their last `.` (layer prefix), ignoring
///   case. Flows (`image:F.exr`) and coordinate maps thus read x from channel 0 and y
///   from channel 1.
///
/// Such files are size-checked (at most 512 MiB of samples, as for the `image` crate)
/// before their pixels are read; sample values are not checked here (NaN included):
/// each consumer checks what it needs.
pub fn open_image(path: &Path) -> Result<DynamicImage> {
    decode_image(path)
}

/// [`open_image`], and for a 1- or 2-channel OpenEXR its count of value channels (alpha
/// not counted; `None` for every other file, whose [`DynamicImage`] colour type tells):
/// a grey EXR comes out as RGB, and field readers need to know it had one value per pixel.
pub fn open_image_exr_channels(path: &Path) -> Result<(DynamicImage, Option<u32>)> {
    Ok(match decode_any(path)? {
        Decoded::Image(img) => (img, None),
        Decoded::Exr(exr) => {
            let n = exr.names.len() as u32 - exr.alpha as u32;
            (exr.to_image(), Some(n))
        }
    })
}

pub(super) fn decode_image(path: &Path) -> Result<DynamicImage> {
    Ok(match decode_any(path)? {
        Decoded::Image(img) => img,
        Decoded::Exr(exr) => exr.to_image(),
    })
}

/// The number of frames of an animated GIF or PNG (APNG), which every reader here
/// takes the first frame of; `None` for other files and for files that cannot be read
/// (loading them says why).
pub fn animation_frames(path: &Path) -> Option<usize> {
    use image::AnimationDecoder;
    if !fs::metadata(path).ok()?.is_file() {
        return None;
    }
    let reader = image::ImageReader::open(path)
        .ok()?
        .with_guessed_format()
        .ok()?;
    let format = reader.format()?;
    let file = BufReader::new(File::open(path).ok()?);
    match format {
        ImageFormat::Gif => {
            let decoder = image::codecs::gif::GifDecoder::new(file).ok()?;
            Some(decoder.into_frames().take_while(|f| f.is_ok()).count())
        }
        ImageFormat::Png => {
            let decoder = image::codecs::png::PngDecoder::new(file).ok()?;
            if !decoder.is_apng().ok()? {
                return None;
            }
            let frames = decoder.apng().ok()?.into_frames();
            Some(frames.take_while(|f| f.is_ok()).count())
        }
        _ => None,
    }
}

/// A decoded file: anything the `image` crate reads, or a 1- or 2-channel OpenEXR.
pub(super) enum Decoded {
    Image(DynamicImage),
    Exr(FewChannelExr),
}

pub(super) fn decode_any(path: &Path) -> Result<Decoded> {
    let io_err = |source| Error::Io {
        path: path.to_path_buf(),
        source,
    };
    if path.is_dir() {
        return Err(Error::BadImage {
            path: path.to_path_buf(),
            reason: "it is a directory, not an image file".into(),
        });
    }
    let meta = fs::metadata(path).ok();
    if meta.as_ref().is_some_and(|m| !m.is_file()) {
        // A device (`/dev/zero`), a pipe, a socket: no length to check against and
        // perhaps no end. Checked before opening: opening a named pipe blocks until
        // something writes to it.
        return Err(Error::BadImage {
            path: path.to_path_buf(),
            reason: "it is not a regular file (a device or a pipe); give an image file".into(),
        });
    }
    let reader = image::ImageReader::open(path).map_err(io_err)?;
    let reader = reader.with_guessed_format().map_err(io_err)?;
    let len = meta.map(|m| m.len());
    if len == Some(0) {
        return Err(Error::BadImage {
            path: path.to_path_buf(),
            reason: "the file is empty".into(),
        });
    }
    if reader.format().is_none() {
        let analysis = crate::analysis::file::is_analysis_file(path).unwrap_or(false);
        return Err(Error::BadImage {
            path: path.to_path_buf(),
            reason: if analysis {
                "it is a texsyn analysis file, not an image; give the exemplar image it was \
                 made from (synth, surface, advect and bench take analysis files in place \
                 of the exemplar)"
                    .into()
            } else {
                "unrecognized image format (neither the content nor the extension names \
                 a supported format)"
                    .into()
            },
        });
    }
    // The JPEG decoder turns a truncated file into an image whose missing part is grey,
    // without an error: look for the end of the image first.
    if reader.format() == Some(ImageFormat::Jpeg) {
        let bytes = fs::read(path).map_err(io_err)?;
        if jpeg_lacks_end(&bytes) {
            return Err(Error::BadImage {
                path: path.to_path_buf(),
                reason: "the JPEG file is truncated (its image data ends before the \
                         end-of-image marker); export or download it again"
                    .into(),
            });
        }
    }
    let is_exr = reader.format() == Some(ImageFormat::OpenExr);
    let bad = |reason: String| Error::BadImage {
        path: path.to_path_buf(),
        reason,
    };
    // Decoders read untrusted bytes: a panic in one is a bad file, not a crash.
    let e = match crate::error::catch_quietly(|| reader.decode()) {
        Ok(Ok(img)) => return Ok(Decoded::Image(img)),
        Ok(Err(e)) => e,
        Err(_) => {
            return Err(bad(format!(
                "the {} decoder failed on this file (corrupt data)",
                if is_exr { "OpenEXR" } else { "image" }
            )))
        }
    };
    let mut reason = match &e {
        image::ImageError::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            format!("the file is truncated ({e})")
        }
        image::ImageError::Limits(_) => {
            let size = image::ImageReader::open(path)
                .ok()
                .and_then(|r| r.with_guessed_format().ok())
                .and_then(|r| r.into_dimensions().ok())
                .map_or(String::new(), |(w, h)| format!("it is {w}x{h} pixels: "));
            format!(
                "{size}too large to decode ({e}; the decoder's limit is 512 MiB of pixels); \
                 give a smaller image"
            )
        }
        _ => e.to_string(),
    };
    // The `image` crate reads only RGB(A) EXRs: read 1- and 2-channel ones with `exr`.
    if is_exr {
        if let Some(names) = exr_channel_names(path) {
            if matches!(names.len(), 1 | 2) {
                return read_few_channel_exr(path).map(Decoded::Exr).map_err(|r| {
                    bad(format!(
                        "cannot decode the {}-channel OpenEXR ({}): {r}",
                        names.len(),
                        names.join(", ")
                    ))
                });
            }
            let colour = |c: &str| matches!(c.to_ascii_uppercase().as_str(), "R" | "G" | "B" | "A");
            let rgb = ["R", "G", "B"].iter().all(|c| {
                names
                    .iter()
                    .any(|n| channel_base(n).eq_ignore_ascii_case(c))
            });
            reason = if rgb && names.iter().all(|n| colour(channel_base(n))) {
                // Channels the decoder reads: the data itself is bad.
                format!("{reason} (the file is truncated or corrupt)")
            } else {
                format!(
                    "{reason} (its channels: {}; texsyn reads RGB, RGBA, 1- and 2-channel \
                     OpenEXRs)",
                    names.join(", ")
                )
            };
        }
    }
    Err(bad(reason))
}

/// Whether a JPEG (starting with SOI) ends before its image's end-of-image marker:
/// walks the marker segments, and the entropy-coded data after each start of scan, to
/// the EOI of the main image (an EXIF thumbnail's lies inside its segment and is
/// skipped; data after the EOI, such as a motion photo's video, is not looked at).
/// Structural damage it cannot follow is left to the decoder (`false`).
pub fn jpeg_lacks_end(b: &[u8]) -> bool {
    if b.len() < 2 || b[0] != 0xFF || b[1] != 0xD8 {
        return false;
    }
    let mut i = 2;
    loop {
        // The next marker: 0xFF (fill bytes allowed) then its code.
        if i >= b.len() {
            return true;
        }
        if b[i] != 0xFF {
            return false;
        }
        while i < b.len() && b[i] == 0xFF {
            i += 1;
        }
        let Some(&code) = b.get(i) else {
            return true;
        };
        i += 1;
        match code {
            0xD9 => return false,
            0x01 | 0xD0..=0xD7 => continue,
            _ => {
                let Some(len) = b.get(i..i + 2) else {
                    return true;
                };
                let len = u16::from_be_bytes([len[0], len[1]]) as usize;
                if len < 2 {
                    return false;
                }
                i += len;
                if code == 0xDA {
                    // Entropy-coded data up to the next marker that is not a stuffed
                    // 0xFF00 or a restart marker.
                    loop {
                        let (Some(&x), Some(&y)) = (b.get(i), b.get(i + 1)) else {
                            return true;
                        };
                        if x == 0xFF && y != 0x00 && !(0xD0..=0xD7).contains(&y) && y != 0xFF {
                            break;
                        }
                        i += if x == 0xFF && y != 0xFF { 2 } else { 1 };
                    }
                }
            }
        }
    }
}

/// Refuses a decoded image with a NaN or infinite sample (only float images can hold
/// one): masks, material maps and evaluated images would otherwise clamp it silently.
/// `what` names the input ("feature mask", ...).
pub fn check_finite(img: &DynamicImage, path: &Path, what: &str) -> Result<()> {
    let color = img.color();
    if color.bytes_per_pixel() / color.channel_count().max(1) != 4 {
        return Ok(());
    }
    check_finite_samples(&img.to_rgba32f().into_raw(), 4, img.width(), path, what)
}

/// [`check_finite`] for interleaved samples of `channels` per pixel.
pub(super) fn check_finite_samples(
    samples: &[f32],
    channels: usize,
    width: u32,
    path: &Path,
    what: &str,
) -> Result<()> {
    match samples.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => {
            let pixel = (i / channels.max(1)) as u64;
            Err(Error::BadImage {
                path: path.to_path_buf(),
                reason: format!(
                    "pixel ({}, {}) holds a NaN or infinite value; the {what} needs finite values",
                    pixel % width.max(1) as u64,
                    pixel / width.max(1) as u64
                ),
            })
        }
    }
}
