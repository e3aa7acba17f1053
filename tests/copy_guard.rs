//! The copy guard (`gpu::copy_guard`): the stillest schedule whose probe copies at most
//! the budget is kept, the probe is the result when it is the output's window, the
//! choice does not depend on the window, and the guard stays out of the way where it
//! does not apply.

use std::sync::Arc;

use texsyn::gpu::copy_guard::{COPY_PROBE_SIZE, GUARD_MIN_SIDE, GUARD_TIERS};
use texsyn::quality::verbatim_stats;
use texsyn::{Analysis, AnalysisOptions, GpuContext, GpuSynthesizer, Session, SynthParams};

/// The bundled gravel (128 px) enlarged to `side`, analysed.
fn gravel_analysis(side: u32) -> Analysis {
    let img = image::open(concat!(env!("CARGO_MANIFEST_DIR"), "/assets/gravel.png")).unwrap();
    let img = img.resize_exact(side, side, image::imageops::FilterType::Triangle);
    let ex = texsyn::image_io::exemplar_from_image(&img).unwrap();
    texsyn::analysis::analyze(&ex, &AnalysisOptions::default(), |_| {}).unwrap()
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
        let s = syn.synthesize_to_host(&ctx, &with_extra(extra)).unwrap();
        let copy = verbatim_stats(&s.coords, s.width, s.height, ew, eh, tileable)
            .unwrap()
            .largest_region_fraction;
        tiers.push((extra, copy, s));
    }
    let plain = syn.synthesize_to_host(&ctx, &output).unwrap();
    assert_ne!(tiers[0].2.coords, plain.coords);
    assert_ne!(tiers[1].2.coords, plain.coords);

    // Budgets at, just under and above each probe's copy: the first tier within the
    // budget is kept (its probe is the result), the default if none is.
    let mut budgets = vec![1.0f32];
    for (_, c, _) in &tiers {
        budgets.push(*c as f32);
        budgets.push(*c as f32 * 0.999);
    }
    for b in budgets {
        let choice = syn.choose_schedule(&ctx, &output, b).unwrap();
        let kept = tiers.iter().position(|(_, c, _)| *c <= b as f64);
        let probed = kept.map_or(tiers.len(), |i| i + 1);
        assert_eq!(
            choice.probes,
            tiers[..probed]
                .iter()
                .map(|(e, c, _)| (*e, *c))
                .collect::<Vec<_>>(),
            "budget {b}"
        );
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
    let w = syn.choose_schedule(&ctx, &window, 1.0).unwrap();
    assert_eq!(w.params.extra_still_levels, GUARD_TIERS[0]);
    assert_eq!(w.probes, vec![(tiers[0].0, tiers[0].1)]);
    assert!(w.result.is_none());
    let piece = syn.synthesize_to_host(&ctx, &w.params).unwrap();
    let whole = syn
        .synthesize_to_host(
            &ctx,
            &SynthParams {
                width: 400,
                height: 24,
                origin: [0, -70],
                ..with_extra(GUARD_TIERS[0])
            },
        )
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
        let c = syn.choose_schedule(&ctx, &p, 1.0).unwrap();
        assert_eq!((c.params, c.probes.is_empty()), (p, true));
    }
    let off = syn.choose_schedule(&ctx, &output, 0.0).unwrap();
    assert_eq!((off.params, off.probes.is_empty()), (output.clone(), true));

    // Bad budgets and bad parameters are errors, not panics.
    for b in [-0.1, 1.5, f32::NAN] {
        assert!(syn.choose_schedule(&ctx, &output, b).is_err(), "{b}");
    }
    let zero = SynthParams {
        width: 0,
        ..output.clone()
    };
    assert!(syn.choose_schedule(&ctx, &zero, 0.25).is_err());
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
            .synthesize_to_host(
                open.context(),
                &SynthParams {
                    extra_still_levels: extra,
                    ..params.clone()
                },
            )
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
