//! Bad velocities, time steps, parameters and options are errors with what to change.

use texsyn::gpu::advect::AdvectOptions;
use texsyn::passes::velocity::quantize_velocity;
use texsyn::SynthParams;

use crate::common::ctx;
use crate::harness::*;

#[test]
fn bad_velocities_and_time_steps() {
    let params = output(40, 32);
    let mut adv = FrameLoop::new(&Synth::gravel(32), &params, AdvectOptions::default()).adv;
    let good = vec![[0.5f32, 0.0]; 40 * 32];
    let err = |r: texsyn::Result<()>| r.unwrap_err().to_string();
    assert!(err(adv.step(&good[1..], 1.0)).contains("velocity field has"));
    for dt in [0.0, -1.0, f32::NAN, f32::INFINITY] {
        assert!(err(adv.step(&good, dt)).contains("time step"), "dt {dt}");
    }
    let mut nan = good.clone();
    nan[45] = [f32::NAN, 0.0];
    assert!(err(adv.step(&nan, 1.0)).contains("(5, 1)"));
    // Huge velocities are clamped (documented), not an error or a panic.
    let huge = vec![[1e30f32, -1e30]; 40 * 32];
    adv.step(&huge, 1.0).unwrap();
    assert_eq!(
        quantize_velocity([1e30, -1e30], 1.0),
        [64 * 1024, -64 * 1024]
    );
    assert_eq!(quantize_velocity([f32::NAN, 1.0], 1.0), [0, 1024]);
    // Parameters may change between frames, the size may not.
    adv.set_params(&SynthParams {
        seed: 5,
        coherence: 2.0,
        ..params.clone()
    })
    .unwrap();
    adv.step(&good, 1.0).unwrap();
    assert!(adv
        .set_params(&SynthParams {
            width: 41,
            ..params
        })
        .is_err());
    assert!(adv
        .set_options(AdvectOptions {
            threshold: -1.0,
            ..AdvectOptions::default()
        })
        .is_err());
    for sets_every in [0, 17] {
        let e = adv
            .set_options(AdvectOptions {
                sets_every,
                ..AdvectOptions::default()
            })
            .unwrap_err()
            .to_string();
        assert!(e.contains("sets every"), "{e}");
    }
    let e = adv
        .set_options(AdvectOptions {
            coarsest_passes: Some(17),
            ..AdvectOptions::keep_look()
        })
        .unwrap_err()
        .to_string();
    assert!(e.contains("17 on the coarsest advected level"), "{e}");
    let d = AdvectOptions::default();
    for (o, needle) in [
        // One level with the finest upsampled would advect nothing.
        (AdvectOptions { levels: 1, ..d }, "use 2-16 levels"),
        // No level at all: the advice must not be another failing setting.
        (
            AdvectOptions {
                levels: 0,
                upsample_finest: false,
                ..d
            },
            "use 1-16 levels",
        ),
        // Re-synthesized levels need an advected level above them and the finest
        // upsampled.
        (
            AdvectOptions {
                levels: 3,
                resynthesize: 2,
                ..d
            },
            "at least 4 levels",
        ),
        (
            AdvectOptions {
                levels: 6,
                upsample_finest: false,
                resynthesize: 2,
                ..d
            },
            "drop --advect-finest",
        ),
        // `keep_look` remakes the advected levels itself, below the coarsest one.
        (
            AdvectOptions {
                levels: 2,
                ..AdvectOptions::keep_look()
            },
            "use at least 3 levels",
        ),
        (
            AdvectOptions {
                resynthesize: 2,
                ..AdvectOptions::keep_look()
            },
            "keep_look remakes the advected levels itself",
        ),
        (
            AdvectOptions {
                upsample_finest: false,
                ..AdvectOptions::keep_look()
            },
            "keep_look remakes the advected levels itself",
        ),
        // More re-synthesized levels than the pyramid has room for: an error, not fewer.
        (
            AdvectOptions {
                levels: 16,
                resynthesize: 14,
                ..d
            },
            "can be re-synthesized",
        ),
        (
            AdvectOptions {
                levels: 16,
                resynthesize: 15,
                ..d
            },
            "at most 14",
        ),
        (
            AdvectOptions { fade: 65, ..d },
            "a fade of 65 frames: use 0 (off) to 64",
        ),
        (
            AdvectOptions {
                fade: 2,
                fade_change: 256,
                ..d
            },
            "a pop test of 256",
        ),
        (
            AdvectOptions {
                anchor_spacing: 65,
                ..d
            },
            "use a spacing of 0 (off) to 64",
        ),
        (
            AdvectOptions {
                anchor_spacing: 4,
                anchor_upsample: f32::NAN,
                ..d
            },
            "an upsampled share of NaN",
        ),
        (
            AdvectOptions {
                anchor_upsample: 1.5,
                ..d
            },
            "a share of 0 to 1",
        ),
    ] {
        let e = adv.set_options(o).unwrap_err().to_string();
        assert!(e.contains(needle), "{o:?}: {e}");
    }
    adv.set_options(AdvectOptions {
        levels: 1,
        upsample_finest: false,
        ..AdvectOptions::default()
    })
    .unwrap();
    adv.step(&good, 1.0).unwrap();
    ctx().take_uncaptured_errors().unwrap();
}
