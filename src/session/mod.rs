//! The high-level API: a builder that takes an exemplar (image, pixels or a saved
//! analysis), analyses it if needed, uploads it to a GPU (headless or the caller's
//! device) and synthesizes textures.
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

use std::path::{Path, PathBuf};
use std::sync::Arc;

mod source;
pub use source::{crop_rows, ExemplarSource, Magnified};
#[cfg(feature = "gltf")]
mod surface;
#[cfg(feature = "gltf")]
pub use surface::{
    MaterialMap, SurfaceBuilder, SurfaceEvent, SurfaceSession, SurfaceTimings, TexturedSurface,
};

use crate::analysis::{self, Analysis, AnalysisOptions, Exemplar, Progress};
use crate::error::{Error, Result};
use crate::gpu::copy_guard::DEFAULT_COPY_BUDGET;
use crate::gpu::synth::{GpuSynthesis, GpuSynthesizer};
use crate::gpu::GpuContext;
use crate::passes::{SynthParams, Synthesis};

enum Source {
    None,
    Path(PathBuf),
    Exemplar(Exemplar),
    Analysis(Analysis),
}

/// Builds a [`Session`].
pub struct SessionBuilder {
    source: Source,
    options: AnalysisOptions,
    params: SynthParams,
    context: Option<GpuContext>,
    progress: Option<Box<dyn FnMut(Progress)>>,
    copy_budget: f32,
}

/// An analysed exemplar on a GPU, ready to synthesize.
pub struct Session {
    context: GpuContext,
    synthesizer: Arc<GpuSynthesizer>,
    params: SynthParams,
    copy_budget: f32,
}

impl Session {
    /// A builder: give it an exemplar (`exemplar_path`, `exemplar` or `analysis`), then
    /// options, then [`SessionBuilder::build`].
    pub fn builder() -> SessionBuilder {
        SessionBuilder {
            source: Source::None,
            options: AnalysisOptions::default(),
            params: SynthParams::default(),
            context: None,
            progress: None,
            copy_budget: DEFAULT_COPY_BUDGET,
        }
    }

    /// Synthesizes with the session's parameters and reads the result back.
    pub fn run(&self) -> Result<Texture> {
        self.run_with(&self.params)
    }

    /// Synthesizes with other parameters (size, window, seed, ...), same exemplar. The
    /// jitter schedule goes through the copy guard ([`Self::schedule`]).
    pub fn run_with(&self, params: &SynthParams) -> Result<Texture> {
        let choice = self.synthesizer.choose_schedule(params, self.copy_budget)?;
        let s = match choice.result {
            Some(s) => s,
            None => self.synthesizer.synthesize_to_host(&choice.params)?,
        };
        Ok(Texture {
            synthesis: s,
            channels: self.analysis().channels,
            exemplar_size: [self.analysis().width, self.analysis().height],
            tileable: self.analysis().tileable,
        })
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

impl SessionBuilder {
    /// The exemplar: an image file, or a saved analysis (`texsyn analyze`), told apart
    /// by content.
    pub fn exemplar_path(mut self, path: impl AsRef<Path>) -> Self {
        self.source = Source::Path(path.as_ref().to_path_buf());
        self
    }

    /// An exemplar already in memory (e.g. [`Exemplar::from_rgba8`]).
    pub fn exemplar(mut self, exemplar: Exemplar) -> Self {
        self.source = Source::Exemplar(exemplar);
        self
    }

    /// An analysis made earlier; skips the analysis.
    pub fn analysis(mut self, analysis: Analysis) -> Self {
        self.source = Source::Analysis(analysis);
        self
    }

    /// Analysis options (k, exclusion radius, tileability, feature mask, appearance
    /// space); ignored when the source is an analysis.
    pub fn analysis_options(mut self, options: AnalysisOptions) -> Self {
        self.options = options;
        self
    }

    /// Similarity-set size (default 2).
    pub fn k(mut self, k: u32) -> Self {
        self.options.k = k;
        self
    }

    /// Force tileable (wrap-around) or non-tileable handling; default: detected.
    pub fn tileable(mut self, tileable: bool) -> Self {
        self.options.tileable = Some(tileable);
        self
    }

    /// All synthesis parameters at once (the other setters change single fields).
    pub fn params(mut self, params: SynthParams) -> Self {
        self.params = params;
        self
    }

    /// Output size in pixels (default 256x256).
    pub fn size(mut self, width: u32, height: u32) -> Self {
        self.params.width = width;
        self.params.height = height;
        self
    }

    /// Random seed (default 1): the same seed gives the same bytes.
    pub fn seed(mut self, seed: u32) -> Self {
        self.params.seed = seed;
        self
    }

    /// Per-level randomness (index = level, coarsest first; the last value repeats).
    pub fn randomness(mut self, r: Vec<f32>) -> Self {
        self.params.randomness = r;
        self
    }

    /// Correction passes per coarse level (default 4; see [`SynthParams::passes`]).
    pub fn passes(mut self, passes: u32) -> Self {
        self.params.passes = passes;
        self
    }

    /// Correction passes at the second-finest level (default: `passes`, at most 2 in an
    /// isometric synthesis from exemplars of 256x256 px and more, 3 from smaller ones
    /// without a feature channel, also along a field; see
    /// [`SynthParams::second_finest_passes`]).
    pub fn second_finest_passes(mut self, passes: u32) -> Self {
        self.params.second_finest_passes = Some(passes);
        self
    }

    /// Score the similarity sets on every `n`-th correction pass only (default 1; see
    /// [`SynthParams::sets_every`]).
    pub fn sets_every(mut self, n: u32) -> Self {
        self.params.sets_every = n;
        self
    }

    /// Bias towards coherent candidates, 0 to 4 (default 1; see
    /// [`SynthParams::coherence`]).
    pub fn coherence(mut self, c: f32) -> Self {
        self.params.coherence = c;
        self
    }

    /// The output is the window at `(x, y)` of the unbounded texture (default `0, 0`):
    /// windows of the same session and seed fit together (see [`SynthParams::origin`]).
    pub fn window(mut self, x: i32, y: i32) -> Self {
        self.params.origin = [x, y];
        self
    }

    /// Anisometric synthesis along a Jacobian field (see [`crate::field`]).
    pub fn field(mut self, field: crate::field::Field) -> Self {
        self.params.field = Some(field);
        self
    }

    /// A texture of its own with thin margins, faster than an exact window of the
    /// unbounded texture (default `false`; see [`SynthParams::standalone`]).
    pub fn standalone(mut self, on: bool) -> Self {
        self.params.standalone = on;
        self
    }

    /// Blend colours across patch seams (default `true`; see [`SynthParams::seam_blend`]).
    pub fn seam_blend(mut self, on: bool) -> Self {
        self.params.seam_blend = on;
        self
    }

    /// Output one period of a seamlessly tiling texture.
    pub fn tileable_output(mut self, on: bool) -> Self {
        self.params.tileable_output = on;
        self
    }

    /// Run on the caller's device instead of creating a headless one.
    pub fn context(mut self, context: GpuContext) -> Self {
        self.context = Some(context);
        self
    }

    /// Called as the analysis goes: when each stage of a level starts, during the
    /// similarity-set search and after each level ([`Progress::stage`] says which).
    pub fn on_progress(mut self, f: impl FnMut(Progress) + 'static) -> Self {
        self.progress = Some(Box::new(f));
        self
    }

    /// The copy guard's budget, 0..=1 (default [`DEFAULT_COPY_BUDGET`], 0 = no guard,
    /// the default schedule always): the largest verbatim copy, as a fraction of the
    /// exemplar, that a stiller schedule may make (see [`crate::gpu::copy_guard`]).
    /// It is measured on the window at the origin of the output's size (at least
    /// 512x512) and holds there: windows elsewhere can copy more
    /// ([`GpuSynthesizer::output_within_probe`](crate::GpuSynthesizer::output_within_probe));
    /// 0 bounds the copies at any size and place.
    pub fn copy_budget(mut self, budget: f32) -> Self {
        self.copy_budget = budget;
        self
    }

    /// Loads and analyses the exemplar (unless given an analysis), creates or takes the
    /// GPU context, checks the parameters and uploads the tables.
    pub fn build(self) -> Result<Session> {
        let mut progress = self.progress;
        let mut report = |p: Progress| {
            if let Some(f) = progress.as_mut() {
                f(p)
            }
        };
        let context = match self.context {
            Some(c) => c,
            None => GpuContext::headless()?,
        };
        let fits = |w, h| crate::gpu::synth::check_exemplar_fits(&context, w, h, self.options.k);
        let analysis = match self.source {
            Source::None => {
                return Err(Error::InvalidParameter(
                    "no exemplar given: call exemplar_path, exemplar or analysis".into(),
                ))
            }
            Source::Analysis(a) => a,
            Source::Exemplar(e) => {
                fits(e.width, e.height)?;
                analysis::analyze(&e, &self.options, &mut report)?
            }
            Source::Path(p) => {
                if is_analysis_file(&p)? {
                    Analysis::load(&p)?
                } else {
                    let e = crate::image_io::load_exemplar(&p)?;
                    fits(e.width, e.height)?;
                    analysis::analyze(&e, &self.options, &mut report)?
                }
            }
        };
        // Validate the parameters before uploading.
        if !self.copy_budget.is_finite() || !(0.0..=1.0).contains(&self.copy_budget) {
            return Err(Error::InvalidParameter(format!(
                "copy budget {} must be between 0 and 1",
                self.copy_budget
            )));
        }
        analysis.validate()?;
        crate::passes::SynthPlan::new(&analysis, &self.params)?;
        let synthesizer = Arc::new(GpuSynthesizer::new(&context, Arc::new(analysis))?);
        // The pipelines (and the rasterized field) now, so that `run` only synthesizes.
        if synthesizer.fits(&self.params) {
            synthesizer.prepare(&self.params)?;
        }
        Ok(Session {
            context,
            synthesizer,
            params: self.params,
            copy_budget: self.copy_budget,
        })
    }
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

/// A synthesized texture on the host.
#[derive(Clone, Debug)]
pub struct Texture {
    /// Colours and exemplar coordinates, read back from the GPU.
    pub synthesis: Synthesis,
    /// 1 for grey exemplars, 3 for colour.
    pub channels: u32,
    /// Width and height of the (analysed) exemplar, in pixels.
    pub exemplar_size: [u32; 2],
    /// Whether the exemplar was handled as tileable (coordinates wrap around it).
    pub tileable: bool,
}

impl Texture {
    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.synthesis.width
    }
    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.synthesis.height
    }
    /// Fractional bits of [`Texture::coords`]: 0 (isometric) or 8 (anisometric).
    pub fn coord_frac(&self) -> u32 {
        self.synthesis.coord_frac
    }
    /// RGBA8 bytes, row-major.
    pub fn rgba8(&self) -> Vec<u8> {
        self.synthesis.colors.iter().flatten().copied().collect()
    }
    /// Exemplar coordinates per pixel, in units of `2^-coord_frac()` exemplar pixels.
    pub fn coords(&self) -> &[[i32; 2]] {
        &self.synthesis.coords
    }
    /// Saves the colours (PNG, or another format by extension), atomically.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<()> {
        crate::image_io::save_image_atomic(
            path.as_ref(),
            self.width(),
            self.height(),
            self.channels,
            &self.rgba8(),
        )
    }
    /// Saves the coordinate map as a float EXR (R = x, G = y, exemplar pixels),
    /// atomically.
    pub fn save_coords(&self, path: impl AsRef<Path>) -> Result<()> {
        crate::image_io::save_coords_exr_f32_atomic(
            path.as_ref(),
            self.width(),
            self.height(),
            &self.synthesis.coords_f32(),
        )
    }
}

/// Whether `path` starts with the analysis-file magic (a missing file is an error).
pub fn is_analysis_file(path: &Path) -> Result<bool> {
    use std::io::Read;
    let mut f = crate::image_io::open_regular(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mut head = [0u8; 8];
    let mut n = 0;
    while n < head.len() {
        match f.read(&mut head[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(source) => {
                return Err(Error::Io {
                    path: path.to_path_buf(),
                    source,
                })
            }
        }
    }
    Ok(n == head.len() && head == analysis::file::MAGIC)
}
