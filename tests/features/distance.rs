//! The signed-distance transform against brute force, the feature channel's scale, masks
//! read from images.

use texsyn::analysis::feature::{
    feature_channel, signed_distance, squared_distance_transform, DEFAULT_FEATURE_CLAMP,
};
use texsyn::analysis::FeatureMask;

use crate::helpers::*;

#[test]
fn distance_transform_matches_brute_force() {
    let mut rng = Lcg(7);
    for (w, h) in [(1, 1), (1, 9), (9, 1), (5, 7), (16, 16), (23, 17), (31, 8)] {
        for density in [0u32, 1, 5, 30, 100] {
            for wrap in [false, true] {
                let sites: Vec<bool> = (0..w * h)
                    .map(|_| match density {
                        0 => false,
                        100 => true,
                        d => rng.next() % 100 < d,
                    })
                    .collect();
                let fast = squared_distance_transform(&sites, w as u32, h as u32, wrap);
                let slow = brute_force(&sites, w, h, wrap);
                assert_eq!(fast, slow, "{w}x{h}, density {density}%, wrap {wrap}");
            }
        }
    }
    // A single site: exact distances in the corner, and wrap-around.
    let mut sites = vec![false; 10 * 6];
    sites[0] = true;
    let d = squared_distance_transform(&sites, 10, 6, false);
    assert_eq!(d[5 * 10 + 9], 81.0 + 25.0);
    let d = squared_distance_transform(&sites, 10, 6, true);
    assert_eq!(d[5 * 10 + 9], 1.0 + 1.0);
}

#[test]
fn signed_distance_is_positive_inside_and_wraps() {
    // A vertical band, columns 5..=7 of a 16x4 image.
    let inside: Vec<bool> = (0..4)
        .flat_map(|_| (0..16).map(|x| (5..=7).contains(&x)))
        .collect();
    let mask = FeatureMask::new(16, 4, inside).unwrap();
    let d = signed_distance(&mask, false);
    let row: Vec<f32> = d[..16].to_vec();
    assert_eq!(row[5], 0.5);
    assert_eq!(row[6], 1.5);
    assert_eq!(row[7], 0.5);
    assert_eq!(row[4], -0.5);
    assert_eq!(row[0], -4.5);
    assert_eq!(row[15], -7.5);
    // Wrapping: column 15 is 6 columns from column 5 across the border.
    let d = signed_distance(&mask, true);
    assert_eq!(d[15], -5.5);
    assert_eq!(d[0], -4.5);
    // Every row is the same.
    assert!(d.chunks(16).all(|r| r == &d[..16]));
    // Constant masks: infinite distances, clamped later.
    let all = FeatureMask::new(16, 4, vec![true; 64]).unwrap();
    assert!(signed_distance(&all, false)
        .iter()
        .all(|&v| v == f32::INFINITY));
    let none = FeatureMask::new(16, 4, vec![false; 64]).unwrap();
    assert!(signed_distance(&none, true)
        .iter()
        .all(|&v| v == f32::NEG_INFINITY));
}

#[test]
fn feature_channel_scale_and_constant_masks() {
    let (ex, mask) = bricks(48, 40);
    let var = |v: &[f32], stride: usize, offset: usize| {
        let vals: Vec<f64> = v
            .iter()
            .skip(offset)
            .step_by(stride)
            .map(|&x| x as f64)
            .collect();
        let m = vals.iter().sum::<f64>() / vals.len() as f64;
        (
            m,
            vals.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / vals.len() as f64,
        )
    };
    let colour_var: f64 = (0..3).map(|c| var(&ex.values, 3, c).1).sum();
    for w in [0.5f32, 1.0, 3.0] {
        let f = feature_channel(&mask, w, DEFAULT_FEATURE_CLAMP, &ex.values, 3, true);
        assert_eq!(f.len(), 48 * 40);
        let (m, v) = var(&f, 1, 0);
        assert!(m.abs() < 1e-5, "the channel is centred ({m})");
        let ratio = v / (w as f64 * w as f64 * colour_var);
        assert!(
            (ratio - 1.0).abs() < 1e-3,
            "w = {w}: variance ratio {ratio}"
        );
    }
    // Constant masks carry nothing: a zero channel, no NaN.
    for flag in [false, true] {
        let m = FeatureMask::new(48, 40, vec![flag; 48 * 40]).unwrap();
        let f = feature_channel(&m, 2.0, 4.0, &ex.values, 3, false);
        assert!(f.iter().all(|&v| v == 0.0));
    }
    // A constant exemplar does not divide by zero either.
    let grey = vec![0.5f32; 48 * 40];
    let f = feature_channel(&mask, 1.0, 8.0, &grey, 1, false);
    assert!(f.iter().all(|v| v.is_finite()) && f.iter().any(|&v| v != 0.0));
}

#[test]
fn mask_from_image_thresholds_at_the_midpoint() {
    // 0 / 255, 0 / 1 (a "nonzero" mask), anti-aliased and RGB masks.
    let img = |f: &dyn Fn(u32, u32) -> u8| {
        image::DynamicImage::ImageLuma8(image::GrayImage::from_fn(8, 4, |x, y| {
            image::Luma([f(x, y)])
        }))
    };
    let expect: Vec<bool> = (0..4).flat_map(|_| (0..8).map(|x| x >= 5)).collect();
    for (lo, hi) in [(0u8, 255u8), (0, 1), (20, 200)] {
        let m = FeatureMask::from_image(&img(&|x, _| if x >= 5 { hi } else { lo }));
        assert_eq!((m.width, m.height), (8, 4));
        assert_eq!(m.inside, expect, "values {lo}/{hi}");
    }
    let rgb = image::DynamicImage::ImageRgb8(image::RgbImage::from_fn(8, 4, |x, _| {
        image::Rgb(if x >= 5 { [255, 0, 0] } else { [0, 0, 0] })
    }));
    assert_eq!(FeatureMask::from_image(&rgb).inside, expect);
    // Constant images: nonzero is all feature, zero is none.
    assert!(FeatureMask::from_image(&img(&|_, _| 7))
        .inside
        .iter()
        .all(|&b| b));
    assert!(FeatureMask::from_image(&img(&|_, _| 0))
        .inside
        .iter()
        .all(|&b| !b));
    assert!((FeatureMask::from_image(&img(&|x, _| (x >= 6) as u8)).coverage() - 0.25).abs() < 1e-9);
}
