//! Principal component analysis: covariance accumulation and a cyclic Jacobi eigensolver.
//! Dimensions here are small (25-75 for appearance vectors, 32 for runtime
//! neighbourhoods), so forming the covariance matrix is cheap and Jacobi is exact enough.

use super::par_ranges;

/// Principal components of a set of vectors.
#[derive(Clone, Debug)]
pub struct Pca {
    /// Dimension of the input vectors (length of `mean` and of each component).
    pub dim: usize,
    /// Mean of the fitted samples, subtracted before projecting onto the components.
    pub mean: Vec<f64>,
    /// Components as rows (unit vectors), by decreasing variance.
    pub components: Vec<Vec<f64>>,
    /// Variance along each kept component.
    pub variances: Vec<f64>,
    /// Total variance (trace of the covariance).
    pub total_variance: f64,
}

/// Samples per block of the covariance accumulation: products are summed in f32 within a
/// block (vectorizes well), and the block sums are added up in f64.
const BLOCK: usize = 256;

/// `sum_i a[i] * b[i]` with eight interleaved partial sums (a fixed order).
#[inline(always)]
fn dot(a: &[f32], b: &[f32]) -> f32 {
    let mut s = [0.0f32; 8];
    for (x, y) in a.chunks_exact(8).zip(b.chunks_exact(8)) {
        for l in 0..8 {
            s[l] += x[l] * y[l];
        }
    }
    ((s[0] + s[1]) + (s[2] + s[3])) + ((s[4] + s[5]) + (s[6] + s[7]))
}

/// Lane sums of four dot products of `a` with `b[0..4]`: lane `l` sums the products
/// at positions `l mod 8`, as in [`dot`], so every code path gives identical results.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn dot4_lanes(a: &[f32; BLOCK], b: [&[f32; BLOCK]; 4]) -> [[f32; 8]; 4] {
    use std::arch::x86_64::*;
    // SAFETY: SSE is part of the x86_64 baseline; all loads are within the arrays
    // (i + 8 <= BLOCK) and unaligned loads are used.
    unsafe {
        let mut lo = [_mm_setzero_ps(); 4];
        let mut hi = [_mm_setzero_ps(); 4];
        let mut i = 0;
        while i < BLOCK {
            let x0 = _mm_loadu_ps(a.as_ptr().add(i));
            let x1 = _mm_loadu_ps(a.as_ptr().add(i + 4));
            for j in 0..4 {
                let y0 = _mm_loadu_ps(b[j].as_ptr().add(i));
                let y1 = _mm_loadu_ps(b[j].as_ptr().add(i + 4));
                lo[j] = _mm_add_ps(lo[j], _mm_mul_ps(x0, y0));
                hi[j] = _mm_add_ps(hi[j], _mm_mul_ps(x1, y1));
            }
            i += 8;
        }
        let mut out = [[0.0f32; 8]; 4];
        for j in 0..4 {
            _mm_storeu_ps(out[j].as_mut_ptr(), lo[j]);
            _mm_storeu_ps(out[j].as_mut_ptr().add(4), hi[j]);
        }
        out
    }
}

#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn dot4_lanes(a: &[f32; BLOCK], b: [&[f32; BLOCK]; 4]) -> [[f32; 8]; 4] {
    let mut s = [[0.0f32; 8]; 4];
    for i in 0..BLOCK / 8 {
        for j in 0..4 {
            for l in 0..8 {
                s[j][l] += a[i * 8 + l] * b[j][i * 8 + l];
            }
        }
    }
    s
}

/// Adds the sums and the upper-triangle products of one transposed block of samples.
#[inline(always)]
fn accumulate_block_with(
    xt: &[f32],
    dim: usize,
    sum: &mut [f64],
    outer: &mut [f64],
    dot4_lanes: impl Fn(&[f32; BLOCK], [&[f32; BLOCK]; 4]) -> [[f32; 8]; 4],
) {
    let row = |b: usize| -> &[f32; BLOCK] { xt[b * BLOCK..(b + 1) * BLOCK].try_into().unwrap() };
    let mut o = 0;
    for (a, sum_a) in sum.iter_mut().enumerate().take(dim) {
        let ra = row(a);
        let mut lanes = [0.0f32; 8];
        for x in ra.chunks_exact(8) {
            for l in 0..8 {
                lanes[l] += x[l];
            }
        }
        *sum_a += lanes.iter().map(|&x| x as f64).sum::<f64>();
        let mut bb = a;
        while bb + 4 <= dim {
            for s in dot4_lanes(ra, [row(bb), row(bb + 1), row(bb + 2), row(bb + 3)]) {
                outer[o] +=
                    (((s[0] + s[1]) + (s[2] + s[3])) + ((s[4] + s[5]) + (s[6] + s[7]))) as f64;
                o += 1;
            }
            bb += 4;
        }
        for bb in bb..dim {
            outer[o] += dot(ra, row(bb)) as f64;
            o += 1;
        }
    }
}

fn accumulate_block(xt: &[f32], dim: usize, sum: &mut [f64], outer: &mut [f64]) {
    accumulate_block_with(xt, dim, sum, outer, dot4_lanes);
}

impl Pca {
    /// PCA of `count` vectors produced by `sample(i, out)`, keeping `keep` components.
    ///
    /// Products are accumulated in f32 within blocks of samples and in f64 across
    /// blocks, over `threads` workers (the result does not depend on the thread count).
    /// The samples are first shifted by the mean of the first block of samples, so the
    /// covariance, formed as `E[xy] - E[x]E[y]`, does not suffer from cancellation (and
    /// is exactly zero for constant samples). Samples of very different scales should
    /// still be centred by the caller.
    pub fn fit(
        dim: usize,
        count: usize,
        keep: usize,
        threads: usize,
        sample: impl Fn(usize, &mut [f32]) + Sync,
    ) -> Pca {
        let pairs = dim * (dim + 1) / 2;
        let blocks = count.div_ceil(BLOCK);
        let mut v = vec![0.0f32; dim];
        let mut shift = vec![0.0f64; dim];
        let first = count.min(BLOCK);
        for i in 0..first {
            sample(i, &mut v);
            for (s, &x) in shift.iter_mut().zip(&v) {
                *s += x as f64;
            }
        }
        let shift: Vec<f32> = shift
            .iter()
            .map(|s| (s / first.max(1) as f64) as f32)
            .collect();
        let partials = par_ranges(blocks, threads, |range| {
            let mut sum = vec![0.0f64; dim];
            let mut outer = vec![0.0f64; pairs];
            // Transposed block: dimension a of sample s at a * BLOCK + s.
            let mut xt = vec![0.0f32; dim * BLOCK];
            let mut v = vec![0.0f32; dim];
            for b in range {
                let (lo, hi) = (b * BLOCK, ((b + 1) * BLOCK).min(count));
                if hi - lo < BLOCK {
                    xt.fill(0.0);
                }
                for i in lo..hi {
                    sample(i, &mut v);
                    for (a, (&x, &r)) in v.iter().zip(&shift).enumerate() {
                        xt[a * BLOCK + i - lo] = x - r;
                    }
                }
                accumulate_block(&xt, dim, &mut sum, &mut outer);
            }
            (sum, outer)
        });
        let mut sum = vec![0.0f64; dim];
        let mut outer = vec![0.0f64; pairs];
        for (s, o) in partials {
            for (x, y) in sum.iter_mut().zip(s) {
                *x += y;
            }
            for (x, y) in outer.iter_mut().zip(o) {
                *x += y;
            }
        }
        let n = count.max(1) as f64;
        // Mean of the shifted samples: the covariance is shift-invariant.
        let mean: Vec<f64> = sum.iter().map(|s| s / n).collect();
        let mut cov = vec![0.0f64; dim * dim];
        let mut o = 0;
        for a in 0..dim {
            for b in a..dim {
                let c = outer[o] / n - mean[a] * mean[b];
                o += 1;
                cov[a * dim + b] = c;
                cov[b * dim + a] = c;
            }
        }
        let mean: Vec<f64> = mean
            .iter()
            .zip(&shift)
            .map(|(m, &s)| m + s as f64)
            .collect();
        let total_variance: f64 = (0..dim).map(|a| cov[a * dim + a].max(0.0)).sum();
        let (values, vectors) = symmetric_eigen(&cov, dim);
        let keep = keep.min(dim);
        let mut components = Vec::with_capacity(keep);
        let mut variances = Vec::with_capacity(keep);
        for i in 0..keep {
            let mut c = vectors[i].clone();
            // Fix the sign so results are deterministic: largest entry positive.
            let (mut big, mut at) = (0.0f64, 0);
            for (j, x) in c.iter().enumerate() {
                if x.abs() > big + 1e-12 {
                    big = x.abs();
                    at = j;
                }
            }
            if c[at] < 0.0 {
                c.iter_mut().for_each(|x| *x = -*x);
            }
            components.push(c);
            variances.push(values[i].max(0.0));
        }
        // Pad with zero components when dim < keep (e.g. grey exemplars at tiny sizes).
        Pca {
            dim,
            mean,
            components,
            variances,
            total_variance,
        }
    }

    /// Fraction of the total variance not captured by the kept components.
    pub fn residual_variance(&self) -> f64 {
        if self.total_variance <= 1e-20 {
            return 0.0;
        }
        let kept: f64 = self.variances.iter().sum();
        (1.0 - kept / self.total_variance).clamp(0.0, 1.0)
    }

    /// Projects `v` (minus the mean) onto the kept components.
    pub fn project(&self, v: &[f64], out: &mut [f64]) {
        for (o, c) in out.iter_mut().zip(&self.components) {
            let mut s = 0.0;
            for ((x, m), w) in v.iter().zip(&self.mean).zip(c) {
                s += (x - m) * w;
            }
            *o = s;
        }
    }
}

/// Eigen-decomposition of a symmetric `n x n` matrix (row-major): Householder reduction
/// to tridiagonal form and the implicit QL algorithm (EISPACK `tred2` / `tql2`, as in
/// JAMA). Returns eigenvalues in decreasing order and the matching unit eigenvectors.
pub fn symmetric_eigen(matrix: &[f64], n: usize) -> (Vec<f64>, Vec<Vec<f64>>) {
    if n == 0 {
        return (Vec::new(), Vec::new());
    }
    // v[i][j] row-major; the eigenvectors end up in the columns.
    let mut v: Vec<Vec<f64>> = (0..n)
        .map(|i| matrix[i * n..(i + 1) * n].to_vec())
        .collect();
    let mut d = vec![0.0f64; n];
    let mut e = vec![0.0f64; n];
    tred2(&mut v, &mut d, &mut e);
    tql2(&mut v, &mut d, &mut e);
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&i, &j| {
        d[j].partial_cmp(&d[i])
            .unwrap_or(std::cmp::Ordering::Equal)
            .then(i.cmp(&j))
    });
    let values = order.iter().map(|&i| d[i]).collect();
    let vectors = order
        .iter()
        .map(|&i| (0..n).map(|k| v[k][i]).collect())
        .collect();
    (values, vectors)
}

/// Householder reduction of the symmetric matrix in `v` to tridiagonal form: diagonal in
/// `d`, subdiagonal in `e[1..]`, the orthogonal transformation accumulated in `v`.
#[allow(clippy::needless_range_loop)] // index-heavy numerics, kept close to EISPACK
fn tred2(v: &mut [Vec<f64>], d: &mut [f64], e: &mut [f64]) {
    let n = d.len();
    d.copy_from_slice(&v[n - 1]);
    for i in (1..n).rev() {
        let mut scale = 0.0;
        let mut h = 0.0;
        for dk in d.iter().take(i) {
            scale += dk.abs();
        }
        if scale == 0.0 {
            e[i] = d[i - 1];
            for j in 0..i {
                d[j] = v[i - 1][j];
                v[i][j] = 0.0;
                v[j][i] = 0.0;
            }
        } else {
            for dk in d.iter_mut().take(i) {
                *dk /= scale;
                h += *dk * *dk;
            }
            let mut f = d[i - 1];
            let mut g = h.sqrt();
            if f > 0.0 {
                g = -g;
            }
            e[i] = scale * g;
            h -= f * g;
            d[i - 1] = f - g;
            for ej in e.iter_mut().take(i) {
                *ej = 0.0;
            }
            for j in 0..i {
                f = d[j];
                v[j][i] = f;
                g = e[j] + v[j][j] * f;
                for k in j + 1..i {
                    g += v[k][j] * d[k];
                    e[k] += v[k][j] * f;
                }
                e[j] = g;
            }
            f = 0.0;
            for j in 0..i {
                e[j] /= h;
                f += e[j] * d[j];
            }
            let hh = f / (h + h);
            for j in 0..i {
                e[j] -= hh * d[j];
            }
            for j in 0..i {
                f = d[j];
                g = e[j];
                for k in j..i {
                    v[k][j] -= f * e[k] + g * d[k];
                }
                d[j] = v[i - 1][j];
                v[i][j] = 0.0;
            }
        }
        d[i] = h;
    }
    for i in 0..n - 1 {
        v[n - 1][i] = v[i][i];
        v[i][i] = 1.0;
        let h = d[i + 1];
        if h != 0.0 {
            for k in 0..=i {
                d[k] = v[k][i + 1] / h;
            }
            for j in 0..=i {
                let mut g = 0.0;
                for k in 0..=i {
                    g += v[k][i + 1] * v[k][j];
                }
                for k in 0..=i {
                    v[k][j] -= g * d[k];
                }
            }
        }
        for row in v.iter_mut().take(i + 1) {
            row[i + 1] = 0.0;
        }
    }
    for j in 0..n {
        d[j] = v[n - 1][j];
        v[n - 1][j] = 0.0;
    }
    v[n - 1][n - 1] = 1.0;
    e[0] = 0.0;
}

/// Implicit QL iterations on the tridiagonal matrix (`d`, `e`), accumulating the
/// rotations into `v`. Leaves the eigenvalues in `d` (unsorted).
fn tql2(v: &mut [Vec<f64>], d: &mut [f64], e: &mut [f64]) {
    let n = d.len();
    for i in 1..n {
        e[i - 1] = e[i];
    }
    e[n - 1] = 0.0;
    let mut f = 0.0f64;
    let mut tst1 = 0.0f64;
    let eps = f64::EPSILON;
    for l in 0..n {
        tst1 = tst1.max(d[l].abs() + e[l].abs());
        let mut m = l;
        while m < n - 1 && e[m].abs() > eps * tst1 {
            m += 1;
        }
        if m > l {
            let mut iter = 0;
            loop {
                iter += 1;
                let mut g = d[l];
                let mut p = (d[l + 1] - g) / (2.0 * e[l]);
                let mut r = p.hypot(1.0);
                if p < 0.0 {
                    r = -r;
                }
                d[l] = e[l] / (p + r);
                d[l + 1] = e[l] * (p + r);
                let dl1 = d[l + 1];
                let mut h = g - d[l];
                for di in d.iter_mut().skip(l + 2) {
                    *di -= h;
                }
                f += h;
                p = d[m];
                let mut c = 1.0;
                let mut c2 = c;
                let mut c3 = c;
                let el1 = e[l + 1];
                let mut s = 0.0;
                let mut s2 = 0.0;
                for i in (l..m).rev() {
                    c3 = c2;
                    c2 = c;
                    s2 = s;
                    g = c * e[i];
                    h = c * p;
                    r = p.hypot(e[i]);
                    e[i + 1] = s * r;
                    s = e[i] / r;
                    c = p / r;
                    p = c * d[i] - s * g;
                    d[i + 1] = h + s * (c * g + s * d[i]);
                    for row in v.iter_mut() {
                        h = row[i + 1];
                        row[i + 1] = s * row[i] + c * h;
                        row[i] = c * row[i] - s * h;
                    }
                }
                p = -s * s2 * c3 * el1 * e[l] / dl1;
                e[l] = s * p;
                d[l] = c * p;
                if e[l].abs() <= eps * tst1 || iter >= 60 {
                    break;
                }
            }
        }
        d[l] += f;
        e[l] = 0.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference solver for the tests: cyclic Jacobi rotations.
    fn jacobi_eigen(matrix: &[f64], n: usize) -> (Vec<f64>, Vec<Vec<f64>>) {
        let mut a = matrix.to_vec();
        let mut v = vec![0.0f64; n * n];
        for i in 0..n {
            v[i * n + i] = 1.0;
        }
        let scale: f64 = a.iter().map(|x| x * x).sum::<f64>().sqrt().max(1e-300);
        for _sweep in 0..100 {
            let mut off = 0.0;
            for p in 0..n {
                for q in p + 1..n {
                    off += a[p * n + q] * a[p * n + q];
                }
            }
            if off.sqrt() <= 1e-14 * scale {
                break;
            }
            for p in 0..n {
                for q in p + 1..n {
                    let apq = a[p * n + q];
                    if apq.abs() <= 1e-300 {
                        continue;
                    }
                    let app = a[p * n + p];
                    let aqq = a[q * n + q];
                    let theta = (aqq - app) / (2.0 * apq);
                    let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                    let t = if theta == 0.0 { 1.0 } else { t };
                    let c = 1.0 / (t * t + 1.0).sqrt();
                    let s = t * c;
                    for k in 0..n {
                        let akp = a[k * n + p];
                        let akq = a[k * n + q];
                        a[k * n + p] = c * akp - s * akq;
                        a[k * n + q] = s * akp + c * akq;
                    }
                    for k in 0..n {
                        let apk = a[p * n + k];
                        let aqk = a[q * n + k];
                        a[p * n + k] = c * apk - s * aqk;
                        a[q * n + k] = s * apk + c * aqk;
                    }
                    for k in 0..n {
                        let vkp = v[k * n + p];
                        let vkq = v[k * n + q];
                        v[k * n + p] = c * vkp - s * vkq;
                        v[k * n + q] = s * vkp + c * vkq;
                    }
                }
            }
        }
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&i, &j| {
            a[j * n + j]
                .partial_cmp(&a[i * n + i])
                .unwrap_or(std::cmp::Ordering::Equal)
                .then(i.cmp(&j))
        });
        let values = order.iter().map(|&i| a[i * n + i]).collect();
        let vectors = order
            .iter()
            .map(|&i| (0..n).map(|k| v[k * n + i]).collect())
            .collect();
        (values, vectors)
    }

    #[test]
    fn tridiagonal_ql_matches_jacobi() {
        for &n in &[1usize, 2, 3, 8, 25, 32, 75] {
            // Random symmetric matrix (and a covariance-like PSD one).
            let mut x = 12345u64 + n as u64;
            let mut rnd = || {
                x = x
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((x >> 11) as f64 / (1u64 << 53) as f64) - 0.5
            };
            let b: Vec<f64> = (0..n * n).map(|_| rnd()).collect();
            let mut a = vec![0.0; n * n];
            for i in 0..n {
                for j in 0..n {
                    a[i * n + j] = (0..n).map(|k| b[i * n + k] * b[j * n + k]).sum::<f64>();
                }
            }
            let (v1, e1) = symmetric_eigen(&a, n);
            let (v2, _) = jacobi_eigen(&a, n);
            for i in 0..n {
                assert!(
                    (v1[i] - v2[i]).abs() < 1e-9 * v2[0].abs().max(1.0),
                    "n={n} i={i}"
                );
                // A e = lambda e.
                for r in 0..n {
                    let ae: f64 = (0..n).map(|k| a[r * n + k] * e1[i][k]).sum();
                    assert!((ae - v1[i] * e1[i][r]).abs() < 1e-9 * v1[0].abs().max(1.0));
                }
                let norm: f64 = e1[i].iter().map(|x| x * x).sum();
                assert!((norm - 1.0).abs() < 1e-10);
            }
        }
        let (vals, _) = symmetric_eigen(&[0.0; 16], 4);
        assert!(vals.iter().all(|v| *v == 0.0));
    }

    #[test]
    fn jacobi_diagonalizes_known_matrix() {
        // Eigenvalues of [[2,1],[1,2]] are 3 and 1.
        let (vals, vecs) = symmetric_eigen(&[2.0, 1.0, 1.0, 2.0], 2);
        assert!((vals[0] - 3.0).abs() < 1e-12 && (vals[1] - 1.0).abs() < 1e-12);
        let v = &vecs[0];
        assert!((v[0].abs() - v[1].abs()).abs() < 1e-12);
    }

    #[test]
    fn pca_finds_dominant_direction_and_residual() {
        // Points along (1,2,0) with small noise in z: one component holds ~all variance.
        let pts: Vec<[f64; 3]> = (0..1000)
            .map(|i| {
                let t = i as f64 / 100.0;
                [t, 2.0 * t, ((i * 7919) % 13) as f64 * 1e-3]
            })
            .collect();
        let pca = Pca::fit(3, pts.len(), 1, 2, |i, out| {
            for (o, v) in out.iter_mut().zip(&pts[i]) {
                *o = *v as f32;
            }
        });
        let c = &pca.components[0];
        let n = (5.0f64).sqrt();
        assert!((c[0] - 1.0 / n).abs() < 1e-6 && (c[1] - 2.0 / n).abs() < 1e-6);
        assert!((pca.mean[0] - 4.995).abs() < 1e-5 && (pca.mean[1] - 9.99).abs() < 1e-5);
        assert!(pca.residual_variance() < 1e-6);
    }

    #[test]
    fn pca_of_offset_and_constant_samples() {
        // A tiny variance on top of a large offset: no cancellation.
        let f = |i: usize| {
            [
                0.7 + 1e-4 * ((i * 37 % 101) as f32 / 101.0),
                0.3f32,
                -0.2 + 2e-6 * ((i % 7) as f32),
            ]
        };
        let pca = Pca::fit(3, 5000, 2, 3, |i, out| out.copy_from_slice(&f(i)));
        let var0: f64 = (0..5000)
            .map(|i| f(i)[0] as f64)
            .map(|x| x * x)
            .sum::<f64>()
            / 5000.0
            - ((0..5000).map(|i| f(i)[0] as f64).sum::<f64>() / 5000.0).powi(2);
        assert!(
            (pca.variances[0] / var0 - 1.0).abs() < 1e-3,
            "{} vs {var0}",
            pca.variances[0]
        );
        assert!(pca.components[0][0] > 0.999);
        assert!((pca.mean[1] - 0.3).abs() < 1e-7);
        // Constant samples: zero covariance, and a deterministic (canonical) basis.
        let pca = Pca::fit(4, 3000, 2, 2, |_, out| {
            out.copy_from_slice(&[0.1, 0.2, 0.3, 0.4])
        });
        assert_eq!(pca.total_variance, 0.0);
        assert_eq!(pca.variances, vec![0.0, 0.0]);
        assert_eq!(pca.components[0], vec![1.0, 0.0, 0.0, 0.0]);
        assert_eq!(pca.components[1], vec![0.0, 1.0, 0.0, 0.0]);
        assert_eq!(pca.residual_variance(), 0.0);
    }
}
