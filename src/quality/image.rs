//! The images the figures compare: [`FloatImage`], 1 (grey) or 3 (RGB) channels of
//! `f32` in `[0, 1]`, with the conversions, crops and downsampling the figures use.
//!
//! When two images with different channel counts are compared, the grey one is
//! replicated into RGB: a grey exemplar compared with its RGB-encoded output gives the
//! same figures as grey against grey, and colour lost in a grey output is counted as an
//! error rather than hidden.

use std::borrow::Cow;

use super::common::invalid;
use crate::analysis::Exemplar;
use crate::error::Result;

/// A float image: row-major, `channels` values per pixel, values in `[0, 1]`.
#[derive(Clone, Debug, PartialEq)]
pub struct FloatImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// 1 (grey) or 3 (RGB).
    pub channels: u32,
    /// `width * height * channels` values, row-major, channels interleaved, in `[0, 1]`.
    pub data: Vec<f32>,
}

impl FloatImage {
    /// Checks the fields and builds the image.
    pub fn new(width: u32, height: u32, channels: u32, data: Vec<f32>) -> Result<Self> {
        let img = Self {
            width,
            height,
            channels,
            data,
        };
        img.validate()?;
        Ok(img)
    }

    /// Converts a decoded image: grey (with or without alpha) gives 1 channel, anything
    /// else 3; alpha is dropped. 16-bit and float precision are kept (floats clamped to
    /// `[0, 1]`).
    pub fn from_dynamic(img: &image::DynamicImage) -> Self {
        let color = img.color();
        let bytes_per_channel = color.bytes_per_pixel() / color.channel_count().max(1);
        let (width, height) = (img.width(), img.height());
        let (channels, data): (u32, Vec<f32>) = if !color.has_color() {
            if bytes_per_channel <= 1 {
                (
                    1,
                    img.to_luma8()
                        .into_raw()
                        .iter()
                        .map(|&v| v as f32 / 255.0)
                        .collect(),
                )
            } else {
                (
                    1,
                    img.to_luma16()
                        .into_raw()
                        .iter()
                        .map(|&v| v as f32 / 65535.0)
                        .collect(),
                )
            }
        } else if bytes_per_channel <= 1 {
            (
                3,
                img.to_rgb8()
                    .into_raw()
                    .iter()
                    .map(|&v| v as f32 / 255.0)
                    .collect(),
            )
        } else if bytes_per_channel == 2 {
            (
                3,
                img.to_rgb16()
                    .into_raw()
                    .iter()
                    .map(|&v| v as f32 / 65535.0)
                    .collect(),
            )
        } else {
            let clamp = |v: f32| if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
            (
                3,
                img.to_rgb32f().into_raw().into_iter().map(clamp).collect(),
            )
        };
        Self {
            width,
            height,
            channels,
            data,
        }
    }

    /// The exemplar's float channels (1 or 3).
    pub fn from_exemplar(exemplar: &Exemplar) -> Self {
        Self {
            width: exemplar.width,
            height: exemplar.height,
            channels: exemplar.channels,
            data: exemplar.values.clone(),
        }
    }

    /// RGBA8 pixels (e.g. a synthesized texture) as 3 channels; alpha dropped.
    pub fn from_rgba8(width: u32, height: u32, colors: &[[u8; 4]]) -> Result<Self> {
        if colors.len() as u64 != width as u64 * height as u64 {
            return Err(invalid(format!(
                "{} RGBA pixels given for a {width}x{height} image",
                colors.len()
            )));
        }
        let data = colors
            .iter()
            .flat_map(|c| c[..3].iter().map(|&v| v as f32 / 255.0))
            .collect();
        Self::new(width, height, 3, data)
    }

    /// Checks that the image is non-empty, has 1 or 3 channels and the right amount of
    /// data.
    pub fn validate(&self) -> Result<()> {
        if self.channels != 1 && self.channels != 3 {
            return Err(invalid(format!(
                "image has {} channels; 1 or 3 expected",
                self.channels
            )));
        }
        if self.width == 0 || self.height == 0 {
            return Err(invalid(format!(
                "image is empty ({}x{})",
                self.width, self.height
            )));
        }
        let expect = self.width as u64 * self.height as u64 * self.channels as u64;
        if self.data.len() as u64 != expect {
            return Err(invalid(format!(
                "{}x{}x{} image holds {} values instead of {expect}",
                self.width,
                self.height,
                self.channels,
                self.data.len()
            )));
        }
        Ok(())
    }

    /// Number of pixels.
    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// The values of pixel `(x, y)` (`channels` floats).
    ///
    /// # Panics
    /// If `(x, y)` is outside the image or the image is inconsistent.
    pub fn pixel(&self, x: u32, y: u32) -> &[f32] {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside the image"
        );
        let c = self.channels as usize;
        let i = (y as usize * self.width as usize + x as usize) * c;
        &self.data[i..i + c]
    }

    /// Half resolution by 2x2 box filtering: `max(1, size / 2)` on each axis (an odd
    /// last row or column is dropped; a side of 1 stays 1).
    pub fn downsample2(&self) -> Self {
        let c = self.channels as usize;
        let (w, h) = (self.width as usize, self.height as usize);
        let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
        if self.data.len() != w * h * c {
            return Self {
                width: 0,
                height: 0,
                channels: self.channels,
                data: Vec::new(),
            };
        }
        let mut data = vec![0.0f32; nw * nh * c];
        for y in 0..nh {
            let ys = 2 * y..(2 * y + 2).min(h);
            for x in 0..nw {
                let xs = 2 * x..(2 * x + 2).min(w);
                let n = (ys.len() * xs.len()) as f32;
                for ch in 0..c {
                    let mut s = 0.0f32;
                    for sy in ys.clone() {
                        for sx in xs.clone() {
                            s += self.data[(sy * w + sx) * c + ch];
                        }
                    }
                    data[(y * nw + x) * c + ch] = s / n;
                }
            }
        }
        Self {
            width: nw as u32,
            height: nh as u32,
            channels: self.channels,
            data,
        }
    }

    /// Grey version (Rec. 709 luma of RGB); a grey image is returned unchanged.
    pub fn to_grey(&self) -> Self {
        if self.channels != 3 {
            return self.clone();
        }
        let data = self
            .data
            .chunks_exact(3)
            .map(|p| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2])
            .collect();
        Self {
            width: self.width,
            height: self.height,
            channels: 1,
            data,
        }
    }

    /// RGB version (grey replicated); an RGB image is returned unchanged.
    pub fn to_rgb(&self) -> Self {
        if self.channels != 1 {
            return self.clone();
        }
        let data = self.data.iter().flat_map(|&v| [v, v, v]).collect();
        Self {
            width: self.width,
            height: self.height,
            channels: 3,
            data,
        }
    }

    /// The `width x height` sub-image at `(x, y)`.
    pub fn crop(&self, x: u32, y: u32, width: u32, height: u32) -> Result<Self> {
        self.validate()?;
        if x as u64 + width as u64 > self.width as u64
            || y as u64 + height as u64 > self.height as u64
        {
            return Err(invalid(format!(
                "crop {width}x{height} at ({x}, {y}) exceeds the {}x{} image",
                self.width, self.height
            )));
        }
        let c = self.channels as usize;
        let mut data = Vec::with_capacity(width as usize * height as usize * c);
        for row in y..y + height {
            let start = (row as usize * self.width as usize + x as usize) * c;
            data.extend_from_slice(&self.data[start..start + width as usize * c]);
        }
        Ok(Self {
            width,
            height,
            channels: self.channels,
            data,
        })
    }

    /// A `width x height` image repeating this one periodically (a "tiled copy").
    pub fn tiled(&self, width: u32, height: u32) -> Result<Self> {
        self.validate()?;
        if width == 0 || height == 0 || width as u64 * height as u64 > 1 << 28 {
            return Err(invalid(format!(
                "tiled copy of {width}x{height}: give 1 to 2^28 pixels"
            )));
        }
        let c = self.channels as usize;
        let (w, h) = (self.width as usize, self.height as usize);
        let mut data = Vec::with_capacity(width as usize * height as usize * c);
        for y in 0..height as usize {
            for x in 0..width as usize {
                let i = ((y % h) * w + x % w) * c;
                data.extend_from_slice(&self.data[i..i + c]);
            }
        }
        Ok(Self {
            width,
            height,
            channels: self.channels,
            data,
        })
    }
}

/// Validates both images and brings them to the same channel count (grey replicated
/// into RGB when they differ).
pub(super) fn matched<'a>(
    a: &'a FloatImage,
    b: &'a FloatImage,
) -> Result<(Cow<'a, FloatImage>, Cow<'a, FloatImage>)> {
    a.validate()?;
    b.validate()?;
    Ok(match (a.channels, b.channels) {
        (1, 3) => (Cow::Owned(a.to_rgb()), Cow::Borrowed(b)),
        (3, 1) => (Cow::Borrowed(a), Cow::Owned(b.to_rgb())),
        _ => (Cow::Borrowed(a), Cow::Borrowed(b)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn downsample_and_conversions() {
        let img = FloatImage::new(3, 3, 1, (0..9).map(|v| v as f32 / 8.0).collect()).unwrap();
        let d = img.downsample2();
        assert_eq!((d.width, d.height, d.channels), (1, 1, 1));
        assert!((d.data[0] - (0.0 + 1.0 + 3.0 + 4.0) / 32.0).abs() < 1e-6);
        let one = FloatImage::new(1, 5, 3, vec![0.5; 15])
            .unwrap()
            .downsample2();
        assert_eq!((one.width, one.height), (1, 2));
        let rgb = img.to_rgb();
        assert_eq!(rgb.channels, 3);
        assert_eq!(
            rgb.to_grey()
                .data
                .iter()
                .zip(&img.data)
                .filter(|(a, b)| (*a - *b).abs() > 1e-6)
                .count(),
            0
        );
        let bad = FloatImage {
            width: 4,
            height: 4,
            channels: 2,
            data: vec![0.0; 32],
        };
        assert!(bad.validate().is_err());
        assert!(FloatImage::new(2, 2, 3, vec![0.0; 11]).is_err());
    }
}
