//! The copy guard (`gpu::copy_guard`): the stiller schedule is kept exactly when its probe
//! copies at most the budget, the probe is the result when it is the output's window,
//! the choice does not depend on the window, and the guard stays out of the way where
//! it does not apply.

use std::sync::Arc;

use texsyn::gpu::copy_guard::COPY_PROBE_SIZE;
use texsyn::quality::verbatim_stats;
use texsyn::{Analysis, AnalysisOptions, GpuContext, GpuSynthesizer, Session, SynthParams};

fn gravel_analysis() -> Analysis {
    let ex = texsyn::image_io::load_exemplar(
        concat!(env!("CARGO_MANIFEST_DIR"), "/assets/gravel.png").as_ref(),
    )
    .unwrap();
    texsyn::analysis::analyze(&ex, &AnalysisOptions::default(), |_| {}).unwrap()
}

#[test]
fn the_guard_keeps_the_stiller_schedule_only_within_its_budget() {
    let ctx = GpuContext::headless().expect("a device");
    let syn = GpuSynthesizer::new(&ctx, Arc::new(gravel_analysis())).unwrap();
    let a = syn.analysis();
    let (ew, eh, tileable) = (a.width, a.height, a.tileable);
    let output = SynthParams {
        width: COPY_PROBE_SIZE,
        height: COPY_PROBE_SIZE,
        seed: 3,
        ..Default::default()
    };

    // The probe's own copy, measured here from an explicit synthesis.
    let stiller = SynthParams {
        extra_still_levels: 1,
        ..output.clone()
    };
    let s = syn.synthesize_to_host(&ctx, &stiller).unwrap();
    let copy = verbatim_stats(&s.coords, s.width, s.height, ew, eh, tileable)
        .unwrap()
        .largest_region_fraction;
    let plain = syn.synthesize_to_host(&ctx, &output).unwrap();
    assert_ne!(
        s.coords, plain.coords,
        "one more still level changes the texture"
    );

    // A budget just above the copy keeps it, and the probe is the result.
    let keep = syn
        .choose_schedule(&ctx, &output, (copy as f32 + 1e-4).min(1.0))
        .unwrap();
    assert_eq!(keep.params, stiller);
    assert_eq!(keep.probe_copy, Some(copy));
    let r = keep.result.expect("the probe is the output's window");
    assert_eq!((r.coords, r.colors), (s.coords.clone(), s.colors.clone()));

    // Just below: the default schedule, nothing to reuse.
    let drop = syn
        .choose_schedule(&ctx, &output, copy as f32 * 0.999)
        .unwrap();
    assert_eq!(drop.params, output);
    assert_eq!(drop.probe_copy, Some(copy));
    assert!(drop.result.is_none());

    // Another window, same seed: same decision (the probe is the origin's window),
    // so windows still fit together; the result is synthesized apart.
    let window = SynthParams {
        width: 40,
        height: 24,
        origin: [300, -70],
        ..output.clone()
    };
    let w = syn.choose_schedule(&ctx, &window, 1.0).unwrap();
    assert_eq!(w.params.extra_still_levels, 1);
    assert_eq!(w.probe_copy, Some(copy));
    assert!(w.result.is_none());
    let piece = syn.synthesize_to_host(&ctx, &w.params).unwrap();
    let whole = syn
        .synthesize_to_host(
            &ctx,
            &SynthParams {
                width: 400,
                height: 24,
                origin: [0, -70],
                ..stiller.clone()
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
        stiller.clone(),
    ] {
        let c = syn.choose_schedule(&ctx, &p, 1.0).unwrap();
        assert_eq!((c.params, c.probe_copy.is_none()), (p, true));
    }
    let off = syn.choose_schedule(&ctx, &output, 0.0).unwrap();
    assert_eq!((off.params, off.probe_copy), (output.clone(), None));

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
fn a_session_applies_its_budget() {
    let analysis = gravel_analysis();
    let build = |budget: f32| {
        Session::builder()
            .analysis(analysis.clone())
            .size(96, 64)
            .seed(9)
            .copy_budget(budget)
            .build()
            .unwrap()
    };
    let (open, off) = (build(1.0), build(0.0));
    assert_eq!(open.copy_budget(), 1.0);
    let params = open.params().clone();
    assert_eq!(open.schedule(&params).unwrap().extra_still_levels, 1);
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
    assert_eq!(open.run().unwrap().coords(), &direct(1)[..]);
    assert_eq!(off.run().unwrap().coords(), &direct(0)[..]);
    assert!(Session::builder()
        .analysis(analysis)
        .copy_budget(f32::NAN)
        .build()
        .is_err());
}
