//! Quality figures for synthesized textures, used by `texsyn eval` and the tests.
//!
//! Each figure answers one question about an output. Most are distances or shares of
//! defects, where lower is better; each function's documentation says how to read it.
//!
//! * [`texture_energy`] (`energy`): are the output's neighbourhoods the exemplar's?
//!   The mean squared per-channel difference of each output window to its nearest
//!   exemplar window; 0 when every output window occurs in the exemplar.
//!   [`multiscale_energy`] and [`coarse_energy_any_phase`] ask the same of the larger
//!   features at half and quarter resolution.
//! * [`histogram_distance`] (`histogram`): does the output use the exemplar's values in
//!   the same proportions?
//! * [`verbatim_stats`] (`verbatim`): how much of a coordinate map is verbatim copy, and
//!   how large the largest copied piece is.
//! * [`layout_repetition`] (`repetition`): does the layout repeat at one displacement,
//!   as a tiling does?
//! * [`feature_breakage`] (`features`): do thin features (mortar, cracks) survive, or
//!   break into crumbs?
//! * [`jacobian_fidelity`] (`jacobian`): does an anisometric output follow its
//!   Jacobian field?
//! * [`wrap_seam_ratio`] (`tiling`): does an image tile without a visible seam?
//! * [`temporal_report`] and [`TemporalFigures`] (`temporal`): does an advected
//!   sequence move with the flow without popping or blurring?
//! * [`evaluate`] (`report`) gathers the figures of one output into a
//!   [`QualityReport`] with a stable JSON form; [`shuffled_baseline`] is the "shuffled
//!   pixels" reference output that gives them a scale.
//!
//! Images are [`FloatImage`]s: 1 (grey) or 3 (RGB) channels of `f32` in `[0, 1]`.
//! When two images with different channel counts are compared, the grey one is
//! replicated into RGB (so a grey exemplar compared with its RGB-encoded output gives
//! the same figures as grey against grey, and colour lost in a grey output is counted
//! as an error rather than hidden). Every figure is deterministic and independent of
//! the number of threads.

mod common;
mod energy;
mod features;
mod histogram;
mod image;
mod jacobian;
mod repetition;
mod report;
mod temporal;
#[cfg(test)]
mod test_images;
mod tiling;
mod verbatim;
mod windows;

pub(crate) use common::json_num;
pub use energy::{
    coarse_energy_any_phase, multiscale_energy, texture_energy, texture_energy_any,
    texture_energy_exact, texture_energy_map, EnergyMap, DEFAULT_RADIUS,
};
pub use features::{feature_breakage, fragment_fraction, FeatureBreakage, MIN_FEATURE_FRAGMENT};
pub use histogram::histogram_distance;
pub use image::FloatImage;
pub use jacobian::{jacobian_fidelity, JacobianReport};
pub use repetition::{
    layout_repetition, LayoutRepetition, MAX_REPEAT_WINDOW, MIN_REPEAT_DISTANCE, REPEAT_BIN,
};
pub use report::{evaluate, shuffled_baseline, QualityReport};
pub use temporal::{
    high_frequency_energy, pop_fraction, temporal_report, warped_difference, TemporalFigures,
    TemporalReport, POP_BLOCK, POP_CHANGE,
};
pub use tiling::wrap_seam_ratio;
pub use verbatim::{verbatim_stats, verbatim_stats_at_spacing, CoordMap, VerbatimStats};
