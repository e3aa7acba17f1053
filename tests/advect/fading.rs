//! Fading renewals in (`AdvectOptions::fade`): GPU = CPU, the pop test, fades turned on
//! or shortened between frames.

use texsyn::gpu::advect::AdvectOptions;
use texsyn::SynthParams;

use crate::common::ctx;
use crate::harness::*;

/// The output index of region pixel `t` of fade dispatch `p` (a `w` x `h` window), if it
/// lies in the window.
fn window_index(p: &texsyn::passes::common::PassParams, t: usize, w: u32, h: u32) -> Option<usize> {
    let (x, y) = (t as i32 % p.size[0], t as i32 / p.size[0]);
    let (wx, wy) = (x - p.window_offset[0], y - p.window_offset[1]);
    (wx >= 0 && wy >= 0 && wx < w as i32 && wy < h as i32).then(|| (wy * w as i32 + wx) as usize)
}

/// One-frame fades (`fade: 1`) keep the coordinates alone as fade state: GPU = CPU
/// (coordinates and colours) over frames of a fast vortex, some pixels show a blend (not
/// their texel), and longer fades after them start every pixel unfaded.
#[test]
fn one_frame_fades_match_cpu_and_longer_ones_start_unfaded() {
    let gravel = Synth::gravel(32);
    let (w, h) = (48u32, 40u32);
    let params = output(w, h);
    let flow = FAST_VORTEX;
    let opts = AdvectOptions {
        fade: 1,
        fade_change: 40,
        ..AdvectOptions::keep_look()
    };
    let mut frames = FrameLoop::mirrored_with_fade_room(&gravel, &params, opts);
    let region = frames.plan().fade_half_len() as usize / 3;
    let mut blended = 0usize;
    for f in 0..10u64 {
        if f == 8 {
            frames.set_options(AdvectOptions { fade: 4, ..opts });
        }
        let (v, _) = frame_velocities(&flow, w, h, f);
        let p = frames.adv.frame_schedule().last().unwrap().params;
        assert_eq!(
            p.fade_src == 0,
            f == 8,
            "frame {}: fade_src {}",
            f + 1,
            p.fade_src
        );
        let out = frames.step_mirrored(&v, 1.0);
        assert!(frames.matches_mirror(), "frame {} differs", f + 1);
        assert_eq!(frames.rgba(), rgba8(&out), "frame {}", f + 1);
        if f < 8 {
            let state = &frames.cpu()[p.fade_dst as usize..][..3 * region];
            for (t, o) in (0..region).filter_map(|t| Some((t, window_index(&p, t, w, h)?))) {
                let texel = texsyn::passes::gather_aniso::color_at(
                    &p,
                    &gravel.analysis.colors,
                    state[3 * t],
                );
                blended += (out.colors[o] != texel) as usize;
            }
        }
    }
    eprintln!("one-frame fades: {blended} pixel-frames blended");
    assert!(blended > 0, "no pixel blended");
}

/// The fade's pop test (`AdvectOptions::fade_change`): GPU = CPU at a threshold other
/// than the default, and a lower threshold fades more pixels over the same frames.
#[test]
fn fade_change_sets_the_pop_test() {
    let gravel = Synth::gravel(32);
    let (w, h) = (48u32, 40u32);
    let params = output(w, h);
    let flow = FAST_VORTEX;
    let mut faded = Vec::new();
    for change in [20u32, 80] {
        let opts = AdvectOptions {
            fade: 2,
            fade_change: change,
            ..AdvectOptions::keep_look()
        };
        let mut frames = FrameLoop::mirrored_with_fade_room(&gravel, &params, opts);
        let region = frames.plan().fade_half_len() as usize / 3;
        let mut count = 0usize;
        for f in 0..8u64 {
            let (v, _) = frame_velocities(&flow, w, h, f);
            let p = frames.adv.frame_schedule().last().unwrap().params;
            assert_eq!(p.fade_change, change);
            frames.step_mirrored(&v, 1.0);
            assert!(
                frames.coords() == frames.cpu(),
                "threshold {change}, frame {} differs",
                f + 1
            );
            let state = &frames.cpu()[p.fade_dst as usize..][..3 * region];
            count += (0..region).filter(|&t| state[3 * t + 2][0] > 0).count();
        }
        faded.push(count);
    }
    eprintln!("pixel-frames fading at 20 and 80: {faded:?}");
    assert!(faded[0] > faded[1] && faded[1] > 0, "{faded:?}");
}

/// Fading (`AdvectOptions::fade`): GPU = CPU (coordinates, fade state and colours) over
/// frames of a fast vortex with `keep_look`, whose renewals pop; some pixels fade, none
/// for more than N frames, and a pixel that does not fade shows exactly its
/// coordinate's texel. Turning fading on between frames (the coordinate buffer grows)
/// starts every pixel unfaded, and the frames after it read the state.
#[test]
fn fading_frames_match_cpu_and_fade_pops() {
    let gravel = Synth::gravel(32);
    let a = gravel.analysis.clone();
    let (w, h) = (48u32, 40u32);
    let params = SynthParams {
        origin: [5, -3],
        ..output(w, h)
    };
    let n = 4u32;
    let opts = AdvectOptions {
        fade: n,
        ..AdvectOptions::keep_look()
    };
    let flow = FAST_VORTEX;
    let mut frames = FrameLoop::mirrored_with_fade_room(&gravel, &params, opts);
    let plan = frames.plan();
    assert!(frames.matches_mirror(), "frame 0 differs");
    let region = plan.fade_half_len() as usize / 3;
    let (mut faded, mut shown) = (0usize, 0usize);
    for f in 0..12u64 {
        let (v, _) = frame_velocities(&flow, w, h, f);
        let schedule = frames.adv.frame_schedule();
        let fade = schedule.last().unwrap();
        assert_eq!(fade.kind, texsyn::passes::plan::PassKind::Fade);
        let out = frames.step_mirrored(&v, 1.0);
        assert!(frames.matches_mirror(), "frame {} differs", f + 1);
        assert_eq!(frames.rgba(), rgba8(&out), "frame {}", f + 1);
        let p = &fade.params;
        let state = &frames.cpu()[p.fade_dst as usize..][..3 * region];
        for t in 0..region {
            let left = state[3 * t + 2][0];
            assert!((0..=n as i32).contains(&left), "{left} frames left");
            faded += (left > 0) as usize;
            if let (0, Some(o)) = (left, window_index(p, t, w, h)) {
                let texel = texsyn::passes::gather_aniso::color_at(p, &a.colors, state[3 * t]);
                assert_eq!(out.colors[o], texel);
                shown += 1;
            }
        }
    }
    eprintln!("fading: {faded} pixel-frames of {}", 12 * region);
    assert!(faded > 0 && shown > 0, "no pixel faded");
    // A shorter fade between frames: the fades under way go on with it (at most 2 frames
    // left), GPU = CPU.
    frames.set_options(AdvectOptions { fade: 2, ..opts });
    let (v, _) = frame_velocities(&flow, w, h, 12);
    let dst = frames.adv.frame_schedule().last().unwrap().params.fade_dst as usize;
    frames.step_mirrored(&v, 1.0);
    assert!(frames.matches_mirror(), "shorter fade differs");
    let cpu = frames.cpu();
    assert!((0..region).all(|t| (0..=2).contains(&cpu[dst + 3 * t + 2][0])));
    // Fading turned on between frames.
    let mut frames =
        FrameLoop::mirrored_with_fade_room(&gravel, &params, AdvectOptions::keep_look());
    assert_eq!(frames.coords().len(), plan.coord_buffer_len() as usize);
    for f in 0..4u64 {
        if f == 2 {
            frames.set_options(opts);
        }
        let (v, _) = frame_velocities(&flow, w, h, f);
        if f >= 2 {
            let src = frames.adv.frame_schedule().last().unwrap().params.fade_src;
            assert_eq!(src == 0, f == 2, "frame {}: fade_src {src}", f + 1);
        }
        let out = frames.step_mirrored(&v, 1.0);
        assert!(frames.matches_mirror_start(), "frame {} differs", f + 1);
        assert_eq!(frames.rgba(), rgba8(&out), "frame {}", f + 1);
    }
    // Turned on between `encode_step` and the submission of its encoder: the recorded
    // frame is kept (the enlarged buffer is filled in the next frame's encoder).
    let mut frames =
        FrameLoop::mirrored_with_fade_room(&gravel, &params, AdvectOptions::keep_look());
    for f in 0..3u64 {
        let (v, _) = frame_velocities(&flow, w, h, f);
        let buffer = velocity_buffer(&v);
        frames.step_mirrored_with(&v, 1.0, |adv| {
            let mut encoder = ctx().device.create_command_encoder(&Default::default());
            adv.encode_step(&mut encoder, &buffer, 1.0).unwrap();
            if f == 0 {
                adv.set_options(opts).unwrap();
            }
            ctx().queue.submit([encoder.finish()]);
        });
        assert!(
            frames.matches_mirror_start(),
            "encoded frame {} differs",
            f + 1
        );
    }
    ctx().take_uncaptured_errors().unwrap();
}
