//! Mirror of `shaders/gather_aniso.wgsl`: the output colour is the exemplar bilinearly
//! interpolated at the finest level's continuous coordinate (integer weights in
//! 1/65536, rounded), for the pixels of the output window.

use super::common::{bilinear_rgba, PassParams};

/// Bilinear RGBA8 colour at a fixed-point exemplar position.
pub fn color_at(p: &PassParams, colors: &[[u8; 4]], c: [i32; 2]) -> [u8; 4] {
    bilinear_rgba(colors, p.ex_size, p.tileable != 0, c).map(|v| v as u8)
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
