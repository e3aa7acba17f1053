//! Mirror of `shaders/distortion.wgsl`: flags the advected pixels whose coordinates no
//! longer follow the desired Jacobian and renews them (upsampled again, or continued from
//! an anchor).

use super::common::{fit_coord, region_index, scaled_jd, PassParams};
use super::fill::in_chart;

/// Squared length of a coordinate difference, wrapped to the nearest representative for
/// tileable exemplars and clamped so its square cannot overflow.
fn step_err(p: &PassParams, d: [i32; 2]) -> u32 {
    let mut e = d;
    if p.tileable != 0 {
        for (ek, size) in e.iter_mut().zip(p.ex_size) {
            let n = size << p.coord_frac;
            if *ek > n / 2 {
                *ek -= n;
            }
            if *ek < -n / 2 {
                *ek += n;
            }
        }
    }
    let c = e.map(|v| v.clamp(-16384, 16384).unsigned_abs());
    c[0] * c[0] + c[1] * c[1]
}

/// Whether the distortion pass flags region pixel `(x, y)` for upsampling again, from
/// the advected coordinates in the scratch region (see `distortion.wgsl`).
pub fn flagged(
    p: &PassParams,
    coords: &[[i32; 2]],
    jac: &[[i32; 4]],
    surface: &[u32],
    x: i32,
    y: i32,
) -> bool {
    let t = (y * p.size[0] + x) as usize;
    if p.distortion_max == u32::MAX || !in_chart(p, surface, t as u32) {
        return false;
    }
    let scratch = p.flag_base as usize;
    let s = coords[scratch + t];
    let (j, h) = (jac[p.coord_base as usize + t], p.spacing);
    let at = |dx: i32, dy: i32| coords[scratch + region_index([x + dx, y + dy], p)];
    // None: a seam on both sides (a strip between two seams, see distortion.wgsl).
    let axis = |e: [i32; 2]| {
        let ex = scaled_jd(h, j, e);
        let f = at(e[0], e[1]);
        let b = at(-e[0], -e[1]);
        let fwd = [f[0] - s[0] - ex[0], f[1] - s[1] - ex[1]];
        let bwd = [s[0] - b[0] - ex[0], s[1] - b[1] - ex[1]];
        let err = step_err(p, fwd).min(step_err(p, bwd));
        (err <= seam_err(p.spacing)).then_some(err)
    };
    let (ex, ey) = (axis([1, 0]), axis([0, 1]));
    // A pixel between seams on both axes continues no neighbour: it is upsampled again
    // too (else such pixels spread and blur the texture, distortion.wgsl).
    let isolated = ex.is_none() && ey.is_none();
    let err = ex.unwrap_or(0) + ey.unwrap_or(0);
    isolated || err > p.distortion_max
}

/// Mirror of `distortion.wgsl`: writes the advected coordinates from the scratch region
/// back to the level, and in place of the [`flagged`] ones their upsampling from the
/// coarser level ([`super::upsample_aniso::upsample_pixel`]; it reads only that level) or
/// their anchored renewal (`renewal`).
pub fn distortion(p: &PassParams, coords: &mut [[i32; 2]], jac: &[[i32; 4]], surface: &[u32]) {
    let base = p.coord_base as usize;
    let scratch = p.flag_base as usize;
    let mut out = Vec::with_capacity((p.size[0] * p.size[1]) as usize);
    for y in 0..p.size[1] {
        for x in 0..p.size[0] {
            let t = (y * p.size[0] + x) as usize;
            out.push(if flagged(p, coords, jac, surface, x, y) {
                renewal(p, coords, jac, surface, [x, y])
            } else {
                coords[scratch + t]
            });
        }
    }
    coords[base..base + out.len()].copy_from_slice(&out);
}

/// The new coordinate of flagged region pixel `q` (see `renewal` in `distortion.wgsl`):
/// upsampled again from the coarser level, or with anchored renewals
/// ([`PassParams::anchor`]) mostly the continuation of the nearest-landing of the four
/// anchors around it.
fn renewal(
    p: &PassParams,
    coords: &[[i32; 2]],
    jac: &[[i32; 4]],
    surface: &[u32],
    q: [i32; 2],
) -> [i32; 2] {
    let upsample = || super::upsample_aniso::upsample_pixel(p, coords, jac, q);
    let b = (p.anchor & 255) as i32;
    if b == 0 {
        return upsample();
    }
    let scratch = p.flag_base as usize;
    let advected = |a: [i32; 2]| coords[scratch + region_index(a, p)];
    let last = [p.size[0] - 1, p.size[1] - 1];
    let own = [0, 1].map(|k| (q[k] / b * b + b / 2).min(last[k]));
    let key = advected(own).map(|v| (v >> 10) as u32);
    let roll =
        super::common::hash32(key[0].wrapping_mul(73_856_093) ^ key[1].wrapping_mul(19_349_663));
    if roll & 255 < p.anchor >> 8 {
        return upsample();
    }
    let t = (q[1] * p.size[0] + q[0]) as usize;
    let s = coords[scratch + t];
    let j = jac[p.coord_base as usize + t];
    let k0 = [0, 1].map(|k| (q[k] - b / 2).div_euclid(b));
    // The first nearest continuation, within a whole pixel step.
    let mut best = seam_err(p.spacing) + 1;
    let mut pick = None;
    for k in 0..4 {
        let a = [0, 1].map(|ax| (k0[ax] + (k >> ax & 1)) * b + b / 2);
        if (0..2).any(|ax| a[ax] < 0 || a[ax] > last[ax]) {
            continue;
        }
        let ta = (a[1] * p.size[0] + a[0]) as u32;
        if !in_chart(p, surface, ta) || jac[p.coord_base as usize + ta as usize] != j {
            continue;
        }
        let (aa, d) = (
            advected(a),
            scaled_jd(p.spacing, j, [q[0] - a[0], q[1] - a[1]]),
        );
        let c = fit_coord([aa[0] + d[0], aa[1] + d[1]], p);
        let e = step_err(p, [c[0] - s[0], c[1] - s[1]]);
        if e < best {
            best = e;
            pick = Some(c);
        }
    }
    pick.unwrap_or_else(upsample)
}

/// Squared step error of a whole pixel step at spacing `h`, `(h 256)^2`: beyond it an
/// axis is a seam on both sides and does not count as distortion.
pub fn seam_err(h: i32) -> u32 {
    // Capped (no overflow): step errors stay below 2^30 anyway.
    let h = h.min(128);
    ((h * h) as u32) << 16
}

/// `distortion_max` for threshold `c` (Jacobian units) at spacing `h`.
pub fn distortion_max(c: f32, h: i32) -> u32 {
    let v = (c as f64 * h as f64 * 256.0).powi(2);
    v.min(i32::MAX as f64) as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flags(coords: &mut Vec<[i32; 2]>, c: f32) -> Vec<i32> {
        let p = PassParams {
            ex_size: [4096, 4096],
            size: [8, 8],
            spacing: 1,
            flag_base: 64,
            distortion_max: distortion_max(c, 1),
            ..Default::default()
        };
        let jac = vec![[1024, 0, 0, 1024]; 64];
        // The advected coordinates in the scratch region, as the advect pass leaves them.
        coords.resize(128, [0, 0]);
        coords.copy_within(0..64, 64);
        let f: Vec<i32> = (0..64)
            .map(|t| flagged(&p, coords, &jac, &[], t % 8, t / 8) as i32)
            .collect();
        distortion(&p, coords, &jac, &[]);
        for t in 0..64 {
            if f[t] == 0 {
                assert_eq!(
                    coords[t],
                    coords[64 + t],
                    "unflagged pixels are copied back"
                );
            }
        }
        f
    }

    #[test]
    fn anchored_renewals_keep_the_content_and_follow_j() {
        // A 16x16 level at spacing 2 whose advected coordinates turned by 0.1 radian
        // about its centre: every pixel is flagged at threshold 0.05.
        let (n, h) = (16, 2);
        let p = PassParams {
            ex_size: [4096, 4096],
            size: [n, n],
            spacing: h,
            coord_frac: 8,
            flag_base: (n * n) as u32,
            distortion_max: distortion_max(0.05, h),
            ..Default::default()
        };
        let jac = vec![[1024, 0, 0, 1024]; (n * n) as usize];
        let (c, sn) = (0.1f64.cos(), 0.1f64.sin());
        let mut advected: Vec<[i32; 2]> = (0..n * n)
            .map(|t| {
                let (x, y) = ((t % n) as f64 - 7.5, (t / n) as f64 - 7.5);
                let u = (h * 256) as f64;
                [
                    (2000.0 * 256.0 + u * (c * x - sn * y)).round() as i32,
                    (2000.0 * 256.0 + u * (sn * x + c * y)).round() as i32,
                ]
            })
            .collect();
        // Pixel (9, 9) shows another patch: no anchor continues it.
        advected[9 * 16 + 9] = [3000 << 8, 900 << 8];
        let run_along = |anchor: u32, jac: &[[i32; 4]]| {
            let mut coords = advected.clone();
            coords.extend_from_slice(&advected);
            let p = PassParams { anchor, ..p };
            for t in 0..n * n {
                assert!(flagged(&p, &coords, jac, &[], t % n, t / n));
            }
            distortion(&p, &mut coords, jac, &[]);
            coords.truncate((n * n) as usize);
            coords
        };
        let run = |anchor: u32| run_along(anchor, &jac);
        // Upsampled (no coarser level here: the exemplar's corner, fit_coord(0)).
        let corner = fit_coord([0, 0], &p);
        assert!(run(0).iter().all(|&c| c == corner));
        assert!(run(4 | (256 << 8)).iter().all(|&c| c == corner));
        let anchored = run(4);
        let step = h * 256;
        let mut straight = 0;
        for y in 0..n {
            for x in 0..n {
                let t = (y * n + x) as usize;
                let (a, s) = (anchored[t], advected[t]);
                if (x, y) == (9, 9) {
                    assert_eq!(a, corner, "a pixel no anchor continues is upsampled");
                    continue;
                }
                // Nearly what it showed: within the turn times the distance to its anchor
                // (at most 2 sqrt 2 pixels, 0.1 x 2.83 x 512 = 145 units, against 512
                // for one pixel).
                let d = ((a[0] - s[0]) as f64).hypot((a[1] - s[1]) as f64);
                assert!(d <= 150.0, "({x}, {y}) moved by {d}");
                if x + 1 < n && anchored[t + 1] == [a[0] + step, a[1]] {
                    straight += 1;
                }
            }
        }
        // The turned field follows J again within each anchor's pixels (a pixel takes
        // the anchor nearest to it, so about half of the steps are inside one); none of
        // its steps did before.
        assert!(straight >= 120, "{straight} straight steps of 240");
        assert!(!advected
            .windows(2)
            .any(|w| w[1] == [w[0][0] + step, w[0][1]]));
        // Along a varying field (J differs by a unit from pixel to pixel) only an anchor
        // continues an anchor (itself: it keeps its coordinate); the rest are upsampled.
        let varying: Vec<[i32; 4]> = (0..n * n).map(|t| [1024 + t, 0, 0, 1024]).collect();
        for (t, c) in run_along(4, &varying).into_iter().enumerate() {
            let anchor = t as i32 % n % 4 == 2 && t as i32 / n % 4 == 2;
            assert_eq!(c, if anchor { advected[t] } else { corner }, "pixel {t}");
        }
        // Half upsampled: decided per anchor block, so a block is either.
        let half = run(4 | (128 << 8));
        let up = half.iter().filter(|&&c| c == corner).count();
        assert!((40..=216).contains(&up), "{up} of 256 upsampled");
        for (t, &c) in half.iter().enumerate() {
            assert!(c == corner || c == anchored[t], "pixel {t}");
        }
    }

    #[test]
    fn a_strip_between_two_seams_is_not_distortion() {
        // Identity coordinates, but column 4 comes from elsewhere in the exemplar: both
        // of its x steps are seams.
        let mut coords: Vec<[i32; 2]> = (0..64)
            .map(|i| {
                let (x, y) = (i % 8, i / 8);
                let jump = if x == 4 { 40 } else { 0 };
                [(x + jump) << 8, y << 8]
            })
            .collect();
        assert!(flags(&mut coords, 0.5).iter().all(|&f| f == 0));
    }

    #[test]
    fn a_pixel_between_seams_on_both_axes_is_flagged() {
        // Identity coordinates, but pixel (3, 4) comes from elsewhere in the exemplar:
        // it continues no neighbour, whatever the threshold; its neighbours, each with a
        // seam on one side only, are left alone.
        let coords: Vec<[i32; 2]> = (0..64)
            .map(|i| {
                let (x, y) = (i % 8, i / 8);
                let jump = if (x, y) == (3, 4) { 40 } else { 0 };
                [(x + jump) << 8, (y + jump) << 8]
            })
            .collect();
        for c in [0.5, 100.0] {
            let f = flags(&mut coords.clone(), c);
            assert_eq!(f.iter().sum::<i32>(), 1, "threshold {c}");
            assert_eq!(f[4 * 8 + 3], 1);
        }
        // Level 0 flags nothing (it has no coarser level to upsample from).
        let p = PassParams {
            ex_size: [4096, 4096],
            size: [8, 8],
            spacing: 1,
            flag_base: 64,
            distortion_max: u32::MAX,
            ..Default::default()
        };
        let mut c = coords.clone();
        c.extend_from_within(0..64);
        distortion(&p, &mut c, &vec![[1024, 0, 0, 1024]; 64], &[]);
        assert_eq!(&c[..64], &coords[..]);
    }

    #[test]
    fn stretched_coordinates_are_flagged() {
        // 1.6 exemplar pixels per output pixel along x against J = I: 0.6 > c = 0.5.
        let mut coords: Vec<[i32; 2]> = (0..64).map(|i| [(i % 8) * 410, (i / 8) << 8]).collect();
        assert!(flags(&mut coords.clone(), 0.5).iter().all(|&f| f == 1));
        // Below the threshold (0.6 < 0.7): nothing.
        assert!(flags(&mut coords, 0.7).iter().all(|&f| f == 0));
    }
}
