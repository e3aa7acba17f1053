//! Mirror of `shaders/gather_aniso.wgsl`: the output colour is the exemplar bilinearly
//! interpolated at the finest level's continuous coordinate (integer weights in
//! 1/65536, rounded), for the pixels of the output window.

use super::common::{bilinear_taps, read_coord_fx, PassParams};

/// Bilinear RGBA8 colour at a fixed-point exemplar position.
pub fn color_at(p: &PassParams, colors: &[[u8; 4]], c: [i32; 2]) -> [u8; 4] {
    let (i0, i1, f) = bilinear_taps(read_coord_fx(c, p), p);
    let at = |x: i32, y: i32| colors[(y * p.ex_size[0] + x) as usize];
    let w = [
        (256 - f[0]) * (256 - f[1]),
        f[0] * (256 - f[1]),
        (256 - f[0]) * f[1],
        f[0] * f[1],
    ];
    let t = [
        at(i0[0], i0[1]),
        at(i1[0], i0[1]),
        at(i0[0], i1[1]),
        at(i1[0], i1[1]),
    ];
    let mut out = [0u8; 4];
    for ch in 0..4 {
        let v: i32 = (0..4).map(|i| w[i] * t[i][ch] as i32).sum();
        out[ch] = ((v + 32768) >> 16) as u8;
    }
    out
}

/// Returns the window's fixed-point coordinates and RGBA8 colours, row-major.
pub fn run(
    p: &PassParams,
    coords: &[[i32; 2]],
    colors: &[[u8; 4]],
) -> (Vec<[i32; 2]>, Vec<[u8; 4]>) {
    let n = (p.window_size[0] * p.window_size[1]) as usize;
    let mut out_coords = Vec::with_capacity(n);
    let mut out_colors = Vec::with_capacity(n);
    for y in 0..p.window_size[1] {
        for x in 0..p.window_size[0] {
            let q = [x + p.window_offset[0], y + p.window_offset[1]];
            let c = coords[p.coord_base as usize + (q[1] * p.size[0] + q[0]) as usize];
            out_coords.push(c);
            out_colors.push(color_at(p, colors, c));
        }
    }
    (out_coords, out_colors)
}
