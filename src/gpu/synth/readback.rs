//! Getting results back to the host: waiting for the device, mapping a buffer and
//! copying it out, and reading an output texture as RGBA8 rows.

use super::GpuSynthesis;
use crate::error::{Error, Result};
use crate::gpu::GpuContext;

impl GpuSynthesis {
    /// Copies the texture back to the host as tightly packed RGBA8 rows (waits for the
    /// GPU). For when the pixels are needed after all;
    /// [`synthesize_to_host`](super::GpuSynthesizer::synthesize_to_host) does the
    /// synthesis and this read-back in one submission. After
    /// [`GpuSynthesizer::encode`](super::GpuSynthesizer::encode), call it only once the encoder is submitted: before,
    /// the texture is still blank (zeros), which this cannot tell from a result. `ctx`
    /// must be the context the texture was made on (the synthesizer's, or a clone): this
    /// struct does not record it, and wgpu panics on another instance's device.
    pub fn read_rgba8(&self, ctx: &GpuContext) -> Result<Vec<u8>> {
        let (w, h) = (self.width, self.height);
        let row = (w as u64 * 4).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT as u64);
        let buffer = ctx.scoped(|| {
            let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("texsyn texture readback"),
                size: row * h as u64,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let mut encoder = ctx.device.create_command_encoder(&Default::default());
            encoder.copy_texture_to_buffer(
                self.texture.as_image_copy(),
                wgpu::TexelCopyBufferInfo {
                    buffer: &buffer,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(row as u32),
                        rows_per_image: Some(h),
                    },
                },
                self.texture.size(),
            );
            ctx.queue.submit([encoder.finish()]);
            buffer
        })?;
        let data = read_buffer(ctx, &buffer)?;
        let mut out = Vec::with_capacity(w as usize * h as usize * 4);
        for y in 0..h as usize {
            let start = y * row as usize;
            out.extend_from_slice(&data[start..start + w as usize * 4]);
        }
        Ok(out)
    }
}

/// Waits until the device has finished the work submitted so far.
pub(crate) fn wait(ctx: &GpuContext) -> Result<()> {
    ctx.device
        .poll(wgpu::PollType::wait_indefinitely())
        .map(|_| ())
        .map_err(|e| Error::Gpu(format!("waiting for the GPU: {e}")))
}

/// Reads a `MAP_READ` buffer back to the host (waits for the device).
pub(crate) fn read_buffer(ctx: &GpuContext, buffer: &wgpu::Buffer) -> Result<Vec<u8>> {
    read_mapped(
        buffer,
        || wait(ctx),
        "buffer mapping was cancelled",
        "reading back results",
    )
}

/// Maps `buffer` for reading, runs `wait` (a device poll that lets the mapping
/// complete) and copies the contents out: the one read-back sequence of the
/// synthesizer ([`read_buffer`]) and the mesh renderer, which word their errors
/// differently: `cancelled` when the mapping is dropped, `"{failed}: {e}"` when it fails.
pub(crate) fn read_mapped(
    buffer: &wgpu::Buffer,
    wait: impl FnOnce() -> Result<()>,
    cancelled: &str,
    failed: &str,
) -> Result<Vec<u8>> {
    let (tx, rx) = std::sync::mpsc::channel();
    buffer.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = tx.send(r);
    });
    wait()?;
    rx.recv()
        .map_err(|_| Error::Gpu(cancelled.into()))?
        .map_err(|e| Error::Gpu(format!("{failed}: {e}")))?;
    let data = buffer
        .get_mapped_range(..)
        .map_err(|e| Error::Gpu(format!("{failed}: {e}")))?
        .to_vec();
    buffer.unmap();
    Ok(data)
}
