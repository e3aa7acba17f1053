//! Exemplars from image files: the conversion of decoded pixels (any bit depth, grey or
//! colour, alpha ignored) to an [`Exemplar`], and box-filtered downsampling for
//! magnification.

use std::path::Path;

use image::{DynamicImage, ImageBuffer, Pixel};

use super::decode::{decode_any, Decoded};
use super::exr::FewChannelExr;
use crate::analysis::{check_exemplar_size, Exemplar};
use crate::error::{Error, Result};

/// Loads an exemplar from any image file the `image` crate can decode. The format is
/// detected from the file's content (falling back on the extension).
///
/// * `channels` is 1 for grey and grey+alpha images, 3 otherwise (alpha is ignored).
///   A 1-channel OpenEXR is grey; a 2-channel OpenEXR is grey + alpha when one of its
///   channels is alpha (`A`; the other is the luminance), and is refused otherwise (two
///   channels such as `R`, `G` or `U`, `V` are a field, not a picture).
/// * `values` keep the full source precision (16-bit samples are divided by 65535, not
///   first reduced to 8 bits); float samples (HDR, EXR) must be finite, at most 1% of
///   them outside [0, 1] (more is an HDR image: an error), and are clamped to [0, 1].
/// * `colors` are RGBA8 with grey replicated into RGB and alpha always 255.
///
/// Errors: a missing or unreadable file is [`Error::Io`]; an empty, non-image, truncated
/// or corrupt file is [`Error::BadImage`] with the decoder's reason; an image smaller than
/// [`crate::analysis::MIN_EXEMPLAR_SIZE`] on either side is [`Error::ExemplarTooSmall`].
pub fn load_exemplar(path: &Path) -> Result<Exemplar> {
    match decode_any(path)? {
        Decoded::Image(img) => exemplar_from(&img, Some(path)),
        Decoded::Exr(exr) => exemplar_from_exr(&exr, path),
    }
}

/// Builds an [`Exemplar`] from an already decoded image (see [`load_exemplar`] for the
/// conversion rules). Fails with [`Error::ExemplarTooSmall`] for images below the minimum
/// size.
pub fn exemplar_from_image(img: &DynamicImage) -> Result<Exemplar> {
    exemplar_from(img, None)
}

fn exemplar_from(img: &DynamicImage, path: Option<&Path>) -> Result<Exemplar> {
    let bad_floats = |reason: String| {
        let what = path.map_or("exemplar".into(), |p| p.display().to_string());
        Error::InvalidParameter(format!("{what}: {reason}"))
    };
    let (width, height) = (img.width(), img.height());
    check_exemplar_size(width, height)?;
    let n = width as usize * height as usize;

    let mut colors: Vec<[u8; 4]> = Vec::with_capacity(n);
    let (channels, values): (u32, Vec<f32>) = match img {
        DynamicImage::ImageLuma8(b) => (1, samples(b, n, &mut colors, push_grey8)),
        DynamicImage::ImageLumaA8(b) => (1, samples(b, n, &mut colors, push_grey8)),
        DynamicImage::ImageLuma16(b) => (1, samples(b, n, &mut colors, push_grey16)),
        DynamicImage::ImageLumaA16(b) => (1, samples(b, n, &mut colors, push_grey16)),
        DynamicImage::ImageRgb8(b) => (3, samples(b, n, &mut colors, push_rgb8)),
        DynamicImage::ImageRgba8(b) => (3, samples(b, n, &mut colors, push_rgb8)),
        DynamicImage::ImageRgb16(b) => (3, samples(b, n, &mut colors, push_rgb16)),
        DynamicImage::ImageRgba16(b) => (3, samples(b, n, &mut colors, push_rgb16)),
        DynamicImage::ImageRgb32F(b) => (3, float_samples(b, n, &mut colors).map_err(bad_floats)?),
        DynamicImage::ImageRgba32F(b) => (3, float_samples(b, n, &mut colors).map_err(bad_floats)?),
        // `DynamicImage` is non-exhaustive: anything new goes through float RGB.
        other => {
            let b = other.to_rgb32f();
            (3, float_samples(&b, n, &mut colors).map_err(bad_floats)?)
        }
    };

    Ok(Exemplar {
        width,
        height,
        channels,
        values,
        colors,
    })
}

/// Float exemplars (EXR, HDR) are display colours in [0, 1]: a NaN or infinite sample is
/// an error, and so is an image with more than 1% of its samples outside [0, 1] (an HDR
/// image, which clamping would wash out); the rest is clamped.
fn check_float_samples(
    pixels: impl Iterator<Item = [f32; 3]>,
    width: u32,
) -> std::result::Result<(), String> {
    let (mut outside, mut total) = (0usize, 0usize);
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for (i, p) in pixels.enumerate() {
        for v in p {
            if !v.is_finite() {
                return Err(format!(
                    "pixel ({}, {}) is NaN or infinite; texsyn needs finite colours",
                    i as u32 % width.max(1),
                    i as u32 / width.max(1)
                ));
            }
            if !(-1.0 / 255.0..=1.0 + 1.0 / 255.0).contains(&v) {
                outside += 1;
                lo = lo.min(v);
                hi = hi.max(v);
            }
            total += 1;
        }
    }
    if outside * 100 > total {
        return Err(format!(
            "{:.1}% of the samples lie outside [0, 1] ({}): texsyn works on display \
             colours in [0, 1]; tone-map or rescale the image first (e.g. save it as a PNG)",
            outside as f64 * 100.0 / total as f64,
            match (lo < 0.0, hi > 1.0) {
                (true, true) => format!("from {lo} to {hi}"),
                (true, false) => format!("down to {lo}"),
                _ => format!("up to {hi}"),
            }
        ));
    }
    Ok(())
}

pub(super) fn grey8(v: u8) -> [u8; 4] {
    [v, v, v, 255]
}

/// 16-bit to 8-bit with rounding (exact for values that came from 8 bits: v * 257).
fn u16_to_u8(v: u16) -> u8 {
    ((v as u32 * 255 + 32767) / 65535) as u8
}

pub(super) fn f32_to_unit(v: f32) -> f32 {
    // NaN fails both comparisons of `clamp`'s contract, so handle it first.
    if v.is_nan() {
        0.0
    } else {
        v.clamp(0.0, 1.0)
    }
}

/// An exemplar's values (`C` per pixel, `C * n` reserved) and colours from the first
/// `C` channels of every pixel of `b` (grey or RGB; alpha, where there is one, is
/// ignored), converted by `push`: one loop for all the buffer types `exemplar_from`
/// reads, with alpha or without.
fn samples<P: Pixel, const C: usize>(
    b: &ImageBuffer<P, Vec<P::Subpixel>>,
    n: usize,
    colors: &mut Vec<[u8; 4]>,
    mut push: impl FnMut(&mut Vec<f32>, &mut Vec<[u8; 4]>, [P::Subpixel; C]),
) -> Vec<f32> {
    let mut values = Vec::with_capacity(C * n);
    for p in b.pixels() {
        push(&mut values, colors, leading(p));
    }
    values
}

/// The first `C` channels of `p`.
fn leading<P: Pixel, const C: usize>(p: &P) -> [P::Subpixel; C] {
    std::array::from_fn(|i| p.channels()[i])
}

/// [`samples`] of a float RGB or RGBA buffer, after [`check_float_samples`] (the
/// reason of a refusal is returned for the caller to name the file).
fn float_samples<P: Pixel<Subpixel = f32>>(
    b: &ImageBuffer<P, Vec<f32>>,
    n: usize,
    colors: &mut Vec<[u8; 4]>,
) -> std::result::Result<Vec<f32>, String> {
    check_float_samples(b.pixels().map(leading), b.width())?;
    Ok(samples(b, n, colors, push_rgbf))
}

fn push_grey8(values: &mut Vec<f32>, colors: &mut Vec<[u8; 4]>, [v]: [u8; 1]) {
    values.push(v as f32 / 255.0);
    colors.push(grey8(v));
}

fn push_grey16(values: &mut Vec<f32>, colors: &mut Vec<[u8; 4]>, [v]: [u16; 1]) {
    values.push(v as f32 / 65535.0);
    colors.push(grey8(u16_to_u8(v)));
}

fn push_rgb8(values: &mut Vec<f32>, colors: &mut Vec<[u8; 4]>, c: [u8; 3]) {
    values.extend(c.iter().map(|&v| v as f32 / 255.0));
    colors.push([c[0], c[1], c[2], 255]);
}

fn push_rgb16(values: &mut Vec<f32>, colors: &mut Vec<[u8; 4]>, c: [u16; 3]) {
    values.extend(c.iter().map(|&v| v as f32 / 65535.0));
    colors.push([u16_to_u8(c[0]), u16_to_u8(c[1]), u16_to_u8(c[2]), 255]);
}

fn push_rgbf(values: &mut Vec<f32>, colors: &mut Vec<[u8; 4]>, c: [f32; 3]) {
    let c = c.map(f32_to_unit);
    values.extend_from_slice(&c);
    let q = c.map(|v| (v * 255.0).round() as u8);
    colors.push([q[0], q[1], q[2], 255]);
}

/// A grey exemplar from a 1-channel, or a grey + alpha 2-channel, OpenEXR (same float
/// rules as [`exemplar_from_image`]); other 2-channel EXRs are refused.
fn exemplar_from_exr(exr: &FewChannelExr, path: &Path) -> Result<Exemplar> {
    if exr.channels() == 2 && !exr.alpha {
        return Err(Error::BadImage {
            path: path.to_path_buf(),
            reason: format!(
                "a 2-channel OpenEXR ({}) is a two-value field (flow, coordinates...), not a \
                 picture; an exemplar needs grey (1 channel), grey + alpha (e.g. Y, A), RGB \
                 or RGBA channels",
                exr.names.join(", ")
            ),
        });
    }
    let (width, height) = (exr.width, exr.height);
    check_exemplar_size(width, height)?;
    let c = exr.channels();
    let luma = || exr.data.iter().step_by(c).copied();
    check_float_samples(luma().map(|v| [v; 3]), width)
        .map_err(|reason| Error::InvalidParameter(format!("{}: {reason}", path.display())))?;
    let values: Vec<f32> = luma().map(f32_to_unit).collect();
    let colors = values
        .iter()
        .map(|&v| grey8((v * 255.0).round() as u8))
        .collect();
    Ok(Exemplar {
        width,
        height,
        channels: 1,
        values,
        colors,
    })
}

/// Box-filters an exemplar down by an integer factor (cropping to a multiple of it):
/// the analysed exemplar of magnification, whose colours come from the full one.
/// Returns the small exemplar and the full one's colours cropped to `factor` times it.
pub fn downsample_exemplar(ex: &Exemplar, factor: u32) -> Result<(Exemplar, Vec<[u8; 4]>)> {
    ex.check()?;
    if !(1..=64).contains(&factor) {
        return Err(Error::InvalidParameter(format!(
            "downsampling factor {factor}: use 1 to 64"
        )));
    }
    let (w, h) = (ex.width / factor.max(1), ex.height / factor.max(1));
    if factor == 0
        || w < crate::analysis::MIN_EXEMPLAR_SIZE
        || h < crate::analysis::MIN_EXEMPLAR_SIZE
    {
        return Err(Error::InvalidParameter(format!(
            "magnifying {factor}x needs an exemplar of at least {} pixels a side (it is {}x{}); \
             use a larger exemplar or a smaller factor",
            crate::analysis::MIN_EXEMPLAR_SIZE * factor.max(1),
            ex.width,
            ex.height
        )));
    }
    let c = ex.channels as usize;
    let f = factor as usize;
    let n = (f * f) as f32;
    let mut values = Vec::with_capacity(w as usize * h as usize * c);
    let mut colors = Vec::with_capacity(w as usize * h as usize);
    for y in 0..h as usize {
        for x in 0..w as usize {
            let mut v = vec![0f32; c];
            let mut col = [0u32; 4];
            for dy in 0..f {
                for dx in 0..f {
                    let i = (y * f + dy) * ex.width as usize + x * f + dx;
                    for (s, x) in v.iter_mut().zip(&ex.values[i * c..(i + 1) * c]) {
                        *s += x;
                    }
                    for (s, x) in col.iter_mut().zip(ex.colors[i]) {
                        *s += x as u32;
                    }
                }
            }
            values.extend(v.iter().map(|s| s / n));
            let half = (f * f / 2) as u32;
            colors.push(col.map(|s| ((s + half) / (f * f) as u32) as u8));
        }
    }
    let mut hi = Vec::with_capacity(w as usize * h as usize * f * f);
    for y in 0..h as usize * f {
        let row = y * ex.width as usize;
        hi.extend_from_slice(&ex.colors[row..row + w as usize * f]);
    }
    Ok((
        Exemplar {
            width: w,
            height: h,
            channels: ex.channels,
            values,
            colors,
        },
        hi,
    ))
}
