//! Coordinate maps: synthesized exemplar coordinates as a 32-bit float OpenEXR
//! (R = x, G = y, B = 0), written and read back.

use std::io::Cursor;
use std::path::Path;

use image::{DynamicImage, ImageFormat};

use super::atomic::write_files_atomic;
use super::decode::{decode_image, open_image_exr_channels};
use super::write::{check_buffer, encode_err};
use crate::error::{Error, Result};

/// Writes synthesized exemplar coordinates atomically as a 32-bit float RGB OpenEXR
/// (whatever the extension): R = x, G = y, B = 0. Exact for |coordinate| < 2^24.
pub fn save_coords_exr_atomic(
    path: &Path,
    width: u32,
    height: u32,
    coords: &[[i32; 2]],
) -> Result<()> {
    check_buffer(width, height, 1, coords.len(), "the coordinate map")?;
    let f: Vec<[f32; 2]> = coords.iter().map(|c| [c[0] as f32, c[1] as f32]).collect();
    save_coords_exr_f32_atomic(path, width, height, &f)
}

/// [`save_coords_exr_atomic`] for continuous coordinates (anisometric synthesis), in
/// exemplar pixels.
pub fn save_coords_exr_f32_atomic(
    path: &Path,
    width: u32,
    height: u32,
    coords: &[[f32; 2]],
) -> Result<()> {
    let bytes = encode_coords_exr_f32(path, width, height, coords)?;
    write_files_atomic(&[(path, &bytes)])
}

/// The file [`save_coords_exr_f32_atomic`] writes, encoded in memory.
pub fn encode_coords_exr_f32(
    path: &Path,
    width: u32,
    height: u32,
    coords: &[[f32; 2]],
) -> Result<Vec<u8>> {
    check_buffer(width, height, 1, coords.len(), "the coordinate map")?;
    let data: Vec<f32> = coords.iter().flat_map(|c| [c[0], c[1], 0.0]).collect();
    let img = image::Rgb32FImage::from_raw(width, height, data).unwrap();
    let mut buf = Cursor::new(Vec::new());
    DynamicImage::ImageRgb32F(img)
        .write_to(&mut buf, ImageFormat::OpenExr)
        .map_err(|e| encode_err(path, e))?;
    Ok(buf.into_inner())
}

/// Reads a coordinate map as floats (exemplar pixels, not rounded): `(width, height,
/// coords)`. Same checks as [`load_coords_exr`].
pub fn load_coords_exr_f32(path: &Path) -> Result<(u32, u32, Vec<[f32; 2]>)> {
    // The decoder's own message (e.g. for a 4-channel XYZW EXR) does not say what is
    // expected.
    let (img, exr_channels) = open_image_exr_channels(path).map_err(|e| match e {
        Error::BadImage { path, reason } => Error::BadImage {
            path,
            reason: format!(
                "{reason}; a coordinate map is an RGB or RGBA float EXR (R = x, G = y), as \
                 --coords-out writes, or a 2-channel float EXR (R, G or e.g. X, Y)"
            ),
        },
        other => other,
    })?;
    let bad = |reason: String| Error::BadImage {
        path: path.to_path_buf(),
        reason,
    };
    if exr_channels == Some(1) {
        return Err(bad(
            "a 1-channel EXR holds one value per pixel; a coordinate map needs two (x, y), as \
             --coords-out writes"
                .into(),
        ));
    }
    let (width, height) = (img.width(), img.height());
    let pixels: Vec<[f32; 2]> = match &img {
        DynamicImage::ImageRgb32F(b) => b.pixels().map(|p| [p.0[0], p.0[1]]).collect(),
        DynamicImage::ImageRgba32F(b) => b.pixels().map(|p| [p.0[0], p.0[1]]).collect(),
        other => {
            return Err(bad(format!(
                "not a float coordinate map (pixel type {:?}); write one with --coords-out",
                other.color()
            )))
        }
    };
    if let Some(i) = pixels
        .iter()
        .position(|c| !c.iter().all(|v| v.is_finite() && v.abs() <= 1e9))
    {
        return Err(bad(format!(
            "pixel {i} holds {:?}, not a valid exemplar coordinate",
            pixels[i]
        )));
    }
    Ok((width, height, pixels))
}

/// Reads a coordinate map written by [`save_coords_exr_atomic`] (any float RGB/RGBA image
/// the `image` crate reads, or a 2-channel float EXR, see
/// [`open_image`](super::open_image)): returns `(width, height, coords)` with R and G
/// rounded to the nearest integer. Non-float images and non-finite or out-of-range values
/// are [`Error::BadImage`].
pub fn load_coords_exr(path: &Path) -> Result<(u32, u32, Vec<[i32; 2]>)> {
    let img = decode_image(path)?;
    let bad = |reason: String| Error::BadImage {
        path: path.to_path_buf(),
        reason,
    };
    let (width, height) = (img.width(), img.height());
    let mut out = Vec::with_capacity(width as usize * height as usize);
    let mut push = |x: f32, y: f32| -> Result<()> {
        let ok = |v: f32| v.is_finite() && v.abs() <= i32::MAX as f32 / 2.0;
        if !ok(x) || !ok(y) {
            return Err(bad(format!(
                "pixel {} holds ({x}, {y}), not a valid exemplar coordinate",
                out.len()
            )));
        }
        out.push([x.round() as i32, y.round() as i32]);
        Ok(())
    };
    match &img {
        DynamicImage::ImageRgb32F(b) => {
            for p in b.pixels() {
                push(p.0[0], p.0[1])?;
            }
        }
        DynamicImage::ImageRgba32F(b) => {
            for p in b.pixels() {
                push(p.0[0], p.0[1])?;
            }
        }
        other => {
            return Err(bad(format!(
                "not a float coordinate map (pixel type {:?}); write one with --coords-out",
                other.color()
            )))
        }
    }
    Ok((width, height, out))
}
