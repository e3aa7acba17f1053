//! The frames of an advection session: each step's velocities (sampled in 2D, projected
//! into the atlas on a mesh), the step, the read-back, the temporal figures, and the
//! interleaved whole syntheses that the costs are compared with.

use std::sync::Arc;
use std::time::{Duration, Instant};

use super::report::{AdvectCosts, AdvectNote, AdvectSummary};
use crate::error::{Error, Result};
use crate::flow::{displacement, Flow};
use crate::gpu::advect::{AdvectOptions, Advection};
use crate::gpu::synth::GpuSynthesizer;
use crate::gpu::GpuContext;
use crate::passes::PassKind;
use crate::quality::{FloatImage, TemporalFigures};
use crate::surface::pipeline::PreparedSurface;
use crate::SynthParams;

/// One whole synthesis of the output every this many frames, to compare a frame's cost
/// with: interleaved with the frames, so that both medians see the same machine (a
/// shared CPU's speed drifts between minutes).
const FULL_EVERY: u32 = 8;
/// The least number of timed whole syntheses behind the comparison.
const FULL_RUNS: usize = 5;

/// One frame of an advection: the texture (the 2D output, or the mesh's atlas).
#[derive(Clone, Debug)]
pub struct AdvectFrame {
    /// 0 for the synthesized start, then 1, 2, ...
    pub index: u32,
    /// Width in pixels (the atlas side on a mesh).
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// RGBA8 pixels, row-major.
    pub rgba: Vec<u8>,
    /// The step's GPU time, synchronized (`None` for frame 0).
    pub step_time: Option<Duration>,
}

/// Whole syntheses timed for comparison: the default synthesis (what a host would run
/// to make each frame from scratch) and one with the settings of the advection's frame
/// 0 (anisometric, the finest level corrected, no seam blending), whose pyramid a frame
/// updates in part.
pub(super) struct SynthesisTimer {
    pub params: SynthParams,
    pub frame0_params: SynthParams,
    pub size_hint: &'static str,
    pub runs: Vec<(Duration, Duration)>,
}

impl SynthesisTimer {
    /// A warm-up (it builds the pipelines), then the first timed run.
    pub fn start(&mut self, synthesizer: &GpuSynthesizer) -> Result<()> {
        self.time(synthesizer)?;
        self.runs.clear();
        self.time(synthesizer)
    }

    fn time(&mut self, synthesizer: &GpuSynthesizer) -> Result<()> {
        let once = |p: &SynthParams| -> Result<Duration> {
            let t = Instant::now();
            synthesizer
                .synthesize(p)
                .map_err(|e| with_hint(e, self.size_hint))?;
            Ok(t.elapsed())
        };
        let run = (once(&self.params)?, once(&self.frame0_params)?);
        self.runs.push(run);
        Ok(())
    }
}

/// A texture advecting along a flow; made by
/// [`AdvectSession::builder`](super::AdvectSession::builder). Pull the frames with
/// [`Self::next_frame`] (or iterate), then [`Self::finish`] for the summary.
pub struct AdvectSession {
    pub(super) ctx: GpuContext,
    pub(super) advection: Advection,
    pub(super) synthesizer: Arc<GpuSynthesizer>,
    pub(super) surface: Option<PreparedSurface>,
    pub(super) flow: Flow,
    pub(super) dt: f32,
    pub(super) params: SynthParams,
    pub(super) options: AdvectOptions,
    pub(super) grey: bool,
    pub(super) frames: Option<u32>,
    pub(super) next: u32,
    pub(super) figures: Option<TemporalFigures>,
    pub(super) timer: Option<SynthesisTimer>,
    pub(super) costs: Vec<Duration>,
    pub(super) passes: Option<Vec<Vec<(PassKind, usize, Duration)>>>,
    pub(super) notes: Vec<AdvectNote>,
    pub(super) constant_jacobian: bool,
}

impl AdvectSession {
    /// The next frame (frame 0 first), or `None` after the frames asked for. Steps the
    /// advection with the flow at the frame's time, waits for the GPU, reads the frame
    /// back and adds it to the temporal figures.
    pub fn next_frame(&mut self) -> Result<Option<AdvectFrame>> {
        let t = self.next;
        if self.frames.is_some_and(|n| t > n) {
            return Ok(None);
        }
        let (w, h) = (self.params.width, self.params.height);
        let mut moved = Vec::new();
        let mut step_time = None;
        if t > 0 {
            let v = match &self.surface {
                Some(prep) => crate::surface::flow::atlas_velocity(prep, &self.flow, t as f32)?,
                None => self.flow.sample(w, h, t as f32)?,
            };
            let start = Instant::now();
            let profile = if self.passes.is_some() {
                Some(self.advection.profile_step(&v, self.dt)?)
            } else {
                self.advection.step(&v, self.dt)?;
                None
            };
            self.ctx.wait_idle()?;
            let elapsed = start.elapsed();
            self.costs.push(elapsed);
            step_time = Some(elapsed);
            if let (Some(passes), Some(p)) = (&mut self.passes, profile) {
                passes.push(p);
            }
            moved = displacement(&v, self.dt);
        }
        let rgba = self.advection.read_rgba8()?;
        if let Some(figures) = &mut self.figures {
            figures.push(
                to_float(self.grey, w, h, bytemuck::cast_slice(&rgba))?,
                &moved,
            )?;
        }
        if t > 0 && t.is_multiple_of(FULL_EVERY) {
            if let Some(timer) = &mut self.timer {
                timer.time(&self.synthesizer)?;
            }
        }
        self.next = t + 1;
        Ok(Some(AdvectFrame {
            index: t,
            width: w,
            height: h,
            rgba,
            step_time,
        }))
    }

    /// A frame as an image to look at: on a mesh, two views of the mesh textured with it
    /// ([`Self::preview_size`]); in 2D, the frame itself.
    pub fn preview(&self, frame: AdvectFrame) -> Result<image::RgbaImage> {
        use crate::surface::render;
        match &self.surface {
            Some(prep) => render::render_views(
                &self.ctx,
                &prep.atlas.mesh,
                &render::SurfaceTexture::Color {
                    rgba: &frame.rgba,
                    width: frame.width,
                    height: frame.height,
                },
                &render::RenderOptions {
                    views: 2,
                    view_size: 256,
                    ..Default::default()
                },
            ),
            None => image::RgbaImage::from_raw(frame.width, frame.height, frame.rgba)
                .ok_or_else(|| Error::InvalidParameter("internal: size".into())),
        }
    }

    /// The size of [`Self::preview`]'s images: two 256-pixel views side by side on a
    /// mesh, the output's size in 2D.
    pub fn preview_size(&self) -> [u32; 2] {
        match self.surface {
            Some(_) => [2 * 256, 256],
            None => [self.params.width, self.params.height],
        }
    }

    /// The frames' size: the 2D output's, or the atlas's on a mesh.
    pub fn size(&self) -> [u32; 2] {
        [self.params.width, self.params.height]
    }

    /// The options the frames run with (the scheme chosen).
    pub fn options(&self) -> AdvectOptions {
        self.options
    }

    /// What the session noted while it was set up (also given to
    /// [`AdvectSessionBuilder::on_note`](super::AdvectSessionBuilder::on_note)).
    pub fn notes(&self) -> &[AdvectNote] {
        &self.notes
    }

    /// The advection itself (e.g. for its GPU texture), from frame 0 on.
    pub fn advection(&self) -> &Advection {
        &self.advection
    }

    /// The advection, to drive on from here (e.g. with velocities of the caller's own,
    /// [`Advection::encode_step`]); the figures and costs end here.
    pub fn into_advection(self) -> Advection {
        self.advection
    }

    /// The device the session runs on.
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// The costs and the temporal figures of the frames so far (the last frame pulled is
    /// the last of the figures). With [`AdvectSessionBuilder::compare_cost`], times the
    /// remaining whole syntheses first.
    ///
    /// [`AdvectSessionBuilder::compare_cost`]: super::AdvectSessionBuilder::compare_cost
    pub fn finish(mut self) -> Result<AdvectSummary> {
        let mut synthesis = None;
        if let Some(timer) = &mut self.timer {
            while timer.runs.len() < FULL_RUNS {
                timer.time(&self.synthesizer)?;
            }
            synthesis = Some((
                median(&mut timer.runs.iter().map(|r| r.0).collect::<Vec<_>>()),
                median(&mut timer.runs.iter().map(|r| r.1).collect::<Vec<_>>()),
            ));
        }
        // A turning flow breaks the texture's patches up over the first tens of frames,
        // and the correction then costs more: the later half of a long run shows the
        // lasting cost.
        let costs = &mut self.costs;
        let late = (costs.len() >= 16).then(|| {
            let n = costs.len() - costs.len() / 2;
            (n, median(&mut costs[costs.len() / 2..].to_vec()))
        });
        let figures = self.figures.take().expect("kept until finished").finish()?;
        Ok(AdvectSummary {
            costs: AdvectCosts {
                frame: median(costs),
                late,
                synthesis,
                passes: self.passes.take(),
            },
            figures,
            keep_look: self.options.keep_look,
            constant_jacobian: self.constant_jacobian,
            preview_size: self.preview_size(),
        })
    }
}

impl Iterator for AdvectSession {
    type Item = Result<AdvectFrame>;

    fn next(&mut self) -> Option<Self::Item> {
        self.next_frame().transpose()
    }
}

/// A frame as the temporal figures read it: grey where the exemplar is grey.
pub(super) fn to_float(grey: bool, w: u32, h: u32, rgba: &[[u8; 4]]) -> Result<FloatImage> {
    if grey {
        FloatImage::new(w, h, 1, rgba.iter().map(|p| p[0] as f32 / 255.0).collect())
    } else {
        FloatImage::from_rgba8(w, h, rgba)
    }
}

/// `e` with `hint` if it is the library's output-too-large error (the advection cannot
/// be made in windows).
pub(super) fn with_hint(e: Error, hint: &'static str) -> Error {
    match e {
        Error::TooLarge {
            what: "output",
            width,
            height,
            limit,
            ..
        } => Error::TooLarge {
            what: "output",
            width,
            height,
            limit,
            hint,
        },
        other => other,
    }
}

fn median(v: &mut [Duration]) -> Duration {
    v.sort();
    v.get(v.len() / 2).copied().unwrap_or_default()
}
