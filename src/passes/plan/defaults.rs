//! Per-level defaults derived from the exemplar: jitter randomness and correction passes.

use super::SynthParams;
use crate::analysis::Analysis;

/// Default jitter randomness of `level` (`finest` = the finest level's index): a whole
/// pixel at the coarse levels, so features are rearranged rather than the exemplar's
/// layout reproduced, none at the finest levels, so exemplar detail stays intact. The
/// larger the exemplar (its shorter side), the more fine levels stay still, since a
/// coherent patch of fixed pixel size covers less of it and seams multiply:
/// - under 80: 0 on the finest, 1 above;
/// - 80..128: 0 on the two finest, 0.5 on the third, 1 above;
/// - 128..176: 0 on the three finest, 0.75 on the fourth, 1 above;
/// - 176..288: 0 on the three finest, 0.25 on the fourth, 1 above;
/// - 288..448: 0 on the four finest, 0.25 on the fifth, 1 above;
/// - 448 and up: 0 on the five finest, 0.75 on the sixth, 1 above.
///
/// `extra_still` more levels are still (the partly jittered level moves up with them),
/// as [`SynthParams::extra_still_levels`] asks.
pub fn default_randomness(
    level: u32,
    finest: u32,
    exemplar_min_side: u32,
    extra_still: u32,
) -> f32 {
    let from_finest = finest.saturating_sub(level);
    let (still, partial) = match exemplar_min_side {
        0..80 => (1, None),
        80..128 => (2, Some((2, 0.5))),
        128..176 => (3, Some((3, 0.75))),
        176..288 => (3, Some((3, 0.25))),
        288..448 => (4, Some((4, 0.25))),
        _ => (5, Some((5, 0.75))),
    };
    let still = still + extra_still;
    let partial = partial.map(|(l, r)| (l + extra_still, r));
    match partial {
        _ if from_finest < still => 0.0,
        Some((l, r)) if l == from_finest => r,
        _ => 1.0,
    }
}

/// At most this many correction passes at the second-finest level of an isometric
/// synthesis from a large exemplar ([`crate::analysis::LARGE_EXEMPLAR_PIXELS`]): that
/// level is the costliest corrected one, and fewer passes there cost little quality.
pub const LARGE_SECOND_FINEST_PASSES: u32 = 2;

/// At most this many at the second-finest level from a smaller exemplar, also along a
/// field (not on surfaces or with a feature channel): about half the synthesis's GPU time
/// went there with four passes, for little difference in quality.
pub const SMALL_SECOND_FINEST_PASSES: u32 = 3;

/// At most this many correction passes on a level without similarity sets of its own
/// ([`crate::analysis::level_searched`]: its neighbourhood spans the exemplar). Its only
/// candidates are the coherent ones on a near-constant blur, which two passes settle, and
/// its exact-window margin halves with the passes. Not with a feature channel, whose
/// coarse passes arrange the features.
pub const UNSEARCHED_PASSES: u32 = 2;

/// What [`passes_at`] needs to know of the exemplar.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExemplarShape {
    /// Exemplar width in pixels.
    pub width: u32,
    /// Exemplar height in pixels.
    pub height: u32,
    /// The analysis has a feature channel ([`Analysis::feature`]).
    pub feature: bool,
}

impl ExemplarShape {
    /// The shape of an analysed exemplar.
    pub fn of(analysis: &Analysis) -> Self {
        Self {
            width: analysis.width,
            height: analysis.height,
            feature: analysis.feature.is_some(),
        }
    }
}

/// Correction passes at `level` (`last` = the finest).
pub fn passes_at(params: &SynthParams, level: u32, last: u32, exemplar: ExemplarShape) -> u32 {
    if level == last {
        return params.finest_passes;
    }
    let passes = if level + 1 == last {
        params.second_finest_passes.unwrap_or_else(|| {
            default_second_finest_passes(
                params.passes,
                params.anisometric(),
                params.surface.is_some(),
                exemplar,
            )
        })
    } else {
        params.passes
    };
    let spacing = 1 << (last - level);
    if exemplar.feature || crate::analysis::level_searched(exemplar.width, exemplar.height, spacing)
    {
        passes
    } else {
        passes.min(UNSEARCHED_PASSES)
    }
}

/// The second-finest level's passes when [`SynthParams::second_finest_passes`] is `None`
/// (`anisometric`: along a field or on a surface; `surface`: atlas synthesis): `passes`,
/// capped at [`LARGE_SECOND_FINEST_PASSES`] for an isometric synthesis from a large
/// exemplar and at [`SMALL_SECOND_FINEST_PASSES`] from a smaller one without a feature
/// channel; surfaces keep `passes`.
pub fn default_second_finest_passes(
    passes: u32,
    anisometric: bool,
    surface: bool,
    exemplar: ExemplarShape,
) -> u32 {
    let pixels = exemplar.width as u64 * exemplar.height as u64;
    if surface {
        passes
    } else if pixels >= crate::analysis::LARGE_EXEMPLAR_PIXELS {
        if anisometric {
            passes
        } else {
            passes.min(LARGE_SECOND_FINEST_PASSES)
        }
    } else if exemplar.feature {
        passes
    } else {
        passes.min(SMALL_SECOND_FINEST_PASSES)
    }
}

#[cfg(test)]
mod tests {
    use super::{
        default_randomness, passes_at, ExemplarShape, SynthParams, LARGE_SECOND_FINEST_PASSES,
        SMALL_SECOND_FINEST_PASSES, UNSEARCHED_PASSES,
    };
    use crate::analysis::LARGE_EXEMPLAR_PIXELS;
    use crate::field::Field;

    #[test]
    fn large_isometric_syntheses_correct_the_second_finest_level_less() {
        // Exemplar sizes just at and just under LARGE_EXEMPLAR_PIXELS.
        assert_eq!(LARGE_EXEMPLAR_PIXELS, 256 * 256);
        let shape = |width, height| ExemplarShape {
            width,
            height,
            feature: false,
        };
        let (large, small) = (shape(256, 256), shape(255, 256));
        let iso = SynthParams {
            passes: 4,
            finest_passes: 1,
            ..SynthParams::default()
        };
        // (params, exemplar) -> passes at levels 0..=3 of a 4-level plan.
        let at = |p: &SynthParams, ex: ExemplarShape| {
            (0..4).map(|l| passes_at(p, l, 3, ex)).collect::<Vec<_>>()
        };
        assert_eq!(at(&iso, large), [4, 4, LARGE_SECOND_FINEST_PASSES, 1]);
        assert_eq!(at(&iso, small), [4, 4, SMALL_SECOND_FINEST_PASSES, 1]);
        assert_eq!(SMALL_SECOND_FINEST_PASSES, 3);
        // Never more than the other levels get.
        let one = SynthParams {
            passes: 1,
            ..iso.clone()
        };
        assert_eq!(at(&one, large), [1, 1, 1, 1]);
        // Along a field, every level alike from a large exemplar, and three passes at the
        // second-finest level from a small one (surfaces keep every level's passes,
        // advection pins them: Advection::synthesis_params).
        let field = SynthParams {
            field: Some(Field::Constant {
                angle: 0.3,
                scale: [1.0, 1.0],
                shear: 0.0,
            }),
            ..iso.clone()
        };
        assert_eq!(at(&field, large), [4, 4, 4, 1]);
        assert_eq!(at(&field, small), [4, 4, SMALL_SECOND_FINEST_PASSES, 1]);
        let advected = crate::gpu::advect::Advection::synthesis_params(&field);
        assert_eq!(at(&advected, small), [4, 4, 4, 1]);
        // An explicit count wins, either way.
        for n in [0, 3, 7] {
            let p = SynthParams {
                second_finest_passes: Some(n),
                ..iso.clone()
            };
            assert_eq!(at(&p, large), [4, 4, n, 1]);
            assert_eq!(at(&p, small), [4, 4, n, 1]);
        }
    }

    #[test]
    fn levels_without_similarity_sets_get_at_most_two_passes() {
        let p = SynthParams {
            passes: 4,
            finest_passes: 0,
            ..SynthParams::default()
        };
        // 128 px, levels 0..=7 (spacing 128..1): spacing 64 and 32 span the exemplar
        // with their 4-spacing neighbourhood, 16 does not.
        let at = |p: &SynthParams, width, height, feature| {
            let ex = ExemplarShape {
                width,
                height,
                feature,
            };
            (0..8).map(|l| passes_at(p, l, 7, ex)).collect::<Vec<_>>()
        };
        let u = UNSEARCHED_PASSES;
        assert_eq!(u, 2);
        assert_eq!(at(&p, 128, 128, false), [u, u, u, 4, 4, 4, 3, 0]);
        // The smaller side decides: 129 px wide still leaves spacing 32 unsearched on a
        // 128 px high exemplar, and 129 x 129 searches it.
        assert_eq!(at(&p, 129, 128, false), [u, u, u, 4, 4, 4, 3, 0]);
        assert_eq!(at(&p, 129, 129, false), [u, u, 4, 4, 4, 4, 3, 0]);
        // With a feature channel every level gets its passes.
        assert_eq!(at(&p, 128, 128, true), [4, 4, 4, 4, 4, 4, 4, 0]);
        // A cap, never more passes than asked for.
        let one = SynthParams {
            passes: 1,
            ..p.clone()
        };
        assert_eq!(at(&one, 128, 128, false), [1, 1, 1, 1, 1, 1, 1, 0]);
    }

    /// The schedule, finest level first, for an exemplar of the given smaller side.
    fn schedule(side: u32, extra: u32) -> Vec<f32> {
        let finest = 32 - (side - 1).leading_zeros();
        (0..=finest)
            .rev()
            .map(|l| default_randomness(l, finest, side, extra))
            .collect()
    }

    #[test]
    fn still_levels_grow_with_the_exemplar() {
        // (smaller side, still levels, weight of the first jittered level)
        for (side, still, partial) in [
            (16, 1, 1.0),
            (79, 1, 1.0),
            (80, 2, 0.5),
            (127, 2, 0.5),
            (128, 3, 0.75),
            (175, 3, 0.75),
            (176, 3, 0.25),
            (287, 3, 0.25),
            (288, 4, 0.25),
            (447, 4, 0.25),
            (448, 5, 0.75),
            (4096, 5, 0.75),
        ] {
            for extra in 0..2 {
                let s = schedule(side, extra);
                let still = still + extra as usize;
                assert!(s[..still].iter().all(|&r| r == 0.0), "{side}: {s:?}");
                assert_eq!(s[still], partial, "{side}: {s:?}");
                assert!(s[still + 1..].iter().all(|&r| r == 1.0), "{side}: {s:?}");
            }
        }
    }
}
