//! Opening an exemplar: an image or a saved analysis (told apart by content), checked
//! against the device before any analysis, and the downsampled copy that magnification
//! synthesizes from.

use std::path::Path;

use crate::analysis::{Analysis, Exemplar};
use crate::error::{Error, Result};
use crate::gpu::GpuContext;

/// What an exemplar path holds: a finished analysis, or an image still to analyse.
///
/// ```no_run
/// use texsyn::ExemplarSource;
/// match ExemplarSource::open("assets/gravel.png".as_ref())? {
///     ExemplarSource::Image(ex) => println!("an image of {}x{}", ex.width, ex.height),
///     ExemplarSource::Analysis(a) => println!("an analysis with k = {}", a.k),
/// }
/// # Ok::<(), texsyn::Error>(())
/// ```
pub enum ExemplarSource {
    /// A saved analysis (`texsyn analyze`, [`Analysis::save`]).
    Analysis(Analysis),
    /// An image, to be analysed.
    Image(Exemplar),
}

/// The full-resolution exemplar that a magnified synthesis reads its colours from.
#[derive(Clone, Debug)]
pub struct Magnified {
    /// RGBA8 pixels, row-major, `width` x `height`.
    pub pixels: Vec<[u8; 4]>,
    /// Width: the analysed exemplar's times `factor` (the image cropped to a multiple).
    pub width: u32,
    /// Height: the analysed exemplar's times `factor`.
    pub height: u32,
    /// The magnification factor (2, 4 or 8).
    pub factor: u32,
}

impl ExemplarSource {
    /// Opens `path`: an analysis file (loaded into memory) or an image, told apart by
    /// the analysis-file magic, without analysing anything yet.
    pub fn open(path: &Path) -> Result<Self> {
        if super::is_analysis_file(path)? {
            Analysis::load(path).map(ExemplarSource::Analysis)
        } else {
            load_image(path).map(ExemplarSource::Image)
        }
    }

    /// [`Self::open`], with an analysis file memory-mapped rather than read (a faster
    /// start for large files).
    ///
    /// # Safety
    ///
    /// The file must not be truncated or modified in place while the analysis is in use
    /// (see [`Analysis::load_mapped`]); texsyn replaces analysis files by renaming a new
    /// one over them, which leaves a mapping intact.
    pub unsafe fn open_mapped(path: &Path) -> Result<Self> {
        if super::is_analysis_file(path)? {
            // SAFETY: the caller's contract.
            unsafe { Analysis::load_mapped(path) }.map(ExemplarSource::Analysis)
        } else {
            load_image(path).map(ExemplarSource::Image)
        }
    }

    /// Refuses, before any analysis, an exemplar image whose tables (with similarity
    /// sets of size `k`) the device cannot hold; an analysis is checked on upload.
    pub fn check_fits(&self, ctx: &GpuContext, k: u32) -> Result<()> {
        if let ExemplarSource::Image(ex) = self {
            crate::gpu::synth::check_exemplar_fits(ctx, ex.width, ex.height, k)?;
        }
        Ok(())
    }

    /// Refuses an analysis file (read from `path`) made with another similarity-set
    /// size or tileability than the ones given (`None`: whatever the file has).
    pub fn check_matches(&self, path: &Path, k: Option<u32>, tileable: Option<bool>) -> Result<()> {
        let ExemplarSource::Analysis(analysis) = self else {
            return Ok(());
        };
        if let Some(k) = k.filter(|&k| k != analysis.k) {
            return Err(Error::InvalidParameter(format!(
                "--k {k} does not match the analysis file {} (k = {}); drop --k or re-run `texsyn analyze --k {k}`",
                path.display(),
                analysis.k
            )));
        }
        if let Some(t) = tileable.filter(|&t| t != analysis.tileable) {
            let flag = if t { "--tileable" } else { "--no-tileable" };
            return Err(Error::InvalidParameter(format!(
                "{flag} does not match the analysis file {} (analysed as {}tileable); drop {flag} or re-run `texsyn analyze {flag}`",
                path.display(),
                if analysis.tileable { "" } else { "not " }
            )));
        }
        Ok(())
    }

    /// The exemplar image's size, `None` for an analysis.
    pub fn image_size(&self) -> Option<(u32, u32)> {
        match self {
            ExemplarSource::Image(ex) => Some((ex.width, ex.height)),
            ExemplarSource::Analysis(_) => None,
        }
    }

    /// Magnification by `factor`: the exemplar downsampled `factor` times (what is
    /// analysed and synthesized) and its full-resolution colours (what the output reads).
    /// Needs an image: an analysis has no full-resolution colours.
    pub fn magnify(self, factor: u32) -> Result<(ExemplarSource, Magnified)> {
        match self {
            ExemplarSource::Analysis(_) => Err(Error::InvalidParameter(
                "magnification needs the exemplar image (its full-resolution colours), not an \
                 analysis file"
                    .into(),
            )),
            ExemplarSource::Image(ex) => {
                let (small, pixels) = crate::image_io::downsample_exemplar(&ex, factor)?;
                let magnified = Magnified {
                    pixels,
                    width: small.width * factor,
                    height: small.height * factor,
                    factor,
                };
                Ok((ExemplarSource::Image(small), magnified))
            }
        }
    }
}

/// A warning when the image at `path` is an animation: texsyn uses its first frame.
pub fn animation_warning(path: &Path) -> Option<String> {
    match crate::image_io::animation_frames(path) {
        Some(n @ 2..) => Some(format!(
            "warning: {} is an animation of {n} frames; texsyn uses its first frame \
             (extract another frame to use it)",
            path.display()
        )),
        _ => None,
    }
}

/// An exemplar image; an unrecognized format also says that the file is no analysis file.
fn load_image(path: &Path) -> Result<Exemplar> {
    crate::image_io::load_exemplar(path).map_err(|e| match e {
        Error::BadImage { path, reason } if reason.starts_with("unrecognized") => Error::BadImage {
            path,
            reason: format!(
                "{reason}; nor is it a texsyn analysis file (it does not start with \
                     the analysis-file magic: written by another program, or damaged; \
                     re-run `texsyn analyze`)"
            ),
        },
        other => other,
    })
}

/// The top-left `w x h` pixels of a row-major image `width` pixels wide: a
/// full-resolution map cropped as [`ExemplarSource::magnify`] cropped the exemplar.
pub fn crop_rows(pixels: &[[u8; 4]], width: u32, w: u32, h: u32) -> Vec<[u8; 4]> {
    (0..h as usize)
        .flat_map(|y| pixels[y * width as usize..][..w as usize].iter().copied())
        .collect()
}
