//! Embedding texsyn in a host application that owns its wgpu device: create the
//! instance, adapter, device and queue yourself, hand them to texsyn, record a synthesis
//! into your own command encoder, submit, and use the texture (here: read it back).
//!
//! ```text
//! cargo run --release --example embed
//! ```

use texsyn::GpuContext;
use texsyn::{Session, SynthParams};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // --- The host application's own device (wgpu 30, no window needed here). -------
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
        label: Some("host app device"),
        ..Default::default()
    }))?;

    // --- Hand the device to texsyn (handles are reference counted: the app keeps
    // using its own clones). ---------------------------------------------------------
    let context = GpuContext::from_device(device.clone(), queue.clone());
    println!("adapter: {}", context.describe());
    let session = Session::builder()
        .exemplar_path(concat!(env!("CARGO_MANIFEST_DIR"), "/assets/gravel.png"))
        .context(context)
        .build()?;

    // --- Record a synthesis into the app's encoder, next to its own work. -----------
    let params = SynthParams {
        width: 256,
        height: 128,
        seed: 3,
        ..SynthParams::default()
    };
    // The copy guard's jitter schedule (a no-op for this 128 px exemplar; from 176 px it
    // synthesizes probes and waits): once, not per frame.
    let params = session.schedule(&params)?;
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
        label: Some("host frame"),
    });
    let synthesis = session.encode(&mut encoder, &params)?;
    // `synthesis.texture` is Rgba8Unorm with TEXTURE_BINDING | STORAGE_BINDING |
    // COPY_SRC: bind it in a render pass, or (here) copy it to a buffer.
    let (w, h) = (synthesis.width, synthesis.height);
    let row = (w * 4).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
    let readback = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("host readback"),
        size: row as u64 * h as u64,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    encoder.copy_texture_to_buffer(
        synthesis.texture.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &readback,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(row),
                rows_per_image: Some(h),
            },
        },
        synthesis.texture.size(),
    );
    queue.submit([encoder.finish()]);

    // --- Read it back. ---------------------------------------------------------------
    let (tx, rx) = std::sync::mpsc::channel();
    readback.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = tx.send(r);
    });
    device.poll(wgpu::PollType::wait_indefinitely())?;
    rx.recv()??;
    let mapped = readback.get_mapped_range(..)?;
    let mut sum = 0u64;
    for y in 0..h as usize {
        let start = y * row as usize;
        sum += mapped[start..start + w as usize * 4]
            .iter()
            .map(|&b| b as u64)
            .sum::<u64>();
    }
    drop(mapped);
    readback.unmap();
    session.context().take_uncaptured_errors()?;
    println!(
        "synthesized a {w}x{h} texture on the host's device (mean byte value {:.1})",
        sum as f64 / (w as f64 * h as f64 * 4.0)
    );
    Ok(())
}
