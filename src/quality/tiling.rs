//! Tiling seam: how visible an image's wrap-around edges are when it is tiled.

use super::common::invalid;
use super::image::FloatImage;
use crate::error::Result;

/// How strongly an image's wrap-around edges show when it is tiled: the mean absolute
/// difference between the last and first column and row (over all channels), divided
/// by the mean absolute difference between horizontally and vertically neighbouring
/// pixels inside the image. About 1 (or below) for a seamlessly tiling texture, well
/// above 1 when the tiling seam is visible.
pub fn wrap_seam_ratio(image: &FloatImage) -> Result<f64> {
    let (w, h, c) = (
        image.width as usize,
        image.height as usize,
        image.channels as usize,
    );
    image.validate()?;
    if w < 2 || h < 2 {
        return Err(invalid("the image must be at least 2x2"));
    }
    let px = |x: usize, y: usize| &image.data[(y * w + x) * c..(y * w + x + 1) * c];
    let diff = |a: &[f32], b: &[f32]| -> f64 {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs() as f64)
            .sum::<f64>()
    };
    let (mut inner, mut n_inner) = (0.0, 0usize);
    let (mut seam, mut n_seam) = (0.0, 0usize);
    for y in 0..h {
        for x in 0..w {
            let right = px((x + 1) % w, y);
            let down = px(x, (y + 1) % h);
            let d_r = diff(px(x, y), right);
            let d_d = diff(px(x, y), down);
            if x + 1 == w {
                seam += d_r;
                n_seam += 1;
            } else {
                inner += d_r;
                n_inner += 1;
            }
            if y + 1 == h {
                seam += d_d;
                n_seam += 1;
            } else {
                inner += d_d;
                n_inner += 1;
            }
        }
    }
    let inner = inner / n_inner as f64;
    let seam = seam / n_seam as f64;
    Ok(if inner > 0.0 {
        seam / inner
    } else if seam > 0.0 {
        f64::INFINITY
    } else {
        1.0
    })
}
