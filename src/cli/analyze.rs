//! `texsyn analyze`: analyse an exemplar once and save the result for `synth` / `bench`.

use std::path::PathBuf;
use std::time::Instant;

use texsyn::Event;

use clap::Args;

use texsyn::analysis::{self, Analysis, AnalysisOptions};

use super::{
    channels_name, check_output_dir, fmt_bytes, fmt_duration, AppearanceArgs, CliResult, TileArgs,
    Ui, ADVANCED,
};

/// Analyse an exemplar image and save the analysis file (skips the analysis in synth)
#[derive(Args, Debug)]
#[command(
    long_about = "Analyse an exemplar image and save the analysis file.\n\n\
                  The analysis (Gaussian stack, PCA-reduced appearance vectors, k-coherence \
                  similarity sets) is what synthesis needs; `texsyn synth` and `texsyn bench` \
                  accept the saved file in place of the image and then skip the analysis."
)]
pub struct AnalyzeArgs {
    /// Exemplar image (PNG, JPEG, BMP, TGA, TIFF, WebP, GIF, PNM, HDR, EXR; at least 16x16)
    pub exemplar: PathBuf,

    /// Analysis file to write (written atomically, only once the analysis succeeded)
    #[arg(short, long, value_name = "FILE", value_parser = super::parse_named_output)]
    pub output: PathBuf,

    /// Similarity-set size, including the pixel itself (1..=8)
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u32).range(1..=analysis::MAX_K as i64),
          help_heading = ADVANCED, hide_short_help = true)]
    pub k: u32,

    #[command(flatten)]
    pub tile: TileArgs,

    #[command(flatten)]
    pub appearance: AppearanceArgs,

    /// Similarity-set members lie at least this many pixels from the pixel itself
    #[arg(long, value_name = "R", default_value_t = AnalysisOptions::default().exclusion_radius,
          allow_hyphen_values = true, help_heading = ADVANCED, hide_short_help = true)]
    pub exclusion: u32,

    /// Worker threads (0 = all cores; at most 256)
    #[arg(long, value_name = "N", default_value_t = 0,
          value_parser = parse_threads)]
    pub threads: usize,
}

pub fn run(ui: &Ui, args: AnalyzeArgs) -> CliResult<()> {
    check_output_dir(&args.output)?;
    let mut inputs: Vec<(&str, &std::path::Path)> = vec![("exemplar", &args.exemplar)];
    inputs.extend(
        args.appearance
            .feature_mask
            .as_deref()
            .map(|m| ("feature mask", m)),
    );
    super::check_outputs_not_inputs(&[&args.output], &inputs)?;
    let mut options = AnalysisOptions {
        k: args.k,
        tileable: args.tile.get(),
        exclusion_radius: args.exclusion,
        threads: args.threads,
        ..AnalysisOptions::default()
    };
    args.appearance.apply(&mut options)?;

    let mut analysis_progress = ui.analysis_progress();
    let analyzed = texsyn::analyze_image(&args.exemplar, &options, &mut |event| match event {
        Event::Warning(line) => ui.info(line),
        Event::Analysis(p) => analysis_progress(p),
        _ => {}
    })?;
    let (analysis, load_time, analysis_time) =
        (analyzed.analysis, analyzed.load, analyzed.analysis_time);

    let t2 = Instant::now();
    analysis.save(&args.output)?;
    let save_time = t2.elapsed();

    let size = std::fs::metadata(&args.output)
        .map(|m| m.len())
        .unwrap_or(0);
    print_summary(ui, &args, &options, &analysis);
    ui.info(format!(
        "time: load {}, analysis {}, save {}; wrote {} ({})",
        fmt_duration(load_time),
        fmt_duration(analysis_time),
        fmt_duration(save_time),
        args.output.display(),
        fmt_bytes(size)
    ));
    Ok(())
}

fn print_summary(ui: &Ui, args: &AnalyzeArgs, options: &AnalysisOptions, a: &Analysis) {
    if ui.quiet {
        return;
    }
    ui.info(format!(
        "exemplar: {}, {}x{} {}",
        args.exemplar.display(),
        a.width,
        a.height,
        channels_name(a.channels)
    ));
    let how = if options.tileable.is_some() {
        "forced"
    } else {
        "detected"
    };
    ui.info(format!(
        "tileable: {} ({how})",
        if a.tileable { "yes" } else { "no" }
    ));
    ui.info(format!(
        "k: {}, exclusion radius: {}",
        a.k, options.exclusion_radius
    ));
    print_appearance(ui, a);
    print_levels(ui, a);
}

/// The appearance space and the feature mask's settings.
pub fn print_appearance(ui: &Ui, a: &Analysis) {
    let feature = match &a.feature {
        None => "no feature mask".to_string(),
        Some(f) => format!(
            "feature mask covering {:.1}% of the exemplar, weight {}, distance clamp {} px, in the {}",
            100.0 * f.coverage,
            f.weight,
            f.clamp,
            match f.mode {
                texsyn::analysis::FeatureMode::Appearance => "appearance vectors",
                texsyn::analysis::FeatureMode::Sets => "similarity sets only",
                texsyn::analysis::FeatureMode::Both =>
                    "similarity sets and, at 1/128 of the weight, the appearance vectors",
            }
        ),
    };
    ui.info(format!("appearance: {}, {feature}", a.appearance.name()));
}

/// The per-level table: spacing, margin and the PCA residual variances.
pub fn print_levels(ui: &Ui, a: &Analysis) {
    ui.info(format!("levels: {} (0 = coarsest)", a.levels.len()));
    ui.info("PCA residual variance (fraction of variance not kept in 8D):");
    ui.info("  level  spacing  margin  appearance  runtime");
    for (l, lv) in a.levels.iter().enumerate() {
        if a.has_tables(l) {
            ui.info(format!(
                "  {:>5}  {:>7}  {:>6}  {:>10.5}  {:>7.5}",
                l, lv.spacing, lv.margin, lv.residual_variance, lv.runtime_residual_variance
            ));
        } else {
            // Never corrected, so never analysed (LevelData::et).
            ui.info(format!(
                "  {:>5}  {:>7}  {:>6}  {:>10}  {:>7}",
                l, lv.spacing, lv.margin, "-", "-"
            ));
        }
    }
}

/// `--threads`: 0 (all cores) to [`texsyn::analysis::MAX_THREADS`].
fn parse_threads(s: &str) -> Result<usize, String> {
    let max = texsyn::analysis::MAX_THREADS;
    s.trim()
        .parse::<usize>()
        .ok()
        .filter(|&t| t <= max)
        .ok_or_else(|| format!("{s:?}: give a thread count from 0 (all cores) to {max}"))
}
