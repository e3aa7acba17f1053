//! Mirror of `shaders/gather_aniso.wgsl`: the output colour is the exemplar bilinearly
//! interpolated at the finest level's continuous coordinate (integer weights in
//! 1/65536, rounded), for the pixels of the output window.

use super::common::{bilinear_rgba, region_index, same_patch, scaled_jd, PassParams};

/// Bilinear RGBA8 colour at a fixed-point exemplar position.
pub fn color_at(p: &PassParams, colors: &[[u8; 4]], c: [i32; 2]) -> [u8; 4] {
    let c = if p.nearest != 0 {
        c.map(|v| ((v + 128) >> 8) << 8)
    } else {
        c
    };
    bilinear_rgba(colors, p.ex_size, p.tileable != 0, c).map(|v| v as u8)
}

/// Returns the window's fixed-point coordinates and RGBA8 colours, row-major. With
/// `seam_blend`, as in [`super::gather::run`]: a 4-neighbour `n` whose prediction
/// `S[n] - h J (n - p)` is 3/4 pixel or more from the pixel's coordinate (a patch seam,
/// not the sub-pixel misfit of a varying field) adds its predicted colour at a third of
/// the pixel's weight.
pub fn run(
    p: &PassParams,
    coords: &[[i32; 2]],
    jac: &[[i32; 4]],
    colors: &[[u8; 4]],
) -> (Vec<[i32; 2]>, Vec<[u8; 4]>) {
    let mut out = super::gather::gather_window(p, coords, |c| color_at(p, colors, c));
    if p.seam_blend == 0 {
        return out;
    }
    let base = p.coord_base as usize;
    super::gather::blend_seams(
        p,
        &mut out,
        |c| color_at(p, colors, c),
        |q, d, c| {
            let j = jac[base + region_index(q, p)];
            let s = coords[base + region_index([q[0] + d[0], q[1] + d[1]], p)];
            let o = scaled_jd(p.spacing, j, d);
            let pred = [s[0] - o[0], s[1] - o[1]];
            (!same_patch(pred, c, p)).then_some(pred)
        },
    );
    out
}
