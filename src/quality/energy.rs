//! Texture energy: how far the output's neighbourhoods are from the exemplar's.
//!
//! Each `(2r+1)^2` window of the output is matched with its nearest window of the
//! exemplar; the figure is the mean squared per-channel difference of the pairs, in
//! `[0, 1]`. 0 means every output window occurs in the exemplar (a verbatim copy also
//! scores 0, which the verbatim-copy figures catch); blur, seams and invented
//! structure raise it. [`multiscale_energy`] repeats it at half and quarter resolution,
//! where it reads the layout of larger features, and [`coarse_energy_any_phase`] does so
//! without depending on where the downsampling grid falls.

use std::borrow::Cow;

use super::common::{invalid, parallel_map};
use super::image::{matched, FloatImage};
use super::windows::{dot, pca_basis, Windows};
use crate::analysis::kdtree::KdTree;
use crate::error::Result;

/// Neighbourhood radius used by `texsyn eval` unless told otherwise (7x7 windows).
pub const DEFAULT_RADIUS: u32 = 3;

/// Dimensions kept by the PCA of [`texture_energy`].
const PCA_DIMS: usize = 16;
/// Candidates taken from the kd-tree in PCA space, then compared in full dimension.
const CANDIDATES: usize = 8;
/// Budget of the approximate kd-tree search (points examined).
const MAX_CHECKS: usize = 192;
/// Output rows per work item of [`texture_energy`] (fixed, so that results do not
/// depend on the number of threads).
const BAND_ROWS: usize = 8;

/// Matches channels and checks that both images hold at least one window of side
/// `2 * radius + 1`. Returns the matched images and the side.
fn prepare<'a>(
    exemplar: &'a FloatImage,
    output: &'a FloatImage,
    radius: u32,
) -> Result<(Cow<'a, FloatImage>, Cow<'a, FloatImage>, usize)> {
    let (ex, out) = matched(exemplar, output)?;
    let side = 2 * radius as u64 + 1;
    for (what, img) in [("exemplar", &ex), ("output", &out)] {
        if (img.width as u64) < side || (img.height as u64) < side {
            return Err(invalid(format!(
                "{what} is {}x{}, smaller than the {side}x{side} neighbourhood window (radius {radius})",
                img.width, img.height
            )));
        }
    }
    Ok((ex, out, side as usize))
}

/// Texture energy: the mean, over all `(2r+1)^2` windows lying fully inside `output`,
/// of the squared distance to the nearest window lying fully inside `exemplar`,
/// divided by the number of values in a window (a mean squared per-channel
/// difference, in `[0, 1]`). 0 when every output window occurs in the exemplar.
///
/// Approximate but nearly exact: the nearest window is searched among candidates
/// compared at full dimension: the shifted matches of the left and upper neighbours,
/// and the 8 nearest exemplar windows in a 16-dimensional PCA space (found with an
/// approximate kd-tree search, among windows whose projected distance, a lower bound
/// of the full one, still beats the best candidate). Every figure is a true
/// distance, so the result is an upper bound of [`texture_energy_exact`], a few percent
/// above it (most of the gap from the 16 dimensions kept). Deterministic, independent
/// of the number of threads. Windows of at most 16 values (grey, radius 1) are searched
/// exactly.
///
/// Errors: an image that is empty, inconsistent or smaller than the window.
pub fn texture_energy(exemplar: &FloatImage, output: &FloatImage, radius: u32) -> Result<f64> {
    Ok(mean_energy(&texture_energy_map(exemplar, output, radius)?))
}

/// An [`EnergyMap`]'s mean per value: summed per band of rows, then over bands, in a
/// fixed order (deterministic).
fn mean_energy(map: &EnergyMap) -> f64 {
    let sums = map
        .values
        .chunks(BAND_ROWS * map.width as usize)
        .map(|band| band.iter().map(|&v| v as f64).sum::<f64>());
    sums.sum::<f64>() / (map.values.len() as f64 * map.dim as f64)
}

/// Per-window figures of [`texture_energy`]: the squared distance of every output
/// window to its nearest exemplar window (divide by `dim` for a mean squared
/// per-channel difference). Window `(x, y)` is centred on output pixel
/// `(x + r, y + r)`.
#[derive(Clone, Debug, PartialEq)]
pub struct EnergyMap {
    /// Windows per row: the output width minus `2r`.
    pub width: u32,
    /// Windows per column: the output height minus `2r`.
    pub height: u32,
    /// Values per window (`(2r+1)^2 x channels`).
    pub dim: u32,
    /// Row-major squared distances, `width x height`.
    pub values: Vec<f32>,
}

impl EnergyMap {
    /// A heat map for display: each window's mean squared per-channel difference,
    /// scaled so that `full_scale` is white, as grey `u8`, `width x height`.
    pub fn to_grey8(&self, full_scale: f32) -> Vec<u8> {
        let k = 255.0 / (full_scale.max(f32::MIN_POSITIVE) * self.dim as f32);
        self.values
            .iter()
            .map(|&v| (v * k).round().clamp(0.0, 255.0) as u8)
            .collect()
    }
}

/// [`texture_energy`] window by window (see there for the search).
pub fn texture_energy_map(
    exemplar: &FloatImage,
    output: &FloatImage,
    radius: u32,
) -> Result<EnergyMap> {
    let (ex, out, side) = prepare(exemplar, output, radius)?;
    let exw = Windows::new(&ex, side);
    let outw = Windows::new(&out, side);
    let dim = exw.dim();
    let m = exw.count();

    // Search space: PCA projection, or the windows themselves when they are small.
    let exact = dim <= PCA_DIMS;
    let basis: Vec<f32> = if exact {
        Vec::new()
    } else {
        pca_basis(&exw, PCA_DIMS)
    };
    let pdim = if exact { dim } else { basis.len() / dim };
    let project = |q: &[f32], y: &mut [f32]| {
        if exact {
            y.copy_from_slice(q);
        } else {
            for (v, b) in y.iter_mut().zip(basis.chunks_exact(dim)) {
                *v = dot(b, q);
            }
        }
    };
    const CHUNK: usize = 1024;
    let points: Vec<f32> = parallel_map(m.div_ceil(CHUNK), |ci| {
        let mut q = vec![0.0f32; dim];
        let mut pts = vec![0.0f32; pdim * CHUNK.min(m - ci * CHUNK)];
        for (k, y) in pts.chunks_exact_mut(pdim).enumerate() {
            let i = ci * CHUNK + k;
            exw.gather(i % exw.nx, i / exw.nx, &mut q);
            project(&q, y);
        }
        pts
    })
    .concat();
    let tree = KdTree::build(points, pdim);
    let (k, checks) = if exact {
        (1, 0)
    } else {
        (CANDIDATES, MAX_CHECKS)
    };

    let bands = outw.ny.div_ceil(BAND_ROWS);
    let sums = parallel_map(bands, |b| {
        let mut q = vec![0.0f32; dim];
        let mut p = vec![0.0f32; pdim];
        let mut cand: Vec<(f32, u32)> = Vec::with_capacity(k + 1);
        // Best exemplar window of each output window of the previous row (in this band).
        let mut above: Vec<u32> = vec![u32::MAX; outw.nx];
        let mut values = Vec::with_capacity(BAND_ROWS * outw.nx);
        for y in b * BAND_ROWS..((b + 1) * BAND_ROWS).min(outw.ny) {
            let mut left = u32::MAX;
            for (x, above) in above.iter_mut().enumerate() {
                outw.gather(x, y, &mut q);
                let mut best = f32::INFINITY;
                let mut best_i = u32::MAX;
                let consider = |i: u32, best: &mut f32, best_i: &mut u32| {
                    let (ix, iy) = (i as usize % exw.nx, i as usize / exw.nx);
                    let d = exw.distance(&q, ix, iy, *best);
                    if d < *best || (d == *best && i < *best_i) {
                        *best = d;
                        *best_i = i;
                    }
                };
                // Coherent candidates: the neighbours' matches, shifted.
                if left != u32::MAX && (left as usize % exw.nx) + 1 < exw.nx {
                    consider(left + 1, &mut best, &mut best_i);
                }
                let up = *above;
                if up != u32::MAX && (up as usize / exw.nx) + 1 < exw.ny {
                    consider(up + exw.nx as u32, &mut best, &mut best_i);
                }
                project(&q, &mut p);
                // Candidates: the nearest windows in the projected space among those
                // that can still improve on `best` (projected distances are lower
                // bounds of the full ones), then compared in full.
                cand.clear();
                tree.search(&p, best, checks, |i, d| {
                    let pos = cand.partition_point(|&(cd, ci)| (cd, ci) < (d, i));
                    if pos < k {
                        cand.insert(pos, (d, i));
                        cand.truncate(k);
                    }
                    if cand.len() == k {
                        best.min(cand[k - 1].0)
                    } else {
                        best
                    }
                });
                for &(_, i) in cand.iter() {
                    consider(i, &mut best, &mut best_i);
                }
                values.push(best);
                left = best_i;
                *above = best_i;
            }
        }
        values
    });
    Ok(EnergyMap {
        width: outw.nx as u32,
        height: outw.ny as u32,
        dim: dim as u32,
        values: sums.concat(),
    })
}

/// [`texture_energy`] by brute force (every output window against every exemplar
/// window). For tests and small images: the cost is
/// `output windows x exemplar windows x window values`.
pub fn texture_energy_exact(
    exemplar: &FloatImage,
    output: &FloatImage,
    radius: u32,
) -> Result<f64> {
    let (ex, out, side) = prepare(exemplar, output, radius)?;
    let exw = Windows::new(&ex, side);
    let outw = Windows::new(&out, side);
    let dim = exw.dim();
    let sums = parallel_map(outw.ny, |y| {
        let mut q = vec![0.0f32; dim];
        let mut sum = 0.0f64;
        for x in 0..outw.nx {
            outw.gather(x, y, &mut q);
            let mut best = f32::INFINITY;
            for ey in 0..exw.ny {
                for ex in 0..exw.nx {
                    best = best.min(exw.distance(&q, ex, ey, best));
                }
            }
            sum += best as f64;
        }
        sum
    });
    Ok(sums.iter().sum::<f64>() / (outw.count() as f64 * dim as f64))
}

/// [`texture_energy`] at full, half and quarter resolution (both images downsampled
/// with [`FloatImage::downsample2`]). A coarser scale at which either image is smaller
/// than the window is `NaN` (`null` in JSON); the full scale must be computable.
pub fn multiscale_energy(
    exemplar: &FloatImage,
    output: &FloatImage,
    radius: u32,
) -> Result<[f64; 3]> {
    let full = texture_energy(exemplar, output, radius)?;
    let (e2, o2) = (exemplar.downsample2(), output.downsample2());
    let half = texture_energy(&e2, &o2, radius).unwrap_or(f64::NAN);
    let quarter = texture_energy(&e2.downsample2(), &o2.downsample2(), radius).unwrap_or(f64::NAN);
    Ok([full, half, quarter])
}

/// [`texture_energy`] against several exemplar images at once: each output window's
/// nearest window over all of them (images too small for the window are skipped; all
/// too small is an error).
pub fn texture_energy_any(
    exemplars: &[FloatImage],
    output: &FloatImage,
    radius: u32,
) -> Result<f64> {
    Ok(energy_union(exemplars, output, radius)?.0)
}

/// [`texture_energy_any`], and the energy against the first image alone when its map
/// could be computed (`NaN` otherwise): one search per image.
fn energy_union(exemplars: &[FloatImage], output: &FloatImage, radius: u32) -> Result<(f64, f64)> {
    let mut best: Option<EnergyMap> = None;
    let mut first = f64::NAN;
    let mut first_err = None;
    for (i, ex) in exemplars.iter().enumerate() {
        match texture_energy_map(ex, output, radius) {
            Ok(map) => {
                if i == 0 {
                    first = mean_energy(&map);
                }
                match &mut best {
                    None => best = Some(map),
                    Some(b) => {
                        for (v, n) in b.values.iter_mut().zip(map.values) {
                            *v = v.min(n);
                        }
                    }
                }
            }
            Err(e) => {
                first_err.get_or_insert(e);
            }
        }
    }
    match best {
        Some(m) => Ok((mean_energy(&m), first)),
        None => Err(first_err.unwrap_or_else(|| invalid("texture_energy_any: no exemplar image"))),
    }
}

/// [`multiscale_energy`]'s half and quarter figures without its dependence on where the
/// downsampling grid falls: the output, downsampled from its origin, is matched against
/// the exemplar downsampled at every grid offset (4 at half resolution, 16 at quarter),
/// so a patch copied at an odd exemplar position scores as one copied at an even one.
/// The grid figures swing with the parity of a few large patches (cropping an output by
/// one pixel can change them markedly); these do not. Returns `[half, quarter]`; `NaN`
/// where the coarser images are smaller than the window.
pub fn coarse_energy_any_phase(
    exemplar: &FloatImage,
    output: &FloatImage,
    radius: u32,
) -> Result<[f64; 2]> {
    Ok(coarse_energies(exemplar, output, radius)?.1)
}

/// Half and quarter resolution energies both ways: `(grid, any_phase)`, the grid ones
/// being [`multiscale_energy`]'s (the offset at the origin, searched once for both).
pub(super) fn coarse_energies(
    exemplar: &FloatImage,
    output: &FloatImage,
    radius: u32,
) -> Result<([f64; 2], [f64; 2])> {
    exemplar.validate()?;
    output.validate()?;
    let o2 = output.downsample2();
    let o4 = o2.downsample2();
    // The exemplar cropped by every offset under `f`, then downsampled `f` times; the
    // offset (0, 0) first (the uncropped exemplar, as `multiscale_energy` downsamples it).
    let shifted = |f: u32| -> Result<Vec<FloatImage>> {
        let mut v = Vec::new();
        for dy in 0..f {
            for dx in 0..f {
                if exemplar.width <= dx + f || exemplar.height <= dy + f {
                    continue;
                }
                let mut e = exemplar.crop(dx, dy, exemplar.width - dx, exemplar.height - dy)?;
                let mut s = 1;
                while s < f {
                    e = e.downsample2();
                    s *= 2;
                }
                v.push(e);
            }
        }
        Ok(v)
    };
    let nan = (f64::NAN, f64::NAN);
    let (half_any, half) = energy_union(&shifted(2)?, &o2, radius).unwrap_or(nan);
    let (quarter_any, quarter) = energy_union(&shifted(4)?, &o4, radius).unwrap_or(nan);
    Ok(([half, quarter], [half_any, quarter_any]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quality::test_images::{noise_image, texture};

    #[test]
    fn energy_map_agrees_with_the_mean() {
        let ex = noise_image(24, 24, 3, 1);
        let out = noise_image(40, 30, 3, 2);
        let map = texture_energy_map(&ex, &out, 3).unwrap();
        assert_eq!((map.width, map.height, map.dim), (34, 24, 147));
        let mean = map.values.iter().map(|&v| v as f64).sum::<f64>() / (34.0 * 24.0 * 147.0);
        let e = texture_energy(&ex, &out, 3).unwrap();
        assert!((mean - e).abs() <= 1e-9 * e, "{mean} vs {e}");
        // The exemplar itself has zero energy everywhere.
        assert!(texture_energy_map(&ex, &ex, 3)
            .unwrap()
            .values
            .iter()
            .all(|&v| v == 0.0));
    }

    #[test]
    fn fast_energy_is_close_to_exact() {
        for &(c, r) in &[(3u32, 3u32), (1, 3), (3, 1), (1, 2)] {
            let ex = texture(40, 36, c, 1);
            let out = texture(50, 45, c, 2);
            let fast = texture_energy(&ex, &out, r).unwrap();
            let exact = texture_energy_exact(&ex, &out, r).unwrap();
            assert!(
                fast >= exact * (1.0 - 1e-5),
                "c={c} r={r}: fast {fast} below exact {exact}"
            );
            assert!(
                fast <= exact * 1.03,
                "c={c} r={r}: fast {fast} vs exact {exact}"
            );
            // Deterministic.
            assert_eq!(fast, texture_energy(&ex, &out, r).unwrap());
        }
    }
}
