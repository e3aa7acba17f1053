//! The choice of appearance space (colour, sets, both) and the analysis file that keeps it.

use texsyn::analysis::{
    analyze, Analysis, AnalysisOptions, AppearanceSpace, FeatureMask, FeatureMode, DIM,
};
use texsyn::Error;

use crate::common::TempDir;
use crate::helpers::*;

#[test]
fn color_space_uses_only_the_colour_dimensions() {
    let (ex, mask) = bricks(40, 32);
    let used = |a: &Analysis| {
        // Number of leading Et components that are nonzero somewhere, per level.
        a.levels
            .iter()
            .map(|l| {
                (0..DIM)
                    .filter(|&c| l.et.iter().any(|e| e[c] != 0))
                    .max()
                    .map_or(0, |c| c + 1)
            })
            .max()
            .unwrap()
    };
    let run = |appearance, mask: Option<FeatureMask>| {
        let opts = AnalysisOptions {
            appearance,
            feature_mask: mask,
            tileable: Some(true),
            ..Default::default()
        };
        analyze(&ex, &opts, |_| {}).unwrap()
    };
    let colour = run(AppearanceSpace::Color, None);
    assert_eq!(colour.appearance, AppearanceSpace::Color);
    assert!(used(&colour) <= 3, "RGB gives at most 3 components");
    assert!(colour.levels.iter().all(|l| l.residual_variance < 1e-6));
    let colour_feature = run(AppearanceSpace::Color, Some(mask.clone()));
    assert!(used(&colour_feature) <= 4, "RGB + feature gives at most 4");
    let neighbourhood = run(AppearanceSpace::Neighborhood, Some(mask));
    assert_eq!(used(&neighbourhood), DIM);
    // The runtime is the same: same level sizes, same k.
    for (a, b) in colour.levels.iter().zip(&neighbourhood.levels) {
        assert_eq!(a.et.len(), b.et.len());
        assert_eq!(a.offsets.len(), b.offsets.len());
    }
    assert_eq!(
        "colour".parse::<AppearanceSpace>().unwrap(),
        AppearanceSpace::Color
    );
    assert_eq!(
        "Neighborhood".parse::<AppearanceSpace>().unwrap(),
        AppearanceSpace::Neighborhood
    );
    assert!(matches!(
        "rgb".parse::<AppearanceSpace>(),
        Err(Error::InvalidParameter(_))
    ));
}

/// FeatureMode::Sets: the synthesis's tables are exactly those of the colours alone, the
/// similarity sets are searched with the feature channel (so they differ), and the mode
/// is recorded.
#[test]
fn sets_mode_keeps_the_colour_tables_and_moves_the_sets() {
    let (ex, mask) = bricks(48, 40);
    let run = |mask: Option<FeatureMask>, mode: FeatureMode| {
        let opts = AnalysisOptions {
            feature_mask: mask,
            feature_weight: Some(16.0),
            feature_mode: mode,
            tileable: Some(true),
            ..Default::default()
        };
        analyze(&ex, &opts, |_| {}).unwrap()
    };
    let plain = run(None, FeatureMode::Sets);
    let sets = run(Some(mask.clone()), FeatureMode::Sets);
    let appearance = run(Some(mask), FeatureMode::Appearance);
    assert_eq!(plain.feature, None);
    assert_eq!(sets.feature.map(|f| f.mode), Some(FeatureMode::Sets));
    assert_eq!(
        appearance.feature.map(|f| f.mode),
        Some(FeatureMode::Appearance)
    );
    let mut moved = 0;
    for (l, (p, s)) in plain.levels.iter().zip(&sets.levels).enumerate() {
        assert_eq!(
            (&p.et, &p.proj, &p.qe, p.shift),
            (&s.et, &s.proj, &s.qe, s.shift),
            "level {l}"
        );
        assert_eq!(p.residual_variance, s.residual_variance);
        moved += p
            .offsets
            .iter()
            .zip(&s.offsets)
            .filter(|(a, b)| a != b)
            .count();
    }
    assert!(moved > 0, "the feature channel changed no similarity set");
    // The paper's mode changes the tables themselves.
    assert!(plain
        .levels
        .iter()
        .zip(&appearance.levels)
        .any(|(p, a)| p.et != a.et));
    assert_eq!("Sets".parse::<FeatureMode>().unwrap(), FeatureMode::Sets);
    assert_eq!("both".parse::<FeatureMode>().unwrap(), FeatureMode::Both);
    assert!(matches!(
        "paper".parse::<FeatureMode>(),
        Err(Error::InvalidParameter(_))
    ));
}

/// FeatureMode::Both (the default): the similarity sets are exactly those of `Sets` at
/// the same weight, and the synthesis's tables exactly those of `Appearance` at
/// `BOTH_APPEARANCE_SHARE` of it; the default weight is 16.
#[test]
fn both_mode_takes_the_sets_of_sets_and_the_tables_of_a_light_channel() {
    let (ex, mask) = bricks(48, 40);
    let run = |mode: FeatureMode, w: Option<f32>| {
        let opts = AnalysisOptions {
            feature_mask: Some(mask.clone()),
            feature_weight: w,
            feature_mode: mode,
            tileable: Some(true),
            ..Default::default()
        };
        analyze(&ex, &opts, |_| {}).unwrap()
    };
    assert_eq!(AnalysisOptions::default().feature_mode, FeatureMode::Both);
    let both = run(FeatureMode::Both, None);
    let sets = run(FeatureMode::Sets, Some(16.0));
    let light = run(
        FeatureMode::Appearance,
        Some(16.0 * texsyn::analysis::feature::BOTH_APPEARANCE_SHARE),
    );
    let f = both.feature.unwrap();
    assert_eq!((f.mode, f.weight), (FeatureMode::Both, 16.0));
    for (l, ((b, s), a)) in both
        .levels
        .iter()
        .zip(&sets.levels)
        .zip(&light.levels)
        .enumerate()
    {
        assert_eq!(b.offsets, s.offsets, "level {l}: sets");
        assert_eq!(
            (&b.et, &b.proj, &b.qe, b.shift, b.residual_variance),
            (&a.et, &a.proj, &a.qe, a.shift, a.residual_variance),
            "level {l}: tables"
        );
    }
    // And neither is the other mode's: the light channel moves the tables, the full
    // weight the sets.
    assert!(both
        .levels
        .iter()
        .zip(&sets.levels)
        .any(|(b, s)| b.et != s.et));
    assert!(both
        .levels
        .iter()
        .zip(&light.levels)
        .any(|(b, a)| b.offsets != a.offsets));
}

#[test]
fn analysis_file_keeps_the_appearance_settings() {
    let (ex, mask) = bricks(32, 32);
    let dir = TempDir::new("file");
    for (appearance, mask) in [
        (AppearanceSpace::Neighborhood, None),
        (AppearanceSpace::Color, Some(mask.clone())),
        (AppearanceSpace::Neighborhood, Some(mask)),
    ] {
        let opts = AnalysisOptions {
            appearance,
            feature_weight: Some(2.5),
            feature_clamp: 3.0,
            feature_mask: mask.clone(),
            ..Default::default()
        };
        let a = analyze(&ex, &opts, |_| {}).unwrap();
        assert_eq!(a.appearance, appearance);
        match (&a.feature, &mask) {
            (None, None) => {}
            (Some(f), Some(m)) => {
                assert_eq!((f.weight, f.clamp), (2.5, 3.0));
                assert!((f.coverage as f64 - m.coverage()).abs() < 1e-6);
            }
            other => panic!("feature info {other:?}"),
        }
        let path = dir.path("a.tsa");
        a.save(&path).unwrap();
        assert_eq!(Analysis::load(&path).unwrap(), a);
    }
}
