//! Jacobian fields for anisometric synthesis (Lefebvre & Hoppe 2006 §5).
//!
//! A field gives, at every output position `x` (absolute output pixels, the same
//! coordinates as `SynthParams::origin`), the 2x2 Jacobian `J(x)` that maps an offset in
//! output pixels to an offset in exemplar pixels (at every level: level-`l` pixels to
//! units of `h_l`). `J = I` is isometric synthesis. A texture that should look rotated by
//! `a` and magnified by `s` has `J = (R(a) s)^-1`.
//!
//! The host evaluates the field once per pixel of every level's region (at the pixel's
//! centre in output coordinates) and quantizes it; the GPU passes and their CPU mirrors
//! read the same integers, so they agree bit for bit.
//!
//! Fallback for degenerate fields (documented, tested): singular values of `J` are
//! clamped to `[1/MAX_SCALE, MAX_SCALE]`, so a singular `J` (zero scale, e.g. at a
//! perspective horizon) or a huge one becomes the nearest usable Jacobian with the same
//! orientation. NaN or infinite values are an error.

use std::path::Path;
use std::sync::Arc;

use crate::error::{Error, Result};

/// Fractional bits of the quantized Jacobian entries (1/1024).
pub const JAC_FRAC: u32 = 10;
/// Largest stretch of the exemplar per output pixel (and of its inverse).
pub const MAX_SCALE: f64 = 8.0;

/// A 2x2 matrix `[[a, b], [c, d]]`: `J v = (a v.x + b v.y, c v.x + d v.y)`.
pub type Mat2 = [[f64; 2]; 2];

/// The identity Jacobian: isometric synthesis (one exemplar pixel per output pixel).
pub const IDENTITY: Mat2 = [[1.0, 0.0], [0.0, 1.0]];

/// Where a field comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum Field {
    /// The same transform everywhere: the texture rotated by `angle` (radians; positive
    /// turns its x axis toward +y, which is down, so clockwise as seen on screen),
    /// magnified by `scale` along its own x and y axes, and sheared by `shear` (its y axis
    /// leans by `shear` per unit).
    Constant {
        /// Rotation in radians: the texture's x axis points along `(cos, sin)` in output
        /// pixels (y down), so positive is clockwise on screen; 0 = unrotated.
        angle: f64,
        /// Magnification `[x, y]` along the texture's own axes: output pixels per
        /// exemplar pixel (1 = actual size, 2 = twice as large); non-zero, negative mirrors.
        scale: [f64; 2],
        /// Shear: how far the texture's y axis leans per unit along it (0 = none).
        shear: f64,
    },
    /// The texture's x axis follows circles around `center` (a vortex singularity);
    /// `scale` magnifies it uniformly.
    Vortex {
        /// Centre of the vortex `[x, y]` in absolute output pixels.
        center: [f64; 2],
        /// Uniform magnification (output pixels per exemplar pixel), > 0.
        scale: f64,
    },
    /// The texture is rotated by `turns * 2 pi * (1 - r / radius)` inside `radius` of
    /// `center` (none outside): a swirl.
    Swirl {
        /// Centre of the swirl `[x, y]` in absolute output pixels.
        center: [f64; 2],
        /// Radius in output pixels beyond which there is no rotation, > 0.
        radius: f64,
        /// Rotation at the centre in full turns (1 = 360 degrees); fades linearly to 0
        /// at `radius`.
        turns: f64,
        /// Uniform magnification (output pixels per exemplar pixel) everywhere, > 0.
        scale: f64,
    },
    /// The texture's "up" (-y) points at `center`; its scale grows toward the centre
    /// from `scale` at distance `radius` to `scale * growth` at the centre.
    Radial {
        /// The point the texture's "up" points at, `[x, y]` in absolute output pixels.
        center: [f64; 2],
        /// Distance in output pixels at (and beyond) which the magnification is `scale`, > 0.
        radius: f64,
        /// Magnification (output pixels per exemplar pixel) at `radius` and beyond, > 0.
        scale: f64,
        /// Factor on `scale` at the centre, > 0 (interpolated linearly in the distance;
        /// 1 = constant scale, > 1 = larger toward the centre).
        growth: f64,
    },
    /// A ground plane seen in perspective: the horizon is the row `horizon`, the
    /// texture has magnification `scale` at row `bottom` and shrinks toward the horizon
    /// (x like 1/depth, y like 1/depth^2); `center` is the column of the vanishing point.
    Perspective {
        /// Row (y, absolute output pixels) of the horizon.
        horizon: f64,
        /// Reference row (y, absolute output pixels) for `scale`; must be greater than
        /// `horizon` (below it on screen).
        bottom: f64,
        /// Column (x, absolute output pixels) of the vanishing point.
        center: f64,
        /// Magnification (output pixels per exemplar pixel) at row `bottom` below the
        /// vanishing point, > 0.
        scale: f64,
    },
    /// Per-pixel Jacobians over `[0, width) x [0, height)` of the output (row-major);
    /// positions outside take the nearest pixel's.
    Map(Arc<FieldMap>),
}

/// A sampled field (from an image or an EXR).
#[derive(Clone, Debug, PartialEq)]
pub struct FieldMap {
    /// Width in pixels; map pixel `(i, j)` is the field at output position `(i, j)`.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height` Jacobians, row-major, top row first; each in exemplar pixels per
    /// output pixel, and must be finite.
    pub jacobians: Vec<Mat2>,
}

fn rot(a: f64) -> Mat2 {
    let (s, c) = a.sin_cos();
    [[c, -s], [s, c]]
}

/// The matrix product `a b` (apply `b` first).
pub fn mul(a: &Mat2, b: &Mat2) -> Mat2 {
    [
        [
            a[0][0] * b[0][0] + a[0][1] * b[1][0],
            a[0][0] * b[0][1] + a[0][1] * b[1][1],
        ],
        [
            a[1][0] * b[0][0] + a[1][1] * b[1][0],
            a[1][0] * b[0][1] + a[1][1] * b[1][1],
        ],
    ]
}

/// The determinant of `m` (exemplar area per output area for a Jacobian).
pub fn det(m: &Mat2) -> f64 {
    m[0][0] * m[1][1] - m[0][1] * m[1][0]
}

/// Inverse; `None` when singular or not finite.
pub fn inverse(m: &Mat2) -> Option<Mat2> {
    let d = det(m);
    if d == 0.0 || !d.is_finite() {
        return None;
    }
    Some([[m[1][1] / d, -m[0][1] / d], [-m[1][0] / d, m[0][0] / d]])
}

/// `J` of a texture transformed (exemplar -> screen) by rotation `angle`, then
/// `scale` along its own axes, then `shear`: the inverse of `R S H`.
pub fn jacobian_of_transform(angle: f64, scale: [f64; 2], shear: f64) -> Mat2 {
    let t = mul(
        &rot(angle),
        &mul(
            &[[scale[0], 0.0], [0.0, scale[1]]],
            &[[1.0, shear], [0.0, 1.0]],
        ),
    );
    inverse(&t).unwrap_or([[0.0; 2]; 2])
}

/// Clamps the singular values of `m` to `[1/MAX_SCALE, MAX_SCALE]` (see the module
/// documentation). A zero matrix becomes the identity scaled to the lower bound.
pub fn clamp_singular(m: &Mat2) -> Mat2 {
    // 2x2 SVD in closed form: m = R(theta) diag(s1, s2) R(phi)^T (s2 may be negative).
    let e = (m[0][0] + m[1][1]) / 2.0;
    let f = (m[0][0] - m[1][1]) / 2.0;
    let g = (m[1][0] + m[0][1]) / 2.0;
    let h = (m[1][0] - m[0][1]) / 2.0;
    let q = (e * e + h * h).sqrt();
    let r = (f * f + g * g).sqrt();
    let s1 = q + r;
    let s2 = q - r;
    let lo = 1.0 / MAX_SCALE;
    let c1 = s1.clamp(lo, MAX_SCALE);
    let c2 = if s2 < 0.0 {
        -(-s2).clamp(lo, MAX_SCALE)
    } else {
        s2.clamp(lo, MAX_SCALE)
    };
    if c1 == s1 && c2 == s2 {
        return *m;
    }
    // The angles only where a value was clamped (two atan2 were most of a field's
    // rasterization time).
    let a1 = g.atan2(f);
    let a2 = h.atan2(e);
    let theta = (a2 + a1) / 2.0;
    let phi = (a2 - a1) / 2.0;
    let r_t = rot(theta);
    let r_p = rot(phi);
    let r_pt = [[r_p[0][0], r_p[1][0]], [r_p[0][1], r_p[1][1]]];
    mul(&r_t, &mul(&[[c1, 0.0], [0.0, c2]], &r_pt))
}

impl Field {
    /// The field at output position `(x, y)` before clamping.
    pub fn raw(&self, x: f64, y: f64) -> Mat2 {
        match self {
            Field::Constant {
                angle,
                scale,
                shear,
            } => jacobian_of_transform(*angle, *scale, *shear),
            Field::Vortex { center, scale } => {
                let a = (y - center[1]).atan2(x - center[0]) + std::f64::consts::FRAC_PI_2;
                jacobian_of_transform(a, [*scale; 2], 0.0)
            }
            Field::Swirl {
                center,
                radius,
                turns,
                scale,
            } => {
                let r = ((x - center[0]).powi(2) + (y - center[1]).powi(2)).sqrt();
                let t = (1.0 - r / radius.max(1e-9)).max(0.0);
                jacobian_of_transform(turns * std::f64::consts::TAU * t, [*scale; 2], 0.0)
            }
            Field::Radial {
                center,
                radius,
                scale,
                growth,
            } => {
                let (dx, dy) = (x - center[0], y - center[1]);
                let r = (dx * dx + dy * dy).sqrt();
                // Screen direction of the texture's -y ("up") is toward the centre:
                // rotate so that (0, -1) maps to -(dx, dy)/r.
                let a = if r > 0.0 {
                    (-dx).atan2(dy) + std::f64::consts::PI
                } else {
                    0.0
                };
                let t = (1.0 - r / radius.max(1e-9)).max(0.0);
                let s = scale * (1.0 + (growth - 1.0) * t);
                jacobian_of_transform(a, [s; 2], 0.0)
            }
            Field::Perspective {
                horizon,
                bottom,
                center,
                scale,
            } => {
                // Ground plane: exemplar (u, v) = (X, Z) / texel, screen x = f X / Z,
                // y = horizon + f c / Z. Normalized so that J = I / scale at the bottom
                // row straight below the vanishing point.
                let t_b = (bottom - horizon).max(1e-9);
                let t = y - horizon;
                let k = 1.0 / scale;
                // u = k t_b (x - center) / t, v = -k t_b^2 / t (up the screen = away).
                [
                    [k * t_b / t, -k * t_b * (x - center) / (t * t)],
                    [0.0, k * t_b * t_b / (t * t)],
                ]
            }
            Field::Map(m) => {
                // `validate` refuses empty or short maps; unvalidated ones read identity.
                let i = (x.round().clamp(0.0, m.width.max(1) as f64 - 1.0)) as usize;
                let j = (y.round().clamp(0.0, m.height.max(1) as f64 - 1.0)) as usize;
                m.jacobians
                    .get(j * m.width as usize + i)
                    .copied()
                    .unwrap_or([[1.0, 0.0], [0.0, 1.0]])
            }
        }
    }

    /// The field at `(x, y)` with the singular-value fallback applied. Non-finite values
    /// (e.g. below the horizon's mirror image) fall back to the largest allowed scale.
    pub fn at(&self, x: f64, y: f64) -> Mat2 {
        let m = self.raw(x, y);
        if m.iter().flatten().all(|v| v.is_finite()) {
            clamp_singular(&m)
        } else {
            [[MAX_SCALE, 0.0], [0.0, MAX_SCALE]]
        }
    }

    /// Checks user-given values: every parameter finite; a constant field's scales within
    /// `1/MAX_SCALE..=MAX_SCALE` (positive: a mirror is not a magnification).
    pub fn validate(&self) -> Result<()> {
        let bad = |what: &str| Err(Error::InvalidParameter(format!("field: {what}")));
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        match self {
            Field::Constant {
                angle,
                scale,
                shear,
            } => {
                if !finite(&[*angle, scale[0], scale[1], *shear]) {
                    return bad("angle, scale and shear must be finite numbers");
                }
                if scale[0] == 0.0 || scale[1] == 0.0 {
                    return bad("a zero scale makes the texture vanish; use a scale > 0");
                }
                // A negative scale is a mirror or a half turn, not a magnification: say
                // so rather than synthesize something else than asked.
                if scale[0] < 0.0 || scale[1] < 0.0 {
                    return bad(
                        "a negative scale mirrors or turns the texture; use a scale > 0 \
                         (and an angle to turn it)",
                    );
                }
                // Magnifications outside 1/8..8 would be clamped: refuse them instead of
                // synthesizing another scale in silence.
                let lo = 1.0 / MAX_SCALE;
                if let Some(s) = scale.iter().find(|s| !(lo..=MAX_SCALE).contains(*s)) {
                    let hint = if *s > MAX_SCALE {
                        "; for larger features use magnification (`--magnify`, \
                         `SessionBuilder::magnify`)"
                    } else {
                        ""
                    };
                    return Err(Error::InvalidParameter(format!(
                        "field: scale {s} is outside {lo}..{MAX_SCALE}, the magnifications \
                         texsyn synthesizes{hint}"
                    )));
                }
            }
            Field::Vortex { center, scale } => {
                if !finite(&[center[0], center[1], *scale]) || *scale <= 0.0 {
                    return bad("vortex: centre must be finite and scale > 0");
                }
            }
            Field::Swirl {
                center,
                radius,
                turns,
                scale,
            } => {
                if !finite(&[center[0], center[1], *radius, *turns, *scale])
                    || *scale <= 0.0
                    || *radius <= 0.0
                {
                    return bad("swirl: values must be finite, radius and scale > 0");
                }
            }
            Field::Radial {
                center,
                radius,
                scale,
                growth,
            } => {
                if !finite(&[center[0], center[1], *radius, *scale, *growth])
                    || *scale <= 0.0
                    || *radius <= 0.0
                    || *growth <= 0.0
                {
                    return bad("radial: values must be finite, radius, scale and growth > 0");
                }
            }
            Field::Perspective {
                horizon,
                bottom,
                center,
                scale,
            } => {
                if !finite(&[*horizon, *bottom, *center, *scale]) || *scale <= 0.0 {
                    return bad("perspective: values must be finite and scale > 0");
                }
                if bottom <= horizon {
                    return bad("perspective: the reference row (BOTTOM, by default the output's last) must lie below \
                     the horizon");
                }
            }
            Field::Map(m) => {
                if m.width == 0 || m.height == 0 {
                    return bad("map: it has no pixels (width and height must be at least 1)");
                }
                if m.jacobians.len() != m.width as usize * m.height as usize {
                    return bad("map: size does not match its data");
                }
                if let Some(i) = m
                    .jacobians
                    .iter()
                    .position(|j| !j.iter().flatten().all(|v| v.is_finite()))
                {
                    return Err(Error::InvalidParameter(format!(
                        "field: pixel ({}, {}) is NaN or infinite; every Jacobian must be finite",
                        i % m.width as usize,
                        i / m.width as usize
                    )));
                }
            }
        }
        Ok(())
    }

    /// The identity everywhere: isometric synthesis run through the anisometric passes
    /// (advection, a tileable output made on a torus).
    pub fn identity() -> Self {
        Field::Constant {
            angle: 0.0,
            scale: [1.0, 1.0],
            shear: 0.0,
        }
    }

    /// Whether this is the identity everywhere (isometric synthesis).
    pub fn is_identity(&self) -> bool {
        matches!(self, Field::Constant { angle, scale, shear }
            if *angle == 0.0 && *scale == [1.0, 1.0] && *shear == 0.0)
    }
}

/// Quantizes a (clamped) Jacobian to the integers the passes read: row-major
/// `(a, b, c, d)` in 1/2^JAC_FRAC.
pub fn quantize(m: &Mat2) -> [i32; 4] {
    let s = (1u32 << JAC_FRAC) as f64;
    [
        (m[0][0] * s).round() as i32,
        (m[0][1] * s).round() as i32,
        (m[1][0] * s).round() as i32,
        (m[1][1] * s).round() as i32,
    ]
}

/// Quantized Jacobians of a level's region: `origin`/`size` in level pixels, the level
/// `2^steps` times coarser than the output. Pixel `p` samples the field at its centre in
/// output coordinates, `(p + 0.5) * 2^steps - 0.5` (`steps` is at most 62).
pub fn rasterize_region(
    field: &Field,
    origin: [i32; 2],
    size: [u32; 2],
    steps: u32,
) -> Vec<[i32; 4]> {
    rasterize_with(field, origin, size, steps, |x, y| quantize(&field.at(x, y)))
}

/// [`rasterize_region`] for a torus standing for an output `scale` times its size on
/// each axis ([`crate::passes::plan::Torus`]): pixel `p` stands for output position
/// `(t + 0.5) scale - 0.5`, `t` its centre in torus pixels, and takes the field there
/// times `diag(scale)` (the texture advances per torus pixel what it advances over
/// `scale` output pixels).
pub fn rasterize_region_scaled(
    field: &Field,
    origin: [i32; 2],
    size: [u32; 2],
    steps: u32,
    scale: [f64; 2],
) -> Vec<[i32; 4]> {
    let d = [[scale[0], 0.0], [0.0, scale[1]]];
    rasterize_with(field, origin, size, steps, |x, y| {
        let m = field.at((x + 0.5) * scale[0] - 0.5, (y + 0.5) * scale[1] - 0.5);
        quantize(&clamp_singular(&mul(&m, &d)))
    })
}

/// `at(x, y)` at every pixel centre of a level's region (output coordinates): once for a
/// constant field, else rows in parallel (trigonometry and a 2x2 SVD per pixel: about
/// 40 ns each).
fn rasterize_with(
    field: &Field,
    origin: [i32; 2],
    size: [u32; 2],
    steps: u32,
    at: impl Fn(f64, f64) -> [i32; 4] + Sync,
) -> Vec<[i32; 4]> {
    let f = (1u64 << steps.min(62)) as f64;
    let w = size[0] as usize;
    if let Field::Constant { .. } = field {
        return vec![at(0.0, 0.0); w * size[1] as usize];
    }
    crate::analysis::par_ranges(size[1] as usize, 0, |rows| {
        let mut out = Vec::with_capacity(rows.len() * w);
        for y in rows {
            let fy = (origin[1] as i64 + y as i64) as f64 * f + 0.5 * f - 0.5;
            for x in 0..w as i64 {
                let fx = (origin[0] as i64 + x) as f64 * f + 0.5 * f - 0.5;
                out.push(at(fx, fy));
            }
        }
        out
    })
    .concat()
}

/// A direction-and-scale field from an image the size of the output: channel 0 is the
/// texture's rotation (0..1 -> 0..2 pi), channel 1 its magnification on a log scale
/// (0..1 -> 1/8..8, 0.5 = 1); a grey image (grey+alpha, a 1-channel EXR) is rotation
/// only, a 2-channel EXR (angle, log scale) is both.
pub fn load_direction_scale_image(path: &Path) -> Result<FieldMap> {
    let (img, exr_channels) = crate::image_io::open_image_exr_channels(path)?;
    let (w, h) = (img.width(), img.height());
    let has_scale = match exr_channels {
        Some(n) => n >= 2,
        None => img.color().channel_count() >= 2 && img.color().has_color(),
    };
    let rgb = img.to_rgb32f();
    let mut jacobians = Vec::with_capacity(w as usize * h as usize);
    for (i, p) in rgb.pixels().enumerate() {
        if !(p[0].is_finite() && p[1].is_finite()) {
            return Err(Error::InvalidParameter(format!(
                "{}: pixel ({}, {}) is NaN or infinite; a direction-and-scale image needs finite values (angle 0..1, log scale 0..1)",
                path.display(),
                i as u32 % w,
                i as u32 / w
            )));
        }
        let angle = p[0] as f64 * std::f64::consts::TAU;
        let scale = if has_scale {
            (2f64).powf((p[1] as f64 - 0.5) * 6.0)
        } else {
            1.0
        };
        jacobians.push(jacobian_of_transform(angle, [scale; 2], 0.0));
    }
    Ok(FieldMap {
        width: w,
        height: h,
        jacobians,
    })
}

/// A full 2x2 field from an EXR the size of the output: channels R, G, B, A hold the
/// Jacobian row-major `(a, b, c, d)` (exemplar pixels per output pixel).
pub fn load_jacobian_exr(path: &Path) -> Result<FieldMap> {
    let (img, exr_channels) = crate::image_io::open_image_exr_channels(path)?;
    let (w, h) = (img.width(), img.height());
    if let Some(n) = exr_channels {
        return Err(Error::InvalidParameter(format!(
            "{}: a Jacobian EXR needs 4 channels (R, G, B, A = J00, J01, J10, J11), it has {n}",
            path.display()
        )));
    }
    if !matches!(
        img,
        image::DynamicImage::ImageRgba32F(_) | image::DynamicImage::ImageRgb32F(_)
    ) {
        return Err(Error::InvalidParameter(format!(
            "{}: not a float (EXR) image; exr: takes a float RGBA EXR holding J (for an \
             8-bit direction-and-scale image use image:FILE)",
            path.display()
        )));
    }
    if img.color().channel_count() < 4 {
        return Err(Error::InvalidParameter(format!(
            "{}: a Jacobian EXR needs 4 channels (R, G, B, A = J00, J01, J10, J11), it has {}",
            path.display(),
            img.color().channel_count()
        )));
    }
    let rgba = img.to_rgba32f();
    let jacobians = rgba
        .pixels()
        .map(|p| [[p[0] as f64, p[1] as f64], [p[2] as f64, p[3] as f64]])
        .collect();
    Ok(FieldMap {
        width: w,
        height: h,
        jacobians,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &Mat2, b: &Mat2) -> bool {
        a.iter()
            .flatten()
            .zip(b.iter().flatten())
            .all(|(x, y)| (x - y).abs() < 1e-9)
    }

    #[test]
    fn clamp_keeps_moderate_matrices() {
        let m = jacobian_of_transform(0.7, [1.5, 0.8], 0.3);
        assert!(close(&clamp_singular(&m), &m));
        let r = [[0.0, 1.0], [1.0, 0.0]]; // a reflection
        assert!(close(&clamp_singular(&r), &r));
    }

    #[test]
    fn clamp_bounds_singular_values() {
        for m in [
            [[0.0, 0.0], [0.0, 0.0]],
            [[1.0, 2.0], [2.0, 4.0]],
            [[100.0, 0.0], [0.0, 1.0]],
            [[0.0, -50.0], [0.001, 0.0]],
        ] {
            let c = clamp_singular(&m);
            let d = det(&c).abs();
            assert!(
                (1.0 / 64.0 - 1e-9..=64.0 + 1e-9).contains(&d),
                "{m:?} -> {c:?}"
            );
            let fro = c.iter().flatten().map(|v| v * v).sum::<f64>().sqrt();
            assert!(fro <= MAX_SCALE * 2f64.sqrt() + 1e-9);
        }
    }

    #[test]
    fn identity_quantizes_exactly() {
        assert_eq!(quantize(&IDENTITY), [1024, 0, 0, 1024]);
        assert!(Field::Constant {
            angle: 0.0,
            scale: [1.0, 1.0],
            shear: 0.0
        }
        .is_identity());
    }

    #[test]
    fn perspective_is_identity_over_scale_at_the_bottom() {
        let f = Field::Perspective {
            horizon: 10.0,
            bottom: 100.0,
            center: 50.0,
            scale: 2.0,
        };
        assert!(close(&f.raw(50.0, 100.0), &[[0.5, 0.0], [0.0, 0.5]]));
        // Smaller on screen (larger J) toward the horizon.
        assert!(det(&f.at(50.0, 40.0)) > det(&f.at(50.0, 100.0)));
    }

    #[test]
    fn bad_parameters_are_errors() {
        assert!(Field::Constant {
            angle: f64::NAN,
            scale: [1.0, 1.0],
            shear: 0.0
        }
        .validate()
        .is_err());
        let m = FieldMap {
            width: 1,
            height: 1,
            jacobians: vec![[[f64::INFINITY, 0.0], [0.0, 1.0]]],
        };
        assert!(Field::Map(Arc::new(m)).validate().is_err());
        // Constant scales: positive and within 1/8..8, the range synthesized unclamped.
        let constant = |sx: f64, sy: f64| {
            Field::Constant {
                angle: 0.0,
                scale: [sx, sy],
                shear: 0.0,
            }
            .validate()
        };
        assert!(constant(1.0, 1.0).is_ok());
        assert!(constant(0.125, 8.0).is_ok());
        assert!(constant(-1.0, 1.0).is_err());
        assert!(constant(100.0, 1.0).is_err());
        assert!(constant(1.0, 0.1).is_err());
    }
}
