//! Synthesis on the GPU: uploads an [`Analysis`](crate::analysis::Analysis) once, then
//! runs the plan's dispatches (upsample, jitter, correction subpasses per level, gather)
//! in one compute pass per call. Results stay on the GPU (a `wgpu::Texture`) or are read
//! back to the host.

mod buffers;
mod diagnostics;
mod limits;
mod magnify;
mod maps;
mod output;
mod pipelines;
mod probe;
mod readback;
mod record;
mod synthesize;
mod synthesizer;
mod variant;
mod windows;

pub use limits::check_exemplar_fits;
pub use magnify::MagnifiedSynthesis;
pub use maps::ExtraMap;
pub use output::{GpuSynthesis, OUTPUT_FORMAT, OUTPUT_FORMAT_SRGB};
pub use synthesizer::{GpuSynthesizer, LevelProgress};
pub use windows::MAX_WINDOWED_PIXELS;

pub(crate) use limits::check_device_limits;
pub(crate) use pipelines::PassPipelines;
pub(crate) use probe::ProbeRun;
pub(crate) use readback::{read_buffer, read_mapped, wait};
pub(crate) use variant::Variant;
