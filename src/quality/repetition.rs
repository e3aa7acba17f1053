//! Layout repetition: whether the output repeats the exemplar's layout at one
//! displacement, as a tiling does, even where its verbatim pieces are small.
//!
//! Pairs of output pixels that copy the same exemplar pixel are binned by their
//! displacement; the share of pixels in the fullest bin is the figure. 0 means no
//! repeated layout; about `1 - 1/n` means the exemplar tiled `n` times across.

use super::verbatim::check_coord_map;
use crate::error::Result;

/// Displacements shorter than this (pixels) do not count in [`layout_repetition`]: a
/// pixel copied twice a few pixels apart is local redundancy, not a repeated layout.
pub const MIN_REPEAT_DISTANCE: f64 = 24.0;

/// Side of the displacement bins of [`layout_repetition`] in output pixels: repeats of
/// a layout that is only nearly periodic (jitter, seams) fall into the same bin.
pub const REPEAT_BIN: i32 = 8;

/// [`layout_repetition`] looks at most this many pixels along each axis (the centre of
/// larger outputs): every pair of pixels that copy the same exemplar pixel is counted,
/// which grows with the square of the area.
pub const MAX_REPEAT_WINDOW: u32 = 512;

/// Beyond this many pairs (outputs many times the exemplar's size, or degenerate maps
/// that copy few exemplar pixels) [`layout_repetition`] counts a random share of them.
const MAX_REPEAT_PAIRS: f64 = 5e7;

/// How much of the output's layout repeats at one displacement: see
/// [`layout_repetition`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LayoutRepetition {
    /// Output pixels whose exemplar pixel is copied again at the most frequent
    /// displacement (binned), over all output pixels: 0 when the layout never repeats,
    /// about `1 - 1/n` for the exemplar tiled `n` times across. A bin holds 64
    /// displacements, so a degenerate map (one exemplar pixel copied everywhere) reaches
    /// up to 64.
    pub share: f64,
    /// That displacement `[dx, dy]` in output pixels (the mean of the pairs in its bin);
    /// `[0, 0]` when no pixel repeats.
    pub vector: [f64; 2],
}

/// Layout repetition of a coordinate map: pairs of output pixels that copy the same
/// exemplar pixel (modulo the exemplar size when `tileable`) at least
/// [`MIN_REPEAT_DISTANCE`] apart, binned by their displacement in [`REPEAT_BIN`]-pixel
/// bins; the fullest bin gives the figure. A texture whose features stand on a lattice
/// (a near-tiling of the exemplar) scores high even when its verbatim regions are
/// small, since each region continues the lattice. Every exemplar pixel of a `n x`
/// larger output appears about `n` times whatever the method; what this measures is
/// whether those copies keep one displacement: a random layout puts about
/// `REPEAT_BIN^2 / exemplar pixels` of them in a bin (0.4% for a 128x128 exemplar).
/// Outputs larger than [`MAX_REPEAT_WINDOW`] are measured on their central window of
/// that size; beyond 5e7 pairs a random sample of the pixels is paired (an estimate,
/// still deterministic).
///
/// Errors: as [`verbatim_stats`](super::verbatim_stats).
pub fn layout_repetition(
    coords: &[[i32; 2]],
    out_w: u32,
    out_h: u32,
    ex_w: u32,
    ex_h: u32,
    tileable: bool,
) -> Result<LayoutRepetition> {
    check_coord_map(coords, out_w, out_h, ex_w, ex_h)?;
    let (w, h) = (out_w as usize, out_h as usize);
    let key = |c: [i32; 2]| -> (i64, i64) {
        let (x, y) = (c[0] as i64, c[1] as i64);
        if tileable {
            (y.rem_euclid(ex_h as i64), x.rem_euclid(ex_w as i64))
        } else {
            (y, x)
        }
    };
    // The central window; raster order within a group (stable sort), so each pair
    // points forward.
    let (cw, ch) = (
        w.min(MAX_REPEAT_WINDOW as usize),
        h.min(MAX_REPEAT_WINDOW as usize),
    );
    let (x0, y0) = ((w - cw) / 2, (h - ch) / 2);
    let mut order: Vec<u32> = (0..ch)
        .flat_map(|y| (0..cw).map(move |x| ((y0 + y) * w + x0 + x) as u32))
        .collect();
    order.sort_by_key(|&i| key(coords[i as usize]));
    // Pairs of each group of pixels sharing an exemplar pixel; beyond a budget, pixels
    // are kept at random (a hash of their index, so the figure stays deterministic) with
    // probability rho, and each counted pair stands for 1 / rho^2: unbiased, unlike a
    // regular subsample, which aliases with a periodic layout.
    let groups = |order: &[u32]| -> Vec<std::ops::Range<usize>> {
        let mut out = Vec::new();
        let mut start = 0;
        while start < order.len() {
            let k = key(coords[order[start] as usize]);
            let mut end = start + 1;
            while end < order.len() && key(coords[order[end] as usize]) == k {
                end += 1;
            }
            out.push(start..end);
            start = end;
        }
        out
    };
    let mut ranges = groups(&order);
    let pairs: f64 = ranges
        .iter()
        .map(|g| (g.len() as f64) * (g.len() as f64 - 1.0) / 2.0)
        .sum();
    let rho = (MAX_REPEAT_PAIRS / pairs.max(1.0)).sqrt().min(1.0);
    if rho < 1.0 {
        let keep = (rho * 4_294_967_296.0) as u64;
        order.retain(|&i| {
            let mut z = (i as u64).wrapping_add(0x9e37_79b9_7f4a_7c15);
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            ((z ^ (z >> 31)) >> 32) < keep
        });
        ranges = groups(&order);
    }
    // Bins of (pairs, dx sum, dy sum) over the forward displacements (dy >= 0).
    let (cwi, chi) = (cw as i32, ch as i32);
    let bx0 = (1 - cwi).div_euclid(REPEAT_BIN);
    let nbx = ((cwi - 1).div_euclid(REPEAT_BIN) - bx0 + 1) as usize;
    let nby = ((chi - 1).div_euclid(REPEAT_BIN) + 1) as usize;
    let mut bins = vec![(0u64, 0i64, 0i64); nbx * nby];
    let min2 = MIN_REPEAT_DISTANCE * MIN_REPEAT_DISTANCE;
    for g in ranges {
        let group = &order[g];
        for (a, &i) in group.iter().enumerate() {
            let (xa, ya) = ((i as usize % w) as i32, (i as usize / w) as i32);
            for &j in &group[a + 1..] {
                let (dx, dy) = ((j as usize % w) as i32 - xa, (j as usize / w) as i32 - ya);
                if ((dx * dx + dy * dy) as f64) < min2 {
                    continue;
                }
                let b = (dy.div_euclid(REPEAT_BIN) as usize) * nbx
                    + (dx.div_euclid(REPEAT_BIN) - bx0) as usize;
                let e = &mut bins[b];
                e.0 += 1;
                e.1 += dx as i64;
                e.2 += dy as i64;
            }
        }
    }
    // The fullest bin; ties go to the first in row-major bin order (deterministic).
    let best = bins
        .iter()
        .fold((0u64, 0i64, 0i64), |b, &v| if v.0 > b.0 { v } else { b });
    Ok(match best {
        (0, _, _) => LayoutRepetition {
            share: 0.0,
            vector: [0.0, 0.0],
        },
        (n, sx, sy) => LayoutRepetition {
            share: n as f64 / (rho * rho) / (cw * ch) as f64,
            vector: [sx as f64 / n as f64, sy as f64 / n as f64],
        },
    })
}
