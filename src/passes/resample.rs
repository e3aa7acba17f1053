//! Mirror of `shaders/resample.wgsl`: a tileable output made on a torus
//! ([`super::plan::Torus`]) takes its coordinates from the torus's finest level. Per
//! axis, output pixel `x` of `n` stands for torus position `u = (x + 0.5) m / n - 0.5`
//! (`m` the torus period), whose nearest torus pixel is `q = floor((2x + 1) m / 2n)`;
//! the coordinate is `S[q] + J'(q) (u - q)`, with `u - q` rounded to 1/256 pixel, so the
//! texture advances across the output as the field asks, with the output's period; along
//! no field (`nearest`) rounded to whole texels. Integer arithmetic only (the same bytes
//! on every device).

use super::common::{fit_coord, PassParams};

/// Torus pixel `q` and `u - q` in 1/256 pixel (`-128..=128`) for output pixel `x` of `n`
/// on a torus of period `m` (`n`, `m` up to 2^15).
#[inline]
pub fn source(x: i32, n: i32, m: i32) -> (i32, i32) {
    let t = (2 * x + 1) * m;
    let q = t / (2 * n);
    // u - q = (t - n - 2 n q) / 2n, shifted by n to stay non-negative: r in [0, 2n).
    let r = t - 2 * n * q;
    let f = (256 * r + n) / (2 * n) - 128;
    (q, f)
}

/// Writes the output's coordinates (`p.size`, at `p.coord_base`) from the torus's
/// finest level (`p.parent_size`, at `p.parent_coord_base`) and its Jacobians.
pub fn run(p: &PassParams, coords: &mut [[i32; 2]], jac: &[[i32; 4]]) {
    for y in 0..p.size[1] {
        let (qy, fy) = source(y, p.size[1], p.parent_size[1]);
        for x in 0..p.size[0] {
            let (qx, fx) = source(x, p.size[0], p.parent_size[0]);
            let src = p.parent_coord_base as usize + (qy * p.parent_size[0] + qx) as usize;
            let (s, j) = (coords[src], jac[src]);
            // J' (in 1/1024) times the offset (1/256 pixel): 1/256 exemplar pixel.
            let o = [
                (j[0] * fx + j[1] * fy + 512) >> 10,
                (j[2] * fx + j[3] * fy + 512) >> 10,
            ];
            let mut c = [s[0] + o[0], s[1] + o[1]];
            if p.nearest != 0 {
                // Along no field: whole texels, as isometric synthesis has (the gather
                // reads the nearest one anyway).
                c = c.map(|v| ((v + 128) >> 8) << 8);
            }
            let i = p.coord_base as usize + (y * p.size[0] + x) as usize;
            coords[i] = fit_coord(c, p);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::source;

    #[test]
    fn output_pixels_map_to_the_nearest_torus_pixel() {
        for (n, m) in [(65, 64), (66, 68), (129, 128), (131, 132), (9, 8), (10, 12)] {
            for x in 0..n {
                let (q, f) = source(x, n, m);
                let u = (x as f64 + 0.5) * m as f64 / n as f64 - 0.5;
                assert!((0..m).contains(&q), "{n}->{m}: pixel {x} -> {q}");
                assert!((u - q as f64).abs() <= 0.5 + 1e-9, "{n}->{m}: {x}");
                assert!(((u - q as f64) * 256.0 - f as f64).abs() <= 0.5 + 1e-9);
            }
        }
        // Where the sizes agree, every pixel is its own source.
        assert!((0..64).all(|x| source(x, 64, 64) == (x, 0)));
    }
}
