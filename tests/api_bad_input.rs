//! The library's public API given inconsistent or extreme values: each is a clear
//! `texsyn::Error`, never a panic.

mod common;
use common::ctx;

use std::sync::{Arc, OnceLock};

use texsyn::analysis::{analyze, Analysis, AnalysisOptions, Exemplar, FeatureMask};
use texsyn::field::FieldMap;
use texsyn::gpu::synth::GpuSynthesizer;
use texsyn::gpu::GpuContext;
use texsyn::quality::{FloatImage, TemporalFigures};
use texsyn::surface::mesh::Mesh;
use texsyn::{Field, Flow, SynthParams};

fn analysis() -> Arc<Analysis> {
    static A: OnceLock<Arc<Analysis>> = OnceLock::new();
    A.get_or_init(|| {
        Arc::new(
            analyze(
                &common::gravel_crop(32),
                &AnalysisOptions::default(),
                |_| {},
            )
            .unwrap(),
        )
    })
    .clone()
}

#[test]
fn hand_built_analyses_are_checked() {
    let mut a = (*analysis()).clone();
    a.levels.clear();
    let e = GpuSynthesizer::new(ctx(), Arc::new(a.clone()))
        .err()
        .unwrap();
    assert!(e.to_string().contains("levels"), "{e}");
    let params = SynthParams {
        width: 16,
        height: 16,
        ..Default::default()
    };
    assert!(texsyn::passes::synthesize_cpu(&a, &params).is_err());
    let mut a = (*analysis()).clone();
    a.levels[2].et.to_mut().truncate(10);
    assert!(a.validate().is_err());
    let mut a = (*analysis()).clone();
    a.colors.clear();
    assert!(a.validate().is_err());
    analysis().validate().unwrap();
}

#[test]
fn inconsistent_maps_masks_and_sizes_are_errors() {
    let empty = Field::Map(Arc::new(FieldMap {
        width: 0,
        height: 0,
        jacobians: vec![],
    }));
    assert!(empty.validate().is_err());
    // An unvalidated map reads identity instead of indexing out of bounds.
    assert_eq!(empty.at(3.0, 4.0), [[1.0, 0.0], [0.0, 1.0]]);

    let flow = Flow::Map {
        width: 4,
        height: 4,
        data: Arc::new(vec![[0.0, 0.0]; 3]),
    };
    assert!(flow.validate().is_err());
    assert!(flow.sample(4, 4, 0.0).is_err());
    assert!(Flow::Uniform { vx: 1.0, vy: 0.0 }
        .sample(u32::MAX, u32::MAX, 0.0)
        .is_err());

    let mask = FeatureMask {
        width: 32,
        height: 32,
        inside: vec![true; 5],
        source: None,
    };
    assert!(mask.check_size(32, 32).is_err());
    assert!(mask.downsample(2).is_err());
    assert!(Exemplar::from_rgba8(u32::MAX, u32::MAX, &[]).is_err());

    let mut mesh = Mesh::cube(1.0, 1);
    mesh.triangles.push([0, 1, 99_999]);
    let e = texsyn::surface::atlas::build_atlas(
        &mesh,
        &texsyn::surface::atlas::AtlasOptions::for_size(64),
    )
    .err()
    .unwrap();
    assert!(e.to_string().contains("99999"), "{e}");

    // Frames of another size in a temporal report.
    let ex = FloatImage::new(16, 16, 1, vec![0.5; 256]).unwrap();
    let mut figures = TemporalFigures::new(&ex, 1);
    figures
        .push(FloatImage::new(16, 16, 1, vec![0.5; 256]).unwrap(), &[])
        .unwrap();
    assert!(figures
        .push(FloatImage::new(8, 8, 1, vec![0.5; 64]).unwrap(), &[])
        .is_err());
    assert!(ex.tiled(u32::MAX, u32::MAX).is_err());
}

#[test]
fn gpu_entry_points_refuse_what_the_device_cannot_hold() {
    let synth = Arc::new(GpuSynthesizer::new(ctx(), analysis()).unwrap());
    // Windows of an empty output.
    let empty = SynthParams {
        width: 0,
        height: 16,
        ..Default::default()
    };
    assert!(synth.synthesize_in_windows(&empty, &[], |_, _| {}).is_err());
    // Advection wider than a texture may be: TooLarge before any allocation.
    let wide = SynthParams {
        width: ctx().limits().max_texture_dimension_2d + 1,
        height: 1,
        ..Default::default()
    };
    let e = texsyn::Advection::new(synth.clone(), &wide, Default::default())
        .err()
        .unwrap();
    assert!(matches!(e, texsyn::Error::TooLarge { .. }), "{e}");
    // Magnifying a huge width overflows nothing.
    let huge = SynthParams {
        width: u32::MAX,
        ..Default::default()
    };
    let a = analysis();
    let hi = vec![[0u8; 4]; (a.width * a.height * 4) as usize];
    assert!(synth
        .synthesize_magnified(&huge, &hi, a.width * 2, a.height * 2, 2)
        .is_err());
    // Too many views.
    let rgba = vec![128u8; 8 * 8 * 4];
    let opts = texsyn::surface::render::RenderOptions {
        view_size: 32,
        views: u32::MAX,
        ..Default::default()
    };
    let mesh = Mesh::cube(1.0, 1);
    assert!(texsyn::surface::render::render_views(
        ctx(),
        &mesh,
        &texsyn::surface::render::SurfaceTexture::Color {
            rgba: &rgba,
            width: 8,
            height: 8
        },
        &opts
    )
    .is_err());
    ctx().take_uncaptured_errors().unwrap();
}

/// A velocity buffer larger than the output needs is valid (only the first w * h
/// entries are read), and the caller's encoder stays usable.
#[test]
fn a_larger_velocity_buffer_is_read_in_part() {
    let synth = Arc::new(GpuSynthesizer::new(ctx(), analysis()).unwrap());
    let params = SynthParams {
        width: 24,
        height: 24,
        ..Default::default()
    };
    let mut adv = texsyn::Advection::new(synth.clone(), &params, Default::default()).unwrap();
    let mut twin = texsyn::Advection::new(synth, &params, Default::default()).unwrap();
    // The first w * h entries a flow, the rest garbage that must not be read.
    let v = Flow::Vortex {
        cx: 0.4,
        cy: 0.6,
        omega: 0.05,
    }
    .sample(24, 24, 0.0)
    .unwrap();
    let mut contents = v.clone();
    contents.extend(std::iter::repeat_n([40.0f32, -33.0], 24 * 24 * 2));
    let buffer = wgpu::util::DeviceExt::create_buffer_init(
        &ctx().device,
        &wgpu::util::BufferInitDescriptor {
            label: None,
            contents: bytemuck::cast_slice(&contents),
            usage: wgpu::BufferUsages::STORAGE,
        },
    );
    let mut encoder = ctx().device.create_command_encoder(&Default::default());
    adv.encode_step(&mut encoder, &buffer, 1.0).unwrap();
    ctx().queue.submit([encoder.finish()]);
    twin.step(&v, 1.0).unwrap();
    assert!(adv.read_coords().unwrap() == twin.read_coords().unwrap());
    ctx().take_uncaptured_errors().unwrap();
}

/// The adapter a caller would make its own device from (with the limits it chooses).
fn adapter() -> Option<wgpu::Adapter> {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::PRIMARY,
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    pollster::block_on(instance.request_adapter(&Default::default())).ok()
}

/// A caller's device with downlevel limits gets a clear error, and the context stays
/// usable for nothing else going wrong.
#[test]
fn a_downlevel_device_is_refused_clearly() {
    let Some(adapter) = adapter() else {
        return; // The headless tests above need the adapter anyway.
    };
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        required_limits: wgpu::Limits::downlevel_defaults(),
        ..Default::default()
    }))
    .unwrap();
    let ctx = GpuContext::from_device(device, queue);
    let e = GpuSynthesizer::new(&ctx, analysis())
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("storage buffers"), "{e}");
    // Building the pipelines ahead is refused the same way, before wgpu's validation.
    let e = ctx.prepare_pipelines(false).unwrap_err().to_string();
    assert!(e.contains("storage buffers"), "{e}");
    ctx.take_uncaptured_errors().unwrap();

    // Default limits but workgroups of fewer than 64 invocations.
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        required_limits: wgpu::Limits {
            max_compute_invocations_per_workgroup: 32,
            max_compute_workgroup_size_x: 32,
            ..wgpu::Limits::default()
        },
        ..Default::default()
    }))
    .unwrap();
    let ctx = GpuContext::from_device(device, queue);
    let e = GpuSynthesizer::new(&ctx, analysis())
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("workgroups"), "{e}");
    ctx.take_uncaptured_errors().unwrap();
}

/// Helpers that return a figure rather than a `Result` answer NaN for inconsistent input.
#[test]
fn figure_helpers_answer_nan_for_inconsistent_input() {
    use texsyn::quality::{fragment_fraction, high_frequency_energy, warped_difference};
    let a = FloatImage::new(8, 8, 1, vec![0.5; 64]).unwrap();
    let b = FloatImage::new(4, 4, 1, vec![0.5; 16]).unwrap();
    assert!(warped_difference(&a, &b, &[], 0).is_nan());
    assert!(fragment_fraction(&[true; 5], 4, 4, 20).is_nan());
    let broken = FloatImage {
        width: 8,
        height: 8,
        channels: 1,
        data: vec![0.5; 3],
    };
    assert!(high_frequency_energy(&broken).is_nan());
    assert_eq!(warped_difference(&a, &a, &[], 0), 0.0);
    let _ = Mesh::uv_sphere(1.0, u32::MAX, 3); // clamped, not an overflow
}

/// An exemplar whose analysis cannot fit in the memory available is refused up front,
/// naming both amounts and what to do; one that fits, or an unknown amount, passes.
#[test]
fn an_analysis_larger_than_memory_is_refused_before_any_work() {
    use texsyn::analysis::{analysis_memory_estimate, check_analysis_memory};
    let need = analysis_memory_estimate(16000, 16000);
    // 15 levels with level 0, 64 bytes each per pixel.
    assert_eq!(need, 16000 * 16000 * 15 * 64);
    let e = check_analysis_memory(16000, 16000, Some(24 << 30)).unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains("16000x16000"), "{msg}");
    assert!(msg.contains("GiB are available"), "{msg}");
    assert!(msg.contains("--magnify"), "{msg}");
    check_analysis_memory(512, 512, Some(24 << 30)).unwrap();
    check_analysis_memory(16000, 16000, None).unwrap();
    // The 128 px exemplars need about 10 MiB.
    assert!(analysis_memory_estimate(128, 128) < 16 << 20);
}

/// A tileable output whose sides are not multiples of 4 is made on a torus
/// (`passes::plan::Torus`), which needs a Jacobian per coordinate; where that does not
/// fit the device but the output's own periods do, `GpuSynthesizer::plan_for` keeps
/// those (and their faint seam) instead of failing.
#[test]
fn a_torus_that_does_not_fit_keeps_the_outputs_own_periods() {
    let Some(adapter) = adapter() else {
        return; // The headless tests above need the adapter anyway.
    };
    // 2 MiB per binding: a 250x250 torus (252x252 and the output, 147k coordinates) needs
    // 2.4 MB of Jacobians; the output's own pyramid and flags 1.2 MB of coordinates.
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        required_limits: wgpu::Limits {
            max_storage_buffer_binding_size: 2 << 20,
            ..wgpu::Limits::default()
        },
        ..Default::default()
    }))
    .unwrap();
    let small = GpuContext::from_device(device, queue);
    let a = analysis();
    let params = SynthParams {
        width: 250,
        height: 250,
        tileable_output: true,
        ..SynthParams::default()
    };
    let torus = texsyn::passes::SynthPlan::new(&a, &params).unwrap();
    assert_eq!(torus.torus.map(|t| t.period), Some([252, 252]));
    let gpu = GpuSynthesizer::new(&small, a.clone()).unwrap();
    let plan = gpu.plan_for(&params).unwrap();
    assert!(plan.torus.is_none(), "the torus does not fit 2 MiB");
    let out = gpu.synthesize_to_host(&params).unwrap();
    assert_eq!((out.width, out.height, out.coord_frac), (250, 250, 0));
    small.take_uncaptured_errors().unwrap();
    // With the default limits the torus is used.
    let gpu = GpuSynthesizer::new(ctx(), a).unwrap();
    assert_eq!(gpu.plan_for(&params).unwrap(), torus);
}
