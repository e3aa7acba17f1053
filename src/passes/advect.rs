//! Mirrors of `shaders/advect.wgsl` and `shaders/distortion.wgsl`: texture advection
//! (paper section 7, ALGORITHM.md "Advection"). Per frame, the finest levels' continuous
//! coordinates are advected without resampling, `S[p] = S'[p - k] - J(p) (V(p) - k)`
//! with `k` the velocity at the window's centre rounded to whole pixels of the level
//! (one drift for all pixels, so neighbours stay coherent), so the texture moves with the
//! flow (a uniform flow of whole pixels translates it exactly, seams included); where the advected coordinates no
//! longer follow the desired Jacobian (`|J_obs - J|_F > c`, divergent or shearing flows
//! stretch them) the pixel is upsampled again from the coarser level; then the usual
//! correction passes run.

use super::common::{fit_coord, region_index, scaled_jd, PassParams};
use super::fill::in_chart;

/// Fractional bits of velocities (1/16 output pixel per frame).
pub const VELOCITY_FRAC: u32 = 4;
/// Largest speed, output pixels per frame (keeps `J V` within i32).
pub const MAX_SPEED: f32 = 64.0;

/// Velocity (1/16 px) at the finest pixel under level pixel `abs` (absolute).
pub fn velocity_at(p: &PassParams, velocity: &[[i32; 2]], abs: [i32; 2]) -> [i32; 2] {
    let half = (1i32 << p.steps) >> 1;
    let f = |a: i32, o: i32, n: i32| ((a << p.steps) + half - o).clamp(0, n - 1);
    let x = f(abs[0], p.window_origin[0], p.window_size[0]);
    let y = f(abs[1], p.window_origin[1], p.window_size[1]);
    velocity[(y * p.window_size[0] + x) as usize]
}

/// Mirror of `advect_copy.wgsl`: the level's coordinates to the scratch region.
pub fn copy(p: &PassParams, coords: &mut [[i32; 2]]) {
    let n = (p.size[0] * p.size[1]) as usize;
    let (b, f) = (p.coord_base as usize, p.flag_base as usize);
    coords.copy_within(b..b + n, f);
}

pub fn advect(p: &PassParams, coords: &mut [[i32; 2]], jac: &[[i32; 4]], velocity: &[[i32; 2]]) {
    let unit = 16i32 << p.steps;
    for y in 0..p.size[1] {
        for x in 0..p.size[0] {
            let i = p.coord_base as usize + (y * p.size[0] + x) as usize;
            let vq = velocity_at(p, velocity, [p.origin[0] + x, p.origin[1] + y]);
            let ws = p.window_size;
            let vc = velocity[((ws[1] / 2) * ws[0] + ws[0] / 2) as usize];
            let k = vc.map(|c| (c + (unit >> 1)) >> (4 + p.steps));
            let v = [vq[0] - k[0] * unit, vq[1] - k[1] * unit];
            let sx = (x - k[0]).clamp(0, p.size[0] - 1);
            let sy = (y - k[1]).clamp(0, p.size[1] - 1);
            let prev = coords[p.flag_base as usize + (sy * p.size[0] + sx) as usize];
            let j = jac[i];
            let jv = [
                (j[0] * v[0] + j[1] * v[1] + 8) >> 4,
                (j[2] * v[0] + j[3] * v[1] + 8) >> 4,
            ];
            let o = [(jv[0] + 2) >> 2, (jv[1] + 2) >> 2];
            coords[i] = fit_coord([prev[0] - o[0], prev[1] - o[1]], p);
        }
    }
}

fn step_err(p: &PassParams, d: [i32; 2]) -> u32 {
    let mut e = d;
    if p.tileable != 0 {
        for k in 0..2 {
            let n = p.ex_size[k] << p.coord_frac;
            if e[k] > n / 2 {
                e[k] -= n;
            }
            if e[k] < -n / 2 {
                e[k] += n;
            }
        }
    }
    let c = e.map(|v| v.clamp(-16384, 16384).unsigned_abs());
    c[0] * c[0] + c[1] * c[1]
}

pub fn distortion(p: &PassParams, coords: &mut [[i32; 2]], jac: &[[i32; 4]], surface: &[u32]) {
    let base = p.coord_base as usize;
    let mut flags = Vec::with_capacity((p.size[0] * p.size[1]) as usize);
    for y in 0..p.size[1] {
        for x in 0..p.size[0] {
            let t = (y * p.size[0] + x) as u32;
            if !in_chart(p, surface, t) {
                flags.push(0);
                continue;
            }
            let i = base + t as usize;
            let (s, j, h) = (coords[i], jac[i], p.spacing);
            let at = |dx: i32, dy: i32| coords[base + region_index([x + dx, y + dy], p)];
            let axis = |e: [i32; 2]| {
                let ex = scaled_jd(h, j, e);
                let f = at(e[0], e[1]);
                let b = at(-e[0], -e[1]);
                let fwd = [f[0] - s[0] - ex[0], f[1] - s[1] - ex[1]];
                let bwd = [s[0] - b[0] - ex[0], s[1] - b[1] - ex[1]];
                step_err(p, fwd).min(step_err(p, bwd))
            };
            let err = axis([1, 0]) + axis([0, 1]);
            flags.push((err > p.distortion_max) as i32);
        }
    }
    for (t, f) in flags.into_iter().enumerate() {
        coords[p.flag_base as usize + t] = [f, 0];
    }
}

/// `distortion_max` for threshold `c` (Jacobian units) at spacing `h`.
pub fn distortion_max(c: f32, h: i32) -> u32 {
    let v = (c as f64 * h as f64 * 256.0).powi(2);
    v.min(i32::MAX as f64) as u32
}
