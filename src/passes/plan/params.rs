//! The user-facing synthesis parameters and their defaults.

use std::sync::Arc;

use crate::field::Field;
use crate::passes::fill::AtlasDomain;

/// User-facing synthesis parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct SynthParams {
    /// Output size in pixels.
    pub width: u32,
    pub height: u32,
    /// Absolute position of the output window in the infinite texture.
    pub origin: [i32; 2],
    pub seed: u32,
    /// Per-level jitter randomness `r_l` (fraction of `h_l`), index = level. Missing
    /// levels use the last value; an empty list uses [`default_randomness`].
    pub randomness: Vec<f32>,
    /// Levels added to the default schedule's still (unjittered) finest ones, 0..=4;
    /// ignored when `randomness` is given. Larger patches, lower texture energy, larger
    /// verbatim copies: [`crate::gpu::synth::GpuSynthesizer::choose_schedule`] sets it to
    /// 1 or 2 where a probe synthesis stays within a copy budget (the CLI's and
    /// [`crate::Session`]'s default). Default 0.
    pub extra_still_levels: u32,
    /// Correction passes (each = 4 subpasses) at every level but the finest (the
    /// second-finest level may get fewer: [`Self::second_finest_passes`]; levels without
    /// similarity sets of their own at most [`UNSEARCHED_PASSES`]).
    pub passes: u32,
    /// Correction passes at the second-finest level; `None` (default): `passes`, but at
    /// most [`LARGE_SECOND_FINEST_PASSES`] in an isometric synthesis (no field, no atlas)
    /// from an exemplar of [`crate::analysis::LARGE_EXEMPLAR_PIXELS`] or more. That level
    /// is the costliest corrected one (a quarter of the output's pixels). Measured at
    /// 512x512 on lavapipe with a 512 px exemplar: about 22% less GPU time, 0.81-0.88 of
    /// the time of a whole `synth` from an analysis file; texture energy +2.0 / +0.3 /
    /// +0.0% (full / half / quarter resolution, medians over 14 photos of 256-512 px x 2
    /// seeds). Below that size at most [`SMALL_SECOND_FINEST_PASSES`] (3: two passes
    /// there cost +4.6 / +0.9 / 0.0% over 13 exemplars of 64-156 px, three +0.9 / +0.2 /
    /// 0.0%), also along a field, but not on surfaces or with a feature channel.
    pub second_finest_passes: Option<u32>,
    /// Correction passes at the finest level (3/4 of all pixels, so the costly one).
    /// Default 0: the finest level is the coherent upsampling of the next coarser one
    /// (no jitter there, so children continue their parents exactly). Measured on 14
    /// exemplars at 512x512 against one pass there (README, *Measured figures*, with the
    /// seam blending at a third of the pixel's weight that came with it): texture energy
    /// -0.4% to +3% at full resolution (median +1.6%) and within 1% at half and quarter
    /// resolution, Jacobian fidelity up to 9 points higher, about 30% less time.
    pub finest_passes: u32,
    /// The similarity-set candidates (`k - 1` per 3x3 neighbour) are scored on every
    /// `sets_every`-th correction pass of a level (its passes 1, 1 + n, ...); the other
    /// passes score the coherent candidates only. 1..=16; default 1, the paper (every
    /// pass). 2 measured (12 exemplars x 2 seeds at 512x512, lavapipe): texture energy and
    /// colour-histogram distance within 0.3% of every pass (medians; the bundled brick
    /// +2-3%), about a fifth less GPU time for an isometric synthesis (the set candidates
    /// are most of the correction's work: the coherent ones mostly repeat the current
    /// value and are skipped). Not the default: an anisometric synthesis builds a second
    /// correction pipeline for it, which takes back most of its gain from an analysis
    /// file, and an advection frame, which gains less, would cost more than half of the
    /// cheaper synthesis (README, nineteenth session).
    pub sets_every: u32,
    /// Bias towards coherent candidates: the others' distance is multiplied by
    /// `1 + coherence` (0 to 4).
    pub coherence: f32,
    /// Which neighbourhood distance the correction uses.
    pub distance: DistanceMode,
    /// Jacobian field for anisometric synthesis (paper section 5); `None` is isometric.
    /// With a field, coordinates are continuous (1/256 exemplar pixel) and the
    /// anisometric passes run.
    pub field: Option<Field>,
    /// Synthesize one period of a texture that tiles seamlessly (`width` x `height`):
    /// every level is a torus (period `ceil(size / 2^steps)`), neighbours wrap around.
    /// The window origin must be 0. Sides that are not multiples of 4 (from
    /// [`TORUS_MIN_SIDE`] up) are synthesized on a torus whose sides are, then resampled
    /// to the output's size ([`Torus`]): an odd period at the finest or second-finest
    /// level cannot be upsampled coherently across the wrap, and left a faint seam there.
    pub tileable_output: bool,
    /// Atlas synthesis (surface texture, paper section 6): the output is the whole
    /// atlas (`width` x `height` = the domain's finest level), the Jacobians come from
    /// the domain, texels outside charts are not corrected and the gutters are refilled
    /// through the indirection maps after every pass. Excludes `field`, windows and
    /// `tileable_output`.
    pub surface: Option<Arc<AtlasDomain>>,
    /// Output colours: blend, at patch seams, the colours that the 4 neighbours'
    /// coordinates predict (`true`, default), or copy the exemplar at each coordinate
    /// (`false`). Measured to lower the full-resolution texture energy by 10-18%;
    /// coherent pixels are copies either way (see `passes/gather.rs`). Material maps
    /// (`--also`), magnified output and advection frames are not blended.
    pub seam_blend: bool,
    /// A texture of its own rather than a window of the unbounded texture: each level
    /// computes [`STANDALONE_MARGIN`] pixels beyond what the next finer level reads,
    /// instead of the `4 * passes` that make the result independent of the window.
    /// The pixels near the output's edges then see clamped reads a few pixels out, so
    /// the output is not the window `origin`, `width` x `height` of the unbounded texture
    /// and windows do not fit together; the texture itself is as good (12 exemplars x 2
    /// seeds at 512x512: texture energy and histogram distance within 0.3% of the exact
    /// window's, medians, each within 6%). The margins are most of the coarse levels, so
    /// this saves most at small outputs: GPU time about 20% less at 512x512 and 23% at
    /// 256x256 (lavapipe, README). Default `false`: every output stays a window.
    /// Ignored by atlas synthesis and tileable outputs, which have no margins; advection
    /// keeps the full margins, which the flow carries into view.
    pub standalone: bool,
}

/// Pixels each level of a [`SynthParams::standalone`] synthesis computes beyond what the
/// next finer level reads (the finest level adds one for the gather's seam blending):
/// the neighbourhoods of the region's edge pixels read about two pixels out. Levels
/// whose region the finer level reads is under [`STANDALONE_MIN_REGION`] pixels on a side
/// keep the full margin.
pub const STANDALONE_MARGIN: i32 = 2;

/// The smallest region (shorter side, level pixels) that a standalone level computes
/// with the thin margin. On the coarsest levels a few pixels are a large share of the
/// output, and clamped reads at their edges moved its large-scale layout: with the thin
/// margin everywhere the colour-histogram distance of pink_marble rose 1.6x (512x512,
/// seeds 1-2); from 32 pixels up it matched the exact window's within 2% (seeds 1-3),
/// and those levels cost little (their dispatches are mostly fixed overhead).
pub const STANDALONE_MIN_REGION: i32 = 32;

impl SynthParams {
    /// Whether the anisometric passes run (continuous coordinates, per-pixel J).
    pub fn anisometric(&self) -> bool {
        self.field.is_some() || self.surface.is_some()
    }

    /// Whether the desired Jacobian is the same everywhere: no atlas, and no field or a
    /// constant one. Advection keeps a texture's look under turning flows only there
    /// ([`AdvectOptions::recommended`]).
    pub fn constant_jacobian(&self) -> bool {
        self.surface.is_none() && matches!(self.field, None | Some(Field::Constant { .. }))
    }
}

/// Neighbourhood distance of the correction (see `passes/correct.rs`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DistanceMode {
    /// The paper's 8D projection of the 32D neighbourhood at every level.
    Projected,
    /// The full 32D neighbourhood at every level (slower at the finest level).
    Full,
    /// Full on the coarser levels, projected on the finest: measured lower texture
    /// energy than `Projected` at little cost, since the coarse levels are small.
    #[default]
    Mixed,
}

impl Default for SynthParams {
    fn default() -> Self {
        Self {
            width: 256,
            height: 256,
            origin: [0, 0],
            seed: 1,
            randomness: Vec::new(),
            extra_still_levels: 0,
            passes: 4,
            second_finest_passes: None,
            finest_passes: 0,
            sets_every: 1,
            coherence: 1.0,
            distance: DistanceMode::Mixed,
            field: None,
            tileable_output: false,
            surface: None,
            seam_blend: true,
            standalone: false,
        }
    }
}
