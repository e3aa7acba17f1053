//! Advection frames on the GPU equal their CPU mirror: under changing flows and options,
//! through caller-owned velocity buffers and textures, after new parameters or a new
//! analysis between frames.

use std::sync::Arc;

use texsyn::analysis::AnalysisOptions;
use texsyn::flow::Flow;
use texsyn::gpu::advect::AdvectOptions;
use texsyn::gpu::{synth::GpuSynthesizer, GpuContext};
use texsyn::passes::velocity::quantize_velocity;
use texsyn::SynthParams;

use crate::common::{self, ctx};
use crate::harness::*;

#[test]
fn advection_frames_gpu_match_cpu() {
    let gravel = Synth::gravel(32);
    let a = gravel.analysis.clone();
    let params = SynthParams {
        origin: [5, -3],
        ..output(48, 40)
    };
    let opts = AdvectOptions::default();
    let mut frames = FrameLoop::mirrored(&gravel, &params, opts);
    assert!(frames.matches_mirror(), "frame 0 differs");
    let flows = [
        Flow::Vortex {
            cx: 0.3,
            cy: 0.6,
            omega: 0.05,
        },
        Flow::Source {
            cx: 0.5,
            cy: 0.5,
            strength: 2.5,
        },
        Flow::Uniform { vx: 1.3, vy: -0.7 },
        Flow::Vortex {
            cx: 0.6,
            cy: 0.4,
            omega: -0.04,
        },
        Flow::Vortex {
            cx: 0.4,
            cy: 0.5,
            omega: 0.03,
        },
        Flow::Source {
            cx: 0.6,
            cy: 0.3,
            strength: -2.0,
        },
        Flow::Uniform { vx: 6.0, vy: -5.0 },
        Flow::Uniform { vx: 5.5, vy: 4.5 },
    ];
    for (f, flow) in flows.iter().enumerate() {
        // Both ways of scoring the similarity sets, in turn; quarter-pixel reads but in
        // frame 3; from frame 4 on the projected distance at every level, so that the
        // most corrected level reads quarter pixels from its supersampled tables (the
        // second-finest; in frame 5, which advects the finest level too, the finest) and
        // the coarser advected levels read them without tables (interpolating in the
        // shader). Frame 2 also corrects the pixels inside coherent patches. Frame 6
        // re-synthesizes two levels below the finest (their upsampling following the
        // drift that frame 3's uniform flow left). Frames 8 and 9 advect every level
        // under fast uniform flows, so that the coarse levels shift by whole pixels of
        // their own as the drift crosses them. Frame 4 keeps the look (`keep_look`:
        // the levels below the coarsest advected one remade where the vortex turns them).
        let o = AdvectOptions {
            interpolate_sets: f % 2 == 1,
            quarter_reads: f != 2,
            skip_coherent: f != 1,
            upsample_finest: f != 4,
            resynthesize: if f == 5 { 2 } else { 0 },
            keep_look: f == 3,
            levels: match f {
                3 | 5 => 4,
                7 | 8 => 16,
                _ => opts.levels,
            },
            ..opts
        };
        frames.set_options(o);
        if f == 3 {
            frames
                .adv
                .set_params(&SynthParams {
                    distance: texsyn::DistanceMode::Projected,
                    ..params.clone()
                })
                .unwrap();
        }
        assert_eq!(
            frames.adv.frame_schedule().len()
                > frames.plan().advect_schedule(&a, &o, f as u64).len(),
            f == 3,
            "the levels above the advected ones are made again after set_params only"
        );
        let v = flow.sample(48, 40, f as f32).unwrap();
        let out = frames.step_mirrored(&v, 1.5);
        assert!(
            frames.matches_mirror(),
            "frame {} ({flow:?}) differs",
            f + 1
        );
        assert_eq!(frames.rgba(), rgba8(&out));
    }
    // Frame 0 of `keep_look` makes the levels below the coarsest advected one as its
    // frames do; GPU = CPU on it and on a frame after it.
    let opts = AdvectOptions::keep_look();
    let mut kept = FrameLoop::mirrored(&gravel, &params, opts);
    assert!(kept.matches_mirror(), "keep_look: frame 0 differs");
    // The same with anchored renewals (half of them upsampled, then all anchored),
    // alongside: the vortex turns the coarsest advected level past its threshold
    // within these frames. They must match, and change the frames (else the anchored
    // path went untested).
    let anchored = AdvectOptions {
        anchor_spacing: 4,
        anchor_upsample: 0.5,
        ..opts
    };
    let mut an = FrameLoop::new(&gravel, &params, anchored).with_mirror(kept.cpu().to_vec());
    let v = flows[0].sample(48, 40, 0.0).unwrap();
    assert!(
        kept.step_matches_mirror(0, &v, 1.0),
        "keep_look: frame 1 differs"
    );
    assert!(
        an.step_matches_mirror(0, &v, 1.0),
        "keep_look, anchored renewals: frame 1 differs"
    );
    for t in 1..6u64 {
        if t == 3 {
            let all = AdvectOptions {
                anchor_upsample: 0.0,
                ..anchored
            };
            an.set_options(all);
        }
        assert!(
            an.step_matches_mirror(t, &v, 2.0),
            "keep_look, anchored renewals: frame {} differs",
            t + 1
        );
        assert!(kept.step_matches_mirror(t, &v, 2.0));
    }
    assert!(
        an.cpu() != kept.cpu(),
        "the anchored renewals changed nothing"
    );
    let opts = AdvectOptions::default();
    // The caller-owned GPU velocity path gives the same frame as host velocities.
    let v = Flow::Vortex {
        cx: 0.5,
        cy: 0.5,
        omega: -0.03,
    }
    .sample(48, 40, 0.0)
    .unwrap();
    let mut a1 = FrameLoop::new(&gravel, &params, opts);
    let mut a2 = FrameLoop::new(&gravel, &params, opts);
    // A non-finite component counts as 0 on its own, on both paths (the GPU zeroed the
    // whole velocity): the host gets the zeros, the buffer NaN and infinity.
    let (mut host, mut gpu) = (v.clone(), v.clone());
    let bad = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY];
    for i in (0..v.len()).step_by(7) {
        host[i][i % 2] = 0.0;
        gpu[i][i % 2] = bad[i % 3];
        assert_eq!(
            quantize_velocity(gpu[i], 2.0),
            quantize_velocity(host[i], 2.0)
        );
    }
    a1.step(&host, 2.0);
    a2.step_through_buffer(&gpu, 2.0);
    assert!(a1.coords() == a2.coords());
}

/// The 16-bit float of `x`, which must be 0, NaN or a normal 16-bit value held exactly
/// (the test's velocities are multiples of 1/64 below 8).
fn f16_bits(x: f32) -> u16 {
    if x.is_nan() {
        return 0x7e00;
    }
    let b = x.to_bits();
    let sign = ((b >> 16) & 0x8000) as u16;
    if x == 0.0 {
        return sign;
    }
    let exp = ((b >> 23) & 0xff) as i32 - 127 + 15;
    assert!(
        (1..31).contains(&exp) && b & 0x1fff == 0,
        "{x} is no exact f16"
    );
    sign | ((exp as u16) << 10) | ((b >> 13) & 0x3ff) as u16
}

/// A velocity texture the caller owns (`Advection::encode_step_texture`: red, green = x,
/// y): the same frames as the host path, in 32- and 16-bit float formats of two and four
/// channels (a non-finite component 0, as in a buffer); a texture of the wrong size,
/// format or usage is an error before anything is recorded.
#[test]
fn caller_velocity_texture_gives_the_host_paths_frames() {
    let gravel = Synth::gravel(32);
    let (w, h) = (40u32, 36u32);
    let params = output(w, h);
    // Velocities that 16-bit floats hold exactly (multiples of 1/64 below 8).
    let v: Vec<[f32; 2]> = Flow::Vortex {
        cx: 0.4,
        cy: 0.6,
        omega: 0.05,
    }
    .sample(w, h, 0.0)
    .unwrap()
    .iter()
    .map(|p| p.map(|c| (c * 64.0).round() / 64.0))
    .collect();
    let texture = |format: wgpu::TextureFormat, usage: wgpu::TextureUsages, size: [u32; 2]| {
        let texels: Vec<u8> = (0..(size[0] * size[1]) as usize)
            .flat_map(|i| {
                let p = v.get(i).copied().unwrap_or([0.0; 2]);
                // Green of pixel 5 is NaN (the host gets 0 there).
                let g = if i == 5 { f32::NAN } else { p[1] };
                let rgba = [p[0], g, 7.0, 1.0];
                let n = format.components() as usize;
                let bytes = format.block_copy_size(None).unwrap() as usize / n;
                rgba[..n]
                    .iter()
                    .flat_map(|&x| match bytes {
                        4 => x.to_le_bytes().to_vec(),
                        2 => f16_bits(x).to_le_bytes().to_vec(),
                        _ => vec![0u8; bytes],
                    })
                    .collect::<Vec<u8>>()
            })
            .collect();
        wgpu::util::DeviceExt::create_texture_with_data(
            &ctx().device,
            &ctx().queue,
            &wgpu::TextureDescriptor {
                label: None,
                size: wgpu::Extent3d {
                    width: size[0],
                    height: size[1],
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            },
            wgpu::util::TextureDataOrder::LayerMajor,
            &texels,
        )
    };
    let mut host = v.clone();
    host[5][1] = 0.0;
    let opts = AdvectOptions::default();
    let mut reference = FrameLoop::new(&gravel, &params, opts);
    for dt in [1.0, 0.75] {
        reference.step(&host, dt);
    }
    let want = reference.coords();
    let usage = wgpu::TextureUsages::TEXTURE_BINDING;
    use wgpu::TextureFormat as F;
    for format in [F::Rg32Float, F::Rgba32Float, F::Rg16Float, F::Rgba16Float] {
        let t = texture(format, usage, [w, h]);
        let mut frames = FrameLoop::new(&gravel, &params, opts);
        for dt in [1.0, 0.75] {
            let mut encoder = ctx().device.create_command_encoder(&Default::default());
            frames
                .adv
                .encode_step_texture(&mut encoder, &t, dt)
                .unwrap();
            ctx().queue.submit([encoder.finish()]);
        }
        assert!(frames.coords() == want, "{format:?}");
    }
    // Refused before anything is recorded: the encoder still submits, the frame count
    // stays.
    let mut adv = FrameLoop::new(&gravel, &params, opts).adv;
    let bad = [
        (texture(F::Rg32Float, usage, [w + 1, h]), "41x36"),
        (texture(F::Rgba8Unorm, usage, [w, h]), "Rgba8Unorm"),
        (
            texture(F::Rg32Float, wgpu::TextureUsages::COPY_DST, [w, h]),
            "TEXTURE_BINDING",
        ),
    ];
    for (t, needle) in &bad {
        let mut encoder = ctx().device.create_command_encoder(&Default::default());
        let e = adv
            .encode_step_texture(&mut encoder, t, 1.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains(needle), "{e}");
        ctx().queue.submit([encoder.finish()]);
    }
    assert_eq!(adv.frame(), 0);
    ctx().take_uncaptured_errors().unwrap();
}

/// Synthesis parameters (seed, randomness, ...) may change between frames. The
/// frames do not jitter, so a new seed or randomness acts through the levels above the
/// advected ones: the frame after `set_params` makes them again (GPU = CPU), as a new
/// advection with those parameters makes them, and the texture takes them on where the
/// frames renew it. Setting the same parameters again remakes nothing.
#[test]
fn a_new_seed_between_frames_reaches_the_texture() {
    let gravel = Synth::gravel(32);
    let a = gravel.analysis.clone();
    let (params, v) = centred_vortex(64, 64, 0.05);
    let opts = AdvectOptions::keep_look();
    let reseeded = SynthParams {
        seed: params.seed + 1,
        randomness: vec![0.8],
        ..params.clone()
    };
    let mut changed = FrameLoop::new(&gravel, &params, opts);
    let mut kept = FrameLoop::new(&gravel, &params, opts);
    let fresh = FrameLoop::new(&gravel, &reseeded, opts);
    for frames in [&mut changed, &mut kept] {
        frames.step(&v, 1.0);
    }
    changed.adv.set_params(&reseeded).unwrap();
    kept.adv.set_params(&params).unwrap();
    let frame = kept.plan().advect_schedule(&a, &opts, 1);
    assert_eq!(kept.adv.frame_schedule().len(), frame.len());
    assert!(changed.adv.frame_schedule().len() > frame.len());
    let mut changed = changed.mirroring_the_gpu();
    assert!(
        changed.step_matches_mirror(1, &v, 1.0),
        "the frame after set_params differs from the CPU mirror"
    );
    kept.step(&v, 1.0);
    let plan = changed.plan();
    let coarsest = plan.levels.len() - opts.levels;
    assert!(coarsest > 0, "no level above the advected ones");
    let (c, f, k) = (changed.coords(), fresh.coords(), kept.coords());
    let mut moved = 0;
    for l in &plan.levels[..coarsest] {
        let r = l.coord_base as usize..(l.coord_base + l.size[0] * l.size[1]) as usize;
        assert!(c[r.clone()] == f[r.clone()], "level {} differs", l.level);
        moved += c[r.clone()]
            .iter()
            .zip(&k[r])
            .filter(|(x, y)| x != y)
            .count();
    }
    assert!(moved > 0, "the new seed changed no coarse coordinate");
    // Then the vortex renews the advected levels from them: the frames part from those
    // of the advection that kept its seed.
    let differing = |x: &FrameLoop, y: &FrameLoop| {
        let (p, q) = (x.rgba(), y.rgba());
        p.chunks(4).zip(q.chunks(4)).filter(|(s, t)| s != t).count() as f64 / (64.0 * 64.0)
    };
    let first = differing(&changed, &kept);
    for _ in 0..10 {
        for frames in [&mut changed, &mut kept] {
            frames.step(&v, 1.0);
        }
    }
    let later = differing(&changed, &kept);
    assert!(later > 0.5 && later >= first, "{first} -> {later}");
}

/// Synthesis parameters may change between frames, the feature weight too: it lives in
/// the analysis, so a host swaps in the exemplar analysed with another weight (`Advection::set_synthesizer`). The coordinates
/// carry over, the next frame corrects them against the new analysis (GPU = CPU), and it
/// changes the result; an analysis of another exemplar size is refused.
#[test]
fn frames_continue_with_another_feature_weight() {
    let ex = common::gravel_crop(32);
    // The darkest quarter of the exemplar as its features.
    let mut grey: Vec<f32> = ex
        .colors
        .iter()
        .map(|c| c[0] as f32 + c[1] as f32 + c[2] as f32)
        .collect();
    let mut sorted = grey.clone();
    sorted.sort_by(f32::total_cmp);
    let t = sorted[sorted.len() / 4];
    let inside: Vec<bool> = grey.drain(..).map(|g| g <= t).collect();
    let mask = texsyn::analysis::feature::FeatureMask::new(ex.width, ex.height, inside).unwrap();
    let analysed = |w: f32| {
        let opts = AnalysisOptions {
            feature_mask: Some(mask.clone()),
            feature_weight: Some(w),
            ..AnalysisOptions::default()
        };
        Synth::analysed(ex.clone(), &opts)
    };
    let (strong, light) = (analysed(1.0), analysed(0.25));
    let params = output(40, 36);
    let opts = AdvectOptions::default();
    let mut swapped = FrameLoop::new(&strong, &params, opts);
    let mut kept = FrameLoop::new(&strong, &params, opts);
    let v = Flow::Vortex {
        cx: 0.5,
        cy: 0.5,
        omega: 0.05,
    }
    .sample(40, 36, 0.0)
    .unwrap();
    for frames in [&mut swapped, &mut kept] {
        for _ in 0..2 {
            frames.step(&v, 1.0);
        }
    }
    swapped.set_synthesizer(&light);
    assert!(Arc::ptr_eq(swapped.adv.synthesizer(), &light.synth));
    let mut swapped = swapped.mirroring_the_gpu();
    assert!(
        swapped.step_matches_mirror(2, &v, 1.0),
        "the frame after the swap differs from the CPU mirror"
    );
    kept.step(&v, 1.0);
    assert_ne!(
        swapped.coords(),
        kept.coords(),
        "the new feature weight changed nothing"
    );
    // Coordinates are positions in a 32x32 exemplar: a 40x40 one is refused, and so is
    // a synthesizer on another context (the advection's buffers live on its own); a
    // refused swap leaves the advection as it was.
    let before = swapped.coords();
    let other = Synth::gravel(40);
    let e = swapped
        .adv
        .set_synthesizer(other.synth)
        .unwrap_err()
        .to_string();
    assert!(e.contains("same size"), "{e}");
    let elsewhere = GpuContext::headless().unwrap();
    let foreign = Arc::new(GpuSynthesizer::new(&elsewhere, light.analysis.clone()).unwrap());
    assert!(swapped.adv.set_synthesizer(foreign.clone()).is_err());
    assert!(swapped.adv.set_synthesizer(foreign).is_err());
    assert!(Arc::ptr_eq(swapped.adv.synthesizer(), &light.synth));
    assert_eq!(swapped.coords(), before);
    let mut swapped = swapped.with_mirror(before);
    assert!(swapped.step_matches_mirror(3, &v, 1.0));
}
