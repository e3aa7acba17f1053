//! `texsyn bench`: analysis time and GPU synthesis timings per output size.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use clap::Args;

use texsyn::passes::SynthParams;
use texsyn::{
    AnalysisTiming, Benchmark, BenchmarkProgress, BenchmarkTable, ExemplarSource, PassTable,
};

use super::{channels_name, fail, fmt_duration, parse_sizes, CliResult, Sizes, Ui};

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

pub fn run(ui: &Ui, args: BenchArgs) -> CliResult<()> {
    // A field from a file has one size: read and check it against --sizes before any
    // work (presets are resolved per size, and checked now too: e.g. a zero scale).
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
        for &[w, h] in &args.sizes.0 {
            spec.resolve([0, 0], w, h)?;
        }
    }
    let t = Instant::now();
    // SAFETY: nothing in this process writes the file, and texsyn replaces analysis
    // files by renaming a new one over them, which leaves this mapping intact; another
    // program truncating it in place during the upload would make this process fault
    // (`Analysis::load_mapped`), which a one-shot command accepts for the faster start.
    let source = unsafe { ExemplarSource::open_mapped(&args.exemplar)? };
    let read_time = t.elapsed();
    if matches!(source, ExemplarSource::Image(_)) {
        ui.warn_if_animation(&args.exemplar);
    }
    let params = SynthParams {
        seed: args.seed.seed,
        passes: args.schedule.passes,
        second_finest_passes: args.schedule.second_finest_passes,
        finest_passes: args.schedule.finest_passes,
        sets_every: args.schedule.sets_every,
        distance: args.schedule.distance,
        standalone: args.standalone,
        ..SynthParams::default()
    };
    let mut analysis_progress = ui.analysis_progress();
    let mut bench = Benchmark::new(source)
        .sizes(&args.sizes.0)
        .runs(args.runs)
        .warmup(args.warmup)
        .params(params)
        .per_pass(args.per_pass)
        .progress(|p| match p {
            BenchmarkProgress::Analysis(p) => analysis_progress(p),
            BenchmarkProgress::AnalysisRun { run, runs } => {
                ui.progress(format!("analysis run {run}/{runs}"))
            }
            BenchmarkProgress::Size([w, h]) => ui.progress(format!("benchmarking {w}x{h}")),
            BenchmarkProgress::PassRun { run, runs } => {
                ui.progress(format!("per-pass run {run}/{runs}"))
            }
            _ => ui.end_progress(),
        });
    if let Some(spec) = &args.field {
        bench = bench.field(move |w, h| match &file_field {
            Some(f) => Ok(f.clone()),
            None => spec
                .resolve([0, 0], w, h)
                .map_err(|e| texsyn::Error::InvalidParameter(e.to_string())),
        });
    }
    let table = bench.run()?;
    print_table(ui, &args, &table, read_time)
}

/// The table on stdout; an error naming the sizes that failed, if any.
fn print_table(
    ui: &Ui,
    args: &BenchArgs,
    table: &BenchmarkTable,
    read_time: Duration,
) -> CliResult<()> {
    ui.out(format!("adapter: {}", table.adapter))?;
    ui.out(format!(
        "exemplar: {} ({}x{} {}, {} levels, k = {}, {}tileable)",
        args.exemplar.display(),
        table.exemplar_size[0],
        table.exemplar_size[1],
        channels_name(table.channels),
        table.levels,
        table.k,
        if table.tileable { "" } else { "not " }
    ))?;
    ui.out(match table.analysis {
        AnalysisTiming::Loaded => format!(
            "analysis: loaded from an analysis file in {}",
            fmt_duration(read_time)
        ),
        AnalysisTiming::Analysed {
            timing,
            runs: 1,
            threads,
        } => format!(
            "analysis: {} (1 run, {threads} threads)",
            fmt_duration(timing.median)
        ),
        AnalysisTiming::Analysed {
            timing,
            runs,
            threads,
        } => format!(
            "analysis: {} (median of {runs} runs, min {}, max {}; {threads} threads)",
            fmt_duration(timing.median),
            fmt_duration(timing.min),
            fmt_duration(timing.max),
        ),
    })?;
    ui.out(format!(
        "GPU upload: {} (pipelines are built on first use, inside the warm-up)",
        fmt_duration(table.upload)
    ))?;
    ui.out(format!(
        "synthesis: {} passes ({} at the second-finest level, {} at the finest), similarity sets every {}, {:?} distance, {}, seed {}; {} warm-up + {} timed runs per size; GPU = submit + wait, no read-back",
        args.schedule.passes,
        table.second_finest_passes,
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
    // A size that fails shows its error in its row; the exit status then says that the
    // table is incomplete.
    let mut failed: Vec<String> = Vec::new();
    for row in &table.rows {
        let [w, h] = row.size;
        let size = format!("{w}x{h}");
        ui.out(match &row.result {
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
        })?;
        match &row.passes {
            Some(Ok(passes)) => print_passes(ui, passes, "one submission per dispatch")?,
            Some(Err(e)) => return Err(fail(e.to_string())),
            None => {}
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

/// Per (level, pass kind), in schedule order: the dispatches of one run and the median
/// over the runs of their summed times, then the sum of the medians.
pub fn print_pass_table(
    ui: &Ui,
    runs: &[Vec<(texsyn::passes::PassKind, usize, Duration)>],
    note: &str,
) -> CliResult<()> {
    print_passes(ui, &PassTable::from_runs(runs), note)
}

fn print_passes(ui: &Ui, table: &PassTable, note: &str) -> CliResult<()> {
    ui.out(format!(
        "  {:<6} {:<14} {:>10} {:>11}",
        "level", "pass", "dispatches", "median"
    ))?;
    for row in &table.rows {
        // A pass that runs in some runs only shows its mean per run, marked.
        let dispatches = if row.every_run {
            format!("{}", row.dispatches as usize)
        } else {
            format!("{:.1}*", row.dispatches)
        };
        ui.out(format!(
            "  {:<6} {:<14} {:>10} {:>11}",
            row.level,
            format!("{:?}", row.kind),
            dispatches,
            fmt_duration(row.time)
        ))?;
    }
    if table.rows.iter().any(|r| !r.every_run) {
        ui.out("  * ran in some runs only: mean per run of the dispatches and the time")?;
    }
    ui.out(format!(
        "  sum of medians ({note}): {}",
        fmt_duration(table.total)
    ))?;
    Ok(())
}
