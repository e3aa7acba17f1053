//! Synthetic images for the unit tests of the figures.

use super::common::splitmix;
use super::image::FloatImage;

pub(super) fn noise_image(w: u32, h: u32, c: u32, seed: u64) -> FloatImage {
    let mut s = seed;
    let data = (0..w * h * c)
        .map(|_| (splitmix(&mut s) >> 40) as f32 / (1u64 << 24) as f32)
        .collect();
    FloatImage::new(w, h, c, data).unwrap()
}

/// A smooth structured colour texture (sums of sines plus a little noise).
pub(super) fn texture(w: u32, h: u32, c: u32, seed: u64) -> FloatImage {
    let noise = noise_image(w, h, c, seed);
    let mut data = Vec::new();
    for y in 0..h {
        for x in 0..w {
            for ch in 0..c {
                let (fx, fy) = (x as f32, y as f32);
                let v = 0.5
                    + 0.2 * (fx * 0.37 + ch as f32).sin() * (fy * 0.23).cos()
                    + 0.15 * ((fx + fy) * 0.11 + seed as f32).sin()
                    + 0.1 * (noise.pixel(x, y)[ch as usize] - 0.5);
                data.push(v.clamp(0.0, 1.0));
            }
        }
    }
    FloatImage::new(w, h, c, data).unwrap()
}
