//! Mirror of `shaders/fade.wgsl`: the last pass of an advection frame with fading
//! ([`crate::passes::advect::AdvectOptions::fade`]). A pixel whose coordinate jumped
//! since the previous frame (it landed more than [`FADE_JUMP`] from where the flow carried
//! the previous frame's coordinate) where the jumps around it changed the colour by
//! more than `fade_change` on average ([`popped`]; by default [`FADE_CHANGE`]: a renewed
//! or remade patch, a pop) fades from what it showed to its new content over
//! `fade_frames` frames. Other jumps (a seam
//! that moved, a patch remade alike) show at once.
//!
//! The fade state, per pixel of the finest level's region, is three coordinate entries:
//! the pixel's coordinate `A`, its ghost's `B`, and the frames the ghost has left `w`
//! (`[w, 0]`). A frame reads the state `k` pixels upstream at `fade_src` (0: none, every
//! pixel starts unfaded), moves `A` and `B` with the flow exactly as the advect pass moves
//! coordinates, and writes the new state at `fade_dst`. With one-frame fades the ghost
//! shows on the frame of the pop only, so only `A` is read and written. Ghosts are
//! coordinates, not colours, so they move with the texture without being resampled
//! (nothing blurs). The colours are blended so that the contrast stays: `mean + (a (c -
//! mean) + w (g - mean)) / sqrt(a^2 + w^2)` with `a = N + 2 - w`, around the exemplar's
//! mean colour (a linear blend of two unrelated patches is flat halfway through). The
//! new content leads by one step (`N + 2`, not `N + 1`): a one-frame fade shows the ghost
//! at 1 against 2, not halfway, which pops less for the same texture energy.
//!
//! The pop test is the mean change over the pixel's 3x3 neighbourhood within its
//! [`TILE`]x[`TILE`] tile (the pass's workgroup, whose invocations share their changes
//! through workgroup memory; pixels that did not jump count 0): an isolated speck that
//! changed is no pop, a patch that changed is. It pops less than testing the pixel's own
//! change; a neighbourhood across tiles would need a pass of its own, which costs more.

use super::advect::{offset, velocity_at, whole_shift};
use super::common::{fit_coord, wrap, PassParams};
use super::gather_aniso::color_at;

/// A jump: more than 1.5 exemplar pixels (1/256 units) per unit of the Jacobian's
/// largest column (at least 1), on either axis.
pub const FADE_JUMP: i32 = 384;

pub use crate::options::FADE_CHANGE;

/// Entries of fade state per pixel of the finest level's region.
pub const STATE_ENTRIES: u32 = 3;

/// Whether coordinate `s` jumped from `a`, where the flow carried the previous frame's
/// coordinate (`jumped` in `fade.wgsl`).
pub fn jumped(p: &PassParams, s: [i32; 2], a: [i32; 2], j: [i32; 4]) -> bool {
    let mut d = [s[0] - a[0], s[1] - a[1]];
    if p.tileable != 0 {
        for (dc, size) in d.iter_mut().zip(p.ex_size) {
            let n = size << p.coord_frac;
            if *dc > n / 2 {
                *dc -= n;
            }
            if *dc < -n / 2 {
                *dc += n;
            }
        }
    }
    let col = (j[0].abs() + j[2].abs()).max(j[1].abs() + j[3].abs());
    let limit = (FADE_JUMP * col.max(1024)) >> 10;
    d[0].abs() > limit || d[1].abs() > limit
}

/// The new colour `c` and the ghost's `g`, `w` frames left of `N`: the ghost weighted
/// `w` against `N + 2 - w` (`fade_blend`).
pub fn blend(p: &PassParams, c: [u8; 4], g: [u8; 4], w: i32) -> [u8; 4] {
    let m = p.fade_mean.to_le_bytes();
    let a = p.fade_frames as i32 + 2 - w;
    let f = ((1u32 << 30) / (a * a + w * w) as u32).isqrt() as i32;
    std::array::from_fn(|k| {
        let (mk, ck, gk) = (m[k] as i32, c[k] as i32, g[k] as i32);
        let num = a * (ck - mk) + w * (gk - mk);
        (mk + ((num * f + (1 << 14)) >> 15)).clamp(0, 255) as u8
    })
}

/// What the pass reads.
pub(super) struct Frame<'a> {
    p: &'a PassParams,
    coords: &'a [[i32; 2]],
    jac: &'a [[i32; 4]],
    velocity: &'a [[i32; 2]],
    colors: &'a [[u8; 4]],
    /// The frame's whole shift.
    k: [i32; 2],
}

impl<'a> Frame<'a> {
    pub(super) fn new(
        p: &'a PassParams,
        coords: &'a [[i32; 2]],
        jac: &'a [[i32; 4]],
        velocity: &'a [[i32; 2]],
        colors: &'a [[u8; 4]],
    ) -> Self {
        Frame {
            p,
            coords,
            jac,
            velocity,
            colors,
            k: if p.fade_src != 0 {
                whole_shift(p, coords, velocity)
            } else {
                [0, 0]
            },
        }
    }

    /// The index of the fade state at region pixel `q`'s upstream pixel, `k` pixels up
    /// the flow, if it lies in the region (`upstream`).
    fn upstream(&self, q: [i32; 2]) -> Option<usize> {
        let (p, k) = (self.p, self.k);
        let (mut sx, mut sy) = (q[0] - k[0], q[1] - k[1]);
        if p.periodic != 0 {
            (sx, sy) = (wrap(sx, p.size[0]), wrap(sy, p.size[1]));
        } else if sx < 0 || sy < 0 || sx >= p.size[0] || sy >= p.size[1] {
            return None;
        }
        Some(p.fade_src as usize + 3 * (sy * p.size[0] + sx) as usize)
    }

    /// The coordinate buffer's index of region pixel `q`.
    fn index(&self, q: [i32; 2]) -> usize {
        self.p.coord_base as usize + (q[1] * self.p.size[0] + q[0]) as usize
    }

    /// Region pixel `q`'s state entry `e` (0: the coordinate, 1: the ghost) as the flow
    /// carried it from the previous frame's state at `si`.
    fn carried(&self, q: [i32; 2], si: usize, e: usize) -> [i32; 2] {
        let p = self.p;
        let vq = velocity_at(p, self.velocity, [p.origin[0] + q[0], p.origin[1] + q[1]]);
        let o = offset(p, self.jac[self.index(q)], vq, self.k);
        let c = self.coords[si + e];
        fit_coord([c[0] - o[0], c[1] - o[1]], p)
    }

    /// Region pixel `q`'s state upstream (its index) and the coordinate the flow carried
    /// there, and how much the pixel's colour changed if it jumped from it (else
    /// [`NO_JUMP`]); `None` if nothing is upstream (the first frame, or a pixel new to the
    /// region).
    fn jump(&self, q: [i32; 2]) -> Option<(usize, [i32; 2], i32)> {
        let p = self.p;
        if p.fade_src == 0 {
            return None;
        }
        let si = self.upstream(q)?;
        let i = self.index(q);
        let s = self.coords[i];
        let a = self.carried(q, si, 0);
        // Most jumps are not pops: seams that moved, patches remade alike.
        let change = if jumped(p, s, a, self.jac[i]) {
            grey_change(color_at(p, self.colors, s), color_at(p, self.colors, a))
        } else {
            NO_JUMP
        };
        Some((si, a, change))
    }

    /// Region pixel `q`'s new fade state, its ghost and the frames the ghost has left,
    /// from its [`Frame::jump`] and whether it popped.
    fn state(
        &self,
        q: [i32; 2],
        jump: Option<(usize, [i32; 2], i32)>,
        pop: bool,
    ) -> ([i32; 2], i32) {
        let p = self.p;
        let s = self.coords[self.index(q)];
        let Some((si, a, _)) = jump else {
            return (s, 0);
        };
        // At most N: a fade saved under a longer N goes on with the new one. One-frame
        // fades keep no ghost from frame to frame.
        let left = if p.fade_frames > 1 {
            (self.coords[si + 2][0] - 1).clamp(0, p.fade_frames as i32)
        } else {
            0
        };
        // A pop while a ghost shows: the one shown most stays the ghost.
        if pop && 2 * left <= p.fade_frames as i32 {
            (a, p.fade_frames as i32)
        } else if left > 0 {
            (self.carried(q, si, 1), left)
        } else {
            (s, 0)
        }
    }
}

/// A pixel's change where it did not jump (counts 0 in the pop test).
pub const NO_JUMP: i32 = -1;

/// The side of the square tiles the pop test looks within: the fade pass's workgroups,
/// from the region's origin.
pub const TILE: i32 = 8;

/// Whether the pixel at `q` of a region of `size` popped, given every region pixel's
/// change (row-major; [`NO_JUMP`] where it did not jump): the mean change over its 3x3
/// neighbourhood within its [`TILE`]-square tile (pixels that did not jump count 0)
/// exceeds `fade_change` (`popped` in `fade.wgsl`, which shares the changes through
/// workgroup memory). An isolated speck that changed is no pop, a patch that changed is.
pub fn popped(changes: &[i32], size: [i32; 2], q: [i32; 2], fade_change: u32) -> bool {
    let tile = [q[0] - q[0] % TILE, q[1] - q[1] % TILE];
    let (mut sum, mut n) = (0, 0);
    for dy in -1..=1 {
        for dx in -1..=1 {
            let m = [q[0] + dx, q[1] + dy];
            let in_tile = (0..2).all(|k| m[k] >= tile[k] && m[k] < tile[k] + TILE);
            if in_tile && m[0] < size[0] && m[1] < size[1] {
                sum += changes[(m[1] * size[0] + m[0]) as usize].max(0);
                n += 1;
            }
        }
    }
    sum > n * fade_change as i32
}

/// How much a colour changed from `a` to `c`, `(|dR| + 2 |dG| + |dB|) / 4` (0..255;
/// `grey_change`).
pub fn grey_change(c: [u8; 4], a: [u8; 4]) -> i32 {
    let d = |k: usize| (c[k] as i32 - a[k] as i32).abs();
    (d(0) + 2 * d(1) + d(2)) >> 2
}

/// Runs the pass over the finest level's region (`p.size` at `p.coord_base`): writes
/// the new fade state and returns the window's coordinates and colours, row-major.
pub fn run(
    p: &PassParams,
    coords: &mut [[i32; 2]],
    jac: &[[i32; 4]],
    velocity: &[[i32; 2]],
    colors: &[[u8; 4]],
) -> (Vec<[i32; 2]>, Vec<[u8; 4]>) {
    let n = p.window_size[0] as usize * p.window_size[1] as usize;
    let (mut out_coords, mut out_colors) = (vec![[0; 2]; n], vec![[0; 4]; n]);
    let frame = Frame::new(p, coords, jac, velocity, colors);
    let pixels = || (0..p.size[1]).flat_map(|y| (0..p.size[0]).map(move |x| [x, y]));
    let jumps: Vec<_> = pixels().map(|q| frame.jump(q)).collect();
    let changes: Vec<i32> = jumps.iter().map(|j| j.map_or(NO_JUMP, |j| j.2)).collect();
    let mut state = Vec::with_capacity((p.size[0] * p.size[1]) as usize * 3);
    for (q, &jump) in pixels().zip(&jumps) {
        let s = frame.coords[frame.index(q)];
        let pop = jump.is_some_and(|j| j.2 >= 0) && popped(&changes, p.size, q, p.fade_change);
        let (ghost, w) = frame.state(q, jump, pop);
        state.extend([s, ghost, [w, 0]]);
        let (wx, wy) = (q[0] - p.window_offset[0], q[1] - p.window_offset[1]);
        if wx < 0 || wy < 0 || wx >= p.window_size[0] || wy >= p.window_size[1] {
            continue;
        }
        let o = (wy * p.window_size[0] + wx) as usize;
        let mut v = color_at(p, colors, s);
        if w > 0 {
            v = blend(p, v, color_at(p, colors, ghost), w);
        }
        out_coords[o] = s;
        out_colors[o] = v;
    }
    let dst = &mut coords[p.fade_dst as usize..][..state.len()];
    if p.fade_frames > 1 {
        dst.copy_from_slice(&state);
    } else {
        // One-frame fades: the coordinates alone (the ghost's entries are not written).
        for (d, s) in dst.chunks_exact_mut(3).zip(state.chunks_exact(3)) {
            d[0] = s[0];
        }
    }
    (out_coords, out_colors)
}

/// The exemplar's mean colour, RGBA8 packed little-endian (`PassParams::fade_mean`).
pub fn mean_color(colors: &[[u8; 4]]) -> u32 {
    let n = colors.len().max(1) as u64;
    let mut sum = [0u64; 4];
    for c in colors {
        for (s, &v) in sum.iter_mut().zip(c) {
            *s += v as u64;
        }
    }
    u32::from_le_bytes(sum.map(|s| ((s + n / 2) / n) as u8))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(frames: u32, mean: [u8; 4]) -> PassParams {
        PassParams {
            fade_frames: frames,
            fade_mean: u32::from_le_bytes(mean),
            ..Default::default()
        }
    }

    #[test]
    fn blend_keeps_the_new_colour_at_no_ghost_and_the_contrast_halfway() {
        let p = params(6, [100, 100, 100, 255]);
        // No ghost left: the new colour exactly.
        assert_eq!(
            blend(&p, [30, 200, 120, 255], [0, 0, 0, 255], 0),
            [30, 200, 120, 255]
        );
        // Halfway (w = 4 against N + 2 - w = 4) between two deviations of 40 of opposite
        // signs on red, equal on green: red stays at the mean, green 40 * 2 / sqrt(2) =
        // 56.6 above.
        let v = blend(&p, [140, 140, 100, 255], [60, 140, 100, 255], 4);
        assert_eq!(v, [100, 157, 100, 255]);
        // Just popped (w = N): mostly the ghost.
        let v = blend(&p, [200, 100, 100, 255], [0, 100, 100, 255], 6);
        assert!(v[0] < 40, "{v:?}");
        // A one-frame fade: the new content leads, 100 (2 - 1) / sqrt(5) = 44.7 above.
        let v = blend(
            &params(1, [100; 4]),
            [200, 100, 100, 255],
            [0, 100, 100, 255],
            1,
        );
        assert_eq!(v[0], 145);
        // Clamped to 0..255.
        assert_eq!(blend(&p, [255, 0, 0, 255], [255, 0, 0, 255], 4)[0], 255);
    }

    #[test]
    fn jumps_are_measured_across_the_wrap_and_scale_with_the_jacobian() {
        let mut p = params(8, [0; 4]);
        p.ex_size = [64, 64];
        p.coord_frac = 8;
        let id = [1024, 0, 0, 1024];
        assert!(!jumped(&p, [1000, 1000], [1000 + 384, 1000], id));
        assert!(jumped(&p, [1000, 1000], [1000 + 385, 1000], id));
        // Across the wrap: far apart in numbers, 2 pixels apart around the torus.
        let n = 64 << 8;
        assert!(jumped(&p, [0, 0], [n - 512, 0], id));
        p.tileable = 1;
        assert!(!jumped(&p, [0, 0], [n - 256, 0], id));
        assert!(jumped(&p, [0, 0], [n - 512, 0], id));
        // Twice the Jacobian (the texture minified 2x): twice the tolerance.
        assert!(!jumped(&p, [0, 0], [700, 0], [2048, 0, 0, 2048]));
    }

    #[test]
    fn pops_are_patches_that_changed_within_a_tile() {
        // A 12x10 region: tiles of 8 from its origin, the right and bottom ones cut short.
        let size = [12, 10];
        let mut changes = vec![NO_JUMP; 120];
        let mut set = |x: i32, y: i32, c: i32| changes[(y * 12 + x) as usize] = c;
        // An isolated speck that changed a lot: no pop (mean 200 / 9 over its 3x3).
        set(3, 3, 200);
        // A 3x3 patch that changed by 70 in tile (0, 0)'s corner: its centre's mean is 70.
        for y in 5..8 {
            for x in 5..8 {
                set(x, y, 70);
            }
        }
        assert!(!popped(&changes, size, [3, 3], 60));
        assert!(popped(&changes, size, [6, 6], 60));
        assert!(!popped(&changes, size, [6, 6], 70));
        // (7, 7), the tile's corner: its window is the 2x2 inside the tile, all 70 (across
        // the tile's edges it would be 4 of 9).
        assert!(popped(&changes, size, [7, 7], 60));
        // Across a tile's edge the neighbours do not count: (7, 7) and (8, 7) changed, in
        // different tiles, each alone in its window.
        let mut changes = vec![NO_JUMP; 120];
        changes[7 * 12 + 7] = 100;
        changes[7 * 12 + 8] = 100;
        assert!(!popped(&changes, size, [7, 7], 30));
        // At the region's bottom-right corner the window holds the 2x2 inside the region.
        let mut changes = vec![NO_JUMP; 120];
        for (x, y) in [(10, 8), (11, 8), (10, 9), (11, 9)] {
            changes[y * 12 + x] = 50;
        }
        assert!(popped(&changes, size, [11, 9], 49));
        assert!(!popped(&changes, size, [11, 9], 50));
    }

    #[test]
    fn mean_color_rounds() {
        assert_eq!(
            mean_color(&[[0, 10, 255, 255], [1, 11, 255, 255]]).to_le_bytes(),
            [1, 11, 255, 255]
        );
    }
}
