//! Integration tests of `texsyn::quality`: texture energy, histograms, verbatim-copy
//! statistics, the report and its JSON form.

use texsyn::quality::{
    coarse_energy_any_phase, evaluate, histogram_distance, layout_repetition, multiscale_energy,
    shuffled_baseline, texture_energy, texture_energy_any, texture_energy_exact, verbatim_stats,
    CoordMap, FloatImage, DEFAULT_RADIUS,
};

struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
    fn below(&mut self, n: u32) -> u32 {
        (((self.next_u64() >> 32) * n as u64) >> 32) as u32
    }
}

/// A natural-looking colour texture: multi-octave value noise with per-channel tints.
fn value_noise(w: u32, h: u32, channels: u32, seed: u64) -> FloatImage {
    let mut rng = Rng(seed);
    let octaves: Vec<(u32, Vec<f32>)> = [4u32, 8, 16, 32]
        .iter()
        .map(|&cells| {
            (
                cells,
                (0..(cells + 1) * (cells + 1) * channels)
                    .map(|_| rng.f32())
                    .collect(),
            )
        })
        .collect();
    let mut data = Vec::with_capacity((w * h * channels) as usize);
    for y in 0..h {
        for x in 0..w {
            for c in 0..channels {
                let mut v = 0.0;
                let mut amp = 0.5;
                let mut total = 0.0;
                for (cells, grid) in &octaves {
                    let fx = x as f32 / w as f32 * *cells as f32;
                    let fy = y as f32 / h as f32 * *cells as f32;
                    let (ix, iy) = (fx as u32, fy as u32);
                    let (tx, ty) = (fx - ix as f32, fy - iy as f32);
                    let g =
                        |gx: u32, gy: u32| grid[((gy * (cells + 1) + gx) * channels + c) as usize];
                    let top = g(ix, iy) * (1.0 - tx) + g(ix + 1, iy) * tx;
                    let bottom = g(ix, iy + 1) * (1.0 - tx) + g(ix + 1, iy + 1) * tx;
                    v += amp * (top * (1.0 - ty) + bottom * ty);
                    total += amp;
                    amp *= 0.6;
                }
                data.push((v / total).clamp(0.0, 1.0));
            }
        }
    }
    FloatImage::new(w, h, channels, data).unwrap()
}

/// A synthetic "synthesized" output: random `patch x patch` blocks of the exemplar
/// pasted on a grid (verbatim regions with seams between them), with its coordinate map.
fn patchwork(
    ex: &FloatImage,
    w: u32,
    h: u32,
    patch: u32,
    seed: u64,
) -> (FloatImage, Vec<[i32; 2]>) {
    let mut rng = Rng(seed);
    let c = ex.channels as usize;
    let mut data = vec![0.0f32; (w * h) as usize * c];
    let mut coords = vec![[0i32; 2]; (w * h) as usize];
    for by in (0..h).step_by(patch as usize) {
        for bx in (0..w).step_by(patch as usize) {
            let ox = rng.below(ex.width - patch + 1);
            let oy = rng.below(ex.height - patch + 1);
            for y in by..(by + patch).min(h) {
                for x in bx..(bx + patch).min(w) {
                    let (sx, sy) = (ox + x - bx, oy + y - by);
                    let i = (y * w + x) as usize;
                    data[i * c..(i + 1) * c].copy_from_slice(ex.pixel(sx, sy));
                    coords[i] = [sx as i32, sy as i32];
                }
            }
        }
    }
    (FloatImage::new(w, h, ex.channels, data).unwrap(), coords)
}

#[test]
fn exemplar_against_itself_has_zero_energy() {
    for channels in [1, 3] {
        let ex = value_noise(64, 48, channels, 1);
        let e = texture_energy(&ex, &ex, 3).unwrap();
        assert!(e.abs() < 1e-12, "self energy {e}");
        let m = multiscale_energy(&ex, &ex, 3).unwrap();
        assert!(m.iter().all(|v| v.abs() < 1e-12), "{m:?}");
    }
}

/// A verbatim copy taken at an odd offset is made of exemplar windows at every scale, but
/// downsampling from its origin puts its 2x2 blocks across the exemplar's: the grid
/// figures see errors, the any-phase ones must not.
#[test]
fn coarse_energy_does_not_depend_on_the_copy_offset() {
    // Pixel-scale detail, where the downsampling grid matters most.
    let mut rng = Rng(40);
    let (w, h) = (96u32, 88u32);
    let noise: Vec<f32> = (0..w * h).map(|_| rng.f32()).collect();
    let ex = FloatImage::new(w, h, 1, noise).unwrap();
    for (dx, dy) in [(1, 0), (0, 1), (1, 1), (2, 3), (3, 2)] {
        let out = ex.crop(dx, dy, w - 4, h - 4).unwrap();
        let grid = multiscale_energy(&ex, &out, 3).unwrap();
        let [half, quarter] = coarse_energy_any_phase(&ex, &out, 3).unwrap();
        assert!(
            grid[0] < 1e-12,
            "full resolution: a verbatim copy, {grid:?}"
        );
        assert!(
            half < 1e-12 && quarter < 1e-12,
            "offset ({dx}, {dy}): {half} {quarter}"
        );
        // The grid figure sees the offset at half resolution when it is odd, at quarter
        // resolution whenever it is not a multiple of 4.
        if dx % 2 == 1 || dy % 2 == 1 {
            assert!(grid[1] > 1e-3, "offset ({dx}, {dy}): grid half {grid:?}");
        }
        assert!(grid[2] > 1e-3, "offset ({dx}, {dy}): grid quarter {grid:?}");
    }
    // An aligned copy scores zero both ways, and the any-phase figure is never above the
    // grid one (its exemplar windows include the grid's).
    let out = ex.crop(4, 8, w - 8, h - 16).unwrap();
    let grid = multiscale_energy(&ex, &out, 3).unwrap();
    assert!(grid.iter().all(|v| *v < 1e-12), "{grid:?}");
    let other = FloatImage::new(64, 64, 1, (0..64 * 64).map(|_| rng.f32()).collect()).unwrap();
    let grid = multiscale_energy(&ex, &other, 3).unwrap();
    let any = coarse_energy_any_phase(&ex, &other, 3).unwrap();
    assert!(
        any[0] > 0.0 && any[0] <= grid[1] && any[1] <= grid[2],
        "{grid:?} {any:?}"
    );
    // The union is the per-window minimum over its images.
    let e1 = texture_energy(&ex, &other, 3).unwrap();
    let both = texture_energy_any(&[ex.clone(), other.clone()], &other, 3).unwrap();
    assert!(both < 1e-12 && e1 > 0.0, "{both} {e1}");
    assert!(texture_energy_any(&[], &other, 3).is_err());
}

#[test]
fn tiled_copy_has_tiny_energy_and_shuffled_much_more() {
    // A periodic exemplar: its tiled copy consists of windows that all occur in it.
    let base = value_noise(16, 16, 3, 2);
    let ex = base.tiled(64, 64).unwrap();
    let tiled = base.tiled(200, 150).unwrap();
    let e_tiled = texture_energy(&ex, &tiled, 3).unwrap();
    assert!(
        e_tiled.abs() < 1e-12,
        "tiled periodic copy energy {e_tiled}"
    );

    // A non-periodic exemplar tiled 2x2: only the windows across the seams are new.
    let ex = value_noise(64, 64, 3, 3);
    let tiled = ex.tiled(128, 128).unwrap();
    let shuffled = shuffled_baseline(&ex, 128, 128, 7);
    let e_tiled = texture_energy(&ex, &tiled, 3).unwrap();
    let e_shuffled = texture_energy(&ex, &shuffled, 3).unwrap();
    let e_self = texture_energy(&ex, &ex, 3).unwrap();
    println!("energy: self {e_self:.3e}, tiled {e_tiled:.3e}, shuffled {e_shuffled:.3e}");
    assert!(
        e_tiled < 0.1 * e_shuffled,
        "tiled {e_tiled} vs shuffled {e_shuffled}"
    );
    assert!(e_shuffled > 1e-3);
    // Exact and fast agree on the seams too.
    let exact = texture_energy_exact(&ex, &tiled, 3).unwrap();
    assert!(
        e_tiled >= exact * (1.0 - 1e-5) && e_tiled <= exact * 1.03,
        "fast {e_tiled} exact {exact}"
    );
}

#[test]
fn fast_energy_matches_brute_force() {
    let ex = value_noise(48, 48, 3, 4);
    let (patchy, _) = patchwork(&ex, 80, 72, 12, 5);
    let other = value_noise(70, 64, 3, 6);
    let shuffled = shuffled_baseline(&ex, 60, 60, 8);
    for (name, out) in [
        ("patchwork", &patchy),
        ("other texture", &other),
        ("shuffled", &shuffled),
    ] {
        for r in [1, 3] {
            let fast = texture_energy(&ex, out, r).unwrap();
            let exact = texture_energy_exact(&ex, out, r).unwrap();
            println!(
                "{name} r={r}: fast {fast:.6e} exact {exact:.6e} ratio {:.5}",
                fast / exact
            );
            assert!(
                fast >= exact * (1.0 - 1e-5),
                "{name}: fast {fast} below exact {exact}"
            );
            assert!(fast <= exact * 1.03, "{name}: fast {fast} exact {exact}");
        }
    }
}

#[test]
fn channel_mismatch_replicates_grey() {
    let grey = value_noise(40, 40, 1, 9);
    let rgb = grey.to_rgb();
    assert_eq!(texture_energy(&grey, &rgb, 2).unwrap(), 0.0);
    assert_eq!(texture_energy(&rgb, &grey, 2).unwrap(), 0.0);
    assert!(histogram_distance(&grey, &rgb)
        .unwrap()
        .iter()
        .all(|&d| d == 0.0));
    // A colour exemplar against a grey output: colour loss is an error.
    let colour = value_noise(40, 40, 3, 10);
    assert!(texture_energy(&colour, &colour.to_grey(), 2).unwrap() > 1e-4);
}

#[test]
fn histogram_distance_properties() {
    let ex = value_noise(50, 40, 3, 11);
    let same = histogram_distance(&ex, &ex).unwrap();
    assert_eq!(same, vec![0.0; 3]);
    // Pixel order does not matter: a permutation has the same histogram.
    let mut flipped = ex.clone();
    flipped.data = ex.data.chunks_exact(3).rev().flatten().copied().collect();
    assert!(histogram_distance(&ex, &flipped)
        .unwrap()
        .iter()
        .all(|&d| d < 1e-12));
    let inverted = FloatImage {
        data: ex.data.iter().map(|v| 1.0 - v).collect(),
        ..ex.clone()
    };
    let d = histogram_distance(&ex, &inverted).unwrap();
    assert!(d.iter().all(|&v| v > 0.0 && v <= 1.0), "{d:?}");
    // Black against white is the maximum, 1.
    let black = FloatImage::new(4, 4, 1, vec![0.0; 16]).unwrap();
    let white = FloatImage::new(3, 5, 1, vec![1.0; 15]).unwrap();
    assert!((histogram_distance(&black, &white).unwrap()[0] - 1.0).abs() < 1e-12);
    // Half a step: all values 0 against all values 128/255.
    let mid = FloatImage::new(2, 2, 1, vec![128.0 / 255.0; 4]).unwrap();
    assert!((histogram_distance(&black, &mid).unwrap()[0] - 128.0 / 255.0).abs() < 1e-12);
}

fn identity(w: u32, h: u32, dx: i32, dy: i32) -> Vec<[i32; 2]> {
    (0..h)
        .flat_map(|y| (0..w).map(move |x| [x as i32 + dx, y as i32 + dy]))
        .collect()
}

#[test]
fn layout_repetition_finds_a_tiling_and_not_a_random_layout() {
    // The 32x32 exemplar tiled 4 x 3 times (wrapped coordinates, as a tileable
    // exemplar's): every pixel but the last period's recurs 32 pixels right and down.
    let (w, h) = (128u32, 96u32);
    let tiled: Vec<[i32; 2]> = (0..h)
        .flat_map(|y| (0..w).map(move |x| [(x % 32) as i32, (y % 32) as i32]))
        .collect();
    let r = layout_repetition(&tiled, w, h, 32, 32, true).unwrap();
    // Horizontal repeats: 96 of 128 columns have one 32 px to their right (3/4 of the
    // pixels); vertical: 64 of 96 rows (2/3). The fullest bin is the horizontal one.
    assert!((r.share - 0.75).abs() < 1e-12, "{r:?}");
    assert_eq!(r.vector, [32.0, 0.0]);
    // The same tiling, unwrapped coordinates of a non-tileable exemplar: identical
    // figure (the coordinates are already in range).
    assert_eq!(layout_repetition(&tiled, w, h, 32, 32, false).unwrap(), r);
    // Tiled with a shear (each period row shifted by 11): the vector follows it.
    let sheared: Vec<[i32; 2]> = (0..h)
        .flat_map(|y| (0..w).map(move |x| [((x + 11 * (y / 32)) % 32) as i32, (y % 32) as i32]))
        .collect();
    let s = layout_repetition(&sheared, w, h, 32, 32, true).unwrap();
    assert!((s.share - 0.75).abs() < 1e-12, "{s:?}");
    // Random coordinates of a 64x64 exemplar: a pixel's copy lies at a given
    // displacement with probability 1/4096, so an 8x8 bin holds about 64/4096 = 1.6%.
    let mut rng = Rng(7);
    let random: Vec<[i32; 2]> = (0..w * h)
        .map(|_| [rng.below(64) as i32, rng.below(64) as i32])
        .collect();
    let q = layout_repetition(&random, w, h, 64, 64, true).unwrap();
    assert!(q.share > 0.0 && q.share < 0.04, "{q:?}");
    // Every pixel distinct (an output no larger than the exemplar): nothing repeats.
    let id = identity(32, 24, 0, 0);
    let z = layout_repetition(&id, 32, 24, 32, 24, false).unwrap();
    assert_eq!((z.share, z.vector), (0.0, [0.0, 0.0]));
    // Copies closer than MIN_REPEAT_DISTANCE do not count: a 2-pixel period.
    let near: Vec<[i32; 2]> = (0..h)
        .flat_map(|y| (0..w).map(move |x| [(x % 2) as i32, (y % 2) as i32]))
        .collect();
    let n = layout_repetition(&near, w, h, 32, 32, false).unwrap();
    assert!(n.share > 0.9, "{n:?}"); // repeats at 24+ px exist too (every even shift)
    assert!(n.vector[0].hypot(n.vector[1]) >= 24.0, "{n:?}");
    // Deterministic; a large output is measured on its central 512x512 window.
    assert_eq!(layout_repetition(&random, w, h, 64, 64, true).unwrap(), q);
    let big: Vec<[i32; 2]> = (0..640u32 * 600)
        .map(|i| [((i % 640) % 32) as i32, ((i / 640) % 32) as i32])
        .collect();
    let b = layout_repetition(&big, 640, 600, 32, 32, true).unwrap();
    assert!((b.share - (1.0 - 32.0 / 512.0)).abs() < 1e-12, "{b:?}");
    // Beyond the pair budget a random sample of the pixels stands for all of them: an
    // 8x8 exemplar tiled over 512x512 (4096 copies of each pixel) and a map copying one
    // pixel everywhere both finish quickly, the first near its true figure (the copy 24
    // pixels on: 488/512 of the pixels).
    let fine: Vec<[i32; 2]> = (0..512u32 * 512)
        .map(|i| [((i % 512) % 8) as i32, ((i / 512) % 8) as i32])
        .collect();
    let f = layout_repetition(&fine, 512, 512, 8, 8, true).unwrap();
    assert!((f.share - 488.0 / 512.0).abs() < 0.05, "{f:?}");
    let one = vec![[3i32, 4]; 512 * 512];
    let o = layout_repetition(&one, 512, 512, 8, 8, true).unwrap();
    assert!(o.share.is_finite() && o.share > 1.0, "{o:?}");
    // Bad sizes are errors.
    assert!(layout_repetition(&tiled, w, h + 1, 32, 32, true).is_err());
    assert!(layout_repetition(&[], 0, 0, 32, 32, true).is_err());
    assert!(layout_repetition(&tiled, w, h, 0, 32, true).is_err());
}

#[test]
fn verbatim_identity_is_one_region() {
    let coords = identity(32, 24, 0, 0);
    let s = verbatim_stats(&coords, 32, 24, 32, 24, false).unwrap();
    assert_eq!(s.coherent_fraction, 1.0);
    assert_eq!(s.largest_region_pixels, 32 * 24);
    assert_eq!(s.largest_region_fraction, 1.0);
    assert_eq!(s.regions, 1);
}

#[test]
fn verbatim_four_quadrants() {
    // 16x16 output, quadrants of 8x8 copied from four different offsets.
    let (w, h) = (16u32, 16u32);
    let offsets = [[3, 5], [40, 2], [7, 30], [25, 25]];
    let coords: Vec<[i32; 2]> = (0..h)
        .flat_map(|y| {
            (0..w).map(move |x| {
                let q = (y / 8 * 2 + x / 8) as usize;
                [x as i32 + offsets[q][0], y as i32 + offsets[q][1]]
            })
        })
        .collect();
    let s = verbatim_stats(&coords, w, h, 64, 64, false).unwrap();
    assert_eq!(s.regions, 4);
    assert_eq!(s.largest_region_pixels, 64);
    assert!((s.largest_region_fraction - 64.0 / 4096.0).abs() < 1e-15);
    // Pairs: 2 * 16 * 15 = 480; incoherent: 16 across the vertical seam + 16 across the
    // horizontal one.
    assert!(
        (s.coherent_fraction - 448.0 / 480.0).abs() < 1e-12,
        "{}",
        s.coherent_fraction
    );
}

#[test]
fn verbatim_wraps_only_when_tileable() {
    // Copy from offset (20, 20) of a 32x32 exemplar: coordinates wrap at 32.
    let (w, h) = (24u32, 24u32);
    let coords: Vec<[i32; 2]> = (0..h)
        .flat_map(|y| (0..w).map(move |x| [(x as i32 + 20) % 32, (y as i32 + 20) % 32]))
        .collect();
    let t = verbatim_stats(&coords, w, h, 32, 32, true).unwrap();
    assert_eq!(t.coherent_fraction, 1.0);
    assert_eq!((t.regions, t.largest_region_pixels), (1, 576));
    let n = verbatim_stats(&coords, w, h, 32, 32, false).unwrap();
    // Not tileable: the wrap at x = 12 and y = 12 breaks coherence into 4 regions.
    assert_eq!(n.regions, 4);
    assert_eq!(n.largest_region_pixels, 12 * 12);
    assert!((n.coherent_fraction - (2.0 * 24.0 * 23.0 - 48.0) / (2.0 * 24.0 * 23.0)).abs() < 1e-12);
    // A region larger than a tileable exemplar (it repeats it).
    let big: Vec<[i32; 2]> = identity(64, 64, 0, 0);
    let s = verbatim_stats(&big, 64, 64, 32, 32, true).unwrap();
    assert_eq!(s.largest_region_fraction, 4.0);
    // Negative coordinates wrap too.
    let neg = identity(8, 8, -40, -3);
    assert_eq!(verbatim_stats(&neg, 8, 8, 32, 32, true).unwrap().regions, 1);
    // Extreme values do not overflow.
    let ext = vec![[i32::MAX, i32::MIN], [i32::MIN, i32::MIN]];
    assert_eq!(
        verbatim_stats(&ext, 2, 1, 32, 32, false)
            .unwrap()
            .coherent_fraction,
        0.0
    );
    assert_eq!(
        verbatim_stats(&ext, 2, 1, 32, 32, true)
            .unwrap()
            .coherent_fraction,
        1.0
    );
}

#[test]
fn unusable_inputs_are_errors_not_panics() {
    let ex = value_noise(32, 32, 3, 12);
    let tiny = value_noise(6, 40, 3, 13);
    assert!(texture_energy(&ex, &tiny, 3).is_err());
    assert!(texture_energy(&tiny, &ex, 3).is_err());
    assert!(texture_energy_exact(&ex, &tiny, 3).is_err());
    assert!(multiscale_energy(&ex, &tiny, 3).is_err());
    assert!(texture_energy(&ex, &ex, u32::MAX).is_err());
    let msg = texture_energy(&ex, &tiny, 3).unwrap_err().to_string();
    assert!(msg.contains("7x7"), "{msg}");
    // Exactly the window size works (one window).
    let seven = ex.crop(3, 4, 7, 7).unwrap();
    assert_eq!(texture_energy(&ex, &seven, 3).unwrap(), 0.0);
    let empty = FloatImage {
        width: 0,
        height: 0,
        channels: 3,
        data: vec![],
    };
    assert!(texture_energy(&ex, &empty, 1).is_err());
    assert!(histogram_distance(&ex, &empty).is_err());
    let bad = FloatImage {
        width: 8,
        height: 8,
        channels: 4,
        data: vec![0.0; 256],
    };
    assert!(histogram_distance(&ex, &bad).is_err());
    let short = FloatImage {
        width: 8,
        height: 8,
        channels: 3,
        data: vec![0.0; 10],
    };
    assert!(texture_energy(&ex, &short, 1).is_err());
    assert!(verbatim_stats(&[], 0, 0, 32, 32, false).is_err());
    assert!(verbatim_stats(&[[0, 0]; 3], 2, 2, 32, 32, false).is_err());
    assert!(verbatim_stats(&[[0, 0]; 4], 2, 2, 0, 32, false).is_err());
    // 1x1 map: no pairs.
    let one = verbatim_stats(&[[5, 5]], 1, 1, 32, 32, false).unwrap();
    assert_eq!(
        (
            one.coherent_fraction,
            one.largest_region_pixels,
            one.regions
        ),
        (0.0, 1, 1)
    );
    assert!(ex.crop(30, 0, 4, 4).is_err());
    // The baseline of an unusable exemplar is black, not a panic; empty sizes work.
    assert_eq!(shuffled_baseline(&empty, 2, 2, 1).data, vec![0.0; 12]);
    assert!(shuffled_baseline(&ex, 0, 5, 1).data.is_empty());
    // Downsampling odd and degenerate sizes.
    let odd = value_noise(7, 3, 1, 14).downsample2();
    assert_eq!((odd.width, odd.height), (3, 1));
}

#[test]
fn multiscale_reports_nan_for_scales_too_small() {
    let ex = value_noise(20, 20, 3, 15);
    let out = value_noise(30, 30, 3, 16);
    let m = multiscale_energy(&ex, &out, 3).unwrap();
    assert!(m[0].is_finite() && m[0] > 0.0);
    assert!(m[1].is_finite()); // 10x10 and 15x15
    assert!(m[2].is_nan()); // 5x5 < 7x7
    let report = evaluate(&ex, &out, 3, None).unwrap();
    let json = report.to_json();
    assert!(json.contains("\"quarter\":null"), "{json}");
    assert!(json.contains("\"verbatim\":null"), "{json}");
}

#[test]
fn shuffled_baseline_is_deterministic_and_draws_exemplar_pixels() {
    let ex = value_noise(16, 16, 3, 17);
    let a = shuffled_baseline(&ex, 40, 30, 99);
    assert_eq!(a, shuffled_baseline(&ex, 40, 30, 99));
    assert_ne!(a, shuffled_baseline(&ex, 40, 30, 100));
    assert_eq!((a.width, a.height, a.channels), (40, 30, 3));
    for px in a.data.chunks_exact(3) {
        assert!(ex.data.chunks_exact(3).any(|q| q == px));
    }
}

#[test]
fn report_and_json() {
    let ex = value_noise(48, 48, 3, 18);
    let (out, coords) = patchwork(&ex, 64, 64, 16, 19);
    let map = CoordMap {
        coords: &coords,
        width: 64,
        height: 64,
        tileable: false,
    };
    let r = evaluate(&ex, &out, DEFAULT_RADIUS, Some(map)).unwrap();
    let v = r.verbatim.unwrap();
    assert_eq!(v.largest_region_pixels, 256);
    assert_eq!(v.regions, 16);
    assert!(r.energy[0] > 0.0 && r.energy[0] < 0.05);
    // The report's grid figures are multiscale_energy's, its any-phase ones
    // coarse_energy_any_phase's (evaluate shares their offset-(0, 0) searches).
    assert_eq!(
        r.energy,
        multiscale_energy(&ex, &out, DEFAULT_RADIUS).unwrap()
    );
    let any = coarse_energy_any_phase(&ex, &out, DEFAULT_RADIUS).unwrap();
    assert_eq!(r.energy_any_phase, [r.energy[0], any[0], any[1]]);
    assert_eq!(r.histogram.len(), 3);
    assert!((r.histogram_mean - r.histogram.iter().sum::<f64>() / 3.0).abs() < 1e-15);
    let json = r.to_json();
    println!("{json}");
    for key in [
        "\"texture_energy\":{\"full\":",
        "\"texture_energy_any_phase\":{\"full\":",
        "\"half\":",
        "\"quarter\":",
        "\"histogram_emd\":{\"per_channel\":[",
        "\"mean\":",
        "\"verbatim\":{\"coherent_fraction\":",
        "\"largest_region_fraction\":",
        "\"largest_region_pixels\":256",
        "\"regions\":16",
        "\"repetition\":{\"share\":",
        "\"vector\":[",
        "\"radius\":3",
    ] {
        assert!(json.contains(key), "{key} missing in {json}");
    }
    assert_eq!(json.matches('{').count(), json.matches('}').count());
    assert!(!json.contains("NaN") && !json.contains("inf"));
}

#[test]
fn from_dynamic_keeps_precision_and_drops_alpha() {
    let g16 = image::ImageBuffer::<image::Luma<u16>, _>::from_fn(3, 2, |x, y| {
        image::Luma([(x * 1000 + y * 7) as u16])
    });
    let f = FloatImage::from_dynamic(&image::DynamicImage::ImageLuma16(g16));
    assert_eq!((f.width, f.height, f.channels), (3, 2, 1));
    assert!((f.pixel(2, 1)[0] - 2007.0 / 65535.0).abs() < 1e-7);
    let rgba = image::RgbaImage::from_fn(2, 2, |x, _| image::Rgba([255, x as u8 * 100, 0, 7]));
    let f = FloatImage::from_dynamic(&image::DynamicImage::ImageRgba8(rgba));
    assert_eq!(f.channels, 3);
    assert_eq!(f.pixel(1, 0), &[1.0, 100.0 / 255.0, 0.0]);
    let la = image::GrayAlphaImage::from_pixel(2, 2, image::LumaA([51, 0]));
    let f = FloatImage::from_dynamic(&image::DynamicImage::ImageLumaA8(la));
    assert_eq!((f.channels, f.data[0]), (1, 0.2));
    let colors = [[255u8, 0, 51, 9]; 4];
    let f = FloatImage::from_rgba8(2, 2, &colors).unwrap();
    assert_eq!(f.pixel(1, 1), &[1.0, 0.0, 0.2]);
    assert!(FloatImage::from_rgba8(3, 2, &colors).is_err());
}

/// A 512x512 output against a 128x128 exemplar (r = 3): a patchwork of the exemplar
/// scores far below a shuffled baseline, and the fast energy is an upper bound within 3%
/// of brute force on a crop where that is affordable.
#[test]
fn patchwork_energy_is_far_below_a_shuffle_and_bounds_brute_force() {
    let ex = value_noise(128, 128, 3, 20);
    let (out, _) = patchwork(&ex, 512, 512, 24, 21);
    let shuffled = shuffled_baseline(&ex, 512, 512, 22);
    let mut energies = Vec::new();
    for (name, img) in [("patchwork", &out), ("shuffled", &shuffled)] {
        let e = texture_energy(&ex, img, 3).unwrap();
        println!("texture_energy 512x512 vs 128x128 r=3 ({name}): {e:.6e}");
        energies.push(e);
    }
    assert!(energies[0] < 0.5 * energies[1], "{energies:?}");
    let m = multiscale_energy(&ex, &out, 3).unwrap();
    println!("multiscale_energy (patchwork): {m:?}");
    let crop = out.crop(100, 200, 40, 40).unwrap();
    let exact = texture_energy_exact(&ex, &crop, 3).unwrap();
    let fast = texture_energy(&ex, &crop, 3).unwrap();
    println!(
        "40x40 crop: fast {fast:.6e} exact {exact:.6e} (ratio {:.5})",
        fast / exact
    );
    assert!(
        fast >= exact * (1.0 - 1e-5) && fast <= exact * 1.03,
        "{fast} vs {exact}"
    );
}

/// The temporal figures: a flat exemplar has no sharpness to compare with (NaN, not a
/// huge number), a sequence that starts later is labelled with its own frame numbers,
/// and frames that change channel count say so.
#[test]
fn temporal_figures_edge_cases() {
    use texsyn::quality::TemporalFigures;
    let flat = FloatImage::new(16, 16, 1, vec![0.5; 256]).unwrap();
    let frame = value_noise(16, 16, 1, 3);
    let mut f = TemporalFigures::new(&flat, 1);
    f.push(frame.clone(), &[]).unwrap();
    let r = f.finish().unwrap();
    assert!(r.sharpness.iter().all(|s| s.is_nan()), "{:?}", r.sharpness);

    let ex = value_noise(24, 24, 1, 4);
    let mut f = TemporalFigures::new(&ex, 2).starting_at(3);
    for _ in 0..3 {
        f.push(frame.clone(), &[]).unwrap();
    }
    let r = f.finish().unwrap();
    let labels: Vec<usize> = r.energy.iter().map(|e| e.0).collect();
    assert_eq!(labels, vec![3, 4, 5]);

    let mut f = TemporalFigures::new(&ex, 1);
    f.push(frame.clone(), &[]).unwrap();
    let e = f.push(frame.to_rgb(), &[]).unwrap_err().to_string();
    assert!(e.contains("all grey or all colour"), "{e}");
}
