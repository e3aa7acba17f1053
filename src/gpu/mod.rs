//! GPU side: device creation ([`context`]), the generated shader constants
//! ([`shaders`]), synthesis on the GPU ([`synth`]), the choice of its jitter schedule
//! ([`copy_guard`]), texture advection ([`advect`]) and the placement of a CPU driver's
//! worker threads ([`cpu_threads`]).

pub mod advect;
pub mod context;
pub mod copy_guard;
pub mod cpu_threads;
pub mod shaders;
pub mod synth;

pub use context::GpuContext;

/// `wgpu::util::DeviceExt::create_buffer_init` without its panic: on a lost or destroyed
/// device the buffer cannot be mapped, and wgpu's helper panics there ("Failed to get
/// mapped range"). Here the (invalid) buffer comes back unfilled instead, and the error
/// reaches the caller through the error scope every texsyn call runs in, as
/// [`crate::Error::Gpu`].
pub(crate) fn buffer_init(
    device: &wgpu::Device,
    desc: &wgpu::util::BufferInitDescriptor<'_>,
) -> wgpu::Buffer {
    let size = (desc.contents.len() as u64)
        .next_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT)
        .max(wgpu::COPY_BUFFER_ALIGNMENT);
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: desc.label,
        size,
        usage: desc.usage,
        mapped_at_creation: true,
    });
    if let Ok(mut view) = buffer.get_mapped_range_mut(..) {
        view.slice(..desc.contents.len())
            .copy_from_slice(desc.contents);
        drop(view);
        buffer.unmap();
    }
    buffer
}
