//! GPU side: device creation ([`context`]), the generated shader constants
//! ([`shaders`]), synthesis on the GPU ([`synth`]) and the choice of its jitter schedule
//! ([`copy_guard`]).

pub mod advect;
pub mod context;
pub mod copy_guard;
pub mod cpu_threads;
pub mod shaders;
pub mod synth;

pub use context::GpuContext;
