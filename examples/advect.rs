//! A host application's frame loop driving texture advection on its own wgpu device:
//! the application owns the device, the queue and a GPU velocity buffer it updates
//! every frame (here a vortex whose speed changes over time) and its own, uneven, time
//! steps; texsyn records each frame into the application's command encoder and leaves
//! the texture on the GPU. Halfway the application changes the options (a shorter fade
//! of the renewals) and the parameters (less randomness, more coherence) without
//! starting over.
//! Nothing is read back except the frames this example saves to show the result.
//!
//! ```text
//! cargo run --release --example advect [OUT_DIR]      # default: the current directory
//! ```
//!
//! OUT_DIR is created if it does not exist.

use std::sync::Arc;

use texsyn::analysis::{analyze, AnalysisOptions};
use texsyn::flow::Flow;
use texsyn::GpuContext;
use texsyn::GpuSynthesizer;
use texsyn::SynthParams;
use texsyn::{AdvectOptions, Advection};

fn main() -> texsyn::Result<()> {
    let dir = std::path::PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| ".".into()));
    std::fs::create_dir_all(&dir).map_err(|e| texsyn::Error::Write {
        path: dir.clone(),
        reason: format!("cannot create the directory: {e}"),
    })?;

    // The application's own device (any adapter; lavapipe without a GPU).
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::PRIMARY,
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::HighPerformance,
        force_fallback_adapter: false,
        compatible_surface: None,
        ..Default::default()
    }))?;
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("host application"),
        ..Default::default()
    }))?;
    let ctx = GpuContext::from_device(device.clone(), queue.clone());

    let exemplar = texsyn::image_io::load_exemplar(
        concat!(env!("CARGO_MANIFEST_DIR"), "/assets/gravel.png").as_ref(),
    )?;
    let analysis = Arc::new(analyze(&exemplar, &AnalysisOptions::default(), |_| {})?);
    let synthesizer = Arc::new(GpuSynthesizer::new(&ctx, analysis)?);
    let (w, h) = (256u32, 256u32);
    let params = SynthParams {
        width: w,
        height: h,
        seed: 4,
        ..SynthParams::default()
    };
    // The options recommended for these parameters: in 2D without a field, the texture
    // keeps its look under the turning flow (remade as it turns, renewals faded over two
    // frames); on an atlas or along a varying field it would be carried as the paper
    // does (docs/advection.md).
    let options = AdvectOptions::recommended(&params);
    let mut advection = Advection::new(synthesizer, &params, options)?;

    // The application's velocity buffer (vec2<f32> per pixel), updated every frame (a
    // velocity texture, e.g. a fluid simulation's Rg32Float output, goes to
    // `encode_step_texture` instead).
    let velocity = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("host velocity"),
        size: w as u64 * h as u64 * 8,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    for frame in 1..=60u32 {
        if frame == 31 {
            // Renewals faded over one frame: a lower texture energy, a little more popping.
            advection.set_options(AdvectOptions { fade: 1, ..options })?;
            // Less randomness (larger patches, more repeats) and more coherence. The
            // frames do not jitter: the levels above the advected ones are made again
            // with the new parameters, and the texture takes them on where the frames
            // renew it.
            advection.set_params(&SynthParams {
                randomness: vec![0.7],
                coherence: 1.0,
                ..params.clone()
            })?;
        }
        // The host's frame time, in units of the velocities' time.
        let dt = if frame % 2 == 0 { 1.25 } else { 0.75 };
        let omega = 0.02 * (frame as f32 * 0.1).sin();
        let v = Flow::Vortex {
            cx: 0.5,
            cy: 0.5,
            omega,
        }
        .sample(w, h, frame as f32)?;
        ctx.queue
            .write_buffer(&velocity, 0, bytemuck::cast_slice(&v));
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        advection.encode_step(&mut encoder, &velocity, dt)?;
        // ... the application would record its own rendering here, sampling
        // advection.texture() ...
        ctx.queue.submit([encoder.finish()]);
        if frame % 20 == 0 {
            let rgba = advection.read_rgba8()?;
            let path = dir.join(format!("advect_{frame:03}.png"));
            texsyn::image_io::save_image_atomic(&path, w, h, 4, &rgba)?;
            println!("frame {frame}: wrote {}", path.display());
        }
    }
    ctx.take_uncaptured_errors()?;
    Ok(())
}
