//! Mirror of `shaders/upsample.wgsl`: `S_l[p] = S_{l-1}[floor(p/2)] + h_l * (p mod 2)`
//! with absolute positions `p`; level 0 (no parent) starts from `(0, 0)`.

use super::common::{fit_coord, PassParams};

/// The coordinate a pixel at absolute position `abs` gets from its parent.
#[inline]
pub fn upsample_pixel(p: &PassParams, coords: &[[i32; 2]], abs: [i32; 2]) -> [i32; 2] {
    if p.parent_size[0] == 0 {
        return fit_coord([0, 0], p);
    }
    let px = ((abs[0] >> 1) - p.parent_origin[0]).clamp(0, p.parent_size[0] - 1);
    let py = ((abs[1] >> 1) - p.parent_origin[1]).clamp(0, p.parent_size[1] - 1);
    let parent = coords[p.parent_coord_base as usize + (py * p.parent_size[0] + px) as usize];
    fit_coord(
        [
            parent[0] + p.spacing * (abs[0] & 1),
            parent[1] + p.spacing * (abs[1] & 1),
        ],
        p,
    )
}

/// Upsamples the coarser level's coordinates into this level's region (`upsample.wgsl`).
pub fn run(p: &PassParams, coords: &mut [[i32; 2]]) {
    for y in 0..p.size[1] {
        for x in 0..p.size[0] {
            let c = upsample_pixel(p, coords, [p.origin[0] + x, p.origin[1] + y]);
            coords[p.coord_base as usize + (y * p.size[0] + x) as usize] = c;
        }
    }
}
