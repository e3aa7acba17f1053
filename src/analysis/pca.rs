//! Principal component analysis: covariance accumulation and a cyclic Jacobi eigensolver.
//! Dimensions here are small (25-75 for appearance vectors, 32 for runtime
//! neighbourhoods), so forming the covariance matrix is cheap and Jacobi is exact enough.

use super::par_ranges;

/// Principal components of a set of vectors.
#[derive(Clone, Debug)]
pub struct Pca {
    pub dim: usize,
    pub mean: Vec<f64>,
    /// Components as rows (unit vectors), by decreasing variance.
    pub components: Vec<Vec<f64>>,
    /// Variance along each kept component.
    pub variances: Vec<f64>,
    /// Total variance (trace of the covariance).
    pub total_variance: f64,
}

impl Pca {
    /// PCA of `count` vectors produced by `sample(i, out)`, keeping `keep` components.
    /// Accumulates in f64 over `threads` workers.
    pub fn fit(
        dim: usize,
        count: usize,
        keep: usize,
        threads: usize,
        sample: impl Fn(usize, &mut [f64]) + Sync,
    ) -> Pca {
        let partials = par_ranges(count, threads, |range| {
            let mut sum = vec![0.0f64; dim];
            let mut outer = vec![0.0f64; dim * dim];
            let mut v = vec![0.0f64; dim];
            for i in range {
                sample(i, &mut v);
                for a in 0..dim {
                    sum[a] += v[a];
                    let va = v[a];
                    let row = &mut outer[a * dim..a * dim + dim];
                    for b in a..dim {
                        row[b] += va * v[b];
                    }
                }
            }
            (sum, outer)
        });
        let mut sum = vec![0.0f64; dim];
        let mut outer = vec![0.0f64; dim * dim];
        for (s, o) in partials {
            for a in 0..dim {
                sum[a] += s[a];
            }
            for (x, y) in outer.iter_mut().zip(o) {
                *x += y;
            }
        }
        let n = count.max(1) as f64;
        let mean: Vec<f64> = sum.iter().map(|s| s / n).collect();
        let mut cov = vec![0.0f64; dim * dim];
        for a in 0..dim {
            for b in a..dim {
                let c = outer[a * dim + b] / n - mean[a] * mean[b];
                cov[a * dim + b] = c;
                cov[b * dim + a] = c;
            }
        }
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

/// Eigen-decomposition of a symmetric `n x n` matrix (row-major) by cyclic Jacobi
/// rotations. Returns eigenvalues in decreasing order and the matching unit eigenvectors.
pub fn symmetric_eigen(matrix: &[f64], n: usize) -> (Vec<f64>, Vec<Vec<f64>>) {
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

#[cfg(test)]
mod tests {
    use super::*;

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
        let pca = Pca::fit(3, pts.len(), 1, 2, |i, out| out.copy_from_slice(&pts[i]));
        let c = &pca.components[0];
        let n = (5.0f64).sqrt();
        assert!((c[0] - 1.0 / n).abs() < 1e-6 && (c[1] - 2.0 / n).abs() < 1e-6);
        assert!(pca.residual_variance() < 1e-6);
    }
}
