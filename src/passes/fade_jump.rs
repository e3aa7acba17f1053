//! Mirror of `shaders/fade_jump.wgsl`: the first pass of an advection frame's fade.
//! Per pixel of the finest level's region, how much a jump of its coordinate changed its
//! grey level (-1 where it moved with the flow; [`super::fade`]), into the flag region
//! (`[change, 0]` at `flag_base` + the pixel's region index), which the frame no longer
//! needs; the fade pass sums it over each pixel's 3x3 neighbourhood.

use super::common::PassParams;
use super::fade::Frame;

pub fn run(
    p: &PassParams,
    coords: &mut [[i32; 2]],
    jac: &[[i32; 4]],
    velocity: &[[i32; 2]],
    colors: &[[u8; 4]],
) {
    let frame = Frame::new(p, coords, jac, velocity, colors);
    let mut changes = Vec::with_capacity((p.size[0] * p.size[1]) as usize);
    for y in 0..p.size[1] {
        for x in 0..p.size[0] {
            changes.push([frame.jump_change([x, y]), 0]);
        }
    }
    coords[p.flag_base as usize..][..changes.len()].copy_from_slice(&changes);
}
