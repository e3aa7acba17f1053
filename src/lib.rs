//! texsyn: real-time appearance-space texture synthesis (Lefebvre & Hoppe 2006) on wgpu.
//!
//! Give it a small image of a material (an *exemplar*) and it makes as much new texture as
//! you want: on an image, along direction and scale fields, over a mesh's texture atlas,
//! and moving frame by frame along a flow. The exemplar is analysed once on the CPU; every
//! synthesis pass runs as a WGSL compute shader.
//!
//! # Entry points
//!
//! Every job has a builder; the `texsyn` command line is a thin client of the same calls.
//!
//! | job | builder | result |
//! |---|---|---|
//! | a texture (any size, windows, fields, tileable, magnified, material maps) | [`Session::builder`] | [`Texture`] |
//! | a textured mesh (glTF in, glTF out) | [`SurfaceSession::builder`] | [`TexturedSurface`] |
//! | a texture moving along a flow, in 2D or on a mesh | [`AdvectSession::builder`] | [`AdvectFrame`]s |
//! | quality figures of a result | [`Evaluation::new`] | [`EvaluationReport`] |
//! | timings | [`Benchmark::new`] | [`BenchmarkTable`] |
//!
//! ```no_run
//! let session = texsyn::Session::builder()
//!     .exemplar_path("assets/gravel.png")
//!     .size(512, 512)
//!     .seed(7)
//!     .build()?;
//! session.run()?.save("out.png")?;
//! # Ok::<(), texsyn::Error>(())
//! ```
//!
//! An application with its own device builds a [`GpuContext`] from it
//! ([`GpuContext::from_device`]) and records syntheses into its own command encoders
//! ([`GpuSynthesizer::encode`], [`Advection::encode_step`]); `texsyn::wgpu` is the wgpu
//! this crate is built against, so that the versions match.
//!
//! # Lower levels
//!
//! For research and tools: [`analysis`] (the exemplar's appearance space and similarity
//! sets), [`passes`] (the synthesis plan and a CPU mirror of every GPU pass, bit for bit),
//! [`field`] and [`flow`] (Jacobian and velocity fields), [`surface`] (meshes, atlases,
//! glTF, rendering), [`quality`] (the figures `texsyn eval` prints) and [`image_io`] (image
//! files, written atomically).

#![warn(missing_docs)]

pub use wgpu;

/// A module public only with the `internals` feature (the crate's own tests, which
/// check the GPU layer pass by pass); otherwise reached through the crate root's
/// re-exports.
macro_rules! internal_module {
    ($name:ident) => {
        #[cfg(feature = "internals")]
        #[doc(hidden)]
        pub mod $name;
        #[cfg(not(feature = "internals"))]
        mod $name;
    };
}

pub mod analysis;
mod error;
pub mod field;
pub mod flow;
internal_module!(gpu);
pub mod image_io;
mod options;
pub mod passes;
pub mod quality;
mod session;
mod shader_preprocess;
pub mod surface;

pub use analysis::{Analysis, AnalysisOptions, Exemplar};
pub use error::{Error, Result};
pub use field::{Field, FieldMap};
pub use flow::Flow;
pub use gpu::advect::Advection;
pub use gpu::context::GpuOptions;
pub use gpu::copy_guard::DEFAULT_COPY_BUDGET;
pub use gpu::synth::{
    ExtraMap, GpuSynthesis, GpuSynthesizer, LevelProgress, MagnifiedSynthesis, OUTPUT_FORMAT,
    OUTPUT_FORMAT_SRGB,
};
pub use gpu::GpuContext;
pub use options::{AdvectOptions, DistanceMode, SynthParams};
pub use passes::Synthesis;
// The builders and what they return (src/session/), all at the root.
pub use session::*;
