//! Mirror of `shaders/jitter.wgsl`:
//! `S[p] += floor(h_l * r_l * H(p, l, seed) + 0.5)`, in fixed point. `H` takes 12 bits
//! of each hash as a value in [-1, 1); the amplitude `h_l r_l` comes in 1/16 pixel,
//! so the offset is `(amp * s + 2^14) >> 15`, exactly the same on every device.

use super::common::{fit_coord, hash_pixel, PassParams};

#[inline]
pub fn jitter_offset(abs: [i32; 2], level: u32, seed: u32, amp: i32) -> [i32; 2] {
    let h = hash_pixel(abs, level, seed);
    let s = [(h[0] & 0xfff) as i32 - 2048, (h[1] & 0xfff) as i32 - 2048];
    [
        (amp * s[0] + (1 << 14)) >> 15,
        (amp * s[1] + (1 << 14)) >> 15,
    ]
}

pub fn run(p: &PassParams, coords: &mut [[i32; 2]]) {
    if p.jitter_amp == 0 {
        return;
    }
    for y in 0..p.size[1] {
        for x in 0..p.size[0] {
            let i = p.coord_base as usize + (y * p.size[0] + x) as usize;
            let o = jitter_offset(
                [p.origin[0] + x, p.origin[1] + y],
                p.level,
                p.seed,
                p.jitter_amp,
            );
            let f = p.coord_frac;
            coords[i] = fit_coord([coords[i][0] + (o[0] << f), coords[i][1] + (o[1] << f)], p);
        }
    }
}
