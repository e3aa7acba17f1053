//! The plan's regions: which absolute region of the synthesis pyramid each level computes
//! (margins, tileable tori, atlases), the per-level pass parameters and the Jacobians.

use super::{
    default_randomness, default_second_finest_passes, passes_at, ExemplarShape, SynthParams,
    STANDALONE_MARGIN, STANDALONE_MIN_REGION,
};
use crate::analysis::Analysis;
use crate::error::{Error, Result};
use crate::field::{self, Field};
use crate::passes::common::{PassParams, COORD_FRAC};
use crate::passes::fill::SurfaceLayout;

/// One level of the plan.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelPlan {
    /// Pyramid level, 0 = coarsest.
    pub level: u32,
    /// Exemplar pixels between neighbouring coordinates at this level (`h_l`).
    pub spacing: u32,
    /// Absolute origin of the region computed at this level.
    pub origin: [i32; 2],
    /// Size of that region in level pixels.
    pub size: [u32; 2],
    /// Offset of this level's coordinates in the concatenated coordinate array.
    pub coord_base: u32,
    /// Jitter randomness at this level (fraction of `spacing`).
    pub randomness: f32,
    /// Pixels on each side of the region beyond what the finer level reads (0 for
    /// atlases, periodic outputs and level 0).
    pub margin: u32,
}

/// The plan of one synthesis: every level's region and the parameters it was made for.
#[derive(Clone, Debug, PartialEq)]
pub struct SynthPlan {
    /// The levels, coarsest first.
    pub levels: Vec<LevelPlan>,
    /// The parameters (with a torus along no field: the identity field).
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

/// How a [`SynthParams::tileable_output`] whose sides are not multiples of 4 is made: an
/// odd period at the finest or second-finest level cannot be upsampled coherently across
/// the wrap and leaves a faint seam. So the levels are synthesized on a torus of `period`
/// (each side the nearest multiple of 4, [`torus_period`]) along the field scaled by
/// `output / period`, and a resampling pass (`resample.wgsl`) maps it onto the `output`
/// grid: output pixel `x` takes the torus coordinate nearest to
/// `u = (x + 0.5) period / output - 0.5` plus `J' (u - q)`, so the texture advances as the
/// field asks per output pixel and the period is the output's. Along no field the
/// resampled coordinates are rounded to whole texels, so coherent patches stay exact
/// copies of the exemplar. `GpuSynthesizer::plan_for` falls back to the output's own
/// periods where the torus does not fit the device.
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

/// `x / 2` rounded towards negative infinity: the parent of absolute pixel `x`.
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
    /// Whether every Jacobian of [`Self::jacobians`] is the identity: an anisometric plan
    /// whose field is the identity transform (advection without a field), not on a
    /// surface. The GPU passes then use the constant (`IDENTITY_J`), the same values.
    pub fn identity_jacobians(&self) -> bool {
        self.params.surface.is_none()
            && self.torus.is_none()
            && self.params.field.as_ref().is_some_and(Field::is_identity)
    }

    /// Quantized Jacobians of every level's region, in the coordinate array's layout
    /// (empty for isometric synthesis). Pixel `p` of level `l` samples the field at its
    /// centre in output pixels.
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
    pub(super) fn torus_output_params(&self, analysis: &Analysis, t: &Torus) -> PassParams {
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
