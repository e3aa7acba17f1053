//! Mirror of `shaders/fill.wgsl`, and the atlas domain it reads: surface synthesis runs
//! the anisometric passes on a texture atlas, where texels outside the charts are not
//! corrected and, after every pass, the gutter texels around each chart are refilled
//! through the indirection map with the coordinates of the same surface point in the
//! neighbouring chart (Lefebvre & Hoppe 2006 §6). Correcting a texel near a chart edge then reads,
//! at its immediate neighbours, the texture across the seam.
//!
//! Filling the gutter once per pass and reading it like any texel is the same as
//! redirecting every neighbour read `S[q]` to `S[I(q)]`: an entry's source is always a
//! chart texel, which no fill writes, and a subpass reads what the previous pass wrote.

use super::common::{fit_coord, PassParams};

/// Texels per row of the fill dispatch (entries are laid out 2D so any count fits the
/// workgroup-count limits). Same as `FILL_ROW` in `fill.wgsl`.
pub const FILL_ROW: u32 = 2048;

/// Fractional bits of the entries' offsets (1/16 texel).
pub const FILL_OFFSET_FRAC: u32 = 4;

/// Largest offset magnitude, in texels (keeps `h * J * offset` within i32).
pub const FILL_OFFSET_MAX: i32 = 2 << FILL_OFFSET_FRAC;

pub use crate::options::{AtlasDomain, AtlasLevel, FillEntry};

impl AtlasLevel {
    /// Whether texel `t` is inside a chart.
    pub fn is_inside(&self, t: usize) -> bool {
        (self.inside[t >> 5] >> (t & 31)) & 1 != 0
    }
}

/// Where each plan level's mask and entries lie in the surface buffer.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SurfaceLayout {
    /// Word offset of the level's chart mask.
    pub mask_base: u32,
    /// Word offset of the level's indirection entries.
    pub fill_base: u32,
    /// Entries of the band.
    pub band_count: u32,
    /// Entries of the whole gutter.
    pub fill_count: u32,
}

impl AtlasDomain {
    /// The surface buffer for a plan of `n_levels` levels (plan level `i` = domain
    /// level `n_levels - 1 - i`) and each plan level's layout in it.
    pub fn surface_words(&self, n_levels: usize) -> (Vec<u32>, Vec<SurfaceLayout>) {
        let mut words = Vec::new();
        let mut layout = Vec::with_capacity(n_levels);
        for i in 0..n_levels {
            let l = &self.levels[n_levels - 1 - i];
            let mask_base = words.len() as u32;
            words.extend_from_slice(&l.inside);
            let fill_base = words.len() as u32;
            for e in &l.fill {
                words.extend_from_slice(&[e.dst, e.src, e.off[0] as u32, e.off[1] as u32]);
            }
            layout.push(SurfaceLayout {
                mask_base,
                fill_base,
                band_count: l.band.min(l.fill.len() as u32),
                fill_count: l.fill.len() as u32,
            });
        }
        (words, layout)
    }
}

/// Whether region texel `t` of the dispatch's level is inside a chart (mirror of
/// `in_chart` in `common.wgsl`).
pub fn in_chart(p: &PassParams, surface: &[u32], t: u32) -> bool {
    p.masked == 0 || (surface[(p.mask_base + (t >> 5)) as usize] >> (t & 31)) & 1 != 0
}

/// `h J d` for an offset in 1/16 texel, in 1/256 exemplar pixel (the fill's variant of
/// `scaled_jd`).
pub fn scaled_jd_frac(h: i32, j: [i32; 4], off: [i32; 2]) -> [i32; 2] {
    let r = 1 << (FILL_OFFSET_FRAC - 1);
    let x = (j[0] * off[0] + j[1] * off[1] + r) >> FILL_OFFSET_FRAC;
    let y = (j[2] * off[0] + j[3] * off[1] + r) >> FILL_OFFSET_FRAC;
    [(h * x + 2) >> 2, (h * y + 2) >> 2]
}

/// Refills the dispatch's gutter texels through their indirection entries (`fill.wgsl`).
pub fn run(p: &PassParams, coords: &mut [[i32; 2]], jac: &[[i32; 4]], surface: &[u32]) {
    let base = p.coord_base as usize;
    for e in 0..p.fill_count as usize {
        let w = p.fill_base as usize + 4 * e;
        let (dst, src) = (surface[w] as usize, surface[w + 1] as usize);
        let off = [surface[w + 2] as i32, surface[w + 3] as i32];
        let s = coords[base + src];
        let o = scaled_jd_frac(p.spacing, jac[base + src], off);
        coords[base + dst] = fit_coord([s[0] + o[0], s[1] + o[1]], p);
    }
}
