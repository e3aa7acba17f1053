//! [`Texture`]: a synthesized texture on the host, with its material maps and
//! coordinates, and the checks and atomic writes of its files.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::passes::Synthesis;

use super::{CopyGuardReport, RunTimings};

/// A material map aligned with the exemplar (normal, height, roughness...), given to
/// [`SessionBuilder::material_map`](super::SessionBuilder::material_map).
#[derive(Clone, Debug)]
pub struct MaterialMap {
    /// The image file (its size must be the exemplar image's).
    pub path: PathBuf,
    /// A tangent-space normal map: its x, y rotate with the texture along a field.
    pub normal: bool,
    /// A normal map with green = y down (DirectX); otherwise y up (OpenGL, glTF).
    pub green_down: bool,
}

impl MaterialMap {
    /// A plain map (height, roughness...): its values are copied as they are.
    pub fn plain(path: impl Into<PathBuf>) -> Self {
        MaterialMap {
            path: path.into(),
            normal: false,
            green_down: false,
        }
    }
    /// A tangent-space normal map with green = y up (OpenGL, glTF, Blender).
    pub fn normal(path: impl Into<PathBuf>) -> Self {
        MaterialMap {
            normal: true,
            ..Self::plain(path)
        }
    }
    /// A tangent-space normal map with green = y down (DirectX).
    pub fn normal_green_down(path: impl Into<PathBuf>) -> Self {
        MaterialMap {
            green_down: true,
            ..Self::normal(path)
        }
    }
}

/// A material map resynthesized through a texture's coordinates ([`Texture::maps`]).
#[derive(Clone, Debug)]
pub struct SynthesizedMap {
    /// RGBA8 pixels, the size of [`Texture::width`] x [`Texture::height`].
    pub pixels: Vec<[u8; 4]>,
    /// The map file's channels (1 grey, 3 RGB, 4 RGBA): what it is saved with.
    pub channels: u32,
    /// A normal map.
    pub normal: bool,
    /// A normal map with green = y down.
    pub green_down: bool,
}

/// The colours of a magnified output ([`SessionBuilder::magnify`](super::SessionBuilder::magnify)).
#[derive(Clone, Debug)]
pub(super) struct MagnifiedImage {
    pub width: u32,
    pub height: u32,
    pub factor: u32,
    pub colors: Vec<[u8; 4]>,
}

/// A synthesized texture on the host.
///
/// ```no_run
/// let session = texsyn::Session::builder()
///     .exemplar_path("assets/gravel.png")
///     .size(512, 512)
///     .build()?;
/// let texture = session.run()?;
/// // The image and its coordinates, all or nothing.
/// texture.save_all("out.png".as_ref(), Some("out.exr".as_ref()), &[])?;
/// # Ok::<(), texsyn::Error>(())
/// ```
#[derive(Clone, Debug)]
pub struct Texture {
    /// The synthesis at its own resolution: exemplar coordinates (empty without
    /// [`SessionBuilder::coordinates`](super::SessionBuilder::coordinates)) and colours
    /// (those of the output unless magnified; empty for a magnified output without
    /// coordinates or maps).
    pub synthesis: Synthesis,
    /// 1 for grey exemplars, 3 for colour.
    pub channels: u32,
    /// Width and height of the (analysed) exemplar, in pixels.
    pub exemplar_size: [u32; 2],
    /// Whether the exemplar was handled as tileable (coordinates wrap around it).
    pub tileable: bool,
    pub(super) magnified: Option<MagnifiedImage>,
    pub(super) maps: Vec<SynthesizedMap>,
    pub(super) windowed: bool,
    pub(super) copy_guard: Option<CopyGuardReport>,
    pub(super) timings: RunTimings,
}

impl Texture {
    /// Width of the output image in pixels (magnified, if it is).
    pub fn width(&self) -> u32 {
        self.magnified
            .as_ref()
            .map_or(self.synthesis.width, |m| m.width)
    }
    /// Height of the output image in pixels (magnified, if it is).
    pub fn height(&self) -> u32 {
        self.magnified
            .as_ref()
            .map_or(self.synthesis.height, |m| m.height)
    }
    /// The magnification factor, if magnified.
    pub fn magnification(&self) -> Option<u32> {
        self.magnified.as_ref().map(|m| m.factor)
    }
    /// Fractional bits of [`Texture::coords`]: 0 (isometric) or 8 (anisometric).
    pub fn coord_frac(&self) -> u32 {
        self.synthesis.coord_frac
    }
    /// The output image's colours, RGBA8, row-major.
    pub fn colors(&self) -> &[[u8; 4]] {
        match &self.magnified {
            Some(m) => &m.colors,
            None => &self.synthesis.colors,
        }
    }
    /// RGBA8 bytes of the output image, row-major.
    pub fn rgba8(&self) -> Vec<u8> {
        self.colors().iter().flatten().copied().collect()
    }
    /// Exemplar coordinates per pixel of the synthesis (before any magnification), in
    /// units of `2^-coord_frac()` exemplar pixels.
    pub fn coords(&self) -> &[[i32; 2]] {
        &self.synthesis.coords
    }
    /// The material maps, in the order given, the size of the output image.
    pub fn maps(&self) -> &[SynthesizedMap] {
        &self.maps
    }
    /// Whether the output was assembled from windows (too large for one piece).
    pub fn assembled_from_windows(&self) -> bool {
        self.windowed
    }
    /// What the copy guard did, if it probed or had a reason not to.
    pub fn copy_guard(&self) -> Option<&CopyGuardReport> {
        self.copy_guard.as_ref()
    }
    /// How long the run's steps took.
    pub fn timings(&self) -> &RunTimings {
        &self.timings
    }
    /// Saves the colours (PNG, or another format by extension), atomically.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<()> {
        self.save_all(path.as_ref(), None, &[])
    }
    /// Saves the coordinate map as a float EXR (R = x, G = y, exemplar pixels),
    /// atomically.
    pub fn save_coords(&self, path: impl AsRef<Path>) -> Result<()> {
        let (w, h) = (self.synthesis.width, self.synthesis.height);
        crate::image_io::save_coords_exr_f32_atomic(
            path.as_ref(),
            w,
            h,
            &self.synthesis.coords_f32(),
        )
    }
    /// Saves the image, its coordinates (a float EXR, if `coords` is given) and its
    /// material maps (one path per map, in order) all or nothing: every file is encoded
    /// and written to a temporary file before any is renamed into place, so files that
    /// existed before stay as they were if any step fails.
    pub fn save_all(&self, image: &Path, coords: Option<&Path>, maps: &[&Path]) -> Result<()> {
        use crate::image_io::{encode_coords_exr_f32, encode_image, write_files_atomic};
        if maps.len() != self.maps.len() {
            return Err(Error::InvalidParameter(format!(
                "{} map paths for {} material maps",
                maps.len(),
                self.maps.len()
            )));
        }
        let (w, h) = (self.width(), self.height());
        let mut files: Vec<(&Path, Vec<u8>)> = Vec::new();
        if let Some(path) = coords {
            let (sw, sh) = (self.synthesis.width, self.synthesis.height);
            let c = self.synthesis.coords_f32();
            files.push((path, encode_coords_exr_f32(path, sw, sh, &c)?));
        }
        for (path, m) in maps.iter().zip(&self.maps) {
            let bytes = encode_image(path, w, h, m.channels, bytemuck::cast_slice(&m.pixels))?;
            files.push((path, bytes));
        }
        let rgba8: &[u8] = bytemuck::cast_slice(self.colors());
        files.push((image, encode_image(image, w, h, self.channels, rgba8)?));
        write_files_atomic(&files.iter().map(|(p, b)| (*p, &b[..])).collect::<Vec<_>>())
    }
}

/// Refuses, before any work, an output extension the image writer does not support
/// (no extension: PNG).
pub fn check_image_path(path: &Path) -> Result<()> {
    use image::ImageFormat as F;
    let Some(ext) = path.extension() else {
        return Ok(());
    };
    let ok = F::from_extension(ext).is_some_and(|f| {
        matches!(
            f,
            F::Png
                | F::Jpeg
                | F::Bmp
                | F::Tga
                | F::Tiff
                | F::WebP
                | F::Gif
                | F::Pnm
                | F::OpenExr
                | F::Hdr
        )
    });
    if ok {
        return Ok(());
    }
    Err(Error::InvalidParameter(format!(
        "cannot write {}: unsupported image extension .{}; supported: {} (no extension: png)",
        path.display(),
        ext.to_string_lossy(),
        crate::image_io::SUPPORTED_SAVE_EXTENSIONS
    )))
}

/// The largest side each output format's encoder writes (the `image` crate and its
/// WebP encoder refuse larger ones, which would surface only after the synthesis).
fn format_max_side(path: &Path) -> Option<(&'static str, u32)> {
    use image::ImageFormat as F;
    match F::from_extension(path.extension()?)? {
        F::Jpeg => Some(("JPEG", 65535)),
        F::Gif => Some(("GIF", 65535)),
        F::Tga => Some(("TGA", 65535)),
        F::WebP => Some(("WebP", 16384)),
        _ => None,
    }
}

/// Refuses, before any work, an image of `width` x `height` that the format of `path`
/// cannot hold.
pub fn check_image_size(path: &Path, width: u64, height: u64) -> Result<()> {
    match format_max_side(path) {
        Some((name, max)) if width > max as u64 || height > max as u64 => {
            Err(Error::InvalidParameter(format!(
                "cannot write {}: {name} images are at most {max} pixels a side and the output is \
                 {width}x{height}; use .png, .tif or .exr",
                path.display()
            )))
        }
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_formats_refuse_sizes_they_cannot_encode() {
        check_image_size(Path::new("a.png"), 70000, 16).unwrap();
        check_image_size(Path::new("a.gif"), 65535, 16).unwrap();
        let e = check_image_size(Path::new("a.gif"), 70000, 16).unwrap_err();
        assert!(
            e.to_string().contains("GIF images are at most 65535"),
            "{e}"
        );
        check_image_size(Path::new("a.webp"), 16, 16385).unwrap_err();
        check_image_size(Path::new("a.JPG"), 65536, 1).unwrap_err();
    }
}
