//! GPU side: device creation ([`context`]), the generated shader constants
//! ([`shaders`]) and synthesis on the GPU ([`synth`]).

pub mod advect;
pub mod context;
pub mod shaders;
pub mod synth;

pub use context::GpuContext;
