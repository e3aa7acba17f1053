//! Histogram distance: whether the output uses the exemplar's values in the same
//! proportions, whatever their arrangement.
//!
//! Per channel, the earth mover's distance between the two 256-bin value histograms:
//! 0 for equal histograms, 1 for all black against all white. A shift of the whole
//! histogram by `k/255` reads `k/255`. It says nothing about structure (any permutation
//! of the exemplar's pixels scores 0); read it next to the texture energy.

use super::image::{matched, FloatImage};
use crate::error::Result;

/// Per-channel earth mover's distance between the normalized 256-bin histograms of the
/// two images (`sum |CDF_a - CDF_b| / 255`, in `[0, 1]`; 0 for equal histograms, 1 for
/// all-black against all-white). Values are binned as `round(v * 255)`. Channels are
/// matched as for every figure (see the [module documentation](super)).
/// [`QualityReport`] also carries the mean over channels.
///
/// [`QualityReport`]: super::QualityReport
pub fn histogram_distance(exemplar: &FloatImage, output: &FloatImage) -> Result<Vec<f64>> {
    let (a, b) = matched(exemplar, output)?;
    let c = a.channels as usize;
    let hist = |img: &FloatImage, ch: usize| {
        let mut h = [0u64; 256];
        for px in img.data.chunks_exact(c) {
            let v = px[ch];
            let bin = if v.is_nan() {
                0
            } else {
                (v.clamp(0.0, 1.0) * 255.0).round() as usize
            };
            h[bin] += 1;
        }
        h
    };
    Ok((0..c)
        .map(|ch| {
            let (ha, hb) = (hist(&a, ch), hist(&b, ch));
            let (na, nb) = (a.pixel_count() as f64, b.pixel_count() as f64);
            let (mut ca, mut cb, mut emd) = (0u64, 0u64, 0.0f64);
            for bin in 0..255 {
                ca += ha[bin];
                cb += hb[bin];
                emd += (ca as f64 / na - cb as f64 / nb).abs();
            }
            emd / 255.0
        })
        .collect())
}
