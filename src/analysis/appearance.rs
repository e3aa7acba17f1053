//! Appearance space (paper section 3): per level, every exemplar pixel's 5x5
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
use super::{par_ranges, AppearanceSpace, DIAGONALS, DIM, ET_QMAX, PROJ_QMAX, QE_MAX};

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
    let et = par_ranges(h, threads, |rows| {
        let mut out = Vec::with_capacity(rows.len() * w);
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
                out.push(e);
            }
        }
        out
    })
    .concat();
    (et, pca.residual_variance())
}

/// Quantized level data computed from the float transformed exemplar.
pub struct QuantizedLevel {
    pub et: Vec<[i16; DIM]>,
    pub proj: [[i16; 4 * DIM]; DIM],
    pub qe: Vec<[i16; DIM]>,
    pub shift: u32,
    pub runtime_residual: f64,
    /// Float features for similarity search: `Et(u)` and the projected runtime
    /// neighbourhood, 16 floats per pixel.
    pub features: Vec<f32>,
}

pub const FEATURE_DIM: usize = 2 * DIM;

/// Runtime neighbourhood basis and quantization of one level.
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
    let max_abs = et
        .iter()
        .flat_map(|e| e.iter())
        .fold(0.0f32, |m, v| m.max(v.abs()));
    let scale = if max_abs > 1e-12 {
        ET_QMAX / max_abs
    } else {
        0.0
    };
    let et_q: Vec<[i16; DIM]> = et
        .iter()
        .map(|e| e.map(|v| (v * scale).round() as i16))
        .collect();
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
    // Exemplar side of the distance: 3 * P * N_E(u), exactly as the GPU forms
    // P * (sum of three predictions) for synthesized pixels. Also the float features
    // for the similarity sets: Et and the projected neighbourhood.
    let parts = par_ranges(n, threads, |range| {
        let mut qs = Vec::with_capacity(range.len());
        let mut feats = Vec::with_capacity(range.len() * FEATURE_DIM * with_features as usize);
        for p in range {
            let mut q = [0i32; DIM];
            for j in 0..4 {
                let e = &et_q[diag(p, j)];
                for c in 0..DIM {
                    let (pq, ev) = (&proj_t[j * DIM + c], e[c] as i32);
                    for r in 0..DIM {
                        q[r] += pq[r] * ev;
                    }
                }
            }
            qs.push(q);
            if with_features {
                let mut f = pf_bias;
                for j in 0..4 {
                    let ef = &et[diag(p, j)];
                    for c in 0..DIM {
                        let (pf, efv) = (&pf_t[j * DIM + c], ef[c]);
                        for r in 0..DIM {
                            f[r] += pf[r] * efv;
                        }
                    }
                }
                feats.extend_from_slice(&et[p]);
                feats.extend_from_slice(&f);
            }
        }
        (qs, feats)
    });
    let mut q_full = Vec::with_capacity(n);
    let mut features = Vec::with_capacity(n * FEATURE_DIM);
    for (q, f) in parts {
        q_full.extend(q);
        features.extend(f);
    }
    let max_q = q_full
        .iter()
        .flat_map(|q| q.iter())
        .fold(0i64, |m, &v| m.max((v as i64).abs()));
    let mut shift = 0u32;
    while (max_q >> shift) > QE_MAX as i64 {
        shift += 1;
    }
    let qe = q_full
        .iter()
        .map(|q| q.map(|v| (v >> shift) as i16))
        .collect();
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
}
