//! The high-level API: a builder that takes an exemplar (image, pixels or a saved
//! analysis), analyses it if needed, uploads it to a GPU (headless or the caller's
//! device) and synthesizes textures of any size, with their material maps and
//! coordinates, magnified if asked.
//!
//! ```no_run
//! let session = texsyn::Session::builder()
//!     .exemplar_path("assets/gravel.png")
//!     .seed(7)
//!     .size(512, 512)
//!     .build()?;
//! let texture = session.run()?;          // pixels on the host
//! texture.save("out.png")?;
//! let on_gpu = session.run_gpu()?;       // a wgpu::Texture, no read-back
//! # Ok::<(), texsyn::Error>(())
//! ```

use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::Duration;

mod analyze;
mod build;
mod builder;
mod run;
mod source;
mod texture;
pub use analyze::{analyze_image, AnalyzedImage};
pub use builder::{LevelCallback, SessionBuilder};
pub use run::{CopyGuardReport, RunTimings, SynthesisTiming, LONG_SYNTHESIS_PIXELS};
pub use source::{crop_rows, ExemplarSource, Magnified};
use texture::MagnifiedImage;
pub use texture::{check_image_path, check_image_size, MaterialMap, SynthesizedMap, Texture};
mod benchmark;
pub use benchmark::{
    AnalysisTiming, Benchmark, BenchmarkProgress, BenchmarkTable, PassRow, PassTable, SizeRow,
    Timing,
};
mod evaluation;
pub use evaluation::{
    EnergyMapImage, Evaluation, EvaluationNote, EvaluationReport, FrameFigures, ImageFigures,
};
mod advect;
pub use advect::{
    AdvectCosts, AdvectFrame, AdvectNote, AdvectScheme, AdvectSession, AdvectSessionBuilder,
    AdvectSummary, SchemeReason, DEFAULT_ATLAS_SIZE,
};
#[cfg(feature = "gltf")]
mod surface;
#[cfg(feature = "gltf")]
pub use surface::{
    SurfaceBuilder, SurfaceEvent, SurfaceMap, SurfaceSession, SurfaceTimings, TexturedSurface,
};

use crate::analysis::{self, Analysis, AnalysisOptions, Progress};
use crate::error::{Error, Result};
use crate::gpu::synth::{GpuSynthesis, GpuSynthesizer};
use crate::gpu::GpuContext;
use crate::passes::SynthParams;

/// What a session tells the caller while it builds ([`SessionBuilder::build_reporting`])
/// and runs ([`Session::run_reporting`]), in this order.
#[derive(Debug)]
#[non_exhaustive]
pub enum Event<'a> {
    /// A warning about the input, in words (e.g. an animated exemplar: its first frame
    /// is used).
    Warning(String),
    /// The device is ready.
    Device(&'a GpuContext),
    /// The analysis's progress.
    Analysis(Progress),
    /// The exemplar is analysed, or its analysis loaded (`from_file`).
    Exemplar {
        /// The analysis the session synthesizes from.
        analysis: &'a Analysis,
        /// Whether it was read from an analysis file.
        from_file: bool,
    },
    /// A note about the output, in words (e.g. how a tileable output of sides that are
    /// not multiples of 4 is made).
    Note(String),
    /// An output assembled from windows: `done` of `total` windows synthesized.
    Windows {
        /// Windows done.
        done: usize,
        /// Windows in all.
        total: usize,
        /// Time since the first window started.
        elapsed: Duration,
    },
}

/// How long the steps of [`SessionBuilder::build`] took.
#[derive(Clone, Copy, Debug, Default)]
pub struct BuildTimings {
    /// Reading the exemplar image or analysis file.
    pub read: Duration,
    /// The analysis (`None`: an analysis was given or read).
    pub analysis: Option<Duration>,
    /// Creating the device (alongside the read; zero for the caller's context).
    pub device: Duration,
    /// Uploading the tables.
    pub upload: Duration,
    /// Building the pipelines (alongside the upload).
    pub pipelines: Duration,
    /// The rest of the preparation (a field's Jacobians).
    pub prepare: Duration,
}

/// An analysed exemplar on a GPU, ready to synthesize.
pub struct Session {
    context: GpuContext,
    synthesizer: Arc<GpuSynthesizer>,
    params: SynthParams,
    copy_budget: f32,
    /// The full-resolution colours when magnifying.
    magnified: Option<Magnified>,
    /// The exemplar image's own size (before magnification's downsampling).
    exemplar_size: Option<(u32, u32)>,
    maps: Vec<MaterialMap>,
    coordinates: bool,
    levels: Option<Arc<Mutex<LevelCallback>>>,
    timings: BuildTimings,
}

impl Session {
    /// A builder: give it an exemplar (`exemplar_path`, `exemplar` or `analysis`), then
    /// options, then [`SessionBuilder::build`].
    ///
    /// ```no_run
    /// let session = texsyn::Session::builder()
    ///     .exemplar_path("assets/gravel.png")
    ///     .size(512, 512)
    ///     .build()?;
    /// # Ok::<(), texsyn::Error>(())
    /// ```
    pub fn builder() -> SessionBuilder {
        SessionBuilder::new()
    }

    /// Synthesizes with the session's parameters and reads the result back: the copy
    /// guard chooses the schedule ([`Self::schedule`]), then the output is synthesized
    /// in one piece or assembled from windows, magnified and with its material maps if
    /// the builder asked for them.
    ///
    /// ```no_run
    /// let session = texsyn::Session::builder()
    ///     .exemplar_path("assets/gravel.png")
    ///     .size(512, 512)
    ///     .build()?;
    /// session.run()?.save("gravel_512.png")?;
    /// # Ok::<(), texsyn::Error>(())
    /// ```
    pub fn run(&self) -> Result<Texture> {
        self.run_inner(&self.params, &mut |_| {})
    }

    /// Synthesizes with other parameters (size, window, seed, ...), same exemplar. The
    /// jitter schedule goes through the copy guard ([`Self::schedule`]).
    ///
    /// ```no_run
    /// # let session = texsyn::Session::builder().exemplar_path("a.png").build()?;
    /// let right = texsyn::SynthParams { origin: [256, 0], ..session.params().clone() };
    /// let neighbour = session.run_with(&right)?; // fits the run() output on its right
    /// # Ok::<(), texsyn::Error>(())
    /// ```
    pub fn run_with(&self, params: &SynthParams) -> Result<Texture> {
        self.run_inner(params, &mut |_| {})
    }

    /// How long the steps of building the session took.
    pub fn timings(&self) -> &BuildTimings {
        &self.timings
    }

    /// Synthesizes into a new GPU texture (`Rgba8Unorm`); only the copy guard's probe
    /// (if any, see [`Self::schedule`]) is read back.
    pub fn run_gpu(&self) -> Result<GpuSynthesis> {
        let params = self.schedule(&self.params)?;
        self.synthesizer.synthesize(&params)
    }

    /// `params` with the jitter schedule the copy guard chooses for them
    /// ([`GpuSynthesizer::choose_schedule`] with the session's budget): from 176 px, two
    /// or one more still levels where a probe synthesis copies at most that much of the
    /// exemplar. It synthesizes the probes and waits for them; the choice depends on the exemplar, the
    /// seed and the parameters but not on the window, so call it once and [`Self::encode`]
    /// with the result as often as needed.
    pub fn schedule(&self, params: &SynthParams) -> Result<SynthParams> {
        Ok(self
            .synthesizer
            .choose_schedule(params, self.copy_budget)?
            .params)
    }

    /// The copy guard's budget (see [`SessionBuilder::copy_budget`]).
    pub fn copy_budget(&self) -> f32 {
        self.copy_budget
    }

    /// Records a synthesis with `params` as they are into the caller's command encoder
    /// (for embedding in a frame; no copy guard: pass [`Self::schedule`]'s parameters for
    /// the same texture as [`Self::run_gpu`]); the texture is ready once the caller
    /// submits the encoder.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        params: &SynthParams,
    ) -> Result<GpuSynthesis> {
        self.synthesizer.encode(encoder, params)
    }

    /// Starts texture advection (frame 0 is synthesized with the session's parameters,
    /// made anisometric if they are not) on the session's device and exemplar; then call
    /// [`Advection::step`](crate::gpu::advect::Advection::step) or
    /// [`encode_step`](crate::gpu::advect::Advection::encode_step) once a frame.
    /// [`AdvectOptions::recommended`](crate::gpu::advect::AdvectOptions::recommended)
    /// with [`Self::params`] gives the options the CLI uses by default.
    pub fn advection(
        &self,
        options: crate::gpu::advect::AdvectOptions,
    ) -> Result<crate::gpu::advect::Advection> {
        crate::gpu::advect::Advection::new(Arc::clone(&self.synthesizer), &self.params, options)
    }

    /// The exemplar analysis the session synthesizes from.
    pub fn analysis(&self) -> &Analysis {
        self.synthesizer.analysis()
    }

    /// The GPU device and queue (the caller's, or a headless one).
    pub fn context(&self) -> &GpuContext {
        &self.context
    }

    /// The parameters [`Self::run`] and [`Self::run_gpu`] use.
    pub fn params(&self) -> &SynthParams {
        &self.params
    }

    /// The synthesizer (the analysis uploaded to the GPU), shared: clone the `Arc` to
    /// keep it beyond the session, e.g. for [`crate::gpu::advect::Advection::new`].
    pub fn synthesizer(&self) -> &Arc<GpuSynthesizer> {
        &self.synthesizer
    }
}

/// What to do with an output too large for one piece, in the API's terms.
const API_WINDOW_HINT: &str = "synthesize it in windows (SynthParams::origin) and assemble them";

/// The error for an output larger than the device allows, checked before the analysis
/// and the plan (the plan rejects huge outputs with a less specific message). The buffer
/// check is a lower bound (the finest level alone); [`GpuSynthesizer::fits`] checks the
/// whole pyramid.
/// `hint` says what to do instead (the API's way, or a command's).
pub(crate) fn check_output_size(
    ctx: &GpuContext,
    width: u32,
    height: u32,
    hint: &'static str,
) -> Result<()> {
    let limits = ctx.limits();
    let max_dim = limits.max_texture_dimension_2d;
    let too_large = |limit: String| Error::TooLarge {
        what: "output",
        width,
        height,
        limit,
        hint,
    };
    if width > max_dim || height > max_dim {
        return Err(too_large(format!("at most {max_dim} pixels a side")));
    }
    let bytes = width as u64 * height as u64 * 8;
    let max = limits
        .max_storage_buffer_binding_size
        .min(limits.max_buffer_size);
    if bytes > max {
        return Err(too_large(format!(
            "its coordinate pyramid needs more than {} MiB in one buffer, the device allows {} MiB",
            bytes >> 20,
            max >> 20
        )));
    }
    Ok(())
}

/// How a tileable output whose sides are not multiples of 4 is made, in words: each
/// level's period is half the finer one's, rounded up, and an odd period (or an odd
/// half) cannot be upsampled coherently across the wrap.
fn tileable_note(s: &GpuSynthesizer, params: &SynthParams) -> Result<Option<String>> {
    let (width, height) = (params.width, params.height);
    if !params.tileable_output || (width % 4 == 0 && height % 4 == 0) {
        return Ok(None);
    }
    Ok(Some(match s.plan_for(params)?.torus {
        Some(t) => format!(
            "tileable: synthesized on a {}x{} torus and resampled to {width}x{height} \
             (sides that are multiples of 4 wrap cleanly{})",
            t.period[0],
            t.period[1],
            if t.period[0] % 4 != 0 || t.period[1] % 4 != 0 {
                "; a side under 8 pixels keeps its period and may show a faint seam"
            } else {
                ""
            }
        ),
        None => format!(
            "note: this tileable output keeps its own periods ({}), and a side that is \
             not a multiple of 4 shows a faint seam where the tiles meet (e.g. {}x{} \
             tiles cleanly)",
            if width.min(height) < crate::passes::plan::TORUS_MIN_SIDE {
                "a side under 8 pixels"
            } else {
                "its torus would not fit the device"
            },
            width.next_multiple_of(4),
            height.next_multiple_of(4)
        ),
    }))
}

/// Loads an analysis file or analyses an image, whichever `path` holds.
pub fn load_source(
    path: &Path,
    options: &AnalysisOptions,
    progress: impl FnMut(Progress),
) -> Result<Analysis> {
    if is_analysis_file(path)? {
        Analysis::load(path)
    } else {
        let ex = crate::image_io::load_exemplar(path)?;
        analysis::analyze(&ex, options, progress)
    }
}

pub use crate::analysis::file::is_analysis_file;
