//! Feature-preserving appearance (Lefebvre & Hoppe 2006 §3.2): a binary feature mask (mortar
//! between bricks, cracks, the outlines of spots) becomes a signed-distance channel that
//! is appended to the colour channels before the Gaussian stack and the 5x5
//! neighbourhood gathering, so the PCA sees it like any colour. Synthesis (the GPU
//! passes, the 8D `Et`) does not change at all.
//!
//! The channel, per exemplar pixel:
//!
//! 1. `d` = signed Euclidean distance to the mask boundary in exemplar pixels, positive
//!    inside the mask, negative outside: `d = dist(p, nearest pixel on the other side) - 0.5`
//!    (pixels next to the boundary get `+-0.5`), from an exact two-pass separable
//!    distance transform ([`squared_distance_transform`], Felzenszwalb & Huttenlocher
//!    2012), wrapping around for tileable exemplars.
//! 2. `s = clamp(d, -dmax, dmax) / dmax` (`dmax` = [`super::AnalysisOptions::feature_clamp`],
//!    default [`DEFAULT_FEATURE_CLAMP`] = 1 px at the finest level). Clamping keeps the
//!    medial-axis ridges of large regions out of the channel (paper: "clamping the
//!    distance magnitude to some maximum helps suppress singularities along the feature
//!    medial axis"); at 1 px the channel says inside, outside or on the boundary, and
//!    nothing of where inside a region a pixel lies, which the colours say better.
//! 3. The channel is `w * sigma_colour * (s - mean(s)) / std(s)`: standardised, then
//!    scaled so that at weight `w = 1` ([`DEFAULT_FEATURE_WEIGHT`]) its variance equals
//!    the total variance of the colour channels (the sum over R, G, B), whatever the
//!    exemplar's contrast. `w` trades structure against colour fidelity (Lefebvre & Hoppe 2006, Figure 6);
//!    a very large `w` makes synthesis ignore colour and turns noisy.
//!
//! A mask that is all feature or all background gives a constant `s`; its channel is then
//! zero (no information, and nothing is divided by a zero deviation).
//!
//! The channel trades colour fidelity for structure: it keeps features such as mortar
//! whole while the colour texture energy rises somewhat; the defaults below were chosen
//! by measurement on masks thresholded from exemplars' mortar and cracks.

use std::path::{Path, PathBuf};

use image::DynamicImage;

use crate::error::{Error, Result};

/// Default weight of the feature channel with [`super::FeatureMode::Appearance`]: as much
/// variance as all colour channels together.
pub const DEFAULT_FEATURE_WEIGHT: f32 = 1.0;
/// Default weight with [`super::FeatureMode::Sets`] and [`super::FeatureMode::Both`]:
/// there the channel steers the similarity-set search, where weight 1 changes little and
/// 4 to 64 give about the same sets.
pub const DEFAULT_SETS_FEATURE_WEIGHT: f32 = 16.0;
/// With [`super::FeatureMode::Both`], the share of the weight the channel has in the
/// appearance vectors the synthesis matches (the sets get all of it): light enough that
/// the colour energy does not rise over no mask.
pub const BOTH_APPEARANCE_SHARE: f32 = 1.0 / 128.0;

/// The default weight of a mode (`AnalysisOptions::feature_weight` = `None`).
pub fn default_weight(mode: super::FeatureMode) -> f32 {
    match mode {
        super::FeatureMode::Appearance => DEFAULT_FEATURE_WEIGHT,
        super::FeatureMode::Sets | super::FeatureMode::Both => DEFAULT_SETS_FEATURE_WEIGHT,
    }
}
/// Largest accepted feature weight (beyond it colour no longer matters at all).
pub const MAX_FEATURE_WEIGHT: f32 = 100.0;
/// Default clamp `dmax` of the signed distance, in exemplar pixels: 1 px keeps about as
/// much of the features whole as 4 for much less colour energy; a deeper distance
/// constrains where inside a region each pixel comes from, which the colours decide.
pub const DEFAULT_FEATURE_CLAMP: f32 = 1.0;
/// Accepted range of the clamp: below 0.5 every pixel would be clamped (the smallest
/// |distance| is 0.5).
pub const FEATURE_CLAMP_RANGE: std::ops::RangeInclusive<f32> = 0.5..=4096.0;

/// A binary feature mask of the exemplar's size.
#[derive(Clone, Debug, PartialEq)]
pub struct FeatureMask {
    /// Width in pixels (must equal the exemplar's).
    pub width: u32,
    /// Height in pixels (must equal the exemplar's).
    pub height: u32,
    /// Row-major, `true` = feature.
    pub inside: Vec<bool>,
    /// File it was read from, named in error messages.
    pub source: Option<PathBuf>,
}

impl FeatureMask {
    /// A mask from row-major flags (`true` = feature).
    pub fn new(width: u32, height: u32, inside: Vec<bool>) -> Result<Self> {
        if inside.len() as u64 != width as u64 * height as u64 || width == 0 || height == 0 {
            return Err(Error::InvalidParameter(format!(
                "feature mask of {width}x{height} needs {} flags, got {}",
                width as u64 * height as u64,
                inside.len()
            )));
        }
        Ok(Self {
            width,
            height,
            inside,
            source: None,
        })
    }

    /// A mask from an image: grey level (Rec. 709 luma of RGB; alpha is ignored) above
    /// the midpoint of the image's darkest and brightest values is feature. So black /
    /// white, 0 / 1 and anti-aliased masks all work. An image of a single value is all
    /// feature if that value is nonzero, else all background.
    pub fn from_image(img: &DynamicImage) -> Self {
        let luma = img.to_luma32f();
        let (w, h) = luma.dimensions();
        let (lo, hi) = luma
            .pixels()
            .map(|p| if p.0[0].is_nan() { 0.0 } else { p.0[0] })
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            });
        let inside = if hi > lo {
            let mid = 0.5 * (lo + hi);
            luma.pixels().map(|p| p.0[0] > mid).collect()
        } else {
            vec![hi > 0.0; (w as usize) * (h as usize)]
        };
        Self {
            width: w,
            height: h,
            inside,
            source: None,
        }
    }

    /// Reads a mask from any image file the `image` crate decodes (see
    /// [`FeatureMask::from_image`]). Missing or unreadable file: [`Error::Io`]; not an
    /// image: [`Error::BadImage`].
    pub fn load(path: &Path) -> Result<Self> {
        let img = crate::image_io::open_image(path)?;
        crate::image_io::check_finite(&img, path, "feature mask")?;
        let mut m = Self::from_image(&img);
        m.source = Some(path.to_path_buf());
        Ok(m)
    }

    /// The mask of an exemplar downsampled `factor` times (cropped to a multiple of it,
    /// as [`crate::image_io::downsample_exemplar`] crops): a pixel is a feature when at
    /// least half of its block is. For `--magnify`, whose mask is given at full size.
    pub fn downsample(&self, factor: u32) -> Result<Self> {
        self.check_size(self.width, self.height)?;
        let f = factor.max(1) as usize;
        let (w, h) = (self.width as usize / f, self.height as usize / f);
        let mut inside = Vec::with_capacity(w * h);
        for y in 0..h {
            for x in 0..w {
                let count = (0..f)
                    .flat_map(|dy| (0..f).map(move |dx| (dx, dy)))
                    .filter(|&(dx, dy)| {
                        self.inside[(y * f + dy) * self.width as usize + x * f + dx]
                    })
                    .count();
                inside.push(2 * count >= f * f);
            }
        }
        let mut m = Self::new(w as u32, h as u32, inside)?;
        m.source = self.source.clone();
        Ok(m)
    }

    /// Fraction of the pixels that are feature.
    pub fn coverage(&self) -> f64 {
        self.inside.iter().filter(|&&b| b).count() as f64 / self.inside.len().max(1) as f64
    }

    fn name(&self) -> String {
        match &self.source {
            Some(p) => format!("feature mask {}", p.display()),
            None => "feature mask".into(),
        }
    }

    /// Checks that the mask has the exemplar's size.
    pub fn check_size(&self, width: u32, height: u32) -> Result<()> {
        if (self.width, self.height) != (width, height) {
            return Err(Error::InvalidParameter(format!(
                "{} is {}x{} but the exemplar is {width}x{height}; the mask must have the \
                 exemplar's size",
                self.name(),
                self.width,
                self.height
            )));
        }
        if self.inside.len() != width as usize * height as usize {
            return Err(Error::InvalidParameter(format!(
                "{}: {} flags for {width}x{height} pixels",
                self.name(),
                self.inside.len()
            )));
        }
        Ok(())
    }

    /// Checks that the mask has both values. A blank mask (no feature, or nothing but
    /// features) adds a constant channel: the result would silently equal one without a
    /// mask, at a higher cost (an empty or inverted export is the likely cause). The
    /// analysis accepts such masks; the CLI refuses them with this check, after
    /// [`Self::check_size`], so that a mask of the wrong size says so first.
    pub fn check_not_blank(&self) -> Result<()> {
        let coverage = self.coverage();
        if coverage == 0.0 || coverage == 1.0 {
            return Err(Error::InvalidParameter(format!(
                "{}: {} pixel is a feature (the image has a single value), so the mask would \
                 change nothing; features are the bright pixels of a two-valued image (e.g. \
                 white mortar on black)",
                self.name(),
                if coverage == 0.0 { "no" } else { "every" }
            )));
        }
        Ok(())
    }
}

/// Checks a feature weight: finite and in `0..=MAX_FEATURE_WEIGHT`.
pub fn check_weight(w: f32) -> Result<()> {
    if !(w.is_finite() && (0.0..=MAX_FEATURE_WEIGHT).contains(&w)) {
        return Err(Error::InvalidParameter(format!(
            "feature weight {w}: it must be a number in [0, {MAX_FEATURE_WEIGHT}] (default \
             {DEFAULT_SETS_FEATURE_WEIGHT}, {DEFAULT_FEATURE_WEIGHT} in the appearance mode)"
        )));
    }
    Ok(())
}

/// Checks a distance clamp `dmax` (exemplar pixels).
pub fn check_clamp(d: f32) -> Result<()> {
    if !(d.is_finite() && FEATURE_CLAMP_RANGE.contains(&d)) {
        return Err(Error::InvalidParameter(format!(
            "feature distance clamp {d}: it must be a number of pixels in [{}, {}] (default \
             {DEFAULT_FEATURE_CLAMP})",
            FEATURE_CLAMP_RANGE.start(),
            FEATURE_CLAMP_RANGE.end()
        )));
    }
    Ok(())
}

/// Lower envelope of parabolas (Felzenszwalb & Huttenlocher): `out[q] = min_p (q - p)^2 + f[p]`
/// over the `p` with finite `f[p]`; `INFINITY` everywhere if there is none.
fn edt_1d(f: &[f64], out: &mut [f64], v: &mut Vec<usize>, z: &mut Vec<f64>) {
    v.clear();
    z.clear();
    z.push(f64::NEG_INFINITY);
    for (q, &fq) in f.iter().enumerate() {
        if !fq.is_finite() {
            continue;
        }
        let qf = q as f64;
        while let Some(&p) = v.last() {
            // Where parabola q gets below parabola p (q > p, both finite).
            let pf = p as f64;
            let s = ((fq + qf * qf) - (f[p] + pf * pf)) / (2.0 * (qf - pf));
            if s <= *z.last().unwrap() {
                v.pop();
                z.pop();
            } else {
                z.push(s);
                break;
            }
        }
        // The first parabola starts at z[0] = -inf and is never removed (s is finite).
        v.push(q);
    }
    if v.is_empty() {
        out.fill(f64::INFINITY);
        return;
    }
    // z[i] is where parabola v[i] starts to be the lowest (z[0] = -inf).
    let mut k = 0;
    for (q, o) in out.iter_mut().enumerate() {
        let qf = q as f64;
        while k + 1 < v.len() && z[k + 1] < qf {
            k += 1;
        }
        let d = qf - v[k] as f64;
        *o = d * d + f[v[k]];
    }
}

/// Exact squared Euclidean distance (in pixels) from every pixel to the nearest `true`
/// pixel of `sites` (row-major `width x height`), by two separable passes of the lower
/// envelope of parabolas. `wrap`: distances wrap around the borders (tileable exemplars).
/// `INFINITY` everywhere if there is no site.
pub fn squared_distance_transform(sites: &[bool], width: u32, height: u32, wrap: bool) -> Vec<f64> {
    let (w, h) = (width as usize, height as usize);
    assert_eq!(sites.len(), w * h, "sites must be width x height");
    let mut g: Vec<f64> = sites
        .iter()
        .map(|&s| if s { 0.0 } else { f64::INFINITY })
        .collect();
    let (mut v, mut z) = (Vec::new(), Vec::new());
    // One line: with wrap, three periods side by side (the nearest periodic copy of any
    // site is within one period), and the middle one is kept.
    let mut line = |input: &[f64], output: &mut [f64]| {
        let n = input.len();
        if wrap {
            let ext: Vec<f64> = (0..3 * n).map(|i| input[i % n]).collect();
            let mut out = vec![0.0; 3 * n];
            edt_1d(&ext, &mut out, &mut v, &mut z);
            output.copy_from_slice(&out[n..2 * n]);
        } else {
            edt_1d(input, output, &mut v, &mut z);
        }
    };
    // Columns, then rows.
    let mut col = vec![0.0; h];
    let mut col_out = vec![0.0; h];
    for x in 0..w {
        for y in 0..h {
            col[y] = g[y * w + x];
        }
        line(&col, &mut col_out);
        for y in 0..h {
            g[y * w + x] = col_out[y];
        }
    }
    let mut row_out = vec![0.0; w];
    for y in 0..h {
        line(&g[y * w..(y + 1) * w], &mut row_out);
        g[y * w..(y + 1) * w].copy_from_slice(&row_out);
    }
    g
}

/// Signed distance to the mask boundary in pixels, positive inside the mask: inside,
/// the distance to the nearest background pixel minus 0.5; outside, minus (the distance
/// to the nearest feature pixel minus 0.5). `+INFINITY` everywhere for an all-feature
/// mask, `-INFINITY` for an empty one.
pub fn signed_distance(mask: &FeatureMask, wrap: bool) -> Vec<f32> {
    let to_inside = squared_distance_transform(&mask.inside, mask.width, mask.height, wrap);
    let outside: Vec<bool> = mask.inside.iter().map(|&b| !b).collect();
    let to_outside = squared_distance_transform(&outside, mask.width, mask.height, wrap);
    mask.inside
        .iter()
        .zip(to_inside.iter().zip(&to_outside))
        .map(|(&inside, (&di, &dout))| {
            if inside {
                (dout.sqrt() - 0.5) as f32
            } else {
                -(di.sqrt() - 0.5) as f32
            }
        })
        .collect()
}

/// The feature channel appended to the exemplar (see the module doc): one value per
/// pixel. `colour` holds the exemplar's `channels` values per pixel; it only sets the
/// scale (the channel's variance is `weight^2` times the colours' total variance).
pub fn feature_channel(
    mask: &FeatureMask,
    weight: f32,
    clamp: f32,
    colour: &[f32],
    channels: usize,
    wrap: bool,
) -> Vec<f32> {
    let n = mask.inside.len();
    let s: Vec<f64> = signed_distance(mask, wrap)
        .iter()
        .map(|&d| (d.clamp(-clamp, clamp) / clamp) as f64)
        .collect();
    let mean = s.iter().sum::<f64>() / n.max(1) as f64;
    let var = s.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n.max(1) as f64;
    // Total colour variance (sum over the channels).
    let mut colour_var = 0.0f64;
    for c in 0..channels {
        let vals = colour.iter().skip(c).step_by(channels);
        let m = vals.clone().map(|&v| v as f64).sum::<f64>() / n.max(1) as f64;
        colour_var += vals.map(|&v| (v as f64 - m).powi(2)).sum::<f64>() / n.max(1) as f64;
    }
    // A constant mask carries nothing; a constant exemplar has nothing to balance
    // against, so any positive scale does.
    if var <= 1e-12 {
        return vec![0.0; n];
    }
    let sigma = if colour_var > 1e-12 {
        colour_var.sqrt()
    } else {
        1.0
    };
    let scale = weight as f64 * sigma / var.sqrt();
    s.iter().map(|v| ((v - mean) * scale) as f32).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute(sites: &[bool], w: usize, h: usize, wrap: bool) -> Vec<f64> {
        let mut out = vec![f64::INFINITY; w * h];
        for y in 0..h {
            for x in 0..w {
                for sy in 0..h {
                    for sx in 0..w {
                        if !sites[sy * w + sx] {
                            continue;
                        }
                        let mut dx = (x as i64 - sx as i64).abs();
                        let mut dy = (y as i64 - sy as i64).abs();
                        if wrap {
                            dx = dx.min(w as i64 - dx);
                            dy = dy.min(h as i64 - dy);
                        }
                        let d = (dx * dx + dy * dy) as f64;
                        if d < out[y * w + x] {
                            out[y * w + x] = d;
                        }
                    }
                }
            }
        }
        out
    }

    #[test]
    fn edt_matches_brute_force() {
        let mut state = 12345u32;
        for (w, h, density) in [
            (1, 1, 2),
            (7, 5, 3),
            (13, 17, 10),
            (16, 9, 40),
            (20, 20, 200),
        ] {
            for wrap in [false, true] {
                let sites: Vec<bool> = (0..w * h)
                    .map(|_| {
                        state = state.wrapping_mul(1664525).wrapping_add(1013904223);
                        (state >> 8).is_multiple_of(density)
                    })
                    .collect();
                let fast = squared_distance_transform(&sites, w as u32, h as u32, wrap);
                assert_eq!(fast, brute(&sites, w, h, wrap), "{w}x{h} wrap {wrap}");
            }
        }
    }
}
