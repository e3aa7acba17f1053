//! `texsyn synth`: synthesize a texture from an exemplar image or an analysis file.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use clap::Args;

use texsyn::analysis::{AnalysisOptions, MAX_K};
use texsyn::gpu::synth::GpuSynthesizer;
use texsyn::gpu::GpuContext;
use texsyn::passes::SynthParams;

/// Outputs of at least this many pixels (2048x2048) report progress level by level.
const LONG_SYNTHESIS_PIXELS: u64 = 1 << 22;

use super::{
    channels_name, check_output_dir, check_output_size, fail, fmt_duration, parse_coherence,
    parse_randomness, parse_size, parse_window, AppearanceArgs, CliResult, Randomness, TileArgs,
    Ui, ADVANCED, CONTROLS, LOOK, OUTPUT, WINDOW_HINT,
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
    #[arg(long, value_name = "F", default_value_t = texsyn::gpu::copy_guard::DEFAULT_COPY_BUDGET,
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

/// One `--also` map.
#[derive(Clone, Debug)]
pub struct AlsoMap {
    pub input: PathBuf,
    pub output: PathBuf,
    pub normal: bool,
    /// A normal map with green = y down (DirectX), `normal-dx:`.
    pub green_down: bool,
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

fn parse_copy_budget(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(f) if (0.0..=1.0).contains(&f) => Ok(f),
        _ => Err(format!(
            "'{s}': give a fraction of the exemplar's area between 0 and 1 (0 turns the copy guard off)"
        )),
    }
}

pub fn parse_magnify(s: &str) -> Result<u32, String> {
    match s {
        "2" | "4" | "8" => Ok(s.parse().unwrap()),
        _ => Err(format!("'{s}': the magnification factor must be 2, 4 or 8")),
    }
}

fn parse_also(s: &str) -> Result<AlsoMap, String> {
    // normal: green up (OpenGL, glTF, Blender); normal-dx: green down (DirectX).
    let (kind, green_down, rest) = if let Some(r) = s.strip_prefix("normal:") {
        (Some(true), false, r)
    } else if let Some(r) = s.strip_prefix("normal-dx:") {
        (Some(true), true, r)
    } else if let Some(r) = s.strip_prefix("plain:") {
        (Some(false), false, r)
    } else {
        (None, false, s)
    };
    let (input, output) = split_in_out(rest).map_err(|why| format!("'{s}': {why}"))?;
    // `word:IN=OUT` with an unknown word is a typo of a kind, not a file name.
    if kind.is_none() {
        if let Some((prefix, _)) = input.split_once(':') {
            if prefix.len() > 1
                && prefix
                    .bytes()
                    .all(|b| b.is_ascii_alphanumeric() || b == b'-')
            {
                return Err(format!(
                    "'{s}': unknown map kind '{prefix}:' (normal:, normal-dx: or plain:)"
                ));
            }
        }
    }
    if input.is_empty() || output.is_empty() {
        return Err(format!("'{s}': both IN and OUT must be given"));
    }
    let input = PathBuf::from(input);
    let normal = kind.unwrap_or_else(|| {
        input
            .file_name()
            .is_some_and(|n| n.to_string_lossy().to_lowercase().contains("normal"))
    });
    Ok(AlsoMap {
        input,
        output: output.into(),
        normal,
        green_down,
    })
}

/// Splits `IN=OUT`. A name may contain `=`: with several, the split is the one whose
/// `IN` is an existing file (it must be the only one).
fn split_in_out(rest: &str) -> Result<(&str, &str), String> {
    let splits: Vec<(&str, &str)> = rest
        .match_indices('=')
        .map(|(i, _)| (&rest[..i], &rest[i + 1..]))
        .collect();
    match splits[..] {
        [] => Err("expected IN=OUT, e.g. normal.png=out_normal.png".into()),
        [one] => Ok(one),
        _ => {
            let existing: Vec<_> = splits
                .iter()
                .filter(|(input, _)| !input.is_empty() && Path::new(input).is_file())
                .collect();
            match existing[..] {
                [one] => Ok(*one),
                [] => Err(format!(
                    "{} '=' signs and no split whose IN is an existing file: check the input's \
                     name",
                    splits.len()
                )),
                _ => Err(format!(
                    "ambiguous: {} are all existing files; rename the input or the output so \
                     that only one '=' separates IN from OUT",
                    existing
                        .iter()
                        .map(|(i, _)| format!("'{i}'"))
                        .collect::<Vec<_>>()
                        .join(" and ")
                )),
            }
        }
    }
}

pub use texsyn::session::ExemplarSource as Source;
pub use texsyn::session::{crop_rows, Magnified};

/// Reads EXEMPLAR (an analysis file or an image, told apart by content) without
/// analysing it yet; `--k` / `--tileable` must agree with an analysis file.
pub fn read_source(
    ui: &Ui,
    path: &Path,
    k: Option<u32>,
    tileable: Option<bool>,
) -> CliResult<Source> {
    // SAFETY: nothing in this process writes the file, and texsyn replaces analysis
    // files by renaming a new one over them, which leaves this mapping intact. Another
    // program truncating the file in place while the tables are read (the upload and
    // the preparation, well under a second) would make this process fault
    // (`Analysis::load_mapped`); a one-shot command accepts that for the faster start.
    let analysis = match unsafe { Source::open_mapped(path)? } {
        Source::Image(ex) => {
            ui.warn_if_animation(path);
            return Ok(Source::Image(ex));
        }
        Source::Analysis(a) => a,
    };
    if let Some(k) = k.filter(|&k| k != analysis.k) {
        return Err(fail(format!(
            "--k {k} does not match the analysis file {} (k = {}); drop --k or re-run `texsyn analyze --k {k}`",
            path.display(),
            analysis.k
        )));
    }
    if let Some(t) = tileable.filter(|&t| t != analysis.tileable) {
        let flag = if t { "--tileable" } else { "--no-tileable" };
        return Err(fail(format!(
            "{flag} does not match the analysis file {} (analysed as {}tileable); drop {flag} or re-run `texsyn analyze {flag}`",
            path.display(),
            if analysis.tileable { "" } else { "not " }
        )));
    }
    Ok(Source::Analysis(analysis))
}

/// `--magnify F`: the exemplar downsampled F times and its full-resolution colours.
pub fn magnify_source(source: Source, f: u32) -> CliResult<(Source, Magnified)> {
    if let Source::Analysis(_) = source {
        return Err(fail(
            "--magnify needs the exemplar image (its full-resolution colours), not an analysis file",
        ));
    }
    Ok(source.magnify(f)?)
}

/// The library's size errors name its API (`SynthParams::origin`); name the option
/// (a tileable output is one period: it cannot be split into windows).
pub fn cli_hint(tileable_output: bool) -> impl Fn(texsyn::Error) -> texsyn::Error {
    move |e| {
        with_hint(
            e,
            if tileable_output {
                "a tileable output is one synthesis: give a smaller --size"
            } else {
                WINDOW_HINT
            },
        )
    }
}

/// `e` with `hint` if it is the library's output-too-large error.
pub fn with_hint(e: texsyn::Error, hint: &'static str) -> texsyn::Error {
    match e {
        texsyn::Error::TooLarge {
            what: "output",
            width,
            height,
            limit,
            ..
        } => texsyn::Error::TooLarge {
            what: "output",
            width,
            height,
            limit,
            hint,
        },
        other => other,
    }
}

pub fn run(ui: &Ui, args: SynthArgs) -> CliResult<()> {
    // Cheap checks first, so that a typo does not cost an analysis.
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
    let mut outputs: Vec<&std::path::Path> = vec![&args.output];
    outputs.extend(args.coords_out.as_deref());
    outputs.extend(args.also.iter().map(|a| a.output.as_path()));
    super::check_distinct_outputs(&outputs)?;
    let mut inputs: Vec<(&str, &std::path::Path)> = vec![("exemplar", &args.exemplar)];
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
        // Read now (cheap) so that a missing map does not cost an analysis; it is
        // decoded and checked against the exemplar's size later.
        texsyn::image_io::open_regular(&a.input)
            .map_err(|e| fail(format!("--also: cannot read {}: {e}", a.input.display())))?;
    }
    let [width, height] = args.size;
    // The image outputs (magnified with --magnify) must fit their formats.
    let f = args.magnify.unwrap_or(1) as u64;
    for out in std::iter::once(&args.output).chain(args.also.iter().map(|a| &a.output)) {
        check_save_size(out, width as u64 * f, height as u64 * f)?;
    }
    // What the output file holds (larger than the synthesis with --magnify).
    let mut out_size = (width, height);
    // The device is created on a thread of its own while the input is read: loading the
    // driver is mostly waiting, and reading an analysis file is the other large part of
    // the fixed cost of a synthesis from a file. Joined before any error is returned, so
    // that no exit happens in the middle of the driver's start-up.
    let device = std::thread::spawn(|| {
        let t = Instant::now();
        (GpuContext::headless(), t.elapsed())
    });
    let input = (|| -> CliResult<_> {
        // The field (a file's size and values too) before the analysis.
        let field = match &args.field.field {
            Some(f) => Some(f.resolve(args.window, width, height)?),
            None => None,
        };

        // Read the input first (cheap), then check the size against the device, and only
        // then analyse (expensive).
        let t = Instant::now();
        let mut source = read_source(ui, &args.exemplar, args.k, args.tile.get())?;
        let read_time = t.elapsed();
        if let Source::Analysis(a) = &source {
            // The appearance space is fixed by the analysis: options that would change it
            // are refused rather than silently ignored.
            if args.appearance.feature_mask.is_some() {
                return Err(fail(format!(
                    "--feature-mask applies when analysing an image; {} is an analysis file: re-run `texsyn analyze --feature-mask ...`",
                    args.exemplar.display()
                )));
            }
            if args
                .appearance
                .appearance
                .is_some_and(|given| given != a.appearance)
            {
                return Err(fail(format!(
                    "--appearance does not match the analysis file {}; drop it or re-run `texsyn analyze --appearance ...`",
                    args.exemplar.display()
                )));
            }
        }
        // Magnification: analyse a downsampled copy, keep the full colours.
        let mut hi_res = None;
        // The size extra maps must have: the exemplar's (before any downsampling).
        let mut full_size = None;
        if let Source::Image(ex) = &source {
            full_size = Some((ex.width, ex.height));
        }
        if let Some(f) = args.magnify {
            let (small, hi) = magnify_source(source, f)?;
            source = small;
            hi_res = Some(hi);
        }
        Ok((field, source, read_time, hi_res, full_size))
    })();
    let (ctx, device_time) = device
        .join()
        .map_err(|_| fail("creating the GPU device failed (its thread panicked)".to_string()))?;
    let (field, source, read_time, hi_res, full_size) = input?;
    let ctx = ctx?;

    ui.info(format!("adapter: {}", ctx.describe()));
    // An output larger than the device takes in one piece is synthesized in windows and
    // assembled (the same bytes); a periodic or magnified one cannot be split.
    let mut windowed = false;
    if let Err(e) = check_output_size(&ctx, width, height) {
        if args.tileable_output || args.magnify.is_some() {
            return Err(cli_hint(args.tileable_output)(e).into());
        }
        windowed = true;
    }
    if windowed && width as usize * height as usize > texsyn::gpu::synth::MAX_WINDOWED_PIXELS {
        return Err(fail(format!(
            "--size {width}x{height}: outputs larger than the device takes in one piece are \
             assembled in memory, at most {} Mpixel (16384x16384); synthesize parts of it \
             with --window X,Y and a smaller --size",
            texsyn::gpu::synth::MAX_WINDOWED_PIXELS >> 20
        )));
    }

    source.check_fits(&ctx, args.k.unwrap_or(AnalysisOptions::default().k))?;
    let (analysis, from_file, analysis_time) = match source {
        Source::Analysis(a) => (a, true, None),
        Source::Image(ex) => {
            let t = Instant::now();
            let mut options = AnalysisOptions {
                k: args.k.unwrap_or(AnalysisOptions::default().k),
                tileable: args.tile.get(),
                // Only a corrected finest level reads its similarity sets, and this
                // analysis serves this one synthesis: same bytes, 8-26% less analysis
                // time (128-512 px exemplars).
                finest_sets: args.schedule.finest_passes > 0,
                ..AnalysisOptions::default()
            };
            args.appearance.apply(&mut options)?;
            // With --magnify the mask may be given at the full exemplar's size, like
            // the --also maps: it is downsampled as the exemplar was.
            if let (Some(f), Some(mask), Some((fw, fh))) =
                (args.magnify, &options.feature_mask, full_size)
            {
                if (mask.width / f, mask.height / f) == (ex.width, ex.height) && f > 1 {
                    options.feature_mask = Some(mask.downsample(f)?);
                } else if (mask.width, mask.height) != (ex.width, ex.height) {
                    return Err(fail(format!(
                        "--feature-mask: {}x{} pixels, but the exemplar is {fw}x{fh}; give the \
                         mask at the exemplar's size",
                        mask.width, mask.height
                    )));
                }
            }
            super::check_feature_mask(&options, ex.width, ex.height)?;
            let a = texsyn::analysis::analyze(&ex, &options, ui.analysis_progress())?;
            (a, false, Some(t.elapsed()))
        }
    };
    ui.info(format!(
        "exemplar: {}x{} {}, {} levels, k = {}, {}tileable{}",
        analysis.width,
        analysis.height,
        channels_name(analysis.channels),
        analysis.levels.len(),
        analysis.k,
        if analysis.tileable { "" } else { "not " },
        if from_file { " (analysis file)" } else { "" }
    ));
    let channels = analysis.channels;

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
    // Validate the parameters before uploading anything.
    texsyn::passes::SynthPlan::new(&analysis, &params)?;

    // The pipelines are built on another thread while the analysis uploads (both take
    // tens of milliseconds on lavapipe; a large exemplar's upload is mostly page faults).
    let t = Instant::now();
    let analysis = Arc::new(analysis);
    let (synthesizer, pipelines) = std::thread::scope(|scope| {
        let pipelines = scope.spawn(|| {
            let t = Instant::now();
            (ctx.prepare_synthesis(&analysis, &params), t.elapsed())
        });
        let synthesizer = GpuSynthesizer::new(&ctx, analysis.clone());
        (synthesizer, pipelines.join())
    });
    let upload_time = t.elapsed();
    let synthesizer = synthesizer?;
    let (built, pipeline_build_time) = pipelines.map_err(|_| {
        fail("building the GPU pipelines failed (their thread panicked)".to_string())
    })?;
    built?;
    if args.tileable_output && (width % 4 != 0 || height % 4 != 0) {
        // Each level's period is half the finer one's, rounded up: an odd period (or an
        // odd half) cannot be upsampled coherently across the wrap (`Torus`).
        ui.info(match synthesizer.plan_for(&params)?.torus {
            Some(t) => format!(
                "tileable: synthesized on a {}x{} torus and resampled to {width}x{height} \
                 (sides that are multiples of 4 wrap cleanly{})",
                t.period[0],
                t.period[1],
                if t.period[0] % 4 != 0 || t.period[1] % 4 != 0 {
                    "; a side under 8 pixels keeps its period and may show a faint seam"
                } else {
                    ""
                }
            ),
            None => format!(
                "note: this tileable output keeps its own periods ({}), and a side that is \
                 not a multiple of 4 shows a faint seam where the tiles meet (e.g. {}x{} \
                 tiles cleanly)",
                if width.min(height) < texsyn::passes::plan::TORUS_MIN_SIDE {
                    "a side under 8 pixels"
                } else {
                    "its torus would not fit the device"
                },
                width.next_multiple_of(4),
                height.next_multiple_of(4)
            ),
        });
    }
    // The library's check covers the whole pyramid (the one above, the finest level).
    windowed |= !args.tileable_output && args.magnify.is_none() && !synthesizer.fits(&params);
    // The rest of the preparation (the pipelines are built: a field's Jacobians), before
    // the synthesis so that the summary times them apart. Windows build theirs as they go.
    let t = Instant::now();
    if !windowed {
        synthesizer.prepare(&params)?;
    }
    let prepare_time = t.elapsed();
    // The copy guard's probe (its synthesis is the result when it is the output's).
    let t = Instant::now();
    let choice = synthesizer
        .choose_schedule(&params, args.copy_budget)
        .map_err(cli_hint(args.tileable_output))?;
    let guard_time = (!choice.probes.is_empty()).then(|| t.elapsed());
    let mut guard_line = (!choice.probes.is_empty() || choice.unprobed.is_some())
        .then(|| choice.describe(args.copy_budget));
    if choice.params.extra_still_levels > 0 && !GpuSynthesizer::output_within_probe(&params) {
        // The guard bounds the copies of its probe window only (copy_guard docs).
        if let Some(line) = guard_line.as_mut() {
            let probe = GpuSynthesizer::probe_params(&params);
            line.push_str(&format!(
                "\nnote: the copy guard measured the {}x{} window at the origin, not this \
                 one; tiles of a larger texture can copy more than the budget between them. \
                 For a copy bounded at any size and place, use --copy-budget 0",
                probe.width, probe.height
            ));
        }
    }
    let params = choice.params;
    let mut probe_result = choice.result;
    let mut reused_probe = false;
    // Outputs of several megapixels take seconds (minutes on a CPU device): report each
    // level, at most once a second (each window, when in windows). Smaller ones keep
    // their single submission.
    if !ui.quiet && !windowed && width as u64 * height as u64 >= LONG_SYNTHESIS_PIXELS {
        let (start, mut last) = (Instant::now(), None::<Instant>);
        synthesizer.set_progress(Some(Box::new(move |done, total| {
            if last.is_none_or(|t| t.elapsed().as_secs_f32() >= 1.0) {
                last = Some(Instant::now());
                super::stderr_line(format_args!(
                    "synthesizing {width}x{height}: level {done}/{total} done ({})",
                    fmt_duration(start.elapsed())
                ));
            }
        })));
    }

    // Material sets: every extra map is read (and checked) before any synthesis.
    // With --magnify they are full-resolution, cropped as the exemplar was.
    let mut extra = Vec::with_capacity(args.also.len());
    let (ew, eh) =
        full_size.unwrap_or((synthesizer.analysis().width, synthesizer.analysis().height));
    for a in &args.also {
        let (mw, mh, map_channels, map_pixels) = texsyn::image_io::load_material_map(&a.input)
            .map_err(|e| fail(format!("--also: {e}")))?;
        if (mw, mh) != (ew, eh) {
            return Err(fail(format!(
                "--also {}: {mw}x{mh} pixels, but the exemplar is {ew}x{eh}; extra maps must be aligned with it",
                a.input.display(),
            )));
        }
        let pixels = match &hi_res {
            Some(Magnified {
                width: hw,
                height: hh,
                ..
            }) => crop_rows(&map_pixels, ew, *hw, *hh),
            None => map_pixels,
        };
        extra.push((
            texsyn::gpu::synth::ExtraMap {
                pixels,
                normal: a.normal,
                green_down: a.green_down,
            },
            map_channels,
        ));
    }

    let timings;
    if let (
        Some(Magnified {
            pixels: hi,
            width: hw,
            height: hh,
            factor: f,
        }),
        false,
    ) = (&hi_res, args.coords_out.is_some() || !extra.is_empty())
    {
        let t = Instant::now();
        let gpu = synthesizer
            .synthesize_magnified(&params, hi, *hw, *hh, *f)
            .map_err(cli_hint(args.tileable_output))?;
        ctx.take_uncaptured_errors()?;
        out_size = (gpu.width, gpu.height);
        let synth = t.elapsed();
        let t = Instant::now();
        let rgba8 = gpu.read_rgba8(&ctx)?;
        let readback = t.elapsed();
        let t = Instant::now();
        texsyn::image_io::save_image_atomic(&args.output, gpu.width, gpu.height, channels, &rgba8)?;
        timings = Timings::Separate {
            synth,
            readback,
            write: t.elapsed(),
        };
    } else if args.coords_out.is_some() || !extra.is_empty() || windowed {
        // Coordinates and maps come back with the synthesis, in one go: report the
        // two together. With --magnify the colours and maps are magnified, the
        // coordinates are one per pixel before magnification (analysed exemplar).
        let t = Instant::now();
        let maps: Vec<_> = extra.iter().map(|(m, _)| m.clone()).collect();
        let (coords, out_w, out_h, colors, map_pixels) = match &hi_res {
            Some(Magnified {
                pixels: hi,
                width: hw,
                height: hh,
                factor: f,
            }) => {
                let m = synthesizer
                    .synthesize_magnified_with_maps(&params, hi, *hw, *hh, *f, &maps)
                    .map_err(cli_hint(args.tileable_output))?;
                (
                    m.synthesis.coords_f32(),
                    m.width,
                    m.height,
                    m.colors,
                    m.maps,
                )
            }
            None if windowed => {
                let start = Instant::now();
                let (s, map_pixels) =
                    synthesizer.synthesize_in_windows(&params, &maps, |done, total| {
                        ui.progress(format!(
                            "synthesizing {width}x{height} in windows: {done}/{total} done ({})",
                            fmt_duration(start.elapsed())
                        ))
                    })?;
                // Float coordinates only when written (2 GiB at 16384x16384).
                let coords = match args.coords_out {
                    Some(_) => s.coords_f32(),
                    None => Vec::new(),
                };
                (coords, width, height, s.colors, map_pixels)
            }
            None => {
                let (s, map_pixels) = match probe_result.take() {
                    Some(s) if maps.is_empty() => {
                        reused_probe = true;
                        (s, Vec::new())
                    }
                    _ => synthesizer
                        .synthesize_with_maps(&params, &maps)
                        .map_err(cli_hint(args.tileable_output))?,
                };
                (s.coords_f32(), width, height, s.colors, map_pixels)
            }
        };
        ctx.take_uncaptured_errors()?;
        out_size = (out_w, out_h);
        let synth_readback = t.elapsed();
        let t = Instant::now();
        // All or nothing: every output is encoded, then written to its temporary file,
        // and only then are they all renamed (files that existed before stay as they
        // were if any step fails).
        use texsyn::image_io::{encode_coords_exr_f32, encode_image, write_files_atomic};
        let mut files: Vec<(&Path, Vec<u8>)> = Vec::new();
        if let Some(coords_path) = &args.coords_out {
            let bytes = encode_coords_exr_f32(coords_path, width, height, &coords)?;
            files.push((coords_path, bytes));
        }
        for (a, (pixels, (_, ch))) in args.also.iter().zip(map_pixels.iter().zip(&extra)) {
            let bytes: Vec<u8> = pixels.iter().flatten().copied().collect();
            files.push((
                &a.output,
                encode_image(&a.output, out_w, out_h, *ch, &bytes)?,
            ));
        }
        let rgba8: Vec<u8> = colors.iter().flatten().copied().collect();
        files.push((
            &args.output,
            encode_image(&args.output, out_w, out_h, channels, &rgba8)?,
        ));
        write_files_atomic(&files.iter().map(|(p, b)| (*p, &b[..])).collect::<Vec<_>>())?;
        timings = Timings::Combined {
            synth_readback,
            write: t.elapsed(),
        };
    } else if let Some(s) = probe_result.take() {
        // The probe was this very synthesis (colours already on the host).
        let t = Instant::now();
        let rgba8: Vec<u8> = s.colors.iter().flatten().copied().collect();
        texsyn::image_io::save_image_atomic(&args.output, width, height, channels, &rgba8)?;
        timings = Timings::Probe { write: t.elapsed() };
    } else {
        let t = Instant::now();
        let gpu = synthesizer
            .synthesize(&params)
            .map_err(cli_hint(args.tileable_output))?;
        ctx.take_uncaptured_errors()?;
        let synth = t.elapsed();
        let t = Instant::now();
        let rgba8 = gpu.read_rgba8(&ctx)?;
        let readback = t.elapsed();
        let t = Instant::now();
        texsyn::image_io::save_image_atomic(&args.output, width, height, channels, &rgba8)?;
        timings = Timings::Separate {
            synth,
            readback,
            write: t.elapsed(),
        };
    }

    let px = width as f64 * height as f64;
    let magnified = if out_size != (width, height) {
        format!(", magnified from {width}x{height}")
    } else {
        String::new()
    };
    let placement = if args.standalone && !windowed {
        "standalone".to_string()
    } else {
        format!("window {},{}", args.window[0], args.window[1])
    };
    ui.info(format!(
        "output: {} ({}x{}{magnified}, seed {}, {placement})",
        args.output.display(),
        out_size.0,
        out_size.1,
        args.seed.seed,
    ));
    if let Some(line) = guard_line {
        ui.info(line);
    }
    if let Some(c) = &args.coords_out {
        ui.info(format!("coordinates: {}", c.display()));
    }
    for a in &args.also {
        ui.info(format!(
            "map: {} -> {}{}",
            a.input.display(),
            a.output.display(),
            match (a.normal, a.green_down) {
                (false, _) => "",
                (true, false) => " (normal map, green up)",
                (true, true) => " (normal map, green down)",
            }
        ));
    }
    match analysis_time {
        None => ui.info(format!(
            "time: load analysis file {}",
            fmt_duration(read_time)
        )),
        Some(a) => ui.info(format!(
            "time: load image {}, analysis {}",
            fmt_duration(read_time),
            fmt_duration(a)
        )),
    }
    ui.info(format!("      device {}", fmt_duration(device_time)));
    ui.info(format!(
        "      GPU upload {} (pipelines {} alongside), preparation {}",
        fmt_duration(upload_time),
        fmt_duration(pipeline_build_time),
        fmt_duration(prepare_time)
    ));
    if let Some(g) = guard_time {
        ui.info(format!(
            "      copy guard probes (synthesis + read-back) {}",
            fmt_duration(g)
        ));
    }
    match timings {
        Timings::Separate {
            synth,
            readback,
            write,
        } => {
            ui.info(format!(
                "      synthesis (GPU, synchronized) {} ({:.3} Mpixel/s)",
                fmt_duration(synth),
                px / synth.as_secs_f64() / 1e6
            ));
            ui.info(format!(
                "      read-back {}, write {}",
                fmt_duration(readback),
                fmt_duration(write)
            ));
        }
        Timings::Combined {
            synth_readback,
            write,
        } => {
            if reused_probe {
                ui.info("      synthesis: the copy guard's probe");
            } else {
                ui.info(format!(
                    "      synthesis + read-back of colours and coordinates {}",
                    fmt_duration(synth_readback)
                ));
            }
            ui.info(format!("      write {}", fmt_duration(write)));
        }
        Timings::Probe { write } => {
            ui.info("      synthesis: the copy guard's probe");
            ui.info(format!("      write {}", fmt_duration(write)));
        }
    }
    super::leave_to_exit((synthesizer, ctx));
    Ok(())
}

enum Timings {
    Separate {
        synth: Duration,
        readback: Duration,
        write: Duration,
    },
    Combined {
        synth_readback: Duration,
        write: Duration,
    },
    /// The copy guard's probe was the result: only the write is left.
    Probe { write: Duration },
}

/// Rejects an output extension the library cannot write, before any work (the library
/// checks again when saving).
pub fn check_save_extension(path: &Path) -> CliResult<()> {
    use image::ImageFormat as F;
    let Some(ext) = path.extension() else {
        return Ok(());
    };
    let ok = F::from_extension(ext).is_some_and(|f| {
        matches!(
            f,
            F::Png
                | F::Jpeg
                | F::Bmp
                | F::Tga
                | F::Tiff
                | F::WebP
                | F::Gif
                | F::Pnm
                | F::OpenExr
                | F::Hdr
        )
    });
    if ok {
        Ok(())
    } else {
        Err(fail(format!(
            "cannot write {}: unsupported image extension .{}; supported: {} (no extension: png)",
            path.display(),
            ext.to_string_lossy(),
            texsyn::image_io::SUPPORTED_SAVE_EXTENSIONS
        )))
    }
}

/// The largest side each output format's encoder writes (the `image` crate and its
/// WebP encoder refuse larger ones, which would surface only after the synthesis).
fn format_max_side(path: &Path) -> Option<(&'static str, u32)> {
    use image::ImageFormat as F;
    match F::from_extension(path.extension()?)? {
        F::Jpeg => Some(("JPEG", 65535)),
        F::Gif => Some(("GIF", 65535)),
        F::Tga => Some(("TGA", 65535)),
        F::WebP => Some(("WebP", 16384)),
        _ => None,
    }
}

/// An output of `width` x `height` must fit its format: checked before any work.
pub fn check_save_size(path: &Path, width: u64, height: u64) -> CliResult<()> {
    match format_max_side(path) {
        Some((name, max)) if width > max as u64 || height > max as u64 => Err(fail(format!(
            "cannot write {}: {name} images are at most {max} pixels a side and the output is \
             {width}x{height}; use .png, .tif or .exr",
            path.display()
        ))),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_formats_refuse_sizes_they_cannot_encode() {
        check_save_size(Path::new("a.png"), 70000, 16).unwrap();
        check_save_size(Path::new("a.gif"), 65535, 16).unwrap();
        let e = check_save_size(Path::new("a.gif"), 70000, 16).unwrap_err();
        assert!(
            e.to_string().contains("GIF images are at most 65535"),
            "{e}"
        );
        check_save_size(Path::new("a.webp"), 16, 16385).unwrap_err();
        check_save_size(Path::new("a.JPG"), 65536, 1).unwrap_err();
    }

    #[test]
    fn also_names_with_equals_signs() {
        let dir = std::env::temp_dir().join(format!("texsyn-also-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = |name: &str| {
            let p = dir.join(name);
            std::fs::write(&p, b"x").unwrap();
            p.to_str().unwrap().to_string()
        };
        // One '=': split there, whether IN exists or not.
        let a = parse_also("in.png=out.png").unwrap();
        assert_eq!((a.input, a.output), ("in.png".into(), "out.png".into()));
        // Several: the split whose IN is an existing file.
        let eq_in = file("rough=0.5.png");
        let a = parse_also(&format!("{eq_in}=out.png")).unwrap();
        assert_eq!(
            (a.input, a.output),
            (eq_in.clone().into(), "out.png".into())
        );
        let a = parse_also(&format!("plain:{eq_in}=o=1.png")).unwrap();
        assert_eq!((a.input, a.output), (eq_in.into(), "o=1.png".into()));
        let plain_in = file("plain.png");
        let a = parse_also(&format!("{plain_in}=o=2.png")).unwrap();
        assert_eq!((a.input, a.output), (plain_in.into(), "o=2.png".into()));
        // No existing split, or two: errors that say so.
        let e = parse_also("missing=a=b.png").unwrap_err();
        assert!(e.contains("no split whose IN is an existing file"), "{e}");
        let (x, _) = (file("x"), file("x=y"));
        let e = parse_also(&format!("{x}=y=z")).unwrap_err();
        assert!(e.contains("ambiguous"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
