//! The option types users set, in one place: what a synthesis does ([`SynthParams`], with
//! the atlas domain the surface layer adds) and what advection frames do
//! ([`AdvectOptions`]). The builders fill them; the plan and the GPU layer read them.

mod advect;
mod atlas;
mod synth;

pub use advect::{
    AdvectOptions, FADE_CHANGE, KEEP_LOOK_FADE, KEEP_LOOK_REMAKE_THRESHOLD, MAX_ANCHOR_SPACING,
    MAX_FADE_FRAMES,
};
pub use atlas::{AtlasDomain, AtlasLevel, FillEntry};
pub use synth::{DistanceMode, SynthParams, STANDALONE_MARGIN, STANDALONE_MIN_REGION};
