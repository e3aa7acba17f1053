//! What the frames run: the pipelines built up front, the turns of the similarity sets,
//! the quarter-pixel tables read.

use texsyn::analysis::{analyze, AnalysisOptions};
use texsyn::flow::Flow;
use texsyn::gpu::advect::{AdvectOptions, Advection};
use texsyn::gpu::GpuContext;
use texsyn::passes::plan::SynthPlan;
use texsyn::SynthParams;

use crate::common;
use crate::harness::{output, FrameLoop, Synth};

/// `Advection::new` (and `set_options`) build the pipelines of the frames: a host's frame
/// loop builds none (they cost 0.2 s of the first frame at 128x128 on lavapipe).
#[test]
fn frames_build_no_pipelines_after_new() {
    // A context of its own: the other tests build pipelines on the shared one meanwhile.
    let own = GpuContext::headless().unwrap();
    let gravel = Synth::gravel_on(&own, 48);
    let params = output(40, 40);
    let v = Flow::Vortex {
        cx: 0.5,
        cy: 0.5,
        omega: 0.02,
    }
    .sample(40, 40, 0.0)
    .unwrap();
    for options in [
        AdvectOptions::recommended(&params),
        AdvectOptions::default(),
        AdvectOptions {
            sets_every: 3,
            ..AdvectOptions::keep_look()
        },
        // The finest level advected and corrected: its corrections read quarter-pixel
        // tables, a variant of their own.
        AdvectOptions {
            upsample_finest: false,
            ..AdvectOptions::default()
        },
        AdvectOptions {
            resynthesize: 1,
            levels: 3,
            ..AdvectOptions::default()
        },
    ] {
        let mut adv = FrameLoop::on(&own, &gravel, &params, options).adv;
        let built = own.built_pipelines();
        assert!(built > 0);
        for _ in 0..20 {
            adv.step(&v, 1.0).unwrap();
        }
        assert_eq!(own.built_pipelines(), built, "{options:?}");
        // Options changed between frames: built by set_options, not by the frames.
        adv.set_options(AdvectOptions {
            fade: 1,
            anchor_spacing: 4,
            ..options
        })
        .unwrap();
        let built = own.built_pipelines();
        for _ in 0..20 {
            adv.step(&v, 1.0).unwrap();
        }
        assert_eq!(
            own.built_pipelines(),
            built,
            "{options:?} with fade 1 and anchors"
        );
    }
}

/// With one correction pass per frame, the most corrected level's similarity sets follow
/// the frames' `sets_every` (`AdvectOptions`, default 2) over the frames, at the same
/// cost every frame: with the finest level upsampled (default), the second-finest runs
/// its four subpasses each frame, two with the sets (k) and two without (k = 1); with the
/// finest advected, the finest runs two of its four, one with them. Every pixel class has
/// them at every other correction (every correction with `sets_every` 1). The synthesis
/// parameter of the same name (frame 0's) does not steer the frames.
#[test]
fn advection_frames_take_turns_with_the_similarity_sets() {
    let ex = common::gravel_crop(32);
    let a = common::assets::analysed(&ex);
    assert_eq!(AdvectOptions::default().sets_every, 2);
    assert!(AdvectOptions::default().upsample_finest);
    for upsample_finest in [true, false] {
        for sets_every in [1u32, 2] {
            let o = AdvectOptions {
                sets_every,
                upsample_finest,
                ..Default::default()
            };
            let params = Advection::synthesis_params(&SynthParams {
                width: 40,
                height: 24,
                sets_every: 3 - sets_every,
                ..Default::default()
            });
            let plan = SynthPlan::new(&a, &params).unwrap();
            let n = plan.levels.len();
            let top = if upsample_finest { n - 2 } else { n - 1 };
            let per_frame = if upsample_finest { 4 } else { 2 };
            let mut per_class: std::collections::HashMap<[i32; 2], Vec<i32>> = Default::default();
            for frame in 0..8u64 {
                let schedule = plan.advect_schedule(&a, &o, frame);
                // Nothing corrects the finest level when it is upsampled.
                assert_eq!(
                    schedule.iter().any(|d| d.level == n - 1
                        && d.kind == texsyn::passes::plan::PassKind::CorrectAniso),
                    !upsample_finest
                );
                let ks: Vec<(i32, [i32; 2])> = schedule
                    .iter()
                    .filter(|d| {
                        d.level == top && d.kind == texsyn::passes::plan::PassKind::CorrectAniso
                    })
                    .map(|d| (d.params.k, d.params.parity))
                    .collect();
                assert_eq!(ks.len(), per_frame, "frame {frame}");
                let with_sets = ks.iter().filter(|(k, _)| *k == a.k as i32).count();
                assert_eq!(
                    with_sets,
                    per_frame / sets_every as usize,
                    "frame {frame}, upsampled finest {upsample_finest}"
                );
                for (k, parity) in ks {
                    per_class.entry(parity).or_default().push(k);
                }
            }
            assert_eq!(per_class.len(), 4);
            for (parity, ks) in per_class {
                let want: Vec<i32> = (0..ks.len())
                    .map(|i| {
                        if sets_every == 1 || i % 2 == 0 {
                            a.k as i32
                        } else {
                            1
                        }
                    })
                    .collect();
                // Each class starts with or without them, then alternates.
                let flipped: Vec<i32> = want
                    .iter()
                    .map(|&k| {
                        if sets_every == 1 {
                            k
                        } else {
                            a.k as i32 + 1 - k
                        }
                    })
                    .collect();
                assert!(ks == want || ks == flipped, "class {parity:?}: {ks:?}");
            }
        }
    }
}

/// With `keep_look` every advected level runs all its subpasses every frame (four per
/// pass: two passes at the coarsest advected level, `coarsest_passes`, one below), and each
/// follows `sets_every` (scoring the sets on every correction of the coarser advected
/// levels costs a quarter of the frame's GPU time for the same figures): per frame, the subpasses divided by `sets_every` score the similarity sets
/// (one of four for 4, two of eight), and each parity class scores them on every
/// `sets_every`-th of its corrections.
#[test]
fn keep_look_levels_take_turns_with_the_similarity_sets() {
    use texsyn::passes::plan::PassKind;
    let ex = common::gravel_crop(32);
    let a = common::assets::analysed(&ex);
    assert_eq!(AdvectOptions::keep_look().sets_every, 4);
    assert_eq!(AdvectOptions::keep_look().coarsest_passes, None);
    let params = Advection::synthesis_params(&SynthParams {
        width: 40,
        height: 24,
        ..Default::default()
    });
    let plan = SynthPlan::new(&a, &params).unwrap();
    let n = plan.levels.len();
    // Two passes on the coarsest advected level by default, where J is constant.
    assert_eq!(plan.advect_coarsest_passes(&AdvectOptions::keep_look()), 2);
    assert_eq!(plan.advect_coarsest_passes(&AdvectOptions::default()), 1);
    let swirl = SynthPlan::new(
        &a,
        &SynthParams {
            field: Some(texsyn::Field::Swirl {
                center: [20.0, 12.0],
                radius: 10.0,
                turns: 0.5,
                scale: 1.0,
            }),
            ..params.clone()
        },
    )
    .unwrap();
    assert_eq!(swirl.advect_coarsest_passes(&AdvectOptions::keep_look()), 1);
    for sets_every in [1u32, 2, 4] {
        let o = AdvectOptions {
            sets_every,
            ..AdvectOptions::keep_look()
        };
        let advected = n - 1 - o.levels + 1..n - 1;
        assert_eq!(advected.len(), 3);
        for level in advected {
            // The coarsest advected level two passes (`coarsest_passes`), the others one.
            let passes = if level == n - 4 { 2 } else { 1 };
            let mut per_class: std::collections::HashMap<[i32; 2], usize> = Default::default();
            for frame in 0..8u64 {
                let ks: Vec<(i32, [i32; 2])> = plan
                    .advect_schedule(&a, &o, frame)
                    .iter()
                    .filter(|d| d.level == level && d.kind == PassKind::CorrectAniso)
                    .map(|d| (d.params.k, d.params.parity))
                    .collect();
                assert_eq!(ks.len(), 4 * passes, "level {level}, frame {frame}");
                let with_sets: Vec<_> = ks.iter().filter(|(k, _)| *k == a.k as i32).collect();
                assert_eq!(
                    with_sets.len(),
                    4 * passes / sets_every as usize,
                    "level {level}, frame {frame}, sets every {sets_every}"
                );
                assert!(ks.iter().all(|(k, _)| *k == a.k as i32 || *k == 1));
                for (_, parity) in with_sets {
                    *per_class.entry(*parity).or_default() += 1;
                }
            }
            // Over 8 frames each class scores them 8 x passes / sets_every times.
            assert_eq!(per_class.len(), 4, "level {level}");
            assert!(
                per_class
                    .values()
                    .all(|&c| c == 8 * passes / sets_every as usize),
                "level {level}, sets every {sets_every}: {per_class:?}"
            );
        }
    }
}

/// The corrections of an advection frame's most corrected level read that level's
/// quarter-pixel tables, where it uses the projected distance: the finest level when it
/// is advected (with the default distances, which score the coarser levels with the full
/// distance), the second-finest when the finest is upsampled (with the projected distance
/// everywhere; by default that level uses the full distance, which reads no tables). The
/// plan must recognize the level although the coarse levels store no tables (their
/// offsets skip them); taking `(levels - 1) w h` for the finest level's offset would
/// silently interpolate four texels per read instead (the same bytes, more time).
#[test]
fn advection_frames_read_the_finest_quarter_tables() {
    use texsyn::passes::plan::{quarter_tables_level, PassKind};
    for size in [32u32, 64] {
        let ex = common::gravel_crop(size);
        let a = analyze(&ex, &AnalysisOptions::default(), |_| {}).unwrap();
        let finest = a.levels.len() - 1;
        let o = AdvectOptions::default();
        assert!(o.quarter_reads, "the default frames read quarter pixels");
        let params = SynthParams {
            width: 48,
            height: 40,
            ..Default::default()
        };
        let plan = SynthPlan::new(&a, &Advection::synthesis_params(&params)).unwrap();
        let projected = SynthPlan::new(
            &a,
            &Advection::synthesis_params(&SynthParams {
                distance: texsyn::DistanceMode::Projected,
                ..params.clone()
            }),
        )
        .unwrap();
        let advected = AdvectOptions {
            upsample_finest: false,
            ..o
        };
        for frame in 0..4u64 {
            let s = plan.advect_schedule(&a, &advected, frame);
            let corrections: Vec<_> = s
                .iter()
                .filter(|d| d.kind == PassKind::CorrectAniso)
                .collect();
            assert!(corrections.iter().any(|d| d.level == finest));
            for d in corrections {
                assert_eq!(
                    d.reads_quarter_tables(&a),
                    d.level == finest,
                    "exemplar {size}, frame {frame}, level {}",
                    d.level
                );
            }
            assert_eq!(quarter_tables_level(&s, &a), Some(finest));
            let s = projected.advect_schedule(&a, &o, frame);
            assert_eq!(quarter_tables_level(&s, &a), Some(finest - 1));
            assert_eq!(
                quarter_tables_level(&plan.advect_schedule(&a, &o, frame), &a),
                None
            );
        }
        // The exact reads interpolate at the position itself: no tables.
        let exact = AdvectOptions {
            quarter_reads: false,
            ..o
        };
        for p in [&plan, &projected] {
            for opts in [
                exact,
                AdvectOptions {
                    upsample_finest: false,
                    ..exact
                },
            ] {
                assert!(p
                    .advect_schedule(&a, &opts, 0)
                    .iter()
                    .all(|d| !d.reads_quarter_tables(&a)));
            }
        }
    }
}
