//! Mirror of `shaders/jitter.wgsl`:
//! `S[p] += floor(h_l * r_l * H(p, l, seed) + 0.5)`, in fixed point. `H` takes 12 bits
//! of each hash as a value in [-1, 1); the amplitude `h_l r_l` comes in 1/16 pixel,
//! so the offset is `(amp * s + 2^14) >> 15`, exactly the same on every device. The
//! result is mirrored back into the level's valid range ([`fit_jittered`]).

use super::common::{fit_coord, hash_pixel, PassParams};

/// The jitter of absolute pixel `abs` at `level` (amplitude `amp` in 1/16 pixel): the
/// hashed offset, rounded.
#[inline]
pub fn jitter_offset(abs: [i32; 2], level: u32, seed: u32, amp: i32) -> [i32; 2] {
    let h = hash_pixel(abs, level, seed);
    let s = [(h[0] & 0xfff) as i32 - 2048, (h[1] & 0xfff) as i32 - 2048];
    [
        (amp * s[0] + (1 << 14)) >> 15,
        (amp * s[1] + (1 << 14)) >> 15,
    ]
}

/// Jitters the level's coordinates (`jitter.wgsl`); nothing when the amplitude is 0.
pub fn run(p: &PassParams, coords: &mut [[i32; 2]]) {
    if p.jitter_amp == 0 {
        return;
    }
    for y in 0..p.size[1] {
        for x in 0..p.size[0] {
            let i = p.coord_base as usize + (y * p.size[0] + x) as usize;
            let o = jitter_offset(
                [p.origin[0] + x, p.origin[1] + y],
                p.level,
                p.seed,
                p.jitter_amp,
            );
            let f = p.coord_frac;
            coords[i] = fit_jittered([coords[i][0] + (o[0] << f), coords[i][1] + (o[1] << f)], p);
        }
    }
}

/// `t` mirrored into `[0, n]` (period `2n`); 0 where `n <= 0`.
fn mirror(t: i32, n: i32) -> i32 {
    if n <= 0 {
        return 0;
    }
    let m = t.rem_euclid(2 * n);
    if m > n {
        2 * n - m
    } else {
        m
    }
}

/// A jittered coordinate back into the exemplar: wrapped (tileable), else mirrored at
/// the edges of the valid range (clamping piled the coarse levels' jitter onto them).
pub fn fit_jittered(c: [i32; 2], p: &PassParams) -> [i32; 2] {
    if p.tileable != 0 {
        return fit_coord(c, p);
    }
    let f = p.coord_frac;
    let lo = [p.margin << f, p.margin << f];
    let hi = [
        (p.ex_size[0] - 1 - p.margin) << f,
        (p.ex_size[1] - 1 - p.margin) << f,
    ];
    [
        lo[0] + mirror(c[0] - lo[0], hi[0] - lo[0]),
        lo[1] + mirror(c[1] - lo[1], hi[1] - lo[1]),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mirror_folds_into_the_range() {
        // Period 2n: 0..=n rising, then falling back.
        let n = 5;
        let got: Vec<i32> = (-7..=13).map(|t| mirror(t, n)).collect();
        assert_eq!(
            got,
            [3, 4, 5, 4, 3, 2, 1, 0, 1, 2, 3, 4, 5, 4, 3, 2, 1, 0, 1, 2, 3]
        );
        assert_eq!(mirror(7, 0), 0);
    }

    #[test]
    fn jittered_coordinates_are_mirrored_not_piled_on_the_edges() {
        let p = PassParams {
            ex_size: [128, 96],
            margin: 32,
            ..Default::default()
        };
        // Valid range: x in 32..=95, y in 32..=63.
        assert_eq!(fit_jittered([40, 40], &p), [40, 40]);
        assert_eq!(fit_jittered([30, 70], &p), [34, 56]);
        assert_eq!(fit_jittered([100, 20], &p), [90, 44]);
        // A jitter wider than the range folds more than once and stays inside.
        for c in -300..300 {
            let [x, y] = fit_jittered([c, c], &p);
            assert!(
                (32..=95).contains(&x) && (32..=63).contains(&y),
                "{c}: {x}, {y}"
            );
        }
        // Continuous (anisometric) coordinates: the same in 1/256 pixel.
        let q = PassParams { coord_frac: 8, ..p };
        assert_eq!(fit_jittered([30 << 8, 70 << 8], &q), [34 << 8, 56 << 8]);
        // Tileable exemplars wrap as before.
        let t = PassParams { tileable: 1, ..p };
        assert_eq!(fit_jittered([-3, 100], &t), [125, 4]);
    }
}
