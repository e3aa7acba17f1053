//! Mirror of `shaders/gather_map.wgsl`: material sets. An extra exemplar-aligned map
//! (normal, height, roughness...) is read at the finest level's coordinates exactly like
//! the colours; tangent-space normal maps have their x, y rotated with the texture when
//! a field rotates it (by the rotation part of `J^-1`, integer arithmetic).

use super::common::{bilinear_rgba, PassParams};

fn isqrt(x: i32) -> i32 {
    let mut r = (x as f64).sqrt() as i32;
    while r * r > x {
        r -= 1;
    }
    while (r + 1) * (r + 1) <= x {
        r += 1;
    }
    r
}

/// Rotates an RGBA8 tangent-space normal by the rotation part of `J^-1`. `J` acts on
/// image axes (y down); a map whose green is y up (OpenGL, glTF: `green_up`) has y
/// flipped before and after.
pub fn rotate_normal(v: [i32; 4], j: [i32; 4], green_up: bool) -> [i32; 4] {
    let flip = if green_up { -1 } else { 1 };
    let n = [2 * v[0] - 255, (2 * v[1] - 255) * flip];
    let r = if j[0] * j[3] - j[1] * j[2] >= 0 {
        let (a, b) = (j[0] + j[3], j[2] - j[1]);
        let l = isqrt(a * a + b * b).max(1);
        [(a * n[0] + b * n[1]) / l, (a * n[1] - b * n[0]) / l]
    } else {
        let (a, b) = (j[0] - j[3], j[2] + j[1]);
        let l = isqrt(a * a + b * b).max(1);
        [(a * n[0] + b * n[1]) / l, (b * n[0] - a * n[1]) / l]
    };
    [
        ((r[0] + 256) >> 1).clamp(0, 255),
        ((r[1] * flip + 256) >> 1).clamp(0, 255),
        v[2],
        v[3],
    ]
}

/// The map's RGBA8 values over the output window, row-major.
pub fn run(p: &PassParams, coords: &[[i32; 2]], jac: &[[i32; 4]], map: &[[u8; 4]]) -> Vec<[u8; 4]> {
    let mut out = Vec::with_capacity((p.window_size[0] * p.window_size[1]) as usize);
    let at = |c: [i32; 2]| map[(c[1] * p.ex_size[0] + c[0]) as usize].map(|v| v as i32);
    for y in 0..p.window_size[1] {
        for x in 0..p.window_size[0] {
            let q = [x + p.window_offset[0], y + p.window_offset[1]];
            let idx = p.coord_base as usize + (q[1] * p.size[0] + q[0]) as usize;
            let c = coords[idx];
            let v = if p.coord_frac == 0 {
                at(c)
            } else {
                let v = bilinear_rgba(map, p.ex_size, p.tileable != 0, c);
                if p.map_kind != 0 {
                    rotate_normal(v, jac[idx], p.map_kind == 2)
                } else {
                    v
                }
            };
            out.push(v.map(|c| c as u8));
        }
    }
    out
}
