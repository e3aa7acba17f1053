//! Jacobian fidelity: whether an anisometric synthesis follows the Jacobian field it
//! was asked for.
//!
//! The finite-difference Jacobian of the synthesized coordinate map is compared with
//! the field, as a relative Frobenius error. Patch seams (jumps to another part of the
//! exemplar) are counted apart, since they are not distortions; the local Jacobian
//! measures each pixel within its own patch.

use super::common::{invalid, json_num};
use crate::error::Result;

/// How well a coordinate map follows a Jacobian field (see [`jacobian_fidelity`]).
#[derive(Clone, Debug, PartialEq)]
pub struct JacobianReport {
    /// Pixels with both forward neighbours inside the image.
    pub pixels: usize,
    /// Relative tolerance used for the `within_*` fractions.
    pub tolerance: f64,
    /// Fraction of all those pixels whose finite-difference Jacobian is within
    /// `tolerance` of the field (relative Frobenius error).
    pub within_all: f64,
    /// The same over pixels that are not on a patch seam.
    pub within_non_seam: f64,
    /// Fraction of pixels on a patch seam: a forward neighbour's coordinate differs
    /// from the field's prediction by more than one exemplar pixel (a jump to another
    /// part of the exemplar, not a distortion).
    pub seam_fraction: f64,
    /// Median relative Frobenius error over non-seam pixels.
    pub median_error_non_seam: f64,
    /// Fraction of all pixels (borders included) whose *local* Jacobian is within
    /// `tolerance`: per axis, the difference on the side(s) that stay in the pixel's
    /// own patch (central when both do, one-sided when one neighbour is across a seam).
    /// A pixel on a patch only one pixel wide along an axis (a seam on both sides) has
    /// no local Jacobian there and counts as outside the tolerance.
    pub within_local: f64,
    /// Fraction of pixels with a seam on both sides along some axis (see `within_local`).
    pub strip_fraction: f64,
}

impl JacobianReport {
    /// JSON object with the fields above (same names); non-finite numbers are `null`.
    pub fn to_json(&self) -> String {
        format!(
            "{{\"pixels\":{},\"tolerance\":{},\"within_all\":{},\"within_non_seam\":{},\"seam_fraction\":{},\"median_error_non_seam\":{},\"within_local\":{},\"strip_fraction\":{}}}",
            self.pixels,
            json_num(self.tolerance),
            json_num(self.within_all),
            json_num(self.within_non_seam),
            json_num(self.seam_fraction),
            json_num(self.median_error_non_seam),
            json_num(self.within_local),
            json_num(self.strip_fraction)
        )
    }
}

/// The observed Jacobian's columns `cx`, `cy` minus `J` (as `[dJ00, dJ01, dJ10, dJ11]`),
/// and the relative Frobenius error `|J_obs - J|_F / |J|_F`.
fn jacobian_error(cx: [f64; 2], cy: [f64; 2], j: &[[f64; 2]; 2]) -> ([f64; 4], f64) {
    let e = [
        cx[0] - j[0][0],
        cy[0] - j[0][1],
        cx[1] - j[1][0],
        cy[1] - j[1][1],
    ];
    let norm_j = j.iter().flatten().map(|v| v * v).sum::<f64>().sqrt();
    (
        e,
        e.iter().map(|v| v * v).sum::<f64>().sqrt() / norm_j.max(1e-12),
    )
}

/// Compares the finite-difference Jacobian of a continuous coordinate map (exemplar
/// pixels, e.g. [`crate::Synthesis::coords_f32`]) with the field it was synthesized
/// along. `J_obs(p) = [S(p+x) - S(p), S(p+y) - S(p)]` (differences wrapped to the
/// shortest way around the exemplar), against `J` at the pixel (output position
/// `origin + p`, with the same clamping as synthesis). Error:
/// `|J_obs - J|_F / |J|_F`.
pub fn jacobian_fidelity(
    coords: &[[f32; 2]],
    width: u32,
    height: u32,
    exemplar_size: [u32; 2],
    origin: [i32; 2],
    field: &crate::field::Field,
    tolerance: f64,
) -> Result<JacobianReport> {
    let (w, h) = (width as usize, height as usize);
    if coords.len() != w * h || w < 2 || h < 2 {
        return Err(invalid(format!(
            "coordinate map of {} values for {width}x{height} (at least 2x2 needed)",
            coords.len()
        )));
    }
    field.validate()?;
    if exemplar_size[0] == 0 || exemplar_size[1] == 0 {
        return Err(invalid("the exemplar size must be at least 1x1"));
    }
    let ex = [exemplar_size[0] as f64, exemplar_size[1] as f64];
    let wrap = |d: f64, n: f64| d - n * (d / n).round();
    let mut errors_all = 0usize;
    let mut errors_ok = Vec::new();
    let mut seams = 0usize;
    let mut total = 0usize;
    for y in 0..h - 1 {
        for x in 0..w - 1 {
            let s = coords[y * w + x];
            let sx = coords[y * w + x + 1];
            let sy = coords[(y + 1) * w + x];
            let cx = [
                wrap((sx[0] - s[0]) as f64, ex[0]),
                wrap((sx[1] - s[1]) as f64, ex[1]),
            ];
            let cy = [
                wrap((sy[0] - s[0]) as f64, ex[0]),
                wrap((sy[1] - s[1]) as f64, ex[1]),
            ];
            let j = field.at(
                (origin[0] as i64 + x as i64) as f64,
                (origin[1] as i64 + y as i64) as f64,
            );
            let (e, err) = jacobian_error(cx, cy, &j);
            let seam = (e[0] * e[0] + e[2] * e[2]).sqrt() > 1.0
                || (e[1] * e[1] + e[3] * e[3]).sqrt() > 1.0;
            total += 1;
            if err <= tolerance {
                errors_all += 1;
            }
            if seam {
                seams += 1;
            } else {
                errors_ok.push(err);
            }
        }
    }
    // The local Jacobian, per axis from the neighbours that continue the pixel's patch.
    let mut local_ok = 0usize;
    let mut strips = 0usize;
    for y in 0..h {
        for x in 0..w {
            let s = coords[y * w + x];
            let j = field.at(
                (origin[0] as i64 + x as i64) as f64,
                (origin[1] as i64 + y as i64) as f64,
            );
            // Column `axis` of the observed Jacobian, or None across seams on both sides.
            let column = |axis: usize| -> Option<[f64; 2]> {
                let (fwd, bwd) = if axis == 0 {
                    (
                        (x + 1 < w).then(|| y * w + x + 1),
                        (x > 0).then(|| y * w + x - 1),
                    )
                } else {
                    (
                        (y + 1 < h).then(|| (y + 1) * w + x),
                        (y > 0).then(|| (y - 1) * w + x),
                    )
                };
                let want = [j[0][axis], j[1][axis]];
                let side = |i: Option<usize>, sign: f64| {
                    i.map(|i| {
                        let n = coords[i];
                        [
                            sign * wrap((n[0] - s[0]) as f64, ex[0]),
                            sign * wrap((n[1] - s[1]) as f64, ex[1]),
                        ]
                    })
                    .filter(|d| ((d[0] - want[0]).powi(2) + (d[1] - want[1]).powi(2)).sqrt() <= 1.0)
                };
                match (side(fwd, 1.0), side(bwd, -1.0)) {
                    (Some(a), Some(b)) => Some([(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0]),
                    (Some(a), None) | (None, Some(a)) => Some(a),
                    (None, None) => None,
                }
            };
            match (column(0), column(1)) {
                (Some(cx), Some(cy)) => {
                    if jacobian_error(cx, cy, &j).1 <= tolerance {
                        local_ok += 1;
                    }
                }
                _ => strips += 1,
            }
        }
    }
    let n_ok = errors_ok.len();
    let within_ok = errors_ok.iter().filter(|&&e| e <= tolerance).count();
    errors_ok.sort_by(|a, b| a.total_cmp(b));
    Ok(JacobianReport {
        pixels: total,
        tolerance,
        within_all: errors_all as f64 / total as f64,
        within_non_seam: if n_ok > 0 {
            within_ok as f64 / n_ok as f64
        } else {
            0.0
        },
        seam_fraction: seams as f64 / total as f64,
        median_error_non_seam: if n_ok > 0 {
            errors_ok[n_ok / 2]
        } else {
            f64::NAN
        },
        within_local: local_ok as f64 / (w * h) as f64,
        strip_fraction: strips as f64 / (w * h) as f64,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::Field;

    /// Two isometric patches side by side, the right one a 1-pixel column: forward
    /// differences fail at the seam, the local Jacobian only on the strip.
    #[test]
    fn local_jacobian_ignores_one_sided_seams() {
        let (w, h) = (8u32, 6u32);
        let mut coords = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let (ox, oy) = match x {
                    0..=3 => (10.0, 20.0),
                    4 => (60.0, 5.0), // a strip one pixel wide
                    _ => (90.0, 70.0),
                };
                coords.push([ox + x as f32, oy + y as f32]);
            }
        }
        let identity = Field::Constant {
            angle: 0.0,
            scale: [1.0, 1.0],
            shear: 0.0,
        };
        let r = jacobian_fidelity(&coords, w, h, [128, 128], [0, 0], &identity, 0.15).unwrap();
        // Forward differences: columns 3 and 4 (of 7 measured) step across a seam.
        assert!((r.seam_fraction - 2.0 / 7.0).abs() < 1e-9, "{r:?}");
        assert!((r.within_all - 5.0 / 7.0).abs() < 1e-9, "{r:?}");
        // Local: only column 4 (a seam on both sides) has no Jacobian along x.
        assert!((r.strip_fraction - 1.0 / 8.0).abs() < 1e-9, "{r:?}");
        assert!((r.within_local - 7.0 / 8.0).abs() < 1e-9, "{r:?}");
        // A rotated field is not followed, locally or not.
        let rotated = Field::Constant {
            angle: 0.8,
            scale: [1.0, 1.0],
            shear: 0.0,
        };
        let r = jacobian_fidelity(&coords, w, h, [128, 128], [0, 0], &rotated, 0.15).unwrap();
        assert_eq!(r.within_local, 0.0, "{r:?}");
    }
}
