//! Mirror of `shaders/correct.wgsl`: one correction subpass. Pixels whose absolute
//! position has parity `p.parity` are replaced by the best of their k-coherent
//! candidates; all other pixels are only read, so the subpass can run in place.
//!
//! Neighbourhood (isometric): for each diagonal `D`, three predictions of the appearance
//! at `p + D` from the pixels `p + D'`, `D' in {D, (D.x,0), (0,D.y)}`:
//! `Et[S[p+D'] + h (D - D')]`, summed in integers (`3 N_S(p;D)`).
//!
//! Distance, two modes (`p.full_distance`):
//! - *projected* (the paper): the four sums times the quantized projection blocks
//!   `P_D`, summed, is `3 * Np_S`, compared in 8D with the exemplar side `qe`
//!   (`3 * P N_E`), both shifted right by `shift`;
//! - *full*: the 32D sums compared directly with `3 Et[c + h D]` at the candidate's four
//!   diagonal neighbours (differences shifted right by 2 so 32 squares fit a u32). It
//!   keeps the ~10-20% of neighbourhood variance the 8D projection drops, and costs
//!   four reads per candidate instead of one; texsyn uses it on the coarse levels,
//!   which are small, and the projected distance on the finest.
//!
//! Candidates: `S[p+d] + O_i(S[p+d]) - h d` for `d` in the 3x3 block (row-major from
//! (-1,-1)), `i = 1..k` (i = 1 is the coherent candidate, offset 0). The first candidate
//! with the strictly smallest distance wins; the current value is tried first, so ties
//! keep it. Non-coherent candidates (i > 1) pay `dist * (1 + coherence/16)`. Candidates
//! outside the valid region (non-tileable exemplars) are skipped.

use super::common::{fit_near, is_valid, read_coord, region_index, PassParams};
use crate::analysis::{DIAGONALS, DIM, QE_MAX};

/// The per-level tables a correction pass reads.
pub struct LevelTables<'a> {
    /// Appearance vectors `Et` of the level.
    pub et: &'a [[i16; DIM]],
    /// Projected appearance vectors `qe` of the level.
    pub qe: &'a [[i16; DIM]],
    /// Similarity offsets, `k - 1` per exemplar pixel.
    pub offsets: &'a [[i16; 2]],
    /// Quantized projection blocks of the runtime neighbourhood.
    pub proj: &'a [[i16; 4 * DIM]; DIM],
}

#[inline]
fn ex_index(c: [i32; 2], p: &PassParams) -> usize {
    (c[1] * p.ex_size[0] + c[0]) as usize
}

/// Per diagonal, the sum of the three predictions of `Et` at `q + D` (`3 N_S(q;D)`).
pub fn prediction_sums(
    p: &PassParams,
    t: &LevelTables,
    coords: &[[i32; 2]],
    q: [i32; 2],
) -> [[i32; DIM]; 4] {
    let base = p.coord_base as usize;
    let h = p.step;
    let mut out = [[0i32; DIM]; 4];
    for (j, d) in DIAGONALS.iter().enumerate() {
        for dp in [*d, [d[0], 0], [0, d[1]]] {
            let s = coords[base + region_index([q[0] + dp[0], q[1] + dp[1]], p)];
            let u = read_coord(
                [s[0] + h[0] * (d[0] - dp[0]), s[1] + h[1] * (d[1] - dp[1])],
                p,
            );
            let e = t.et[ex_index(u, p)];
            for c in 0..DIM {
                out[j][c] += e[c] as i32;
            }
        }
    }
    out
}

/// `3 * P * N_S` shifted: the projected synthesized neighbourhood.
pub fn project(p: &PassParams, t: &LevelTables, sums: &[[i32; DIM]; 4]) -> [i32; DIM] {
    let mut acc = [0i32; DIM];
    for (j, sum) in sums.iter().enumerate() {
        for (r, a) in acc.iter_mut().enumerate() {
            for (c, s) in sum.iter().enumerate() {
                *a += t.proj[r][j * DIM + c] as i32 * s;
            }
        }
    }
    acc.map(|v| v >> p.shift)
}

/// Projected (8D) distance to the exemplar side of candidate `c`.
#[inline]
pub fn projected_distance(ns: &[i32; DIM], qe: &[i16; DIM]) -> u32 {
    let mut d = 0u32;
    for c in 0..DIM {
        let x = (ns[c] - qe[c] as i32).clamp(-2 * QE_MAX, 2 * QE_MAX);
        d += (x * x) as u32;
    }
    d
}

/// Full (32D) distance between the prediction sums and `3 Et` around candidate `c`.
#[inline]
pub fn full_distance(p: &PassParams, t: &LevelTables, sums: &[[i32; DIM]; 4], c: [i32; 2]) -> u32 {
    let h = p.step;
    let mut d = 0u32;
    for (j, dd) in DIAGONALS.iter().enumerate() {
        let e = t.et[ex_index(read_coord([c[0] + h[0] * dd[0], c[1] + h[1] * dd[1]], p), p)];
        for k in 0..DIM {
            let x = (sums[j][k] - 3 * e[k] as i32) >> 2;
            d += (x * x) as u32;
        }
    }
    d
}

/// New coordinate of the pixel at region position `q`.
pub fn correct_pixel(
    p: &PassParams,
    t: &LevelTables,
    coords: &[[i32; 2]],
    q: [i32; 2],
) -> [i32; 2] {
    let base = p.coord_base as usize;
    let h = p.step;
    let sums = prediction_sums(p, t, coords, q);
    let full = p.full_distance != 0;
    let ns = if full { [0; DIM] } else { project(p, t, &sums) };
    let distance = |c: [i32; 2]| {
        if full {
            full_distance(p, t, &sums, c)
        } else {
            projected_distance(&ns, &t.qe[ex_index(c, p)])
        }
    };
    let current = coords[base + region_index(q, p)];
    let mut best = current;
    let mut best_d = u32::MAX;
    if is_valid(current, p) {
        best_d = distance(current);
    }
    let km1 = (p.k - 1).max(0) as usize;
    for dy in -1..=1 {
        for dx in -1..=1 {
            let s = coords[base + region_index([q[0] + dx, q[1] + dy], p)];
            for i in 0..p.k as usize {
                let o = if i == 0 {
                    [0, 0]
                } else {
                    let o = t.offsets[ex_index(s, p) * km1 + i - 1];
                    [o[0] as i32, o[1] as i32]
                };
                let raw = [s[0] + o[0] - h[0] * dx, s[1] + o[1] - h[1] * dy];
                if !is_valid(raw, p) {
                    continue;
                }
                let c = fit_near(raw, p);
                // The best so far cannot beat itself (ties keep it; the bias only adds).
                if c == best {
                    continue;
                }
                let mut d = distance(c);
                if i > 0 {
                    d += (d >> 4) * p.coherence;
                }
                if d < best_d {
                    best_d = d;
                    best = c;
                }
            }
        }
    }
    best
}

/// One subpass over the level's region.
pub fn run(p: &PassParams, t: &LevelTables, coords: &mut [[i32; 2]]) {
    for [x, y] in super::common::subpass_pixels(p) {
        let c = correct_pixel(p, t, coords, [x, y]);
        coords[p.coord_base as usize + (y * p.size[0] + x) as usize] = c;
    }
}
