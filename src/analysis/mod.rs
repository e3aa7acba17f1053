//! Host-side exemplar analysis (Lefebvre & Hoppe 2006 §3-4): Gaussian stack, 5x5 appearance
//! vectors reduced to 8D by PCA, the 4-diagonal runtime neighbourhoods and their 8D
//! projection, and k-coherence similarity sets. Everything the GPU needs is quantized to
//! integers here so that the GPU passes and their CPU mirrors compute identical bytes.

pub mod appearance;
pub mod feature;
pub mod file;
pub mod kcoherence;
pub mod kdtree;
pub mod pca;
pub mod stack;
pub mod table;

use crate::error::{Error, Result};
pub use feature::FeatureMask;
pub use table::Table;

/// Smallest exemplar side we accept: below this the 5x5 neighbourhoods at the finest
/// level already cover most of the image and synthesis can only copy it.
pub const MIN_EXEMPLAR_SIZE: u32 = 16;
/// Dimension of the transformed exemplar and of the projected runtime neighbourhood.
pub const DIM: usize = 8;
/// Largest |value| of a quantized transformed-exemplar component.
pub const ET_QMAX: f32 = 2047.0;
/// Largest |value| of a quantized projection-matrix entry (rows are unit vectors).
pub const PROJ_QMAX: f32 = 127.0;
/// Projected neighbourhood values are shifted right until they fit in this range so that
/// 8 squared differences (clamped to 2*QE_MAX) fit in a u32 even after the largest
/// coherence bias (distance x 5).
pub const QE_MAX: i32 = 4095;
/// Largest k supported by the GPU passes.
pub const MAX_K: u32 = 8;
/// Exemplars of at least this many pixels search their similarity sets with less
/// effort (see `analyze`).
pub const LARGE_EXEMPLAR_PIXELS: u64 = 256 * 256;

/// The exemplar as loaded: RGBA8 colours (what synthesis outputs) and the float
/// channels the analysis runs on (1 for grey exemplars, 3 for colour; alpha is ignored).
#[derive(Clone, Debug, PartialEq)]
pub struct Exemplar {
    /// Width in pixels (at least [`MIN_EXEMPLAR_SIZE`]).
    pub width: u32,
    /// Height in pixels (at least [`MIN_EXEMPLAR_SIZE`]).
    pub height: u32,
    /// 1 (grey) or 3 (RGB).
    pub channels: u32,
    /// Row-major, `channels` floats per pixel in [0, 1].
    pub values: Vec<f32>,
    /// Row-major RGBA8 (grey is replicated into RGB; alpha is 255).
    pub colors: Vec<[u8; 4]>,
}

/// `width * height`, refusing sizes whose per-channel buffers could not be addressed.
fn pixel_count(width: u32, height: u32) -> Result<usize> {
    (width as usize)
        .checked_mul(height as usize)
        .filter(|&n| n <= usize::MAX / 16)
        .ok_or_else(|| {
            Error::InvalidParameter(format!("exemplar: {width}x{height} pixels is too large"))
        })
}

impl Exemplar {
    /// An exemplar from 8-bit RGBA pixels (row-major, 4 bytes a pixel, sRGB-encoded as
    /// images usually are; alpha is ignored): 3 channels. For grey or 16-bit/float data,
    /// build an `image::DynamicImage` and use [`crate::image_io::exemplar_from_image`].
    /// Errors: a buffer of the wrong length, or a size below [`MIN_EXEMPLAR_SIZE`].
    pub fn from_rgba8(width: u32, height: u32, rgba: &[u8]) -> Result<Exemplar> {
        let n = pixel_count(width, height)?;
        if rgba.len() != n * 4 {
            return Err(Error::InvalidParameter(format!(
                "exemplar: {} bytes given for {width}x{height} RGBA8 pixels ({} expected)",
                rgba.len(),
                n * 4
            )));
        }
        check_exemplar_size(width, height)?;
        let colors: Vec<[u8; 4]> = rgba
            .chunks_exact(4)
            .map(|p| [p[0], p[1], p[2], 255])
            .collect();
        let values = colors
            .iter()
            .flat_map(|p| [p[0], p[1], p[2]].map(|v| v as f32 / 255.0))
            .collect();
        Ok(Exemplar {
            width,
            height,
            channels: 3,
            values,
            colors,
        })
    }

    /// Checks that the public fields agree (sizes, channel count, finite values in
    /// [0, 1]); [`analyze`] calls it, so a hand-built exemplar fails with a clear error.
    pub fn check(&self) -> Result<()> {
        check_exemplar_size(self.width, self.height)?;
        let n = pixel_count(self.width, self.height)?;
        if self.channels != 1 && self.channels != 3 {
            return Err(Error::InvalidParameter(format!(
                "exemplar: {} channels; it must have 1 (grey) or 3 (RGB)",
                self.channels
            )));
        }
        if self.values.len() != n * self.channels as usize {
            return Err(Error::InvalidParameter(format!(
                "exemplar: {} values for {}x{} pixels of {} channel(s) ({} expected)",
                self.values.len(),
                self.width,
                self.height,
                self.channels,
                n * self.channels as usize
            )));
        }
        if self.colors.len() != n {
            return Err(Error::InvalidParameter(format!(
                "exemplar: {} colours for {}x{} pixels",
                self.colors.len(),
                self.width,
                self.height
            )));
        }
        if let Some(i) = self
            .values
            .iter()
            .position(|v| !(v.is_finite() && (0.0..=1.0).contains(v)))
        {
            let px = i / self.channels as usize;
            return Err(Error::InvalidParameter(format!(
                "exemplar: value {} at pixel ({}, {}) is not a number in [0, 1]",
                self.values[i],
                px % self.width as usize,
                px / self.width as usize
            )));
        }
        Ok(())
    }
}

/// What a pixel's appearance vector holds before the PCA to 8D.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum AppearanceSpace {
    /// The Gaussian-weighted 5x5 neighbourhood of every channel (the paper's appearance
    /// space; 75D for RGB, 100D with a feature channel).
    #[default]
    Neighborhood,
    /// The pixel's own channels only (3D for RGB, plus the feature channel if any): plain
    /// colour, for comparison (Lefebvre & Hoppe 2006, Figure 4). Still projected by PCA into the same 8D
    /// `Et` (the components beyond the input dimension are zero), so synthesis costs the
    /// same.
    Color,
}

impl AppearanceSpace {
    /// `"neighborhood"` or `"color"` (the CLI's spelling).
    pub fn name(self) -> &'static str {
        match self {
            AppearanceSpace::Neighborhood => "neighborhood",
            AppearanceSpace::Color => "color",
        }
    }
}

impl std::str::FromStr for AppearanceSpace {
    type Err = Error;
    /// `neighborhood` / `neighbourhood` or `color` / `colour` (any case).
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "neighborhood" | "neighbourhood" => Ok(AppearanceSpace::Neighborhood),
            "color" | "colour" => Ok(AppearanceSpace::Color),
            _ => Err(Error::InvalidParameter(format!(
                "appearance space {s:?}: expected \"neighborhood\" or \"color\""
            ))),
        }
    }
}

/// Where a feature mask acts ([`AnalysisOptions::feature_mode`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FeatureMode {
    /// The paper's way (section 3.2): the channel joins the appearance vectors that the
    /// synthesis matches and the similarity sets are found with. Structures stay whole
    /// but the 8D appearance space then also carries the channel, and the colour texture
    /// energy rises where the colours already show the features. The mode for structure
    /// the colours do not show.
    Appearance,
    /// The channel shapes the similarity sets only: the exemplar places a pixel may jump
    /// to have its colour neighbourhood *and* its feature context, while the appearance
    /// vectors the synthesis matches are those of the colours alone, as without a mask.
    /// A smaller structural gain than `Appearance`, without its colour cost. The
    /// appearance step runs twice, so the analysis takes about a third longer; the
    /// runtime is the same.
    Sets,
    /// Both (the default): the similarity sets are searched as with `Sets`, and the
    /// appearance vectors the synthesis matches carry the channel too, lightly, at
    /// [`feature::BOTH_APPEARANCE_SHARE`] of the weight (1/128: 0.125 at the default 16).
    /// Against no mask it lowers both the colour texture energy and the breakage of the
    /// features. Where the colours do not show the structure at all it barely helps: use
    /// `Appearance`.
    /// The analysis costs as in `Sets`; the runtime is the same.
    #[default]
    Both,
}

impl FeatureMode {
    /// `"appearance"`, `"sets"` or `"both"` (the CLI's spelling).
    pub fn name(self) -> &'static str {
        match self {
            FeatureMode::Appearance => "appearance",
            FeatureMode::Sets => "sets",
            FeatureMode::Both => "both",
        }
    }
}

impl std::str::FromStr for FeatureMode {
    type Err = Error;
    /// `appearance`, `sets` or `both` (any case).
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "appearance" => Ok(FeatureMode::Appearance),
            "sets" => Ok(FeatureMode::Sets),
            "both" => Ok(FeatureMode::Both),
            _ => Err(Error::InvalidParameter(format!(
                "feature mode {s:?}: expected \"appearance\", \"sets\" or \"both\""
            ))),
        }
    }
}

/// How a feature mask entered an analysis (kept in [`Analysis`] and its file).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FeatureInfo {
    /// [`AnalysisOptions::feature_weight`].
    pub weight: f32,
    /// [`AnalysisOptions::feature_clamp`] (`dmax`, exemplar pixels).
    pub clamp: f32,
    /// Fraction of the exemplar's pixels inside the mask.
    pub coverage: f32,
    /// [`AnalysisOptions::feature_mode`].
    pub mode: FeatureMode,
}

/// Options of the analysis.
#[derive(Clone, Debug)]
pub struct AnalysisOptions {
    /// Size of the similarity sets including the pixel itself (paper: k = 2).
    pub k: u32,
    /// `None`: detect from the wrap-around seams; `Some(t)`: force.
    pub tileable: Option<bool>,
    /// Similarity-set members must lie at least this many pixels (Chebyshev, at the
    /// finest level; scaled with the level spacing, capped) from the query pixel.
    pub exclusion_radius: u32,
    /// Worker threads (0 = all available cores).
    pub threads: usize,
    /// Appearance vector: 5x5 neighbourhoods (default) or plain colour.
    pub appearance: AppearanceSpace,
    /// Optional binary feature mask of the exemplar's size (Lefebvre & Hoppe 2006 §3.2): its
    /// clamped signed-distance field becomes an extra channel of the exemplar before the
    /// Gaussian stack and the neighbourhood PCA (see [`feature`]). `None`: colour only.
    pub feature_mask: Option<FeatureMask>,
    /// Weight `w` of the feature channel, in `[0, 100]`: at 1 the channel has as much
    /// variance as all colour channels together. `None`: the mode's default
    /// ([`feature::default_weight`]: 16 for `Both` and `Sets`, 1 for `Appearance`).
    /// Ignored without a mask.
    pub feature_weight: Option<f32>,
    /// Clamp `dmax` of the signed distance, in exemplar pixels
    /// ([`feature::DEFAULT_FEATURE_CLAMP`], 1).
    pub feature_clamp: f32,
    /// Where the mask acts: in the similarity sets and lightly in the appearance vectors
    /// (`Both`, the default), in the appearance vectors (`Appearance`, the paper's way)
    /// or in the similarity sets only (`Sets`). Ignored without a mask.
    pub feature_mode: FeatureMode,
    /// Search the finest level's similarity sets (default). Only a synthesis that
    /// corrects the finest level reads them ([`crate::passes::SynthParams::finest_passes`]
    /// above 0, advection); the default synthesis leaves that level uncorrected, so
    /// `false` saves the longest step of the search (measured on 128-512 px exemplars:
    /// 8-26% of the analysis time, 2 cores) for the same output bytes. The
    /// finest level's `offsets` table is then empty ([`Analysis::has_finest_sets`]), and
    /// a synthesis that would correct that level is refused with an error. Its `et`
    /// and `qe` tables, which only that correction reads, are left out too.
    pub finest_sets: bool,
}

impl Default for AnalysisOptions {
    fn default() -> Self {
        Self {
            k: 2,
            tileable: None,
            exclusion_radius: 4,
            threads: 0,
            appearance: AppearanceSpace::Neighborhood,
            feature_mask: None,
            feature_weight: None,
            feature_clamp: feature::DEFAULT_FEATURE_CLAMP,
            feature_mode: FeatureMode::Both,
            finest_sets: true,
        }
    }
}

/// The exemplar's colours alone.
fn colour_plane(ex: &Exemplar) -> stack::Plane {
    stack::Plane {
        width: ex.width,
        height: ex.height,
        channels: ex.channels,
        data: ex.values.clone(),
    }
}

/// The exemplar's colours with the feature channel of `mask` at `weight` appended to
/// each pixel.
fn with_feature_channel(
    ex: &Exemplar,
    mask: &FeatureMask,
    weight: f32,
    clamp: f32,
    tileable: bool,
) -> stack::Plane {
    let c = ex.channels as usize;
    let f = feature::feature_channel(mask, weight, clamp, &ex.values, c, tileable);
    let mut data = Vec::with_capacity(ex.values.len() + f.len());
    for (px, v) in ex.values.chunks_exact(c).zip(&f) {
        data.extend_from_slice(px);
        data.push(*v);
    }
    stack::Plane {
        width: ex.width,
        height: ex.height,
        channels: ex.channels + 1,
        data,
    }
}

/// Per-level data used at run time.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelData {
    /// `h_l`: exemplar pixels spanned by one synthesis pixel at this level.
    pub spacing: u32,
    /// Non-tileable exemplars: synthesized coordinates stay in
    /// `[margin, size - 1 - margin]` so that no neighbourhood crosses the border.
    pub margin: u32,
    /// Quantized 8D transformed exemplar `Et_l`, row-major `width*height`. Empty, with
    /// `qe`, on levels no synthesis corrects: level 0 (synthesis starts there from one
    /// coordinate and goes on upsampling) and a finest level analysed without its
    /// similarity sets ([`AnalysisOptions::finest_sets`]).
    pub et: Table<[i16; DIM]>,
    /// Quantized runtime projection `P_l` (8 rows x 32 columns; column `j * 8 + c` weighs
    /// component `c` of diagonal neighbour `j`, in `DIAGONALS` order).
    pub proj: [[i16; 4 * DIM]; DIM],
    /// `3 * P_l * N_E(u)` computed in integers from `et` and `proj`, then arithmetically
    /// shifted right by `shift`: the exemplar side of the correction distance.
    pub qe: Table<[i16; DIM]>,
    /// Right shift applied to `3 * P_l * N` (exemplar side in `qe`, synthesized side in
    /// the correction pass) so that its largest exemplar value fits in [`QE_MAX`].
    pub shift: u32,
    /// k-coherence offsets `O_i(u) = C_i(u) - u` for i = 2..k: `(k-1)` pairs per pixel.
    pub offsets: Table<[i16; 2]>,
    /// Fraction of the appearance-vector variance not kept by the 8D PCA.
    pub residual_variance: f32,
    /// Same for the 32D -> 8D runtime neighbourhood projection.
    pub runtime_residual_variance: f32,
}

/// The result of analysing an exemplar: everything synthesis needs. Save it with
/// [`Analysis::save`] and load it with [`Analysis::load`] to skip the analysis.
#[derive(Clone, Debug, PartialEq)]
pub struct Analysis {
    /// Exemplar width in pixels.
    pub width: u32,
    /// Exemplar height in pixels.
    pub height: u32,
    /// Colour channels of the exemplar the analysis ran on: 1 (grey) or 3 (RGB), not
    /// counting a feature-mask channel.
    pub channels: u32,
    /// Whether the exemplar was treated as tileable (borders wrap; no margins).
    pub tileable: bool,
    /// Similarity-set size including the pixel itself, `1..=`[`MAX_K`].
    pub k: u32,
    /// RGBA8 exemplar colours (the finest stack level, i.e. the exemplar itself).
    pub colors: Vec<[u8; 4]>,
    /// Levels `0..=L`, `levels[l].spacing == 2^(L-l)`.
    pub levels: Vec<LevelData>,
    /// The appearance space the analysis used (informational: synthesis is the same).
    pub appearance: AppearanceSpace,
    /// The feature mask's settings if one was used (informational).
    pub feature: Option<FeatureInfo>,
}

impl Analysis {
    /// Whether the finest level's similarity sets are there: false for an analysis made
    /// with [`AnalysisOptions::finest_sets`] off (its finest `offsets` table is empty),
    /// which serves only syntheses that leave the finest level uncorrected.
    pub fn has_finest_sets(&self) -> bool {
        self.k <= 1 || self.levels.last().is_none_or(|l| !l.offsets.is_empty())
    }

    /// Whether level `l` has its correction tables (`et`, `qe`): see [`LevelData::et`].
    pub fn has_tables(&self, l: usize) -> bool {
        self.levels.get(l).is_some_and(|l| !l.et.is_empty())
    }

    /// The exemplar's width times height.
    pub fn pixel_count(&self) -> u64 {
        self.width as u64 * self.height as u64
    }

    /// Where level `l`'s `et` and `qe` entries start in the tables of all levels
    /// concatenated (levels without tables take no room).
    pub fn table_base(&self, l: usize) -> usize {
        self.levels[..l].iter().map(|l| l.et.len()).sum()
    }
}

/// The four diagonals of the runtime neighbourhood, in the order used everywhere.
pub const DIAGONALS: [[i32; 2]; 4] = [[1, 1], [1, -1], [-1, 1], [-1, -1]];

/// Number of levels beyond the coarsest: `L = ceil(log2(max(w, h)))`.
pub fn level_count(width: u32, height: u32) -> u32 {
    let m = width.max(height).max(1);
    32 - (m - 1).leading_zeros()
}

/// Peak host memory of [`analyze`], bytes: about 64 bytes per pixel and level (the
/// float and quantized tables, the Gaussian stack, the similarity-search features).
/// Measured (maximum resident set of `texsyn analyze`): 1024x1024 grey 559 MB and RGB
/// 664 MB, 12 levels with level 0, i.e. 44-53 bytes per pixel and level.
pub fn analysis_memory_estimate(width: u32, height: u32) -> u64 {
    width as u64 * height as u64 * (level_count(width, height) as u64 + 1) * 64
}

/// Host memory the system reports as available (Linux `MemAvailable`), if it can tell.
pub fn available_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib.saturating_mul(1024))
}

/// An exemplar whose analysis would not fit in `available` bytes of memory is refused
/// before any work, with what to do, instead of ending in an allocation abort or the
/// out-of-memory killer minutes later. `None` (unknown): no check.
pub fn check_analysis_memory(width: u32, height: u32, available: Option<u64>) -> Result<()> {
    let need = analysis_memory_estimate(width, height);
    match available {
        Some(have) if need > have => Err(Error::InvalidParameter(format!(
            "exemplar {width}x{height} is too large to analyse on this machine: the analysis \
             needs about {:.1} GiB of memory and {:.1} GiB are available; downsample it, or \
             keep its detail with `texsyn synth --magnify F` (analysis on a 1/F copy, colours \
             from the full image)",
            need as f64 / (1u64 << 30) as f64,
            have as f64 / (1u64 << 30) as f64
        ))),
        _ => Ok(()),
    }
}

/// Validity margin of level `l` for non-tileable exemplars: `h_l` (half the radius of
/// the 5x5 neighbourhood, whose outer taps read clamped border pixels), capped at a
/// quarter of the smaller side so a valid region exists. Measured against the full
/// radius `2 h_l` (6 exemplars forced non-tileable, 512x512, seeds 1 and 2): a wider
/// reach into the border lowers the texture energy on 5 of 6 (median ratio to
/// texture-synthesis 1.13 -> 1.11 full, 1.01 -> 0.99 half resolution) and the histogram
/// distance (0.79 -> 0.66), because the coarse levels no longer draw only from the
/// exemplar's centre.
pub fn level_margin(width: u32, height: u32, spacing: u32, tileable: bool) -> u32 {
    if tileable {
        0
    } else {
        spacing.min(width.min(height) / 4)
    }
}

/// Whether a level of `spacing` has similarity sets of its own: its 5x5 neighbourhood
/// (`4 * spacing` wide) is narrower than the exemplar. Wider, the level is a near-constant
/// blur, its sets would be noise, and the analysis stores zero offsets (every set member
/// is the pixel itself) without searching; the synthesis corrects it with at most
/// [`crate::passes::plan::UNSEARCHED_PASSES`] passes (without a feature channel).
pub fn level_searched(width: u32, height: u32, spacing: u32) -> bool {
    4 * spacing < width.min(height)
}

/// Refuses an exemplar narrower or lower than [`MIN_EXEMPLAR_SIZE`] pixels with
/// [`Error::ExemplarTooSmall`].
pub fn check_exemplar_size(width: u32, height: u32) -> Result<()> {
    if width < MIN_EXEMPLAR_SIZE || height < MIN_EXEMPLAR_SIZE {
        return Err(Error::ExemplarTooSmall {
            width,
            height,
            min: MIN_EXEMPLAR_SIZE,
        });
    }
    Ok(())
}

/// Most worker threads the analysis starts, whatever it is asked for: the work is split
/// into at most 64 chunks (`par_ranges`), so more threads only idle, and a huge count
/// would fail to spawn (or overflow the kd-tree's power-of-two split).
pub const MAX_THREADS: usize = 256;

/// A thread count where 0 means all cores, at most [`MAX_THREADS`].
pub(crate) fn resolve_threads(threads: usize) -> usize {
    if threads == 0 {
        std::thread::available_parallelism()
            .map(|t| t.get())
            .unwrap_or(1)
    } else {
        threads
    }
    .min(MAX_THREADS)
}

/// Runs `f` over `0..n` split into chunks on `threads` workers (0 = all cores) and
/// returns the chunk results in order. Chunks are handed out dynamically so uneven work
/// balances. The chunks depend on `n` only (at most 64 of them), so neither the results
/// nor the order in which partial results are combined depend on the thread count.
pub fn par_ranges<T: Send>(
    n: usize,
    threads: usize,
    f: impl Fn(std::ops::Range<usize>) -> T + Sync,
) -> Vec<T> {
    let threads = resolve_threads(threads);
    let chunk = n.div_ceil(64).max(1);
    let chunks = n.div_ceil(chunk).max(1);
    if threads <= 1 || chunks <= 1 {
        return (0..chunks)
            .map(|c| f(c * chunk..((c + 1) * chunk).min(n)))
            .collect();
    }
    let next = std::sync::atomic::AtomicUsize::new(0);
    let mut results: Vec<Option<T>> = (0..chunks).map(|_| None).collect();
    std::thread::scope(|s| {
        let handles: Vec<_> = (0..threads.min(chunks))
            .map(|_| {
                s.spawn(|| {
                    let mut mine = Vec::new();
                    loop {
                        let c = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        if c >= chunks {
                            break;
                        }
                        mine.push((c, f(c * chunk..((c + 1) * chunk).min(n))));
                    }
                    mine
                })
            })
            .collect();
        for h in handles {
            for (c, r) in h.join().expect("analysis worker panicked") {
                results[c] = Some(r);
            }
        }
    });
    results.into_iter().map(|r| r.unwrap()).collect()
}

/// Fills `out` in parallel: `f(range, part)` writes the items `range` of `out` into
/// `part` (`part.len() == range.len()`). The ranges are those of [`par_ranges`] over
/// `out.len() / per_item` items, `per_item` elements each (e.g. rows of `per_item`
/// pixels), so the results do not depend on the thread count.
///
/// Where [`par_ranges`] returns per-chunk vectors that the caller concatenates, this
/// writes each element once, in place: on the analysis's large tables the second copy
/// of fresh memory, with its page faults, cost as much as the arithmetic.
pub fn par_fill<T: Send>(
    out: &mut [T],
    per_item: usize,
    threads: usize,
    f: impl Fn(std::ops::Range<usize>, &mut [T]) + Sync,
) {
    let n = out.len() / per_item.max(1);
    assert_eq!(n * per_item, out.len(), "par_fill: partial item");
    let chunk = n.div_ceil(64).max(1);
    let parts: Vec<(usize, &mut [T])> = out
        .chunks_mut(chunk * per_item)
        .enumerate()
        .map(|(c, part)| (c * chunk, part))
        .collect();
    let queue = std::sync::Mutex::new(parts.into_iter());
    let work = || loop {
        let next = queue.lock().expect("par_fill queue").next();
        let Some((start, part)) = next else { break };
        let len = part.len() / per_item.max(1);
        f(start..start + len, part);
    };
    let threads = resolve_threads(threads);
    let workers = threads.min(n.div_ceil(chunk).max(1));
    if workers <= 1 {
        work();
        return;
    }
    std::thread::scope(|s| {
        let handles: Vec<_> = (1..workers).map(|_| s.spawn(work)).collect();
        work();
        for h in handles {
            h.join().expect("analysis worker panicked");
        }
    });
}

/// Whether the exemplar tiles: the mean squared difference across its wrap-around
/// seams is at most 1.25 times that between neighbouring interior pixels.
///
/// The bound was 1.5 until measured: two GIMP patterns with seams 1.34 and 1.38 times
/// their interior differences (burlap, cracked) synthesize with lower texture energy
/// as non-tileable (512x512, seeds 1-2, ratio to texture-synthesis 1.37 -> 1.30 and
/// 1.91 -> 1.24), since patches that cross a faint seam make neighbourhoods the
/// exemplar does not contain; those at 0.5-0.95 (pink marble, walnut, leopard) are
/// better wrapped (e.g. pink marble 0.65 wrapped, 0.81-0.85 not).
pub fn detect_tileable(ex: &Exemplar) -> bool {
    // An inconsistent hand-built exemplar is not tileable (analyze reports why).
    ex.check().is_ok() && detect_tileable_checked(ex)
}

/// [`detect_tileable`] of an exemplar already checked (by [`analyze`]).
fn detect_tileable_checked(ex: &Exemplar) -> bool {
    let (w, h, c) = (ex.width as usize, ex.height as usize, ex.channels as usize);
    let px = |x: usize, y: usize| &ex.values[(y * w + x) * c..(y * w + x + 1) * c];
    let d2 = |a: &[f32], b: &[f32]| {
        a.iter()
            .zip(b)
            .map(|(x, y)| ((x - y) * (x - y)) as f64)
            .sum::<f64>()
    };
    let (mut interior, mut ni) = (0.0, 0usize);
    for y in 0..h {
        for x in 0..w - 1 {
            interior += d2(px(x, y), px(x + 1, y));
            ni += 1;
        }
    }
    for y in 0..h - 1 {
        for x in 0..w {
            interior += d2(px(x, y), px(x, y + 1));
            ni += 1;
        }
    }
    let (mut seam, mut ns) = (0.0, 0usize);
    for y in 0..h {
        seam += d2(px(w - 1, y), px(0, y));
        ns += 1;
    }
    for x in 0..w {
        seam += d2(px(x, h - 1), px(x, 0));
        ns += 1;
    }
    let interior = interior / ni as f64;
    let seam = seam / ns as f64;
    seam <= 1.25 * interior + 1e-9
}

/// Progress of a running analysis, for display.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Progress {
    /// Levels finished so far, `0..=total`.
    pub done: u32,
    /// Levels in all (`L + 1`, level 0 included).
    pub total: u32,
    /// What is being computed now (for level `done`, counting from 0 = coarsest);
    /// [`Stage::LevelDone`] right after a level is finished.
    pub stage: Stage,
    /// How far the stage has got, 0 to 1 (similarity sets report their steps; other
    /// stages report 0 when they start).
    pub fraction: f32,
}

/// A step of the analysis of one level, as [`Progress`] reports it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// The Gaussian stack of every level (before level 0).
    Stack,
    /// 5x5 appearance vectors and their PCA to 8D.
    Appearance,
    /// The runtime 4-diagonal neighbourhoods and their projection.
    Neighbourhoods,
    /// The k-coherence similarity sets (the longest step on large exemplars).
    SimilaritySets,
    /// The level is finished (`done` counts it).
    LevelDone,
}

impl Stage {
    /// A short name for progress lines.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Stack => "Gaussian stack",
            Stage::Appearance => "appearance vectors",
            Stage::Neighbourhoods => "runtime neighbourhoods",
            Stage::SimilaritySets => "similarity sets",
            Stage::LevelDone => "done",
        }
    }
}

/// Analyses an exemplar. `progress` is called when each stage of a level starts, during
/// the similarity-set search and after each level (a few seconds apart at most for
/// exemplars of a few megapixels).
pub fn analyze(
    ex: &Exemplar,
    opts: &AnalysisOptions,
    mut progress: impl FnMut(Progress),
) -> Result<Analysis> {
    ex.check()?;
    if opts.k == 0 || opts.k > MAX_K {
        return Err(Error::InvalidParameter(format!(
            "k = {}: the similarity-set size must be between 1 and {MAX_K}",
            opts.k
        )));
    }
    if ex.width > i16::MAX as u32 || ex.height > i16::MAX as u32 {
        return Err(Error::InvalidParameter(format!(
            "exemplar {}x{} is larger than texsyn supports (32767 pixels a side); downsample it",
            ex.width, ex.height
        )));
    }
    // Members must lie at least the radius away (Chebyshev): at half the exemplar's
    // larger side, no pixel has any.
    let half = ex.width.max(ex.height) / 2;
    if opts.k > 1 && opts.exclusion_radius >= half {
        return Err(Error::InvalidParameter(format!(
            "exclusion radius {} leaves no similarity-set members on a {}x{} exemplar: \
             use less than {half} (default 4)",
            opts.exclusion_radius, ex.width, ex.height
        )));
    }
    check_analysis_memory(ex.width, ex.height, available_memory())?;
    let feature_weight = opts
        .feature_weight
        .unwrap_or_else(|| feature::default_weight(opts.feature_mode));
    feature::check_weight(feature_weight)?;
    feature::check_clamp(opts.feature_clamp)?;
    if let Some(mask) = &opts.feature_mask {
        mask.check_size(ex.width, ex.height)?;
    }
    let threads = opts.threads;
    let tileable = opts.tileable.unwrap_or_else(|| detect_tileable_checked(ex));
    let top = level_count(ex.width, ex.height);
    // The feature channel, if any, is appended to the colours so that the stack blurs it
    // and the appearance vectors gather it like a colour.
    let plane = match &opts.feature_mask {
        None => colour_plane(ex),
        Some(mask) => with_feature_channel(ex, mask, feature_weight, opts.feature_clamp, tileable),
    };
    // The synthesis's tables: with `Sets`, from the colours alone; with `Both`, from the
    // colours and the channel at a share of the weight; with `Appearance` (or no mask),
    // from `plane`, as the similarity sets.
    let colour_plane = opts
        .feature_mask
        .as_ref()
        .and_then(|mask| match opts.feature_mode {
            FeatureMode::Sets => Some(colour_plane(ex)),
            FeatureMode::Both => Some(with_feature_channel(
                ex,
                mask,
                feature_weight * feature::BOTH_APPEARANCE_SHARE,
                opts.feature_clamp,
                tileable,
            )),
            FeatureMode::Appearance => None,
        });
    let profile = std::env::var_os("TEXSYN_PROFILE").is_some();
    let total = top + 1;
    let mut report = |done: u32, stage: Stage, fraction: f32| {
        progress(Progress {
            done,
            total,
            stage,
            fraction,
        })
    };
    report(0, Stage::Stack, 0.0);
    let t_stack = std::time::Instant::now();
    let stack = stack::gaussian_stack(plane, top, tileable, threads);
    let colour_stack = colour_plane.map(|p| stack::gaussian_stack(p, top, tileable, threads));
    if profile {
        eprintln!("stack {:?}", t_stack.elapsed());
    }
    let mut levels: Vec<LevelData> = Vec::with_capacity(stack.len());
    for (l, plane) in stack.iter().enumerate() {
        let spacing = 1u32 << (top - l as u32);
        let margin = level_margin(ex.width, ex.height, spacing, tileable);
        let done = l as u32;
        // Left out where no synthesis reads them (see LevelData::et): level 0, and the
        // finest level without its sets. An unsearched level needs no features either.
        let searched = |spacing: u32| level_searched(ex.width, ex.height, spacing);
        let tables = !(l == 0 || spacing == 1 && !opts.finest_sets);
        let large = ex.width as u64 * ex.height as u64 >= LARGE_EXEMPLAR_PIXELS;
        let t0 = std::time::Instant::now();
        let (mut t1, mut run, mut et_float) = (t0, None, Vec::new());
        if tables || searched(spacing) {
            report(done, Stage::Appearance, 0.0);
            let (et, residual) = appearance::transformed_exemplar(
                plane,
                spacing,
                tileable,
                opts.appearance,
                threads,
            );
            t1 = std::time::Instant::now();
            report(done, Stage::Neighbourhoods, 0.0);
            // Where the 5x5 neighbourhood (4 h_l wide) spans the whole exemplar, the level
            // is a near-constant blur and similarity sets are noise: `searched` is false,
            // the search is skipped and zero offsets stored (those candidates are then the
            // coherent ones). Saves a quarter of the analysis time of a 128x128 exemplar.
            //
            // Large exemplars (256x256 pixels and more) search their sets in Et alone (8D,
            // the 5x5 neighbourhood) with less effort (`SimilarityQuery::light`): much
            // less CPU time for the same texture energy and verbatim figures; smaller
            // exemplars keep the 16D features (Et and the projected runtime
            // neighbourhood) and the full effort, which cost them little.
            let q = appearance::quantize_level(
                &et,
                ex.width,
                ex.height,
                spacing,
                tileable,
                threads,
                searched(spacing) && !large,
            );
            // The tables the synthesis reads: these, or the colours' alone
            // (FeatureMode::Sets; the similarity sets below are still searched with the
            // feature channel).
            run = Some(match &colour_stack {
                Some(cs) => {
                    let (et_c, r_c) = appearance::transformed_exemplar(
                        &cs[l],
                        spacing,
                        tileable,
                        opts.appearance,
                        threads,
                    );
                    let q_c = appearance::quantize_level(
                        &et_c, ex.width, ex.height, spacing, tileable, threads, false,
                    );
                    (q, Some(q_c), r_c)
                }
                None => (q, None, residual),
            });
            et_float = et;
        }
        let t2 = std::time::Instant::now();
        let exclusion = opts
            .exclusion_radius
            .max(spacing)
            .min(ex.width.min(ex.height) / 4);
        // Left out on request (`finest_sets`): an empty table, not zero offsets, so that
        // a synthesis that would read it can tell and refuse.
        let offsets = if spacing == 1 && !opts.finest_sets {
            Vec::new()
        } else if searched(spacing) {
            report(done, Stage::SimilaritySets, 0.0);
            kcoherence::similarity_offsets(
                &kcoherence::SimilarityQuery {
                    features: if large {
                        et_float.as_flattened()
                    } else {
                        &run.as_ref()
                            .expect("a searched level has its features")
                            .0
                            .features
                    },
                    dim: if large { DIM } else { appearance::FEATURE_DIM },
                    width: ex.width,
                    height: ex.height,
                    tileable,
                    margin,
                    exclusion_radius: exclusion,
                    k: opts.k,
                    spacing,
                    // The coarser level's sets seed the search.
                    init: levels
                        .last()
                        .filter(|l| searched(l.spacing))
                        .map(|l| &l.offsets[..]),
                    light: large,
                },
                threads,
                &mut |f| report(done, Stage::SimilaritySets, f),
            )
        } else {
            vec![[0i16; 2]; (ex.width * ex.height * opts.k.saturating_sub(1)) as usize]
        };
        if profile {
            eprintln!(
                "level {l}: appearance {:?} runtime {:?} kcoherence {:?}",
                t1 - t0,
                t2 - t1,
                t2.elapsed()
            );
        }
        let level = match run {
            Some((q, q_colour, residual)) if tables => {
                let run = q_colour.unwrap_or(q);
                LevelData {
                    spacing,
                    margin,
                    et: run.et.into(),
                    proj: run.proj,
                    qe: run.qe.into(),
                    shift: run.shift,
                    offsets: offsets.into(),
                    residual_variance: residual as f32,
                    runtime_residual_variance: run.runtime_residual as f32,
                }
            }
            // No tables: nothing to report either (0, shown as "-"; not NaN, so that
            // analyses still compare equal to themselves).
            _ => LevelData {
                spacing,
                margin,
                et: Table::new(),
                proj: [[0; 4 * DIM]; DIM],
                qe: Table::new(),
                shift: 0,
                offsets: offsets.into(),
                residual_variance: 0.0,
                runtime_residual_variance: 0.0,
            },
        };
        levels.push(level);
        report(done + 1, Stage::LevelDone, 1.0);
    }
    Ok(Analysis {
        width: ex.width,
        height: ex.height,
        channels: ex.channels,
        tileable,
        k: opts.k,
        colors: ex.colors.clone(),
        levels,
        appearance: opts.appearance,
        feature: opts.feature_mask.as_ref().map(|m| FeatureInfo {
            weight: feature_weight,
            clamp: opts.feature_clamp,
            coverage: m.coverage() as f32,
            mode: opts.feature_mode,
        }),
    })
}
