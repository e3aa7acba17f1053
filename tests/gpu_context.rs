//! Device creation and error handling on whatever adapter the machine has (lavapipe in
//! CI). Adapter choice is tested through `GpuContext::with_options`, not environment
//! variables, so the tests cannot race each other.

mod common;
use common::fresh_ctx as context;

use texsyn::gpu::context::{GpuContext, GpuOptions};
use texsyn::Error;

/// A buffer descriptor wgpu rejects: MAP_READ may only be combined with COPY_DST.
fn invalid_buffer() -> wgpu::BufferDescriptor<'static> {
    wgpu::BufferDescriptor {
        label: Some("invalid"),
        // Mapped at creation, a size that is not a multiple of 4 is invalid on every
        // device (mappable storage, which a CPU device gets, is not).
        size: 15,
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: true,
    }
}

#[test]
fn headless_creates_a_device_with_the_adapter_limits() {
    let ctx = context();
    let description = ctx.describe();
    println!("adapter: {description}");
    assert!(
        description.contains(&ctx.adapter_info.name),
        "{description}"
    );
    assert!(description.contains(&format!("{:?}", ctx.adapter_info.backend)));

    // The device was requested with the adapter's limits, not the WebGPU defaults.
    let limits = ctx.limits();
    println!(
        "max_buffer_size {} max_storage_buffer_binding_size {} max_texture_dimension_2d {}",
        limits.max_buffer_size,
        limits.max_storage_buffer_binding_size,
        limits.max_texture_dimension_2d
    );
    assert!(limits.max_compute_invocations_per_workgroup >= 64);
    assert!(limits.max_texture_dimension_2d >= 2048);
    // Exactly the adapter's (lavapipe's exceed the defaults: 2^31 - 1 bytes against 2^28).
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::all(),
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    let adapter_limits = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()))
        .into_iter()
        .find(|a| {
            let i = a.get_info();
            i.name == ctx.adapter_info.name && i.backend == ctx.adapter_info.backend
        })
        .map(|a| a.limits())
        .expect("the context's adapter is listed");
    assert_eq!(limits.max_buffer_size, adapter_limits.max_buffer_size);
    assert_eq!(
        limits.max_texture_dimension_2d,
        adapter_limits.max_texture_dimension_2d
    );
    assert_eq!(
        limits.max_storage_buffer_binding_size,
        adapter_limits.max_storage_buffer_binding_size
    );

    // A valid operation inside a scope succeeds and returns its value.
    let buffer = ctx
        .scoped(|| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("ok"),
                size: 256,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        })
        .expect("valid buffer");
    assert_eq!(buffer.size(), 256);
    ctx.wait_idle().expect("wait_idle");
    ctx.take_uncaptured_errors().expect("no stray errors");
}

#[test]
fn scoped_turns_validation_errors_into_gpu_errors() {
    let ctx = context();
    let result = ctx.scoped(|| ctx.device.create_buffer(&invalid_buffer()));
    match result {
        Err(Error::Gpu(message)) => {
            println!("{message}");
            assert!(message.contains("validation"), "{message}");
        }
        Err(other) => panic!("expected Error::Gpu, got {other:?}"),
        Ok(_) => panic!("an invalid buffer was accepted"),
    }
    // The scope caught it: nothing leaked to the uncaptured handler.
    ctx.take_uncaptured_errors().expect("no stray errors");

    // Nested scopes and later calls still work.
    let value = ctx.scoped(|| ctx.scoped(|| 7).unwrap()).unwrap();
    assert_eq!(value, 7);
}

#[test]
fn uncaptured_errors_are_collected_instead_of_panicking() {
    let ctx = context();
    let _buffer = ctx.device.create_buffer(&invalid_buffer());
    match ctx.take_uncaptured_errors() {
        Err(Error::Gpu(message)) => assert!(message.contains("validation"), "{message}"),
        other => panic!("expected the uncaptured error, got {other:?}"),
    }
    // Taken: the next call is clean.
    ctx.take_uncaptured_errors().expect("errors were taken");
}

#[test]
fn non_matching_adapter_is_a_helpful_no_adapter_error() {
    let found = context().adapter_info.name;
    let result = GpuContext::with_options(GpuOptions {
        backend: None,
        adapter: Some("no-such-adapter-0xdeadbeef".to_string()),
        ..Default::default()
    });
    match result {
        Err(Error::NoAdapter(message)) => {
            println!("{message}");
            assert!(message.contains("no-such-adapter-0xdeadbeef"), "{message}");
            assert!(message.contains("TEXSYN_ADAPTER"), "{message}");
            // The adapters that do exist are listed, with their indices.
            assert!(message.contains(&found), "{message}");
            assert!(message.contains("[0]"), "{message}");
            let full = Error::NoAdapter(message).to_string();
            assert!(full.contains("lavapipe"), "{full}");
        }
        Err(other) => panic!("expected Error::NoAdapter, got {other:?}"),
        Ok(ctx) => panic!("matched {}", ctx.describe()),
    }

    // An index past the end is no match either.
    let result = GpuContext::with_options(GpuOptions {
        backend: None,
        adapter: Some("999".to_string()),
        ..Default::default()
    });
    assert!(matches!(result, Err(Error::NoAdapter(_))), "{result:?}");
}

#[test]
fn adapter_by_name_and_index() {
    let expected = context().adapter_info;
    // A case-changed part of the default adapter's name picks the same adapter.
    let part: String = expected
        .name
        .chars()
        .take(4)
        .collect::<String>()
        .to_uppercase();
    let ctx = GpuContext::with_options(GpuOptions {
        backend: Some(format!("{:?}", expected.backend).to_lowercase()),
        adapter: Some(part),
        ..Default::default()
    })
    .expect("adapter by name");
    assert_eq!(ctx.adapter_info.name, expected.name);

    let ctx = GpuContext::with_options(GpuOptions {
        backend: Some(format!("{:?}", expected.backend)),
        adapter: Some("0".to_string()),
        ..Default::default()
    })
    .expect("adapter by index");
    println!("[0] {}", ctx.describe());
}

#[test]
fn unknown_backend_is_an_invalid_parameter() {
    let result = GpuContext::with_options(GpuOptions {
        backend: Some("glide".to_string()),
        adapter: None,
        ..Default::default()
    });
    match result {
        Err(Error::InvalidParameter(message)) => assert!(message.contains("glide"), "{message}"),
        other => panic!("expected InvalidParameter, got {other:?}"),
    }
}

#[test]
fn from_device_wraps_a_callers_device() {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::PRIMARY,
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::HighPerformance,
        force_fallback_adapter: false,
        compatible_surface: None,
        ..Default::default()
    }))
    .expect("an adapter");
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("caller's device"),
        ..Default::default()
    }))
    .expect("a device");

    let ctx = GpuContext::from_device(device, queue);
    println!("from_device: {}", ctx.describe());
    assert_eq!(ctx.adapter_info, adapter.get_info());
    // The caller asked for default limits; the context reports the device's.
    assert_eq!(
        ctx.limits().max_buffer_size,
        wgpu::Limits::default().max_buffer_size
    );
    assert!(matches!(
        ctx.scoped(|| ctx.device.create_buffer(&invalid_buffer())),
        Err(Error::Gpu(_))
    ));
    ctx.wait_idle().unwrap();
}

#[test]
fn every_embedded_shader_builds_a_compute_pipeline() {
    let ctx = context();
    for shader in texsyn::gpu::shaders::ALL {
        let pipeline = ctx.scoped(|| {
            let module = ctx
                .device
                .create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some(shader.name),
                    source: wgpu::ShaderSource::Wgsl(shader.source.into()),
                });
            ctx.device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(shader.name),
                    layout: None,
                    module: &module,
                    entry_point: Some(shader.entry_point),
                    compilation_options: Default::default(),
                    cache: None,
                })
        });
        if let Err(e) = pipeline {
            panic!("{} ({}): {e}", shader.file, shader.name);
        }
        assert!(shader.workgroup_size.iter().all(|&n| n >= 1));
        println!(
            "{}: {} {:?} ok",
            shader.file, shader.entry_point, shader.workgroup_size
        );
    }
}

/// Pipelines built ahead of time are valid, shared by the synthesizers of a context, and
/// a synthesis afterwards runs without errors.
#[test]
fn pipelines_prepared_ahead_of_time() {
    let ctx = context();
    ctx.prepare_pipelines(false).unwrap();
    ctx.prepare_pipelines(true).unwrap();
    ctx.take_uncaptured_errors().unwrap();
    let exemplar =
        texsyn::image_io::load_exemplar(std::path::Path::new("assets/gravel.png")).unwrap();
    let analysis = std::sync::Arc::new(
        texsyn::analysis::analyze(&exemplar, &Default::default(), |_| {}).unwrap(),
    );
    for _ in 0..2 {
        let s = texsyn::gpu::synth::GpuSynthesizer::new(&ctx, analysis.clone()).unwrap();
        let params = texsyn::SynthParams {
            width: 24,
            height: 16,
            ..Default::default()
        };
        let out = s.synthesize_to_host(&params).unwrap();
        assert_eq!(out.colors.len(), 24 * 16);
        // A synthesizer's own preparation (the exact variants of a plan, here along a
        // field and with the identity field) changes nothing in the result.
        for field in [
            texsyn::field::Field::Constant {
                angle: 0.4,
                scale: [1.0, 1.0],
                shear: 0.0,
            },
            texsyn::field::Field::Constant {
                angle: 0.0,
                scale: [1.0, 1.0],
                shear: 0.0,
            },
        ] {
            let p = texsyn::SynthParams {
                field: Some(field),
                ..params.clone()
            };
            let before = s.synthesize_to_host(&p).unwrap();
            s.prepare(&p).unwrap();
            assert_eq!(s.synthesize_to_host(&p).unwrap(), before);
        }
    }
    ctx.take_uncaptured_errors().unwrap();
}

/// A plan's pipelines built before its synthesizer exists (on a thread of their own, as
/// the CLI does while the analysis uploads): the same result, and invalid parameters
/// are the plan's errors.
#[test]
fn pipelines_of_a_plan_prepared_before_the_upload() {
    let ctx = context();
    let exemplar =
        texsyn::image_io::load_exemplar(std::path::Path::new("assets/brick.png")).unwrap();
    let analysis = std::sync::Arc::new(
        texsyn::analysis::analyze(&exemplar, &Default::default(), |_| {}).unwrap(),
    );
    let params = texsyn::SynthParams {
        width: 40,
        height: 24,
        seed: 4,
        tileable_output: true,
        ..Default::default()
    };
    let cold = {
        let c = context();
        let s = texsyn::gpu::synth::GpuSynthesizer::new(&c, analysis.clone()).unwrap();
        s.synthesize_to_host(&params).unwrap()
    };
    let s = std::thread::scope(|scope| {
        let built = scope.spawn(|| ctx.prepare_synthesis(&analysis, &params));
        let s = texsyn::gpu::synth::GpuSynthesizer::new(&ctx, analysis.clone()).unwrap();
        built.join().unwrap().unwrap();
        s
    });
    assert_eq!(s.synthesize_to_host(&params).unwrap(), cold);
    let bad = texsyn::SynthParams {
        width: 0,
        ..params.clone()
    };
    assert!(ctx.prepare_synthesis(&analysis, &bad).is_err());
    ctx.take_uncaptured_errors().unwrap();
}

/// On a CPU adapter (lavapipe) with two or more cores, the driver's unnamed worker threads
/// carry the name of the thread that created the device and are bound to separate cores
/// (`texsyn::gpu::cpu_threads`). Other tests create devices at the same time, whose
/// threads may not be bound yet: so this asks for two bound threads on two cores, not
/// that every thread of the name is bound.
#[cfg(target_os = "linux")]
#[test]
fn a_cpu_device_has_its_worker_threads_bound_to_separate_cores() {
    use texsyn::gpu::cpu_threads::INIT_THREAD_NAME;
    let ctx = context();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    if ctx.adapter_info.device_type != wgpu::DeviceType::Cpu || cores < 2 {
        println!("skipped: {} with {cores} cores", ctx.describe());
        return;
    }
    let mut bound = std::collections::BTreeSet::new();
    let mut named = 0;
    for task in std::fs::read_dir("/proc/self/task").unwrap().flatten() {
        let comm = std::fs::read_to_string(task.path().join("comm")).unwrap_or_default();
        if comm.trim_end() != INIT_THREAD_NAME {
            continue;
        }
        named += 1;
        let status = std::fs::read_to_string(task.path().join("status")).unwrap_or_default();
        let allowed = status
            .lines()
            .find_map(|l| l.strip_prefix("Cpus_allowed_list:"))
            .map(|v| v.trim().to_string())
            .unwrap_or_default();
        // One core: a plain number, no range or list.
        if let Ok(cpu) = allowed.parse::<u32>() {
            bound.insert(cpu);
        }
    }
    println!("{named} threads named {INIT_THREAD_NAME}, bound to cores {bound:?}");
    assert!(named >= 2, "the driver's threads do not carry the name");
    assert!(bound.len() >= 2, "threads not spread over cores: {bound:?}");
}
