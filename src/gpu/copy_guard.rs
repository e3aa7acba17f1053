//! The copy guard: one more still level where it does not copy too much.
//!
//! The default jitter schedule ([`crate::passes::plan::default_randomness`]) is set so
//! that no exemplar, regular or not, copies more than about a fifth of itself verbatim.
//! Most exemplars could take one more still level (larger patches, fewer seams, lower
//! texture energy), but regular ones then copy a third to three quarters of themselves,
//! and which ones do cannot be told from the exemplar beforehand. So the guard tries:
//! it synthesizes a probe with one more still level, measures its largest verbatim copy
//! from the coordinates, and keeps that schedule if the copy stays within a budget.
//!
//! Measured (README, *Measured figures*, twenty-third session; 42 exemplars of 64-512
//! px x seeds 1-3, 512x512, lavapipe): full-resolution texture energy over
//! `texture-synthesis`'s 1.06 -> 0.84 (median), half and quarter resolution about 1.0,
//! and the stiller schedule kept in 106 of 126 syntheses.
//!
//! The decision must not depend on the output window, or windows of the unbounded
//! texture would not fit together: the probe is always the window at the origin of
//! [`COPY_PROBE_SIZE`] pixels (a periodic output is its own probe), with the caller's
//! other parameters. When the output is that window, the probe is the result.

use super::context::GpuContext;
use super::synth::GpuSynthesizer;
use crate::error::{Error, Result};
use crate::passes::{SynthParams, Synthesis};
use crate::quality::verbatim_stats;

/// The default budget: the largest verbatim copy the stiller schedule may make, as a
/// fraction of the exemplar's area (issue 2 allows 0.30; this keeps a margin for the
/// windows and seeds the probe does not see).
pub const DEFAULT_COPY_BUDGET: f32 = 0.25;

/// Side of the probe window (pixels), at the origin of the unbounded texture.
pub const COPY_PROBE_SIZE: u32 = 512;

/// What [`GpuSynthesizer::choose_schedule`] decided.
#[derive(Clone, Debug)]
pub struct ScheduleChoice {
    /// The parameters to synthesize with (`extra_still_levels` decided).
    pub params: SynthParams,
    /// The probe's largest verbatim copy (fraction of the exemplar), when one was made.
    pub probe_copy: Option<f64>,
    /// The probe's synthesis when it is the result (`params` with the probe's window).
    pub result: Option<Synthesis>,
}

impl ScheduleChoice {
    /// Whether the stiller schedule was kept.
    pub fn stiller(&self) -> bool {
        self.params.extra_still_levels > 0
    }

    /// One line for a log: what was chosen and why.
    pub fn describe(&self, budget: f32) -> String {
        match self.probe_copy {
            None => "jitter schedule: the default (no copy guard)".into(),
            Some(c) if self.stiller() => format!(
                "jitter schedule: one more still level (the probe copied {:.1}% of the exemplar, within the {:.0}% budget)",
                c * 100.0,
                budget * 100.0
            ),
            Some(c) => format!(
                "jitter schedule: the default (one more still level copied {:.1}% of the exemplar, over the {:.0}% budget)",
                c * 100.0,
                budget * 100.0
            ),
        }
    }
}

impl GpuSynthesizer {
    /// Chooses the jitter schedule for `params` with the copy guard (module docs):
    /// `extra_still_levels` becomes 1 if a probe synthesis with it copies at most
    /// `budget` of the exemplar verbatim, else stays 0. Nothing is probed (the
    /// parameters come back as they are) when `budget` is 0, when `params` gives its own
    /// `randomness` or `extra_still_levels`, or for anisometric and atlas synthesis
    /// (whose patches the field shapes; not measured). Costs one synthesis of the probe
    /// window, plus the result's own when it is another window or the probe failed.
    pub fn choose_schedule(
        &self,
        ctx: &GpuContext,
        params: &SynthParams,
        budget: f32,
    ) -> Result<ScheduleChoice> {
        if !budget.is_finite() || !(0.0..=1.0).contains(&budget) {
            return Err(Error::InvalidParameter(format!(
                "copy budget {budget} must be between 0 and 1"
            )));
        }
        let unchanged = ScheduleChoice {
            params: params.clone(),
            probe_copy: None,
            result: None,
        };
        if budget == 0.0
            || !params.randomness.is_empty()
            || params.extra_still_levels != 0
            || params.anisometric()
        {
            return Ok(unchanged);
        }
        // Invalid parameters fail as they would without the guard.
        crate::passes::SynthPlan::new(self.analysis(), params)?;
        let stiller = SynthParams {
            extra_still_levels: 1,
            ..params.clone()
        };
        let probe = Self::probe_params(&stiller);
        let s = self.synthesize_to_host(ctx, &probe)?;
        let a = self.analysis();
        let copy = verbatim_stats(&s.coords, s.width, s.height, a.width, a.height, a.tileable)?
            .largest_region_fraction;
        if copy <= budget as f64 {
            let result = (probe == stiller).then_some(s);
            Ok(ScheduleChoice {
                params: stiller,
                probe_copy: Some(copy),
                result,
            })
        } else {
            Ok(ScheduleChoice {
                probe_copy: Some(copy),
                ..unchanged
            })
        }
    }

    /// The probe window for `params`: the origin's [`COPY_PROBE_SIZE`] square, or the
    /// output itself when it is periodic.
    pub fn probe_params(params: &SynthParams) -> SynthParams {
        if params.tileable_output {
            return params.clone();
        }
        SynthParams {
            width: COPY_PROBE_SIZE,
            height: COPY_PROBE_SIZE,
            origin: [0, 0],
            ..params.clone()
        }
    }
}
