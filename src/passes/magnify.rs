//! Mirror of `shaders/magnify.wgsl`: magnification (Lefebvre & Hoppe 2006 §5-6). The window is
//! rendered at `F` times its synthesized resolution from a higher-resolution exemplar
//! `E_H` (`F` times the analysed one): output pixel `o` sits at `x = (o + 1/2)/F - 1/2`
//! in synthesized pixels and blends, with bilinear weights, the predictions
//! `E_H[F (S[q] + J(q) (x - q))]` of the four nearest synthesized pixels `q`. Integer
//! arithmetic throughout (`2F (x - q)` is an integer; positions in 1/256 texel). Normal
//! maps (`map_kind` 1 or 2) have each prediction rotated by its own `J` (material sets).

use super::common::{bilinear_rgba, region_index, PassParams, COORD_FRAC};

fn hi_bilinear(p: &PassParams, hi: &[[u8; 4]], u: [i32; 2]) -> [i32; 4] {
    bilinear_rgba(hi, p.hi_size, p.tileable != 0, u)
}

/// The magnified window (`F * window_size`), RGBA8 row-major. `coords`/`jac` as in
/// [`super::run_cpu`]; `p` is the gather dispatch's parameters with `hi_size` and
/// `magnify` set.
pub fn run(p: &PassParams, coords: &[[i32; 2]], jac: &[[i32; 4]], hi: &[[u8; 4]]) -> Vec<[u8; 4]> {
    let big = p.magnify as i32;
    let (w, h) = (p.window_size[0] * big, p.window_size[1] * big);
    let den = 2 * big;
    let mut out = Vec::with_capacity((w * h) as usize);
    for oy in 0..h {
        for ox in 0..w {
            let num = [2 * ox + 1 - big, 2 * oy + 1 - big];
            let q0 = [(num[0] + den) / den - 1, (num[1] + den) / den - 1];
            let r = [num[0] - den * q0[0], num[1] - den * q0[1]];
            let mut acc = [0i32; 4];
            for dy in 0..=1 {
                for dx in 0..=1 {
                    let q = [
                        q0[0] + dx + p.window_offset[0],
                        q0[1] + dy + p.window_offset[1],
                    ];
                    let idx = p.coord_base as usize + region_index(q, p);
                    let sh = COORD_FRAC - p.coord_frac;
                    let s = [coords[idx][0] << sh, coords[idx][1] << sh];
                    let v = [r[0] - den * dx, r[1] - den * dy];
                    let off = if p.coord_frac != 0 {
                        let j = jac[idx];
                        [
                            (j[0] * v[0] + j[1] * v[1] + 4) >> 3,
                            (j[2] * v[0] + j[3] * v[1] + 4) >> 3,
                        ]
                    } else {
                        [128 * v[0], 128 * v[1]]
                    };
                    let wx = if dx == 1 { r[0] } else { den - r[0] };
                    let wy = if dy == 1 { r[1] } else { den - r[1] };
                    let mut c = hi_bilinear(p, hi, [big * s[0] + off[0], big * s[1] + off[1]]);
                    if p.coord_frac != 0 && p.map_kind != 0 {
                        c = super::gather_map::rotate_normal(c, jac[idx], p.map_kind == 2);
                    }
                    for ch in 0..4 {
                        acc[ch] += wx * wy * c[ch];
                    }
                }
            }
            let total = den * den;
            out.push(acc.map(|v| ((v + total / 2) / total) as u8));
        }
    }
    out
}
