//! What the frames look like under flows: uniform flows translate, periodic outputs wrap,
//! vortices keep the texture and its sharpness; the Lamb-Oseen vortex's profile.

use texsyn::flow::Flow;
use texsyn::gpu::advect::AdvectOptions;
use texsyn::passes::run_cpu_frame;
use texsyn::passes::velocity::quantize_velocity;
use texsyn::quality::texture_energy;
use texsyn::SynthParams;

use crate::common::ctx;
use crate::common::images::{exemplar_grey as ex_image, grey, plain_diff, warped_diff};
use crate::harness::*;

/// The frames leave the pixels inside coherent patches, which the correction would keep
/// or only nudge within the pixel: under a turning flow a sixth of the most corrected
/// level's pixels are skipped (0.16 measured; the second-finest level, whose patches are
/// fewer pixels across than the finest's), and a frame with the skip differs from one
/// without it in 0.5% of them, by more than a pixel in 0.01%.
#[test]
fn frames_leave_coherent_patches() {
    let gravel = Synth::gravel(64);
    let a = gravel.analysis.clone();
    let params = output(96, 96);
    let on = AdvectOptions::default();
    assert!(on.skip_coherent);
    let off = AdvectOptions {
        skip_coherent: false,
        ..on
    };
    let flow = Flow::Vortex {
        cx: 0.5,
        cy: 0.5,
        omega: 0.01,
    };
    let v = flow.sample(96, 96, 0.0).unwrap();
    let q: Vec<[i32; 2]> = v.iter().map(|&v| quantize_velocity(v, 1.0)).collect();
    let mut frames = FrameLoop::new(&gravel, &params, on);
    let plan = frames.plan();
    let jac = plan.jacobians();
    // The level the frames correct most: the second-finest (the finest is upsampled).
    let top = plan.levels.len() - 2;
    let p = plan.pass_params(&a, top);
    let (base, size) = (p.coord_base as usize, p.size);
    let n = (size[0] * size[1]) as usize;
    // Every correction of a default frame carries the switch.
    let schedule = plan.advect_schedule(&a, &on, 0);
    let corrections: Vec<_> = schedule
        .iter()
        .filter(|d| d.kind == texsyn::passes::plan::PassKind::CorrectAniso)
        .collect();
    assert!(!corrections.is_empty());
    assert!(corrections.iter().all(|d| d.params.coherent_skip == 1));
    let (mut skipped, mut differ, mut far) = (0usize, 0usize, 0usize);
    let count = 12u64;
    for t in 0..count {
        let start = frames.coords();
        // The share of the level's pixels a correction would skip, counted on the state
        // the frame starts from.
        skipped += (0..size[1])
            .flat_map(|y| (0..size[0]).map(move |x| [x, y]))
            .filter(|&px| texsyn::passes::correct_aniso::coherent_interior(&p, &start, &jac, px))
            .count();
        let frame = |o: &AdvectOptions| {
            let mut c = start.clone();
            run_cpu_frame(&a, &plan.advect_schedule(&a, o, t), &mut c, &jac, &[], &q).unwrap();
            c
        };
        let (c_on, c_off) = (frame(&on), frame(&off));
        differ += (0..n)
            .filter(|&i| c_on[base + i] != c_off[base + i])
            .count();
        far += (0..n)
            .filter(|&i| {
                let (a, b) = (c_on[base + i], c_off[base + i]);
                (a[0] - b[0]).abs().max((a[1] - b[1]).abs()) > 256
            })
            .count();
        frames.step(&v, 1.0);
        assert!(
            frames.coords() == c_on,
            "frame {} differs from the CPU",
            t + 1
        );
    }
    let total = (count as usize * n) as f64;
    let (skipped, differ) = (skipped as f64 / total, differ as f64 / total);
    eprintln!(
        "coherent interiors {skipped:.3}, pixels that differ {differ:.4}, by more than a pixel {:.4}",
        far as f64 / total
    );
    assert!(
        skipped > 0.1,
        "only {skipped} of the pixels are coherent interiors"
    );
    // The correction would only nudge some of them within the pixel.
    let far = far as f64 / total;
    assert!(
        differ > 0.0 && differ < 0.05,
        "{differ} of the pixels differ"
    );
    assert!(
        far < 0.002,
        "{far} of the pixels differ by more than a pixel"
    );
}

/// A uniform flow of whole pixels moves the coordinates of every level exactly, patch
/// seams included (with the finest level upsampled, through the drift's phase): without
/// corrections nearly every pixel equals the previous frame's shifted by the flow (the
/// first frames re-upsample a few pixels that continue no patch). The corrections then
/// retouch some: with the finest level advected, 0.3-6% of its pixels per frame; with it
/// upsampled, more (11-21% at (2, -1) pixels per frame, where the odd vertical speed
/// leaves the second-finest level half a pixel in place on every other frame, so its
/// corrections read the exemplar at other texels; an even speed retouches about none).
/// Either way the frames differ far less than unwarped ones.
#[test]
fn uniform_flow_of_whole_pixels_translates_exactly() {
    let gravel = Synth::gravel(64);
    let (w, h) = (96u32, 80u32);
    let params = output(w, h);
    let v = Flow::Uniform { vx: 2.0, vy: -1.0 }
        .sample(w, h, 0.0)
        .unwrap();
    for (upsample_finest, resynthesize, keep_look, fade) in [
        (true, 0, false, 0),
        (false, 0, false, 0),
        (true, 2, false, 0),
        (true, 0, true, 0),
        (true, 0, true, 8),
    ] {
        for passes in [0, 1] {
            let o = AdvectOptions {
                upsample_finest,
                passes,
                resynthesize,
                keep_look,
                fade,
                levels: if keep_look {
                    4
                } else {
                    2 + resynthesize.max(1)
                },
                ..Default::default()
            };
            let mut frames = FrameLoop::new(&gravel, &params, o);
            frames.run(5, &v, 1.0, |_, prev, cur| {
                let warped = warped_diff(prev, cur, w, h, |_, _| (2.0, -1.0), 6);
                let still = warped_diff(prev, cur, w, h, |_, _| (0.0, 0.0), 6);
                let (mut same, mut total) = (0, 0);
                for y in 6..h - 6 {
                    for x in 6..w - 6 {
                        let i = ((y * w + x) * 4) as usize;
                        let j = (((y + 1) * w + x - 2) * 4) as usize;
                        same += (cur[i] == prev[j]) as usize;
                        total += 1;
                    }
                }
                let same = same as f64 / total as f64;
                eprintln!(
                    "upsampled finest {upsample_finest}, re-synthesized {resynthesize}, \
                     keep_look {keep_look}, fade {fade}, passes {passes}: warped \
                     {warped:.3}, unwarped {still:.3}, identical {same:.3}"
                );
                // Measured over frames 1-5: 0.95-0.999 without corrections (the first
                // frame re-upsamples a few pixels that continue no patch), 0.94-0.997
                // with the finest level advected, 0.79-0.89 with it upsampled.
                // The warped difference against the unwarped: 0.6-5.6% and 0.1-4%,
                // and 8.5-18% with the finest level upsampled and corrections.
                // Re-synthesized levels: 0.73-0.92 without corrections (the advected
                // level's few re-upsampled pixels are 8x8 finest pixels each), warped
                // 7-30% of unwarped; with corrections 0.35-0.46 and 50-64%: they read
                // the exemplar at the advected level's sub-pixel offset, which a whole
                // pixel per frame of the finest level changes (see `AdvectOptions`).
                // `keep_look` remakes nothing under a uniform flow: 1.000 without
                // corrections (frame 0 makes the advected levels without jitter), 0.89-0.94
                // with them, warped 6-10% of unwarped.
                let (want, ratio) = match (passes, upsample_finest) {
                    (0, _) if keep_look => (0.99, 0.01),
                    _ if keep_look => (0.85, 0.15),
                    (0, _) if resynthesize > 0 => (0.7, 0.35),
                    _ if resynthesize > 0 => (0.3, 0.75),
                    (0, _) => (0.93, 0.1),
                    (_, false) => (0.9, 0.1),
                    _ => (0.75, 0.25),
                };
                assert!(
                    warped < ratio * still && same > want,
                    "upsampled finest {upsample_finest}, re-synthesized {resynthesize}, \
                     keep_look {keep_look}, passes {passes}: warped {warped}, unwarped \
                     {still}, identical {same}"
                );
            });
        }
    }
}

/// A periodic output (`tileable_output`) stays periodic under a flow: the pixels that
/// leave one edge come back at the other, so a uniform flow of whole pixels moves the
/// whole texture around the torus, edges included (they were clamped: the columns that
/// entered repeated the edge). GPU = CPU on such frames, with the finest level advected
/// and upsampled.
#[test]
fn periodic_outputs_wrap_around_under_a_flow() {
    let gravel = Synth::gravel(32);
    let (w, h) = (48u32, 40u32);
    let params = SynthParams {
        tileable_output: true,
        ..output(w, h)
    };
    let (vx, vy) = (3i32, -2i32);
    let v = Flow::Uniform {
        vx: vx as f32,
        vy: vy as f32,
    }
    .sample(w, h, 0.0)
    .unwrap();
    for upsample_finest in [false, true] {
        let o = AdvectOptions {
            upsample_finest,
            passes: 0,
            ..AdvectOptions::default()
        };
        let mut frames = FrameLoop::new(&gravel, &params, o).mirroring_the_gpu();
        let mut prev = frames.rgba();
        for t in 0..3u64 {
            assert!(
                frames.step_matches_mirror(t, &v, 1.0),
                "upsampled finest {upsample_finest}: frame {} differs from the CPU's",
                t + 1
            );
            let cur = frames.rgba();
            // Every pixel, edges included, against the previous frame moved around the
            // torus.
            let (mut same, mut edge_same, mut edge_total) = (0usize, 0usize, 0usize);
            for y in 0..h as i32 {
                for x in 0..w as i32 {
                    let i = ((y * w as i32 + x) * 4) as usize;
                    let sx = (x - vx).rem_euclid(w as i32);
                    let sy = (y - vy).rem_euclid(h as i32);
                    let j = ((sy * w as i32 + sx) * 4) as usize;
                    let eq = cur[i..i + 3] == prev[j..j + 3];
                    same += eq as usize;
                    if x < vx.abs()
                        || x >= w as i32 - vx.abs()
                        || y < vy.abs()
                        || y >= h as i32 - vy.abs()
                    {
                        edge_same += eq as usize;
                        edge_total += 1;
                    }
                }
            }
            let same = same as f64 / (w * h) as f64;
            let edge = edge_same as f64 / edge_total as f64;
            eprintln!(
                "upsampled finest {upsample_finest}, frame {}: identical {same:.3}, in the \
                 strips that crossed an edge {edge:.3}",
                t + 1
            );
            // Measured: 0.96-0.995 and 0.97-0.99 with the finest level advected; with it
            // upsampled, the odd speed leaves the second-finest level half a pixel in
            // place every other frame (see above), 0.90 and 0.83 at frame 1. Clamped at
            // the edges, the strips held 0.5-0.76.
            let (want, want_edge) = if upsample_finest {
                (0.85, 0.78)
            } else {
                (0.93, 0.93)
            };
            assert!(
                same > want && edge > want_edge,
                "upsampled finest {upsample_finest}, frame {}: identical {same}, edge strips {edge}",
                t + 1
            );
            prev = cur;
        }
    }
    ctx().take_uncaptured_errors().unwrap();
}

/// A uniform sub-pixel flow only translates the texture: thin features (the brick's
/// mortar lines, strips of their own patch between two seams) must not be taken for
/// distortion and re-upsampled every frame, which broke them apart.
#[test]
fn sub_pixel_uniform_flow_keeps_thin_features() {
    let brick = Synth::asset("brick");
    let (w, h) = (96u32, 96u32);
    let mut frames = FrameLoop::new(&brick, &output(w, h), AdvectOptions::default());
    let exi = ex_image(&brick.exemplar);
    let energy = |rgba: &[u8]| texture_energy(&exi, &grey(rgba, w, h), 3).unwrap();
    let e0 = energy(&frames.rgba());
    let v = Flow::Uniform { vx: 0.37, vy: 0.21 }
        .sample(w, h, 0.0)
        .unwrap();
    let e40 = energy(&frames.run(40, &v, 1.0, |_, _, _| {}));
    eprintln!("brick, uniform (0.37, 0.21): energy {e0:.5} -> {e40:.5} after 40 frames");
    assert!(e40 < 1.2 * e0, "energy {e0} -> {e40}");
}

/// What 300 frames of a rigid vortex (`omega` radians per frame) about the centre of a
/// 96x96 advection (64 px gravel crop) measure: the plain difference between two
/// independent syntheses, the mean flow-warped frame difference, the texture energy at
/// frames 0, 50 and 300, and the high-frequency energy at frames 0 and 300.
struct VortexRun {
    scratch: f64,
    warped: f64,
    energy: [f64; 3],
    sharpness: [f64; 2],
}

fn vortex_run(options: impl FnOnce(&SynthParams) -> AdvectOptions, omega: f32) -> VortexRun {
    let gravel = Synth::gravel(64);
    let (w, h) = (96u32, 96u32);
    let (params, v) = centred_vortex(w, h, omega);
    // Resynthesizing from scratch: how much two independent frames differ.
    let fresh = |seed| {
        let s = gravel
            .synth
            .synthesize_to_host(&SynthParams {
                seed,
                ..params.clone()
            })
            .unwrap();
        s.colors.iter().flatten().copied().collect::<Vec<u8>>()
    };
    let scratch = plain_diff(&fresh(1), &fresh(2));
    let mut frames = FrameLoop::new(&gravel, &params, options(&params));
    let exi = ex_image(&gravel.exemplar);
    let energy = |rgba: &[u8]| texture_energy(&exi, &grey(rgba, w, h), 2).unwrap();
    let sharp = |rgba: &[u8]| texsyn::quality::high_frequency_energy(&grey(rgba, w, h));
    let first = frames.rgba();
    let (energy0, sharp0) = (energy(&first), sharp(&first));
    let (mut warped, mut energy50) = (0.0, 0.0);
    let at = |x: f32, y: f32| {
        let i = (y as u32 * w + x as u32) as usize;
        (v[i][0], v[i][1])
    };
    let prev = frames.run(300, &v, 1.0, |t, prev, cur| {
        warped += warped_diff(prev, cur, w, h, at, 6) / 300.0;
        if t == 50 {
            energy50 = energy(cur);
        }
    });
    let run = VortexRun {
        scratch,
        warped,
        energy: [energy0, energy50, energy(&prev)],
        sharpness: [sharp0, sharp(&prev)],
    };
    eprintln!(
        "scratch {:.2}, warped {:.2}, energy 0 {:.5} 50 {:.5} 300 {:.5}, sharpness {:.5} -> {:.5}",
        run.scratch,
        run.warped,
        run.energy[0],
        run.energy[1],
        run.energy[2],
        run.sharpness[0],
        run.sharpness[1]
    );
    run
}

/// A vortex for 300 frames keeps the texture: no blur, steady energy, frames that follow
/// the flow.
#[test]
fn vortex_keeps_the_texture_for_300_frames() {
    let VortexRun {
        scratch,
        warped,
        energy: [_, energy50, energy300],
        sharpness: [sharp0, sharp300],
    } = vortex_run(|_| AdvectOptions::default(), 0.02);
    assert!(
        warped < 0.6 * scratch,
        "warped frame difference {warped} vs resynthesis {scratch}"
    );
    assert!(
        (energy300 / energy50 - 1.0).abs() < 0.2,
        "energy {energy50} -> {energy300}"
    );
    assert!(sharp300 > 0.8 * sharp0, "blurred: {sharp0} -> {sharp300}");
}

/// The same with the options recommended in 2D (`keep_look`, renewals faded over
/// two frames; the CLI's default): frame 300's texture energy within 20% of frame 0's,
/// the flow-warped difference well below a resynthesis's, no blur.
#[test]
fn recommended_options_keep_the_look_for_300_frames() {
    let recommended = |params: &SynthParams| {
        let options = AdvectOptions::recommended(params);
        assert!(options.keep_look && options.fade == 2);
        options
    };
    let VortexRun {
        scratch,
        warped,
        energy: [energy0, _, energy300],
        sharpness: [sharp0, sharp300],
    } = vortex_run(recommended, 0.01);
    assert!(
        (energy300 / energy0 - 1.0).abs() < 0.2,
        "energy {energy0} -> {energy300}"
    );
    assert!(
        warped < 0.6 * scratch,
        "warped {warped} vs resynthesis {scratch}"
    );
    assert!(sharp300 > 0.8 * sharp0, "blurred: {sharp0} -> {sharp300}");
}

/// Grass under a vortex: pixels that continue no patch must be re-synthesized, or they
/// spread and the correction settles them on the exemplar's flat content (leaves,
/// shadows), blurring the texture. Before they were flagged this kept 0.79 of frame 0's
/// high-frequency energy after 300 frames (advecting the finest level); then 0.97. Since
/// the finest level is upsampled, frame 300 keeps 0.88 of frame 0's, which is sharper
/// than the exemplar: 0.99 of the exemplar's (the blur measure).
#[test]
fn vortex_does_not_blur_grass() {
    let grass = Synth::asset("grass");
    let exemplar_sharpness = texsyn::quality::high_frequency_energy(&ex_image(&grass.exemplar));
    let (w, h) = (96u32, 96u32);
    let (params, v) = centred_vortex(w, h, 0.02);
    let mut frames = FrameLoop::new(&grass, &params, AdvectOptions::default());
    let sharpness = |rgba: &[u8]| texsyn::quality::high_frequency_energy(&grey(rgba, w, h));
    let sharp0 = sharpness(&frames.rgba());
    let sharp300 = sharpness(&frames.run(300, &v, 1.0, |_, _, _| {}));
    eprintln!("sharpness {sharp0} -> {sharp300}, exemplar {exemplar_sharpness}");
    assert!(
        sharp300 > 0.9 * exemplar_sharpness && sharp300 > 0.8 * sharp0,
        "blurred: sharpness {sharp0} -> {sharp300}, exemplar {exemplar_sharpness}"
    );
}

/// Re-synthesizing the levels below the finest every frame
/// (`AdvectOptions::resynthesize`) keeps a vortex's texture energy near frame 0's, where
/// advecting them lets it rise (the patches break up as they turn), at the price of
/// more change between frames.
#[test]
fn resynthesized_levels_keep_the_texture_energy_under_a_vortex() {
    let gravel = Synth::asset("gravel");
    let exi = ex_image(&gravel.exemplar);
    let (w, h) = (96u32, 96u32);
    let (params, v) = centred_vortex(w, h, 0.02);
    let mut figures = Vec::new();
    for (resynthesize, keep_look) in [(0, false), (3, false), (0, true)] {
        let o = if keep_look {
            AdvectOptions::keep_look()
        } else {
            AdvectOptions {
                resynthesize,
                levels: 2 + resynthesize.max(1),
                ..AdvectOptions::default()
            }
        };
        let mut frames = FrameLoop::new(&gravel, &params, o);
        let energy = |rgba: &[u8]| texture_energy(&exi, &grey(rgba, w, h), 3).unwrap();
        let first = frames.rgba();
        let mut warped = 0.0;
        let flow = |x: f32, y: f32| {
            let i = (y as u32 * w + x as u32) as usize;
            (v[i][0], v[i][1])
        };
        let last = frames.run(100, &v, 1.0, |_, prev, cur| {
            warped += warped_diff(prev, cur, w, h, flow, 6) / 100.0;
        });
        let (e0, e100) = (energy(&first), energy(&last));
        eprintln!(
            "re-synthesized {resynthesize}, keep_look {keep_look}: energy {e0:.5} -> \
             {e100:.5}, warped difference {warped:.3}"
        );
        figures.push((e0, e100, warped));
    }
    // Measured (twice the default vortex's speed): advected 0.0039 -> 0.0093, warped
    // difference 16.5; re-synthesized 0.0026 -> 0.0043, 21.1; `keep_look` 0.0040 ->
    // 0.0050, 19.8 (at the default speed and 256x256 it stays within 15% on gravel).
    let (advected, resynthesized, kept) = (figures[0], figures[1], figures[2]);
    for f in [resynthesized, kept] {
        assert!(f.1 < 1.7 * f.0 && f.1 < 0.6 * advected.1, "{figures:?}");
        assert!(f.2 < 1.6 * advected.2, "{figures:?}");
    }
    assert!(kept.1 < 1.4 * kept.0, "{figures:?}");
}

/// The Lamb-Oseen vortex: rigid at the centre, tangential everywhere, its speed peaking
/// near 1.12 core radii at 0.64 omega rc and falling as 1/r; parsed from four numbers.
#[test]
fn lamb_oseen_vortex_profile() {
    let (w, h) = (400u32, 200u32);
    let (omega, core) = (0.02f32, 0.1f32);
    let flow: Flow = "vortex:0.5,0.5,0.02,0.1".parse().unwrap();
    assert_eq!(
        flow,
        Flow::LambOseen {
            cx: 0.5,
            cy: 0.5,
            omega,
            core
        }
    );
    let v = flow.sample(w, h, 0.0).unwrap();
    let rc = core * h as f32; // 20 px: a fraction of the smaller side
    let mut peak = (0.0f32, 0.0f32);
    for y in 0..h {
        for x in 0..w {
            let (dx, dy) = (x as f32 + 0.5 - 200.0, y as f32 + 0.5 - 100.0);
            let r = dx.hypot(dy);
            let [vx, vy] = v[(y * w + x) as usize];
            // Tangential, clockwise on screen for positive omega (as the rigid vortex).
            assert!((vx * dx + vy * dy).abs() <= 1e-5 * r.max(1.0), "({x}, {y})");
            assert!(vy * dx - vx * dy >= 0.0);
            let speed = vx.hypot(vy);
            if r < 1.0 {
                // Rigid there: the rate is omega (1 - r^2 / 2 rc^2) to first order.
                assert!(
                    (speed / r - omega).abs() < 1e-3 * omega,
                    "centre rate {}",
                    speed / r
                );
            }
            if speed > peak.0 {
                peak = (speed, r);
            }
            if r > 6.0 * rc {
                // Beyond the core: omega rc^2 / r to within exp(-36).
                assert!((speed * r / (omega * rc * rc) - 1.0).abs() < 1e-4, "r {r}");
            }
        }
    }
    assert!((peak.0 / (omega * rc) - 0.638).abs() < 0.005, "{peak:?}");
    assert!((peak.1 / rc - 1.121).abs() < 0.05, "{peak:?}");
    // Three numbers stay the rigid rotation; bad cores are errors, not a NaN field.
    assert!(matches!(
        "vortex:0.5,0.5,0.02".parse::<Flow>().unwrap(),
        Flow::Vortex { .. }
    ));
    for bad in [
        "vortex:0.5,0.5,0.02,0",
        "vortex:0.5,0.5,0.02,-1",
        "vortex:9,0.5,0.02,0.1",
    ] {
        assert!(bad.parse::<Flow>().is_err(), "{bad}");
    }
    let zero = Flow::LambOseen {
        cx: 0.5,
        cy: 0.5,
        omega,
        core: 0.0,
    };
    assert!(zero.validate().is_err());
    // Sampled anyway (the library does not force validate first): still, never NaN,
    // also at a pixel centre that is the vortex's centre.
    let still = zero.sample(9, 9, 0.0).unwrap();
    assert!(still.iter().all(|v| *v == [0.0, 0.0]), "{still:?}");
}
