//! Verbatim copy: how much of a synthesized coordinate map copies the exemplar in
//! one piece.
//!
//! Neighbouring output pixels whose exemplar coordinates differ by the same step as
//! their positions are coherent; the coherent regions are the connected pieces copied
//! verbatim. Coherent synthesis builds its output from such pieces, so a high coherent
//! fraction is expected; the largest region says how large they get, and a fraction
//! near 1 (a region the exemplar's size) means the exemplar was copied wholesale.

use super::common::invalid;
use crate::error::Result;

/// How much of a synthesized coordinate map is verbatim copy of the exemplar.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VerbatimStats {
    /// Coherent neighbouring pairs / all horizontal and vertical pairs (0 when there
    /// are no pairs).
    pub coherent_fraction: f64,
    /// Pixels of the largest coherent region / exemplar pixels. Can exceed 1 for a
    /// tileable exemplar (a region wrapping around repeats the exemplar).
    pub largest_region_fraction: f64,
    /// Pixels of the largest coherent region.
    pub largest_region_pixels: u64,
    /// Number of coherent regions (connected components over coherent pairs; single
    /// pixels count as regions).
    pub regions: u64,
}

/// A synthesized coordinate map: `coords[y * width + x]` is the exemplar pixel copied
/// to output pixel `(x, y)`.
#[derive(Clone, Copy, Debug)]
pub struct CoordMap<'a> {
    /// `width * height` exemplar pixel coordinates `[x, y]`, row-major.
    pub coords: &'a [[i32; 2]],
    /// Output width in pixels.
    pub width: u32,
    /// Output height in pixels.
    pub height: u32,
    /// Whether exemplar coordinates wrap around (tileable exemplar).
    pub tileable: bool,
}

/// The errors shared by the coordinate-map figures: an empty map, a map whose length is
/// not `out_w * out_h`, or an empty exemplar size.
pub(super) fn check_coord_map(
    coords: &[[i32; 2]],
    out_w: u32,
    out_h: u32,
    ex_w: u32,
    ex_h: u32,
) -> Result<()> {
    if out_w == 0 || out_h == 0 || coords.is_empty() {
        return Err(invalid(format!(
            "coordinate map is empty ({out_w}x{out_h})"
        )));
    }
    if coords.len() as u64 != out_w as u64 * out_h as u64 {
        return Err(invalid(format!(
            "coordinate map holds {} entries for a {out_w}x{out_h} output",
            coords.len()
        )));
    }
    if ex_w == 0 || ex_h == 0 {
        return Err(invalid(format!("exemplar size {ex_w}x{ex_h} is empty")));
    }
    Ok(())
}

/// Verbatim-copy statistics of a coordinate map (`coords[y * out_w + x]` = exemplar
/// pixel copied to `(x, y)`). A horizontal or vertical pair `(p, p + e)` is coherent
/// when `coords[p + e] == coords[p] + e` (modulo the exemplar size when `tileable`).
/// Regions are the connected components over coherent pairs.
///
/// Errors: an empty map, a map whose length is not `out_w * out_h`, or an empty
/// exemplar size.
pub fn verbatim_stats(
    coords: &[[i32; 2]],
    out_w: u32,
    out_h: u32,
    ex_w: u32,
    ex_h: u32,
    tileable: bool,
) -> Result<VerbatimStats> {
    verbatim_stats_at_spacing(coords, out_w, out_h, ex_w, ex_h, tileable, 1)
}

/// [`verbatim_stats`] of a coarser synthesis level, whose pixels step `spacing`
/// exemplar pixels (the level spacing `h_l` of Lefebvre & Hoppe 2006): a pair
/// `(p, p + e)` is coherent when `coords[p + e] == coords[p] + spacing * e`, and each
/// pixel counts as `spacing^2` exemplar pixels in `largest_region_fraction`
/// (`largest_region_pixels` stays in this level's pixels). When the finer levels only
/// upsample, their regions are these regions, enlarged.
pub fn verbatim_stats_at_spacing(
    coords: &[[i32; 2]],
    out_w: u32,
    out_h: u32,
    ex_w: u32,
    ex_h: u32,
    tileable: bool,
    spacing: u32,
) -> Result<VerbatimStats> {
    check_coord_map(coords, out_w, out_h, ex_w, ex_h)?;
    if spacing == 0 {
        return Err(invalid("a level's spacing must be at least 1"));
    }
    let (w, h) = (out_w as usize, out_h as usize);
    // In 64 bits, so that no coordinate can overflow.
    let (ew, eh) = (ex_w as i64, ex_h as i64);
    let step = spacing as i64;
    let coherent = |a: [i32; 2], b: [i32; 2], e: [i64; 2]| {
        let (tx, ty) = (a[0] as i64 + step * e[0], a[1] as i64 + step * e[1]);
        let (bx, by) = (b[0] as i64, b[1] as i64);
        if tileable {
            tx.rem_euclid(ew) == bx.rem_euclid(ew) && ty.rem_euclid(eh) == by.rem_euclid(eh)
        } else {
            tx == bx && ty == by
        }
    };
    let n = w * h;
    let mut uf = UnionFind::new(n);
    let (mut pairs, mut good) = (0u64, 0u64);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if x + 1 < w {
                pairs += 1;
                if coherent(coords[i], coords[i + 1], [1, 0]) {
                    good += 1;
                    uf.union(i, i + 1);
                }
            }
            if y + 1 < h {
                pairs += 1;
                if coherent(coords[i], coords[i + w], [0, 1]) {
                    good += 1;
                    uf.union(i, i + w);
                }
            }
        }
    }
    let mut largest = 0u64;
    let mut regions = 0u64;
    for i in 0..n {
        if uf.parent[i] as usize == i {
            regions += 1;
            largest = largest.max(uf.size[i] as u64);
        }
    }
    Ok(VerbatimStats {
        coherent_fraction: if pairs == 0 {
            0.0
        } else {
            good as f64 / pairs as f64
        },
        largest_region_fraction: largest as f64 * (step * step) as f64
            / (ex_w as f64 * ex_h as f64),
        largest_region_pixels: largest,
        regions,
    })
}

/// Disjoint sets of pixels (union by size, path halving).
struct UnionFind {
    parent: Vec<u32>,
    size: Vec<u32>,
}

impl UnionFind {
    fn new(n: usize) -> Self {
        Self {
            parent: (0..n as u32).collect(),
            size: vec![1; n],
        }
    }

    fn find(&mut self, mut i: usize) -> usize {
        while self.parent[i] as usize != i {
            let g = self.parent[self.parent[i] as usize];
            self.parent[i] = g;
            i = g as usize;
        }
        i
    }

    fn union(&mut self, a: usize, b: usize) {
        let (mut a, mut b) = (self.find(a), self.find(b));
        if a == b {
            return;
        }
        if self.size[a] < self.size[b] {
            std::mem::swap(&mut a, &mut b);
        }
        self.parent[b] = a as u32;
        self.size[a] += self.size[b];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_coarse_level_copies_what_its_upsampled_level_copies() {
        // A 24x20 map at spacing 4 of a 64x64 exemplar: random coordinates, with two
        // coherent blocks (one wrapping around the exemplar's edge).
        let (w, h, ex, step) = (24usize, 20usize, 64i32, 4i32);
        let mut seed = 7u32;
        let mut rnd = || {
            seed = seed.wrapping_mul(1664525).wrapping_add(1013904223);
            (seed >> 8) as i32
        };
        // Odd x: never coherent with the blocks' even x (steps keep the parity).
        let mut coarse: Vec<[i32; 2]> = (0..w * h)
            .map(|_| [2 * (rnd() % 32) + 1, rnd() % ex])
            .collect();
        for y in 2..9 {
            for x in 3..15 {
                coarse[y * w + x] = [8 + step * (x as i32 - 3), 4 + step * (y as i32 - 2)];
            }
        }
        for y in 12..17 {
            for x in 10..20 {
                let wrap = |v: i32| v.rem_euclid(ex);
                coarse[y * w + x] = [
                    wrap(50 + step * (x as i32 - 10)),
                    20 + step * (y as i32 - 12),
                ];
            }
        }
        // Upsampled to spacing 2 (children `S[p] + 2 o`), as the finest level is.
        let fine: Vec<[i32; 2]> = (0..4 * w * h)
            .map(|i| {
                let (x, y) = (i % (2 * w), i / (2 * w));
                let p = coarse[(y / 2) * w + x / 2];
                let wrap = |v: i32| v.rem_euclid(ex);
                [
                    wrap(p[0] + 2 * (x % 2) as i32),
                    wrap(p[1] + 2 * (y % 2) as i32),
                ]
            })
            .collect();
        for tileable in [false, true] {
            let c = verbatim_stats_at_spacing(&coarse, w as u32, h as u32, 64, 64, tileable, 4)
                .unwrap();
            let f =
                verbatim_stats_at_spacing(&fine, 2 * w as u32, 2 * h as u32, 64, 64, tileable, 2)
                    .unwrap();
            assert_eq!(
                c.largest_region_fraction, f.largest_region_fraction,
                "{tileable}"
            );
            assert_eq!(4 * c.largest_region_pixels, f.largest_region_pixels);
            assert_eq!(c.largest_region_pixels, 12 * 7, "{tileable}");
            assert_eq!(c.largest_region_fraction, (12 * 7 * 16) as f64 / 4096.0);
        }
        // Spacing 1 is verbatim_stats.
        assert_eq!(
            verbatim_stats_at_spacing(&fine, 2 * w as u32, 2 * h as u32, 64, 64, true, 1).unwrap(),
            verbatim_stats(&fine, 2 * w as u32, 2 * h as u32, 64, 64, true).unwrap()
        );
        assert!(
            verbatim_stats_at_spacing(&fine, 2 * w as u32, 2 * h as u32, 64, 64, true, 0).is_err()
        );
    }
}
