//! Encoding and saving images: RGBA8 pixels to grey, grey + alpha, RGB or RGBA in the
//! format named by the extension.

use std::io::Cursor;
use std::path::Path;

use image::{DynamicImage, ImageFormat};

use super::atomic::write_files_atomic;
use crate::error::{Error, Result};

/// Extensions accepted by [`save_image_atomic`], for error messages.
pub const SUPPORTED_SAVE_EXTENSIONS: &str =
    "png, jpg/jpeg, bmp, tga, tif/tiff, webp, gif, pnm/ppm/pgm/pam, exr, hdr";

fn save_format(path: &Path) -> Result<ImageFormat> {
    let Some(ext) = path.extension() else {
        return Ok(ImageFormat::Png);
    };
    let fmt = ImageFormat::from_extension(ext).filter(|f| {
        matches!(
            f,
            ImageFormat::Png
                | ImageFormat::Jpeg
                | ImageFormat::Bmp
                | ImageFormat::Tga
                | ImageFormat::Tiff
                | ImageFormat::WebP
                | ImageFormat::Gif
                | ImageFormat::Pnm
                | ImageFormat::OpenExr
                | ImageFormat::Hdr
        )
    });
    fmt.ok_or_else(|| {
        Error::InvalidParameter(format!(
            "cannot write {}: unsupported image extension .{}; supported: {} (no extension: png)",
            path.display(),
            ext.to_string_lossy(),
            SUPPORTED_SAVE_EXTENSIONS
        ))
    })
}

pub(super) fn check_buffer(
    width: u32,
    height: u32,
    per_pixel: u64,
    len: usize,
    what: &str,
) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(Error::InvalidParameter(format!(
            "cannot write a {width}x{height} image"
        )));
    }
    let expected = width as u64 * height as u64 * per_pixel;
    if len as u64 != expected {
        return Err(Error::InvalidParameter(format!(
            "{what} has {len} entries, expected {expected} for a {width}x{height} image"
        )));
    }
    Ok(())
}

pub(super) fn encode_err(path: &Path, e: image::ImageError) -> Error {
    Error::Write {
        path: path.to_path_buf(),
        reason: format!("encoding failed: {e}"),
    }
}

/// Encodes `img`; if the encoder rejects its pixel layout (e.g. GIF and grey), retries with
/// the nearest layouts that keep the most information: RGB8, RGBA8, then float RGB.
fn encode_with_fallback(img: &DynamicImage, format: ImageFormat) -> image::ImageResult<Vec<u8>> {
    let encode = |img: &DynamicImage| {
        let mut buf = Cursor::new(Vec::new());
        img.write_to(&mut buf, format).map(|()| buf.into_inner())
    };
    let first = match encode(img) {
        Err(e @ image::ImageError::Unsupported(_)) => e,
        other => return other,
    };
    let fallbacks = [
        DynamicImage::ImageRgb8(img.to_rgb8()),
        DynamicImage::ImageRgba8(img.to_rgba8()),
        DynamicImage::ImageRgb32F(img.to_rgb32f()),
    ];
    for alt in fallbacks.iter().filter(|a| a.color() != img.color()) {
        match encode(alt) {
            Err(image::ImageError::Unsupported(_)) => continue,
            other => return other,
        }
    }
    Err(first)
}

/// Binary PGM (P5) for grey images, binary PPM (P6) for the others.
fn encode_pnm(img: &DynamicImage) -> image::ImageResult<Vec<u8>> {
    use image::codecs::pnm::{PnmEncoder, PnmSubtype, SampleEncoding};
    use image::{ExtendedColorType, ImageEncoder};
    let (raw, subtype, color) = if img.color().channel_count() == 1 {
        let g = img.to_luma8().into_raw();
        (
            g,
            PnmSubtype::Graymap(SampleEncoding::Binary),
            ExtendedColorType::L8,
        )
    } else {
        let c = img.to_rgb8().into_raw();
        (
            c,
            PnmSubtype::Pixmap(SampleEncoding::Binary),
            ExtendedColorType::Rgb8,
        )
    };
    let mut buf = Vec::new();
    PnmEncoder::new(&mut buf)
        .with_subtype(subtype)
        .write_image(&raw, img.width(), img.height(), color)?;
    Ok(buf)
}

/// Writes `rgba8` (`width * height * 4` bytes, row-major RGBA) atomically as a grey
/// (`channels == 1`, the R channel), RGB (3) or RGBA (4) image. The format comes from the
/// extension (see [`SUPPORTED_SAVE_EXTENSIONS`]; no extension: PNG); formats that lack
/// the requested layout get the nearest one the encoder supports (JPEG drops alpha,
/// HDR/EXR are written as float, `.pgm` is always grey (luminance), `.ppm` always RGB
/// and `.pnm` grey or RGB (binary P5/P6); `.pam` keeps alpha).
pub fn save_image_atomic(
    path: &Path,
    width: u32,
    height: u32,
    channels: u32,
    rgba8: &[u8],
) -> Result<()> {
    let bytes = encode_image(path, width, height, channels, rgba8)?;
    write_files_atomic(&[(path, &bytes)])
}

/// The file [`save_image_atomic`] writes, encoded in memory (to write several outputs
/// all or nothing with [`write_files_atomic`]).
pub fn encode_image(
    path: &Path,
    width: u32,
    height: u32,
    channels: u32,
    rgba8: &[u8],
) -> Result<Vec<u8>> {
    let format = save_format(path)?;
    check_buffer(width, height, 4, rgba8.len(), "the RGBA8 buffer")?;
    let img = match channels {
        1 => {
            let grey: Vec<u8> = rgba8.chunks_exact(4).map(|p| p[0]).collect();
            DynamicImage::ImageLuma8(image::GrayImage::from_raw(width, height, grey).unwrap())
        }
        2 => {
            let la: Vec<u8> = rgba8.chunks_exact(4).flat_map(|p| [p[0], p[3]]).collect();
            DynamicImage::ImageLumaA8(image::GrayAlphaImage::from_raw(width, height, la).unwrap())
        }
        3 => {
            let rgb: Vec<u8> = rgba8
                .chunks_exact(4)
                .flat_map(|p| [p[0], p[1], p[2]])
                .collect();
            DynamicImage::ImageRgb8(image::RgbImage::from_raw(width, height, rgb).unwrap())
        }
        4 => DynamicImage::ImageRgba8(
            image::RgbaImage::from_raw(width, height, rgba8.to_vec()).unwrap(),
        ),
        c => {
            return Err(Error::InvalidParameter(format!(
                "cannot write {}: {c} channels requested; use 1 (grey), 2 (grey + alpha), 3 (RGB) or 4 (RGBA)",
                path.display()
            )))
        }
    };
    // The PNM family shares one `ImageFormat`; honour the specific extensions.
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    let img = match ext.as_deref() {
        Some("pgm") if channels != 1 => DynamicImage::ImageLuma8(img.to_luma8()),
        Some("ppm") if channels != 3 => DynamicImage::ImageRgb8(img.to_rgb8()),
        _ => img,
    };
    match ext.as_deref() {
        // The PNM encoder writes PAM (P7) unless told a subtype; P5/P6 are what .pnm,
        // .pgm and .ppm readers expect (alpha is dropped, as for JPEG).
        Some("pnm" | "pgm" | "ppm") => encode_pnm(&img),
        _ => encode_with_fallback(&img, format),
    }
    .map_err(|e| encode_err(path, e))
}
