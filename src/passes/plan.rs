//! The synthesis plan: which region of the infinite synthesis pyramid each level
//! computes, and the per-dispatch parameters. GPU and CPU both execute this plan.
//!
//! The output is a window of an unbounded texture: level `l` computes an absolute region
//! that covers everything the finer level reads, plus a margin of `4 * passes` pixels
//! (`4 * finest_passes + 1` at the finest level, whose gather reads the 4-neighbours).
//! A correction pass of 4 subpasses propagates information at most 4 pixels, so pixels
//! that far from the region edge never see the clamped reads at the edge: the result is
//! independent of the window, and overlapping windows agree.

use std::sync::Arc;

use super::common::{PassParams, COORD_FRAC};
use super::fill::{AtlasDomain, SurfaceLayout, FILL_ROW};
use crate::analysis::Analysis;
use crate::error::{Error, Result};
use crate::field::{self, Field};

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
    /// ([`super::advect::AdvectOptions::recommended`]).
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

/// Default per-level randomness: a whole pixel at the coarse levels, so features are
/// rearranged rather than the exemplar's layout reproduced, none at the finest levels
/// so exemplar detail stays intact (measured: fine-level jitter raises the texture
/// energy more than it adds variety). How far down the jitter reaches depends on the
/// exemplar size, because the same coherent patch covers more of a small exemplar:
/// measured largest verbatim region (3-4 seeds, 512x512 output) 0.25-0.35 of a 96 px
/// exemplar and 0.25-0.28 of a 64 px one with the 128 px schedule; 0.17-0.26 and
/// 0.19-0.27 with the schedules below.
/// - min side 128..176: 0 on the three finest levels, 0.75 on the fourth, 1 above (0.5 on
///   the fourth let the largest verbatim region reach 0.30-0.34 of a 128 px exemplar on
///   2 of 5 seeds; 0.75 kept it at 0.15-0.28 for +0-4% texture energy (pink marble,
///   energy x 1e3, mean of 5 seeds: 0.177 -> 0.183), where jitter one level further
///   down costs +17-24%);
/// - 80..128: 0 on the two finest, 0.5 on the third, 1 above;
/// - under 80: 0 on the finest, 1 above.
///
/// Larger exemplars jitter less. With the 128 px schedule the patches keep their size in
/// pixels, so they shrink against a larger exemplar and the seams multiply. Measured on
/// photos resized to each size (three CC0 photos, and the 168-400 px samples of the
/// `texture-synthesis` repository, not shipped), 512x512 outputs, seeds 1-3,
/// full-resolution texture energy over `texture-synthesis`'s (median), 128 px schedule
/// -> the ones below: 176 px 1.01 -> 0.93, 256 px 1.24 -> 1.14, 384 px 1.94 -> 1.27,
/// 512 px 4.2 -> 2.45 (there `texture-synthesis` copies 28-39% of the exemplar
/// verbatim). The largest verbatim region stayed at most 0.145 (176-287 px), 0.145
/// (288-447 px, a brick wall included) and 0.177 (448-512 px) of the exemplar. One
/// still level more than below reached 0.26-0.29 at 176-256 px and 0.21-0.48 on a 350
/// px brick wall (regular textures tip over into copying first):
/// - 176..288: 0 on the three finest levels, 0.25 on the fourth, 1 above;
/// - 288..448: 0 on the four finest, 0.25 on the fifth, 1 above;
/// - 448 and up: 0 on the five finest, 0.75 on the sixth, 1 above.
///
/// `extra_still` levels more are still (the partly jittered level moves up with them):
/// what [`SynthParams::extra_still_levels`] asks for.
pub fn default_randomness(
    level: u32,
    finest: u32,
    exemplar_min_side: u32,
    extra_still: u32,
) -> f32 {
    let from_finest = finest.saturating_sub(level);
    let (still, partial) = match exemplar_min_side {
        0..80 => (1, None),
        80..128 => (2, Some((2, 0.5))),
        128..176 => (3, Some((3, 0.75))),
        176..288 => (3, Some((3, 0.25))),
        288..448 => (4, Some((4, 0.25))),
        _ => (5, Some((5, 0.75))),
    };
    let still = still + extra_still;
    let partial = partial.map(|(l, r)| (l + extra_still, r));
    match partial {
        _ if from_finest < still => 0.0,
        Some((l, r)) if l == from_finest => r,
        _ => 1.0,
    }
}

/// One level of the plan.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelPlan {
    pub level: u32,
    pub spacing: u32,
    /// Absolute origin and size of the region computed at this level.
    pub origin: [i32; 2],
    pub size: [u32; 2],
    /// Offset of this level's coordinates in the concatenated coordinate array.
    pub coord_base: u32,
    pub randomness: f32,
    /// Pixels on each side of the region beyond what the finer level reads (0 for
    /// atlases, periodic outputs and level 0).
    pub margin: u32,
}

#[derive(Clone, Debug, PartialEq)]
pub struct SynthPlan {
    pub levels: Vec<LevelPlan>,
    pub params: SynthParams,
    /// Where the output window lies in the finest level's region.
    pub window_offset: [u32; 2],
    /// Total coordinates over all levels.
    pub coord_count: u64,
    /// Atlas synthesis: each level's mask and indirection entries in the surface buffer.
    pub surface_layout: Vec<SurfaceLayout>,
    /// A tileable output whose sides are not all multiples of 4 is synthesized on a
    /// torus whose sides are, then resampled to the output's size ([`Torus`]).
    pub torus: Option<Torus>,
}

/// How a [`SynthParams::tileable_output`] whose sides are not multiples of 4 is made.
/// Each level's period is half the finer one's, rounded up, and an odd period at the
/// finest or second-finest level cannot be upsampled coherently across the wrap (the
/// children of an odd number of parents are one more than the period): the texture
/// jumped by a pixel there, a faint seam where the tiles meet (wrap-seam ratio 1.55-1.75
/// at 65 and 129, leopard, seeds 1-3). So the levels are synthesized on a torus of
/// `period` (each side the nearest multiple of 4, [`torus_period`]) along the field
/// scaled by `output / period` on each axis, and a resampling pass (`resample.wgsl`)
/// maps it onto the `output` grid: output pixel `x` takes the torus coordinate nearest to
/// `u = (x + 0.5) period / output - 0.5` plus `J' (u - q)`, so that the texture advances
/// exactly as the field asks per output pixel and the period is the output's. The
/// coordinates are continuous (an anisometric plan, the identity field where none is
/// given, with an isometric synthesis's passes); along no field the resampled ones are
/// rounded to whole texels and the gather reads those, so coherent patches are exact
/// copies of the exemplar, as in isometric synthesis (and the copy guard measures them).
/// `GpuSynthesizer::plan_for` falls back to the output's own periods where the torus
/// does not fit the device.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Torus {
    /// Sides of the synthesized torus (multiples of 4).
    pub period: [u32; 2],
    /// Sides of the output (`SynthParams::width`, `height`).
    pub output: [u32; 2],
    /// Where the output's resampled coordinates start in the coordinate array (after
    /// every level's).
    pub base: u32,
    /// The caller asked for isometric synthesis (no field): the gather reads the
    /// nearest texel.
    pub isometric: bool,
}

/// Outputs of at least this many pixels a side that are not multiples of 4 are made on a
/// torus ([`Torus`]); smaller ones would change the synthesized scale by more than 3/8.
pub const TORUS_MIN_SIDE: u32 = 8;

/// The torus side a tileable output side `n` is synthesized on: `n` itself if it is a
/// multiple of 4 (or under [`TORUS_MIN_SIDE`]), else the nearest multiple of 4 (the
/// larger of two equally near ones).
pub fn torus_period(n: u32) -> u32 {
    if n.is_multiple_of(4) || n < TORUS_MIN_SIDE {
        n
    } else {
        (n + 2) / 4 * 4
    }
}

fn floor_div2(x: i32) -> i32 {
    x >> 1
}

impl SynthPlan {
    /// The plan of a synthesis ([`Self::with_torus`] with the torus allowed).
    pub fn new(analysis: &Analysis, params: &SynthParams) -> Result<Self> {
        Self::with_torus(analysis, params, true)
    }

    /// The plan; with `allow_torus`, a tileable output whose sides are not multiples of 4
    /// is made on a torus and resampled ([`Torus`]). Advection keeps every level at the
    /// output's own periods (its frames move the levels themselves).
    pub fn with_torus(
        analysis: &Analysis,
        params: &SynthParams,
        allow_torus: bool,
    ) -> Result<Self> {
        if params.width == 0 || params.height == 0 {
            return Err(Error::InvalidParameter(format!(
                "output size {}x{}: width and height must be at least 1",
                params.width, params.height
            )));
        }
        let second = params.second_finest_passes.unwrap_or(0);
        if params.passes > 16 || params.finest_passes > 16 || second > 16 {
            return Err(Error::InvalidParameter(format!(
                "{}/{}/{} correction passes (coarser / second-finest / finest levels): at \
                 most 16 are supported",
                params.passes, second, params.finest_passes
            )));
        }
        let finest = analysis.levels.len().saturating_sub(1);
        if params.finest_passes > 0 && !(analysis.has_finest_sets() && analysis.has_tables(finest))
        {
            return Err(Error::InvalidParameter(format!(
                "{} correction pass(es) at the finest level need its similarity sets, which \
                 this analysis left out (AnalysisOptions::finest_sets = false): analyse the \
                 exemplar again with them, or keep finest_passes at 0",
                params.finest_passes
            )));
        }
        if !(1..=16).contains(&params.sets_every) {
            return Err(Error::InvalidParameter(format!(
                "similarity sets every {} passes: must be 1 to 16",
                params.sets_every
            )));
        }
        if !params.coherence.is_finite() || !(0.0..=4.0).contains(&params.coherence) {
            return Err(Error::InvalidParameter(format!(
                "coherence {} must be between 0 and 4",
                params.coherence
            )));
        }
        if let Some(f) = &params.field {
            f.validate()?;
            // h J d must fit the fixed-point arithmetic: h <= 2^13 (|J d| <= 2^14 / 1024).
            let h = analysis.levels.first().map_or(1, |l| l.spacing);
            if h > 1 << 13 {
                return Err(Error::InvalidParameter(format!(
                    "anisometric synthesis supports exemplars up to 8192 pixels a side \
                     (this one has {} levels)",
                    analysis.levels.len()
                )));
            }
        }
        if params.extra_still_levels > 4 {
            return Err(Error::InvalidParameter(format!(
                "{} extra still levels: at most 4",
                params.extra_still_levels
            )));
        }
        for &r in &params.randomness {
            if !r.is_finite() || !(0.0..=2.0).contains(&r) {
                return Err(Error::InvalidParameter(format!(
                    "randomness {r} must be between 0 and 2"
                )));
            }
        }
        // Absolute positions stay far from i32 overflow (the plan adds margins and the
        // coarser levels' regions; the hash takes them as 32-bit integers).
        const MAX_ABS: i64 = 1 << 28;
        let ends = [
            params.origin[0] as i64,
            params.origin[1] as i64,
            params.origin[0] as i64 + params.width as i64,
            params.origin[1] as i64 + params.height as i64,
        ];
        if ends.iter().any(|v| v.abs() > MAX_ABS) {
            return Err(Error::InvalidParameter(format!(
                "window {},{} of {}x{} leaves the supported texture area (+-{MAX_ABS} pixels)",
                params.origin[0], params.origin[1], params.width, params.height
            )));
        }
        let n_levels = analysis.levels.len() as u32;
        let last = n_levels - 1;
        // Each correction subpass moves information one pixel, so a level's margin is
        // 4 pixels per pass at that level; the finest level adds one for the gather's
        // seam blending, which reads the 4-neighbours of the output's edge pixels.
        // A standalone texture needs no independence from its window, only some context
        // for its edge pixels, except on the coarsest levels (`need`: the shorter side of
        // the region the finer level reads).
        let margin_at = |level: u32, need: i32| -> i32 {
            let mut m = 4 * passes_at(params, level, last, ExemplarShape::of(analysis)) as i32;
            if params.standalone && need >= STANDALONE_MIN_REGION {
                m = m.min(STANDALONE_MARGIN);
            }
            m + (level == last) as i32
        };
        // Walk from the finest level to the coarsest: `need` is the half-open absolute
        // region whose values must be exact; the computed region adds the margin.
        if params.tileable_output && params.origin != [0, 0] {
            return Err(Error::InvalidParameter(
                "a tileable output is one period of the texture: its window origin must be 0,0"
                    .into(),
            ));
        }
        let period = [torus_period(params.width), torus_period(params.height)];
        let torus = allow_torus
            && params.tileable_output
            && params.surface.is_none()
            && period != [params.width, params.height];
        // A torus is synthesized along a field (the identity if none is given), scaled in
        // `jacobians`: the plan's parameters say anisometric.
        let isometric = params.field.is_none();
        let params = &if torus && isometric {
            SynthParams {
                field: Some(Field::identity()),
                // The passes of an isometric synthesis (`passes_at` reads the field).
                second_finest_passes: Some(params.second_finest_passes.unwrap_or_else(|| {
                    default_second_finest_passes(
                        params.passes,
                        false,
                        false,
                        ExemplarShape::of(analysis),
                    )
                })),
                ..params.clone()
            }
        } else {
            params.clone()
        };
        let (w, h) = if torus {
            (period[0], period[1])
        } else {
            (params.width, params.height)
        };
        let (mut lo, mut hi) = (
            params.origin,
            [params.origin[0] + w as i32, params.origin[1] + h as i32],
        );
        if let Some(d) = &params.surface {
            if params.field.is_some() || params.tileable_output || params.origin != [0, 0] {
                return Err(Error::InvalidParameter(
                    "atlas synthesis takes its Jacobians from the atlas: no field, window \
                     origin or tileable output"
                        .into(),
                ));
            }
            if d.levels.len() < n_levels as usize
                || d.levels[0].size != [params.width, params.height]
            {
                return Err(Error::InvalidParameter(format!(
                    "the atlas domain has {} levels of a {:?} atlas; this synthesis needs {} \
                     levels of {}x{}",
                    d.levels.len(),
                    d.levels.first().map(|l| l.size),
                    n_levels,
                    params.width,
                    params.height
                )));
            }
        }
        let mut rev = Vec::with_capacity(n_levels as usize);
        for level in (0..n_levels).rev() {
            let mut margin = 0;
            let (rlo, rhi) = if let Some(d) = &params.surface {
                // The atlas at this level's resolution, no margin: outside is gutter.
                let sz = d.levels[(last - level) as usize].size;
                ([0, 0], [sz[0] as i32, sz[1] as i32])
            } else if params.tileable_output {
                // One period, no margin: neighbours wrap around instead.
                ([0, 0], [hi[0].max(1), hi[1].max(1)])
            } else if level == 0 {
                (lo, hi)
            } else {
                margin = margin_at(level, (hi[0] - lo[0]).min(hi[1] - lo[1]));
                (
                    [lo[0] - margin, lo[1] - margin],
                    [hi[0] + margin, hi[1] + margin],
                )
            };
            rev.push((level, rlo, rhi, margin));
            lo = [floor_div2(rlo[0]), floor_div2(rlo[1])];
            // Along a field an odd child averages the predictions of its parent and the
            // next one (`upsample_aniso`), so a region ending on an odd child needs one
            // parent more to be exact: its last (margin) pixels, which magnification
            // reads, otherwise differed between windows. Tileable and surface regions keep
            // their sizes (periods, atlases), and a standalone texture is no window.
            let odd_reach = params.field.is_some()
                && !params.standalone
                && !params.tileable_output
                && params.surface.is_none()
                && level > 0;
            hi = if odd_reach {
                [floor_div2(rhi[0]) + 1, floor_div2(rhi[1]) + 1]
            } else {
                [floor_div2(rhi[0] - 1) + 1, floor_div2(rhi[1] - 1) + 1]
            };
        }
        rev.reverse();
        let mut levels = Vec::with_capacity(rev.len());
        let mut base: u64 = 0;
        for (level, rlo, rhi, margin) in rev {
            let size = [(rhi[0] - rlo[0]) as u32, (rhi[1] - rlo[1]) as u32];
            let randomness = if params.randomness.is_empty() {
                default_randomness(
                    level,
                    last,
                    analysis.width.min(analysis.height),
                    params.extra_still_levels,
                )
            } else {
                let i = (level as usize).min(params.randomness.len() - 1);
                params.randomness[i]
            };
            levels.push(LevelPlan {
                level,
                spacing: analysis.levels[level as usize].spacing,
                origin: rlo,
                size,
                coord_base: base as u32,
                randomness,
                margin: margin as u32,
            });
            base += size[0] as u64 * size[1] as u64;
        }
        let torus = torus.then(|| {
            let t = Torus {
                period,
                output: [params.width, params.height],
                base: base as u32,
                isometric,
            };
            base += params.width as u64 * params.height as u64;
            t
        });
        if base > u32::MAX as u64 / 2 {
            return Err(Error::InvalidParameter(format!(
                "output {}x{} is too large for one synthesis; synthesize it in windows",
                params.width, params.height
            )));
        }
        let fin = levels.last().unwrap();
        let window_offset = [
            (params.origin[0] - fin.origin[0]) as u32,
            (params.origin[1] - fin.origin[1]) as u32,
        ];
        let surface_layout = params
            .surface
            .as_ref()
            .map(|d| d.surface_words(levels.len()).1)
            .unwrap_or_default();
        for (l, lp) in levels.iter().enumerate() {
            if let Some(d) = &params.surface {
                let dl = &d.levels[levels.len() - 1 - l];
                let n = lp.size[0] as usize * lp.size[1] as usize;
                if dl.size != lp.size || dl.jac.len() != n || dl.inside.len() != n.div_ceil(32) {
                    return Err(Error::InvalidParameter(format!(
                        "atlas domain level {} is inconsistent with its {:?} region",
                        levels.len() - 1 - l,
                        lp.size
                    )));
                }
                if dl
                    .fill
                    .iter()
                    .any(|e| e.dst as usize >= n || e.src as usize >= n)
                {
                    return Err(Error::InvalidParameter(
                        "atlas domain indirection entry out of range".into(),
                    ));
                }
            }
        }
        Ok(Self {
            levels,
            params: params.clone(),
            window_offset,
            coord_count: base,
            surface_layout,
            torus,
        })
    }

    /// Uniform parameters of any pass at `level` (parity and correction-specific
    /// fields are filled by the caller).
    pub fn pass_params(&self, analysis: &Analysis, level: usize) -> PassParams {
        let lp = &self.levels[level];
        let ld = &analysis.levels[level];
        let parent = if level > 0 {
            &self.levels[level - 1]
        } else {
            lp
        };
        let px = analysis.width * analysis.height;
        let km1 = analysis.k.saturating_sub(1);
        PassParams {
            ex_size: [analysis.width as i32, analysis.height as i32],
            origin: lp.origin,
            size: [lp.size[0] as i32, lp.size[1] as i32],
            parent_origin: parent.origin,
            // Level 0 has no parent: upsample starts it from (0, 0).
            parent_size: if level > 0 {
                [parent.size[0] as i32, parent.size[1] as i32]
            } else {
                [0, 0]
            },
            parity: [0, 0],
            spacing: lp.spacing as i32,
            step: if analysis.tileable {
                [
                    (lp.spacing % analysis.width) as i32,
                    (lp.spacing % analysis.height) as i32,
                ]
            } else {
                [lp.spacing as i32; 2]
            },
            tileable: analysis.tileable as i32,
            margin: ld.margin as i32,
            level: lp.level,
            seed: self.params.seed,
            jitter_amp: (lp.spacing as f32 * lp.randomness * 16.0).round() as i32,
            k: analysis.k as i32,
            shift: ld.shift,
            coherence: (self.params.coherence * 16.0).round() as u32,
            et_base: analysis.table_base(level) as u32,
            off_base: level as u32 * px * km1,
            proj_base: level as u32 * 64,
            coord_base: lp.coord_base,
            parent_coord_base: parent.coord_base,
            window_offset: [self.window_offset[0] as i32, self.window_offset[1] as i32],
            window_size: [self.params.width as i32, self.params.height as i32],
            full_distance: 0,
            coord_frac: if self.params.anisometric() {
                COORD_FRAC
            } else {
                0
            },
            periodic: self.params.tileable_output as u32,
            map_kind: 0,
            hi_size: [0, 0],
            magnify: 1,
            masked: self.params.surface.is_some() as u32,
            mask_base: self.surface_layout.get(level).map_or(0, |s| s.mask_base),
            fill_base: self.surface_layout.get(level).map_or(0, |s| s.fill_base),
            // The band; the schedule's last fill of a level covers the whole gutter.
            fill_count: self.surface_layout.get(level).map_or(0, |s| s.band_count),
            flag_base: 0,
            window_origin: [self.params.origin[0], self.params.origin[1]],
            distortion_max: 0,
            steps: (self.levels.len() - 1 - level) as u32,
            nearest: 0,
            dither: 0,
            seam_blend: self.params.seam_blend as u32,
            inset: 0,
            kset_interp: 0,
            quarter: 0,
            stamp: 0,
            clean_before: 0,
            coherent_skip: 0,
            drift: 0,
            fade_src: 0,
            fade_dst: 0,
            fade_frames: 0,
            fade_mean: 0,
            fade_change: 0,
            anchor: 0,
        }
    }
}

impl SynthPlan {
    /// Quantized Jacobians of every level's region, in the coordinate array's layout
    /// (empty for isometric synthesis). Pixel `p` of level `l` samples the field at its
    /// centre in output pixels.
    /// Whether every Jacobian of [`Self::jacobians`] is the identity: an anisometric plan
    /// whose field is the identity transform (advection without a field), not on a
    /// surface. The GPU passes then use the constant (`IDENTITY_J`), the same values.
    pub fn identity_jacobians(&self) -> bool {
        self.params.surface.is_none()
            && self.torus.is_none()
            && self.params.field.as_ref().is_some_and(Field::is_identity)
    }

    pub fn jacobians(&self) -> Vec<[i32; 4]> {
        if let Some(d) = &self.params.surface {
            let n = self.levels.len();
            return (0..n)
                .flat_map(|i| d.levels[n - 1 - i].jac.iter().copied())
                .collect();
        }
        let Some(f) = &self.params.field else {
            return Vec::new();
        };
        let last = self.levels.len() as u32 - 1;
        let mut out = Vec::with_capacity(self.coord_count as usize);
        // On a torus, the field at the output position each torus pixel stands for,
        // scaled by output / period (see `Torus`); then the output's own.
        let scale = self.torus.map(|t| {
            [
                t.output[0] as f64 / t.period[0] as f64,
                t.output[1] as f64 / t.period[1] as f64,
            ]
        });
        for (i, l) in self.levels.iter().enumerate() {
            out.extend(match scale {
                Some(k) => field::rasterize_region_scaled(f, l.origin, l.size, last - i as u32, k),
                None => field::rasterize_region(f, l.origin, l.size, last - i as u32),
            });
        }
        if let Some(t) = &self.torus {
            out.extend(field::rasterize_region(f, [0, 0], t.output, 0));
        }
        out
    }

    /// Where the output's coordinates lie: the start of their region in the coordinate
    /// array, its row length, and the window's offset in it (the finest level's region,
    /// or a torus's resampled output).
    pub fn output_region(&self) -> (u32, u32, [u32; 2]) {
        match &self.torus {
            Some(t) => (t.base, t.output[0], [0, 0]),
            None => {
                let fin = self.levels.last().expect("a plan has levels");
                (fin.coord_base, fin.size[0], self.window_offset)
            }
        }
    }

    /// A torus's resampling and gather parameters: the output's region (`size`,
    /// `coord_base`) read from the finest level's (`parent_size`,
    /// `parent_coord_base`), periodic, the nearest texel along no field.
    fn torus_output_params(&self, analysis: &Analysis, t: &Torus) -> PassParams {
        let last = self.levels.len() - 1;
        let fin = &self.levels[last];
        PassParams {
            origin: [0, 0],
            size: [t.output[0] as i32, t.output[1] as i32],
            parent_origin: [0, 0],
            parent_size: [fin.size[0] as i32, fin.size[1] as i32],
            parent_coord_base: fin.coord_base,
            coord_base: t.base,
            window_offset: [0, 0],
            nearest: t.isometric as u32,
            ..self.pass_params(analysis, last)
        }
    }
}

impl SynthPlan {
    /// The surface buffer (chart masks and indirection entries) of an atlas synthesis;
    /// empty otherwise.
    pub fn surface_words(&self) -> (Vec<u32>, Vec<SurfaceLayout>) {
        match &self.params.surface {
            Some(d) => d.surface_words(self.levels.len()),
            None => (Vec::new(), Vec::new()),
        }
    }
}

/// What a dispatch does.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PassKind {
    Upsample,
    Jitter,
    Correct,
    Gather,
    /// Anisometric variants (continuous coordinates, Jacobian field).
    UpsampleAniso,
    CorrectAniso,
    GatherAniso,
    /// Atlas synthesis: refill the gutters through the indirection map.
    Fill,
    /// Advection: move the coordinates with the flow (into the scratch region).
    Advect,
    /// Advection: copy the moved coordinates back, flagging the pixels whose
    /// coordinates the flow distorted too much (for the upsample pass).
    Distortion,
    /// Advection: add the frame's centre velocity, in whole finest pixels, to the drift
    /// (one invocation, first in a frame).
    Drift,
    /// Advection frames with fading: the finest level's colours, pixels whose
    /// coordinate jumped fading in over a few frames (`fade.rs`); in place of the gather.
    Fade,
    /// A tileable output made on a torus ([`Torus`]): the finest level's coordinates
    /// resampled onto the output's grid.
    Resample,
}

/// One dispatch of the schedule: the GPU and the CPU mirror run the same list.
#[derive(Clone, Copy, Debug)]
pub struct Dispatch {
    pub kind: PassKind,
    pub level: usize,
    pub params: PassParams,
}

impl Dispatch {
    /// Threads this dispatch needs (x, y): one per pixel, or per pixel of one parity.
    pub fn threads(&self) -> [u32; 2] {
        let p = &self.params;
        match self.kind {
            PassKind::Upsample | PassKind::UpsampleAniso | PassKind::Jitter => {
                [p.size[0] as u32, p.size[1] as u32]
            }
            PassKind::Correct | PassKind::CorrectAniso => {
                let axis = |class: i32, size: i32| {
                    if class == 2 {
                        1
                    } else {
                        ((size - 2 * p.inset).max(0) as u32).div_ceil(2)
                    }
                };
                [axis(p.parity[0], p.size[0]), axis(p.parity[1], p.size[1])]
            }
            PassKind::Gather | PassKind::GatherAniso => {
                [p.window_size[0] as u32, p.window_size[1] as u32]
            }
            PassKind::Fill => [p.fill_count.min(FILL_ROW), p.fill_count.div_ceil(FILL_ROW)],
            PassKind::Advect | PassKind::Distortion | PassKind::Resample | PassKind::Fade => {
                [p.size[0] as u32, p.size[1] as u32]
            }
            PassKind::Drift => [1, 1],
        }
    }

    /// Whether this dispatch may read a level's quarter-pixel tables
    /// (`crate::gpu::synth`'s fine tables) instead of interpolating `et` and `qe`: an
    /// anisometric correction with the projected distance that reads quarter pixels
    /// (advection frames) of a level with tables (recognized by its table offset,
    /// [`Analysis::table_base`], which skips levels without tables: until the
    /// thirty-first session the GPU path compared it with `(levels - 1) w h`, which
    /// stopped matching when level 0 lost its tables (twenty-fifth session), so the
    /// frames interpolated four texels per read: the same values, about 1.3x the time).
    /// A schedule reads the tables of one level, [`quarter_tables_level`]; the others
    /// interpolate.
    pub fn reads_quarter_tables(&self, analysis: &Analysis) -> bool {
        self.kind == PassKind::CorrectAniso
            && self.params.quarter != 0
            && self.params.full_distance == 0
            && self.level < analysis.levels.len()
            && self.params.et_base as usize == analysis.table_base(self.level)
    }
}

/// The level whose quarter-pixel tables a schedule reads: the finest level with a
/// dispatch that [`Dispatch::reads_quarter_tables`] (an advection frame's most
/// corrected level: the finest, or the second-finest when the finest is upsampled, or
/// the advected level above the re-synthesized ones).
pub fn quarter_tables_level(schedule: &[Dispatch], analysis: &Analysis) -> Option<usize> {
    schedule
        .iter()
        .filter(|d| d.reads_quarter_tables(analysis))
        .map(|d| d.level)
        .max()
}

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
/// ([`super::advect::AdvectOptions::resynthesize`]): upsampled following the drift's
/// phase (`drift`, 0 for none), as the finest level is, then corrected as in a
/// synthesis. No jitter: it is a function of the pixel's place on the screen, so
/// re-applied every frame it would pin the texture's detail to the screen while the flow
/// moves it (measured: gravel, 256x256 vortex, 300 frames, three re-synthesized levels,
/// energy at frame 300 0.0032 with it against 0.0022 without, warped difference 0.096
/// against 0.077); the advected levels carry frame 0's jitter.
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

/// Correction subpass order (absolute parities).
pub const SUBPASS_ORDER: [[i32; 2]; 4] = [[0, 0], [1, 1], [1, 0], [0, 1]];

impl SynthPlan {
    /// Where advection keeps its per-pixel distortion flags, and a synthesis its
    /// corrections' change stamps (see [`Self::schedule_with`]): after every level's
    /// coordinates. A coordinate buffer holds [`Self::coord_buffer_len`] entries.
    pub fn flag_base(&self) -> u32 {
        self.coord_count as u32
    }

    /// Entries of a GPU coordinate buffer for this plan: the coordinates, then the flag
    /// region ([`Self::flag_base`], [`Self::flag_count`]), then the two entries of the
    /// advection frames' drift ([`Self::drift_index`]).
    pub fn coord_buffer_len(&self) -> u64 {
        self.coord_count + self.flag_count() + 2
    }

    /// Where an advection keeps its drift: the whole finest pixels the flow's centre
    /// has moved since frame 0 (the sum of its velocity rounded frame by frame), before
    /// and after the current frame (`PassParams::drift`; zero at frame 0).
    pub fn drift_index(&self) -> u32 {
        (self.coord_count + self.flag_count()) as u32
    }

    /// Where an advection with fading keeps its two halves of fade state
    /// (`passes::fade`): after the drift, each [`Self::fade_half_len`] entries.
    pub fn fade_base(&self) -> u32 {
        self.drift_index() + 2
    }

    /// Entries of one half of the fade state: [`super::fade::STATE_ENTRIES`] per pixel
    /// of the finest level's region.
    pub fn fade_half_len(&self) -> u64 {
        let fin = self.levels.last().expect("a plan has levels");
        super::fade::STATE_ENTRIES as u64 * fin.size[0] as u64 * fin.size[1] as u64
    }

    /// Entries of an advection's coordinate buffer: [`Self::coord_buffer_len`], plus
    /// the two halves of fade state with `fade`.
    pub fn advect_buffer_len(&self, fade: bool) -> u64 {
        self.coord_buffer_len() + if fade { 2 * self.fade_half_len() } else { 0 }
    }

    /// An advection frame's fade dispatch in place of its gather `g` (`options.fade` > 0):
    /// over the finest level's region with the frame's drift and dither, reading the
    /// state half `frame % 2` (written by the previous frame; frame 0's synthesis writes
    /// half 0), writing the other. `first` (frame 0): writing half 0 with every pixel
    /// unfaded.
    fn fade_dispatch(
        &self,
        analysis: &Analysis,
        g: &Dispatch,
        options: &super::advect::AdvectOptions,
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
                dither: super::advect::dither(frame),
                flag_base: self.flag_base(),
                fade_src: src,
                fade_dst: dst,
                fade_frames: options.fade,
                fade_mean: super::fade::mean_color(&analysis.colors),
                fade_change: options.fade_change,
                ..g.params
            },
        }
    }

    /// Entries of the flag region (the largest level).
    pub fn flag_count(&self) -> u64 {
        self.levels
            .iter()
            .map(|l| l.size[0] as u64 * l.size[1] as u64)
            .max()
            .unwrap_or(0)
    }

    /// The plan an advection frame's dispatches come from: this synthesis with the
    /// frames' `passes` correction passes at every level and their `sets_every`.
    fn frame_plan(&self, options: &super::advect::AdvectOptions) -> SynthPlan {
        let mut frame_plan = self.clone();
        frame_plan.params.passes = options.passes;
        frame_plan.params.second_finest_passes = Some(options.passes);
        frame_plan.params.finest_passes = options.passes;
        frame_plan.params.sets_every = options.sets_every.clamp(1, 16);
        frame_plan
    }

    /// The correction passes per frame of the coarsest advected level where it is not the
    /// most corrected one: [`super::advect::AdvectOptions::coarsest_passes`], or where it
    /// is `None`, 2 (at least `passes`, none with none) with `keep_look` where the
    /// desired Jacobian is the same everywhere (no atlas; no field or a constant one), else
    /// `passes`.
    pub fn advect_coarsest_passes(&self, options: &super::advect::AdvectOptions) -> u32 {
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
        options: &super::advect::AdvectOptions,
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

    /// The dispatches of one advection frame (paper section 7), on the `levels` finest
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
    /// [`AdvectOptions::upsample_finest`]: super::advect::AdvectOptions::upsample_finest
    pub fn advect_schedule(
        &self,
        analysis: &Analysis,
        options: &super::advect::AdvectOptions,
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
                super::advect::KEEP_LOOK_REMAKE_THRESHOLD
            } else {
                c
            };
            let adv = PassParams {
                flag_base: self.flag_base(),
                distortion_max: super::advect::distortion_max(c, base.spacing),
                drift,
                ..base
            };
            out.push(Dispatch {
                kind: PassKind::Advect,
                level,
                params: PassParams {
                    dither: super::advect::dither(frame),
                    ..adv
                },
            });
            // The advected coordinates wait in the scratch region; the distortion pass
            // writes them back, and the flagged ones upsampled again from the coarser
            // level (on the coarsest level, which has nothing to upsample from, none is
            // flagged; on the coarsest advected level, with anchored renewals, mostly
            // continued from an anchor instead). One pass where a separate upsampling of
            // the flagged pixels read every pixel's flag: about 5% of a 512x512 frame.
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
            // the same). Measured (README, 256x256 vortex over 300 frames): a quarter of
            // the coarser levels' subpasses per frame gave the same figures as half; an
            // eighth raises the energy at frame 300 by 2-5% (gravel, brick; the marble's
            // veins stay), for a per-frame cost of 48-50% of a synthesis at 512x512 on
            // lavapipe instead of 53-56%.
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
                            // four per frame and follows the same rule (fifty-fourth
                            // session, gravel with `--fade 1`: every 2 at all three levels
                            // 0.18% pops at a mean x1.17 against 0.21% at x1.19 with the
                            // coarser two scoring every correction; `keep_look()`'s 4,
                            // 0.20% at x1.17, the coarser corrections about a third
                            // cheaper; brick and grass alike).
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
    /// ([`super::advect::AdvectOptions::resynthesize`]) are made as the later frames
    /// make them (no jitter, the frames' passes), so that frame 1 does not change the
    /// texture's look; so are, with [`super::advect::AdvectOptions::keep_look`], the
    /// advected levels below the coarsest one, which its frames remake under a turning
    /// flow.
    pub fn advect_first_schedule(
        &self,
        analysis: &Analysis,
        options: &super::advect::AdvectOptions,
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
        options: &super::advect::AdvectOptions,
    ) -> Vec<Dispatch> {
        let n = self.levels.len();
        let coarsest = n - options.levels.clamp(1, n);
        let mut s = self.schedule_inner(analysis, false, false);
        s.retain(|d| d.level < coarsest);
        s
    }

    /// Every dispatch of the synthesis, in order.
    pub fn schedule(&self, analysis: &Analysis) -> Vec<Dispatch> {
        self.schedule_with(analysis, true)
    }

    /// The schedule; with `shrink`, correction subpass `s` of a level (counted over all
    /// its passes) skips the `s + 1` outermost rings of the margin. Each subpass reads
    /// one pixel around the pixels it updates, so the pixels `s + 1` in from the edge
    /// are exactly what the full subpasses would give, and after the last of the
    /// level's `4 passes` subpasses that is everything inside the margin (plus the ring
    /// the finest level's gather reads): the output does not change, and the coarse
    /// levels, mostly margin, cost ~40% less.
    pub fn schedule_with(&self, analysis: &Analysis, shrink: bool) -> Vec<Dispatch> {
        self.schedule_inner(analysis, shrink, true)
    }

    /// [`Self::schedule_with`]; with `skip`, the corrections skip settled pixels (below).
    fn schedule_inner(&self, analysis: &Analysis, shrink: bool, skip: bool) -> Vec<Dispatch> {
        let aniso = self.params.anisometric();
        let (upsample, correct, gather) = if aniso {
            (
                PassKind::UpsampleAniso,
                PassKind::CorrectAniso,
                PassKind::GatherAniso,
            )
        } else {
            (PassKind::Upsample, PassKind::Correct, PassKind::Gather)
        };
        let mut out = Vec::new();
        // Corrections skip the pixels whose 3x3 neighbourhood, the pixel included, is
        // unchanged since their class's previous subpass, which left the pixel as it
        // was: a correction is a function of those nine coordinates (and of the pixel's
        // Jacobian, fixed during a synthesis), so it would leave it again. A pixel that
        // changes writes its subpass's stamp (counted over the whole schedule, from 1)
        // for itself and its 8 neighbours after the coordinates (`flag_base`); a pixel
        // whose stamp is below the stamp of its class's latest subpass with the same
        // candidates (`sets_every` alternates two kinds) is skipped. A level's first
        // pass (of each kind) runs in full, and so do jittered levels (below). Measured on
        // lavapipe, 512x512: the corrections took 0.80-0.90 of their time where the
        // copy guard keeps two more still levels, 0.84-0.90 with the default schedule
        // (gravel 128 and 512 px, `GpuSynthesizer::profile`). Not in atlas synthesis,
        // whose fills rewrite the gutters between subpasses, nor in advection
        // (`advect_schedule`, whose coordinates move between frames, and
        // `advect_first_schedule`: `skip` off). The CPU mirror computes every pixel: the
        // same bytes.
        let skipping = skip && self.params.surface.is_none();
        let mut stamp = 0u32;
        for level in 0..self.levels.len() {
            let params = self.pass_params(analysis, level);
            out.push(Dispatch {
                kind: upsample,
                level,
                params,
            });
            // Atlas synthesis: gutters refilled after every pass that writes coordinates.
            let fill = Dispatch {
                kind: PassKind::Fill,
                level,
                params,
            };
            let fill_all = Dispatch {
                kind: PassKind::Fill,
                level,
                params: PassParams {
                    fill_count: self.surface_layout.get(level).map_or(0, |s| s.fill_count),
                    ..params
                },
            };
            let fills = params.fill_count > 0;
            if level == 0 {
                if fill_all.params.fill_count > 0 {
                    out.push(fill_all);
                }
                continue;
            }
            if params.jitter_amp != 0 {
                out.push(Dispatch {
                    kind: PassKind::Jitter,
                    level,
                    params,
                });
            }
            if fills {
                out.push(fill);
            }
            let finest = level + 1 == self.levels.len();
            let passes = passes_at(
                &self.params,
                level as u32,
                self.levels.len() as u32 - 1,
                ExemplarShape::of(analysis),
            );
            let full = match self.params.distance {
                DistanceMode::Projected => false,
                DistanceMode::Full => true,
                DistanceMode::Mixed => !finest,
            };
            // A periodic region of odd size needs a third class along that axis.
            let periodic = self.params.tileable_output;
            let sz = self.levels[level].size;
            let wx = super::common::has_wrap_class(sz[0] as i32, periodic);
            let wy = super::common::has_wrap_class(sz[1] as i32, periodic);
            let mut order: Vec<[i32; 2]> = SUBPASS_ORDER.to_vec();
            if wx {
                order.extend([[2, 0], [2, 1]]);
            }
            if wy {
                order.extend([[0, 2], [1, 2]]);
            }
            if wx && wy {
                order.push([2, 2]);
            }
            let margin = self.levels[level].margin as i32;
            let mut subpass = 0;
            // Only on unjittered levels: on a jittered one few pixels settle before the
            // last pass (0-12% could be skipped in passes 1-2, 22-53% in pass 3, counted
            // with the CPU mirror), which did not pay for the stamps.
            let skipping = skipping && params.jitter_amp == 0;
            // Per class and kind of pass (with the sets, without): the stamp of its
            // latest subpass of that kind at this level (0: none yet).
            let mut previous = vec![[0u32; 2]; order.len()];
            for pass in 0..passes {
                // Without the sets a pass is the same correction with k = 1 (its own
                // pipeline, whose candidate loop compiles to the coherent candidates).
                let k = if pass % self.params.sets_every == 0 {
                    params.k
                } else {
                    1
                };
                for (class, &parity) in order.iter().enumerate() {
                    subpass += 1;
                    stamp += 1;
                    // Since then, every change in the neighbourhood (also one by a
                    // subpass of the other kind) left a newer stamp.
                    let kind = (k != params.k) as usize;
                    let clean_before = if skipping { previous[class][kind] } else { 0 };
                    previous[class][kind] = stamp;
                    // Stamps serve the level's next subpasses: none from its last.
                    let last = pass + 1 == passes && class + 1 == order.len();
                    let stamp = if skipping && !last { stamp } else { 0 };
                    let params = PassParams {
                        k,
                        parity,
                        full_distance: full as u32,
                        inset: if shrink { subpass.min(margin) } else { 0 },
                        flag_base: self.flag_base(),
                        stamp,
                        clean_before,
                        ..params
                    };
                    out.push(Dispatch {
                        kind: correct,
                        level,
                        params,
                    });
                    if fills {
                        out.push(fill);
                    }
                }
            }
            if fill_all.params.fill_count > fill.params.fill_count {
                out.push(fill_all);
            }
        }
        let last = self.levels.len() - 1;
        if let Some(t) = &self.torus {
            let params = self.torus_output_params(analysis, t);
            out.push(Dispatch {
                kind: PassKind::Resample,
                level: last,
                params,
            });
            out.push(Dispatch {
                kind: gather,
                level: last,
                params,
            });
            return out;
        }
        out.push(Dispatch {
            kind: gather,
            level: last,
            params: self.pass_params(analysis, last),
        });
        out
    }
}

/// At most this many correction passes at the second-finest level of an isometric
/// synthesis from a large exemplar (see [`SynthParams::second_finest_passes`]).
pub const LARGE_SECOND_FINEST_PASSES: u32 = 2;

/// At most this many at the second-finest level of an isometric synthesis from a smaller
/// exemplar (thirtieth session). There four passes took about half of a 512x512
/// synthesis's GPU time from the bundled 128 px brick on lavapipe (80-140 ms); three,
/// with the margins they shrink, 48-49 ms (`bench --per-pass`, 2 alternating runs). Texture
/// energy +0.9 / +0.2 / 0.0% (full / half / quarter resolution, medians over 13 exemplars
/// of 64-156 px x seeds 1-2; worst +3.7 / +0.8 / +0.1%), histogram distance 1.000 (worst
/// +6.9%, the leopard). Along fields too (not on surfaces, nor in advection, which pins
/// its passes): 13 exemplars x `swirl`, `perspective` and `rotate:30` (384x384, seed 1)
/// gave texture energy 1.001 / 1.000 / 1.000, histogram distance 1.000 and Jacobian
/// fidelity (within 15%, all pixels / away from seams) 0.999 / 1.000 of four passes'
/// (medians; worst energy +0.7%, fidelity -2.9 / -0.9%), and a 512x512 swirl from the
/// bundled gravel took 181-189 ms instead of 207-213 ms (`bench`, 2 alternating runs).
/// Not with a feature channel, whose figures (README, *Controls*) were measured with four.
pub const SMALL_SECOND_FINEST_PASSES: u32 = 3;

/// At most this many correction passes on a level without similarity sets of its own
/// ([`crate::analysis::level_searched`]: its neighbourhood spans the exemplar, e.g. the
/// two coarsest corrected levels of a 400 or 512 px exemplar, or of a 128 px one).
/// Their only candidates are the coherent ones on a near-constant blur, and two passes
/// settle them: measured on 17 exemplars of 128-512 px x seeds 1-2 (512x512, thirtieth
/// session), 26 of the 34 outputs were the same bytes as with four passes, and the texture
/// energy and histogram distance of all 34 were 0.988 / 0.996 / 0.996 and 0.989 of the
/// four passes' (means; medians 1.000). Their exact-window margins halve with the
/// passes: the two levels took 14.6-27.3 ms of a 400 px exemplar's 512x512 synthesis on
/// lavapipe, 5.4-7.0 ms with two passes. One pass moved more outputs (histogram distance
/// up to 2x on one). Not with a feature channel (`--feature-mask`), whose coarse passes
/// arrange the features: a 128 px brick-wall mask synthesized through its coordinates
/// measured a texture energy of 0.048 with the cap against 0.037 without (the test
/// `feature_mask_carries_structure_that_colour_lacks`).
pub const UNSEARCHED_PASSES: u32 = 2;

/// What [`passes_at`] needs to know of the exemplar.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExemplarShape {
    pub width: u32,
    pub height: u32,
    /// The analysis has a feature channel ([`Analysis::feature`]).
    pub feature: bool,
}

impl ExemplarShape {
    pub fn of(analysis: &Analysis) -> Self {
        Self {
            width: analysis.width,
            height: analysis.height,
            feature: analysis.feature.is_some(),
        }
    }
}

/// Correction passes at `level` (`last` = the finest).
pub fn passes_at(params: &SynthParams, level: u32, last: u32, exemplar: ExemplarShape) -> u32 {
    if level == last {
        return params.finest_passes;
    }
    let passes = if level + 1 == last {
        params.second_finest_passes.unwrap_or_else(|| {
            default_second_finest_passes(
                params.passes,
                params.anisometric(),
                params.surface.is_some(),
                exemplar,
            )
        })
    } else {
        params.passes
    };
    let spacing = 1 << (last - level);
    if exemplar.feature || crate::analysis::level_searched(exemplar.width, exemplar.height, spacing)
    {
        passes
    } else {
        passes.min(UNSEARCHED_PASSES)
    }
}

/// The second-finest level's passes when [`SynthParams::second_finest_passes`] is `None`
/// (`anisometric`: along a field or on a surface; `surface`: atlas synthesis).
pub fn default_second_finest_passes(
    passes: u32,
    anisometric: bool,
    surface: bool,
    exemplar: ExemplarShape,
) -> u32 {
    let pixels = exemplar.width as u64 * exemplar.height as u64;
    if surface {
        passes
    } else if pixels >= crate::analysis::LARGE_EXEMPLAR_PIXELS {
        if anisometric {
            passes
        } else {
            passes.min(LARGE_SECOND_FINEST_PASSES)
        }
    } else if exemplar.feature {
        passes
    } else {
        passes.min(SMALL_SECOND_FINEST_PASSES)
    }
}

#[cfg(test)]
mod tests {
    use super::{
        default_randomness, passes_at, ExemplarShape, SynthParams, LARGE_SECOND_FINEST_PASSES,
        SMALL_SECOND_FINEST_PASSES, UNSEARCHED_PASSES,
    };
    use crate::analysis::LARGE_EXEMPLAR_PIXELS;
    use crate::field::Field;

    #[test]
    fn large_isometric_syntheses_correct_the_second_finest_level_less() {
        // Exemplar sizes just at and just under LARGE_EXEMPLAR_PIXELS.
        assert_eq!(LARGE_EXEMPLAR_PIXELS, 256 * 256);
        let shape = |width, height| ExemplarShape {
            width,
            height,
            feature: false,
        };
        let (large, small) = (shape(256, 256), shape(255, 256));
        let iso = SynthParams {
            passes: 4,
            finest_passes: 1,
            ..SynthParams::default()
        };
        // (params, exemplar) -> passes at levels 0..=3 of a 4-level plan.
        let at = |p: &SynthParams, ex: ExemplarShape| {
            (0..4).map(|l| passes_at(p, l, 3, ex)).collect::<Vec<_>>()
        };
        assert_eq!(at(&iso, large), [4, 4, LARGE_SECOND_FINEST_PASSES, 1]);
        assert_eq!(at(&iso, small), [4, 4, SMALL_SECOND_FINEST_PASSES, 1]);
        assert_eq!(SMALL_SECOND_FINEST_PASSES, 3);
        // Never more than the other levels get.
        let one = SynthParams {
            passes: 1,
            ..iso.clone()
        };
        assert_eq!(at(&one, large), [1, 1, 1, 1]);
        // Along a field, every level alike from a large exemplar, and three passes at the
        // second-finest level from a small one (surfaces keep every level's passes,
        // advection pins them: Advection::synthesis_params).
        let field = SynthParams {
            field: Some(Field::Constant {
                angle: 0.3,
                scale: [1.0, 1.0],
                shear: 0.0,
            }),
            ..iso.clone()
        };
        assert_eq!(at(&field, large), [4, 4, 4, 1]);
        assert_eq!(at(&field, small), [4, 4, SMALL_SECOND_FINEST_PASSES, 1]);
        let advected = crate::gpu::advect::Advection::synthesis_params(&field);
        assert_eq!(at(&advected, small), [4, 4, 4, 1]);
        // An explicit count wins, either way.
        for n in [0, 3, 7] {
            let p = SynthParams {
                second_finest_passes: Some(n),
                ..iso.clone()
            };
            assert_eq!(at(&p, large), [4, 4, n, 1]);
            assert_eq!(at(&p, small), [4, 4, n, 1]);
        }
    }

    #[test]
    fn levels_without_similarity_sets_get_at_most_two_passes() {
        let p = SynthParams {
            passes: 4,
            finest_passes: 0,
            ..SynthParams::default()
        };
        // 128 px, levels 0..=7 (spacing 128..1): spacing 64 and 32 span the exemplar
        // with their 4-spacing neighbourhood, 16 does not.
        let at = |p: &SynthParams, width, height, feature| {
            let ex = ExemplarShape {
                width,
                height,
                feature,
            };
            (0..8).map(|l| passes_at(p, l, 7, ex)).collect::<Vec<_>>()
        };
        let u = UNSEARCHED_PASSES;
        assert_eq!(u, 2);
        assert_eq!(at(&p, 128, 128, false), [u, u, u, 4, 4, 4, 3, 0]);
        // The smaller side decides: 129 px wide still leaves spacing 32 unsearched on a
        // 128 px high exemplar, and 129 x 129 searches it.
        assert_eq!(at(&p, 129, 128, false), [u, u, u, 4, 4, 4, 3, 0]);
        assert_eq!(at(&p, 129, 129, false), [u, u, 4, 4, 4, 4, 3, 0]);
        // With a feature channel every level gets its passes.
        assert_eq!(at(&p, 128, 128, true), [4, 4, 4, 4, 4, 4, 4, 0]);
        // A cap, never more passes than asked for.
        let one = SynthParams {
            passes: 1,
            ..p.clone()
        };
        assert_eq!(at(&one, 128, 128, false), [1, 1, 1, 1, 1, 1, 1, 0]);
    }

    /// The schedule, finest level first, for an exemplar of the given smaller side.
    fn schedule(side: u32, extra: u32) -> Vec<f32> {
        let finest = 32 - (side - 1).leading_zeros();
        (0..=finest)
            .rev()
            .map(|l| default_randomness(l, finest, side, extra))
            .collect()
    }

    #[test]
    fn still_levels_grow_with_the_exemplar() {
        // (smaller side, still levels, weight of the first jittered level)
        for (side, still, partial) in [
            (16, 1, 1.0),
            (79, 1, 1.0),
            (80, 2, 0.5),
            (127, 2, 0.5),
            (128, 3, 0.75),
            (175, 3, 0.75),
            (176, 3, 0.25),
            (287, 3, 0.25),
            (288, 4, 0.25),
            (447, 4, 0.25),
            (448, 5, 0.75),
            (4096, 5, 0.75),
        ] {
            for extra in 0..2 {
                let s = schedule(side, extra);
                let still = still + extra as usize;
                assert!(s[..still].iter().all(|&r| r == 0.0), "{side}: {s:?}");
                assert_eq!(s[still], partial, "{side}: {s:?}");
                assert!(s[still + 1..].iter().all(|&r| r == 1.0), "{side}: {s:?}");
            }
        }
    }
}
