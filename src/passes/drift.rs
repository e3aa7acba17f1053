//! Mirror of `shaders/drift.wgsl`: the advection frames' drift, the velocity at the
//! output window's centre summed in whole finest pixels.

use super::common::PassParams;
use super::velocity::VELOCITY_FRAC;

/// The velocity at the output window's centre (1/1024 px per frame).
pub(crate) fn centre_velocity(p: &PassParams, velocity: &[[i32; 2]]) -> [i32; 2] {
    let ws = p.window_size;
    velocity[((ws[1] / 2) * ws[0] + ws[0] / 2) as usize]
}

/// Mirror of `drift.wgsl`: adds the centre velocity, rounded to whole finest pixels, to
/// the frames' drift (`p.drift`: the entry before this frame, then the one after).
pub fn drift(p: &PassParams, coords: &mut [[i32; 2]], velocity: &[[i32; 2]]) {
    let i = p.drift as usize;
    let vc = centre_velocity(p, velocity);
    let k = vc.map(|c| (c + (1 << (VELOCITY_FRAC - 1))) >> VELOCITY_FRAC);
    let a = coords[i + 1];
    coords[i] = a;
    coords[i + 1] = [a[0] + k[0], a[1] + k[1]];
}
