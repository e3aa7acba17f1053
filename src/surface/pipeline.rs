//! Surface synthesis end to end: atlas, tangent field and per-level maps on the host
//! ([`prepare`]), then the anisometric passes in the atlas on the GPU ([`synthesize`]).

use std::sync::Arc;
use std::time::{Duration, Instant};

use super::atlas::{build_atlas, Atlas, AtlasOptions};
use super::maps::{build_domain, MapsReport};
use super::mesh::Mesh;
use super::tangent_field::{DirectionSource, ScaleSource, TangentField};
use crate::analysis::Analysis;
use crate::error::{Error, Result};
use crate::gpu::synth::{ExtraMap, GpuSynthesizer};
use crate::passes::fill::AtlasDomain;
use crate::passes::{SynthParams, Synthesis};

/// How to lay the texture on the surface.
#[derive(Clone, Debug)]
pub struct SurfaceOptions {
    /// Atlas size, gutter and source.
    pub atlas: AtlasOptions,
    /// Which surface direction the exemplar's x axis follows.
    pub direction: DirectionSource,
    /// World units per exemplar texel; `None`: one exemplar texel per atlas texel on
    /// average over the surface (no magnification needed, no texel wasted).
    pub scale: Option<ScaleSource>,
}

impl Default for SurfaceOptions {
    fn default() -> Self {
        Self {
            atlas: AtlasOptions::default(),
            direction: DirectionSource::Up(glam::Vec3::Y),
            scale: None,
        }
    }
}

/// A mesh ready for synthesis: its atlas, field and maps (reusable for any number of
/// syntheses with the same exemplar pyramid depth).
#[derive(Clone, Debug)]
pub struct PreparedSurface {
    /// The mesh with its atlas.
    pub atlas: Atlas,
    /// The tangent field on the atlas mesh.
    pub field: TangentField,
    /// Per-level chart masks, Jacobians and indirection maps for synthesis.
    pub domain: Arc<AtlasDomain>,
    /// What building the maps found.
    pub report: MapsReport,
    /// World units per exemplar texel where it is constant (the automatic choice or a
    /// constant given), else None.
    pub texel_size: Option<f32>,
    /// Time spent on each preparation step.
    pub timings: PrepareTimings,
}

/// Wall-clock time of each step of [`prepare`].
#[derive(Clone, Copy, Debug, Default)]
pub struct PrepareTimings {
    /// Obtaining the atlas.
    pub atlas: Duration,
    /// Building the tangent field.
    pub field: Duration,
    /// Building the per-level maps.
    pub maps: Duration,
}

/// The smallest bounding-box diagonal [`prepare`] takes, in world units.
pub const MIN_MESH_EXTENT: f64 = 1e-6;

/// Atlas, tangent field and the maps of `levels` pyramid levels.
pub fn prepare(mesh: &Mesh, levels: usize, opts: &SurfaceOptions) -> Result<PreparedSurface> {
    // An analysis has at most one level per halving of a 2^16-texel side.
    if !(1..=16).contains(&levels) {
        return Err(Error::InvalidParameter(format!(
            "{levels} pyramid levels: an analysis has 1 to 16"
        )));
    }
    // A mesh modelled at a tiny scale: its triangle areas and the tangent frames'
    // lengths underflow in 32-bit floats long before it is degenerate (measured: a plane
    // scaled by 1e-15 ended in "texel size 0"). Refused with what to do.
    let (lo, hi) = mesh.bounding_box();
    let extent = (hi - lo).as_dvec3().length();
    if extent.is_finite() && extent > 0.0 && extent < MIN_MESH_EXTENT {
        return Err(Error::InvalidParameter(format!(
            "the mesh is {extent:.3e} units across, too small to work on in 32-bit floats \
             (at least {MIN_MESH_EXTENT:e}): scale it up, e.g. export it in millimetres \
             instead of kilometres"
        )));
    }
    let t = Instant::now();
    let atlas = build_atlas(mesh, &opts.atlas)?;
    let atlas_time = t.elapsed();
    let t = Instant::now();
    let (scale, texel_size) = match &opts.scale {
        Some(ScaleSource::Constant(s)) => (ScaleSource::Constant(*s), Some(*s)),
        Some(other) => (other.clone(), None),
        None => {
            let s = auto_texel_size(&atlas);
            (ScaleSource::Constant(s), Some(s))
        }
    };
    if let Some(s) = texel_size {
        if !(s.is_finite() && s > 0.0) {
            return Err(Error::InvalidParameter(format!(
                "texel size {s}: must be a positive number of world units"
            )));
        }
        // Absurd sizes: the whole mesh inside one exemplar texel, or a texel so small
        // the synthesis would clamp every Jacobian (more than 8x over the atlas texel).
        let (lo, hi) = atlas.mesh.bounding_box();
        let diag = (hi - lo).length();
        if s > diag * 4.0 {
            return Err(Error::InvalidParameter(format!(
                "texel size {s} is larger than the mesh itself ({diag:.3} units across): one exemplar texel would cover it all"
            )));
        }
    }
    let field = TangentField::build(
        &atlas.mesh,
        Some(&atlas.chart_of_triangle),
        &opts.direction,
        &scale,
    )?;
    let field_time = t.elapsed();
    let t = Instant::now();
    let (domain, report) = build_domain(&atlas, &field, levels)?;
    Ok(PreparedSurface {
        atlas,
        field,
        domain: Arc::new(domain),
        report,
        texel_size,
        timings: PrepareTimings {
            atlas: atlas_time,
            field: field_time,
            maps: t.elapsed(),
        },
    })
}

/// World units per exemplar texel that make one exemplar texel cover one atlas texel on
/// average: sqrt(surface area / atlas texels inside charts).
pub fn auto_texel_size(atlas: &Atlas) -> f32 {
    let uv_area: f64 = (0..atlas.mesh.triangles.len())
        .map(|t| {
            let [a, b, c] = atlas.uv_texels(t);
            0.5 * ((b - a).perp_dot(c - a)).abs() as f64
        })
        .sum();
    (atlas.mesh.surface_area() / uv_area.max(1e-12)).sqrt() as f32
}

/// Synthesis parameters for the atlas: `base`'s seed, randomness, passes etc., with
/// the output set to the whole atlas.
pub fn atlas_params(prepared: &PreparedSurface, base: &SynthParams) -> SynthParams {
    SynthParams {
        width: prepared.atlas.size,
        height: prepared.atlas.size,
        origin: [0, 0],
        field: None,
        tileable_output: false,
        surface: Some(prepared.domain.clone()),
        ..base.clone()
    }
}

/// Synthesizes the colour atlas (and `extra` maps) on the GPU and reads them back.
/// Gutter texels hold the texture continued across the chart seams.
pub fn synthesize(
    synthesizer: &GpuSynthesizer,
    prepared: &PreparedSurface,
    base: &SynthParams,
    extra: &[ExtraMap],
) -> Result<(Synthesis, Vec<Vec<[u8; 4]>>)> {
    let params = atlas_params(prepared, base);
    synthesizer.synthesize_with_maps(&params, extra)
}

/// The finest level's Jacobians as floats (exemplar pixels per atlas texel), for
/// magnification at render time.
pub fn jacobians_f32(prepared: &PreparedSurface) -> Vec<[f32; 4]> {
    let s = 1.0 / (1u32 << crate::field::JAC_FRAC) as f32;
    prepared.domain.levels[0]
        .jac
        .iter()
        .map(|j| j.map(|v| v as f32 * s))
        .collect()
}

/// The pyramid depth of an analysis (what [`prepare`] needs).
pub fn levels_of(analysis: &Analysis) -> usize {
    analysis.levels.len()
}
