//! `texsyn bench`: analysis time and GPU synthesis timings per output size.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use clap::Args;

use texsyn::analysis::{self, AnalysisOptions};
use texsyn::gpu::synth::GpuSynthesizer;
use texsyn::gpu::GpuContext;
use texsyn::passes::SynthParams;

use super::synth::{read_source, with_hint, Source};
use super::{
    channels_name, check_output_size_hint, fail, fmt_duration, parse_sizes, CliResult, Sizes, Ui,
};

/// Exemplars up to this many pixels are analysed several times and the median reported.
const REPEAT_ANALYSIS_PIXELS: u64 = 256 * 256;
const ANALYSIS_RUNS: usize = 3;

/// Time the analysis and the GPU synthesis at several output sizes; prints a table
#[derive(Args, Debug)]
#[command(
    long_about = "Time the analysis and the GPU synthesis at several output sizes; prints a table on stdout.\n\n\
                  For each size: GPU synthesis time (submit + wait for the device, nothing read \
                  back) after the warm-up runs, as median, min and max of --runs runs, and \
                  output pixels per second from the median; then the median of as many whole \
                  syntheses including the read-back of colours and coordinates to the host. A \
                  size the device cannot handle shows its error in its row."
)]
pub struct BenchArgs {
    /// Exemplar image, or an analysis file (then the load time is reported instead)
    pub exemplar: PathBuf,

    /// Output sizes, comma-separated, each N or WxH
    #[arg(long, value_name = "N[xM],...", default_value = "256,512,1024,2048", value_parser = parse_sizes)]
    pub sizes: Sizes,

    /// Timed runs per size (at least 1)
    #[arg(long, value_name = "N", default_value_t = 7, value_parser = clap::value_parser!(u32).range(1..=10_000))]
    pub runs: u32,

    /// Untimed warm-up runs per size (0..=10000)
    #[arg(long, value_name = "W", default_value_t = 2, value_parser = clap::value_parser!(u32).range(0..=10_000))]
    pub warmup: u32,

    #[command(flatten)]
    pub seed: super::SeedArg,

    #[command(flatten)]
    pub schedule: super::ScheduleArgs,

    /// Time standalone textures (as `texsyn synth --standalone`)
    #[arg(long)]
    pub standalone: bool,

    /// Anisometric synthesis along a field (as `texsyn synth --field`; give a single
    /// --sizes with a map from a file: it must have the benchmarked size)
    #[arg(long, value_name = "SPEC", value_parser = super::field::parse_field)]
    pub field: Option<super::field::FieldSpec>,

    /// Also time every dispatch on its own and print the time by level and pass kind
    #[arg(long)]
    pub per_pass: bool,
}

struct Stats {
    median: Duration,
    min: Duration,
    max: Duration,
}

fn stats(mut times: Vec<Duration>) -> Stats {
    times.sort();
    let n = times.len();
    let median = if n % 2 == 1 {
        times[n / 2]
    } else {
        (times[n / 2 - 1] + times[n / 2]) / 2
    };
    Stats {
        median,
        min: times[0],
        max: times[n - 1],
    }
}

/// Runs `f` `warmup` times untimed, then `runs` times timed.
fn time_runs(
    warmup: u32,
    runs: u32,
    mut f: impl FnMut() -> texsyn::Result<()>,
) -> texsyn::Result<Stats> {
    for _ in 0..warmup {
        f()?;
    }
    let mut times = Vec::with_capacity(runs as usize);
    for _ in 0..runs {
        let t = Instant::now();
        f()?;
        times.push(t.elapsed());
    }
    Ok(stats(times))
}

/// What to do about a size the device cannot synthesize in one piece.
const BENCH_HINT: &str = "benchmark smaller sizes (--sizes)";

pub fn run(ui: &Ui, args: BenchArgs) -> CliResult<()> {
    // A field from a file has one size: read and check it against --sizes before any
    // work (presets are resolved per size below).
    let mut file_field = None;
    if let Some((spec, file)) = args.field.as_ref().and_then(|f| f.file().map(|p| (f, p))) {
        let [[w, h]] = args.sizes.0.as_slice() else {
            return Err(fail(format!(
                "--field {}: a field from a file has one size; give that size alone in --sizes",
                file.display()
            )));
        };
        file_field = Some(spec.resolve([0, 0], *w, *h)?);
    } else if let Some(spec) = &args.field {
        // Presets: their values (e.g. a zero scale) are checked before any work too.
        for &[w, h] in &args.sizes.0 {
            spec.resolve([0, 0], w, h)?;
        }
    }
    let t = Instant::now();
    let source = read_source(ui, &args.exemplar, None, None)?;
    let read_time = t.elapsed();
    let ctx = GpuContext::headless()?;
    // An exemplar the device cannot hold is refused before the analysis.
    source.check_fits(&ctx, AnalysisOptions::default().k)?;
    let (analysis, analysis_line) = match source {
        Source::Analysis(a) => (
            a,
            format!(
                "analysis: loaded from an analysis file in {}",
                fmt_duration(read_time)
            ),
        ),
        Source::Image(ex) => {
            let opts = AnalysisOptions::default();
            let runs = if ex.width as u64 * ex.height as u64 <= REPEAT_ANALYSIS_PIXELS {
                ANALYSIS_RUNS
            } else {
                1
            };
            let mut times = Vec::new();
            let mut result = None;
            for i in 0..runs {
                let t = Instant::now();
                let a = if runs == 1 {
                    // One long run: show its levels.
                    analysis::analyze(&ex, &opts, ui.analysis_progress())?
                } else {
                    ui.progress(format!("analysis run {}/{runs}", i + 1));
                    analysis::analyze(&ex, &opts, |_| {})?
                };
                times.push(t.elapsed());
                result = Some(a);
            }
            ui.end_progress();
            let s = stats(times);
            let line = if runs == 1 {
                format!(
                    "analysis: {} (1 run, {} threads)",
                    fmt_duration(s.median),
                    threads()
                )
            } else {
                format!(
                    "analysis: {} (median of {runs} runs, min {}, max {}; {} threads)",
                    fmt_duration(s.median),
                    fmt_duration(s.min),
                    fmt_duration(s.max),
                    threads()
                )
            };
            (result.expect("at least one run"), line)
        }
    };

    let t = Instant::now();
    let summary = format!(
        "exemplar: {} ({}x{} {}, {} levels, k = {}, {}tileable)",
        args.exemplar.display(),
        analysis.width,
        analysis.height,
        channels_name(analysis.channels),
        analysis.levels.len(),
        analysis.k,
        if analysis.tileable { "" } else { "not " }
    );
    let synthesizer = GpuSynthesizer::new(&ctx, Arc::new(analysis))?;
    let upload = t.elapsed();

    ui.out(format!("adapter: {}", ctx.describe()))?;
    ui.out(summary)?;
    ui.out(analysis_line)?;
    ui.out(format!(
        "GPU upload: {} (pipelines are built on first use, inside the warm-up)",
        fmt_duration(upload)
    ))?;
    ui.out(format!(
        "synthesis: {} passes ({} at the second-finest level, {} at the finest), similarity sets every {}, {:?} distance, {}, seed {}; {} warm-up + {} timed runs per size; GPU = submit + wait, no read-back",
        args.schedule.passes,
        args.schedule.second_finest_passes.unwrap_or_else(|| {
            texsyn::passes::plan::default_second_finest_passes(
                args.schedule.passes,
                args.field.is_some() || file_field.is_some(),
                false,
                texsyn::passes::plan::ExemplarShape::of(synthesizer.analysis()),
            )
        }),
        args.schedule.finest_passes,
        args.schedule.sets_every,
        args.schedule.distance,
        if args.standalone { "standalone textures" } else { "exact windows" },
        args.seed.seed,
        args.warmup,
        args.runs
    ))?;
    ui.out(match &args.field {
        Some(f) => format!("field: {}", f.spec()),
        None => "field: none (isometric)".to_string(),
    })?;
    ui.out("")?;
    ui.out(format!(
        "{:<11} {:>11} {:>11} {:>11} {:>11} {:>16}",
        "size", "GPU median", "GPU min", "GPU max", "Mpixel/s", "incl. read-back"
    ))?;

    // A size that fails shows its error in its row; the others still run, and the exit
    // status then says that the table is incomplete.
    let mut failed: Vec<String> = Vec::new();
    for &[w, h] in &args.sizes.0 {
        let size = format!("{w}x{h}");
        ui.progress(format!("benchmarking {size}"));
        let params = SynthParams {
            width: w,
            height: h,
            seed: args.seed.seed,
            passes: args.schedule.passes,
            second_finest_passes: args.schedule.second_finest_passes,
            finest_passes: args.schedule.finest_passes,
            sets_every: args.schedule.sets_every,
            distance: args.schedule.distance,
            standalone: args.standalone,
            field: match (&file_field, &args.field) {
                (Some(f), _) => Some(f.clone()),
                (None, Some(f)) => Some(f.resolve([0, 0], w, h)?),
                (None, None) => None,
            },
            ..SynthParams::default()
        };
        let row = check_output_size_hint(&ctx, w, h, BENCH_HINT).and_then(|()| {
            let gpu = time_runs(args.warmup, args.runs, || {
                synthesizer
                    .synthesize(&params)
                    .map_err(|e| with_hint(e, BENCH_HINT))?;
                ctx.take_uncaptured_errors()
            })?;
            let whole = time_runs(args.warmup.min(1), args.runs, || {
                synthesizer
                    .synthesize_to_host(&params)
                    .map_err(|e| with_hint(e, BENCH_HINT))?;
                ctx.take_uncaptured_errors()
            })?;
            Ok((gpu, whole))
        });
        ui.end_progress();
        let line = match row {
            Ok((gpu, whole)) => format!(
                "{:<11} {:>11} {:>11} {:>11} {:>11.3} {:>16}",
                size,
                fmt_duration(gpu.median),
                fmt_duration(gpu.min),
                fmt_duration(gpu.max),
                w as f64 * h as f64 / gpu.median.as_secs_f64() / 1e6,
                fmt_duration(whole.median)
            ),
            Err(e) => {
                failed.push(size.clone());
                format!("{size:<11} error: {e}")
            }
        };
        ui.out(line)?;
        if args.per_pass && check_output_size_hint(&ctx, w, h, BENCH_HINT).is_ok() {
            per_pass_table(ui, &ctx, &synthesizer, &params, &args)?;
        }
    }
    if !failed.is_empty() {
        return Err(fail(format!(
            "{} of the sizes failed ({}): see their rows above",
            failed.len(),
            failed.join(", ")
        )));
    }
    Ok(())
}

/// Per level and pass kind, the median over `--runs` of the summed dispatch times.
fn per_pass_table(
    ui: &Ui,
    ctx: &GpuContext,
    synthesizer: &GpuSynthesizer,
    params: &SynthParams,
    args: &BenchArgs,
) -> CliResult<()> {
    let mut runs: Vec<Vec<(texsyn::passes::PassKind, usize, Duration)>> = Vec::new();
    for i in 0..args.warmup + args.runs {
        ui.progress(format!(
            "per-pass run {}/{}",
            i + 1,
            args.warmup + args.runs
        ));
        let r = synthesizer
            .profile(params)
            .map_err(|e| with_hint(e, BENCH_HINT))?;
        ctx.take_uncaptured_errors()?;
        if i >= args.warmup {
            runs.push(r);
        }
    }
    ui.end_progress();
    print_pass_table(ui, &runs, "one submission per dispatch")
}

/// Per (level, pass kind), in schedule order: the dispatches of one run and the median
/// over the runs of their summed times, then the sum of the medians.
pub fn print_pass_table(
    ui: &Ui,
    runs: &[Vec<(texsyn::passes::PassKind, usize, Duration)>],
    note: &str,
) -> CliResult<()> {
    // Per (level, pass): dispatches and time summed within each run. A pass that runs in
    // some runs only (advection corrects a level every other frame) shows its mean per
    // run, marked, since the median of mostly-zero runs would read as 0.
    // ((level, pass), dispatches per run, time per run)
    type Group = ((usize, texsyn::passes::PassKind), Vec<usize>, Vec<Duration>);
    let mut groups: Vec<Group> = Vec::new();
    for (r, run) in runs.iter().enumerate() {
        for &(kind, level, t) in run {
            let i = match groups.iter().position(|g| g.0 == (level, kind)) {
                Some(i) => i,
                None => {
                    groups.push((
                        (level, kind),
                        vec![0; runs.len()],
                        vec![Duration::ZERO; runs.len()],
                    ));
                    groups.len() - 1
                }
            };
            groups[i].1[r] += 1;
            groups[i].2[r] += t;
        }
    }
    // By level, each level's passes in the order they first ran.
    groups.sort_by_key(|g| g.0 .0);
    let mut total = Duration::ZERO;
    let mut any_partial = false;
    ui.out(format!(
        "  {:<6} {:<14} {:>10} {:>11}",
        "level", "pass", "dispatches", "median"
    ))?;
    let n = runs.len().max(1);
    for ((level, kind), counts, sums) in groups {
        let every_run = counts.iter().all(|&c| c > 0);
        let (dispatches, time) = if every_run {
            (
                {
                    let mut c = counts.clone();
                    c.sort_unstable();
                    c[c.len() / 2].to_string()
                },
                stats(sums).median,
            )
        } else {
            any_partial = true;
            (
                format!("{:.1}*", counts.iter().sum::<usize>() as f64 / n as f64),
                sums.iter().sum::<Duration>() / n as u32,
            )
        };
        total += time;
        ui.out(format!(
            "  {:<6} {:<14} {:>10} {:>11}",
            level,
            format!("{kind:?}"),
            dispatches,
            fmt_duration(time)
        ))?;
    }
    if any_partial {
        ui.out("  * ran in some runs only: mean per run of the dispatches and the time")?;
    }
    ui.out(format!(
        "  sum of medians ({note}): {}",
        fmt_duration(total)
    ))?;
    Ok(())
}

fn threads() -> usize {
    std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
}
