//! What the feature tests share: synthetic exemplars and masks, a brute-force distance
//! transform, deterministic bits, the expected error of a bad analysis.

use std::path::Path;

use texsyn::analysis::{Analysis, Exemplar, FeatureMask};
use texsyn::Error;

/// The bundled brick photograph.
pub const BRICK: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/brick.png");

/// Deterministic pseudo-random bits.
pub struct Lcg(pub u64);
impl Lcg {
    pub fn next(&mut self) -> u32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 33) as u32
    }
}

/// Squared distance to the nearest site by brute force (with wrap: periodic distance).
pub fn brute_force(sites: &[bool], w: usize, h: usize, wrap: bool) -> Vec<f64> {
    let mut out = vec![f64::INFINITY; w * h];
    for y in 0..h {
        for x in 0..w {
            for sy in 0..h {
                for sx in 0..w {
                    if !sites[sy * w + sx] {
                        continue;
                    }
                    let mut dx = x.abs_diff(sx);
                    let mut dy = y.abs_diff(sy);
                    if wrap {
                        dx = dx.min(w - dx);
                        dy = dy.min(h - dy);
                    }
                    out[y * w + x] = out[y * w + x].min((dx * dx + dy * dy) as f64);
                }
            }
        }
    }
    out
}

/// An RGB exemplar from a function of the pixel position.
pub fn exemplar_from(w: u32, h: u32, f: impl Fn(u32, u32) -> [f32; 3]) -> Exemplar {
    let mut values = Vec::new();
    let mut colors = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let c = f(x, y).map(|v| v.clamp(0.0, 1.0));
            values.extend_from_slice(&c);
            let q = c.map(|v| (v * 255.0).round() as u8);
            colors.push([q[0], q[1], q[2], 255]);
        }
    }
    Exemplar {
        width: w,
        height: h,
        channels: 3,
        values,
        colors,
    }
}

/// Running-bond brick courses: whether (x, y) is mortar, for bricks of `bw x bh` pixels
/// (mortar included) and mortar lines `m` pixels wide.
pub fn mortar(x: u32, y: u32, bw: u32, bh: u32, m: u32) -> bool {
    let row = y / bh;
    let xo = if row % 2 == 1 { bw / 2 } else { 0 };
    (x + xo) % bw < m || y % bh < m
}

/// A small structured RGB exemplar (running-bond bricks of varying colour, mortar
/// lines 2 px wide) and its mortar mask.
pub fn bricks(w: u32, h: u32) -> (Exemplar, FeatureMask) {
    let mortar = |x: u32, y: u32| mortar(x, y, 16, 10, 2);
    let ex = exemplar_from(w, h, |x, y| {
        let n = ((x.wrapping_mul(2654435761) ^ y.wrapping_mul(40503)).wrapping_mul(2246822519)
            >> 24) as f32
            / 255.0;
        if mortar(x, y) {
            [0.55 + 0.1 * n, 0.55 + 0.1 * n, 0.5 + 0.1 * n]
        } else {
            let row = y / 10;
            let xo = if row % 2 == 1 { 8 } else { 0 };
            let id = (x + xo) / 16 + 7 * row;
            let tone = ((id * 2654435761) >> 28) as f32 / 15.0;
            [
                0.35 + 0.3 * tone + 0.1 * n,
                0.2 + 0.1 * tone,
                0.15 + 0.05 * n,
            ]
        }
    });
    let inside = (0..h)
        .flat_map(|y| (0..w).map(move |x| mortar(x, y)))
        .collect();
    (ex, FeatureMask::new(w, h, inside).unwrap())
}

/// Writes a black-and-white mask PNG, white where `f` holds.
pub fn write_mask_png(path: &Path, w: u32, h: u32, f: impl Fn(u32, u32) -> bool) {
    image::GrayImage::from_fn(w, h, |x, y| image::Luma([if f(x, y) { 255 } else { 0 }]))
        .save(path)
        .unwrap();
}

/// Checks that an analysis failed with `InvalidParameter` naming every needle.
pub fn expect_invalid(r: texsyn::Result<Analysis>, needles: &[&str]) {
    match r {
        Err(Error::InvalidParameter(m)) => {
            for n in needles {
                assert!(m.contains(n), "message {m:?} lacks {n:?}");
            }
        }
        Err(e) => panic!("expected InvalidParameter {needles:?}, got {e:?}"),
        Ok(_) => panic!("expected an error {needles:?}, the analysis succeeded"),
    }
}
