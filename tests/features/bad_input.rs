//! Bad masks and weights are errors (library), constant masks analyse cleanly.

use texsyn::analysis::feature::DEFAULT_SETS_FEATURE_WEIGHT;
use texsyn::analysis::{analyze, AnalysisOptions, FeatureMask};
use texsyn::Error;

use crate::common::TempDir;
use crate::helpers::*;

#[test]
fn bad_masks_and_weights_are_errors() {
    let (ex, mask) = bricks(32, 24);
    let opts = |mask: Option<FeatureMask>, w: f32, clamp: f32| AnalysisOptions {
        feature_mask: mask,
        feature_weight: Some(w),
        feature_clamp: clamp,
        ..Default::default()
    };
    // A mask of another size.
    let small = FeatureMask::new(16, 24, vec![false; 16 * 24]).unwrap();
    expect_invalid(
        analyze(&ex, &opts(Some(small), 1.0, 8.0), |_| {}),
        &[
            "feature mask is 16x24",
            "exemplar is 32x24",
            "exemplar's size",
        ],
    );
    // Weights: NaN, negative, infinite, too large.
    for w in [f32::NAN, -0.5, f32::INFINITY, 1000.0] {
        expect_invalid(
            analyze(&ex, &opts(Some(mask.clone()), w, 8.0), |_| {}),
            &["feature weight", "[0, 100]"],
        );
    }
    for c in [0.0, f32::NAN, -3.0, 1e9] {
        expect_invalid(
            analyze(&ex, &opts(Some(mask.clone()), 1.0, c), |_| {}),
            &["feature distance clamp"],
        );
    }
    // Flags that do not match the size.
    assert!(matches!(
        FeatureMask::new(4, 4, vec![true; 15]),
        Err(Error::InvalidParameter(_))
    ));

    // Files: missing is an I/O error, garbage is not an image; both name the file.
    let dir = TempDir::new("badmask");
    let missing = dir.path("missing.png");
    match FeatureMask::load(&missing) {
        Err(Error::Io { path, .. }) => assert_eq!(path, missing),
        other => panic!("expected Io, got {other:?}"),
    }
    let garbage = dir.path("garbage.png");
    std::fs::write(&garbage, b"not an image at all").unwrap();
    match FeatureMask::load(&garbage) {
        Err(Error::BadImage { path, .. }) => assert_eq!(path, garbage),
        other => panic!("expected BadImage, got {other:?}"),
    }
    // A loaded mask of the wrong size names its file.
    let file = dir.path("small.png");
    write_mask_png(&file, 20, 24, |x, _| x < 3);
    let loaded = FeatureMask::load(&file).unwrap();
    expect_invalid(
        analyze(&ex, &opts(Some(loaded), 1.0, 8.0), |_| {}),
        &["small.png is 20x24"],
    );
}

#[test]
fn constant_masks_analyse_cleanly() {
    let (ex, _) = bricks(40, 32);
    let plain = analyze(&ex, &AnalysisOptions::default(), |_| {}).unwrap();
    for flag in [false, true] {
        let opts = AnalysisOptions {
            feature_mask: Some(FeatureMask::new(40, 32, vec![flag; 40 * 32]).unwrap()),
            ..Default::default()
        };
        let a = analyze(&ex, &opts, |_| {}).unwrap();
        let f = a.feature.expect("the mask is recorded");
        assert_eq!(f.coverage, flag as u8 as f32);
        assert_eq!(f.weight, DEFAULT_SETS_FEATURE_WEIGHT);
        // Level 0 has no tables (never corrected).
        for (l, p) in a.levels.iter().zip(&plain.levels).skip(1) {
            assert!(l.residual_variance.is_finite() && l.runtime_residual_variance.is_finite());
            // A zero channel changes nothing the synthesis sees but rounding.
            let max_diff =
                l.et.iter()
                    .zip(&p.et)
                    .flat_map(|(a, b)| a.iter().zip(b).map(|(x, y)| (x - y).abs()))
                    .max()
                    .unwrap();
            assert!(
                max_diff <= 2,
                "level {}: Et differs by {max_diff}",
                l.spacing
            );
        }
    }
}
