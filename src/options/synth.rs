//! The user-facing synthesis parameters and their defaults.

use std::sync::Arc;

use super::AtlasDomain;
use crate::field::Field;

/// User-facing synthesis parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct SynthParams {
    /// Output width in pixels.
    pub width: u32,
    /// Output height in pixels.
    pub height: u32,
    /// Absolute position of the output window in the infinite texture.
    pub origin: [i32; 2],
    /// Seed of the jitter hash: different seeds give different textures.
    pub seed: u32,
    /// Per-level jitter randomness `r_l` (fraction of `h_l`), index = level. Missing
    /// levels use the last value; an empty list uses
    /// [`default_randomness`](crate::passes::plan::default_randomness).
    pub randomness: Vec<f32>,
    /// Levels added to the default schedule's still (unjittered) finest ones, 0..=4;
    /// ignored when `randomness` is given. Larger patches, lower texture energy, larger
    /// verbatim copies; [`crate::gpu::synth::GpuSynthesizer::choose_schedule`] picks it
    /// within a copy budget. Default 0.
    pub extra_still_levels: u32,
    /// Correction passes (each = 4 subpasses) at every level but the finest (the
    /// second-finest level may get fewer, [`Self::second_finest_passes`]; levels without
    /// similarity sets of their own at most [`UNSEARCHED_PASSES`](crate::passes::plan::UNSEARCHED_PASSES)).
    pub passes: u32,
    /// Correction passes at the second-finest level, the costliest corrected one (a
    /// quarter of the output's pixels). `None` (default):
    /// [`default_second_finest_passes`](crate::passes::plan::default_second_finest_passes).
    pub second_finest_passes: Option<u32>,
    /// Correction passes at the finest level (3/4 of all pixels). Default 0: the finest
    /// level is the coherent upsampling of the next coarser one, which is cheaper and
    /// measured as good.
    pub finest_passes: u32,
    /// Score the similarity-set candidates (`k - 1` per 3x3 neighbour) on every
    /// `sets_every`-th correction pass of a level (passes 1, 1 + n, ...); the other passes
    /// score the coherent candidates only. 1..=16; default 1, as in the paper.
    pub sets_every: u32,
    /// Bias towards coherent candidates: the others' distance is multiplied by
    /// `1 + coherence` (0 to 4).
    pub coherence: f32,
    /// Which neighbourhood distance the correction uses.
    pub distance: DistanceMode,
    /// Jacobian field for anisometric synthesis (Lefebvre & Hoppe 2006 §5); `None` is
    /// isometric. With a field, coordinates are continuous (1/256 exemplar pixel).
    pub field: Option<Field>,
    /// Synthesize one period of a seamlessly tiling texture (`width` x `height`): every
    /// level is a torus, neighbours wrap around, and the window origin must be 0. Sides
    /// that are not multiples of 4 are made on a torus whose sides are
    /// ([`Torus`](crate::passes::plan::Torus)).
    pub tileable_output: bool,
    /// Atlas synthesis (surface texture, Lefebvre & Hoppe 2006 §6): the output is the
    /// whole atlas, the Jacobians come from the domain, texels outside charts are not
    /// corrected and the gutters are refilled after every pass. Excludes `field`, windows
    /// and `tileable_output`.
    pub surface: Option<Arc<AtlasDomain>>,
    /// Blend, at patch seams, the colours that the 4 neighbours' coordinates predict
    /// (`true`, default; lowers the texture energy), or copy the exemplar at each
    /// coordinate. Material maps, magnified output and advection frames are not blended.
    pub seam_blend: bool,
    /// A texture of its own rather than a window of the unbounded texture: each level
    /// computes [`STANDALONE_MARGIN`] pixels beyond what the finer level reads instead of
    /// the `4 * passes` that make the result independent of the window. Cheaper, equally
    /// good, but windows no longer fit together. Ignored by atlases, tileable outputs and
    /// advection. Default `false`.
    pub standalone: bool,
}

/// Pixels each level of a [`SynthParams::standalone`] synthesis computes beyond what the
/// next finer level reads (the finest level adds one for the gather's seam blending):
/// the neighbourhoods of the region's edge pixels read about two pixels out. Levels
/// whose region the finer level reads is under [`STANDALONE_MIN_REGION`] pixels on a side
/// keep the full margin.
pub const STANDALONE_MARGIN: i32 = 2;

/// The smallest region (shorter side, level pixels) that a standalone level computes
/// with the thin margin: on the coarsest levels a few pixels are a large share of the
/// output, and clamped reads at their edges move its large-scale layout.
pub const STANDALONE_MIN_REGION: i32 = 32;

impl SynthParams {
    /// Whether the anisometric passes run (continuous coordinates, per-pixel J).
    pub fn anisometric(&self) -> bool {
        self.field.is_some() || self.surface.is_some()
    }

    /// Whether the desired Jacobian is the same everywhere: no atlas, and no field or a
    /// constant one. Advection keeps a texture's look under turning flows only there
    /// ([`AdvectOptions::recommended`](crate::passes::advect::AdvectOptions::recommended)).
    pub fn constant_jacobian(&self) -> bool {
        self.surface.is_none() && matches!(self.field, None | Some(Field::Constant { .. }))
    }
}

/// Neighbourhood distance of the correction ([`crate::passes::correct`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DistanceMode {
    /// The paper's 8D projection of the 32D neighbourhood at every level.
    Projected,
    /// The full 32D neighbourhood at every level (slower at the finest level).
    Full,
    /// Full on the coarser levels, projected on the finest: lower texture energy than
    /// `Projected` at little cost, since the coarse levels are small.
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
