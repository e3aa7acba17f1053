//! texsyn: real-time appearance-space texture synthesis (Lefebvre & Hoppe 2006) on wgpu.
//!
//! Layout: [`analysis`] (host preprocessing of the exemplar) | [`passes`] (the synthesis
//! plan and CPU mirrors of the WGSL passes) | [`gpu`] (device, pipelines, synthesis on
//! the GPU) | [`field`] (Jacobian fields for anisometric synthesis) | [`quality`] (figures for evaluation) | [`image_io`] (files).

pub mod analysis;
pub mod error;
pub mod field;
pub mod flow;
pub mod gpu;
pub mod image_io;
pub mod passes;
pub mod quality;
pub mod session;
mod shader_preprocess;
pub mod surface;

pub use analysis::{Analysis, AnalysisOptions, Exemplar};
pub use error::{Error, Result};
pub use passes::{DistanceMode, SynthParams, Synthesis};
pub use session::{Session, SessionBuilder, Texture};
// The types an embedder names most, at the root.
pub use field::{Field, FieldMap};
pub use flow::Flow;
pub use gpu::advect::{AdvectOptions, Advection};
pub use gpu::synth::{GpuSynthesis, GpuSynthesizer};
pub use gpu::GpuContext;
