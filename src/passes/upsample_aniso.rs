//! Mirror of `shaders/upsample_aniso.wgsl`: Jacobian-aware upsampling,
//! `S_l[p] = S_{l-1}[floor(p/2)] + h_l J(p) (p mod 2)` in fixed point (1/256 exemplar
//! pixel), absolute positions `p`. With `J = I` it is `upsample` times 256.

use super::common::{coord_delta, fit_coord, same_patch, scaled_jd, PassParams};

/// The anisometric upsampling of region pixel `q` from the coarser level
/// (`upsample_aniso.wgsl`); the distortion pass's renewals use it too.
pub fn upsample_pixel(
    p: &PassParams,
    coords: &[[i32; 2]],
    jac: &[[i32; 4]],
    q: [i32; 2],
) -> [i32; 2] {
    upsample_from(p, coords, jac, q, [p.origin[0] + q[0], p.origin[1] + q[1]])
}

/// The upsampling of region pixel `q` as if it stood at absolute position `abs`.
fn upsample_from(
    p: &PassParams,
    coords: &[[i32; 2]],
    jac: &[[i32; 4]],
    q: [i32; 2],
    abs: [i32; 2],
) -> [i32; 2] {
    if p.parent_size[0] == 0 {
        return fit_coord([0, 0], p);
    }
    let odd = [abs[0] & 1, abs[1] & 1];
    let j = jac[p.coord_base as usize + (q[1] * p.size[0] + q[0]) as usize];
    // Prediction from the parent at block offset d: its coordinate plus h J (p - 2 parent).
    let predict = |d: [i32; 2]| {
        let px = ((abs[0] >> 1) + d[0] - p.parent_origin[0]).clamp(0, p.parent_size[0] - 1);
        let py = ((abs[1] >> 1) + d[1] - p.parent_origin[1]).clamp(0, p.parent_size[1] - 1);
        let parent = coords[p.parent_coord_base as usize + (py * p.parent_size[0] + px) as usize];
        let o = scaled_jd(p.spacing, j, [odd[0] - 2 * d[0], odd[1] - 2 * d[1]]);
        fit_coord([parent[0] + o[0], parent[1] + o[1]], p)
    };
    let base = predict([0, 0]);
    if odd == [0, 0] {
        return base;
    }
    // An odd child lies between 2 (or 4) parents: average their predictions when they
    // agree within a pixel, so that a sub-pixel misfit between parents (a field J that
    // is not a gradient) is spread over the children instead of becoming a step.
    // Predictions a pixel or more apart (a patch seam; every disagreement when J = I)
    // keep the nearest parent's, so isometric results stay exact.
    let mut sum = [0i32; 2];
    for k in 1..4 {
        let d = [k & 1, k >> 1];
        if d[0] > odd[0] || d[1] > odd[1] {
            continue;
        }
        let pred = predict(d);
        if !same_patch(pred, base, p) {
            return base;
        }
        let e = coord_delta([pred[0] - base[0], pred[1] - base[1]], p);
        sum[0] += e[0];
        sum[1] += e[1];
    }
    let shift = (odd[0] + odd[1]) as u32;
    let round = (1 << shift) >> 1;
    fit_coord(
        [
            base[0] + ((sum[0] + round) >> shift),
            base[1] + ((sum[1] + round) >> shift),
        ],
        p,
    )
}

/// With `p.drift` (the levels an advection frame upsamples): the drift's phase, its whole
/// pixels of this level (`2^steps` finest pixels each) mod 2 per axis; else 0.
pub fn drift_phase(p: &PassParams, coords: &[[i32; 2]]) -> [i32; 2] {
    if p.drift == 0 {
        return [0, 0];
    }
    coords[p.drift as usize + 1].map(|a| (a >> p.steps) & 1)
}

/// The level's upsampling. With a drift phase `f` (advection frames, the levels they
/// upsample: the coarser level moves by whole pixels of its own, two of this level's, so
/// a uniform flow of an odd number of this level's pixels leaves it half a pixel behind,
/// in place), pixel `p` is
/// upsampled as the pixel at `p - f`, plus `h J f`: the blocks of 2x2 children, and so
/// the patch seams, move with the drift, and within a patch the result is the same.
pub fn run(p: &PassParams, coords: &mut [[i32; 2]], jac: &[[i32; 4]]) {
    let f = drift_phase(p, coords);
    for y in 0..p.size[1] {
        for x in 0..p.size[0] {
            let abs = [p.origin[0] + x - f[0], p.origin[1] + y - f[1]];
            let mut c = upsample_from(p, coords, jac, [x, y], abs);
            if f != [0, 0] {
                let j = jac[p.coord_base as usize + (y * p.size[0] + x) as usize];
                let o = scaled_jd(p.spacing, j, f);
                c = fit_coord([c[0] + o[0], c[1] + o[1]], p);
            }
            coords[p.coord_base as usize + (y * p.size[0] + x) as usize] = c;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::passes::common::COORD_FRAC;

    /// One row of 2 parents (spacing 2) upsampled to 4 children at spacing 1, J = I.
    fn row(parents: [[i32; 2]; 2], tileable: i32) -> Vec<[i32; 2]> {
        let p = PassParams {
            ex_size: [64, 64],
            size: [4, 1],
            parent_size: [2, 1],
            spacing: 1,
            tileable,
            coord_frac: COORD_FRAC,
            coord_base: 2,
            parent_coord_base: 0,
            ..Default::default()
        };
        let mut coords = vec![parents[0], parents[1], [0, 0], [0, 0], [0, 0], [0, 0]];
        let jac = vec![[1024, 0, 0, 1024]; 6];
        run(&p, &mut coords, &jac);
        coords[2..].to_vec()
    }

    #[test]
    fn sub_pixel_misfits_are_spread_and_seams_kept() {
        let c = |x: f64, y: f64| [(x * 256.0) as i32, (y * 256.0) as i32];
        // Coherent parents (2 exemplar pixels apart, one per child): exact.
        assert_eq!(
            row([c(10.0, 20.0), c(12.0, 20.0)], 1),
            [c(10.0, 20.0), c(11.0, 20.0), c(12.0, 20.0), c(13.0, 20.0)]
        );
        // Half a pixel of misfit: the odd child between them takes half of it, where
        // the nearest parent alone would make a half-pixel step.
        assert_eq!(row([c(10.0, 20.0), c(12.5, 20.25)], 1)[1], c(11.25, 20.125));
        // A pixel or more apart (a seam, and every isometric disagreement): unchanged.
        assert_eq!(row([c(10.0, 20.0), c(13.0, 20.0)], 1)[1], c(11.0, 20.0));
        assert_eq!(row([c(10.0, 20.0), c(12.0, 21.0)], 0)[1], c(11.0, 20.0));
        // Around a tileable exemplar's edge, the short way round.
        assert_eq!(row([c(63.0, 5.0), c(1.25, 5.0)], 1)[1], c(0.125, 5.0));
    }
}
