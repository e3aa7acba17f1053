//! The copy guard: more still levels where they do not copy too much.
//!
//! The default jitter schedule ([`crate::passes::plan::default_randomness`]) is set so
//! that no exemplar, regular or not, copies more than about a fifth of itself verbatim.
//! Most exemplars of 176 px and more could take one or two more still levels (larger
//! patches, fewer seams, lower texture energy), but some then copy a third to a half of
//! themselves, and which ones do cannot be told from the exemplar beforehand. So the
//! guard tries: it synthesizes a probe with two more still levels, then one, measures
//! each probe's largest verbatim copy from its coordinates, and keeps the first schedule
//! whose copy stays within a budget.
//!
//! A probe that copies too much usually shows it long before its finest level: the
//! finer levels only trim its verbatim regions at their borders (the finest, only
//! upsampled, keeps them exactly). So the probe is read back at two coarser levels
//! ([`EARLY_CHECKS`]) and given up there when its copy is clearly over the budget;
//! the next tier's probe then starts sooner. Only a copy within a small margin of the
//! budget waits for the output, which decides.
//!
//! The decision must not depend on the output's origin, or windows of the unbounded
//! texture would not fit together: the probe is always the window at the origin, with
//! the caller's other parameters, of the output's size but at least [`COPY_PROBE_SIZE`]
//! pixels a side (a periodic output is its own probe). When the output is that window,
//! the probe is the result.
//!
//! The probe has the output's size because a stiller schedule's largest verbatim copy
//! grows with the extent, while the default schedule's stays at about a fifth of the
//! exemplar at any size. So an output larger than the probe of a smaller one may keep a
//! less still schedule than it, and the two then differ where they overlap; outputs of
//! one size always agree. Outputs over [`MAX_PROBE_SIZE`] a side keep the default
//! schedule. Other windows of the output's size are not measured: tiles of a large
//! texture can copy more than the budget between them; `--copy-budget 0` (the default
//! schedule) bounds the copies at any size.

use super::synth::{GpuSynthesizer, ProbeRun};
use crate::error::{Error, Result};
use crate::passes::{SynthParams, Synthesis};

/// The default budget: the largest verbatim copy a stiller schedule may make, as a
/// fraction of the exemplar's area (a margin below 0.30 for the windows and seeds the
/// probe does not see).
pub const DEFAULT_COPY_BUDGET: f32 = 0.25;

/// Smallest side of the probe window (pixels), at the origin of the unbounded texture;
/// larger outputs probe their own size.
pub const COPY_PROBE_SIZE: u32 = 512;

/// Largest output side the guard probes: a larger output keeps the default schedule
/// (a probe of its size would cost as much as the output, and the default schedule's
/// copies stay at about a fifth of the exemplar at any size).
pub const MAX_PROBE_SIZE: u32 = 2048;

/// The guard applies to exemplars whose smaller side is at least this. Under it the
/// default schedule already matches `texture-synthesis`'s texture energy, and a stiller
/// schedule gained little while many probes copied too much.
pub const GUARD_MIN_SIDE: u32 = 176;

/// The stiller schedules tried, stillest first (values of
/// [`SynthParams::extra_still_levels`]); the first whose probe stays within the budget is
/// kept.
pub const GUARD_TIERS: [u32; 2] = [2, 1];

/// The probe's early checks: (levels above the finest, margin over the budget). A
/// probe whose largest copy at that level exceeds the budget by more than the margin
/// is given up there: the margins exceed the largest differences seen between the copy
/// at that level and the output's.
pub const EARLY_CHECKS: [(u32, f64); 2] = [(3, 0.04), (2, 0.02)];

/// One probe of the copy guard.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Probe {
    /// The probe's [`SynthParams::extra_still_levels`].
    pub extra_still_levels: u32,
    /// Its largest verbatim copy, as a fraction of the exemplar's area: measured on the
    /// output when `spacing` is 1, else the estimate at the coarser level whose pixels
    /// step `spacing` exemplar pixels, where the probe was given up.
    pub copy: f64,
    /// Exemplar pixels per pixel of the level measured: 1 for the output, more where
    /// the probe was given up at a coarser level.
    pub spacing: u32,
}

/// What [`GpuSynthesizer::choose_schedule`] decided.
#[derive(Clone, Debug)]
pub struct ScheduleChoice {
    /// The parameters to synthesize with (`extra_still_levels` decided).
    pub params: SynthParams,
    /// The probes made, in order. Empty when the guard did not apply.
    pub probes: Vec<Probe>,
    /// The kept probe's synthesis when it is the result (`params` with the probe's
    /// window).
    pub result: Option<Synthesis>,
    /// Why the guard, which would apply to these parameters, probed nothing: the output
    /// is over [`MAX_PROBE_SIZE`] a side, or its probe does not fit the device in one
    /// piece. `None` when it probed, or does not apply at all.
    pub unprobed: Option<String>,
}

impl ScheduleChoice {
    /// One line for a log: what was chosen and why.
    pub fn describe(&self, budget: f32) -> String {
        let pct = |c: f64| format!("{:.1}%", c * 100.0);
        let tried: Vec<String> = self
            .probes
            .iter()
            .map(|p| match p.spacing {
                1 => format!("+{}: {}", p.extra_still_levels, pct(p.copy)),
                h => format!(
                    "+{}: {} at 1/{h} resolution, given up there",
                    p.extra_still_levels,
                    pct(p.copy)
                ),
            })
            .collect();
        let what = match self.params.extra_still_levels {
            0 => "the default".to_string(),
            1 => "one more still level".to_string(),
            n => format!("{n} more still levels"),
        };
        if self.probes.is_empty() {
            return match &self.unprobed {
                Some(why) => format!("jitter schedule: {what} (no copy guard: {why})"),
                None => format!("jitter schedule: {what} (no copy guard)"),
            };
        }
        format!(
            "jitter schedule: {what} (copy guard, budget {:.0}% of the exemplar; probes copied {})",
            budget * 100.0,
            tried.join(", ")
        )
    }
}

impl GpuSynthesizer {
    /// Chooses the jitter schedule for `params` with the copy guard (module docs): the
    /// first of `GUARD_TIERS` whose probe synthesis copies at most `budget` of the
    /// exemplar verbatim becomes `extra_still_levels`, else it stays 0. Nothing is probed
    /// (the parameters come back as they are) when `budget` is 0, for exemplars under
    /// `GUARD_MIN_SIDE`, when `params` gives its own `randomness` or
    /// `extra_still_levels`, for anisometric and atlas synthesis (whose patches the
    /// field shapes; not measured), for outputs over `MAX_PROBE_SIZE` a side
    /// ([`Self::probed_size`]), and where the probe does not fit the device in one
    /// piece ([`GpuSynthesizer::fits`]). Costs one synthesis of the probe window per tier
    /// tried (less for a probe given up early, see `EARLY_CHECKS`), plus the result's
    /// own when it is another window or every probe failed.
    pub fn choose_schedule(&self, params: &SynthParams, budget: f32) -> Result<ScheduleChoice> {
        if !budget.is_finite() || !(0.0..=1.0).contains(&budget) {
            return Err(Error::InvalidParameter(format!(
                "copy budget {budget} must be between 0 and 1"
            )));
        }
        // Invalid parameters fail as they would without the guard.
        crate::passes::SynthPlan::new(self.analysis(), params)?;
        let mut choice = ScheduleChoice {
            params: params.clone(),
            probes: Vec::new(),
            result: None,
            unprobed: None,
        };
        let a = self.analysis();
        if budget == 0.0
            || a.width.min(a.height) < GUARD_MIN_SIDE
            || !params.randomness.is_empty()
            || params.extra_still_levels != 0
            || params.anisometric()
        {
            return Ok(choice);
        }
        if !Self::probed_size(params) {
            choice.unprobed = Some(format!("the output is over {MAX_PROBE_SIZE} px a side"));
            return Ok(choice);
        }
        // A probe the device cannot synthesize in one piece (the output is then
        // assembled from windows).
        if !self.fits(&Self::probe_params(params)) {
            choice.unprobed = Some("its probe would not fit the device in one piece".into());
            return Ok(choice);
        }
        for extra in GUARD_TIERS {
            let stiller = SynthParams {
                extra_still_levels: extra,
                ..params.clone()
            };
            let probe = Self::probe_params(&stiller);
            let checks = EARLY_CHECKS.map(|(up, margin)| (up, budget as f64 + margin));
            match self.synthesize_probe(&probe, &checks)? {
                ProbeRun::Stopped { copy, spacing } => choice.probes.push(Probe {
                    extra_still_levels: extra,
                    copy,
                    spacing,
                }),
                ProbeRun::Done { synthesis, copy } => {
                    choice.probes.push(Probe {
                        extra_still_levels: extra,
                        copy,
                        spacing: 1,
                    });
                    if copy <= budget as f64 {
                        choice.result = (probe == stiller).then_some(synthesis);
                        choice.params = stiller;
                        break;
                    }
                }
            }
        }
        Ok(choice)
    }

    /// Whether the guard probes outputs of this size: a side of at most
    /// `MAX_PROBE_SIZE`, or a periodic output (its own probe).
    pub fn probed_size(params: &SynthParams) -> bool {
        params.tileable_output || params.width.max(params.height) <= MAX_PROBE_SIZE
    }

    /// Whether the output of `params` lies within its probe window (or is a periodic
    /// output, its own probe), where the guard's measurement bounds its copies. Other
    /// windows of the same size are not measured (module docs); for tiles with a
    /// bounded copy, use a budget of 0 (the default schedule).
    pub fn output_within_probe(params: &SynthParams) -> bool {
        let probe = Self::probe_params(params);
        params.tileable_output
            || (params.origin[0] >= probe.origin[0]
                && params.origin[1] >= probe.origin[1]
                && params.origin[0] as i64 + params.width as i64
                    <= probe.origin[0] as i64 + probe.width as i64
                && params.origin[1] as i64 + params.height as i64
                    <= probe.origin[1] as i64 + probe.height as i64)
    }

    /// The probe window for `params`: at the origin, of the output's size but at least
    /// `COPY_PROBE_SIZE` a side, or the output itself when it is periodic.
    pub fn probe_params(params: &SynthParams) -> SynthParams {
        if params.tileable_output {
            return params.clone();
        }
        SynthParams {
            width: params.width.max(COPY_PROBE_SIZE),
            height: params.height.max(COPY_PROBE_SIZE),
            origin: [0, 0],
            ..params.clone()
        }
    }
}
