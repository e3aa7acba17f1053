//! CPU mirrors of the WGSL passes, one module per shader of the same name
//! (`shaders/upsample.wgsl` <-> `upsample.rs`), plus the synthesis plan that both the
//! GPU and the CPU follow. All arithmetic is integer, so GPU and CPU agree bit for bit.

pub mod common;
pub mod correct;
pub mod gather;
pub mod jitter;
pub mod plan;
pub mod upsample;

pub use plan::{LevelPlan, SynthPlan, SynthParams};
