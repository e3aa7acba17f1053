//! Host-side exemplar analysis (paper sections 3-4): Gaussian stack, 5x5 appearance
//! vectors reduced to 8D by PCA, the 4-diagonal runtime neighbourhoods and their 8D
//! projection, and k-coherence similarity sets. Everything the GPU needs is quantized to
//! integers here so that the GPU passes and their CPU mirrors compute identical bytes.

pub mod appearance;
pub mod file;
pub mod kcoherence;
pub mod kdtree;
pub mod pca;
pub mod stack;

use crate::error::{Error, Result};

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
/// 8 squared differences (clamped to 2*QE_MAX) fit in a u32.
pub const QE_MAX: i32 = 8191;
/// Largest k supported by the GPU passes.
pub const MAX_K: u32 = 8;

/// The exemplar as loaded: RGBA8 colours (what synthesis outputs) and the float
/// channels the analysis runs on (1 for grey exemplars, 3 for colour; alpha is ignored).
#[derive(Clone, Debug, PartialEq)]
pub struct Exemplar {
    pub width: u32,
    pub height: u32,
    /// 1 (grey) or 3 (RGB).
    pub channels: u32,
    /// Row-major, `channels` floats per pixel in [0, 1].
    pub values: Vec<f32>,
    /// Row-major RGBA8 (grey is replicated into RGB; alpha is 255).
    pub colors: Vec<[u8; 4]>,
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
}

impl Default for AnalysisOptions {
    fn default() -> Self {
        Self { k: 2, tileable: None, exclusion_radius: 4, threads: 0 }
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
    /// Quantized 8D transformed exemplar `Et_l`, row-major `width*height`.
    pub et: Vec<[i16; DIM]>,
    /// Quantized runtime projection `P_l` (8 rows x 32 columns; column `4*0..` is the
    /// block of diagonal `j` in `DIAGONALS` order: column = j*8 + c).
    pub proj: [[i16; 4 * DIM]; DIM],
    /// `3 * P_l * N_E(u)` computed in integers from `et` and `proj`, then arithmetically
    /// shifted right by `shift`: the exemplar side of the correction distance.
    pub qe: Vec<[i16; DIM]>,
    pub shift: u32,
    /// k-coherence offsets `O_i(u) = C_i(u) - u` for i = 2..k: `(k-1)` pairs per pixel.
    pub offsets: Vec<[i16; 2]>,
    /// Fraction of the appearance-vector variance not kept by the 8D PCA.
    pub residual_variance: f32,
    /// Same for the 32D -> 8D runtime neighbourhood projection.
    pub runtime_residual_variance: f32,
}

/// The result of analysing an exemplar: everything synthesis needs. Save it with
/// [`Analysis::save`] and load it with [`Analysis::load`] to skip the analysis.
#[derive(Clone, Debug, PartialEq)]
pub struct Analysis {
    pub width: u32,
    pub height: u32,
    pub channels: u32,
    pub tileable: bool,
    pub k: u32,
    /// RGBA8 exemplar colours (the finest stack level, i.e. the exemplar itself).
    pub colors: Vec<[u8; 4]>,
    /// Levels `0..=L`, `levels[l].spacing == 2^(L-l)`.
    pub levels: Vec<LevelData>,
}

/// The four diagonals of the runtime neighbourhood, in the order used everywhere.
pub const DIAGONALS: [[i32; 2]; 4] = [[1, 1], [1, -1], [-1, 1], [-1, -1]];

/// Number of levels beyond the coarsest: `L = ceil(log2(max(w, h)))`.
pub fn level_count(width: u32, height: u32) -> u32 {
    let m = width.max(height).max(1);
    32 - (m - 1).leading_zeros()
}

/// Validity margin of level `l` for non-tileable exemplars: the 5x5 neighbourhood
/// (radius `2 h_l`), capped at a quarter of the smaller side so a valid region exists.
pub fn level_margin(width: u32, height: u32, spacing: u32, tileable: bool) -> u32 {
    if tileable {
        0
    } else {
        (2 * spacing).min(width.min(height) / 4)
    }
}

pub fn check_exemplar_size(width: u32, height: u32) -> Result<()> {
    if width < MIN_EXEMPLAR_SIZE || height < MIN_EXEMPLAR_SIZE {
        return Err(Error::ExemplarTooSmall { width, height, min: MIN_EXEMPLAR_SIZE });
    }
    Ok(())
}
