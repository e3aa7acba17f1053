//! The dispatches of advection: the first frame, the later frames and the static levels.

use super::{Dispatch, PassKind, SynthPlan};
use crate::analysis::Analysis;
use crate::passes::advect::AdvectOptions;
use crate::passes::common::PassParams;

/// A level's dispatches of `schedule` but its corrections (and the fills after them):
/// the upsampling and the fills of an atlas's gutters (the finest level of an advection
/// frame that upsamples it, [`SynthPlan::advect_schedule`]). No gather, and no jitter:
/// jitter depends on the pixel's place on the screen, so re-applied every frame it
/// would pin the detail to the screen while the flow moves it (as in
/// [`resynthesized_levels`]); frame 0 leaves it out too, so frame 1 keeps its look.
fn finest_without_corrections(schedule: &[Dispatch], level: usize) -> Vec<Dispatch> {
    let mut out = Vec::new();
    let mut after_correction = false;
    for d in schedule.iter().filter(|d| d.level == level) {
        match d.kind {
            PassKind::CorrectAniso | PassKind::Correct => after_correction = true,
            PassKind::Gather | PassKind::GatherAniso | PassKind::Jitter => {}
            PassKind::Fill if after_correction => after_correction = false,
            _ => {
                after_correction = false;
                out.push(*d);
            }
        }
    }
    out
}

/// The levels `top + 1 ..= top + count` of an advection frame's `schedule` (the frame
/// plan's synthesis), re-synthesized from the advected level `top`
/// ([`AdvectOptions::resynthesize`]): upsampled following the drift's
/// phase (`drift`, 0 for none), as the finest level is, then corrected as in a
/// synthesis. No jitter: it is a function of the pixel's place on the screen, so
/// re-applied every frame it would pin the texture's detail to the screen while the flow
/// moves it; the advected levels carry frame 0's jitter.
fn resynthesized_levels(
    schedule: &[Dispatch],
    top: usize,
    count: usize,
    drift: u32,
) -> Vec<Dispatch> {
    let mut out = Vec::new();
    for d in schedule
        .iter()
        .filter(|d| d.level > top && d.level <= top + count)
    {
        match d.kind {
            PassKind::Gather | PassKind::GatherAniso | PassKind::Jitter => {}
            PassKind::Upsample | PassKind::UpsampleAniso => out.push(Dispatch {
                params: PassParams { drift, ..d.params },
                ..*d
            }),
            _ => out.push(*d),
        }
    }
    out
}

impl SynthPlan {
    /// An advection frame's fade dispatch in place of its gather `g` (`options.fade` > 0):
    /// over the finest level's region with the frame's drift and dither, reading the
    /// state half `frame % 2` (written by the previous frame; frame 0's synthesis writes
    /// half 0), writing the other. `first` (frame 0): writing half 0 with every pixel
    /// unfaded.
    fn fade_dispatch(
        &self,
        analysis: &Analysis,
        g: &Dispatch,
        options: &AdvectOptions,
        frame: u64,
        first: bool,
    ) -> Dispatch {
        let n = self.levels.len() - 1;
        let half = |h: u64| (self.fade_base() as u64 + h * self.fade_half_len()) as u32;
        let (src, dst) = if first {
            (0, half(0))
        } else {
            (half(frame % 2), half((frame + 1) % 2))
        };
        Dispatch {
            kind: PassKind::Fade,
            level: n,
            params: PassParams {
                drift: if first { 0 } else { self.drift_index() },
                dither: crate::passes::advect::dither(frame),
                flag_base: self.flag_base(),
                fade_src: src,
                fade_dst: dst,
                fade_frames: options.fade,
                fade_mean: crate::passes::fade::mean_color(&analysis.colors),
                fade_change: options.fade_change,
                ..g.params
            },
        }
    }

    /// The plan an advection frame's dispatches come from: this synthesis with the
    /// frames' `passes` correction passes at every level and their `sets_every`.
    fn frame_plan(&self, options: &AdvectOptions) -> SynthPlan {
        let mut frame_plan = self.clone();
        frame_plan.params.passes = options.passes;
        frame_plan.params.second_finest_passes = Some(options.passes);
        frame_plan.params.finest_passes = options.passes;
        frame_plan.params.sets_every = options.sets_every.clamp(1, 16);
        frame_plan
    }

    /// The correction passes per frame of the coarsest advected level where it is not the
    /// most corrected one: [`AdvectOptions::coarsest_passes`], or where it
    /// is `None`, 2 (at least `passes`, none with none) with `keep_look` where the
    /// desired Jacobian is the same everywhere (no atlas; no field or a constant one), else
    /// `passes`.
    pub fn advect_coarsest_passes(&self, options: &AdvectOptions) -> u32 {
        options.coarsest_passes.unwrap_or(
            if options.keep_look && self.params.constant_jacobian() && options.passes > 0 {
                options.passes.max(2)
            } else {
                options.passes
            },
        )
    }

    /// The synthesis schedule a frame takes its levels' corrections from (no skipping):
    /// the frames' `passes` at every level but the coarsest advected one, `coarsest`,
    /// which takes [`Self::advect_coarsest_passes`] where it is not the most corrected
    /// level `top`.
    fn frame_synthesis(
        &self,
        analysis: &Analysis,
        options: &AdvectOptions,
        coarsest: usize,
        top: usize,
    ) -> Vec<Dispatch> {
        let full = self
            .frame_plan(options)
            .schedule_inner(analysis, false, false);
        let coarse = self.advect_coarsest_passes(options);
        if coarse == options.passes || coarsest >= top {
            return full;
        }
        let mut plan = self.frame_plan(options);
        plan.params.passes = coarse;
        plan.params.second_finest_passes = Some(coarse);
        plan.params.finest_passes = coarse;
        // Both are in level order (the gather last, at the finest level).
        let mut out: Vec<Dispatch> = full
            .iter()
            .filter(|d| d.level < coarsest)
            .copied()
            .collect();
        out.extend(
            plan.schedule_inner(analysis, false, false)
                .into_iter()
                .filter(|d| d.level == coarsest),
        );
        out.extend(full.into_iter().filter(|d| d.level > coarsest));
        out
    }

    /// The dispatches of one advection frame (Lefebvre & Hoppe 2006 §7), on the `levels` finest
    /// levels, coarse to fine. Each advected level: advect the coordinates in place, flag
    /// the pixels distorted beyond `c` (|J_obs - J|_F, Jacobian units), upsample only
    /// those from the coarser level, then correct with `passes` passes as synthesis does.
    /// With [`AdvectOptions::upsample_finest`] (the default) the finest level is not
    /// advected: it is upsampled from the advected second-finest level, which each frame
    /// corrects with its `passes` whole passes, as a synthesis makes its finest level by
    /// default. Otherwise the finest level is advected too, and with `passes == 1` each
    /// frame runs half of its subpasses. The coarser advected levels run a quarter of
    /// theirs (the rest in the next frames); the coarser levels keep the first frame's
    /// coordinates. The gather ends the frame. Needs an anisometric plan (continuous
    /// coordinates).
    ///
    /// [`AdvectOptions::upsample_finest`]: AdvectOptions::upsample_finest
    pub fn advect_schedule(
        &self,
        analysis: &Analysis,
        options: &AdvectOptions,
        frame: u64,
    ) -> Vec<Dispatch> {
        let (levels, c, passes, nearest) = (
            options.levels,
            options.threshold,
            options.passes,
            options.nearest,
        );
        let n = self.levels.len();
        let upsample_finest = options.upsample_finest && n >= 2;
        // Levels between the advected ones and the finest, re-synthesized every frame.
        let resynth = if upsample_finest {
            options.resynthesize.min(n - 2)
        } else {
            0
        };
        // The finest level the frames advect and correct.
        let top = if upsample_finest {
            n - 2 - resynth
        } else {
            n - 1
        };
        let first = n - levels.clamp(1, n);
        // The synthesis schedule with `passes` correction passes at every level but the
        // coarsest advected one (`coarsest_passes`). No skipping (see
        // `schedule_inner`): the advection moves the coordinates.
        let frame_plan = self.frame_plan(options);
        let full = self.frame_synthesis(analysis, options, first.min(top), top);
        let drift = self.drift_index();
        let mut out = vec![Dispatch {
            kind: PassKind::Drift,
            level: n - 1,
            params: PassParams {
                drift,
                ..self.pass_params(analysis, n - 1)
            },
        }];
        let coarsest = first.min(top);
        for level in coarsest..=top {
            let base = self.pass_params(analysis, level);
            // With `keep_look` the levels below the coarsest advected one are remade
            // wherever they moved other than rigidly (see `AdvectOptions::keep_look`).
            let c = if options.keep_look && level > coarsest {
                crate::passes::advect::KEEP_LOOK_REMAKE_THRESHOLD
            } else {
                c
            };
            let adv = PassParams {
                flag_base: self.flag_base(),
                distortion_max: crate::passes::advect::distortion_max(c, base.spacing),
                drift,
                ..base
            };
            out.push(Dispatch {
                kind: PassKind::Advect,
                level,
                params: PassParams {
                    dither: crate::passes::advect::dither(frame),
                    ..adv
                },
            });
            // The advected coordinates wait in the scratch region; the distortion pass
            // writes them back, and the flagged ones upsampled again from the coarser
            // level (on the coarsest level, which has nothing to upsample from, none is
            // flagged; on the coarsest advected level, with anchored renewals, mostly
            // continued from an anchor instead). One pass rather than a separate
            // upsampling of the flagged pixels, which read every pixel's flag.
            out.push(Dispatch {
                kind: PassKind::Distortion,
                level,
                params: if level > 0 {
                    PassParams {
                        anchor: if level == coarsest {
                            options.anchor_param()
                        } else {
                            0
                        },
                        ..adv
                    }
                } else {
                    PassParams {
                        distortion_max: u32::MAX,
                        ..adv
                    }
                },
            });
            // The level's fills and corrections, as in synthesis (no jitter: the
            // advected pixels keep their place, the re-upsampled ones are rare). With one
            // pass: the most corrected level runs all its subpasses when the finest is
            // upsampled, else half of them (every pixel is corrected every other frame);
            // every other frame one of a coarser level's four runs (every pixel every
            // eighth frame; the two coarser levels take turns, so every frame costs about
            // the same). A quarter of the coarser levels' subpasses per frame looked as
            // good as half, for less time.
            let passes = if level == coarsest && level < top {
                self.advect_coarsest_passes(options)
            } else {
                passes
            };
            // Subpasses per pass: the parity classes (4, more on a periodic level of odd
            // size; a level without similarity sets of its own may run fewer passes).
            let mut classes: Vec<[i32; 2]> = full
                .iter()
                .filter(|d| d.level == level && d.kind == PassKind::CorrectAniso)
                .map(|d| d.params.parity)
                .collect();
            classes.sort_unstable();
            classes.dedup();
            let per_pass = (classes.len() as u64).max(1);
            let mut subpass = 0u64;
            let mut keep_fill = true;
            for d in full.iter().filter(|d| d.level == level) {
                match d.kind {
                    PassKind::CorrectAniso => {
                        let most = level == top;
                        keep_fill = passes > 1
                            || options.keep_look
                            || (most && upsample_finest)
                            || if most {
                                subpass % 2 == (frame + level as u64) % 2
                            } else {
                                (2 * subpass) % 8 == (frame + level as u64) % 8
                            };
                        if keep_fill {
                            let mut d = *d;
                            d.params.kset_interp = options.interpolate_sets as u32;
                            d.params.quarter = options.quarter_reads as u32;
                            // Remade pixels inside a coherent block of the coarser
                            // level's upsampling would be skipped uncorrected.
                            d.params.coherent_skip =
                                (options.skip_coherent && !options.keep_look) as u32;
                            // With one pass, the most corrected level's similarity sets
                            // follow the frames' `sets_every` over the frames (with
                            // more, the passes do), at the same cost every frame when
                            // `sets_every` divides the subpasses per frame. All
                            // four subpasses per frame: subpass s scores them on frames
                            // with (frame + s) a multiple of `sets_every`. Two: of a
                            // frame's two one scores them, and the two swap every other
                            // frame. Each pixel has them at every `sets_every`-th
                            // correction. With `keep_look` every advected level runs its
                            // four per frame and follows the same rule.
                            // With more passes per frame (a keep-look level's
                            // `coarsest_passes`), the same over the level's corrections:
                            // class c's correction in pass p of frame f is its
                            // (f * passes + p)-th.
                            let every = frame_plan.params.sets_every as u64;
                            let sets = if upsample_finest {
                                let (pass, class) = (subpass / per_pass, subpass % per_pass);
                                (frame * passes as u64 + pass + class).is_multiple_of(every)
                            } else {
                                (subpass / 2 + frame / 2).is_multiple_of(every)
                            };
                            if (passes == 1 && most) || options.keep_look {
                                d.params.k = if sets { base.k } else { 1 };
                            }
                            out.push(d);
                        }
                        subpass += 1;
                    }
                    PassKind::Fill if keep_fill => out.push(*d),
                    _ => {}
                }
            }
        }
        out.extend(resynthesized_levels(&full, top, resynth, drift));
        if upsample_finest {
            // The upsampling follows the drift's phase (see `upsample_aniso.rs`), so that
            // a uniform flow of whole pixels moves the finest level's patch seams too.
            out.extend(
                finest_without_corrections(&full, n - 1)
                    .into_iter()
                    .map(|mut d| {
                        if d.kind == PassKind::UpsampleAniso {
                            d.params.drift = drift;
                        }
                        d
                    }),
            );
        }
        if let Some(g) = full.last() {
            let g = Dispatch {
                params: PassParams {
                    nearest: nearest as u32,
                    ..g.params
                },
                ..*g
            };
            if options.fade > 0 {
                out.push(self.fade_dispatch(analysis, &g, options, frame, false));
            } else {
                out.push(g);
            }
        }
        out
    }

    /// The first frame of an advection: the whole synthesis, with the gather every
    /// later frame uses (`options.nearest`: the nearest exemplar texel, else bilinear).
    /// With `options.upsample_finest` (see [`Self::advect_schedule`]) the finest level
    /// is left uncorrected and the re-synthesized levels below it
    /// ([`AdvectOptions::resynthesize`]) are made as the later frames
    /// make them (no jitter, the frames' passes), so that frame 1 does not change the
    /// texture's look; so are, with [`AdvectOptions::keep_look`], the
    /// advected levels below the coarsest one, which its frames remake under a turning
    /// flow.
    pub fn advect_first_schedule(
        &self,
        analysis: &Analysis,
        options: &AdvectOptions,
    ) -> Vec<Dispatch> {
        // Full subpasses: the flow carries the margins into view. No pixel skipped and
        // no stamp written (see `schedule_inner`): the frames keep their own data after
        // the coordinates (`flag_base`).
        let synthesis = self.schedule_inner(analysis, false, false);
        let mut s = synthesis.clone();
        let n = self.levels.len();
        if options.upsample_finest && n >= 2 {
            let resynth = options.resynthesize.min(n - 2);
            let top = n - 2 - resynth;
            let gather = s.pop();
            // The levels the frames remake every frame are made as the frames make them
            // (upsampled, corrected with the frames' passes, no jitter), so that frame 1
            // does not change the look: the re-synthesized levels below `top`, or with
            // `keep_look` the advected levels below the coarsest one (a turning flow
            // remakes them every frame).
            let coarsest = n - options.levels.clamp(1, n);
            let (kept, remade) = if options.keep_look && resynth == 0 && coarsest < top {
                (coarsest, top - coarsest)
            } else {
                (top, resynth)
            };
            s.retain(|d| d.level <= kept);
            if remade > 0 {
                let full = self.frame_synthesis(analysis, options, coarsest, top);
                s.extend(resynthesized_levels(&full, kept, remade, 0));
            }
            s.extend(finest_without_corrections(&synthesis, n - 1));
            s.extend(gather);
        }
        if let Some(g) = s.last_mut() {
            g.params.nearest = options.nearest as u32;
            if options.fade > 0 {
                *g = self.fade_dispatch(analysis, g, options, 0, true);
            }
        }
        s
    }

    /// The dispatches that make the levels above the advected ones (which the frames
    /// only read: renewed pixels are upsampled from them) again, as frame 0 made them
    /// ([`Self::advect_first_schedule`]); none where every level is advected.
    /// [`crate::gpu::advect::Advection`] runs them before the frame after a change of
    /// parameters (a new seed or randomness acts nowhere else: the frames do not jitter)
    /// or of analysis.
    pub fn advect_static_schedule(
        &self,
        analysis: &Analysis,
        options: &AdvectOptions,
    ) -> Vec<Dispatch> {
        let n = self.levels.len();
        let coarsest = n - options.levels.clamp(1, n);
        let mut s = self.schedule_inner(analysis, false, false);
        s.retain(|d| d.level < coarsest);
        s
    }
}
