//! Mirror of `shaders/upsample_aniso.wgsl`: Jacobian-aware upsampling,
//! `S_l[p] = S_{l-1}[floor(p/2)] + h_l J(p) (p mod 2)` in fixed point (1/256 exemplar
//! pixel), absolute positions `p`. With `J = I` it is `upsample` times 256.

use super::common::{fit_coord, scaled_jd, PassParams};

pub fn upsample_pixel(
    p: &PassParams,
    coords: &[[i32; 2]],
    jac: &[[i32; 4]],
    q: [i32; 2],
) -> [i32; 2] {
    if p.parent_size[0] == 0 {
        return fit_coord([0, 0], p);
    }
    let abs = [p.origin[0] + q[0], p.origin[1] + q[1]];
    let px = ((abs[0] >> 1) - p.parent_origin[0]).clamp(0, p.parent_size[0] - 1);
    let py = ((abs[1] >> 1) - p.parent_origin[1]).clamp(0, p.parent_size[1] - 1);
    let parent = coords[p.parent_coord_base as usize + (py * p.parent_size[0] + px) as usize];
    let j = jac[p.coord_base as usize + (q[1] * p.size[0] + q[0]) as usize];
    let o = scaled_jd(p.spacing, j, [abs[0] & 1, abs[1] & 1]);
    fit_coord([parent[0] + o[0], parent[1] + o[1]], p)
}

pub fn run(p: &PassParams, coords: &mut [[i32; 2]], jac: &[[i32; 4]]) {
    for y in 0..p.size[1] {
        for x in 0..p.size[0] {
            // Advection: only the pixels the distortion pass flagged.
            if p.flag_base != 0
                && coords[(p.flag_base + (y * p.size[0] + x) as u32) as usize][0] == 0
            {
                continue;
            }
            let c = upsample_pixel(p, coords, jac, [x, y]);
            coords[p.coord_base as usize + (y * p.size[0] + x) as usize] = c;
        }
    }
}
