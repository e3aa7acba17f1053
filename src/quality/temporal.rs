//! Temporal figures of an advected sequence: coherence from frame to frame (the
//! change after warping by the flow, and popping, where a patch changes at once),
//! texture energy over time, and sharpness against the exemplar.
//!
//! Low warped change and few pops mean the texture moves with the flow; the unwarped
//! change gives their scale. Sharpness near 1 means as sharp as the exemplar; lower
//! means blurred.

use super::common::invalid;
use super::energy::texture_energy;
use super::image::FloatImage;
use crate::error::Result;

/// Temporal coherence of an advected sequence (`texsyn advect`, `texsyn eval --flow`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TemporalReport {
    /// Per consecutive pair: mean absolute difference (0-1) between frame t and frame
    /// t-1 warped by the flow (sampled bilinearly at p - V dt). Low: coherent, no popping.
    pub warped_diff: Vec<f64>,
    /// The same without warping, for scale (what a static viewer sees change).
    pub unwarped_diff: Vec<f64>,
    /// Per consecutive pair: the fraction of 8x8 blocks whose mean warped change
    /// exceeds 0.15 ([`pop_fraction`]): patches that changed at once, popping.
    pub pops: Vec<f64>,
    /// Texture energy (neighbourhood distance to the exemplar) of the frames it was
    /// computed for, as (frame index, energy).
    pub energy: Vec<(usize, f64)>,
    /// High-frequency energy (mean squared Laplacian) of each frame divided by the
    /// exemplar's: 1 is as sharp as the exemplar, lower is blurred.
    pub sharpness: Vec<f64>,
}

impl TemporalReport {
    /// Mean of [`warped_diff`](Self::warped_diff) over the pairs it could be measured on
    /// (NaN entries skipped; NaN if none could, 0 when empty).
    pub fn mean_warped_diff(&self) -> f64 {
        mean(&self.warped_diff)
    }
    /// Mean of [`unwarped_diff`](Self::unwarped_diff) (as for the warped one).
    pub fn mean_unwarped_diff(&self) -> f64 {
        mean(&self.unwarped_diff)
    }
    /// Mean of [`pops`](Self::pops) (as for the warped difference).
    pub fn mean_pops(&self) -> f64 {
        mean(&self.pops)
    }
}

fn mean(v: &[f64]) -> f64 {
    let finite: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if finite.is_empty() {
        if v.is_empty() {
            0.0
        } else {
            f64::NAN
        }
    } else {
        finite.iter().sum::<f64>() / finite.len() as f64
    }
}

/// Mean squared Laplacian of a grey image (interior pixels); NaN for an image whose fields
/// disagree.
pub fn high_frequency_energy(img: &FloatImage) -> f64 {
    if img.validate().is_err() {
        return f64::NAN;
    }
    let g = img.to_grey();
    let (w, h) = (g.width as usize, g.height as usize);
    if w < 3 || h < 3 {
        return 0.0;
    }
    let at = |x: usize, y: usize| g.data[y * w + x] as f64;
    let mut sum = 0.0;
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let l = 4.0 * at(x, y) - at(x - 1, y) - at(x + 1, y) - at(x, y - 1) - at(x, y + 1);
            sum += l * l;
        }
    }
    sum / ((w - 2) * (h - 2)) as f64
}

/// Mean absolute difference between `cur` and `prev` sampled bilinearly at `p - d(p)`
/// (grey, 0-1), over the pixels at least `margin` from the border whose source lies
/// inside `prev`; NaN when there is no such pixel (the flow moved everything out of
/// view) or when the two are not valid images of one size, which the means of
/// [`TemporalReport`] skip.
pub fn warped_difference(prev: &FloatImage, cur: &FloatImage, d: &[[f32; 2]], margin: u32) -> f64 {
    warped_change_map(prev, cur, d, margin).map_or(f64::NAN, |(diff, _, _)| mean_change(&diff))
}

/// The mean of a change map's measured pixels (NaN if none).
fn mean_change(diff: &[f64]) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for v in diff.iter().filter(|v| !v.is_nan()) {
        sum += v;
        n += 1;
    }
    if n == 0 {
        return f64::NAN;
    }
    sum / n as f64
}

/// Per pixel, |cur - prev warped by `d`| in grey (0-1), NaN where it cannot be measured
/// (within `margin` of the border, or warped from outside the frame); with the width and
/// height. None for frames that are not two valid images of one size.
fn warped_change_map(
    prev: &FloatImage,
    cur: &FloatImage,
    d: &[[f32; 2]],
    margin: u32,
) -> Option<(Vec<f64>, usize, usize)> {
    if prev.validate().is_err()
        || cur.validate().is_err()
        || (prev.width, prev.height) != (cur.width, cur.height)
    {
        return None;
    }
    let (a, b) = (prev.to_grey(), cur.to_grey());
    let (w, h) = (b.width as usize, b.height as usize);
    let m = margin as usize;
    let mut out = vec![f64::NAN; w * h];
    for y in m..h.saturating_sub(m) {
        for x in m..w.saturating_sub(m) {
            let v = d.get(y * w + x).copied().unwrap_or([0.0; 2]);
            let (fx, fy) = (x as f32 - v[0], y as f32 - v[1]);
            let (x0, y0) = (fx.floor(), fy.floor());
            if x0 < 0.0 || y0 < 0.0 || x0 as usize + 1 >= w || y0 as usize + 1 >= h {
                continue;
            }
            let (tx, ty) = ((fx - x0) as f64, (fy - y0) as f64);
            let (x0, y0) = (x0 as usize, y0 as usize);
            let p = |xx: usize, yy: usize| a.data[yy * w + xx] as f64;
            let s = p(x0, y0) * (1.0 - tx) * (1.0 - ty)
                + p(x0 + 1, y0) * tx * (1.0 - ty)
                + p(x0, y0 + 1) * (1.0 - tx) * ty
                + p(x0 + 1, y0 + 1) * tx * ty;
            out[y * w + x] = (b.data[y * w + x] as f64 - s).abs();
        }
    }
    Some((out, w, h))
}

/// Side of the blocks [`pop_fraction`] looks at, in pixels.
pub const POP_BLOCK: usize = 8;
/// The mean warped change (0-1, grey) beyond which [`pop_fraction`] counts a block.
pub const POP_CHANGE: f64 = 0.15;

/// Popping between two frames: the fraction of the [`POP_BLOCK`]-pixel blocks (a grid
/// from the top left; only blocks measurable in full, see [`warped_difference`]) whose
/// mean change from `prev` warped by `d` exceeds [`POP_CHANGE`]. A patch that changes at
/// once counts where the same change spread thinly over the frame (seams that move) does
/// not. NaN for frames that are not two valid images of one size or have no such block.
pub fn pop_fraction(prev: &FloatImage, cur: &FloatImage, d: &[[f32; 2]], margin: u32) -> f64 {
    warped_change_map(prev, cur, d, margin).map_or(f64::NAN, |(diff, w, h)| block_pops(&diff, w, h))
}

/// [`pop_fraction`] of a change map.
fn block_pops(diff: &[f64], w: usize, h: usize) -> f64 {
    let (mut blocks, mut pops) = (0usize, 0usize);
    for by in 0..h / POP_BLOCK {
        for bx in 0..w / POP_BLOCK {
            let mut sum = 0.0;
            let mut full = true;
            for y in by * POP_BLOCK..(by + 1) * POP_BLOCK {
                for x in bx * POP_BLOCK..(bx + 1) * POP_BLOCK {
                    let v = diff[y * w + x];
                    full &= !v.is_nan();
                    sum += v;
                }
            }
            if full {
                blocks += 1;
                pops += (sum / (POP_BLOCK * POP_BLOCK) as f64 > POP_CHANGE) as usize;
            }
        }
    }
    if blocks == 0 {
        return f64::NAN;
    }
    pops as f64 / blocks as f64
}

/// The temporal figures of `frames` advected by `displacement(t)` (per-pixel motion
/// between frame t-1 and t, pixels). Texture energy is computed every `energy_every`
/// frames (and for the last one): it is the costly figure.
pub fn temporal_report(
    exemplar: &FloatImage,
    frames: &[FloatImage],
    displacement: impl Fn(usize) -> Vec<[f32; 2]>,
    energy_every: usize,
) -> Result<TemporalReport> {
    let mut figures = TemporalFigures::new(exemplar, energy_every);
    for (t, f) in frames.iter().enumerate() {
        let d = if t > 0 { displacement(t) } else { Vec::new() };
        figures.push(f.clone(), &d)?;
    }
    figures.finish()
}

/// [`temporal_report`] one frame at a time, keeping only the previous and the last
/// frame: memory stays flat however many frames an advection runs.
pub struct TemporalFigures {
    exemplar: FloatImage,
    exemplar_hf: f64,
    every: usize,
    report: TemporalReport,
    prev: Option<FloatImage>,
    /// Frame index of `prev`, and whether its energy is already in the report.
    prev_index: usize,
    prev_has_energy: bool,
}

impl TemporalFigures {
    /// Figures against `exemplar`, texture energy every `energy_every` frames (frame 0
    /// included; the last one is added by [`Self::finish`]). A flat exemplar has no
    /// high frequencies to compare with: the sharpness figures are then NaN (`null` in
    /// `texsyn eval`'s JSON).
    pub fn new(exemplar: &FloatImage, energy_every: usize) -> Self {
        let hf = high_frequency_energy(exemplar);
        Self {
            exemplar: exemplar.clone(),
            exemplar_hf: if hf > 0.0 { hf } else { f64::NAN },
            every: energy_every.max(1),
            report: TemporalReport::default(),
            prev: None,
            prev_index: 0,
            prev_has_energy: false,
        }
    }

    /// The same for a sequence whose first frame is frame `first` (a folder of frames
    /// that starts later): the energies are labelled with the frames' own numbers and
    /// taken on the first frame, the multiples of `energy_every` and the last.
    pub fn starting_at(mut self, first: usize) -> Self {
        self.prev_index = first;
        self
    }

    /// The next frame, with the displacement (pixels) that carried the previous frame to
    /// it (ignored for the first frame).
    pub fn push(&mut self, frame: FloatImage, displacement: &[[f32; 2]]) -> Result<()> {
        frame.validate()?;
        if let Some(prev) = &self.prev {
            if (prev.width, prev.height) != (frame.width, frame.height) {
                return Err(invalid(format!(
                    "frame of {}x{} after one of {}x{}: the frames must all have one size",
                    frame.width, frame.height, prev.width, prev.height
                )));
            }
            if prev.channels != frame.channels {
                return Err(invalid(format!(
                    "frame of {} channels after one of {}: the frames must be all grey or all \
                     colour",
                    frame.channels, prev.channels
                )));
            }
            let n = frame.width as usize * frame.height as usize;
            if !displacement.is_empty() && displacement.len() != n {
                return Err(invalid(format!(
                    "{} displacements for {n} pixels",
                    displacement.len()
                )));
            }
        }
        let t = match &self.prev {
            None => self.prev_index,
            Some(_) => self.prev_index + 1,
        };
        self.report
            .sharpness
            .push(high_frequency_energy(&frame) / self.exemplar_hf);
        if let Some(prev) = &self.prev {
            // One change map for both figures.
            let (warped, pops) = warped_change_map(prev, &frame, displacement, 4)
                .map_or((f64::NAN, f64::NAN), |(diff, w, h)| {
                    (mean_change(&diff), block_pops(&diff, w, h))
                });
            self.report.warped_diff.push(warped);
            self.report.pops.push(pops);
            // An empty displacement reads as zero everywhere.
            self.report
                .unwarped_diff
                .push(warped_difference(prev, &frame, &[], 4));
        }
        // The first frame always (a folder may start after frame 0), then the multiples.
        let energy = self.prev.is_none() || t % self.every == 0;
        if energy {
            self.report
                .energy
                .push((t, texture_energy(&self.exemplar, &frame, 2)?));
        }
        self.prev = Some(frame);
        self.prev_index = t;
        self.prev_has_energy = energy;
        Ok(())
    }

    /// The report, with the last frame's texture energy.
    pub fn finish(mut self) -> Result<TemporalReport> {
        if let (Some(last), false) = (&self.prev, self.prev_has_energy) {
            self.report
                .energy
                .push((self.prev_index, texture_energy(&self.exemplar, last, 2)?));
        }
        Ok(self.report)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grey(w: u32, h: u32, f: impl Fn(u32, u32) -> f32) -> FloatImage {
        let data = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| f(x, y));
        FloatImage {
            width: w,
            height: h,
            channels: 1,
            data: data.collect(),
        }
    }

    /// A patch that changes at once pops; the same total change spread thinly does not;
    /// blocks not measurable in full (the margin) are left out.
    #[test]
    fn a_patch_that_changes_at_once_pops() {
        let (w, h) = (40u32, 32u32);
        let base = |x: u32, y: u32| ((x * 7 + y * 13) % 10) as f32 / 10.0;
        let a = grey(w, h, base);
        assert_eq!(pop_fraction(&a, &a, &[], 0), 0.0);
        // One 8x8 block (x 16..24, y 8..16) changed: 1 of the 4x3 blocks measurable in
        // full (the last column and row have no right or lower neighbour to warp from).
        let b = grey(w, h, |x, y| {
            let v = base(x, y);
            if (16..24).contains(&x) && (8..16).contains(&y) {
                1.0 - v * 0.5
            } else {
                v
            }
        });
        assert!((pop_fraction(&a, &b, &[], 0) - 1.0 / 12.0).abs() < 1e-12);
        // With a margin of 4 the border blocks are not measurable in full: 2 of 3x2.
        assert!((pop_fraction(&a, &b, &[], 4) - 1.0 / 6.0).abs() < 1e-12);
        // A one-pixel column changed by 0.9 in every block: a seam, not a pop.
        let c = grey(w, h, |x, y| {
            if x % 8 == 3 {
                1.0 - base(x, y)
            } else {
                base(x, y)
            }
        });
        assert_eq!(pop_fraction(&a, &c, &[], 0), 0.0);
        assert!(warped_difference(&a, &c, &[], 0) > 0.05);
        // Frames of other sizes have no figure.
        assert!(pop_fraction(&a, &grey(8, 8, base), &[], 0).is_nan());
    }

    /// The figures follow the flow: a uniform shift of whole pixels, warped back, changes
    /// nothing; unwarped, the shifted texture pops everywhere.
    #[test]
    fn pops_are_measured_after_warping() {
        let (w, h) = (32u32, 32u32);
        let base = |x: u32, y: u32| ((x * 7 + y * 13) % 10) as f32 / 10.0;
        let a = grey(w, h, base);
        let b = grey(w, h, |x, y| base(x.wrapping_sub(3) % 1000, y));
        let d = vec![[3.0f32, 0.0]; (w * h) as usize];
        assert_eq!(pop_fraction(&a, &b, &d, 0), 0.0);
        assert_eq!(warped_difference(&a, &b, &d, 0), 0.0);
        assert!(pop_fraction(&a, &b, &[], 0) > 0.5);
    }
}
