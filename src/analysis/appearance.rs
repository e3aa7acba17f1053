//! Appearance space (paper section 3): per level, every exemplar pixel's 5x5
//! Gaussian-weighted neighbourhood (spacing `h_l`) is reduced by PCA to 8 numbers, the
//! transformed exemplar `Et_l`. Then the runtime neighbourhood of a pixel, `Et_l` at its
//! four diagonal neighbours (32D), is reduced by a second PCA to the basis `P_l` (8x32).
//! Finally both are quantized to integers: the GPU compares integer sums, so GPU and CPU
//! results are identical regardless of floating-point contraction or summation order.

use super::pca::Pca;
use super::stack::Plane;
use super::{par_ranges, DIAGONALS, DIM, ET_QMAX, PROJ_QMAX, QE_MAX};

/// At most this many pixels feed a covariance estimate (strided sample); beyond it the
/// estimate no longer changes visibly and the analysis stays fast on large exemplars.
const MAX_PCA_SAMPLES: usize = 65536;

/// Binomial weights of the 5x5 neighbourhood, centre weight 1.
const NEIGHBOURHOOD_WEIGHTS: [f64; 5] = [1.0 / 6.0, 4.0 / 6.0, 1.0, 4.0 / 6.0, 1.0 / 6.0];

fn sample_index(i: usize, count: usize, n: usize) -> usize {
    if count >= n {
        i
    } else {
        (i as u64 * n as u64 / count as u64) as usize
    }
}

fn gather_neighbourhood(
    plane: &Plane,
    x: i32,
    y: i32,
    spacing: i32,
    tileable: bool,
    out: &mut [f64],
) {
    let c = plane.channels as usize;
    let mut o = 0;
    for dy in -2i32..=2 {
        let wy = NEIGHBOURHOOD_WEIGHTS[(dy + 2) as usize];
        for dx in -2i32..=2 {
            let w = wy * NEIGHBOURHOOD_WEIGHTS[(dx + 2) as usize];
            let px = plane.at(x + dx * spacing, y + dy * spacing, tileable);
            for ch in 0..c {
                out[o] = px[ch] as f64 * w;
                o += 1;
            }
        }
    }
}

/// Float transformed exemplar of one level and the PCA residual variance.
pub fn transformed_exemplar(
    plane: &Plane,
    spacing: u32,
    tileable: bool,
    threads: usize,
) -> (Vec<[f32; DIM]>, f64) {
    let (w, h) = (plane.width as usize, plane.height as usize);
    let n = w * h;
    let dim = 25 * plane.channels as usize;
    let s = spacing as i32;
    let count = n.min(MAX_PCA_SAMPLES);
    let pca = Pca::fit(dim, count, DIM, threads, |i, out| {
        let p = sample_index(i, count, n);
        gather_neighbourhood(plane, (p % w) as i32, (p / w) as i32, s, tileable, out);
    });
    let et = par_ranges(n, threads, |range| {
        let mut v = vec![0.0f64; dim];
        let mut proj = [0.0f64; DIM];
        range
            .map(|p| {
                gather_neighbourhood(plane, (p % w) as i32, (p / w) as i32, s, tileable, &mut v);
                pca.project(&v, &mut proj[..pca.components.len()]);
                let mut e = [0.0f32; DIM];
                for (a, b) in e.iter_mut().zip(proj) {
                    *a = b as f32;
                }
                e
            })
            .collect::<Vec<_>>()
    })
    .concat();
    (et, pca.residual_variance())
}

fn read<T: Copy>(v: &[T], w: i32, h: i32, x: i32, y: i32, tileable: bool) -> T {
    let (x, y) = if tileable {
        (x.rem_euclid(w), y.rem_euclid(h))
    } else {
        (x.clamp(0, w - 1), y.clamp(0, h - 1))
    };
    v[(y * w + x) as usize]
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
) -> QuantizedLevel {
    let (w, h) = (width as i32, height as i32);
    let n = et.len();
    let s = spacing as i32;
    let runtime = |p: usize, out: &mut [f64]| {
        let (x, y) = ((p % width as usize) as i32, (p / width as usize) as i32);
        for (j, d) in DIAGONALS.iter().enumerate() {
            let e = read(et, w, h, x + s * d[0], y + s * d[1], tileable);
            for c in 0..DIM {
                out[j * DIM + c] = e[c] as f64;
            }
        }
    };
    let count = n.min(MAX_PCA_SAMPLES);
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
    // Exemplar side of the distance: 3 * P * N_E(u), exactly as the GPU forms
    // P * (sum of three predictions) for synthesized pixels.
    let q_full: Vec<[i32; DIM]> = par_ranges(n, threads, |range| {
        range
            .map(|p| {
                let (x, y) = ((p % width as usize) as i32, (p / width as usize) as i32);
                let mut q = [0i32; DIM];
                for (j, d) in DIAGONALS.iter().enumerate() {
                    let e = read(&et_q, w, h, x + s * d[0], y + s * d[1], tileable);
                    for (r, qr) in q.iter_mut().enumerate() {
                        for c in 0..DIM {
                            *qr += 3 * proj[r][j * DIM + c] as i32 * e[c] as i32;
                        }
                    }
                }
                q
            })
            .collect::<Vec<_>>()
    })
    .concat();
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

    // Features for the similarity sets: Et and the projected neighbourhood (float).
    let features = par_ranges(n, threads, |range| {
        let mut v = vec![0.0f64; 4 * DIM];
        let mut np = [0.0f64; DIM];
        let mut out = Vec::with_capacity(range.len() * FEATURE_DIM);
        for p in range {
            runtime(p, &mut v);
            pca.project(&v, &mut np[..pca.components.len()]);
            out.extend(et[p].iter().copied());
            // The 32D neighbourhood spans four pixels: halve it so both halves weigh alike.
            out.extend(np.iter().map(|v| (*v * 0.5) as f32));
        }
        out
    })
    .concat();
    QuantizedLevel {
        et: et_q,
        proj,
        qe,
        shift,
        runtime_residual: pca.residual_variance(),
        features,
    }
}
