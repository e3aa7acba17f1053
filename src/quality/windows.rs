//! The neighbourhood windows of an image as vectors, the distances between them, and
//! the principal subspace that the texture energy's nearest-window search runs in.
//!
//! A window of side `s` at `(x, y)` covers pixels `x..x+s`, `y..y+s`; its vector holds
//! `s` rows of `s * channels` values. The PCA basis is computed from an even sample of
//! the windows by subspace iteration with a fixed seed, so it is deterministic.

use super::common::{parallel_map, splitmix};
use super::image::FloatImage;

/// Windows sampled (evenly) for the covariance of the PCA.
const PCA_SAMPLES: usize = 8192;
/// Subspace-iteration steps of the PCA.
const PCA_ITERATIONS: usize = 24;

/// The square windows of one image: window `(x, y)` covers pixels `x..x+side`,
/// `y..y+side`, as a vector of `side` rows of `side * channels` values.
pub(super) struct Windows<'a> {
    data: &'a [f32],
    /// Values per image row.
    stride: usize,
    /// Values per window row.
    row: usize,
    side: usize,
    channels: usize,
    /// Window positions per axis.
    pub(super) nx: usize,
    pub(super) ny: usize,
}

impl<'a> Windows<'a> {
    pub(super) fn new(img: &'a FloatImage, side: usize) -> Self {
        let c = img.channels as usize;
        Self {
            data: &img.data,
            stride: img.width as usize * c,
            row: side * c,
            side,
            channels: c,
            nx: img.width as usize + 1 - side,
            ny: img.height as usize + 1 - side,
        }
    }

    pub(super) fn dim(&self) -> usize {
        self.row * self.side
    }

    pub(super) fn count(&self) -> usize {
        self.nx * self.ny
    }

    /// Copies window `(x, y)` into `out` (`dim()` values).
    pub(super) fn gather(&self, x: usize, y: usize, out: &mut [f32]) {
        let base = y * self.stride + x * self.channels;
        for (dy, dst) in out.chunks_exact_mut(self.row).enumerate() {
            let s = base + dy * self.stride;
            dst.copy_from_slice(&self.data[s..s + self.row]);
        }
    }

    /// Squared distance between the gathered vector `q` and window `(x, y)`, or any
    /// value `> bound` once it is certain to exceed `bound`.
    #[inline]
    pub(super) fn distance(&self, q: &[f32], x: usize, y: usize, bound: f32) -> f32 {
        let base = y * self.stride + x * self.channels;
        let mut total = 0.0f32;
        for (dy, a) in q.chunks_exact(self.row).enumerate() {
            let s = base + dy * self.stride;
            total += row_distance(a, &self.data[s..s + self.row]);
            if total > bound {
                return f32::INFINITY;
            }
        }
        total
    }
}

/// Squared distance of two equally long rows (8 partial sums, vectorizable).
#[inline(always)]
fn row_distance(a: &[f32], b: &[f32]) -> f32 {
    let mut s = [0.0f32; 8];
    let ca = a.chunks_exact(8);
    let cb = b.chunks_exact(8);
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for l in 0..8 {
            let d = x[l] - y[l];
            s[l] += d * d;
        }
    }
    for (l, (x, y)) in ra.iter().zip(rb).enumerate() {
        let d = x - y;
        s[l] += d * d;
    }
    ((s[0] + s[1]) + (s[2] + s[3])) + ((s[4] + s[5]) + (s[6] + s[7]))
}

/// Dot product of two equally long rows (8 partial sums, vectorizable).
#[inline(always)]
pub(super) fn dot(a: &[f32], b: &[f32]) -> f32 {
    let mut s = [0.0f32; 8];
    let ca = a.chunks_exact(8);
    let cb = b.chunks_exact(8);
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for l in 0..8 {
            s[l] += x[l] * y[l];
        }
    }
    for (l, (x, y)) in ra.iter().zip(rb).enumerate() {
        s[l] += x * y;
    }
    ((s[0] + s[1]) + (s[2] + s[3])) + ((s[4] + s[5]) + (s[6] + s[7]))
}

/// Orthonormal basis (`p` rows of `dim()` values, `p = min(dims, dim())`) of the
/// dominant principal subspace of the windows, by subspace iteration on their
/// covariance. Rows that the data cannot fill (rank-deficient covariance) are zero.
pub(super) fn pca_basis(w: &Windows, dims: usize) -> Vec<f32> {
    let d = w.dim();
    let p = dims.min(d);
    let m = w.count();
    let s = m.min(PCA_SAMPLES);
    // Evenly spread samples; fixed chunks so the sum does not depend on threads.
    let sample = |j: usize| (j as u64 * m as u64 / s as u64) as usize;
    let mut mean = vec![0.0f64; d];
    let mut q = vec![0.0f32; d];
    for j in 0..s {
        let i = sample(j);
        w.gather(i % w.nx, i / w.nx, &mut q);
        for (a, &v) in mean.iter_mut().zip(&q) {
            *a += v as f64;
        }
    }
    for a in &mut mean {
        *a /= s as f64;
    }
    const CHUNK: usize = 512;
    let partials = parallel_map(s.div_ceil(CHUNK), |c| {
        let mut cov = vec![0.0f64; d * d];
        let mut q = vec![0.0f32; d];
        let mut x = vec![0.0f64; d];
        for j in c * CHUNK..((c + 1) * CHUNK).min(s) {
            let i = sample(j);
            w.gather(i % w.nx, i / w.nx, &mut q);
            for ((xv, &v), &mu) in x.iter_mut().zip(&q).zip(&mean) {
                *xv = v as f64 - mu;
            }
            for r in 0..d {
                let xr = x[r];
                for (cv, &xc) in cov[r * d + r..(r + 1) * d].iter_mut().zip(&x[r..]) {
                    *cv += xr * xc;
                }
            }
        }
        cov
    });
    let mut cov = vec![0.0f64; d * d];
    for part in &partials {
        for (a, b) in cov.iter_mut().zip(part) {
            *a += b;
        }
    }
    for r in 0..d {
        for c in 0..r {
            cov[r * d + c] = cov[c * d + r];
        }
    }
    // Subspace iteration: Q <- orth(C Q), Q stored as p rows of d values.
    let mut seed = 0x5eed_u64;
    let mut basis: Vec<f64> = (0..p * d)
        .map(|_| splitmix(&mut seed) as f64 / u64::MAX as f64 - 0.5)
        .collect();
    orthonormalize(&mut basis, d);
    let scale = (0..d)
        .map(|i| cov[i * d + i])
        .sum::<f64>()
        .max(f64::MIN_POSITIVE);
    let mut next = vec![0.0f64; p * d];
    for _ in 0..PCA_ITERATIONS {
        for (row, out) in basis.chunks_exact(d).zip(next.chunks_exact_mut(d)) {
            for (r, o) in out.iter_mut().enumerate() {
                let crow = &cov[r * d..(r + 1) * d];
                *o = crow.iter().zip(row).map(|(a, b)| a * b).sum::<f64>() / scale;
            }
        }
        std::mem::swap(&mut basis, &mut next);
        orthonormalize(&mut basis, d);
    }
    basis.iter().map(|&v| v as f32).collect()
}

/// Modified Gram-Schmidt (two passes) on rows of `d` values; rows that vanish become
/// zero.
fn orthonormalize(rows: &mut [f64], d: usize) {
    let p = rows.len() / d;
    for i in 0..p {
        let (done, rest) = rows.split_at_mut(i * d);
        let row = &mut rest[..d];
        let norm0 = row.iter().map(|v| v * v).sum::<f64>().sqrt();
        for _ in 0..2 {
            for prev in done.chunks_exact(d) {
                let c: f64 = prev.iter().zip(row.iter()).map(|(a, b)| a * b).sum();
                for (v, a) in row.iter_mut().zip(prev) {
                    *v -= c * a;
                }
            }
        }
        let norm = row.iter().map(|v| v * v).sum::<f64>().sqrt();
        if norm > 1e-9 * norm0 && norm > 1e-150 {
            row.iter_mut().for_each(|v| *v /= norm);
        } else {
            row.fill(0.0);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quality::test_images::texture;

    #[test]
    fn pca_basis_is_orthonormal() {
        let img = texture(40, 40, 3, 3);
        let w = Windows::new(&img, 7);
        let b = pca_basis(&w, 24);
        let d = w.dim();
        for i in 0..24 {
            for j in 0..24 {
                let v: f32 = b[i * d..(i + 1) * d]
                    .iter()
                    .zip(&b[j * d..(j + 1) * d])
                    .map(|(a, b)| a * b)
                    .sum();
                let expect = if i == j { 1.0 } else { 0.0 };
                assert!((v - expect).abs() < 1e-4, "<{i},{j}> = {v}");
            }
        }
    }
}
