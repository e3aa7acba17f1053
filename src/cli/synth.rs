//! `texsyn synth`: synthesize a texture from an exemplar image or an analysis file.

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;

use texsyn::analysis::{AnalysisOptions, MAX_K};
use texsyn::passes::SynthParams;
use texsyn::{Event, Session};

mod also;
use also::parse_also;
pub use also::AlsoMap;

use super::{
    channels_name, check_output_dir, fail, fmt_duration, parse_coherence, parse_randomness,
    parse_size, parse_window, AppearanceArgs, CliResult, Randomness, TileArgs, Ui, ADVANCED,
    CONTROLS, LOOK, OUTPUT,
};

/// Synthesize a texture of any size from an exemplar image or analysis file
#[derive(Args, Debug)]
#[command(
    long_about = "Synthesize a texture of any size from an exemplar image or analysis file.\n\n\
                  The output is a window of an infinite, deterministic texture: the same \
                  exemplar, options and seed always give the same pixels, and windows at \
                  different --window origins fit together seamlessly (along a --field preset, \
                  give all its positions: its defaults follow the window)."
)]
pub struct SynthArgs {
    /// Exemplar image, or an analysis file written by `texsyn analyze` (told apart by content)
    pub exemplar: PathBuf,

    /// Output image (png, jpg, bmp, tga, tif, webp, gif, pnm, exr, hdr; `-`: PNG to stdout)
    ///
    /// Output image; the format follows the extension (png, jpg, bmp, tga, tif, webp, gif,
    /// pnm, exr, hdr; none: png). Written atomically, only once synthesis succeeded. `-`
    /// writes a PNG to standard output
    #[arg(short, long, value_name = "OUT", value_parser = parse_output, help_heading = OUTPUT)]
    pub output: PathBuf,

    /// Output size: N (square) or WxH
    #[arg(long, value_name = "N[xM]", value_parser = parse_size, help_heading = OUTPUT)]
    pub size: [u32; 2],

    /// Origin of the output window in the infinite texture
    #[arg(long, value_name = "X,Y", default_value = "0,0", value_parser = parse_window,
          allow_hyphen_values = true, help_heading = OUTPUT)]
    pub window: [i32; 2],

    /// Make the output one period of a seamlessly tiling texture (not with --window)
    #[arg(long, conflicts_with = "window", help_heading = OUTPUT)]
    pub tileable_output: bool,

    /// Also write the exemplar coordinate of every pixel, as a float EXR (R = x, G = y)
    #[arg(long, value_name = "FILE.exr", help_heading = OUTPUT)]
    pub coords_out: Option<PathBuf>,

    /// Resynthesize an exemplar-aligned map (normal, height...) alike; repeatable
    ///
    /// Material sets: resynthesize an exemplar-aligned map (normal, height, roughness...)
    /// through the same coordinates: IN=OUT, repeatable. `normal:IN=OUT` (or an IN whose
    /// file name contains "normal") marks a tangent-space normal map with green = y up
    /// (OpenGL, glTF, Blender), `normal-dx:IN=OUT` one with green = y down (DirectX);
    /// their x, y rotate with the texture along --field. `plain:IN=OUT` forces a plain map
    #[arg(long, value_name = "[normal:|normal-dx:|plain:]IN=OUT", value_parser = parse_also,
          help_heading = OUTPUT)]
    pub also: Vec<AlsoMap>,

    #[command(flatten, next_help_heading = LOOK)]
    pub seed: super::SeedArg,

    /// Jitter randomness in [0, 2]: one value, or R0,R1,... per level (coarsest first)
    ///
    /// Jitter randomness in [0, 2]: one value for every level, or R0,R1,... per level
    /// (coarsest first, the last repeats). Default, by the exemplar's smaller side: 0 on
    /// the N finest levels, W on the next, 1 on the coarser ones, with N, W = 1, 1 under
    /// 80 px; 2, 0.5 under 128; 3, 0.75 under 176; 3, 0.25 under 288; 4, 0.25 under 448;
    /// 5, 0.75 from 448
    #[arg(long, value_name = "R|R0,R1,...", value_parser = parse_randomness, help_heading = LOOK)]
    pub randomness: Option<Randomness>,

    /// Synthesize small, render F times larger from the full exemplar (2, 4 or 8)
    ///
    /// Magnification: analyse the exemplar downsampled F times, synthesize --size, and
    /// render the output F times larger (2, 4 or 8) with the full-resolution exemplar's
    /// colours. Needs an exemplar image (not an analysis file). With --coords-out the
    /// coordinates (per pixel before magnification) are written too; --also maps
    /// (full-resolution, the exemplar's size) are magnified the same way; a
    /// --feature-mask may be given at the exemplar's size (it is downsampled with it)
    #[arg(long, value_name = "F", value_parser = parse_magnify, help_heading = LOOK)]
    pub magnify: Option<u32>,

    #[command(flatten, next_help_heading = CONTROLS)]
    pub field: super::FieldArg,

    #[command(flatten, next_help_heading = CONTROLS)]
    pub tile: TileArgs,

    /// Appearance options used when analysing an image
    #[command(flatten, next_help_heading = CONTROLS)]
    pub appearance: AppearanceArgs,

    #[command(flatten, next_help_heading = ADVANCED)]
    pub schedule: super::ScheduleArgs,

    /// Similarity-set size when analysing an image (1..=8) [default: 2]
    ///
    /// Similarity-set size used when analysing an image (1..=8) [default: 2]. With an
    /// analysis file it must match the file's
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=MAX_K as i64),
          help_heading = ADVANCED, hide_short_help = true)]
    pub k: Option<u32>,

    /// Bias towards coherent candidates in [0, 4]
    ///
    /// Bias towards coherent candidates in [0, 4]: other candidates' distances are
    /// multiplied by 1 + C
    #[arg(long, value_name = "C", default_value_t = SynthParams::default().coherence,
          value_parser = parse_coherence, help_heading = ADVANCED, hide_short_help = true)]
    pub coherence: f32,

    /// Copy guard: the largest verbatim copy allowed, a fraction of the exemplar (0 = off)
    ///
    /// Copy guard, for exemplars of 176 px and more: first synthesize probes (the window
    /// at the origin of the output's size, at least 512x512; outputs over 2048 px a side
    /// keep the default schedule) with two more still levels, then one, and keep the first
    /// whose largest verbatim copy is at most F of the exemplar's area (0..=1; 0 = the
    /// default schedule, no probe). Isometric synthesis only (ignored with --field or
    /// --randomness). Windows away from the origin are not measured; use 0 for a copy
    /// bounded at any size and place
    #[arg(long, value_name = "F", default_value_t = texsyn::DEFAULT_COPY_BUDGET,
          allow_hyphen_values = true, value_parser = parse_copy_budget,
          help_heading = ADVANCED, hide_short_help = true)]
    pub copy_budget: f32,

    /// A texture of its own, faster, that does not fit together with --window pieces
    ///
    /// A texture of its own instead of a window of the infinite texture: each level
    /// computes 2 pixels of context beyond the output instead of the 4 per correction
    /// pass that make windows agree. Faster at the same quality, but the output no longer
    /// fits together with --window pieces (an output too large for one piece is still
    /// assembled from exact windows); not combinable with --window or --tileable-output
    #[arg(long, conflicts_with_all = ["window", "tileable_output"],
          help_heading = ADVANCED, hide_short_help = true)]
    pub standalone: bool,

    /// Copy the exemplar colour at every coordinate, seams included (no seam blending)
    ///
    /// Copy the exemplar colour at every coordinate, seams included. By default a pixel
    /// on a patch seam blends in the colours its 4 neighbours predict there (coherent
    /// pixels are exact copies either way)
    #[arg(long, help_heading = ADVANCED, hide_short_help = true)]
    pub no_seam_blend: bool,
}

/// `-` is standard output (a PNG: the name has no extension), where the system names it.
fn parse_output(s: &str) -> Result<PathBuf, String> {
    if s == "-" {
        let stdout = std::path::Path::new("/dev/stdout");
        if stdout.exists() {
            return Ok(stdout.to_path_buf());
        }
        return Err("`-` (standard output) is not available on this system; give a file".into());
    }
    Ok(PathBuf::from(s))
}

mod shared;
mod summary;
use shared::parse_copy_budget;
pub use shared::{
    check_save_extension, check_save_size, cli_hint, parse_magnify, read_source, Source,
};

pub fn run(ui: &Ui, args: SynthArgs) -> CliResult<()> {
    check_arguments(&args)?;
    let [width, height] = args.size;
    // The field (a file's size and values too) before anything else.
    let field = match &args.field.field {
        Some(f) => Some(f.resolve(args.window, width, height)?),
        None => None,
    };
    let params = SynthParams {
        width,
        height,
        origin: args.window,
        seed: args.seed.seed,
        randomness: args.randomness.clone().map(|r| r.0).unwrap_or_default(),
        extra_still_levels: 0,
        passes: args.schedule.passes,
        second_finest_passes: args.schedule.second_finest_passes,
        finest_passes: args.schedule.finest_passes,
        sets_every: args.schedule.sets_every,
        coherence: args.coherence,
        distance: args.schedule.distance,
        field,
        tileable_output: args.tileable_output,
        surface: None,
        seam_blend: !args.no_seam_blend,
        standalone: args.standalone,
    };
    let mut options = AnalysisOptions {
        k: args.k.unwrap_or(AnalysisOptions::default().k),
        tileable: args.tile.get(),
        // Only a corrected finest level reads its similarity sets, and this analysis
        // serves this one synthesis: same bytes, less analysis time.
        finest_sets: args.schedule.finest_passes > 0,
        ..AnalysisOptions::default()
    };
    // The mask is the session's to read (after the cheaper checks).
    let appearance = AppearanceArgs {
        feature_mask: None,
        ..args.appearance.clone()
    };
    appearance.apply(&mut options)?;
    // SAFETY: as in `read_source`.
    let mut builder = unsafe { Session::builder().exemplar_path_mapped(&args.exemplar) }
        .analysis_options(options)
        .params(params)
        .copy_budget(args.copy_budget)
        .coordinates(args.coords_out.is_some());
    if let Some(k) = args.k {
        builder = builder.k(k);
    }
    if let Some(space) = args.appearance.appearance {
        builder = builder.appearance(space);
    }
    if let Some(mask) = &args.appearance.feature_mask {
        builder = builder.feature_mask_path(mask);
    }
    if let Some(f) = args.magnify {
        builder = builder.magnify(f);
    }
    for a in &args.also {
        builder = builder.material_map(a.material_map());
    }
    if !ui.quiet {
        // Outputs of several megapixels take seconds (minutes on a CPU device): each
        // level, at most once a second.
        let mut last = None::<Instant>;
        builder = builder.on_level(move |done, total, elapsed| {
            if last.is_none_or(|t| t.elapsed().as_secs_f32() >= 1.0) {
                last = Some(Instant::now());
                super::stderr_line(format_args!(
                    "synthesizing {width}x{height}: level {done}/{total} done ({})",
                    fmt_duration(elapsed)
                ));
            }
        });
    }
    let mut analysis_progress = ui.analysis_progress();
    let mut report = |event: Event| match event {
        Event::Warning(line) | Event::Note(line) => ui.info(line),
        Event::Device(ctx) => ui.info(format!("adapter: {}", ctx.describe())),
        Event::Analysis(p) => analysis_progress(p),
        Event::Exemplar {
            analysis: a,
            from_file,
        } => ui.info(format!(
            "exemplar: {}x{} {}, {} levels, k = {}, {}tileable{}",
            a.width,
            a.height,
            channels_name(a.channels),
            a.levels.len(),
            a.k,
            if a.tileable { "" } else { "not " },
            if from_file { " (analysis file)" } else { "" }
        )),
        Event::Windows {
            done,
            total,
            elapsed,
        } => ui.progress(format!(
            "synthesizing {width}x{height} in windows: {done}/{total} done ({})",
            fmt_duration(elapsed)
        )),
        _ => {}
    };
    let hint = cli_hint(args.tileable_output);
    let session = builder.build_reporting(&mut report).map_err(&hint)?;
    let texture = session.run_reporting(&mut report).map_err(&hint)?;
    let t = Instant::now();
    let maps: Vec<&Path> = args.also.iter().map(|a| a.output.as_path()).collect();
    texture.save_all(&args.output, args.coords_out.as_deref(), &maps)?;
    summary::print(ui, &args, &session, &texture, t.elapsed());
    super::leave_to_exit((session, texture));
    Ok(())
}

/// Cheap checks of the arguments, so that a typo does not cost an analysis.
fn check_arguments(args: &SynthArgs) -> CliResult<()> {
    check_output_dir(&args.output)?;
    check_save_extension(&args.output)?;
    if let Some(c) = &args.coords_out {
        check_output_dir(c)?;
        let exr = c.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr"));
        if !exr {
            return Err(fail(format!(
                "--coords-out {}: the coordinate map is written as OpenEXR (32-bit float); give a .exr file",
                c.display()
            )));
        }
    }
    let mut outputs: Vec<&Path> = vec![&args.output];
    outputs.extend(args.coords_out.as_deref());
    outputs.extend(args.also.iter().map(|a| a.output.as_path()));
    super::check_distinct_outputs(&outputs)?;
    let mut inputs: Vec<(&str, &Path)> = vec![("exemplar", &args.exemplar)];
    inputs.extend(
        args.also
            .iter()
            .map(|a| ("input of --also", a.input.as_path())),
    );
    inputs.extend(super::field::FieldSpec::input(&args.field.field));
    inputs.extend(
        args.appearance
            .feature_mask
            .as_deref()
            .map(|m| ("feature mask", m)),
    );
    super::check_outputs_not_inputs(&outputs, &inputs)?;
    for a in &args.also {
        check_output_dir(&a.output)?;
        check_save_extension(&a.output)?;
        // Opened now (cheap) so that a missing map does not cost an analysis; it is
        // decoded and checked against the exemplar's size when the session runs.
        texsyn::image_io::open_regular(&a.input)
            .map_err(|e| fail(format!("--also: cannot read {}: {e}", a.input.display())))?;
    }
    // The image outputs (magnified with --magnify) must fit their formats.
    let f = args.magnify.unwrap_or(1) as u64;
    let [width, height] = args.size;
    for out in std::iter::once(&args.output).chain(args.also.iter().map(|a| &a.output)) {
        check_save_size(out, width as u64 * f, height as u64 * f)?;
    }
    Ok(())
}
