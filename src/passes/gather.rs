//! Mirror of `shaders/gather.wgsl`: the output colour is the exemplar at the
//! synthesized coordinate of the finest level, for the pixels of the output window.
//!
//! Seam blending (`PassParams::seam_blend`): each 4-neighbour `n` whose coordinate does
//! not continue the pixel's (`S[n] - (n - p) != S[p]`, a patch seam) adds the colour it
//! predicts there, `E[S[n] - (n - p)]`, at a third of the weight of the pixel's own
//! colour. Coherent pixels are exact copies; a seam becomes a short blend between the
//! two patches instead of a hard step, which lowers the texture energy without visible
//! blur. A third rather than half the weight: the uncorrected finest level's seams cross
//! more colour edges, and half weight mixed new colours in.

use super::common::{read_coord, region_index, PassParams};

/// Returns the window's coordinates and RGBA8 colours, row-major.
pub fn run(
    p: &PassParams,
    coords: &[[i32; 2]],
    colors: &[[u8; 4]],
) -> (Vec<[i32; 2]>, Vec<[u8; 4]>) {
    let at = |c: [i32; 2]| colors[(c[1] * p.ex_size[0] + c[0]) as usize];
    if p.seam_blend == 0 {
        return gather_window(p, coords, at);
    }
    let mut out = gather_window(p, coords, at);
    blend_seams(p, &mut out, at, |q, d, c| {
        let s = coords[p.coord_base as usize + region_index([q[0] + d[0], q[1] + d[1]], p)];
        let pred = read_coord([s[0] - d[0], s[1] - d[1]], p);
        (pred != c).then_some(pred)
    });
    out
}

/// Seam blending over a gathered window (`gather_window`'s output), shared by the
/// isometric and anisometric gathers: each pixel's colour counts three times, and each of its
/// 4 neighbours `d` whose prediction `predict(q, d, c)` (q: the pixel's region position,
/// c: its coordinate) does not continue it adds the colour predicted there once.
pub(crate) fn blend_seams(
    p: &PassParams,
    out: &mut (Vec<[i32; 2]>, Vec<[u8; 4]>),
    color: impl Fn([i32; 2]) -> [u8; 4],
    predict: impl Fn([i32; 2], [i32; 2], [i32; 2]) -> Option<[i32; 2]>,
) {
    let mut i = 0;
    for y in 0..p.window_size[1] {
        for x in 0..p.window_size[0] {
            let q = [x + p.window_offset[0], y + p.window_offset[1]];
            let c = out.0[i];
            let mut sum = color(c).map(|v| 3 * v as u32);
            let mut weight = 3u32;
            for d in [[1, 0], [-1, 0], [0, 1], [0, -1]] {
                if let Some(pred) = predict(q, d, c) {
                    let v = color(pred);
                    for k in 0..4 {
                        sum[k] += v[k] as u32;
                    }
                    weight += 1;
                }
            }
            out.1[i] = sum.map(|v| ((v + weight / 2) / weight) as u8);
            i += 1;
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seams_blend_the_neighbours_predictions_and_coherent_pixels_copy() {
        // An 8x1 exemplar, texel x of grey 3 x^2; a 6x1 region whose coordinates run
        // 1, 2, 3 | 5, 6, 7 (a seam between pixels 2 and 3); the window is pixels 1-4.
        let colors: Vec<[u8; 4]> = (0..8).map(|x| [3 * x * x, 0, 0, 255]).collect();
        let coords: Vec<[i32; 2]> = [1, 2, 3, 5, 6, 7].iter().map(|&x| [x, 0]).collect();
        let p = PassParams {
            ex_size: [8, 1],
            size: [6, 1],
            window_offset: [1, 0],
            window_size: [4, 1],
            seam_blend: 1,
            ..Default::default()
        };
        let (c, out) = run(&p, &coords, &colors);
        assert_eq!(c, coords[1..5]);
        // Pixel 2 (texel 3, grey 27): its right neighbour predicts texel 4 (grey 48):
        // (3 * 27 + 48 + 2) / 4 = 32. Pixel 3 (texel 5, grey 75): its left neighbour
        // predicts texel 4: (3 * 75 + 48 + 2) / 4 = 68. The others continue both
        // neighbours (vertical neighbours are the pixel itself) and copy.
        let red: Vec<u8> = out.iter().map(|v| v[0]).collect();
        assert_eq!(red, [12, 32, 68, 108]);
        let (_, plain) = run(&PassParams { seam_blend: 0, ..p }, &coords, &colors);
        let red: Vec<u8> = plain.iter().map(|v| v[0]).collect();
        assert_eq!(red, [12, 27, 75, 108]);
    }
}
