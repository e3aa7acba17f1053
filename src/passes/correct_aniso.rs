//! Mirror of `shaders/correct_aniso.wgsl`: one anisometric correction subpass
//! (Lefebvre & Hoppe 2006 §5). Coordinates are continuous (1/256 exemplar pixel), `J(p)` comes per pixel
//! from the field.
//!
//! Neighbourhood: for each diagonal `D` and `D' in {D, (D.x,0), (0,D.y)}`, the pixel
//! `p + Δ` with `Δ = phi(J^-1 D')` (the immediate neighbour closest in direction)
//! predicts `Et[S[p+Δ] - h J Δ + h D]`, read with bilinear interpolation (integer
//! weights) where the projected distance scores (finest level), at the nearest texel
//! where the full distance does (coarse levels: `Et` is smooth at the pixel scale there,
//! the candidates are scored at their nearest texel too, and the four bilinear reads
//! would cost a fifth of those levels' time). Summed as in the isometric pass (`3 N_S(p;D)`).
//!
//! Candidates: `S[p+d] + O_i(S[p+d]) - h J d` for the 3x3 block and `i = 1..k`, the
//! similarity offsets taken at the exemplar pixel nearest to `S[p+d]`. The projected
//! distance (finest level by default) compares with `qe` bilinearly interpolated at the
//! coherent candidates (`i = 0`; nearest-pixel scoring of every candidate misregisters
//! fine detail by up to half a pixel and breaks coherent patches) and at
//! the nearest texel for the similarity-set ones (fewer seams, same energy); the full
//! distance (coarse levels, smooth at
//! their scale) reads `Et` at the four diagonals of the candidate's nearest pixel. Same tie rule and
//! coherence bias as the isometric pass. With `J = I` every coordinate stays a multiple
//! of 256 and the result is the isometric pass's times 256 (tested).
//!
//! `p.quarter` (advection frames) rounds every interpolated read to its nearest quarter
//! pixel, so the GPU can read the finest level's `Et` and `qe` from tables supersampled
//! at quarter pixels ([`quarter_table`]): one read instead of four. Advection frames
//! look the same with it; a synthesis along a swirl loses Jacobian fidelity, so
//! synthesis keeps the exact positions.
//!
//! `p.coherent_skip` (advection frames) leaves a pixel whose 8 neighbours all continue
//! its patch (`S[q + d] = S[q] + h J d` within [`COHERENT_TOL`] per axis): its own
//! coordinate predicts its neighbourhood, so the correction would keep it or nudge it
//! within the pixel. Under a turning flow about a seventh of the finest level's
//! correction time goes: the skipped pixels' loads, not their SIMD group's arithmetic,
//! which CPU drivers run with the lanes masked (see
//! [`crate::passes::advect::AdvectOptions::skip_coherent`]).

use super::common::{
    bilinear_taps, coord_delta, fit_coord, is_valid_fx, nearest_texel, phi_inv, quarter_texel,
    read_coord_fx, region_index, scaled_jd, PassParams, COORD_FRAC, QUARTER_BITS,
};
use super::correct::{full_distance, project, LevelTables};
use crate::analysis::QE_MAX;
use crate::analysis::{DIAGONALS, DIM};

#[inline]
fn ex_index(c: [i32; 2], p: &PassParams) -> usize {
    (c[1] * p.ex_size[0] + c[0]) as usize
}

/// `Et` bilinearly interpolated at a fixed-point position (weights in 1/65536, rounded).
pub fn et_bilinear(p: &PassParams, t: &LevelTables, u: [i32; 2]) -> [i32; DIM] {
    table_bilinear(p, t.et, u)
}

/// A per-pixel 8D table (`Et` or `qe`) bilinearly interpolated at a fixed-point
/// position (weights in 1/65536, rounded; exact at whole pixels), or with
/// `p.quarter` at the quarter pixel nearest to it.
pub fn table_bilinear(p: &PassParams, table: &[[i16; DIM]], u: [i32; 2]) -> [i32; DIM] {
    let c = read_coord_fx(u, p);
    if p.quarter != 0 {
        let s = quarter_texel(c, p);
        return bilinear_at(p, table, [s[0] << QUARTER_SHIFT, s[1] << QUARTER_SHIFT]);
    }
    bilinear_at(p, table, c)
}

/// Fixed-point units per quarter pixel (as a shift).
const QUARTER_SHIFT: u32 = COORD_FRAC - QUARTER_BITS;

/// A table interpolated at every quarter pixel of the exemplar (`4 w x 4 h` entries,
/// row-major): what [`table_bilinear`] returns with `p.quarter`, so that the GPU reads
/// one entry where interpolation reads four (`crate::gpu::synth`'s fine tables; the
/// same numbers either way). Entries past the last pixel of a non-tileable exemplar
/// are never read; they repeat the edge.
pub fn quarter_table(p: &PassParams, table: &[[i16; DIM]]) -> Vec<[i16; DIM]> {
    let (w, h) = (p.ex_size[0] << QUARTER_BITS, p.ex_size[1] << QUARTER_BITS);
    let mut out = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let c = read_coord_fx([x << QUARTER_SHIFT, y << QUARTER_SHIFT], p);
            // A convex combination rounded: within the i16 range of its texels.
            out.push(bilinear_at(p, table, c).map(|v| v as i16));
        }
    }
    out
}

/// [`table_bilinear`] at a wrapped/clamped position.
fn bilinear_at(p: &PassParams, table: &[[i16; DIM]], c: [i32; 2]) -> [i32; DIM] {
    let (i0, i1, f) = bilinear_taps(c, p);
    let e00 = table[ex_index(i0, p)];
    if f == [0, 0] {
        return e00.map(|v| v as i32);
    }
    let e10 = table[ex_index([i1[0], i0[1]], p)];
    let e01 = table[ex_index([i0[0], i1[1]], p)];
    let e11 = table[ex_index(i1, p)];
    let w00 = (256 - f[0]) * (256 - f[1]);
    let w10 = f[0] * (256 - f[1]);
    let w01 = (256 - f[0]) * f[1];
    let w11 = f[0] * f[1];
    let mut out = [0i32; DIM];
    for c in 0..DIM {
        let v =
            w00 * e00[c] as i32 + w10 * e10[c] as i32 + w01 * e01[c] as i32 + w11 * e11[c] as i32;
        out[c] = (v + 32768) >> 16;
    }
    out
}

/// [`super::correct::projected_distance`] against an interpolated exemplar side.
#[inline]
pub fn projected_distance_i32(ns: &[i32; DIM], qe: &[i32; DIM]) -> u32 {
    let mut d = 0u32;
    for c in 0..DIM {
        let x = (ns[c] - qe[c]).clamp(-2 * QE_MAX, 2 * QE_MAX);
        d += (x * x) as u32;
    }
    d
}

/// Per diagonal, the sum of the three anisometric predictions (`3 N_S(q;D)`).
pub fn prediction_sums(
    p: &PassParams,
    t: &LevelTables,
    coords: &[[i32; 2]],
    jac: &[[i32; 4]],
    q: [i32; 2],
) -> [[i32; DIM]; 4] {
    let base = p.coord_base as usize;
    let j = jac[base + region_index(q, p)];
    let h = p.spacing;
    let one = 1 << COORD_FRAC;
    let mut out = [[0i32; DIM]; 4];
    for (k, d) in DIAGONALS.iter().enumerate() {
        for dp in [*d, [d[0], 0], [0, d[1]]] {
            let delta = phi_inv(j, dp);
            let s = coords[base + region_index([q[0] + delta[0], q[1] + delta[1]], p)];
            let o = scaled_jd(h, j, delta);
            let u = [s[0] - o[0] + h * one * d[0], s[1] - o[1] + h * one * d[1]];
            // Nearest texel with the full distance (coarse levels, smooth at the pixel
            // scale; candidates are scored at their nearest texel too).
            let e = if p.full_distance != 0 {
                t.et[ex_index(nearest_texel(read_coord_fx(u, p), p), p)].map(i32::from)
            } else {
                et_bilinear(p, t, u)
            };
            for c in 0..DIM {
                out[k][c] += e[c];
            }
        }
    }
    out
}

/// How far (fixed-point units per axis) a neighbour may stray from continuing a pixel's
/// patch for `p.coherent_skip` to leave the pixel: a quarter pixel.
pub const COHERENT_TOL: i32 = 1 << (COORD_FRAC - 2);

/// Whether all 8 neighbours of region pixel `q` continue its patch within
/// [`COHERENT_TOL`]: `S[q + d] - S[q] - h J d`, the shortest way around a tileable
/// exemplar. A neighbour clamped at the region's edge is the pixel itself, which does not
/// continue it.
pub fn coherent_interior(
    p: &PassParams,
    coords: &[[i32; 2]],
    jac: &[[i32; 4]],
    q: [i32; 2],
) -> bool {
    let base = p.coord_base as usize;
    let j = jac[base + region_index(q, p)];
    let s = coords[base + region_index(q, p)];
    (-1..=1).all(|dy| {
        (-1..=1).all(|dx| {
            let n = coords[base + region_index([q[0] + dx, q[1] + dy], p)];
            let o = scaled_jd(p.spacing, j, [dx, dy]);
            let e = coord_delta([n[0] - s[0] - o[0], n[1] - s[1] - o[1]], p);
            e[0].abs() <= COHERENT_TOL && e[1].abs() <= COHERENT_TOL
        })
    })
}

/// New fixed-point coordinate of the pixel at region position `q`.
pub fn correct_pixel(
    p: &PassParams,
    t: &LevelTables,
    coords: &[[i32; 2]],
    jac: &[[i32; 4]],
    q: [i32; 2],
) -> [i32; 2] {
    let base = p.coord_base as usize;
    if p.coherent_skip != 0 && coherent_interior(p, coords, jac, q) {
        return coords[base + region_index(q, p)];
    }
    let j = jac[base + region_index(q, p)];
    let h = p.spacing;
    let sums = prediction_sums(p, t, coords, jac, q);
    let full = p.full_distance != 0;
    let ns = if full { [0; DIM] } else { project(p, t, &sums) };
    // `interpolate`: the coherent candidates are scored with `qe` interpolated at their
    // sub-pixel position; the similarity-set ones (jumps elsewhere in the exemplar, of
    // arbitrary sub-pixel phase) at their nearest texel, which gives fewer seams at the
    // same texture energy.
    let distance = |c: [i32; 2], interpolate: bool| {
        if full {
            full_distance(p, t, &sums, nearest_texel(c, p))
        } else if interpolate {
            let e = table_bilinear(p, t.qe, c);
            projected_distance_i32(&ns, &e)
        } else {
            let e = t.qe[ex_index(nearest_texel(c, p), p)].map(i32::from);
            projected_distance_i32(&ns, &e)
        }
    };
    let mut best = coords[base + region_index(q, p)];
    let mut best_d = u32::MAX;
    if is_valid_fx(best, p) {
        best_d = distance(best, true);
    }
    // With the full distance a candidate scores as its nearest texel does: one on the
    // best one's texel cannot beat it (unless it is coherent and the best one is a
    // similarity-set candidate, which carries the coherence penalty), so it is skipped
    // (the shader saves its reads).
    let mut best_texel = nearest_texel(best, p);
    let mut best_from_set = false;
    let km1 = (p.k - 1).max(0) as usize;
    for dy in -1..=1 {
        for dx in -1..=1 {
            let s = coords[base + region_index([q[0] + dx, q[1] + dy], p)];
            let hjd = scaled_jd(h, j, [dx, dy]);
            let sn = nearest_texel(s, p);
            for i in 0..p.k as usize {
                let o = if i == 0 {
                    [0, 0]
                } else {
                    let o = t.offsets[ex_index(sn, p) * km1 + i - 1];
                    [(o[0] as i32) << COORD_FRAC, (o[1] as i32) << COORD_FRAC]
                };
                let raw = [s[0] + o[0] - hjd[0], s[1] + o[1] - hjd[1]];
                if !is_valid_fx(raw, p) {
                    continue;
                }
                let c = fit_coord(raw, p);
                if c == best {
                    continue;
                }
                if full
                    && best_d != u32::MAX
                    && nearest_texel(c, p) == best_texel
                    && (i > 0 || !best_from_set)
                {
                    continue;
                }
                let mut d = distance(c, i == 0 || p.kset_interp != 0);
                if i > 0 {
                    d += (d >> 4) * p.coherence;
                }
                if d < best_d {
                    best_d = d;
                    best = c;
                    best_texel = nearest_texel(c, p);
                    best_from_set = i > 0;
                }
            }
        }
    }
    best
}

/// One subpass over the level's region.
pub fn run(
    p: &PassParams,
    t: &LevelTables,
    coords: &mut [[i32; 2]],
    jac: &[[i32; 4]],
    surface: &[u32],
) {
    for [x, y] in super::common::subpass_pixels(p) {
        // Atlas synthesis leaves texels outside the charts to the fill pass.
        if !super::fill::in_chart(p, surface, (y * p.size[0] + x) as u32) {
            continue;
        }
        let c = correct_pixel(p, t, coords, jac, [x, y]);
        coords[p.coord_base as usize + (y * p.size[0] + x) as usize] = c;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pixel counts as inside a coherent patch when each of its 8 neighbours is its
    /// coordinate plus `h J d` within a quarter pixel per axis; not at the region's edge
    /// (the clamped neighbour is the pixel itself); the shortest way around a tileable
    /// exemplar.
    #[test]
    fn coherent_interior_follows_the_patch() {
        let p = PassParams {
            ex_size: [64, 64],
            size: [5, 5],
            spacing: 1,
            ..Default::default()
        };
        let ident = vec![[1024, 0, 0, 1024]; 25];
        let patch = |origin: [i32; 2], j: [i32; 4]| -> Vec<[i32; 2]> {
            (0..25)
                .map(|i| {
                    let (x, y) = (i % 5 - 2, i / 5 - 2);
                    let o = scaled_jd(1, j, [x, y]);
                    [origin[0] + o[0], origin[1] + o[1]]
                })
                .collect()
        };
        let mut c = patch([20 << 8, 30 << 8], ident[0]);
        assert!(coherent_interior(&p, &c, &ident, [2, 2]));
        assert!(!coherent_interior(&p, &c, &ident, [0, 2]), "edge");
        c[3 * 5 + 3][0] += COHERENT_TOL;
        assert!(coherent_interior(&p, &c, &ident, [2, 2]));
        c[3 * 5 + 3][0] += 1;
        assert!(!coherent_interior(&p, &c, &ident, [2, 2]));
        // Along a field: a rotated, scaled patch is coherent under its own J only.
        let j = [900, -500, 500, 900];
        let rotated = patch([20 << 8, 30 << 8], j);
        let jac = vec![j; 25];
        assert!(coherent_interior(&p, &rotated, &jac, [2, 2]));
        assert!(!coherent_interior(&p, &rotated, &ident, [2, 2]));
        // Across the wrap of a tileable exemplar.
        let wrapped: Vec<[i32; 2]> = patch([0, 0], ident[0])
            .iter()
            .map(|c| [c[0].rem_euclid(64 << 8), c[1].rem_euclid(64 << 8)])
            .collect();
        assert!(!coherent_interior(&p, &wrapped, &ident, [2, 2]));
        let t = PassParams { tileable: 1, ..p };
        assert!(coherent_interior(&t, &wrapped, &ident, [2, 2]));
    }

    /// The quarter-pixel table holds exactly what the quarter-pixel reads interpolate,
    /// for tileable (wrapping past the last pixel) and clamped exemplars.
    #[test]
    fn quarter_table_matches_quarter_reads() {
        let (w, h) = (5, 3);
        let table: Vec<[i16; DIM]> = (0..w * h)
            .map(|i| std::array::from_fn(|c| ((i * 7919 + c * 104_729) % 65_536) as i16))
            .collect();
        for tileable in [0, 1] {
            let p = PassParams {
                ex_size: [w as i32, h as i32],
                tileable,
                quarter: 1,
                ..Default::default()
            };
            let q = quarter_table(&p, &table);
            assert_eq!(q.len(), w * h * 16);
            for y in -300..(h as i32 * 256 + 300) {
                for x in (-300..(w as i32 * 256 + 300)).step_by(7) {
                    let u = [x, y];
                    let s = quarter_texel(read_coord_fx(u, &p), &p);
                    let i = (s[1] * (w as i32 * 4) + s[0]) as usize;
                    assert_eq!(table_bilinear(&p, &table, u), q[i].map(i32::from), "{u:?}");
                }
            }
            // Exact at whole pixels, as the nearest-texel reads of the similarity sets.
            for y in 0..h {
                for x in 0..w {
                    assert_eq!(q[(4 * y) * 4 * w + 4 * x], table[y * w + x]);
                }
            }
        }
    }
}
