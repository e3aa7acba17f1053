//! Feature breakage: how a binary feature mask (mortar, cracks, spot outlines)
//! survives synthesis.
//!
//! The exemplar's mask is carried through the output's coordinate map and compared
//! with itself: the share of feature pixels in small fragments (crumbs of broken
//! features, to read against the exemplar's own share) and the texture energy of the
//! mask (feature shapes the exemplar never shows).

use super::common::{invalid, json_num};
use super::energy::{texture_energy, DEFAULT_RADIUS};
use super::image::FloatImage;
use crate::error::Result;

/// Fragments smaller than this many pixels count as broken features in
/// [`feature_breakage`] (thin mortar or crack pieces cut off from their network).
pub const MIN_FEATURE_FRAGMENT: usize = 20;

/// How a binary feature mask (mortar, cracks, spot outlines) survives synthesis: the
/// exemplar's mask resynthesized through the output's coordinate map, compared with the
/// mask itself. See [`feature_breakage`].
#[derive(Clone, Debug, PartialEq)]
pub struct FeatureBreakage {
    /// Share of the synthesized mask's feature pixels in 8-connected fragments under
    /// [`MIN_FEATURE_FRAGMENT`] pixels: features broken into crumbs.
    pub fragment_fraction: f64,
    /// The same share in the exemplar's own mask (the reference: a mask made of small
    /// spots has a high share without any breakage).
    pub exemplar_fragment_fraction: f64,
    /// Fraction of output pixels that are feature (in the synthesized mask).
    pub coverage: f64,
    /// Fraction of exemplar pixels that are feature.
    pub exemplar_coverage: f64,
    /// Texture energy (7x7 windows) of the synthesized mask against the exemplar's
    /// mask, both as 0/1 images: feature shapes that never occur in the exemplar
    /// (broken, cut, merged or dangling pieces) raise it.
    pub mask_energy: f64,
}

impl FeatureBreakage {
    /// JSON object with the fields above (same names) plus `min_fragment_pixels`
    /// ([`MIN_FEATURE_FRAGMENT`]); non-finite numbers are `null`.
    pub fn to_json(&self) -> String {
        format!(
            "{{\"fragment_fraction\":{},\"exemplar_fragment_fraction\":{},\"coverage\":{},\"exemplar_coverage\":{},\"mask_energy\":{},\"min_fragment_pixels\":{}}}",
            json_num(self.fragment_fraction),
            json_num(self.exemplar_fragment_fraction),
            json_num(self.coverage),
            json_num(self.exemplar_coverage),
            json_num(self.mask_energy),
            MIN_FEATURE_FRAGMENT
        )
    }
}

/// Share of the `true` pixels of a row-major `w x h` mask that lie in 8-connected
/// components under `min` pixels (no wrap-around); 0 for a mask without features, NaN
/// when `inside` does not hold `w * h` flags.
pub fn fragment_fraction(inside: &[bool], w: usize, h: usize, min: usize) -> f64 {
    if w.checked_mul(h) != Some(inside.len()) {
        return f64::NAN; // not a w x h mask
    }
    let mut seen = vec![false; inside.len()];
    let (mut total, mut small) = (0usize, 0usize);
    let mut stack = Vec::new();
    let mut comp = Vec::new();
    for start in 0..inside.len() {
        if !inside[start] || seen[start] {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        comp.clear();
        while let Some(i) = stack.pop() {
            comp.push(i);
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            for dy in -1..=1i64 {
                for dx in -1..=1i64 {
                    let (nx, ny) = (x + dx, y + dy);
                    if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                        continue;
                    }
                    let j = ny as usize * w + nx as usize;
                    if inside[j] && !seen[j] {
                        seen[j] = true;
                        stack.push(j);
                    }
                }
            }
        }
        total += comp.len();
        if comp.len() < min {
            small += comp.len();
        }
    }
    if total == 0 {
        0.0
    } else {
        small as f64 / total as f64
    }
}

/// [`FeatureBreakage`] of an output whose coordinate map is `coords` (`out_w x out_h`,
/// exemplar pixels, rounded to the nearest pixel; wrapped when `tileable`, else
/// clamped) for the exemplar-sized feature `mask`.
///
/// Errors: a map whose length is not `out_w * out_h`, an output smaller than the 7x7
/// window, a non-finite coordinate.
pub fn feature_breakage(
    mask: &crate::analysis::FeatureMask,
    coords: &[[f32; 2]],
    out_w: u32,
    out_h: u32,
    tileable: bool,
) -> Result<FeatureBreakage> {
    let (w, h) = (out_w as usize, out_h as usize);
    if coords.len() != w * h || w == 0 || h == 0 {
        return Err(invalid(format!(
            "coordinate map has {} entries, expected {out_w}x{out_h}",
            coords.len()
        )));
    }
    if mask.width == 0 || mask.height == 0 {
        return Err(invalid("the feature mask is empty"));
    }
    mask.check_size(mask.width, mask.height)?;
    let (ew, eh) = (mask.width as i64, mask.height as i64);
    let mut out = Vec::with_capacity(w * h);
    for c in coords {
        if !(c[0].is_finite() && c[1].is_finite()) {
            return Err(invalid("coordinate map holds a non-finite coordinate"));
        }
        let (x, y) = (c[0].round() as i64, c[1].round() as i64);
        let (x, y) = if tileable {
            (x.rem_euclid(ew), y.rem_euclid(eh))
        } else {
            (x.clamp(0, ew - 1), y.clamp(0, eh - 1))
        };
        out.push(mask.inside[(y * ew + x) as usize]);
    }
    let to_image = |m: &[bool], w: u32, h: u32| {
        FloatImage::new(w, h, 1, m.iter().map(|&b| b as u8 as f32).collect())
    };
    let ex_img = to_image(&mask.inside, mask.width, mask.height)?;
    let out_img = to_image(&out, out_w, out_h)?;
    let coverage = |m: &[bool]| m.iter().filter(|&&b| b).count() as f64 / m.len() as f64;
    Ok(FeatureBreakage {
        fragment_fraction: fragment_fraction(&out, w, h, MIN_FEATURE_FRAGMENT),
        exemplar_fragment_fraction: fragment_fraction(
            &mask.inside,
            mask.width as usize,
            mask.height as usize,
            MIN_FEATURE_FRAGMENT,
        ),
        coverage: coverage(&out),
        exemplar_coverage: coverage(&mask.inside),
        mask_energy: texture_energy(&ex_img, &out_img, DEFAULT_RADIUS)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fragment_fraction_counts_small_8_connected_pieces() {
        // A 30 px line (diagonal steps join it: 8-connectivity), a 3 px crumb.
        let (w, h) = (40usize, 10usize);
        let mut m = vec![false; w * h];
        for x in 0..30 {
            m[(x % 2) * w + x] = true;
        }
        for x in 35..38 {
            m[7 * w + x] = true;
        }
        let f = fragment_fraction(&m, w, h, MIN_FEATURE_FRAGMENT);
        assert!((f - 3.0 / 33.0).abs() < 1e-12, "{f}");
        assert_eq!(fragment_fraction(&vec![false; w * h], w, h, 20), 0.0);
    }
}
