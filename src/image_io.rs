//! Files: loading exemplars, writing output images and coordinate maps, and the atomic
//! writer everything that texsyn writes goes through.
//!
//! * [`load_exemplar`] / [`exemplar_from_image`]: any format the `image` crate reads
//!   (PNG, JPEG, BMP, TGA, TIFF, WebP, GIF, PNM, HDR, OpenEXR), chosen by the file's
//!   content (the extension is only a fallback, e.g. for TGA, which has no signature).
//!   8-bit, 16-bit and float samples; grey, grey+alpha, RGB and RGBA. **Alpha is ignored**:
//!   grey and grey+alpha exemplars have 1 channel, everything else 3.
//! * 1- and 2-channel OpenEXRs, which the `image` crate refuses, are read with the `exr`
//!   crate (see [`open_image`] for the channel rule): a 1-channel EXR (`Y`, or any single
//!   channel) is a grey exemplar; a 2-channel one is grey + alpha when one channel is
//!   alpha (`A`), and a two-value field (flow, coordinate map, `R`/`G`) otherwise.
//! * [`write_atomic`]: write to a temporary file next to the target, fsync, rename over
//!   the target. A failed or interrupted write never leaves a partial file at the target.
//! * [`save_image_atomic`]: RGBA8 pixels to grey / RGB / RGBA in the format named by the
//!   extension.
//! * [`save_coords_exr_atomic`] / [`load_coords_exr`]: the synthesized exemplar
//!   coordinates as a 32-bit float OpenEXR (R = x, G = y, B = 0); a 2-channel (`R`, `G`)
//!   float EXR is read as well.

use std::ffi::OsString;
use std::fs::{self, File, OpenOptions};
use std::io::{BufReader, BufWriter, Cursor, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use image::{DynamicImage, ImageBuffer, ImageFormat, Pixel};

use crate::analysis::{check_exemplar_size, Exemplar};
use crate::error::{Error, Result};

// ---------------------------------------------------------------------------------------
// Loading exemplars
// ---------------------------------------------------------------------------------------

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

/// A material map (`--also`): its size, its channel count as stored (1 grey, 2 grey +
/// alpha, 3 RGB, 4 RGBA) and its pixels as RGBA8 (grey replicated into RGB; alpha kept,
/// 255 where there is none). Unlike [`load_exemplar`], alpha is data here (opacity,
/// packed roughness...), so it is resynthesized and written back. A 1-channel OpenEXR is
/// grey, a 2-channel one with an alpha (`A`) channel grey + alpha, any other 2-channel one
/// RGB with the two channels in R and G and B = 0 (floats clamped to [0, 1]).
pub fn load_material_map(path: &Path) -> Result<(u32, u32, u32, Vec<[u8; 4]>)> {
    let img = match decode_any(path)? {
        Decoded::Image(img) => {
            check_finite(&img, path, "material map")?;
            img
        }
        Decoded::Exr(exr) if exr.channels() == 1 || exr.alpha => {
            check_finite_samples(&exr.data, exr.channels(), exr.width, path, "material map")?;
            let to8 = |v: f32| (f32_to_unit(v) * 255.0).round() as u8;
            let pixels = if exr.channels() == 1 {
                exr.data.iter().map(|&v| grey8(to8(v))).collect()
            } else {
                exr.data
                    .chunks_exact(2)
                    .map(|p| {
                        let g = to8(p[0]);
                        [g, g, g, to8(p[1])]
                    })
                    .collect()
            };
            return Ok((exr.width, exr.height, exr.channels() as u32, pixels));
        }
        Decoded::Exr(exr) => {
            check_finite_samples(&exr.data, exr.channels(), exr.width, path, "material map")?;
            exr.to_image()
        }
    };
    let channels = img.color().channel_count() as u32;
    let pixels = img.to_rgba8().pixels().map(|p| p.0).collect();
    Ok((img.width(), img.height(), channels.clamp(1, 4), pixels))
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
fn check_finite_samples(
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

fn grey8(v: u8) -> [u8; 4] {
    [v, v, v, 255]
}

/// 16-bit to 8-bit with rounding (exact for values that came from 8 bits: v * 257).
fn u16_to_u8(v: u16) -> u8 {
    ((v as u32 * 255 + 32767) / 65535) as u8
}

fn f32_to_unit(v: f32) -> f32 {
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

fn decode_image(path: &Path) -> Result<DynamicImage> {
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
enum Decoded {
    Image(DynamicImage),
    Exr(FewChannelExr),
}

/// A 1- or 2-channel OpenEXR read with the `exr` crate (see [`open_image`]).
struct FewChannelExr {
    width: u32,
    height: u32,
    /// The channel names, in the order of `data` (see [`open_image`] for the rule).
    names: Vec<String>,
    /// 2 channels, the second of which is alpha.
    alpha: bool,
    /// Row-major, `names.len()` interleaved samples per pixel, 0 outside the data window.
    data: Vec<f32>,
}

impl FewChannelExr {
    fn channels(&self) -> usize {
        self.names.len()
    }

    /// Float RGB: `(v, v, v)` for 1 channel, `(a, b, 0)` for 2.
    fn to_image(&self) -> DynamicImage {
        let rgb: Vec<f32> = if self.channels() == 1 {
            self.data.iter().flat_map(|&v| [v; 3]).collect()
        } else {
            self.data
                .chunks_exact(2)
                .flat_map(|p| [p[0], p[1], 0.0])
                .collect()
        };
        DynamicImage::ImageRgb32F(
            image::Rgb32FImage::from_raw(self.width, self.height, rgb)
                .expect("buffer sized for the image"),
        )
    }
}

/// The most bytes a 1- or 2-channel EXR may take to decode (the `image` crate's default
/// allocation limit).
const MAX_EXR_ALLOC: u64 = 512 * 1024 * 1024;

/// The last `.`-separated part of an EXR channel name (`diffuse.R` -> `R`).
fn channel_base(name: &str) -> &str {
    name.rsplit('.').next().unwrap_or(name)
}

/// Runs `f` (exr crate code on untrusted input), turning a panic into an error message.
fn no_panic<T>(
    f: impl FnOnce() -> std::result::Result<T, String>,
) -> std::result::Result<T, String> {
    crate::error::catch_quietly(f)
        .unwrap_or_else(|()| Err("the OpenEXR decoder failed on this file (corrupt data)".into()))
}

/// Channel names of the first non-deep layer of an EXR, or `None` when its header cannot
/// be read.
fn exr_channel_names(path: &Path) -> Option<Vec<String>> {
    no_panic(|| {
        let file = open_regular(path).map_err(|e| e.to_string())?;
        let meta = exr::meta::MetaData::read_from_buffered(BufReader::new(file), false)
            .map_err(|e| e.to_string())?;
        let header = meta.headers.iter().find(|h| !h.deep).ok_or("")?;
        Ok(header
            .channels
            .list
            .iter()
            .map(|c| c.name.to_string())
            .collect())
    })
    .ok()
}

/// Reads a 1- or 2-channel EXR (see [`open_image`]); errors are the reason, in words.
fn read_few_channel_exr(path: &Path) -> std::result::Result<FewChannelExr, String> {
    use exr::prelude::traits::*;
    let exr_err = |e: exr::error::Error| match e {
        exr::error::Error::Io(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            format!("the file is truncated ({io})")
        }
        // What the exr crate says when a chunk lies past the end of the file.
        exr::error::Error::Invalid(m) if m.contains("missing bytes") => {
            format!("the file is truncated or corrupt ({m})")
        }
        e => e.to_string(),
    };
    let open = || {
        open_regular(path)
            .map(BufReader::new)
            .map_err(|e| e.to_string())
    };
    no_panic(|| {
        // Size check before any pixel buffer is allocated.
        let meta = exr::meta::MetaData::read_from_buffered(open()?, false).map_err(exr_err)?;
        let header = meta
            .headers
            .iter()
            .find(|h| !h.deep)
            .ok_or("the OpenEXR holds only deep data, which texsyn does not read")?;
        if header
            .channels
            .list
            .iter()
            .any(|c| c.sampling != exr::math::Vec2(1, 1))
        {
            return Err("subsampled OpenEXR channels are not supported".into());
        }
        let display = header.shared_attributes.display_window;
        let data_bytes = header.layer_size.area() as u128 * header.channels.bytes_per_pixel as u128;
        let out_bytes = display.size.area() as u128 * 12;
        if data_bytes + out_bytes > MAX_EXR_ALLOC as u128 {
            return Err(format!(
                "the {}x{} OpenEXR needs more than {} MiB to decode",
                display.size.width(),
                display.size.height(),
                MAX_EXR_ALLOC >> 20
            ));
        }

        let img = exr::prelude::read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .first_valid_layer()
            .all_attributes()
            .non_parallel()
            .from_buffered(open()?)
            .map_err(exr_err)?;
        let layer = &img.layer_data;
        let display = img.attributes.display_window;
        let (w, h) = (display.size.width(), display.size.height());
        if w == 0 || h == 0 || w > u32::MAX as usize || h > u32::MAX as usize {
            return Err(format!("the OpenEXR's display window is {w}x{h}"));
        }
        let list = &layer.channel_data.list;
        let mut order: Vec<usize> = (0..list.len()).collect();
        order.sort_by(|&a, &b| list[a].name.to_string().cmp(&list[b].name.to_string()));
        let base = |i: usize| channel_base(&list[i].name.to_string()).to_ascii_uppercase();
        let mut alpha = false;
        match order.len() {
            1 => {}
            2 => {
                let (b0, b1) = (base(order[0]), base(order[1]));
                if b0 == "G" && b1 == "R" {
                    order.swap(0, 1);
                } else if b0 == "A" && b1 != "A" {
                    order.swap(0, 1);
                    alpha = true;
                } else if b1 == "A" && b0 != "A" {
                    alpha = true;
                }
            }
            n => return Err(format!("expected 1 or 2 channels, the layer has {n}")),
        }
        let (lw, lh) = (layer.size.width(), layer.size.height());
        if order.iter().any(|&i| list[i].sample_data.len() != lw * lh) {
            return Err("a channel holds the wrong number of samples (corrupt file)".into());
        }
        let c = order.len();
        let mut data = vec![0f32; w * h * c];
        // Data window pixel (x, y) is display pixel (x + dx, y + dy).
        let dx = layer.attributes.layer_position.x() as i64 - display.position.x() as i64;
        let dy = layer.attributes.layer_position.y() as i64 - display.position.y() as i64;
        for y in 0..lh {
            let ty = y as i64 + dy;
            if ty < 0 || ty >= h as i64 {
                continue;
            }
            for x in 0..lw {
                let tx = x as i64 + dx;
                if tx < 0 || tx >= w as i64 {
                    continue;
                }
                let to = (ty as usize * w + tx as usize) * c;
                for (k, &ch) in order.iter().enumerate() {
                    data[to + k] = list[ch]
                        .sample_data
                        .value_by_flat_index(y * lw + x)
                        .to_f32();
                }
            }
        }
        Ok(FewChannelExr {
            width: w as u32,
            height: h as u32,
            names: order.iter().map(|&i| list[i].name.to_string()).collect(),
            alpha,
            data,
        })
    })
}

fn decode_any(path: &Path) -> Result<Decoded> {
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
        let analysis = crate::session::is_analysis_file(path).unwrap_or(false);
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

/// Opens `path` for reading if it is a regular file. The type is checked before the
/// open, since opening a named pipe blocks until something writes to it; a device such as
/// `/dev/zero` could fill the memory. The error says what the path is instead.
pub fn open_regular(path: &Path) -> std::io::Result<File> {
    let meta = fs::metadata(path)?;
    if meta.is_dir() {
        return Err(std::io::Error::other("it is a directory, not a file"));
    }
    if !meta.is_file() {
        return Err(std::io::Error::other(
            "it is not a regular file (a device or a pipe); give a file",
        ));
    }
    File::open(path)
}

/// Reads the whole file at `path`, refusing files of more than `max` bytes and anything
/// that is not a regular file (a device such as `/dev/zero` or a pipe could fill the
/// memory). Errors are [`Error::Io`] naming `path`; `what` names the input in the
/// message.
pub fn read_file_capped(path: &Path, max: u64, what: &str) -> Result<Vec<u8>> {
    use std::io::Read;
    let io = |source| Error::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = open_regular(path).map_err(io)?;
    let meta = file.metadata().map_err(io)?;
    let too_large = |n: u64| {
        io(std::io::Error::other(format!(
            "{} MiB; texsyn reads {what} of at most {} MiB",
            n >> 20,
            max >> 20
        )))
    };
    if meta.len() > max {
        return Err(too_large(meta.len()));
    }
    let mut bytes = Vec::new();
    file.take(max + 1).read_to_end(&mut bytes).map_err(io)?;
    if bytes.len() as u64 > max {
        // It grew while it was read.
        return Err(too_large(bytes.len() as u64));
    }
    Ok(bytes)
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

/// The most bytes a mesh file (or one of its external buffers) may have.
pub const MAX_MESH_FILE_BYTES: u64 = 2 << 30;

// ---------------------------------------------------------------------------------------
// Atomic writes
// ---------------------------------------------------------------------------------------

static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Removes the temporary file on drop unless disarmed (covers errors and panics in the
/// caller's closure). While armed, the file is listed in [`PENDING_OUTPUTS`], so that an
/// interrupted run can remove it too ([`remove_pending_outputs`]).
struct TempGuard {
    path: PathBuf,
    armed: bool,
}

impl TempGuard {
    fn disarm(&mut self) {
        self.armed = false;
        forget_pending_output(&self.path);
    }
}

impl Drop for TempGuard {
    fn drop(&mut self) {
        if self.armed {
            let _ = fs::remove_file(&self.path);
            forget_pending_output(&self.path);
        }
    }
}

/// Temporary files and staging folders of outputs not yet committed (`true`: a folder).
static PENDING_OUTPUTS: std::sync::Mutex<Vec<(PathBuf, bool)>> = std::sync::Mutex::new(Vec::new());

/// Lists `path` (a temporary file, or a staging folder when `dir`) as an output in
/// progress: [`remove_pending_outputs`] removes it unless [`forget_pending_output`] was
/// called first. Destructors clean up after errors and panics; this is for a process
/// that is interrupted (Ctrl-C, `kill`), where no destructor runs.
pub fn register_pending_output(path: &Path, dir: bool) {
    let mut p = PENDING_OUTPUTS.lock().unwrap_or_else(|e| e.into_inner());
    p.push((path.to_path_buf(), dir));
}

/// The output at `path` was committed or removed: no longer listed.
pub fn forget_pending_output(path: &Path) {
    let mut p = PENDING_OUTPUTS.lock().unwrap_or_else(|e| e.into_inner());
    p.retain(|(q, _)| q != path);
}

/// Removes every output in progress (temporary files, staging folders), for a process
/// about to exit on a signal. Targets are never touched: they hold either the previous
/// file or a complete new one. Returns how many were removed.
pub fn remove_pending_outputs() -> usize {
    let p = PENDING_OUTPUTS.lock().unwrap_or_else(|e| e.into_inner());
    p.iter()
        .filter(|(path, dir)| {
            if *dir {
                fs::remove_dir_all(path).is_ok()
            } else {
                fs::remove_file(path).is_ok()
            }
        })
        .count()
}

/// Writes a file atomically: `write` fills a temporary file `.{filename}.{pid}.{n}.tmp` in
/// the target's directory, which is then flushed, fsynced and renamed over `path` (and
/// the directory is fsynced, best effort). On any error, or if `write` panics, the
/// temporary file is removed and `path` is left untouched: it never holds a partial file.
///
/// All failures are [`Error::Write`] naming `path` (an error returned by `write` that is
/// already an `Error::Write` is passed through unchanged; other errors are wrapped).
/// A symlink at `path` is followed: the file it points to is replaced. The new file gets
/// default permissions. A `path` that is not a regular file (`/dev/null`, a named pipe)
/// is written to directly, never replaced. Temporary files that a killed run left for
/// the same `path` (their process is gone) are removed.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> Result<()>,
) -> Result<()> {
    stage_file(path, write)?.commit()
}

/// A file written in full to its temporary name and fsynced, not yet renamed over its
/// target ([`stage_file`]); dropped without [`StagedFile::commit`], the temporary file is
/// removed and the target never touched.
pub struct StagedFile {
    /// `None`: the target was a stream (a device, a pipe), already written.
    temp: Option<TempGuard>,
    path: PathBuf,
    dir: PathBuf,
}

impl StagedFile {
    /// Renames the temporary file over the target (and fsyncs the directory, best
    /// effort).
    pub fn commit(mut self) -> Result<()> {
        let Some(guard) = self.temp.as_mut() else {
            return Ok(());
        };
        fs::rename(&guard.path, &self.path).map_err(|e| Error::Write {
            path: self.path.clone(),
            reason: format!("cannot rename the temporary file: {e}"),
        })?;
        guard.disarm();
        // Make the rename durable; not all platforms / file systems allow this.
        if let Ok(d) = File::open(&self.dir) {
            let _ = d.sync_all();
        }
        Ok(())
    }
}

/// Writes several files all or nothing: every one is first written to its temporary
/// name and fsynced, and only when all of them succeeded are they renamed over their
/// targets. A failure before that (disk full, a read-only directory) leaves every
/// target as it was, including those that existed before. Only a rename failing part
/// way (rare: the temporary files lie in the targets' own directories) can leave some
/// targets replaced and others not.
pub fn write_files_atomic(files: &[(&Path, &[u8])]) -> Result<()> {
    let mut staged = Vec::with_capacity(files.len());
    for &(path, bytes) in files {
        staged.push(stage_file(path, |w| {
            w.write_all(bytes).map_err(|e| Error::Write {
                path: path.to_path_buf(),
                reason: e.to_string(),
            })
        })?);
    }
    staged.into_iter().try_for_each(StagedFile::commit)
}

/// The first half of [`write_atomic`]: `write` fills the temporary file, which is
/// flushed and fsynced; [`StagedFile::commit`] renames it over `path`.
pub fn stage_file(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> Result<()>,
) -> Result<StagedFile> {
    let werr = |reason: String| Error::Write {
        path: path.to_path_buf(),
        reason,
    };
    // A link to a stream (`/dev/stdout` -> `/proc/self/fd/1` -> `pipe:[..]`, whose target
    // names no path) is written through as it is; other links are followed to the file
    // they name, which is then replaced.
    let stream = fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir());
    let resolved = if stream {
        path.to_path_buf()
    } else {
        follow_symlinks(path).map_err(werr)?
    };
    let path = resolved.as_path();

    let Some(file_name) = path.file_name() else {
        return Err(werr("the path does not name a file".into()));
    };
    if path.is_dir() {
        return Err(werr("it is a directory; give a file name".into()));
    }
    if let Ok(meta) = fs::metadata(path) {
        if !meta.is_file() {
            // A device or a pipe: a stream, not a file to replace.
            let file = OpenOptions::new()
                .write(true)
                .open(path)
                .map_err(|e| werr(format!("cannot open it for writing: {e}")))?;
            let mut w = BufWriter::new(file);
            write(&mut w).map_err(|e| match e {
                Error::Write { .. } => e,
                other => werr(other.to_string()),
            })?;
            w.into_inner().map_err(|e| werr(e.error().to_string()))?;
            return Ok(StagedFile {
                temp: None,
                path: path.to_path_buf(),
                dir: PathBuf::new(),
            });
        }
    }
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !dir.is_dir() {
        return Err(werr(if dir.exists() {
            format!("{} is not a directory", dir.display())
        } else {
            format!(
                "directory {} does not exist; create it first",
                dir.display()
            )
        }));
    }

    remove_stale_temporaries(&dir, file_name);
    let mut tmp_name = OsString::from(".");
    tmp_name.push(file_name);
    tmp_name.push(format!(
        ".{}.{}.tmp",
        std::process::id(),
        TEMP_COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let tmp_path = dir.join(tmp_name);

    // Listed before it exists, so that no interruption falls between the two.
    register_pending_output(&tmp_path, false);
    let file = OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&tmp_path)
        .map_err(|e| {
            forget_pending_output(&tmp_path);
            werr(format!(
                "cannot create a temporary file in {}: {e}",
                dir.display()
            ))
        })?;
    let guard = TempGuard {
        path: tmp_path,
        armed: true,
    };

    let mut w = BufWriter::new(file);
    write(&mut w).map_err(|e| match e {
        Error::Write { .. } => e,
        other => werr(other.to_string()),
    })?;
    let file = w.into_inner().map_err(|e| werr(e.error().to_string()))?;
    file.sync_all()
        .map_err(|e| werr(format!("fsync failed: {e}")))?;
    drop(file);
    Ok(StagedFile {
        temp: Some(guard),
        path: path.to_path_buf(),
        dir,
    })
}

/// `path` with its symlinks followed (a dangling link names the file to create).
fn follow_symlinks(path: &Path) -> std::result::Result<PathBuf, String> {
    let mut p = path.to_path_buf();
    for _ in 0..32 {
        match fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                let target = fs::read_link(&p).map_err(|e| format!("cannot read the link: {e}"))?;
                p = match p.parent() {
                    Some(dir) if target.is_relative() => dir.join(target),
                    _ => target,
                };
            }
            _ => return Ok(p),
        }
    }
    Err("too many levels of symbolic links".into())
}

/// Removes `.{file_name}.{pid}.{n}.tmp` files in `dir` whose process no longer runs
/// (left by a run that was killed while writing). Only where `/proc` tells which
/// processes run; best effort.
fn remove_stale_temporaries(dir: &Path, file_name: &std::ffi::OsStr) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let Some(name) = file_name.to_str() else {
        return;
    };
    let prefix = format!(".{name}.");
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let entry_name = entry.file_name();
        let Some(rest) = entry_name
            .to_str()
            .and_then(|n| n.strip_prefix(&prefix))
            .and_then(|n| n.strip_suffix(".tmp"))
        else {
            continue;
        };
        let Some((pid, n)) = rest.split_once('.') else {
            continue;
        };
        let (Ok(pid), Ok(_)) = (pid.parse::<u32>(), n.parse::<u64>()) else {
            continue;
        };
        if pid != std::process::id() && !Path::new(&format!("/proc/{pid}")).exists() {
            let _ = fs::remove_file(entry.path());
        }
    }
}

// ---------------------------------------------------------------------------------------
// Saving images
// ---------------------------------------------------------------------------------------

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

fn check_buffer(width: u32, height: u32, per_pixel: u64, len: usize, what: &str) -> Result<()> {
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

fn encode_err(path: &Path, e: image::ImageError) -> Error {
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

// ---------------------------------------------------------------------------------------
// Coordinate maps
// ---------------------------------------------------------------------------------------

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
/// the `image` crate reads, or a 2-channel float EXR, see [`open_image`]): returns `(width, height, coords)` with R and G rounded to the
/// nearest integer. Non-float images and non-finite or out-of-range values are
/// [`Error::BadImage`].
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
