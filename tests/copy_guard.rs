//! The copy guard (`gpu::copy_guard`): the stillest schedule whose probe copies at most
//! the budget is kept, the probe is the result when it is the output's window, the
//! choice does not depend on the window, and the guard stays out of the way where it
//! does not apply.

use std::sync::Arc;

use texsyn::gpu::copy_guard::{Probe, COPY_PROBE_SIZE, EARLY_CHECKS, GUARD_MIN_SIDE, GUARD_TIERS};
use texsyn::passes::SynthPlan;
use texsyn::quality::{verbatim_stats, verbatim_stats_at_spacing};
use texsyn::{Analysis, AnalysisOptions, GpuContext, GpuSynthesizer, Session, SynthParams};

/// The bundled gravel (128 px) enlarged to `side`, analysed.
fn gravel_analysis(side: u32) -> Analysis {
    let img = image::open(concat!(env!("CARGO_MANIFEST_DIR"), "/assets/gravel.png")).unwrap();
    let img = img.resize_exact(side, side, image::imageops::FilterType::Triangle);
    let ex = texsyn::image_io::exemplar_from_image(&img).unwrap();
    texsyn::analysis::analyze(&ex, &AnalysisOptions::default(), |_| {}).unwrap()
}

/// The largest verbatim copy of `output`'s window with `extra` more still levels at the
/// level `up` levels above the finest, from the GPU's own coordinates at that level,
/// and that level's spacing.
fn coarse_copy(syn: &GpuSynthesizer, output: &SynthParams, extra: u32, up: u32) -> (f64, u32) {
    let a = syn.analysis();
    let p = SynthParams {
        extra_still_levels: extra,
        ..output.clone()
    };
    let plan = SynthPlan::new(a, &p).unwrap();
    let schedule = plan.schedule(a);
    let l = plan.levels.len() - 1 - up as usize;
    let end = schedule.iter().rposition(|d| d.level == l).unwrap() + 1;
    let all = syn.run_prefix(&p, end).unwrap();
    let lp = &plan.levels[l];
    // The window at the origin, 1/2^up of the output's side there.
    let side = (output.width >> up) as usize;
    assert_eq!(output.origin, [0, 0]);
    let (x0, y0) = (-lp.origin[0] as usize, -lp.origin[1] as usize);
    let mut window = Vec::new();
    for y in 0..side {
        let row = lp.coord_base as usize + (y0 + y) * lp.size[0] as usize + x0;
        window.extend_from_slice(&all[row..row + side]);
    }
    let c = verbatim_stats_at_spacing(
        &window,
        side as u32,
        side as u32,
        a.width,
        a.height,
        a.tileable,
        lp.spacing,
    )
    .unwrap()
    .largest_region_fraction;
    (c, lp.spacing)
}

/// The probe the guard should record for a tier under `budget`: given up at the first
/// early check whose coarse copy exceeds the budget by more than its margin, else
/// measured on the output (`full`).
fn expected_probe(coarse: &[(f64, u32)], full: f64, extra: u32, budget: f32) -> Probe {
    for (&(_, margin), &(copy, spacing)) in EARLY_CHECKS.iter().zip(coarse) {
        if copy > budget as f64 + margin {
            return Probe {
                extra_still_levels: extra,
                copy,
                spacing,
            };
        }
    }
    Probe {
        extra_still_levels: extra,
        copy: full,
        spacing: 1,
    }
}

#[test]
fn the_guard_keeps_the_stillest_schedule_within_its_budget() {
    let ctx = GpuContext::headless().expect("a device");
    let syn = GpuSynthesizer::new(&ctx, Arc::new(gravel_analysis(GUARD_MIN_SIDE))).unwrap();
    let a = syn.analysis();
    let (ew, eh, tileable) = (a.width, a.height, a.tileable);
    let output = SynthParams {
        width: COPY_PROBE_SIZE,
        height: COPY_PROBE_SIZE,
        seed: 3,
        ..Default::default()
    };
    let with_extra = |extra: u32| SynthParams {
        extra_still_levels: extra,
        ..output.clone()
    };

    // Each tier's probe, measured here from explicit syntheses.
    let mut tiers = Vec::new();
    for extra in GUARD_TIERS {
        let s = syn.synthesize_to_host(&with_extra(extra)).unwrap();
        let copy = verbatim_stats(&s.coords, s.width, s.height, ew, eh, tileable)
            .unwrap()
            .largest_region_fraction;
        tiers.push((extra, copy, s));
    }
    let plain = syn.synthesize_to_host(&output).unwrap();
    assert_ne!(tiers[0].2.coords, plain.coords);
    assert_ne!(tiers[1].2.coords, plain.coords);

    let coarse: Vec<Vec<(f64, u32)>> = GUARD_TIERS
        .iter()
        .map(|&e| {
            EARLY_CHECKS
                .iter()
                .map(|&(up, _)| coarse_copy(&syn, &output, e, up))
                .collect()
        })
        .collect();

    // Budgets at, just under and above each probe's copy: the first tier within the
    // budget is kept (its probe is the result), the default if none is. A probe far
    // over the budget is given up at a coarser level (the early checks).
    let mut budgets = vec![1.0f32];
    for (_, c, _) in &tiers {
        budgets.push(*c as f32);
        budgets.push(*c as f32 * 0.999);
    }
    for b in budgets {
        let choice = syn.choose_schedule(&output, b).unwrap();
        let probes: Vec<Probe> = tiers
            .iter()
            .zip(&coarse)
            .map(|((e, c, _), coarse)| expected_probe(coarse, *c, *e, b))
            .collect();
        let kept = probes
            .iter()
            .position(|p| p.spacing == 1 && p.copy <= b as f64);
        let probed = kept.map_or(tiers.len(), |i| i + 1);
        assert_eq!(choice.probes, probes[..probed], "budget {b}");
        match kept {
            Some(i) => {
                assert_eq!(choice.params, with_extra(tiers[i].0), "budget {b}");
                let r = choice.result.expect("the probe is the output's window");
                assert_eq!(r.coords, tiers[i].2.coords);
                assert_eq!(r.colors, tiers[i].2.colors);
            }
            None => {
                assert_eq!(choice.params, output, "budget {b}");
                assert!(choice.result.is_none());
            }
        }
    }

    // Another window, same seed: the same decision (the probe is the origin's window),
    // so windows still fit together; the result is synthesized apart.
    let window = SynthParams {
        width: 40,
        height: 24,
        origin: [300, -70],
        ..output.clone()
    };
    let w = syn.choose_schedule(&window, 1.0).unwrap();
    assert_eq!(w.params.extra_still_levels, GUARD_TIERS[0]);
    assert_eq!(
        w.probes,
        vec![Probe {
            extra_still_levels: tiers[0].0,
            copy: tiers[0].1,
            spacing: 1
        }]
    );
    assert!(w.result.is_none());
    let piece = syn.synthesize_to_host(&w.params).unwrap();
    let whole = syn
        .synthesize_to_host(&SynthParams {
            width: 400,
            height: 24,
            origin: [0, -70],
            ..with_extra(GUARD_TIERS[0])
        })
        .unwrap();
    for y in 0..24 {
        for x in 0..40 {
            assert_eq!(piece.coords[y * 40 + x], whole.coords[y * 400 + 300 + x]);
        }
    }

    // Where the guard does not apply, the parameters come back as they are, unprobed.
    for p in [
        SynthParams {
            randomness: vec![1.0, 0.5, 0.0],
            ..output.clone()
        },
        SynthParams {
            field: Some(texsyn::Field::Constant {
                angle: 0.5,
                scale: [1.0, 1.0],
                shear: 0.0,
            }),
            ..output.clone()
        },
        with_extra(1),
    ] {
        let c = syn.choose_schedule(&p, 1.0).unwrap();
        assert_eq!((c.params, c.probes.is_empty()), (p, true));
    }
    let off = syn.choose_schedule(&output, 0.0).unwrap();
    assert_eq!((off.params, off.probes.is_empty()), (output.clone(), true));

    // Bad budgets and bad parameters are errors, not panics.
    for b in [-0.1, 1.5, f32::NAN] {
        assert!(syn.choose_schedule(&output, b).is_err(), "{b}");
    }
    let zero = SynthParams {
        width: 0,
        ..output.clone()
    };
    assert!(syn.choose_schedule(&zero, 0.25).is_err());
    ctx.take_uncaptured_errors().expect("no wgpu errors");
}

#[test]
fn a_probe_far_over_the_budget_is_given_up_at_a_coarser_level() {
    let ctx = GpuContext::headless().expect("a device");
    let syn = GpuSynthesizer::new(&ctx, Arc::new(gravel_analysis(GUARD_MIN_SIDE))).unwrap();
    let output = SynthParams {
        width: COPY_PROBE_SIZE,
        height: COPY_PROBE_SIZE,
        seed: 5,
        ..Default::default()
    };
    let (up, margin) = EARLY_CHECKS[0];
    let coarse: Vec<(f64, u32)> = GUARD_TIERS
        .iter()
        .map(|&e| coarse_copy(&syn, &output, e, up))
        .collect();
    // A budget every tier's coarse copy exceeds by more than the margin: each probe
    // is given up at that level, and the default schedule stays.
    let low = (coarse.iter().map(|c| c.0).fold(f64::MAX, f64::min) - margin) as f32 * 0.9;
    assert!(low > 0.0, "{coarse:?}");
    let choice = syn.choose_schedule(&output, low).unwrap();
    assert_eq!(choice.params, output);
    assert!(choice.result.is_none());
    let expected: Vec<Probe> = GUARD_TIERS
        .iter()
        .zip(&coarse)
        .map(|(&e, &(copy, spacing))| Probe {
            extra_still_levels: e,
            copy,
            spacing,
        })
        .collect();
    assert_eq!(choice.probes, expected);
    assert_eq!(coarse[0].1, 1 << up);
    assert!(
        choice.describe(low).contains("given up"),
        "{}",
        choice.describe(low)
    );

    // (The first test covers a probe given up two levels above the finest, and a
    // staged probe's result against a plain synthesis.)
    ctx.take_uncaptured_errors().expect("no wgpu errors");
}

#[test]
fn a_session_applies_its_budget_to_large_exemplars_only() {
    let build = |analysis: &Analysis, budget: f32| {
        Session::builder()
            .analysis(analysis.clone())
            .size(96, 64)
            .seed(9)
            .copy_budget(budget)
            .build()
            .unwrap()
    };
    let large = gravel_analysis(GUARD_MIN_SIDE);
    let (open, off) = (build(&large, 1.0), build(&large, 0.0));
    assert_eq!(open.copy_budget(), 1.0);
    let params = open.params().clone();
    assert_eq!(
        open.schedule(&params).unwrap().extra_still_levels,
        GUARD_TIERS[0]
    );
    assert_eq!(off.schedule(&params).unwrap(), params);
    let direct = |extra: u32| {
        open.synthesizer()
            .synthesize_to_host(&SynthParams {
                extra_still_levels: extra,
                ..params.clone()
            })
            .unwrap()
            .coords
    };
    assert_eq!(open.run().unwrap().coords(), &direct(GUARD_TIERS[0])[..]);
    assert_eq!(off.run().unwrap().coords(), &direct(0)[..]);

    // Under GUARD_MIN_SIDE the default schedule stays, whatever the budget.
    let small = gravel_analysis(GUARD_MIN_SIDE - 1);
    let s = build(&small, 1.0);
    assert_eq!(s.schedule(s.params()).unwrap(), *s.params());

    assert!(Session::builder()
        .analysis(large)
        .copy_budget(f32::NAN)
        .build()
        .is_err());
}

/// Which outputs the guard's probe covers: windows inside the probe at the origin (of
/// the output's size, at least the probe size) and periodic outputs; anything reaching
/// beyond is not measured (`output_within_probe`). Outputs over `MAX_PROBE_SIZE` a side
/// are not probed at all (`probed_size`).
#[test]
fn outputs_within_the_probe_window() {
    let n = COPY_PROBE_SIZE;
    let p = |origin: [i32; 2], w: u32, h: u32| SynthParams {
        width: w,
        height: h,
        origin,
        ..SynthParams::default()
    };
    for (params, within) in [
        (p([0, 0], n, n), true),
        (p([0, 0], 64, 32), true),
        (p([n as i32 - 64, 100], 64, 64), true),
        (p([0, 0], n + 1, n), true),
        (p([0, 0], 2 * n, 2 * n), true),
        (p([1, 0], n + 1, n), false),
        (p([0, -1], 2 * n, 2 * n), false),
        (p([-1, 0], 64, 64), false),
        (p([n as i32 - 63, 0], 64, 64), false),
        (p([n as i32, n as i32], 64, 64), false),
        (
            SynthParams {
                tileable_output: true,
                ..p([0, 0], 2 * n, 2 * n)
            },
            true,
        ),
    ] {
        assert_eq!(
            GpuSynthesizer::output_within_probe(&params),
            within,
            "{:?} {}x{} periodic {}",
            params.origin,
            params.width,
            params.height,
            params.tileable_output
        );
    }
    // The probe: at the origin, the output's size but at least the probe size.
    let probe = GpuSynthesizer::probe_params(&p([700, -300], 64, 1000));
    assert_eq!((probe.origin, probe.width, probe.height), ([0, 0], n, 1000));
    let m = texsyn::gpu::copy_guard::MAX_PROBE_SIZE;
    assert!(GpuSynthesizer::probed_size(&p([0, 0], m, m)));
    assert!(!GpuSynthesizer::probed_size(&p([0, 0], m + 1, 8)));
    assert!(GpuSynthesizer::probed_size(&SynthParams {
        tileable_output: true,
        ..p([0, 0], m + 1, 8)
    }));
}

/// An output larger than the probe size is its own probe: measured at its size (a
/// stiller schedule's copies grow with the extent), and the result when it passes.
#[test]
fn a_larger_output_is_its_own_probe() {
    let ctx = GpuContext::headless().expect("a device");
    let syn = GpuSynthesizer::new(&ctx, Arc::new(gravel_analysis(GUARD_MIN_SIDE))).unwrap();
    let a = syn.analysis();
    let output = SynthParams {
        width: COPY_PROBE_SIZE + 96,
        height: COPY_PROBE_SIZE + 8,
        seed: 3,
        ..Default::default()
    };
    let choice = syn.choose_schedule(&output, 1.0).unwrap();
    assert_eq!(choice.params.extra_still_levels, GUARD_TIERS[0]);
    let r = choice.result.expect("the output is the probe");
    assert_eq!((r.width, r.height), (output.width, output.height));
    let copy = verbatim_stats(&r.coords, r.width, r.height, a.width, a.height, a.tileable)
        .unwrap()
        .largest_region_fraction;
    assert_eq!(choice.probes[0].copy, copy);
    assert_eq!(choice.probes[0].spacing, 1);
    assert!(choice.unprobed.is_none());
    let again = syn.synthesize_to_host(&choice.params).unwrap();
    assert_eq!(again.coords, r.coords);
    // Over the largest probed side: the default schedule, unprobed, and it says why.
    let huge = SynthParams {
        width: texsyn::gpu::copy_guard::MAX_PROBE_SIZE + 1,
        height: 16,
        ..output.clone()
    };
    let c = syn.choose_schedule(&huge, 1.0).unwrap();
    assert_eq!((&c.params, c.probes.is_empty()), (&huge, true));
    assert!(
        c.describe(1.0).contains("over 2048 px"),
        "{}",
        c.describe(1.0)
    );
    ctx.take_uncaptured_errors().expect("no wgpu errors");
}

/// A tileable output whose sides are not multiples of 4 is made on a torus and resampled
/// (`passes::plan::Torus`; whole texels along no field) and guarded like any periodic
/// output: its own probe, its copies measured on the resampled coordinates, the kept
/// probe the result. (Unguarded, a 511x511 tileable output from a 512 px exemplar had
/// twice the texture energy of a guarded 512x512.)
#[test]
fn a_tileable_output_made_on_a_torus_is_guarded() {
    let ctx = GpuContext::headless().expect("a device");
    let syn = GpuSynthesizer::new(&ctx, Arc::new(gravel_analysis(GUARD_MIN_SIDE))).unwrap();
    let a = syn.analysis();
    let params = SynthParams {
        width: 66,
        height: 50,
        seed: 3,
        tileable_output: true,
        ..Default::default()
    };
    assert!(SynthPlan::new(a, &params).unwrap().torus.is_some());
    let choice = syn.choose_schedule(&params, 0.25).unwrap();
    let kept = choice.probes.last().expect("probed");
    assert_eq!(kept.spacing, 1, "measured on the output");
    let result = choice.result.expect("a periodic output is its own probe");
    assert_eq!((result.width, result.height), (66, 50));
    assert!(
        result.coords.iter().flatten().all(|v| v % 256 == 0),
        "whole texels"
    );
    let texels: Vec<[i32; 2]> = result.coords.iter().map(|c| c.map(|v| v >> 8)).collect();
    let copy = verbatim_stats(&texels, 66, 50, a.width, a.height, a.tileable)
        .unwrap()
        .largest_region_fraction;
    assert_eq!(kept.copy, copy);
    // Coherent patches are found in the resampled coordinates (whole exemplar copies).
    assert!(copy > 0.01, "largest copy {copy}");
}
