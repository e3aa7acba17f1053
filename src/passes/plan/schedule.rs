//! The dispatches of a synthesis: what each does, in which order.

use super::{passes_at, DistanceMode, ExemplarShape, SynthPlan};
use crate::analysis::Analysis;
use crate::passes::common::PassParams;
use crate::passes::fill::FILL_ROW;

/// What a dispatch does.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PassKind {
    /// Coherent upsampling of the coarser level (`upsample.wgsl`).
    Upsample,
    /// Jitter of the upsampled coordinates (`jitter.wgsl`).
    Jitter,
    /// One correction subpass (`correct.wgsl`).
    Correct,
    /// Colours of the output window (`gather.wgsl`).
    Gather,
    /// Anisometric upsampling (continuous coordinates, Jacobian field).
    UpsampleAniso,
    /// Anisometric correction subpass.
    CorrectAniso,
    /// Anisometric gather.
    GatherAniso,
    /// Atlas synthesis: refill the gutters through the indirection map.
    Fill,
    /// Advection: move the coordinates with the flow (into the scratch region).
    Advect,
    /// Advection: copy the moved coordinates back, flagging the pixels whose
    /// coordinates the flow distorted too much (for the upsample pass).
    Distortion,
    /// Advection: add the frame's centre velocity, in whole finest pixels, to the drift
    /// (one invocation, first in a frame).
    Drift,
    /// Advection frames with fading: the finest level's colours, pixels whose
    /// coordinate jumped fading in over a few frames (`fade.wgsl`); in place of the gather.
    Fade,
    /// A tileable output made on a torus ([`Torus`](super::Torus)): the finest level's coordinates
    /// resampled onto the output's grid.
    Resample,
}

/// One dispatch of the schedule: the GPU and the CPU mirror run the same list.
#[derive(Clone, Copy, Debug)]
pub struct Dispatch {
    /// The pass (and so the pipeline) to run.
    pub kind: PassKind,
    /// The level it works on (index into [`SynthPlan::levels`]).
    pub level: usize,
    /// Its uniform parameters.
    pub params: PassParams,
}

impl Dispatch {
    /// Threads this dispatch needs (x, y): one per pixel, or per pixel of one parity.
    pub fn threads(&self) -> [u32; 2] {
        let p = &self.params;
        match self.kind {
            PassKind::Upsample | PassKind::UpsampleAniso | PassKind::Jitter => {
                [p.size[0] as u32, p.size[1] as u32]
            }
            PassKind::Correct | PassKind::CorrectAniso => {
                let axis = |class: i32, size: i32| {
                    if class == 2 {
                        1
                    } else {
                        ((size - 2 * p.inset).max(0) as u32).div_ceil(2)
                    }
                };
                [axis(p.parity[0], p.size[0]), axis(p.parity[1], p.size[1])]
            }
            PassKind::Gather | PassKind::GatherAniso => {
                [p.window_size[0] as u32, p.window_size[1] as u32]
            }
            PassKind::Fill => [p.fill_count.min(FILL_ROW), p.fill_count.div_ceil(FILL_ROW)],
            PassKind::Advect | PassKind::Distortion | PassKind::Resample | PassKind::Fade => {
                [p.size[0] as u32, p.size[1] as u32]
            }
            PassKind::Drift => [1, 1],
        }
    }

    /// Whether this dispatch may read a level's quarter-pixel tables
    /// (`crate::gpu::synth`'s fine tables) instead of interpolating `et` and `qe`: an
    /// anisometric correction with the projected distance that reads quarter pixels
    /// (advection frames) of a level with tables (recognized by its table offset,
    /// [`Analysis::table_base`], which skips levels without tables). A schedule reads the
    /// tables of one level, [`quarter_tables_level`]; the others interpolate.
    pub fn reads_quarter_tables(&self, analysis: &Analysis) -> bool {
        self.kind == PassKind::CorrectAniso
            && self.params.quarter != 0
            && self.params.full_distance == 0
            && self.level < analysis.levels.len()
            && self.params.et_base as usize == analysis.table_base(self.level)
    }
}

/// The level whose quarter-pixel tables a schedule reads: the finest level with a
/// dispatch that [`Dispatch::reads_quarter_tables`] (an advection frame's most
/// corrected level: the finest, or the second-finest when the finest is upsampled, or
/// the advected level above the re-synthesized ones).
pub fn quarter_tables_level(schedule: &[Dispatch], analysis: &Analysis) -> Option<usize> {
    schedule
        .iter()
        .filter(|d| d.reads_quarter_tables(analysis))
        .map(|d| d.level)
        .max()
}

/// Correction subpass order (absolute parities).
pub const SUBPASS_ORDER: [[i32; 2]; 4] = [[0, 0], [1, 1], [1, 0], [0, 1]];

impl SynthPlan {
    /// Every dispatch of the synthesis, in order.
    pub fn schedule(&self, analysis: &Analysis) -> Vec<Dispatch> {
        self.schedule_with(analysis, true)
    }

    /// The schedule; with `shrink`, correction subpass `s` of a level (counted over all
    /// its passes) skips the `s + 1` outermost rings of the margin. Each subpass reads
    /// one pixel around the pixels it updates, so the pixels `s + 1` in from the edge
    /// are exactly what the full subpasses would give, and after the last of the
    /// level's `4 passes` subpasses that is everything inside the margin (plus the ring
    /// the finest level's gather reads): the output does not change, and the coarse
    /// levels, mostly margin, cost less.
    pub fn schedule_with(&self, analysis: &Analysis, shrink: bool) -> Vec<Dispatch> {
        self.schedule_inner(analysis, shrink, true)
    }

    /// [`Self::schedule_with`]; with `skip`, the corrections skip settled pixels (below).
    pub(super) fn schedule_inner(
        &self,
        analysis: &Analysis,
        shrink: bool,
        skip: bool,
    ) -> Vec<Dispatch> {
        let aniso = self.params.anisometric();
        let (upsample, correct, gather) = if aniso {
            (
                PassKind::UpsampleAniso,
                PassKind::CorrectAniso,
                PassKind::GatherAniso,
            )
        } else {
            (PassKind::Upsample, PassKind::Correct, PassKind::Gather)
        };
        let mut out = Vec::new();
        // Corrections skip the pixels whose 3x3 neighbourhood, the pixel included, is
        // unchanged since their class's previous subpass, which left the pixel as it
        // was: a correction is a function of those nine coordinates (and of the pixel's
        // Jacobian, fixed during a synthesis), so it would leave it again. A pixel that
        // changes writes its subpass's stamp (counted over the whole schedule, from 1)
        // for itself and its 8 neighbours after the coordinates (`flag_base`); a pixel
        // whose stamp is below the stamp of its class's latest subpass with the same
        // candidates (`sets_every` alternates two kinds) is skipped. A level's first
        // pass (of each kind) runs in full, and so do jittered levels (below). Not in
        // atlas synthesis, whose fills rewrite the gutters between subpasses, nor in
        // advection (`advect_schedule`, whose coordinates move between frames, and
        // `advect_first_schedule`: `skip` off). The CPU mirror computes every pixel: the
        // same bytes.
        let skipping = skip && self.params.surface.is_none();
        let mut stamp = 0u32;
        for level in 0..self.levels.len() {
            let params = self.pass_params(analysis, level);
            out.push(Dispatch {
                kind: upsample,
                level,
                params,
            });
            // Atlas synthesis: gutters refilled after every pass that writes coordinates.
            let fill = Dispatch {
                kind: PassKind::Fill,
                level,
                params,
            };
            let fill_all = Dispatch {
                kind: PassKind::Fill,
                level,
                params: PassParams {
                    fill_count: self.surface_layout.get(level).map_or(0, |s| s.fill_count),
                    ..params
                },
            };
            let fills = params.fill_count > 0;
            if level == 0 {
                if fill_all.params.fill_count > 0 {
                    out.push(fill_all);
                }
                continue;
            }
            if params.jitter_amp != 0 {
                out.push(Dispatch {
                    kind: PassKind::Jitter,
                    level,
                    params,
                });
            }
            if fills {
                out.push(fill);
            }
            let finest = level + 1 == self.levels.len();
            let passes = passes_at(
                &self.params,
                level as u32,
                self.levels.len() as u32 - 1,
                ExemplarShape::of(analysis),
            );
            let full = match self.params.distance {
                DistanceMode::Projected => false,
                DistanceMode::Full => true,
                DistanceMode::Mixed => !finest,
            };
            // A periodic region of odd size needs a third class along that axis.
            let periodic = self.params.tileable_output;
            let sz = self.levels[level].size;
            let wx = crate::passes::common::has_wrap_class(sz[0] as i32, periodic);
            let wy = crate::passes::common::has_wrap_class(sz[1] as i32, periodic);
            let mut order: Vec<[i32; 2]> = SUBPASS_ORDER.to_vec();
            if wx {
                order.extend([[2, 0], [2, 1]]);
            }
            if wy {
                order.extend([[0, 2], [1, 2]]);
            }
            if wx && wy {
                order.push([2, 2]);
            }
            let margin = self.levels[level].margin as i32;
            let mut subpass = 0;
            // Only on unjittered levels: on a jittered one few pixels settle before the
            // last pass, which does not pay for the stamps.
            let skipping = skipping && params.jitter_amp == 0;
            // Per class and kind of pass (with the sets, without): the stamp of its
            // latest subpass of that kind at this level (0: none yet).
            let mut previous = vec![[0u32; 2]; order.len()];
            for pass in 0..passes {
                // Without the sets a pass is the same correction with k = 1 (its own
                // pipeline, whose candidate loop compiles to the coherent candidates).
                let k = if pass % self.params.sets_every == 0 {
                    params.k
                } else {
                    1
                };
                for (class, &parity) in order.iter().enumerate() {
                    subpass += 1;
                    stamp += 1;
                    // Since then, every change in the neighbourhood (also one by a
                    // subpass of the other kind) left a newer stamp.
                    let kind = (k != params.k) as usize;
                    let clean_before = if skipping { previous[class][kind] } else { 0 };
                    previous[class][kind] = stamp;
                    // Stamps serve the level's next subpasses: none from its last.
                    let last = pass + 1 == passes && class + 1 == order.len();
                    let stamp = if skipping && !last { stamp } else { 0 };
                    let params = PassParams {
                        k,
                        parity,
                        full_distance: full as u32,
                        inset: if shrink { subpass.min(margin) } else { 0 },
                        flag_base: self.flag_base(),
                        stamp,
                        clean_before,
                        ..params
                    };
                    out.push(Dispatch {
                        kind: correct,
                        level,
                        params,
                    });
                    if fills {
                        out.push(fill);
                    }
                }
            }
            if fill_all.params.fill_count > fill.params.fill_count {
                out.push(fill_all);
            }
        }
        let last = self.levels.len() - 1;
        if let Some(t) = &self.torus {
            let params = self.torus_output_params(analysis, t);
            out.push(Dispatch {
                kind: PassKind::Resample,
                level: last,
                params,
            });
            out.push(Dispatch {
                kind: gather,
                level: last,
                params,
            });
            return out;
        }
        out.push(Dispatch {
            kind: gather,
            level: last,
            params: self.pass_params(analysis, last),
        });
        out
    }
}
