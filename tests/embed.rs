//! The embedding API as a host application uses it: exemplars built in memory, the
//! output sampled as sRGB, advection from a session, and misuse that must fail cleanly
//! without spoiling the caller's command encoder.

mod common;

use texsyn::{AdvectOptions, Error, Exemplar, Session};

fn gravel() -> Exemplar {
    common::gravel()
}

/// The top-left 48x48 pixels of the gravel exemplar as an RGBA8 buffer.
fn gravel_rgba8_crop() -> Vec<u8> {
    let ex = gravel();
    let mut out = Vec::new();
    for y in 0..48 {
        for x in 0..48 {
            out.extend(ex.colors[(y * ex.width + x) as usize]);
        }
    }
    out
}

#[test]
fn exemplars_built_in_memory_are_checked() {
    let rgba = gravel_rgba8_crop();
    let ex = Exemplar::from_rgba8(48, 48, &rgba).expect("a consistent exemplar");
    assert_eq!((ex.width, ex.height, ex.channels), (48, 48, 3));
    assert_eq!(ex.values.len(), 48 * 48 * 3);
    ex.check().expect("from_rgba8 is consistent");
    assert!(matches!(
        Exemplar::from_rgba8(48, 48, &rgba[4..]),
        Err(Error::InvalidParameter(_))
    ));

    // Hand-built exemplars whose fields disagree: errors, not panics.
    let bad = [
        Exemplar {
            values: vec![0.5; 10],
            ..ex.clone()
        },
        Exemplar {
            colors: vec![[0; 4]; 5],
            ..ex.clone()
        },
        Exemplar {
            channels: 4,
            ..ex.clone()
        },
        Exemplar {
            values: {
                let mut v = ex.values.clone();
                v[7] = f32::NAN;
                v
            },
            ..ex.clone()
        },
    ];
    for b in bad {
        let err = b.check().expect_err("inconsistent exemplar accepted");
        println!("{err}");
        assert!(!texsyn::analysis::detect_tileable(&b));
        let analysed = texsyn::analysis::analyze(&b, &Default::default(), |_| {});
        assert!(matches!(analysed, Err(Error::InvalidParameter(_))));
    }
}

/// Reads texels of `view` through a compute shader as the hardware samples them.
fn load_texels(ctx: &texsyn::GpuContext, view: &wgpu::TextureView, n: u32) -> Vec<[f32; 4]> {
    let device = &ctx.device;
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("load texels"),
        source: wgpu::ShaderSource::Wgsl(
            "@group(0) @binding(0) var t: texture_2d<f32>;
             @group(0) @binding(1) var<storage, read_write> out: array<vec4<f32>>;
             @compute @workgroup_size(8, 8)
             fn main(@builtin(global_invocation_id) g: vec3<u32>) {
                 let n = textureDimensions(t);
                 if (g.x < n.x && g.y < n.y) {
                     out[g.y * n.x + g.x] = textureLoad(t, vec2<u32>(g.xy), 0);
                 }
             }"
            .into(),
        ),
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: None,
        layout: None,
        module: &module,
        entry_point: Some("main"),
        compilation_options: Default::default(),
        cache: None,
    });
    let size = n as u64 * n as u64 * 16;
    let out = device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let read = device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(view),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: out.as_entire_binding(),
            },
        ],
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(n.div_ceil(8), n.div_ceil(8), 1);
    }
    encoder.copy_buffer_to_buffer(&out, 0, &read, 0, size);
    ctx.queue.submit([encoder.finish()]);
    read.slice(..)
        .map_async(wgpu::MapMode::Read, |r| r.unwrap());
    device.poll(wgpu::PollType::wait_indefinitely()).unwrap();
    let range = read.slice(..).get_mapped_range().expect("mapped");
    let data: Vec<[f32; 4]> = bytemuck::cast_slice(&range).to_vec();
    drop(range);
    data
}

fn srgb_to_linear(v: u8) -> f32 {
    let c = v as f32 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

#[test]
fn the_output_can_be_sampled_as_srgb() {
    let session = Session::builder()
        .exemplar(Exemplar::from_rgba8(48, 48, &gravel_rgba8_crop()).unwrap())
        .size(32, 32)
        .build()
        .expect("session");
    let ctx = session.context();
    let gpu = session.run_gpu().expect("synthesis");
    let bytes = gpu.read_rgba8(ctx).expect("read-back");
    let Some(view) = gpu.srgb_view(ctx) else {
        assert_eq!(ctx.adapter_info.backend, wgpu::Backend::Gl);
        return;
    };
    let linear = load_texels(ctx, &view, 32);
    let mut worst = 0f32;
    for (texel, px) in linear.iter().zip(bytes.chunks(4)) {
        for c in 0..3 {
            worst = worst.max((texel[c] - srgb_to_linear(px[c])).abs());
        }
    }
    // The stored bytes are sRGB-encoded: the view decodes them (dark values differ
    // most from a plain /255, so a non-decoding view would fail this).
    assert!(
        worst < 2e-3,
        "largest difference from the sRGB decode: {worst}"
    );
    let plain = gpu.texture.create_view(&Default::default());
    let raw = load_texels(ctx, &plain, 32);
    assert!(raw
        .iter()
        .zip(bytes.chunks(4))
        .all(|(t, p)| (t[0] - p[0] as f32 / 255.0).abs() < 1e-3));
    ctx.take_uncaptured_errors().expect("no wgpu errors");
}

#[test]
fn advection_from_a_session_and_a_bad_velocity_buffer() {
    let session = Session::builder()
        .exemplar(Exemplar::from_rgba8(48, 48, &gravel_rgba8_crop()).unwrap())
        .size(32, 32)
        .seed(3)
        .build()
        .expect("session");
    let ctx = session.context();
    let mut advection = session
        .advection(AdvectOptions::default())
        .expect("advection");

    // A velocity buffer without STORAGE usage: an error before anything is recorded,
    // so the caller's encoder still finishes and submits cleanly.
    let unusable = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("no storage usage"),
        size: 32 * 32 * 8,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::VERTEX,
        mapped_at_creation: false,
    });
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    let err = advection
        .encode_step(&mut encoder, &unusable, 1.0)
        .expect_err("a buffer without STORAGE usage was accepted");
    assert!(err.to_string().contains("STORAGE"), "{err}");
    ctx.queue.submit([encoder.finish()]);
    ctx.take_uncaptured_errors()
        .expect("the caller's encoder was spoiled");

    // A proper buffer: a uniform flow of 2 pixels moves the texture by 2 pixels.
    let before = advection.read_rgba8().unwrap();
    let velocity = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("velocity"),
        size: 32 * 32 * 8,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    ctx.queue.write_buffer(
        &velocity,
        0,
        bytemuck::cast_slice(&vec![[2f32, 0.0]; 32 * 32]),
    );
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    advection
        .encode_step(&mut encoder, &velocity, 1.0)
        .expect("step");
    ctx.queue.submit([encoder.finish()]);
    let after = advection.read_rgba8().unwrap();
    let px = |b: &[u8], x: usize, y: usize| b[(y * 32 + x) * 4..][..4].to_vec();
    let same = (0..32)
        .flat_map(|y| (2..32).map(move |x| (x, y)))
        .filter(|&(x, y)| px(&after, x, y) == px(&before, x - 2, y))
        .count();
    assert!(
        same * 10 > 30 * 32 * 8,
        "only {same} of {} pixels moved with the flow",
        30 * 32
    );
    assert!(advection.srgb_view().is_some() || ctx.adapter_info.backend == wgpu::Backend::Gl);
    ctx.take_uncaptured_errors().expect("no wgpu errors");
}

#[test]
fn progress_reports_and_level_by_level_synthesis_gives_the_same_bytes() {
    use texsyn::analysis::{Progress, Stage};
    let log = std::rc::Rc::new(std::cell::RefCell::new(Vec::<Progress>::new()));
    let session = Session::builder()
        .exemplar(Exemplar::from_rgba8(48, 48, &gravel_rgba8_crop()).unwrap())
        .size(40, 24)
        .seed(5)
        // No copy-guard probe, whose levels would report too.
        .copy_budget(0.0)
        .on_progress({
            let log = log.clone();
            move |p| log.borrow_mut().push(p)
        })
        .build()
        .expect("session");
    let ctx = session.context();

    // Analysis: the stack first, then each level's stages; the similarity search
    // reports fractions; the last report says every level is done.
    let stages = log.borrow().clone();
    assert_eq!(stages[0].stage, Stage::Stack);
    let last = *stages.last().unwrap();
    assert_eq!((last.stage, last.done), (Stage::LevelDone, last.total));
    assert_eq!(last.total as usize, session.analysis().levels.len());
    assert!(stages
        .iter()
        .any(|p| p.stage == Stage::SimilaritySets && p.fraction > 0.0 && p.fraction <= 1.0));
    assert!(stages.windows(2).all(|w| w[0].done <= w[1].done));
    let done_reports = stages
        .iter()
        .filter(|p| p.stage == Stage::LevelDone)
        .count();
    assert_eq!(done_reports, last.total as usize);

    // Synthesis: one report per level but the last (which the caller's own submission
    // finishes), in order, and the same bytes as one submission.
    let plain = session.run().expect("synthesis");
    let (tx, rx) = std::sync::mpsc::channel();
    session
        .synthesizer()
        .set_progress(Some(Box::new(move |done, total| {
            tx.send((done, total)).unwrap()
        })));
    let split = session.run().expect("synthesis with progress");
    session.synthesizer().set_progress(None);
    let seen: Vec<(u32, u32)> = rx.try_iter().collect();
    let total = session.analysis().levels.len() as u32;
    assert_eq!(seen, (1..total).map(|d| (d, total)).collect::<Vec<_>>());
    assert_eq!(split.synthesis.colors, plain.synthesis.colors);
    assert_eq!(split.synthesis.coords, plain.synthesis.coords);
    assert!(rx.try_iter().next().is_none());

    // The callback may call into its synthesizer: synthesize (that nested synthesis
    // skips its own reports) and take itself off. Both deadlocked while the callback ran
    // under the lock that set_progress takes.
    let sy = session.synthesizer().clone();
    let weak = std::sync::Arc::downgrade(&sy);
    let params2 = session.params().clone();
    let (tx, rx) = std::sync::mpsc::channel();
    sy.set_progress(Some(Box::new(move |done, _| {
        if let Some(s) = weak.upgrade() {
            if done == 1 {
                let nested = s.synthesize_to_host(&params2).unwrap();
                tx.send(nested.colors).unwrap();
                s.set_progress(None);
            }
        }
    })));
    let outer = sy.synthesize_to_host(session.params()).unwrap();
    let nested = rx.try_recv().expect("the callback ran a synthesis");
    assert_eq!(nested, outer.colors);
    assert_eq!(outer.colors, plain.synthesis.colors);

    ctx.take_uncaptured_errors().expect("no wgpu errors");
}

#[test]
fn builder_windows_fit_and_setters_reach_the_parameters() {
    let ex = Exemplar::from_rgba8(48, 48, &gravel_rgba8_crop()).unwrap();
    let build = |b: texsyn::SessionBuilder| b.exemplar(ex.clone()).seed(4).build().unwrap();
    let whole = build(Session::builder().size(32, 24).sets_every(2).coherence(0.5));
    let part = build(
        Session::builder()
            .size(16, 12)
            .window(16, 8)
            .sets_every(2)
            .coherence(0.5),
    );
    let p = part.params();
    assert_eq!((p.origin, p.sets_every, p.coherence), ([16, 8], 2, 0.5));
    assert!(!p.standalone);
    let (w, q) = (whole.run().unwrap(), part.run().unwrap());
    for y in 0..12 {
        for x in 0..16 {
            assert_eq!(
                q.coords()[y * 16 + x],
                w.coords()[(y + 8) * 32 + x + 16],
                "pixel ({x},{y}) of the window"
            );
        }
    }
    let p = build(Session::builder().second_finest_passes(3))
        .params()
        .clone();
    assert_eq!(p.second_finest_passes, Some(3));
    let standalone = build(Session::builder().size(32, 24).standalone(true));
    assert!(standalone.params().standalone);
    // Out-of-range values are refused when the session is built.
    let bad = Session::builder()
        .exemplar(ex.clone())
        .sets_every(0)
        .build();
    assert!(bad.is_err());
}

/// A synthesis reporting progress submits level by level; another thread's `encode` +
/// submit on the same synthesizer in between must not touch its coordinates (they were
/// in one shared scratch buffer: nearly every pixel came out wrong, with no error).
#[test]
fn progress_syntheses_are_not_disturbed_by_other_threads_encoding() {
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    let session = Arc::new(
        Session::builder()
            .exemplar(gravel())
            .size(96, 96)
            .build()
            .unwrap(),
    );
    let ctx = session.context().clone();
    let sy = session.synthesizer().clone();
    let params = texsyn::SynthParams {
        seed: 5,
        width: 96,
        height: 96,
        ..Default::default()
    };
    let reference = sy.synthesize_to_host(&params).unwrap();
    // Slow levels leave room for the other thread's submissions.
    sy.set_progress(Some(Box::new(|_, _| {
        std::thread::sleep(std::time::Duration::from_millis(15))
    })));
    let stop = Arc::new(AtomicBool::new(false));
    let other = {
        let (session, ctx, stop) = (session.clone(), ctx.clone(), stop.clone());
        std::thread::spawn(move || {
            let p = texsyn::SynthParams {
                seed: 77,
                width: 40,
                height: 40,
                ..Default::default()
            };
            let mut n = 0;
            while !stop.load(Ordering::Relaxed) {
                let mut encoder = ctx.device.create_command_encoder(&Default::default());
                session.synthesizer().encode(&mut encoder, &p).unwrap();
                ctx.queue.submit([encoder.finish()]);
                n += 1;
                std::thread::sleep(std::time::Duration::from_millis(3));
            }
            n
        })
    };
    let result = sy.synthesize_to_host(&params);
    stop.store(true, Ordering::Relaxed);
    let n = other.join().unwrap();
    sy.set_progress(None);
    let result = result.unwrap();
    assert!(n > 0);
    assert!(
        result.colors == reference.colors,
        "{n} syntheses in between changed the output"
    );
    assert!(result.coords == reference.coords);
    ctx.take_uncaptured_errors().expect("no wgpu errors");
}

/// Misuse: a destroyed velocity buffer fails before anything is recorded, and a
/// destroyed device gives errors, not panics (wgpu's `create_buffer_init` panics there).
#[test]
fn a_destroyed_buffer_or_device_fail_cleanly() {
    let session = Session::builder()
        .exemplar(Exemplar::from_rgba8(48, 48, &gravel_rgba8_crop()).unwrap())
        .size(32, 32)
        .build()
        .expect("session");
    let ctx = session.context();
    let params = texsyn::SynthParams {
        width: 32,
        height: 32,
        ..Default::default()
    };

    // A destroyed velocity buffer: an error, and the caller's encoder still submits.
    let mut advection = session.advection(AdvectOptions::default()).unwrap();
    let velocity = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("destroyed velocity"),
        size: 32 * 32 * 8,
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    });
    velocity.destroy();
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    assert!(advection.encode_step(&mut encoder, &velocity, 1.0).is_err());
    ctx.queue.submit([encoder.finish()]);
    ctx.take_uncaptured_errors()
        .expect("the caller's encoder was spoiled");

    // A destroyed device: no panic from any call (reading back fails; recording and
    // submitting may report nothing, as wgpu drops work on a lost device).
    ctx.device.destroy();
    assert!(session.run().is_err());
    let _ = session.run_gpu();
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    let _ = session.synthesizer().encode(&mut encoder, &params);
    let _ = advection.step(&vec![[1.0, 0.0]; 32 * 32], 1.0);
    let _ = session.advection(AdvectOptions::default());
}
