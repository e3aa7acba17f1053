//! [`SessionBuilder`]: what a [`Session`](super::Session) synthesizes from and how.

use std::path::{Path, PathBuf};
use std::time::Duration;

use crate::analysis::{Analysis, AnalysisOptions, AppearanceSpace, Exemplar, Progress};
use crate::gpu::copy_guard::DEFAULT_COPY_BUDGET;
use crate::gpu::GpuContext;
use crate::passes::SynthParams;

use super::MaterialMap;

/// Where the exemplar comes from.
pub(super) enum Source {
    None,
    /// A file: an image or an analysis file (memory-mapped with `mapped`).
    Path {
        path: PathBuf,
        mapped: bool,
    },
    Exemplar(Exemplar),
    Analysis(Analysis),
}

/// Called after each level of a long synthesis: `(levels done, levels in all, time since
/// the synthesis started)`.
pub type LevelCallback = Box<dyn FnMut(u32, u32, Duration) + Send>;

/// Builds a [`Session`](super::Session): an exemplar (`exemplar_path`, `exemplar` or
/// `analysis`), analysis options, synthesis parameters and outputs (magnification,
/// material maps, coordinates), then [`Self::build`].
///
/// ```no_run
/// use texsyn::{MaterialMap, Session};
/// let session = Session::builder()
///     .exemplar_path("assets/bricks.png")
///     .feature_mask_path("assets/bricks_mask.png")
///     .material_map(MaterialMap::normal("assets/bricks_normal.png"))
///     .magnify(4)
///     .size(256, 256)
///     .build()?;
/// let texture = session.run()?; // 1024x1024, its normal map alike
/// texture.save_all("bricks.png".as_ref(), None, &["bricks_n.png".as_ref()])?;
/// # Ok::<(), texsyn::Error>(())
/// ```
pub struct SessionBuilder {
    pub(super) source: Source,
    pub(super) options: AnalysisOptions,
    /// `k` as given with [`Self::k`]: an analysis file must agree.
    pub(super) k_given: Option<u32>,
    /// The appearance space as given with [`Self::appearance`]: an analysis file must agree.
    pub(super) appearance_given: Option<AppearanceSpace>,
    pub(super) feature_mask_path: Option<PathBuf>,
    pub(super) params: SynthParams,
    pub(super) context: Option<GpuContext>,
    pub(super) progress: Option<Box<dyn FnMut(Progress)>>,
    pub(super) levels: Option<LevelCallback>,
    pub(super) copy_budget: f32,
    pub(super) magnify: Option<u32>,
    pub(super) maps: Vec<MaterialMap>,
    pub(super) coordinates: bool,
}

impl SessionBuilder {
    pub(super) fn new() -> Self {
        SessionBuilder {
            source: Source::None,
            options: AnalysisOptions::default(),
            k_given: None,
            appearance_given: None,
            feature_mask_path: None,
            params: SynthParams::default(),
            context: None,
            progress: None,
            levels: None,
            copy_budget: DEFAULT_COPY_BUDGET,
            magnify: None,
            maps: Vec::new(),
            coordinates: true,
        }
    }

    /// The exemplar: an image file, or a saved analysis (`texsyn analyze`), told apart
    /// by content.
    pub fn exemplar_path(mut self, path: impl AsRef<Path>) -> Self {
        self.source = Source::Path {
            path: path.as_ref().to_path_buf(),
            mapped: false,
        };
        self
    }

    /// [`Self::exemplar_path`], with an analysis file memory-mapped rather than read (a
    /// faster start for large files).
    ///
    /// # Safety
    ///
    /// The file must not be truncated or modified in place while the session lives (see
    /// [`Analysis::load_mapped`]); texsyn replaces analysis files by renaming a new one
    /// over them, which leaves a mapping intact.
    pub unsafe fn exemplar_path_mapped(mut self, path: impl AsRef<Path>) -> Self {
        self.source = Source::Path {
            path: path.as_ref().to_path_buf(),
            mapped: true,
        };
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

    /// Similarity-set size (default 2); an analysis file must have been made with it.
    pub fn k(mut self, k: u32) -> Self {
        self.options.k = k;
        self.k_given = Some(k);
        self
    }

    /// Force tileable (wrap-around) or non-tileable handling; default: detected. An
    /// analysis file must have been made with the same.
    pub fn tileable(mut self, tileable: bool) -> Self {
        self.options.tileable = Some(tileable);
        self
    }

    /// The appearance space of the analysis; an analysis file must have been made in it.
    pub fn appearance(mut self, space: AppearanceSpace) -> Self {
        self.options.appearance = space;
        self.appearance_given = Some(space);
        self
    }

    /// A binary feature mask of the exemplar's size (any image format; bright =
    /// feature), read when the session is built; with [`Self::magnify`] it may be given
    /// at the full exemplar's size. Only for an exemplar image (not an analysis file),
    /// and not blank.
    pub fn feature_mask_path(mut self, path: impl AsRef<Path>) -> Self {
        self.feature_mask_path = Some(path.as_ref().to_path_buf());
        self
    }

    /// All synthesis parameters at once (the other setters change single fields).
    pub fn params(mut self, params: SynthParams) -> Self {
        self.params = params;
        self
    }

    /// Output size in pixels (default 256x256), before any magnification. Outputs larger
    /// than the device takes in one piece are assembled from windows.
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

    /// Output one period of a seamlessly tiling texture (one synthesis: it cannot be
    /// assembled from windows).
    pub fn tileable_output(mut self, on: bool) -> Self {
        self.params.tileable_output = on;
        self
    }

    /// Magnification by `factor` (2, 4 or 8): the exemplar image is analysed downsampled
    /// `factor` times, the output synthesized at [`Self::size`] and rendered `factor`
    /// times larger with the full-resolution colours (material maps alike). Needs an
    /// exemplar image, not an analysis.
    pub fn magnify(mut self, factor: u32) -> Self {
        self.magnify = Some(factor);
        self
    }

    /// A material map aligned with the exemplar (normal, height, roughness...),
    /// resynthesized through the same coordinates (and magnified the same way); read
    /// when the session runs. Repeatable: [`Texture::maps`](super::Texture::maps) are in
    /// this order.
    pub fn material_map(mut self, map: MaterialMap) -> Self {
        self.maps.push(map);
        self
    }

    /// Whether [`Session::run`](super::Session::run) reads the exemplar coordinates back
    /// (default `true`). Without them an output of the colours alone is read back (half
    /// the transfer) and [`Texture::coords`](super::Texture::coords) is empty.
    pub fn coordinates(mut self, on: bool) -> Self {
        self.coordinates = on;
        self
    }

    /// Run on the caller's device instead of creating a headless one (which is created
    /// on a thread of its own while the exemplar is read).
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

    /// Called after each level of syntheses of at least
    /// [`LONG_SYNTHESIS_PIXELS`](super::LONG_SYNTHESIS_PIXELS) in one piece (each level
    /// is then submitted on its own, which costs a GPU round trip per level); outputs in
    /// windows report each window through [`Session::run_reporting`](super::Session::run_reporting).
    pub fn on_level(mut self, f: impl FnMut(u32, u32, Duration) + Send + 'static) -> Self {
        self.levels = Some(Box::new(f));
        self
    }

    /// The copy guard's budget, 0..=1 (default [`DEFAULT_COPY_BUDGET`], 0 = no guard,
    /// the default schedule always): the largest verbatim copy, as a fraction of the
    /// exemplar, that a stiller schedule may make (the copy guard, in the GPU layer).
    /// It is measured on the window at the origin of the output's size (at least
    /// 512x512) and holds there: windows elsewhere can copy more
    /// ([`GpuSynthesizer::output_within_probe`](crate::GpuSynthesizer::output_within_probe));
    /// 0 bounds the copies at any size and place.
    pub fn copy_budget(mut self, budget: f32) -> Self {
        self.copy_budget = budget;
        self
    }

    /// Reads the exemplar (creating the device meanwhile), checks the request against
    /// the exemplar and the device, analyses the exemplar unless given an analysis,
    /// checks the parameters and uploads the tables. [`Self::build_reporting`] with a
    /// callback that ignores everything.
    pub fn build(self) -> crate::Result<super::Session> {
        self.build_reporting(&mut |_| {})
    }
}
