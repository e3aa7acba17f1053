//! Gaussian stack `E_0 .. E_L`: every level at full exemplar resolution, level `l`
//! low-passed so that detail below `h_l = 2^(L-l)` pixels is gone. Built "a trous":
//! `E_l` is `E_{l+1}` convolved with the binomial kernel [1 4 6 4 1]/16 whose taps are
//! `2^(L-l-1)` pixels apart. Borders wrap for tileable exemplars and clamp otherwise.

use super::par_ranges;

/// A float image with `channels` values per pixel, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Plane {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Floats per pixel.
    pub channels: u32,
    /// Row-major pixel values, `width * height * channels` floats.
    pub data: Vec<f32>,
}

impl Plane {
    /// The `channels` values of pixel `(x, y)`, the coordinates wrapped into the plane
    /// (`tileable`) or clamped to its border.
    #[inline]
    pub fn at(&self, x: i32, y: i32, tileable: bool) -> &[f32] {
        let (w, h) = (self.width as i32, self.height as i32);
        let (x, y) = if tileable {
            (x.rem_euclid(w), y.rem_euclid(h))
        } else {
            (x.clamp(0, w - 1), y.clamp(0, h - 1))
        };
        let c = self.channels as usize;
        let i = (y as usize * self.width as usize + x as usize) * c;
        &self.data[i..i + c]
    }
}

const BINOMIAL: [f32; 5] = [1.0 / 16.0, 4.0 / 16.0, 6.0 / 16.0, 4.0 / 16.0, 1.0 / 16.0];

fn blur_axis(src: &Plane, step: i32, horizontal: bool, tileable: bool, threads: usize) -> Plane {
    let (w, h, c) = (
        src.width as usize,
        src.height as usize,
        src.channels as usize,
    );
    // Source coordinate of each tap along the blurred axis (wrapped or clamped).
    let len = if horizontal { w } else { h };
    let taps: Vec<[u32; 5]> = (0..len as i64)
        .map(|i| {
            std::array::from_fn(|t| {
                let j = i + (t as i64 - 2) * step as i64;
                if tileable {
                    j.rem_euclid(len as i64) as u32
                } else {
                    j.clamp(0, len as i64 - 1) as u32
                }
            })
        })
        .collect();
    let data = &src.data;
    let rows = par_ranges(h, threads, |range| {
        let mut out = vec![0.0f32; range.len() * w * c];
        for (ri, y) in range.enumerate() {
            let orow = &mut out[ri * w * c..(ri + 1) * w * c];
            if horizontal {
                let srow = &data[y * w * c..(y + 1) * w * c];
                for x in 0..w {
                    let o = &mut orow[x * c..(x + 1) * c];
                    for (t, &k) in BINOMIAL.iter().enumerate() {
                        let sx = taps[x][t] as usize * c;
                        for (oc, v) in o.iter_mut().zip(&srow[sx..sx + c]) {
                            *oc += k * v;
                        }
                    }
                }
            } else {
                for (t, &k) in BINOMIAL.iter().enumerate() {
                    let sy = taps[y][t] as usize;
                    let srow = &data[sy * w * c..(sy + 1) * w * c];
                    for (oc, v) in orow.iter_mut().zip(srow) {
                        *oc += k * v;
                    }
                }
            }
        }
        out
    });
    Plane {
        width: src.width,
        height: src.height,
        channels: src.channels,
        data: rows.concat(),
    }
}

/// The Gaussian stack, index = level (`stack[L]` is the exemplar).
pub fn gaussian_stack(exemplar: Plane, levels: u32, tileable: bool, threads: usize) -> Vec<Plane> {
    let mut stack = vec![exemplar];
    for l in (0..levels).rev() {
        let step = 1i32 << (levels - l - 1);
        let prev = stack.last().unwrap();
        let b = blur_axis(prev, step, true, tileable, threads);
        let b = blur_axis(&b, step, false, tileable, threads);
        stack.push(b);
    }
    stack.reverse();
    stack
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stack_preserves_mean_and_smooths() {
        let (w, h) = (32u32, 32u32);
        let data: Vec<f32> = (0..w * h)
            .map(|i| ((i * 2654435761u32) >> 24) as f32 / 255.0)
            .collect();
        let mean = data.iter().sum::<f32>() / data.len() as f32;
        let plane = Plane {
            width: w,
            height: h,
            channels: 1,
            data,
        };
        let stack = gaussian_stack(plane, 5, true, 2);
        assert_eq!(stack.len(), 6);
        let var = |p: &Plane| {
            let m = p.data.iter().sum::<f32>() / p.data.len() as f32;
            (
                m,
                p.data.iter().map(|v| (v - m) * (v - m)).sum::<f32>() / p.data.len() as f32,
            )
        };
        let mut last_var = f32::INFINITY;
        for p in stack.iter().rev() {
            let (m, v) = var(p);
            assert!((m - mean).abs() < 1e-4, "wrap-around blur keeps the mean");
            assert!(v <= last_var + 1e-6);
            last_var = v;
        }
        assert!(var(&stack[0]).1 < 1e-3 * var(&stack[5]).1.max(1e-9) + 1e-6);
    }
}
