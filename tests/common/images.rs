//! Comparing images: grey views of RGBA8 frames, mean differences (plain and along a
//! flow), sizes of written files.

use std::path::Path;

use texsyn::analysis::Exemplar;
use texsyn::quality::FloatImage;

/// The red channel of an RGBA8 image as a one-channel image in 0-1 (the tests' exemplars
/// are grey enough for the texture energy).
pub fn grey(rgba: &[u8], w: u32, h: u32) -> FloatImage {
    FloatImage::new(
        w,
        h,
        1,
        rgba.chunks(4).map(|p| p[0] as f32 / 255.0).collect(),
    )
    .unwrap()
}

/// The exemplar's colours as [`grey`] reads a frame.
pub fn exemplar_grey(ex: &Exemplar) -> FloatImage {
    FloatImage::new(
        ex.width,
        ex.height,
        1,
        ex.colors.iter().map(|p| p[0] as f32 / 255.0).collect(),
    )
    .unwrap()
}

/// Mean absolute grey difference (0-255) between two RGBA8 images.
pub fn plain_diff(a: &[u8], b: &[u8]) -> f64 {
    a.chunks(4)
        .zip(b.chunks(4))
        .map(|(x, y)| (x[0] as f64 - y[0] as f64).abs())
        .sum::<f64>()
        / (a.len() / 4) as f64
}

/// Mean absolute difference between RGBA8 images `b` and `a` shifted by `d(x, y)` (b[p]
/// vs a[p - d], `a` read bilinearly), over the pixels where both exist, away from the
/// border by `m`.
pub fn warped_diff(
    a: &[u8],
    b: &[u8],
    w: u32,
    h: u32,
    d: impl Fn(f32, f32) -> (f32, f32),
    m: u32,
) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for y in m..h - m {
        for x in m..w - m {
            let (dx, dy) = d(x as f32 + 0.5, y as f32 + 0.5);
            let (fx, fy) = (x as f32 - dx, y as f32 - dy);
            let (x0, y0) = (fx.floor() as i64, fy.floor() as i64);
            if x0 < 0 || y0 < 0 || x0 + 1 >= w as i64 || y0 + 1 >= h as i64 {
                continue;
            }
            let (tx, ty) = ((fx - x0 as f32) as f64, (fy - y0 as f32) as f64);
            let px = |xx: i64, yy: i64| a[(yy as usize * w as usize + xx as usize) * 4] as f64;
            let v = px(x0, y0) * (1.0 - tx) * (1.0 - ty)
                + px(x0 + 1, y0) * tx * (1.0 - ty)
                + px(x0, y0 + 1) * (1.0 - tx) * ty
                + px(x0 + 1, y0 + 1) * tx * ty;
            let i = (y * w + x) as usize * 4;
            sum += (b[i] as f64 - v).abs();
            n += 1;
        }
    }
    sum / n.max(1) as f64
}

/// The share of RGBA8 pixels that differ between two images of the same size.
pub fn differing_share(a: &[u8], b: &[u8]) -> f64 {
    assert_eq!(a.len(), b.len(), "images of different sizes");
    a.chunks(4).zip(b.chunks(4)).filter(|(s, t)| s != t).count() as f64 / (a.len() / 4) as f64
}

/// The width and height of an image file (panics with the path when it is unreadable).
pub fn image_size(path: &Path) -> (u32, u32) {
    let img = image::open(path)
        .unwrap_or_else(|e| panic!("{} is not a readable image: {e}", path.display()));
    (img.width(), img.height())
}
