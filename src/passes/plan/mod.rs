//! The synthesis plan: which region of the infinite synthesis pyramid each level
//! computes, and the per-dispatch parameters. GPU and CPU both execute this plan.
//!
//! The output is a window of an unbounded texture: level `l` computes an absolute region
//! that covers everything the finer level reads, plus a margin of `4 * passes` pixels
//! (`4 * finest_passes + 1` at the finest level, whose gather reads the 4-neighbours).
//! A correction pass of 4 subpasses propagates information at most 4 pixels, so pixels
//! that far from the region edge never see the clamped reads at the edge: the result is
//! independent of the window, and overlapping windows agree.

mod advect_schedule;
mod defaults;
mod layout;
mod regions;
mod schedule;

pub use crate::options::{DistanceMode, SynthParams, STANDALONE_MARGIN, STANDALONE_MIN_REGION};
pub use defaults::{
    default_randomness, default_second_finest_passes, passes_at, ExemplarShape,
    LARGE_SECOND_FINEST_PASSES, SMALL_SECOND_FINEST_PASSES, UNSEARCHED_PASSES,
};
pub use regions::{torus_period, LevelPlan, SynthPlan, Torus, TORUS_MIN_SIDE};
pub use schedule::{quarter_tables_level, Dispatch, PassKind, SUBPASS_ORDER};
