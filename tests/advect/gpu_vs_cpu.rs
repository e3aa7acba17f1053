//! Advection frames on the GPU equal their CPU mirror: under changing flows and options,
//! through caller-owned velocity buffers and textures, after new parameters or a new
//! analysis between frames.

use std::sync::Arc;

use texsyn::analysis::{analyze, AnalysisOptions};
use texsyn::flow::Flow;
use texsyn::gpu::advect::{quantize_velocity, AdvectOptions, Advection};
use texsyn::gpu::{synth::GpuSynthesizer, GpuContext};
use texsyn::passes::plan::SynthPlan;
use texsyn::passes::run_cpu_frame;
use texsyn::SynthParams;

use crate::common::{self, ctx};
use crate::harness::*;

#[test]
fn advection_frames_gpu_match_cpu() {
    let (a, synth, _) = Synth::gravel(32).parts();
    let params = SynthParams {
        width: 48,
        height: 40,
        origin: [5, -3],
        ..SynthParams::default()
    };
    let opts = AdvectOptions::default();
    let mut adv = Advection::new(synth.clone(), &params, opts).unwrap();
    let plan: SynthPlan = adv.plan().clone();
    let jac = plan.jacobians();
    let mut cpu = cpu_frame0(&a, &plan, &opts, plan.coord_buffer_len());
    assert!(adv.read_coords().unwrap() == cpu, "frame 0 differs");
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
        adv.set_options(o).unwrap();
        if f == 3 {
            adv.set_params(&SynthParams {
                distance: texsyn::DistanceMode::Projected,
                ..params.clone()
            })
            .unwrap();
        }
        let plan = adv.plan().clone();
        let schedule = adv.frame_schedule();
        assert_eq!(
            schedule.len() > plan.advect_schedule(&a, &o, f as u64).len(),
            f == 3,
            "the levels above the advected ones are made again after set_params only"
        );
        let v = flow.sample(48, 40, f as f32).unwrap();
        adv.step(&v, 1.5).unwrap();
        let q: Vec<[i32; 2]> = v.iter().map(|&v| quantize_velocity(v, 1.5)).collect();
        let out = run_cpu_frame(&a, &schedule, &mut cpu, &jac, &[], &q).unwrap();
        assert!(
            adv.read_coords().unwrap() == cpu,
            "frame {} ({flow:?}) differs",
            f + 1
        );
        let rgba: Vec<u8> = out.colors.iter().flatten().copied().collect();
        assert_eq!(adv.read_rgba8().unwrap(), rgba);
    }
    // Frame 0 of `keep_look` makes the levels below the coarsest advected one as its
    // frames do; GPU = CPU on it and on a frame after it.
    let opts = AdvectOptions::keep_look();
    let mut adv = Advection::new(synth.clone(), &params, opts).unwrap();
    let mut cpu = cpu_frame0(&a, adv.plan(), &opts, adv.plan().coord_buffer_len());
    assert!(
        adv.read_coords().unwrap() == cpu,
        "keep_look: frame 0 differs"
    );
    // The same with anchored renewals (half of them upsampled, then all anchored),
    // alongside: the vortex turns the coarsest advected level past its threshold
    // within these frames. They must match, and change the frames (else the anchored
    // path went untested).
    let anchored = AdvectOptions {
        anchor_spacing: 4,
        anchor_upsample: 0.5,
        ..opts
    };
    let mut an = Advection::new(synth.clone(), &params, anchored).unwrap();
    let mut an_cpu = cpu.clone();
    let v = flows[0].sample(48, 40, 0.0).unwrap();
    assert!(
        step_matches_cpu(&mut adv, &a, 0, &mut cpu, &v, 1.0),
        "keep_look: frame 1 differs"
    );
    assert!(
        step_matches_cpu(&mut an, &a, 0, &mut an_cpu, &v, 1.0),
        "keep_look, anchored renewals: frame 1 differs"
    );
    for t in 1..6u64 {
        if t == 3 {
            let all = AdvectOptions {
                anchor_upsample: 0.0,
                ..anchored
            };
            an.set_options(all).unwrap();
        }
        assert!(
            step_matches_cpu(&mut an, &a, t, &mut an_cpu, &v, 2.0),
            "keep_look, anchored renewals: frame {} differs",
            t + 1
        );
        assert!(step_matches_cpu(&mut adv, &a, t, &mut cpu, &v, 2.0));
    }
    assert!(an_cpu != cpu, "the anchored renewals changed nothing");
    let opts = AdvectOptions::default();
    // The caller-owned GPU velocity path gives the same frame as host velocities.
    let v = Flow::Vortex {
        cx: 0.5,
        cy: 0.5,
        omega: -0.03,
    }
    .sample(48, 40, 0.0)
    .unwrap();
    let mut a1 = Advection::new(synth.clone(), &params, opts).unwrap();
    let mut a2 = Advection::new(synth, &params, opts).unwrap();
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
    a1.step(&host, 2.0).unwrap();
    let buffer = velocity_buffer(&gpu);
    let mut encoder = ctx().device.create_command_encoder(&Default::default());
    a2.encode_step(&mut encoder, &buffer, 2.0).unwrap();
    ctx().queue.submit([encoder.finish()]);
    assert!(a1.read_coords().unwrap() == a2.read_coords().unwrap());
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
    let (_, synth, _) = Synth::gravel(32).parts();
    let (w, h) = (40u32, 36u32);
    let params = SynthParams {
        width: w,
        height: h,
        ..SynthParams::default()
    };
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
    let mut reference = Advection::new(synth.clone(), &params, opts).unwrap();
    for dt in [1.0, 0.75] {
        reference.step(&host, dt).unwrap();
    }
    let want = reference.read_coords().unwrap();
    let usage = wgpu::TextureUsages::TEXTURE_BINDING;
    use wgpu::TextureFormat as F;
    for format in [F::Rg32Float, F::Rgba32Float, F::Rg16Float, F::Rgba16Float] {
        let t = texture(format, usage, [w, h]);
        let mut adv = Advection::new(synth.clone(), &params, opts).unwrap();
        for dt in [1.0, 0.75] {
            let mut encoder = ctx().device.create_command_encoder(&Default::default());
            adv.encode_step_texture(&mut encoder, &t, dt).unwrap();
            ctx().queue.submit([encoder.finish()]);
        }
        assert!(adv.read_coords().unwrap() == want, "{format:?}");
    }
    // Refused before anything is recorded: the encoder still submits, the frame count
    // stays.
    let mut adv = Advection::new(synth, &params, opts).unwrap();
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
    let (a, synth, _) = Synth::gravel(32).parts();
    let (params, v) = centred_vortex(64, 64, 0.05);
    let opts = AdvectOptions::keep_look();
    let reseeded = SynthParams {
        seed: params.seed + 1,
        randomness: vec![0.8],
        ..params.clone()
    };
    let mut changed = Advection::new(synth.clone(), &params, opts).unwrap();
    let mut kept = Advection::new(synth.clone(), &params, opts).unwrap();
    let fresh = Advection::new(synth.clone(), &reseeded, opts).unwrap();
    for adv in [&mut changed, &mut kept] {
        adv.step(&v, 1.0).unwrap();
    }
    changed.set_params(&reseeded).unwrap();
    kept.set_params(&params).unwrap();
    let frame = kept.plan().advect_schedule(&a, &opts, 1);
    assert_eq!(kept.frame_schedule().len(), frame.len());
    assert!(changed.frame_schedule().len() > frame.len());
    let mut cpu = changed.read_coords().unwrap();
    assert!(
        step_matches_cpu(&mut changed, &a, 1, &mut cpu, &v, 1.0),
        "the frame after set_params differs from the CPU mirror"
    );
    kept.step(&v, 1.0).unwrap();
    let plan = changed.plan().clone();
    let coarsest = plan.levels.len() - opts.levels;
    assert!(coarsest > 0, "no level above the advected ones");
    let (c, f, k) = (
        changed.read_coords().unwrap(),
        fresh.read_coords().unwrap(),
        kept.read_coords().unwrap(),
    );
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
    let differing = |x: &Advection, y: &Advection| {
        let (p, q) = (x.read_rgba8().unwrap(), y.read_rgba8().unwrap());
        p.chunks(4).zip(q.chunks(4)).filter(|(s, t)| s != t).count() as f64 / (64.0 * 64.0)
    };
    let first = differing(&changed, &kept);
    for _ in 0..10 {
        for adv in [&mut changed, &mut kept] {
            adv.step(&v, 1.0).unwrap();
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
        let a = Arc::new(analyze(&ex, &opts, |_| {}).unwrap());
        (a.clone(), Arc::new(GpuSynthesizer::new(ctx(), a).unwrap()))
    };
    let ((_, strong), (light_a, light)) = (analysed(1.0), analysed(0.25));
    let params = SynthParams {
        width: 40,
        height: 36,
        ..SynthParams::default()
    };
    let opts = AdvectOptions::default();
    let mut swapped = Advection::new(strong.clone(), &params, opts).unwrap();
    let mut kept = Advection::new(strong.clone(), &params, opts).unwrap();
    let v = Flow::Vortex {
        cx: 0.5,
        cy: 0.5,
        omega: 0.05,
    }
    .sample(40, 36, 0.0)
    .unwrap();
    for adv in [&mut swapped, &mut kept] {
        for _ in 0..2 {
            adv.step(&v, 1.0).unwrap();
        }
    }
    swapped.set_synthesizer(light.clone()).unwrap();
    assert!(Arc::ptr_eq(swapped.synthesizer(), &light));
    let mut cpu = swapped.read_coords().unwrap();
    assert!(
        step_matches_cpu(&mut swapped, &light_a, 2, &mut cpu, &v, 1.0),
        "the frame after the swap differs from the CPU mirror"
    );
    kept.step(&v, 1.0).unwrap();
    assert_ne!(
        swapped.read_coords().unwrap(),
        kept.read_coords().unwrap(),
        "the new feature weight changed nothing"
    );
    // Coordinates are positions in a 32x32 exemplar: a 40x40 one is refused, and so is
    // a synthesizer on another context (the advection's buffers live on its own); a
    // refused swap leaves the advection as it was.
    let before = swapped.read_coords().unwrap();
    let (_, other, _) = Synth::gravel(40).parts();
    let e = swapped.set_synthesizer(other).unwrap_err().to_string();
    assert!(e.contains("same size"), "{e}");
    let elsewhere = GpuContext::headless().unwrap();
    let foreign = Arc::new(GpuSynthesizer::new(&elsewhere, light_a.clone()).unwrap());
    assert!(swapped.set_synthesizer(foreign.clone()).is_err());
    assert!(swapped.set_synthesizer(foreign).is_err());
    assert!(Arc::ptr_eq(swapped.synthesizer(), &light));
    assert_eq!(swapped.read_coords().unwrap(), before);
    let mut cpu = before;
    assert!(step_matches_cpu(
        &mut swapped,
        &light_a,
        3,
        &mut cpu,
        &v,
        1.0
    ));
}
