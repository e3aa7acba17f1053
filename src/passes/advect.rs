//! Mirror of `shaders/advect.wgsl` (and `shared/advect.wgsl`): texture advection
//! (Lefebvre & Hoppe 2006 §7). Per frame, the finest levels' continuous coordinates are
//! advected without resampling, `S[p] = S'[p - k] - J(p) (V(p) - k)`, with `k` one whole
//! shift of the level for all pixels so that neighbours stay coherent: the change of the
//! drift's whole level pixels ([`whole_shift`]), so a uniform flow of whole pixels
//! translates the texture exactly, seams included. The distortion pass
//! ([`crate::passes::distortion`]) then renews the pixels the flow distorted, and the
//! usual correction passes run. The frames' options are [`AdvectOptions`].

use super::common::{fit_coord, wrap, PassParams};
pub use super::distortion::{distortion, distortion_max, flagged, seam_err};
use super::drift::centre_velocity;
pub use super::drift::drift;
pub use super::velocity::{MAX_SPEED, VELOCITY_FRAC};
pub use crate::options::{
    AdvectOptions, KEEP_LOOK_FADE, KEEP_LOOK_REMAKE_THRESHOLD, MAX_ANCHOR_SPACING, MAX_FADE_FRAMES,
};

/// Bits dropped from `J V` (1/2^(JAC_FRAC + VELOCITY_FRAC)) to reach coordinates
/// (1/2^COORD_FRAC).
const JV_SHIFT: u32 = 10 + VELOCITY_FRAC - super::common::COORD_FRAC;

/// The rounding offset of `J V` at `frame` (0 .. 2^JV_SHIFT): the frame index with its
/// bits reversed, a low-discrepancy sequence. Rounding the same fraction down and up in
/// this proportion makes the error of a pixel's displacement stay within a few 1/256
/// exemplar pixels however many frames add up (rounding to nearest repeats the same
/// error, up to half a 1/256 step, every frame, and differently for neighbours). The
/// same for every pixel, so uniform flows stay exactly coherent.
pub fn dither(frame: u64) -> u32 {
    (frame as u32).reverse_bits() >> (32 - JV_SHIFT)
}

/// Velocity (1/1024 px) at the finest pixel under level pixel `abs` (absolute).
pub fn velocity_at(p: &PassParams, velocity: &[[i32; 2]], abs: [i32; 2]) -> [i32; 2] {
    let half = (1i32 << p.steps) >> 1;
    let f = |a: i32, o: i32, n: i32| ((a << p.steps) + half - o).clamp(0, n - 1);
    let x = f(abs[0], p.window_origin[0], p.window_size[0]);
    let y = f(abs[1], p.window_origin[1], p.window_size[1]);
    velocity[(y * p.window_size[0] + x) as usize]
}

/// The whole pixels of a level (`2^steps` finest pixels each) by which a frame moves its
/// coordinates: with the drift, the change of the drift's whole level pixels (rounded
/// down), so that over the frames a level moves by its share of the drift and a uniform
/// flow of whole pixels moves the patch seams of every level with the texture; without
/// it (`p.drift` 0), the centre velocity rounded to whole level pixels.
pub fn whole_shift(p: &PassParams, coords: &[[i32; 2]], velocity: &[[i32; 2]]) -> [i32; 2] {
    if p.drift != 0 {
        let (a0, a1) = (coords[p.drift as usize], coords[p.drift as usize + 1]);
        return [0, 1].map(|c| (a1[c] >> p.steps) - (a0[c] >> p.steps));
    }
    let unit = 1i32 << (VELOCITY_FRAC + p.steps);
    centre_velocity(p, velocity).map(|c| (c + (unit >> 1)) >> (VELOCITY_FRAC + p.steps))
}

/// One component of `J (V - k 2^steps)` in coordinate units (1/2^COORD_FRAC exemplar
/// pixel), rounded down after adding this frame's offset `dither`: `jv` is the row of
/// `J V` (1/2^(10 + VELOCITY_FRAC)), `jk` the row of `J k` (1/1024, k in whole level
/// pixels). `J k 2^steps` is split into whole coordinate units and a remainder, so the
/// result is exact without forming `J (V - k 2^steps)`, which overflows i32 on coarse
/// levels (a level pixel 256 finest pixels wide is 2^18 velocity units, times `J` up to
/// 2^13): the frames' drift shifts such a level by a whole pixel on the frame its share
/// of the drift crosses one, however slow the flow.
pub fn displacement(jv: i32, jk: i32, steps: u32, dither: i32) -> i32 {
    // `J k 2^(steps + VELOCITY_FRAC)` = hi 2^JV_SHIFT + lo, 0 <= lo < 2^JV_SHIFT.
    let up = steps + VELOCITY_FRAC;
    let (hi, lo) = if up >= JV_SHIFT {
        (jk << (up - JV_SHIFT), 0)
    } else {
        let hi = jk >> (JV_SHIFT - up);
        (hi, (jk - (hi << (JV_SHIFT - up))) << up)
    };
    ((jv - lo + dither) >> JV_SHIFT) - hi
}

/// `J (V - k 2^steps)` in coordinate units, rounded with the frame's `dither`
/// ([`displacement`] per component): what a frame subtracts from the coordinate it
/// carries from `k` level pixels upstream (`shared/advect.wgsl`, `displacement`).
pub fn offset(p: &PassParams, j: [i32; 4], vq: [i32; 2], k: [i32; 2]) -> [i32; 2] {
    let d = p.dither as i32;
    [
        displacement(
            j[0] * vq[0] + j[1] * vq[1],
            j[0] * k[0] + j[1] * k[1],
            p.steps,
            d,
        ),
        displacement(
            j[2] * vq[0] + j[3] * vq[1],
            j[2] * k[0] + j[3] * k[1],
            p.steps,
            d,
        ),
    ]
}

/// Mirror of `advect.wgsl`: the level's advected coordinates, into the scratch region
/// (`flag_base`), from which [`distortion`] copies them back.
pub fn advect(p: &PassParams, coords: &mut [[i32; 2]], jac: &[[i32; 4]], velocity: &[[i32; 2]]) {
    let k = whole_shift(p, coords, velocity);
    for y in 0..p.size[1] {
        for x in 0..p.size[0] {
            let i = p.coord_base as usize + (y * p.size[0] + x) as usize;
            let vq = velocity_at(p, velocity, [p.origin[0] + x, p.origin[1] + y]);
            let (sx, sy) = if p.periodic != 0 {
                (wrap(x - k[0], p.size[0]), wrap(y - k[1], p.size[1]))
            } else {
                (
                    (x - k[0]).clamp(0, p.size[0] - 1),
                    (y - k[1]).clamp(0, p.size[1] - 1),
                )
            };
            let prev = coords[p.coord_base as usize + (sy * p.size[0] + sx) as usize];
            let o = offset(p, jac[i], vq, k);
            coords[p.flag_base as usize + (y * p.size[0] + x) as usize] =
                fit_coord([prev[0] - o[0], prev[1] - o[1]], p);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounding_errors_do_not_add_up_over_frames() {
        // A shear flow, v_y = 0.0123 x pixels per frame, for 300 frames along a row: each
        // pixel must move by the exact sum within a few 1/256, and neighbours stay
        // smooth (always rounding to nearest drifts by up to 300/512 pixel, in steps).
        let n = 64;
        let p = PassParams {
            ex_size: [4096, 4096],
            size: [n, 1],
            window_size: [n, 1],
            tileable: 1,
            coord_frac: 8,
            flag_base: n as u32,
            ..Default::default()
        };
        let jac = vec![[1024, 0, 0, 1024]; n as usize];
        let speed = |x: i32| 0.0123 * x as f64;
        let velocity: Vec<[i32; 2]> = (0..n)
            .map(|x| [0, (speed(x) * (1 << VELOCITY_FRAC) as f64).round() as i32])
            .collect();
        let start = |x: i32| [(1000 + x) << 8, 2000 << 8];
        let mut coords: Vec<[i32; 2]> = (0..2 * n).map(start).collect();
        let frames = 300;
        for frame in 0..frames {
            let p = PassParams {
                dither: dither(frame),
                ..p
            };
            advect(&p, &mut coords, &jac, &velocity);
            // Copied back from the scratch region, nothing flagged (as on the coarsest
            // advected level).
            let back = PassParams {
                distortion_max: u32::MAX,
                ..p
            };
            distortion(&back, &mut coords, &jac, &[]);
        }
        for x in 0..n {
            // Exact for the quantized velocity, in 1/256 exemplar pixel.
            let exact = velocity[x as usize][1] as f64 * frames as f64 / 4.0;
            let moved = (start(x)[1] - coords[x as usize][1]) as f64;
            assert!(
                (moved - exact).abs() <= 3.0,
                "x {x}: moved {moved}, exact {exact}"
            );
        }
    }

    #[test]
    fn largest_speeds_and_scales_do_not_overflow() {
        // A level 128 pixels coarser than the finest, the centre moving at +64 pixels
        // per frame and this pixel at -64 (residual -192) per component, J = 8 x a
        // 45-degree rotation: J V must not wrap around.
        let p = PassParams {
            ex_size: [1 << 14, 1 << 14],
            size: [1, 1],
            window_size: [3, 1],
            steps: 7,
            tileable: 1,
            coord_frac: 8,
            flag_base: 1,
            ..Default::default()
        };
        let c = 5793; // 8 cos 45 degrees, in 1/1024
        let jac = [[c, -c, c, c]];
        let fast = 64 << VELOCITY_FRAC;
        let velocity = [[-fast, -fast], [fast, fast], [-fast, -fast]];
        let start = [8000 << 8, 8000 << 8];
        let mut coords = vec![start, [0, 0]];
        advect(&p, &mut coords, &jac, &velocity);
        coords[0] = coords[1];
        // k = 1 level pixel = 128 pixels: S[p] = S'[p - k] - J (V - k), exactly.
        let v = -192.0 * 1024.0;
        let expected = [
            start[0] as f64 - 0.0,
            start[1] as f64 - 2.0 * c as f64 * v / 4096.0,
        ];
        let got = coords[0];
        assert!(
            (got[0] as f64 - expected[0]).abs() <= 1.0,
            "{got:?} vs {expected:?}"
        );
        assert!(
            (got[1] as f64 - expected[1]).abs() <= 1.0,
            "{got:?} vs {expected:?}"
        );
    }

    #[test]
    fn displacement_is_exact_at_every_level() {
        // J (V - k 2^steps) rounded down with the dither, against 64-bit arithmetic, for
        // every level a pyramid can have, the largest J and speeds, and k up to the
        // shifts the drift or the centre velocity give.
        let exact = |jv: i64, jk: i64, steps: u32, d: i64| {
            (jv - (jk << (steps + VELOCITY_FRAC)) + d).div_euclid(1 << JV_SHIFT)
        };
        let fast: i32 = 64 << VELOCITY_FRAC;
        let j: i32 = 8 << 10;
        for steps in 0..=15u32 {
            for jv in [
                -2 * j * fast,
                -j * 777 - 5,
                -1,
                0,
                3,
                4095,
                j * fast + 12345,
                2 * j * fast,
            ] {
                for jk in [
                    -2 * j * 65,
                    -j - 1,
                    -3,
                    -1,
                    0,
                    1,
                    2,
                    5,
                    j * 3 + 7,
                    2 * j * 65,
                ] {
                    if steps >= 6 && jk.abs() > 2 * j * 2 {
                        continue; // a coarse level moves at most a level pixel or two
                    }
                    for d in [0, 1, 2047, 4095] {
                        assert_eq!(
                            displacement(jv, jk, steps, d) as i64,
                            exact(jv as i64, jk as i64, steps, d as i64),
                            "jv {jv}, jk {jk}, steps {steps}, dither {d}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn coarse_levels_cross_a_drift_pixel_exactly() {
        // A level 2^steps finest pixels per pixel under a uniform flow of 8 pixels per
        // frame, on the frame where the drift's share of the level crosses a whole
        // pixel (k = 1 however slow the flow): a coherent patch moves by exactly 8 finest
        // pixels of exemplar. It came out 120 and 376 pixels off at steps 8 and 9 while
        // V - k was clamped to 128 pixels to keep J (V - k) within i32.
        for steps in [2u32, 6, 8, 9, 12] {
            let h = 1i32 << steps;
            let (n, drift, flag_base) = (16i32, 40u32, 20u32);
            let p = PassParams {
                ex_size: [1 << 17, 1 << 17],
                size: [n, 1],
                spacing: h,
                step: [h, h],
                tileable: 1,
                coord_frac: 8,
                steps,
                window_size: [64, 1],
                flag_base,
                drift,
                ..Default::default()
            };
            let mut coords = vec![[0i32; 2]; 64];
            for x in 0..n {
                coords[x as usize] = [(1000 + x * h) << 8, 5 << 8];
            }
            coords[drift as usize] = [h * 3 - 3, 0];
            coords[drift as usize + 1] = [h * 3 + 5, 0];
            let velocity = vec![[8 << VELOCITY_FRAC, 0]; 64];
            let jac = vec![[1024, 0, 0, 1024]; 64];
            let k = whole_shift(&p, &coords, &velocity);
            assert_eq!(k, [if steps >= 3 { 1 } else { 8 >> steps }, 0]);
            advect(&p, &mut coords, &jac, &velocity);
            for x in k[0]..n {
                // S[x] = S'[x - k] - (V - k h) = S'[x] - V.
                let want = [(1000 + x * h - 8) << 8, 5 << 8];
                assert_eq!(
                    coords[(flag_base as i32 + x) as usize],
                    want,
                    "steps {steps}, pixel {x}"
                );
            }
        }
    }
}
