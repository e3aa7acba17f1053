//! Texture advection: GPU = CPU, uniform flows translate, vortices keep the texture.

use std::sync::{Arc, OnceLock};

use texsyn::analysis::{analyze, Analysis, AnalysisOptions, Exemplar};
use texsyn::flow::Flow;
use texsyn::gpu::advect::{quantize_velocity, AdvectOptions, Advection};
use texsyn::gpu::{synth::GpuSynthesizer, GpuContext};
use texsyn::passes::plan::SynthPlan;
use texsyn::passes::run_cpu_frame;
use texsyn::quality::{texture_energy, FloatImage};
use texsyn::SynthParams;

fn ctx() -> &'static GpuContext {
    static CTX: OnceLock<GpuContext> = OnceLock::new();
    CTX.get_or_init(|| {
        GpuContext::headless().expect("a Vulkan adapter (lavapipe) is required for the tests")
    })
}

fn crop(size: u32) -> Exemplar {
    let full =
        texsyn::image_io::load_exemplar(std::path::Path::new("assets/gravel.png")).unwrap();
    let c = full.channels as usize;
    let (mut values, mut colors) = (Vec::new(), Vec::new());
    for y in 0..size as usize {
        for x in 0..size as usize {
            let i = y * full.width as usize + x;
            values.extend_from_slice(&full.values[i * c..(i + 1) * c]);
            colors.push(full.colors[i]);
        }
    }
    Exemplar {
        width: size,
        height: size,
        channels: full.channels,
        values,
        colors,
    }
}

fn setup(size: u32) -> (Arc<Analysis>, Arc<GpuSynthesizer>, Exemplar) {
    let ex = crop(size);
    let a = Arc::new(analyze(&ex, &AnalysisOptions::default(), |_| {}).unwrap());
    let s = Arc::new(GpuSynthesizer::new(ctx(), a.clone()).unwrap());
    (a, s, ex)
}

fn grey(rgba: &[u8], w: u32, h: u32) -> FloatImage {
    FloatImage::new(w, h, 1, rgba.chunks(4).map(|p| p[0] as f32 / 255.0).collect()).unwrap()
}

fn ex_image(ex: &Exemplar) -> FloatImage {
    FloatImage::new(
        ex.width,
        ex.height,
        1,
        ex.colors.iter().map(|p| p[0] as f32 / 255.0).collect(),
    )
    .unwrap()
}

/// Mean absolute difference between `b` and `a` shifted by (dx, dy) (b[p] vs a[p - d]),
/// over the pixels where both exist, away from the border by `m`.
fn warped_diff(a: &[u8], b: &[u8], w: u32, h: u32, d: impl Fn(f32, f32) -> (f32, f32), m: u32) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for y in m..h - m {
        for x in m..w - m {
            let (dx, dy) = d(x as f32 + 0.5, y as f32 + 0.5);
            // a bilinearly at p - d.
            let (fx, fy) = (x as f32 - dx, y as f32 - dy);
            let (x0, y0) = (fx.floor() as i64, fy.floor() as i64);
            if x0 < 0 || y0 < 0 || x0 + 1 >= w as i64 || y0 + 1 >= h as i64 {
                continue;
            }
            let (tx, ty) = ((fx - x0 as f32) as f64, (fy - y0 as f32) as f64);
            let px = |xx: i64, yy: i64| a[(yy as usize * w as usize + xx as usize) * 4] as f64;
            let v = px(x0, y0) * (1.0 - tx) * (1.0 - ty)
                + px(x0 + 1, y0) * tx * (1.0 - ty)
                + px(x0, y0 + 1) * (1.0 - tx) * ty
                + px(x0 + 1, y0 + 1) * tx * ty;
            let i = (y * w + x) as usize * 4;
            sum += (b[i] as f64 - v).abs();
            n += 1;
        }
    }
    sum / n.max(1) as f64
}

#[test]
fn advection_frames_gpu_match_cpu() {
    let (a, synth, _) = setup(32);
    let params = SynthParams {
        width: 48,
        height: 40,
        origin: [5, -3],
        ..SynthParams::default()
    };
    let opts = AdvectOptions::default();
    let mut adv = Advection::new(ctx(), synth.clone(), &params, opts).unwrap();
    let plan: SynthPlan = adv.plan().clone();
    let jac = plan.jacobians();
    let mut cpu = vec![[0i32; 2]; (plan.coord_count + plan.flag_count()) as usize];
    run_cpu_frame(&a, &plan.advect_first_schedule(&a, opts.nearest), &mut cpu, &jac, &[], &[]);
    assert!(adv.read_coords(ctx()).unwrap() == cpu, "frame 0 differs");
    let flows = [
        Flow::Vortex { cx: 0.3, cy: 0.6, omega: 0.05 },
        Flow::Source { cx: 0.5, cy: 0.5, strength: 2.5 },
        Flow::Uniform { vx: 1.3, vy: -0.7 },
    ];
    for (f, flow) in flows.iter().enumerate() {
        let v = flow.sample(48, 40, f as f32).unwrap();
        adv.step(ctx(), &v, 1.5).unwrap();
        let q: Vec<[i32; 2]> = v.iter().map(|&v| quantize_velocity(v, 1.5)).collect();
        let out = run_cpu_frame(&a, &plan.advect_schedule(&a, opts.levels, opts.threshold, opts.passes, f as u64, opts.nearest), &mut cpu, &jac, &[], &q)
            .unwrap();
        assert!(adv.read_coords(ctx()).unwrap() == cpu, "frame {} ({flow:?}) differs", f + 1);
        let rgba: Vec<u8> = out.colors.iter().flatten().copied().collect();
        assert_eq!(adv.read_rgba8(ctx()).unwrap(), rgba);
    }
    // The caller-owned GPU velocity path gives the same frame as host velocities.
    let v = Flow::Vortex { cx: 0.5, cy: 0.5, omega: -0.03 }.sample(48, 40, 0.0).unwrap();
    let mut a1 = Advection::new(ctx(), synth.clone(), &params, opts).unwrap();
    let mut a2 = Advection::new(ctx(), synth, &params, opts).unwrap();
    a1.step(ctx(), &v, 2.0).unwrap();
    let buffer = wgpu::util::DeviceExt::create_buffer_init(
        &ctx().device,
        &wgpu::util::BufferInitDescriptor {
            label: None,
            contents: bytemuck::cast_slice(&v),
            usage: wgpu::BufferUsages::STORAGE,
        },
    );
    let mut encoder = ctx().device.create_command_encoder(&Default::default());
    a2.encode_step(ctx(), &mut encoder, &buffer, 2.0).unwrap();
    ctx().queue.submit([encoder.finish()]);
    assert!(a1.read_coords(ctx()).unwrap() == a2.read_coords(ctx()).unwrap());
}

#[test]
fn flows_probe() {
    let (_a, synth, ex) = setup(64);
    let (w, h) = (96u32, 96u32);
    let params = SynthParams { width: w, height: h, ..SynthParams::default() };
    for flow in [
        Flow::Uniform { vx: 1.0, vy: 0.0 },
        Flow::Uniform { vx: 0.35, vy: 0.2 },
        Flow::Vortex { cx: 0.5, cy: 0.5, omega: 0.01 },
        Flow::Source { cx: 0.5, cy: 0.5, strength: 0.5 },
    ] {
        let mut adv = Advection::new(ctx(), synth.clone(), &params, AdvectOptions::default()).unwrap();
        let first = adv.read_rgba8(ctx()).unwrap();
        let e0 = texture_energy(&ex_image(&ex), &grey(&first, w, h), 2).unwrap();
        let mut prev = first.clone();
        let (mut warped, mut plain) = (0.0, 0.0);
        let frames = 60;
        let v = flow.sample(w, h, 0.0).unwrap();
        for _ in 0..frames {
            adv.step(ctx(), &v, 1.0).unwrap();
            let cur = adv.read_rgba8(ctx()).unwrap();
            warped += warped_diff(&prev, &cur, w, h, |x, y| {
                let i = (y as u32 * w + x as u32) as usize;
                (v[i][0], v[i][1])
            }, 8);
            plain += warped_diff(&prev, &cur, w, h, |_, _| (0.0, 0.0), 8);
            prev = cur;
        }
        let e1 = texture_energy(&ex_image(&ex), &grey(&prev, w, h), 2).unwrap();
        eprintln!("{flow:?}: energy {e0:.4} -> {e1:.4}, warped diff {:.2}, unwarped {:.2}", warped / frames as f64, plain / frames as f64);
    }
}
