//! k-coherence similarity sets (paper section 4, after Tong et al. 2002): for every
//! exemplar pixel `u`, the `k - 1` most similar other pixels in appearance space, found
//! offline with a kd-tree, excluding pixels closer than a radius to `u` so that the set
//! offers real alternatives. Stored as offsets `C_i(u) - u`.

use super::kdtree::KdTree;
use super::par_ranges;

/// Bounded kd-tree search: the similarity set need not be exact, and this keeps the
/// analysis of a 256x256 exemplar well under a second per level.
const MAX_CHECKS: usize = 128;

pub struct SimilarityQuery<'a> {
    pub features: &'a [f32],
    pub dim: usize,
    pub width: u32,
    pub height: u32,
    pub tileable: bool,
    /// Valid-region margin (non-tileable exemplars): members must lie inside it.
    pub margin: u32,
    pub exclusion_radius: u32,
    /// Set size including the pixel itself.
    pub k: u32,
}

/// Offsets `(k-1)` per pixel, row-major.
pub fn similarity_offsets(q: &SimilarityQuery, threads: usize) -> Vec<[i16; 2]> {
    let (w, h) = (q.width as i32, q.height as i32);
    let n = (w * h) as usize;
    let want = q.k.saturating_sub(1) as usize;
    if want == 0 {
        return Vec::new();
    }
    let m = q.margin as i32;
    let valid = |p: usize| {
        let (x, y) = ((p % w as usize) as i32, (p / w as usize) as i32);
        q.tileable || (x >= m && x < w - m && y >= m && y < h - m)
    };
    let members: Vec<u32> = (0..n).filter(|&p| valid(p)).map(|p| p as u32).collect();
    let mut pts = Vec::with_capacity(members.len() * q.dim);
    for &p in &members {
        pts.extend_from_slice(&q.features[p as usize * q.dim..(p as usize + 1) * q.dim]);
    }
    let tree = KdTree::build(pts, q.dim);
    let r = q.exclusion_radius as i32;
    let offset = |a: i32, b: i32, n: i32| {
        let d = b - a;
        if q.tileable {
            // Shortest representative of the wrapped difference.
            let d = d.rem_euclid(n);
            if d > n / 2 {
                d - n
            } else {
                d
            }
        } else {
            d
        }
    };
    par_ranges(n, threads, |range| {
        let mut out = Vec::with_capacity(range.len() * want);
        for p in range {
            let (x, y) = ((p % w as usize) as i32, (p / w as usize) as i32);
            let query = &q.features[p * q.dim..(p + 1) * q.dim];
            let found = tree.knn(query, want, MAX_CHECKS, |i| {
                let c = members[i as usize] as usize;
                let (cx, cy) = ((c % w as usize) as i32, (c / w as usize) as i32);
                offset(x, cx, w).abs() >= r || offset(y, cy, h).abs() >= r
            });
            for i in 0..want {
                match found.get(i) {
                    Some(&(_, idx)) => {
                        let c = members[idx as usize] as usize;
                        let (cx, cy) = ((c % w as usize) as i32, (c / w as usize) as i32);
                        out.push([offset(x, cx, w) as i16, offset(y, cy, h) as i16]);
                    }
                    // Nothing outside the exclusion zone: fall back to the pixel itself.
                    None => out.push([0, 0]),
                }
            }
        }
        out
    })
    .concat()
}
