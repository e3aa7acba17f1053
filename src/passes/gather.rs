//! Mirror of `shaders/gather.wgsl`: the output colour is the exemplar at the
//! synthesized coordinate of the finest level, for the pixels of the output window.

use super::common::PassParams;

/// Returns the window's coordinates and RGBA8 colours, row-major.
pub fn run(
    p: &PassParams,
    coords: &[[i32; 2]],
    colors: &[[u8; 4]],
) -> (Vec<[i32; 2]>, Vec<[u8; 4]>) {
    gather_window(p, coords, |c| colors[(c[1] * p.ex_size[0] + c[0]) as usize])
}

/// The window's coordinates (finest level) and the colour `color(c)` of each, row-major:
/// the walk shared by the isometric and anisometric gathers.
pub fn gather_window(
    p: &PassParams,
    coords: &[[i32; 2]],
    color: impl Fn([i32; 2]) -> [u8; 4],
) -> (Vec<[i32; 2]>, Vec<[u8; 4]>) {
    let n = (p.window_size[0] * p.window_size[1]) as usize;
    let mut out_coords = Vec::with_capacity(n);
    let mut out_colors = Vec::with_capacity(n);
    for y in 0..p.window_size[1] {
        for x in 0..p.window_size[0] {
            let q = [x + p.window_offset[0], y + p.window_offset[1]];
            let c = coords[p.coord_base as usize + (q[1] * p.size[0] + q[0]) as usize];
            out_coords.push(c);
            out_colors.push(color(c));
        }
    }
    (out_coords, out_colors)
}
