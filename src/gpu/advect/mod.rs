//! Texture advection frame by frame, driven by a host application (Lefebvre & Hoppe
//! 2006, section 7).
//!
//! [`Advection::new`] synthesizes the first frame and keeps its coordinate pyramid on
//! the GPU; every [`Advection::step`] (host velocities) or [`Advection::encode_step`]
//! (a velocity buffer the caller owns, recorded into the caller's encoder) runs one
//! frame of [`SynthPlan::advect_schedule`] and leaves the new colours in
//! [`Advection::texture`]. Nothing comes back to the host unless asked for.
//!
//! Velocities are in output pixels (atlas texels for surfaces) per unit time; a frame
//! moves the texture by `velocity * dt`. Host velocities must be finite; speeds above
//! [`MAX_SPEED`](crate::passes::advect::MAX_SPEED) pixels per frame are clamped per
//! component (documented limit of the fixed-point arithmetic). The GPU path cannot
//! report errors per pixel: there, non-finite velocities count as 0.

mod velocity;

use std::sync::Arc;

use super::shaders;
use super::synth::{read_buffer, wait, GpuSynthesis, GpuSynthesizer};
use crate::error::{Error, Result};
use crate::field::Field;
pub use crate::passes::advect::AdvectOptions;
use crate::passes::plan::{Dispatch, PassKind, SynthPlan};
use crate::passes::SynthParams;
use velocity::quantize_pipeline;

/// The advected texture of one window (or atlas) and its state on the GPU.
pub struct Advection {
    synthesizer: Arc<GpuSynthesizer>,
    params: SynthParams,
    plan: SynthPlan,
    options: AdvectOptions,
    coords: wgpu::Buffer,
    velocity: wgpu::Buffer,
    output: GpuSynthesis,
    view: wgpu::TextureView,
    quantize: wgpu::ComputePipeline,
    quantize_layout: wgpu::BindGroupLayout,
    /// The pipeline quantizing a caller's velocity texture, built on first use
    /// ([`Self::encode_step_texture`]).
    texture_quantize: Option<(wgpu::ComputePipeline, wgpu::BindGroupLayout)>,
    frame: u64,
    /// Whether the coordinate buffer holds the fade state the next frame reads (the
    /// previous frame faded).
    fade_state: bool,
    /// The coordinate buffer before [`Self::set_options`] enlarged it, whose contents the
    /// next frame (or read) copies into `coords` first: in the frame's own encoder, so
    /// that a frame recorded by [`Self::encode_step`] but not yet submitted is not lost.
    grow_from: Option<wgpu::Buffer>,
    /// Whether the next frame first makes the levels above the advected ones again
    /// ([`SynthPlan::advect_static_schedule`]): the parameters or the analysis changed.
    remake_static: bool,
}

/// Frames whose schedules [`Advection::new`] and [`Advection::set_options`] build the
/// pipelines of: the subpasses and the similarity sets rotate with periods of 2, 4 and
/// `sets_every` (at most 16) frames.
const PREPARED_FRAMES: u64 = 16;

impl Advection {
    /// Synthesizes frame 0 of `params` (an isometric plan is run with the identity
    /// field: advection needs continuous coordinates).
    pub fn new(
        synthesizer: Arc<GpuSynthesizer>,
        params: &SynthParams,
        options: AdvectOptions,
    ) -> Result<Self> {
        let ctx = &synthesizer.context.clone();
        crate::gpu::synth::check_device_limits(&ctx.limits())?;
        let params = Self::synthesis_params(params);
        options.check()?;
        let plan = SynthPlan::with_torus(synthesizer.analysis(), &params, false)?;
        options.check_for_pyramid(plan.levels.len())?;
        // The synthesis of frame 0 has the same limits (texture sides, buffers).
        synthesizer.check_output(&plan)?;
        let n_coords = plan.advect_buffer_len(options.fade > 0);
        let pixels = params.width as u64 * params.height as u64;
        let max = ctx.limits().max_storage_buffer_binding_size;
        if n_coords * 8 > max {
            return Err(Error::TooLarge {
                what: "advected output",
                width: params.width,
                height: params.height,
                limit: format!("its coordinate pyramid needs {} MiB", (n_coords * 8) >> 20),
                hint: "advect a smaller window",
            });
        }
        let (coords, velocity, output, quantize, quantize_layout) = ctx.scoped(|| {
            let coords = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("texsyn advected coords"),
                size: n_coords * 8,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let velocity = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("texsyn velocity"),
                size: (pixels * 8).max(16),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let texture = synthesizer.output_texture(params.width, params.height);
            // The quarter-pixel tables the frames read, if any (the most corrected
            // level's, with the projected distance), built now rather than in frame 1.
            let analysis = synthesizer.analysis();
            let frame = plan.advect_schedule(analysis, &options, 1);
            if let Some(level) = crate::passes::plan::quarter_tables_level(&frame, analysis) {
                synthesizer.fine_tables(level);
            }
            let (quantize, quantize_layout) = quantize_pipeline(
                ctx,
                wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Storage { read_only: true },
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                shaders::VELOCITY,
            );
            (
                coords,
                velocity,
                GpuSynthesis {
                    texture,
                    width: params.width,
                    height: params.height,
                },
                quantize,
                quantize_layout,
            )
        })?;
        let view = output.texture.create_view(&Default::default());
        let this = Self {
            synthesizer,
            params,
            plan,
            options,
            coords,
            velocity,
            output,
            view,
            quantize,
            quantize_layout,
            texture_quantize: None,
            frame: 0,
            fade_state: options.fade > 0,
            grow_from: None,
            remake_static: false,
        };
        let schedule = this
            .plan
            .advect_first_schedule(this.synthesizer.analysis(), &this.options);
        Self::prepare_frames(&this.synthesizer, &this.plan, &this.options, &schedule)?;
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        this.record(&mut encoder, &schedule, true)?;
        ctx.scoped(|| ctx.queue.submit([encoder.finish()]))?;
        Ok(this)
    }

    /// The parameters frame 0 is synthesized with (and every frame's plan is made
    /// from): `params` made anisometric (the identity field where it has none), without
    /// seam blending, with at least one correction pass on the finest level and with
    /// the full margins (not [`SynthParams::standalone`]).
    pub fn synthesis_params(params: &SynthParams) -> SynthParams {
        let mut p = params.clone();
        // Advected coordinates have several times the seams of a synthesis; blending
        // their colours blurs the texture.
        p.seam_blend = false;
        // The plan keeps a corrected finest level: with `AdvectOptions::upsample_finest =
        // false` every frame corrects it, and frame 0 does too (synthesis leaves it
        // uncorrected by default, which pays only with seam blending: without it, the
        // correction lowers frame 0's energy); either
        // way its region keeps the margin of a corrected level, which the flow carries
        // into view. With the finest level upsampled (the default), frame 0 and the
        // frames leave out its corrections (`SynthPlan::advect_first_schedule`).
        p.finest_passes = p.finest_passes.max(1);
        // The advected levels keep every level's passes: no smaller default at the
        // second-finest level (see passes::plan::SMALL_SECOND_FINEST_PASSES).
        p.second_finest_passes.get_or_insert(p.passes);
        p.standalone = false;
        if !p.anisometric() {
            p.field = Some(Field::identity());
        }
        p
    }

    fn record(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        schedule: &[Dispatch],
        clear: bool,
    ) -> Result<()> {
        let ctx = &self.synthesizer.context;
        ctx.scoped(|| {
            self.synthesizer.record_with(
                encoder,
                &self.plan,
                schedule,
                &self.view,
                clear,
                &[],
                Some((&self.coords, &self.velocity)),
            );
        })
    }

    /// Frames advected so far.
    pub fn frame(&self) -> u64 {
        self.frame
    }

    /// The synthesis parameters in force ([`Self::synthesis_params`] of the last given).
    pub fn params(&self) -> &SynthParams {
        &self.params
    }

    /// The plan every frame runs on (regions and levels of the coordinate pyramid).
    pub fn plan(&self) -> &SynthPlan {
        &self.plan
    }

    /// The advection options in force ([`Self::set_options`] changes them).
    pub fn options(&self) -> AdvectOptions {
        self.options
    }

    /// The current colours (`Rgba8Unorm` holding sRGB-encoded bytes; storage, texture
    /// binding, copy source). [`Self::srgb_view`] samples them as linear colours.
    pub fn texture(&self) -> &wgpu::Texture {
        &self.output.texture
    }

    /// An sRGB view of [`Self::texture`] for sampling (see
    /// [`GpuSynthesis::srgb_view`]); `None` on the GL backend.
    pub fn srgb_view(&self) -> Option<wgpu::TextureView> {
        let ctx = &self.synthesizer.context;
        self.output.srgb_view(ctx)
    }

    /// Changes synthesis parameters between frames (randomness, coherence, distance,
    /// field, seed): the size, window and atlas must stay the same, and so
    /// must the regions each level computes, which the correction passes' margins set
    /// (a change of `passes`, `second_finest_passes` or `finest_passes` that moves them
    /// is refused).
    ///
    /// Coherence, distance and field act on the next frame's corrections (a field also
    /// on its distortion test). The frames do not jitter, so a new seed or randomness
    /// acts through the levels above the advected ones: any change of parameters makes
    /// them again, as frame 0 made them, before the next frame, and the advected levels
    /// take the new content where they are renewed (upsampled from them: under a turning
    /// flow with [`AdvectOptions::keep_look`] within some ten frames; where a uniform flow
    /// brings texture into view; nowhere when every level is advected).
    pub fn set_params(&mut self, params: &SynthParams) -> Result<()> {
        let params = Self::synthesis_params(params);
        let plan = SynthPlan::with_torus(self.synthesizer.analysis(), &params, false)?;
        if !self.same_regions(&plan) || params.surface.is_some() != self.params.surface.is_some() {
            return Err(Error::InvalidParameter(
                "advection parameters may change between frames, but not the output size, \
                 window or atlas, nor the number of correction passes where it changes the \
                 levels' margins: start a new advection for those"
                    .into(),
            ));
        }
        if params != self.params {
            self.remake_static = true;
        }
        self.params = params;
        self.plan = plan;
        Ok(())
    }

    /// Continues the advection with another analysis of an exemplar of the same size,
    /// pyramid and wrapping, on the same context: e.g. the same exemplar analysed with
    /// another feature weight or mask (`AnalysisOptions::feature_weight`), another
    /// appearance space, or another exemplar altogether. The coordinates carry over (they
    /// are exemplar positions), and the next frames correct them against the new
    /// appearance, and the levels above the advected ones are made again against it
    /// first (as [`Self::set_params`] makes them); the size, window or atlas and the
    /// levels' regions stay (refused otherwise, as in [`Self::set_params`]). The analysis is the slow part (build it
    /// ahead, e.g. one per weight a host wants to blend through); the swap itself only
    /// checks and, where the frames read them, builds the new analysis's quarter-pixel
    /// tables, and the pipelines of its frames that are not built yet.
    pub fn set_synthesizer(&mut self, synthesizer: Arc<GpuSynthesizer>) -> Result<()> {
        let ctx = &self.synthesizer.context;
        // Both on this advection's context (its buffers live there).
        synthesizer.check_context(ctx)?;
        let (old, new) = (self.synthesizer.analysis(), synthesizer.analysis());
        let wrapping = |t: bool| if t { "tileable" } else { "not tileable" };
        if (new.width, new.height, new.levels.len(), new.tileable)
            != (old.width, old.height, old.levels.len(), old.tileable)
        {
            return Err(Error::InvalidParameter(format!(
                "the advection's coordinates are positions in a {}x{} exemplar of {} levels \
                 ({}); the new analysis is of a {}x{} exemplar of {} levels ({}): swap in an \
                 analysis of an exemplar of the same size and wrapping, or start a new \
                 advection",
                old.width,
                old.height,
                old.levels.len(),
                wrapping(old.tileable),
                new.width,
                new.height,
                new.levels.len(),
                wrapping(new.tileable),
            )));
        }
        let plan = SynthPlan::with_torus(new, &self.params, false)?;
        if !self.same_regions(&plan) {
            return Err(Error::InvalidParameter(
                "the new analysis changes the levels' margins (its correction passes per \
                 level differ: a feature channel against none, with more than 2 passes): \
                 analyse both with the mask (a feature weight of 0 stands for none), or \
                 start a new advection"
                    .into(),
            ));
        }
        self.options.check_for_pyramid(plan.levels.len())?;
        synthesizer.check_output(&plan)?;
        ctx.scoped(|| {
            let frame = plan.advect_schedule(new, &self.options, self.frame);
            if let Some(level) = crate::passes::plan::quarter_tables_level(&frame, new) {
                synthesizer.fine_tables(level);
            }
        })?;
        Self::prepare_frames(&synthesizer, &plan, &self.options, &[])?;
        if !Arc::ptr_eq(&self.synthesizer, &synthesizer) {
            self.remake_static = true;
        }
        self.synthesizer = synthesizer;
        self.plan = plan;
        Ok(())
    }

    /// The synthesizer (exemplar analysis) the frames correct against.
    pub fn synthesizer(&self) -> &Arc<GpuSynthesizer> {
        &self.synthesizer
    }

    /// Changes the options between frames. Turning fading on ([`AdvectOptions::fade`])
    /// on an advection made without it enlarges its coordinate buffer (refused where the
    /// device cannot bind the larger one; the contents are copied in the next frame's
    /// encoder, so this may come between [`Self::encode_step`] and the submission of its
    /// encoder); the next frame then starts every pixel unfaded, as it does when fades
    /// of one frame become longer (one-frame fades keep no ghosts).
    pub fn set_options(&mut self, options: AdvectOptions) -> Result<()> {
        let ctx = &self.synthesizer.context;
        options.check_for_pyramid(self.plan.levels.len())?;
        // Before anything changes: an error leaves the advection as it was.
        Self::prepare_frames(&self.synthesizer, &self.plan, &options, &[])?;
        let need = self.plan.advect_buffer_len(options.fade > 0) * 8;
        if need > self.coords.size() {
            let max = ctx.limits().max_storage_buffer_binding_size;
            if need > max {
                return Err(Error::TooLarge {
                    what: "advected output with fading",
                    width: self.params.width,
                    height: self.params.height,
                    limit: format!("its coordinates and fade state need {} MiB", need >> 20),
                    hint: "advect a smaller window, or without fading",
                });
            }
            let grown = ctx.scoped(|| {
                ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("texsyn advected coords"),
                    size: need,
                    usage: self.coords.usage(),
                    mapped_at_creation: false,
                })
            })?;
            // The copy waits for the next frame's encoder (see `grow_from`); a buffer
            // enlarged twice before it is copied from the first.
            let old = std::mem::replace(&mut self.coords, grown);
            self.grow_from.get_or_insert(old);
        }
        // One-frame fades keep the coordinates alone (`passes::fade`): a longer fade
        // after them starts every pixel unfaded.
        if self.options.fade <= 1 && options.fade > 1 {
            self.fade_state = false;
        }
        self.options = options;
        Ok(())
    }

    /// Builds the pipelines the frames with `options` dispatch (and those of `extra`)
    /// now, so that the first frames do not stall on them (a host application's frame
    /// loop would drop frames). The
    /// subpasses rotate over the frames, whose schedules repeat within
    /// [`PREPARED_FRAMES`].
    fn prepare_frames(
        synthesizer: &GpuSynthesizer,
        plan: &SynthPlan,
        options: &AdvectOptions,
        extra: &[Dispatch],
    ) -> Result<()> {
        let analysis = synthesizer.analysis();
        // Each frame is a submission of its own (a frame after a change of parameters
        // prepends the static levels' schedule).
        let static_levels = plan.advect_static_schedule(analysis, options);
        let mut schedules = vec![extra.to_vec()];
        for frame in 1..=PREPARED_FRAMES {
            let frame = plan.advect_schedule(analysis, options, frame);
            schedules.push([static_levels.as_slice(), &frame].concat());
            schedules.push(frame);
        }
        synthesizer.prepare_schedules(plan, &schedules)
    }

    /// Whether `plan` computes the same regions at every level as the current one (the
    /// coordinate buffer's layout, which frames carry over).
    fn same_regions(&self, plan: &SynthPlan) -> bool {
        plan.levels.len() == self.plan.levels.len()
            && plan
                .levels
                .iter()
                .zip(&self.plan.levels)
                .all(|(a, b)| a.origin == b.origin && a.size == b.size)
    }

    /// The dispatches of the next frame ([`SynthPlan::advect_schedule`] for the current
    /// frame and options, after [`SynthPlan::advect_static_schedule`] where the
    /// parameters or the analysis changed since the last frame; a fade that has no state
    /// yet starts every pixel unfaded), as the CPU mirror
    /// ([`crate::passes::run_cpu_frame`]) runs them.
    pub fn frame_schedule(&self) -> Vec<Dispatch> {
        let analysis = self.synthesizer.analysis();
        let mut schedule = if self.remake_static {
            self.plan.advect_static_schedule(analysis, &self.options)
        } else {
            Vec::new()
        };
        schedule.extend(
            self.plan
                .advect_schedule(analysis, &self.options, self.frame),
        );
        if !self.fade_state {
            // No fade state yet (fading just turned on): every pixel starts unfaded.
            for d in schedule.iter_mut().filter(|d| d.kind == PassKind::Fade) {
                d.params.fade_src = 0;
            }
        }
        schedule
    }

    /// After a frame: whether the next one finds fade state.
    fn frame_done(&mut self) {
        self.frame += 1;
        self.fade_state = self.options.fade > 0;
        self.remake_static = false;
    }

    /// [`Self::step`] for profiling: each dispatch of the frame is submitted and waited
    /// for on its own, and its time returned with its pass kind and level (the velocity
    /// upload is not counted). The frame's result is the same; the sum is larger than a
    /// frame's time, since nothing overlaps.
    pub fn profile_step(
        &mut self,
        velocity: &[[f32; 2]],
        dt: f32,
    ) -> Result<Vec<(PassKind, usize, std::time::Duration)>> {
        // A handle of its own: the frame below borrows `self` mutably.
        let synthesizer = Arc::clone(&self.synthesizer);
        let ctx = &synthesizer.context;
        self.upload_velocity(velocity, dt)?;
        if self.grow_from.is_some() {
            let mut encoder = ctx.device.create_command_encoder(&Default::default());
            self.record_grow(&mut encoder)?;
            ctx.scoped(|| ctx.queue.submit([encoder.finish()]))?;
        }
        wait(ctx)?;
        let schedule = self.frame_schedule();
        let mut out = Vec::with_capacity(schedule.len());
        for d in &schedule {
            let mut encoder = ctx.device.create_command_encoder(&Default::default());
            self.record(&mut encoder, std::slice::from_ref(d), false)?;
            let buffer = encoder.finish();
            let t = std::time::Instant::now();
            ctx.scoped(|| ctx.queue.submit([buffer]))?;
            wait(ctx)?;
            out.push((d.kind, d.level, t.elapsed()));
        }
        self.frame_done();
        Ok(out)
    }

    /// Records the pending copy into an enlarged coordinate buffer (see `grow_from`).
    fn record_grow(&mut self, encoder: &mut wgpu::CommandEncoder) -> Result<()> {
        let ctx = &self.synthesizer.context;
        if let Some(old) = self.grow_from.take() {
            ctx.scoped(|| encoder.copy_buffer_to_buffer(&old, 0, &self.coords, 0, old.size()))?;
        }
        Ok(())
    }

    fn record_frame(&mut self, encoder: &mut wgpu::CommandEncoder) -> Result<()> {
        self.record_grow(encoder)?;
        let schedule = self.frame_schedule();
        self.record(encoder, &schedule, false)?;
        self.frame_done();
        Ok(())
    }

    /// Waits for the GPU and reads the current colours (RGBA8 rows).
    /// After [`Self::encode_step`], only once its encoder is submitted (before, this
    /// reads the previous frame). `ctx` must be the one the advection was made with (or
    /// a clone); another is an error.
    pub fn read_rgba8(&self) -> Result<Vec<u8>> {
        let ctx = &self.synthesizer.context;
        self.output.read_rgba8(ctx)
    }

    /// Waits for the GPU and reads the whole coordinate buffer (every level, then the
    /// flag region), to compare with the CPU mirror.
    pub fn read_coords(&self) -> Result<Vec<[i32; 2]>> {
        let ctx = &self.synthesizer.context;
        let bytes = self.coords.size();
        let rb = ctx.scoped(|| {
            let rb = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("texsyn advected coords readback"),
                size: bytes,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let mut encoder = ctx.device.create_command_encoder(&Default::default());
            // Enlarged since the last frame: the contents are still in the old buffer
            // (the new one's fade state is zeros, as after the copy).
            let (source, size) = match &self.grow_from {
                Some(old) => (old, old.size()),
                None => (&self.coords, bytes),
            };
            encoder.copy_buffer_to_buffer(source, 0, &rb, 0, size);
            ctx.queue.submit([encoder.finish()]);
            rb
        })?;
        wait(ctx)?;
        let data = read_buffer(ctx, &rb)?;
        Ok(bytemuck::cast_slice(&data).to_vec())
    }
}
