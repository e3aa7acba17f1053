//! Appearance space (Lefebvre & Hoppe 2006 §3): per level, every exemplar pixel's 5x5
//! Gaussian-weighted neighbourhood (spacing `h_l`) is reduced by PCA to 8 numbers, the
//! transformed exemplar `Et_l`. Then the runtime neighbourhood of a pixel, `Et_l` at its
//! four diagonal neighbours (32D), is reduced by a second PCA to the basis `P_l` (8x32).
//! Finally both are quantized to integers: the GPU compares integer sums, so GPU and CPU
//! results are identical regardless of floating-point contraction or summation order.
//!
//! The float work runs in f32 (the results are quantized to 12 bits) with per-level
//! tables of the wrapped or clamped neighbour coordinates; only the PCA covariance is
//! accumulated in f64 (see [`Pca::fit`]).

use super::pca::Pca;
use super::stack::Plane;
use super::{par_fill, par_ranges, AppearanceSpace, DIAGONALS, DIM, ET_QMAX, PROJ_QMAX, QE_MAX};

/// At most this many pixels feed a covariance estimate (strided sample); beyond it the
/// estimate no longer changes visibly and the analysis stays fast on large exemplars.
const MAX_PCA_SAMPLES: usize = 16384;

/// Binomial weights of the 5x5 neighbourhood, centre weight 1.
const NEIGHBOURHOOD_WEIGHTS: [f32; 5] = [1.0 / 6.0, 4.0 / 6.0, 1.0, 4.0 / 6.0, 1.0 / 6.0];

fn sample_index(i: usize, count: usize, n: usize) -> usize {
    if count >= n {
        i
    } else {
        (i as u64 * n as u64 / count as u64) as usize
    }
}

/// Coordinate `i + d` wrapped into `0..n` (tileable) or clamped to it.
#[inline]
fn wrap(i: i64, n: usize, tileable: bool) -> usize {
    if tileable {
        i.rem_euclid(n as i64) as usize
    } else {
        i.clamp(0, n as i64 - 1) as usize
    }
}

/// `table[t * n + i]` = wrapped/clamped `i + taps[t] * spacing`, for each tap `t`.
fn tap_table(n: usize, spacing: u32, taps: &[i32], tileable: bool) -> Vec<u32> {
    let mut t = Vec::with_capacity(taps.len() * n);
    for &d in taps {
        for i in 0..n {
            t.push(wrap(i as i64 + d as i64 * spacing as i64, n, tileable) as u32);
        }
    }
    t
}

const TAPS5: [i32; 5] = [-2, -1, 0, 1, 2];

/// Float transformed exemplar of one level and the PCA residual variance.
///
/// `space` chooses the appearance vector: the Gaussian-weighted 5x5 neighbourhood
/// (`25 * channels` values, the paper's appearance space) or the pixel's own channels
/// (`channels` values: plain colour, the paper's Figure 4 comparison). Either way it is
/// reduced by PCA to `DIM` numbers; with fewer than `DIM` input dimensions the remaining
/// components of `Et` are zero, so synthesis runs unchanged.
pub fn transformed_exemplar(
    plane: &Plane,
    spacing: u32,
    tileable: bool,
    space: AppearanceSpace,
    threads: usize,
) -> (Vec<[f32; DIM]>, f64) {
    let (w, h, c) = (
        plane.width as usize,
        plane.height as usize,
        plane.channels as usize,
    );
    let n = w * h;
    let (taps, weights): (&[i32], &[f32]) = match space {
        AppearanceSpace::Neighborhood => (&TAPS5, &NEIGHBOURHOOD_WEIGHTS),
        AppearanceSpace::Color => (&[0], &[1.0]),
    };
    let nt = taps.len();
    let dim = nt * nt * c;
    let xs = tap_table(w, spacing, taps, tileable);
    let ys = tap_table(h, spacing, taps, tileable);
    // Per-channel mean, subtracted before the covariance accumulation (accuracy).
    let mut mean = vec![0.0f64; c];
    for px in plane.data.chunks_exact(c) {
        for (m, &v) in mean.iter_mut().zip(px) {
            *m += v as f64;
        }
    }
    let mean: Vec<f32> = mean.iter().map(|m| (m / n as f64) as f32).collect();
    let data = &plane.data;
    let gather = |x: usize, y: usize, out: &mut [f32]| {
        let mut o = 0;
        for dy in 0..nt {
            let row = ys[dy * h + y] as usize * w;
            let wy = weights[dy];
            for dx in 0..nt {
                let wt = wy * weights[dx];
                let i = (row + xs[dx * w + x] as usize) * c;
                for ch in 0..c {
                    out[o] = (data[i + ch] - mean[ch]) * wt;
                    o += 1;
                }
            }
        }
    };
    let count = n.min(MAX_PCA_SAMPLES);
    let pca = Pca::fit(dim, count, DIM, threads, |i, out| {
        let p = sample_index(i, count, n);
        gather(p % w, p / w, out);
    });
    // Et_k(p) = sum_j comp_k[j] * (v_j(p) - mean_j): a 5x5 filter bank on the
    // channel-centred plane, with the neighbourhood weights folded into the taps.
    let mut coef = vec![[0.0f32; DIM]; dim];
    let mut bias = [0.0f32; DIM];
    for (k, comp) in pca.components.iter().enumerate() {
        let mut b = 0.0f64;
        for (j, cf) in coef.iter_mut().enumerate() {
            let (dy, dx) = (j / c / nt, j / c % nt);
            cf[k] = (comp[j] * (weights[dy] * weights[dx]) as f64) as f32;
            b -= comp[j] * pca.mean[j];
        }
        bias[k] = b as f32;
    }
    // Centred plane, so that the filter input matches the PCA samples.
    let centred: Vec<f32> = data
        .iter()
        .enumerate()
        .map(|(i, v)| v - mean[i % c])
        .collect();
    let mut et = vec![[0.0f32; DIM]; n];
    par_fill(&mut et, w, threads, |rows, out| {
        let mut o = 0;
        for y in rows {
            for x in 0..w {
                let mut e = bias;
                let mut j = 0;
                for dy in 0..nt {
                    let row = ys[dy * h + y] as usize * w;
                    for dx in 0..nt {
                        let i = (row + xs[dx * w + x] as usize) * c;
                        for ch in 0..c {
                            let v = centred[i + ch];
                            let cf = &coef[j];
                            for k in 0..DIM {
                                e[k] += v * cf[k];
                            }
                            j += 1;
                        }
                    }
                }
                out[o] = e;
                o += 1;
            }
        }
    });
    (et, pca.residual_variance())
}

/// Quantized level data computed from the float transformed exemplar.
pub struct QuantizedLevel {
    /// `Et_l` quantized with one scale per level to `[-ET_QMAX, ET_QMAX]`, row-major.
    pub et: Vec<[i16; DIM]>,
    /// Runtime projection `P_l`: unit rows scaled by [`PROJ_QMAX`] and rounded; row `r`,
    /// column `j * DIM + c` weighs component `c` of diagonal neighbour `j` (`DIAGONALS`
    /// order). Rows past the PCA's components are zero.
    pub proj: [[i16; 4 * DIM]; DIM],
    /// `(3 * P_l * N_E(u)) >> shift` per pixel, row-major: the exemplar side of the
    /// correction distance, each value within `[-QE_MAX, QE_MAX]`.
    pub qe: Vec<[i16; DIM]>,
    /// Smallest right shift that brings every exemplar-side product into [`QE_MAX`].
    pub shift: u32,
    /// Fraction of the 32D runtime-neighbourhood variance not kept by `P_l`.
    pub runtime_residual: f64,
    /// Float features for similarity search: `Et(u)` and the projected runtime
    /// neighbourhood, 16 floats per pixel.
    pub features: Vec<f32>,
}

/// Floats per pixel in [`QuantizedLevel::features`]: `Et(u)` then the projected runtime
/// neighbourhood.
pub const FEATURE_DIM: usize = 2 * DIM;

/// `x.round() as i16` (halves away from zero) without the libm call that `round`
/// compiles to on baseline x86-64: add the largest float below one half with `x`'s
/// sign, then truncate (the expansion LLVM uses for `round` where the target rounds
/// natively). Checked equal to `round` on every finite f32 of magnitude below 40000
/// (the quantization scales keep `|x|` at most [`ET_QMAX`]); several times faster.
#[inline(always)]
fn round_i16(x: f32) -> i16 {
    (x + 0.499_999_97f32.copysign(x)) as i32 as i16
}

/// Runtime neighbourhood basis and quantization of one level.
///
/// Work goes by rows on the analysis threads: per pixel the diagonal neighbours come
/// from the wrapped/clamped tap tables (no division), and the quantization of `Et` and
/// of `3 P N_E` runs in parallel too (on a 512 px exemplar these single-threaded steps
/// were over half of this function's time).
pub fn quantize_level(
    et: &[[f32; DIM]],
    width: u32,
    height: u32,
    spacing: u32,
    tileable: bool,
    threads: usize,
    with_features: bool,
) -> QuantizedLevel {
    let (w, h) = (width as usize, height as usize);
    let n = et.len();
    // Diagonal neighbour coordinates: tap 0 is -spacing, tap 1 is +spacing.
    let xs = tap_table(w, spacing, &[-1, 1], tileable);
    let ys = tap_table(h, spacing, &[-1, 1], tileable);
    let diag = |p: usize, j: usize| {
        let (x, y) = (p % w, p / w);
        let d = DIAGONALS[j];
        let tx = (d[0] > 0) as usize;
        let ty = (d[1] > 0) as usize;
        ys[ty * h + y] as usize * w + xs[tx * w + x] as usize
    };
    let runtime = |p: usize, out: &mut [f32]| {
        for j in 0..4 {
            out[j * DIM..(j + 1) * DIM].copy_from_slice(&et[diag(p, j)]);
        }
    };
    let count = n.min(MAX_PCA_SAMPLES);
    // Et is (close to) zero-mean: it is a PCA projection of (nearly) all pixels.
    let pca = Pca::fit(4 * DIM, count, DIM, threads, |i, out| {
        runtime(sample_index(i, count, n), out)
    });

    // Quantize Et with one scale per level (only distances within a level are compared).
    let max_abs = par_ranges(n, threads, |range| {
        et[range]
            .iter()
            .flat_map(|e| e.iter())
            .fold(0.0f32, |m, v| m.max(v.abs()))
    })
    .into_iter()
    .fold(0.0f32, f32::max);
    let scale = if max_abs > 1e-12 {
        ET_QMAX / max_abs
    } else {
        0.0
    };
    let mut et_q = vec![[0i16; DIM]; n];
    par_fill(&mut et_q, 1, threads, |range, out| {
        for (o, e) in out.iter_mut().zip(&et[range]) {
            *o = e.map(|v| round_i16(v * scale));
        }
    });
    let mut proj = [[0i16; 4 * DIM]; DIM];
    for (r, row) in proj.iter_mut().enumerate() {
        if let Some(c) = pca.components.get(r) {
            for (q, v) in row.iter_mut().zip(c) {
                *q = (v * PROJ_QMAX as f64).round() as i16;
            }
        }
    }
    // Transposed projection (column-major) for the per-pixel products below.
    let mut proj_t = [[0i32; DIM]; 4 * DIM];
    let mut pf_t = [[0.0f32; DIM]; 4 * DIM];
    for r in 0..DIM {
        for col in 0..4 * DIM {
            proj_t[col][r] = 3 * proj[r][col] as i32;
            if let Some(c) = pca.components.get(r) {
                // The 32D neighbourhood spans four pixels: halve it so both halves weigh alike.
                pf_t[col][r] = (c[col] * 0.5) as f32;
            }
        }
    }
    let mut pf_bias = [0.0f32; DIM];
    for (r, c) in pca.components.iter().enumerate() {
        pf_bias[r] = (-0.5 * c.iter().zip(&pca.mean).map(|(a, b)| a * b).sum::<f64>()) as f32;
    }
    // The four diagonal neighbours of (x, y), in DIAGONALS order.
    let taps = |x: usize, y: usize| {
        let mut t = [0usize; 4];
        for (j, d) in DIAGONALS.iter().enumerate() {
            let tx = (d[0] > 0) as usize;
            let ty = (d[1] > 0) as usize;
            t[j] = ys[ty * h + y] as usize * w + xs[tx * w + x] as usize;
        }
        t
    };
    // Exemplar side of the distance: 3 * P * N_E(u), exactly as the GPU forms
    // P * (sum of three predictions) for synthesized pixels. Also the float features
    // for the similarity sets: Et and the projected neighbourhood.
    let mut q_full = vec![[0i32; DIM]; n];
    par_fill(&mut q_full, w, threads, |rows, out| {
        let mut o = 0;
        for y in rows {
            for x in 0..w {
                let mut q = [0i32; DIM];
                for (j, &tj) in taps(x, y).iter().enumerate() {
                    let e = &et_q[tj];
                    for c in 0..DIM {
                        let (pq, ev) = (&proj_t[j * DIM + c], e[c] as i32);
                        for r in 0..DIM {
                            q[r] += pq[r] * ev;
                        }
                    }
                }
                out[o] = q;
                o += 1;
            }
        }
    });
    let mut features = Vec::new();
    if with_features {
        features = vec![0.0f32; n * FEATURE_DIM];
        par_fill(&mut features, w * FEATURE_DIM, threads, |rows, out| {
            let mut o = 0;
            for y in rows {
                for x in 0..w {
                    let mut f = pf_bias;
                    for (j, &tj) in taps(x, y).iter().enumerate() {
                        let ef = &et[tj];
                        for c in 0..DIM {
                            let (pf, efv) = (&pf_t[j * DIM + c], ef[c]);
                            for r in 0..DIM {
                                f[r] += pf[r] * efv;
                            }
                        }
                    }
                    out[o..o + DIM].copy_from_slice(&et[y * w + x]);
                    out[o + DIM..o + FEATURE_DIM].copy_from_slice(&f);
                    o += FEATURE_DIM;
                }
            }
        });
    }
    let max_q = par_ranges(n, threads, |range| {
        q_full[range]
            .iter()
            .flat_map(|q| q.iter())
            .fold(0i64, |m, &v| m.max((v as i64).abs()))
    })
    .into_iter()
    .max()
    .unwrap_or(0);
    let mut shift = 0u32;
    while (max_q >> shift) > QE_MAX as i64 {
        shift += 1;
    }
    let mut qe = vec![[0i16; DIM]; n];
    par_fill(&mut qe, 1, threads, |range, out| {
        for (dst, q) in out.iter_mut().zip(&q_full[range]) {
            *dst = q.map(|v| (v >> shift) as i16);
        }
    });
    QuantizedLevel {
        et: et_q,
        proj,
        qe,
        shift,
        runtime_residual: pca.residual_variance(),
        features,
    }
}

#[cfg(test)]
mod tests {
    use super::super::{analyze, AnalysisOptions, Exemplar};

    fn exemplar(w: u32, h: u32, channels: u32) -> Exemplar {
        let mut values = Vec::new();
        let mut colors = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let mut px = [0u8; 4];
                for c in 0..channels {
                    let v = (((x * 7 + y * 3 + c * 11) % 17) as f32 / 16.0 * 0.6
                        + (((x * 2654435761u32) ^ (y * 40503) ^ c).wrapping_mul(2246822519) >> 24)
                            as f32
                            / 255.0
                            * 0.4)
                        .min(1.0);
                    values.push(v);
                    px[c as usize] = (v * 255.0) as u8;
                }
                if channels == 1 {
                    px = [px[0], px[0], px[0], 255];
                }
                px[3] = 255;
                colors.push(px);
            }
        }
        Exemplar {
            width: w,
            height: h,
            channels,
            values,
            colors,
        }
    }

    #[test]
    fn analysis_does_not_depend_on_the_thread_count() {
        for (channels, tileable, k) in [(3, Some(true), 2), (1, Some(false), 3), (3, None, 4)] {
            let ex = exemplar(45, 38, channels);
            let run = |threads| {
                let opts = AnalysisOptions {
                    k,
                    tileable,
                    threads,
                    ..Default::default()
                };
                analyze(&ex, &opts, |_| {}).unwrap()
            };
            let a = run(1);
            assert_eq!(a, run(2));
            assert_eq!(a, run(7));
            // Levels whose neighbourhood spans the exemplar are not searched.
            for l in &a.levels {
                assert_eq!(l.offsets.len(), 45 * 38 * (k as usize - 1));
                if 4 * l.spacing >= 38 {
                    assert!(l.offsets.iter().all(|o| *o == [0, 0]));
                } else {
                    assert!(
                        l.offsets.iter().filter(|o| **o == [0, 0]).count() < l.offsets.len() / 10
                    );
                }
            }
        }
    }

    #[test]
    fn fast_rounding_matches_round() {
        // Ties, values next to ties, both signs, and a sweep over the quantized range.
        let mut xs = vec![0.0f32, -0.0, 0.5, -0.5, 1.5, -1.5, 2047.5, -2047.5];
        for t in [0.5f32, 1.5, 2.5, 1023.5, 2046.5] {
            for v in [t, -t] {
                xs.push(f32::from_bits(v.to_bits() - 1));
                xs.push(f32::from_bits(v.to_bits() + 1));
            }
        }
        let mut x = -2100.0f32;
        while x < 2100.0 {
            xs.push(x);
            x += 0.013_7;
        }
        for x in xs {
            assert_eq!(super::round_i16(x), x.round() as i16, "{x:e}");
        }
    }

    #[test]
    fn par_fill_matches_a_sequential_fill() {
        for (n, per_item) in [(1usize, 1usize), (63, 1), (65, 3), (1000, 7), (4096, 16)] {
            let expect: Vec<u64> = (0..n * per_item).map(|i| (i as u64) * 31 + 7).collect();
            for threads in [1, 2, 5] {
                let mut out = vec![0u64; n * per_item];
                super::super::par_fill(&mut out, per_item, threads, |items, part| {
                    assert_eq!(part.len(), items.len() * per_item);
                    for (o, i) in part.iter_mut().zip(items.start * per_item..) {
                        *o = (i as u64) * 31 + 7;
                    }
                });
                assert_eq!(out, expect, "n {n} per item {per_item} threads {threads}");
            }
        }
    }
}
