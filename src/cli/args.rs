//! The argument groups several subcommands share (`--seed`, `--field`, the pass
//! schedule, `--tileable`, the appearance options) and the parsers of their values.

use std::path::PathBuf;

use clap::Args;

use super::parse::parse_seed;
use super::{fail, field, CliResult, ADVANCED};

/// `--seed S`.
#[derive(Args, Debug, Clone, Copy)]
pub struct SeedArg {
    /// Random seed (0..=4294967295); each seed gives a different texture
    #[arg(long, value_name = "S", default_value_t = texsyn::SynthParams::default().seed,
          allow_hyphen_values = true, value_parser = parse_seed)]
    pub seed: u32,
}

/// `--field SPEC`: a Jacobian field to synthesize along.
#[derive(Args, Debug, Clone)]
pub struct FieldArg {
    /// Anisometric synthesis along a Jacobian field (SPEC: see --help)
    #[arg(long, value_name = "SPEC", value_parser = field::parse_field,
          long_help = field::FIELD_HELP)]
    pub field: Option<field::FieldSpec>,
}

/// The pass schedule of a synthesis: `--passes`, `--second-finest-passes`,
/// `--finest-passes`, `--sets-every`, `--distance` (tuning knobs: `--help` only).
#[derive(Args, Debug, Clone)]
pub struct ScheduleArgs {
    /// Correction passes on every level but the finest (0..=16)
    ///
    /// Correction passes on every level but the finest (0..=16; each is 4 subpasses). The
    /// two coarsest corrected levels, whose neighbourhood spans the exemplar, get at most 2
    #[arg(long, value_name = "P", default_value_t = texsyn::SynthParams::default().passes,
          value_parser = clap::value_parser!(u32).range(0..=16),
          help_heading = ADVANCED, hide_short_help = true)]
    pub passes: u32,

    /// Correction passes on the second-finest level (0..=16)
    ///
    /// Correction passes on the second-finest level (0..=16). Default: --passes, but at
    /// most 2 in an isometric synthesis from an exemplar of 256x256 pixels or more, and at
    /// most 3 from a smaller one without a --feature-mask: that level is most of the GPU time
    #[arg(long, value_name = "P", value_parser = clap::value_parser!(u32).range(0..=16),
          help_heading = ADVANCED, hide_short_help = true)]
    pub second_finest_passes: Option<u32>,

    /// Correction passes on the finest level (0..=16)
    ///
    /// Correction passes on the finest level (0..=16). With 0 the finest level is the
    /// coherent upsampling of the next coarser one, which costs less for nearly the same
    /// texture; with --no-seam-blend, 1 gives a lower texture energy
    #[arg(long, value_name = "P", default_value_t = texsyn::SynthParams::default().finest_passes,
          value_parser = clap::value_parser!(u32).range(0..=16),
          help_heading = ADVANCED, hide_short_help = true)]
    pub finest_passes: u32,

    /// Score the similarity sets on every N-th correction pass only (1..=16)
    ///
    /// Score the similarity-set candidates on every N-th correction pass of a level
    /// (1..=16; 1 = every pass, as in the paper); the other passes score only the coherent
    /// candidates. 2 is faster for nearly the same texture
    #[arg(long, value_name = "N", default_value_t = texsyn::SynthParams::default().sets_every,
          value_parser = clap::value_parser!(u32).range(1..=16),
          help_heading = ADVANCED, hide_short_help = true)]
    pub sets_every: u32,

    /// Neighbourhood distance: projected (8D), full (32D) or mixed
    ///
    /// Neighbourhood distance: projected (the paper's 8D), full (32D) or mixed (full on the
    /// coarse levels, projected on the finest)
    #[arg(long, value_name = "MODE", default_value = "mixed", value_parser = parse_distance,
          help_heading = ADVANCED, hide_short_help = true)]
    pub distance: texsyn::DistanceMode,
}

/// `--tileable` / `--no-tileable`: force either, or (neither) detect from the seams.
#[derive(Args, Debug, Clone, Copy, Default)]
pub struct TileArgs {
    /// Treat the exemplar as tileable (wrap-around); default: detected from its seams
    #[arg(long, conflicts_with = "no_tileable")]
    pub tileable: bool,
    /// Treat the exemplar as not tileable; default: detected from its seams
    #[arg(long)]
    pub no_tileable: bool,
}

impl TileArgs {
    /// `None` = detect.
    pub fn get(&self) -> Option<bool> {
        match (self.tileable, self.no_tileable) {
            (true, _) => Some(true),
            (_, true) => Some(false),
            _ => None,
        }
    }
}

/// `--feature-mask FILE` and its knobs (`--feature-weight`, `--feature-clamp`,
/// `--feature-mode`), `--appearance color|neighborhood`: how the appearance vectors of an
/// analysed image are formed.
#[derive(Args, Debug, Clone, Default)]
pub struct AppearanceArgs {
    /// Feature mask of the exemplar's size (bright = feature, e.g. mortar or cracks)
    ///
    /// Binary feature mask of the exemplar's size (any image format; bright = feature,
    /// e.g. mortar or cracks): its clamped signed-distance field joins the appearance
    /// vectors so that synthesis keeps those structures whole
    #[arg(long, value_name = "FILE")]
    pub feature_mask: Option<PathBuf>,

    /// Weight of the feature channel in [0, 100]
    ///
    /// Weight of the feature channel in [0, 100]: 1 gives it as much variance as all
    /// colour channels together; larger values favour structure over colour (with
    /// --feature-mode both, the sets get it and the appearance vectors 1/128 of it)
    /// [default: 16; with --feature-mode appearance: 1]
    #[arg(long, value_name = "W", requires = "feature_mask", allow_hyphen_values = true,
          value_parser = parse_feature_weight, help_heading = ADVANCED, hide_short_help = true)]
    pub feature_weight: Option<f32>,

    /// Clamp of the feature mask's signed distance in [0.5, 4096] pixels
    ///
    /// Clamp of the feature mask's signed distance in [0.5, 4096] pixels of the analysed
    /// exemplar: 1 says inside, outside or on the boundary; larger values also say how
    /// deep inside a region a pixel lies, which costs colour fidelity [default: 1]
    #[arg(long, value_name = "PX", requires = "feature_mask", allow_hyphen_values = true,
          value_parser = parse_feature_clamp, help_heading = ADVANCED, hide_short_help = true)]
    pub feature_clamp: Option<f32>,

    /// Where the feature mask acts: both, appearance or sets
    ///
    /// Where the feature mask acts: both (the similarity sets, and lightly the appearance
    /// vectors), appearance (the paper: in the appearance vectors; structures stay the
    /// most whole, for structure the colours do not show) or sets (the similarity sets
    /// only: the colours match as without a mask) [default: both]
    #[arg(long, value_name = "MODE", requires = "feature_mask", value_parser = parse_feature_mode,
          help_heading = ADVANCED, hide_short_help = true)]
    pub feature_mode: Option<texsyn::analysis::FeatureMode>,

    /// Appearance vector: neighborhood (the paper's) or color
    ///
    /// Appearance vector: neighborhood (5x5 neighbourhoods reduced to 8D, the paper's
    /// appearance space) or color (the pixel colour alone, for comparison)
    /// [default: neighborhood; with an analysis file, the file's]
    #[arg(long, value_name = "SPACE", value_parser = parse_appearance,
          help_heading = ADVANCED, hide_short_help = true)]
    pub appearance: Option<texsyn::analysis::AppearanceSpace>,
}

impl AppearanceArgs {
    /// Loads the mask (if any) and sets the appearance options. Errors (unreadable mask)
    /// come before any analysis.
    pub fn apply(&self, options: &mut texsyn::AnalysisOptions) -> CliResult<()> {
        if let Some(a) = self.appearance {
            options.appearance = a;
        }
        if let Some(m) = self.feature_mode {
            options.feature_mode = m;
        }
        if self.feature_weight.is_some() {
            options.feature_weight = self.feature_weight;
        }
        if let Some(path) = &self.feature_mask {
            let mask = texsyn::analysis::FeatureMask::load(path)
                .map_err(|e| fail(format!("--feature-mask: {e}")))?;
            options.feature_mask = Some(mask);
        }
        if let Some(c) = self.feature_clamp {
            options.feature_clamp = c;
        }
        Ok(())
    }
}

pub fn parse_feature_weight(s: &str) -> Result<f32, String> {
    parse_checked(s, texsyn::analysis::feature::check_weight)
}

pub fn parse_feature_clamp(s: &str) -> Result<f32, String> {
    parse_checked(s, texsyn::analysis::feature::check_clamp)
}

/// A number that `check` accepts, or its message.
fn parse_checked(s: &str, check: fn(f32) -> texsyn::Result<()>) -> Result<f32, String> {
    let v: f32 = s
        .trim()
        .parse()
        .map_err(|_| format!("\"{s}\" is not a number"))?;
    check(v).map_err(|e| match e {
        texsyn::Error::InvalidParameter(m) => m,
        other => other.to_string(),
    })?;
    Ok(v)
}

pub fn parse_feature_mode(s: &str) -> Result<texsyn::analysis::FeatureMode, String> {
    s.trim()
        .parse()
        .map_err(|_| format!("\"{s}\": the feature mode is both, appearance or sets"))
}

pub fn parse_appearance(s: &str) -> Result<texsyn::analysis::AppearanceSpace, String> {
    s.trim()
        .parse()
        .map_err(|_| format!("\"{s}\": the appearance space is neighborhood or color"))
}

/// `--distance projected|full|mixed`.
pub fn parse_distance(s: &str) -> Result<texsyn::DistanceMode, String> {
    match s.trim().to_ascii_lowercase().as_str() {
        "projected" => Ok(texsyn::DistanceMode::Projected),
        "full" => Ok(texsyn::DistanceMode::Full),
        "mixed" => Ok(texsyn::DistanceMode::Mixed),
        _ => Err(format!("\"{s}\": the distance is projected, full or mixed")),
    }
}
