//! Mirror of `shaders/gather_aniso.wgsl`: the output colour is the exemplar bilinearly
//! interpolated at the finest level's continuous coordinate (integer weights in
//! 1/65536, rounded), for the pixels of the output window.

use super::common::{bilinear_rgba, PassParams};

/// Bilinear RGBA8 colour at a fixed-point exemplar position.
pub fn color_at(p: &PassParams, colors: &[[u8; 4]], c: [i32; 2]) -> [u8; 4] {
    let c = if p.nearest != 0 {
        c.map(|v| ((v + 128) >> 8) << 8)
    } else {
        c
    };
    bilinear_rgba(colors, p.ex_size, p.tileable != 0, c).map(|v| v as u8)
}

/// Returns the window's fixed-point coordinates and RGBA8 colours, row-major.
pub fn run(
    p: &PassParams,
    coords: &[[i32; 2]],
    colors: &[[u8; 4]],
) -> (Vec<[i32; 2]>, Vec<[u8; 4]>) {
    super::gather::gather_window(p, coords, |c| color_at(p, colors, c))
}
