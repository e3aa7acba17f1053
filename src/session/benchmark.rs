//! [`Benchmark`]: the timing loop of `texsyn bench`: the analysis (or nothing, for an
//! analysis file), the upload, then per output size the GPU synthesis time after warm-up
//! runs, the whole synthesis with its read-back, and optionally the time of every
//! dispatch by level and pass kind. Returns a [`BenchmarkTable`] of figures.

use std::sync::Arc;
use std::time::{Duration, Instant};

use super::check_output_size;
use super::ExemplarSource;
use crate::analysis::{self, AnalysisOptions, Progress};
use crate::error::{Error, Result};
use crate::field::Field;
use crate::gpu::synth::GpuSynthesizer;
use crate::gpu::GpuContext;
use crate::passes::{PassKind, SynthParams};

/// Exemplars up to this many pixels are analysed several times and the median reported.
const REPEAT_ANALYSIS_PIXELS: u64 = 256 * 256;
const ANALYSIS_RUNS: usize = 3;
/// What to do about a size the device cannot synthesize in one piece.
const BENCH_HINT: &str = "benchmark smaller sizes (--sizes)";

/// The field for an output of a width and height.
type FieldFor<'a> = Box<dyn Fn(u32, u32) -> Result<Field> + 'a>;

/// Where a [`Benchmark`] is, for a progress display.
#[derive(Clone, Copy, Debug)]
#[non_exhaustive]
pub enum BenchmarkProgress {
    /// The analysis, when it runs once (a large exemplar).
    Analysis(Progress),
    /// Analysis run `run` (from 1) of `runs` starts (a small exemplar, timed repeatedly).
    AnalysisRun {
        /// The run starting, from 1.
        run: usize,
        /// Analysis runs in all.
        runs: usize,
    },
    /// The analysis is over.
    AnalysisDone,
    /// The size `[width, height]` is being timed.
    Size([u32; 2]),
    /// Per-pass run `run` (from 1) of `runs` starts.
    PassRun {
        /// The run starting, from 1.
        run: u32,
        /// Per-pass runs in all at this size.
        runs: u32,
    },
    /// The current size, or its per-pass runs, are over.
    SizeDone,
}

/// Median, fastest and slowest of timed runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Timing {
    /// The median (of an even count, the mean of the middle two).
    pub median: Duration,
    /// The fastest run.
    pub min: Duration,
    /// The slowest run.
    pub max: Duration,
}

impl Timing {
    /// The figures of `times` (at least one).
    pub fn of(mut times: Vec<Duration>) -> Timing {
        times.sort();
        let n = times.len();
        let median = if n % 2 == 1 {
            times[n / 2]
        } else {
            (times[n / 2 - 1] + times[n / 2]) / 2
        };
        Timing {
            median,
            min: times[0],
            max: times[n - 1],
        }
    }
}

/// How the analysis was obtained.
#[derive(Clone, Copy, Debug)]
pub enum AnalysisTiming {
    /// Loaded from an analysis file (the caller timed the load).
    Loaded,
    /// Analysed `runs` times with `threads` threads.
    Analysed {
        /// The times of the runs.
        timing: Timing,
        /// How many runs (1 for large exemplars).
        runs: usize,
        /// The threads the analysis could use.
        threads: usize,
    },
}

/// One size's figures ([`BenchmarkTable::rows`]).
#[derive(Debug)]
pub struct SizeRow {
    /// `[width, height]`.
    pub size: [u32; 2],
    /// GPU time (submit + wait, no read-back) and whole-synthesis time with read-back,
    /// or why the size failed.
    pub result: Result<(Timing, Timing)>,
    /// With [`Benchmark::per_pass`], for a size the device takes: the dispatch times.
    pub passes: Option<Result<PassTable>>,
}

/// The time of one (level, pass kind) in a [`PassTable`].
#[derive(Clone, Debug)]
pub struct PassRow {
    /// Pyramid level.
    pub level: usize,
    /// Pass kind.
    pub kind: PassKind,
    /// Dispatches per run: the median when the pass ran in every run, else the mean
    /// (see `every_run`).
    pub dispatches: f64,
    /// The median over the runs of the summed dispatch times (the mean when the pass ran
    /// in some runs only, since the median of mostly-zero runs would read as 0).
    pub time: Duration,
    /// Whether the pass ran in every run.
    pub every_run: bool,
}

/// Dispatch times by level and pass kind, in schedule order.
#[derive(Clone, Debug)]
pub struct PassTable {
    /// By level, each level's passes in the order they first ran.
    pub rows: Vec<PassRow>,
    /// The sum of the rows' times.
    pub total: Duration,
}

impl PassTable {
    /// Gathers profiled runs (each a list of `(kind, level, time)` per dispatch).
    ///
    /// ```
    /// use std::time::Duration;
    /// use texsyn::passes::PassKind;
    /// let ms = Duration::from_millis;
    /// let runs = vec![
    ///     vec![(PassKind::Correct, 0, ms(2)), (PassKind::Correct, 0, ms(1))],
    ///     vec![(PassKind::Correct, 0, ms(4))],
    ///     vec![(PassKind::Correct, 0, ms(2))],
    /// ];
    /// let table = texsyn::PassTable::from_runs(&runs);
    /// assert_eq!(table.total, ms(3)); // the median of 3, 4 and 2 ms
    /// ```
    pub fn from_runs(runs: &[Vec<(PassKind, usize, Duration)>]) -> PassTable {
        // ((level, pass), dispatches per run, time per run)
        type Group = ((usize, PassKind), Vec<usize>, Vec<Duration>);
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
        groups.sort_by_key(|g| g.0 .0);
        let n = runs.len().max(1);
        let rows: Vec<PassRow> = groups
            .into_iter()
            .map(|((level, kind), mut counts, sums)| {
                let every_run = counts.iter().all(|&c| c > 0);
                let (dispatches, time) = if every_run {
                    counts.sort_unstable();
                    (counts[counts.len() / 2] as f64, Timing::of(sums).median)
                } else {
                    (
                        counts.iter().sum::<usize>() as f64 / n as f64,
                        sums.iter().sum::<Duration>() / n as u32,
                    )
                };
                PassRow {
                    level,
                    kind,
                    dispatches,
                    time,
                    every_run,
                }
            })
            .collect();
        let total = rows.iter().map(|r| r.time).sum();
        PassTable { rows, total }
    }
}

/// The figures of a [`Benchmark`].
#[derive(Debug)]
pub struct BenchmarkTable {
    /// The adapter, as [`GpuContext::describe`] gives it.
    pub adapter: String,
    /// Analysed exemplar `[width, height]`.
    pub exemplar_size: [u32; 2],
    /// Its channels (1 or 3).
    pub channels: u32,
    /// Its pyramid levels.
    pub levels: usize,
    /// Its similarity-set size.
    pub k: u32,
    /// Whether it was analysed as tileable.
    pub tileable: bool,
    /// How the analysis was obtained.
    pub analysis: AnalysisTiming,
    /// The upload to the GPU.
    pub upload: Duration,
    /// Correction passes at the second-finest level (the default resolved).
    pub second_finest_passes: u32,
    /// One row per size, in the order given.
    pub rows: Vec<SizeRow>,
}

/// Times the analysis and the GPU synthesis at several output sizes.
///
/// ```no_run
/// use texsyn::{Benchmark, ExemplarSource};
/// let source = ExemplarSource::open("assets/gravel.png".as_ref())?;
/// let table = Benchmark::new(source).sizes(&[[256, 256], [512, 512]]).runs(5).run()?;
/// for row in &table.rows {
///     if let Ok((gpu, _)) = &row.result {
///         println!("{:?}: {:?}", row.size, gpu.median);
///     }
/// }
/// # Ok::<(), texsyn::Error>(())
/// ```
pub struct Benchmark<'a> {
    source: Option<ExemplarSource>,
    sizes: Vec<[u32; 2]>,
    runs: u32,
    warmup: u32,
    params: SynthParams,
    field: Option<FieldFor<'a>>,
    per_pass: bool,
    progress: Box<dyn FnMut(BenchmarkProgress) + 'a>,
}

impl<'a> Benchmark<'a> {
    /// A benchmark of `source` at 256, 512, 1024 and 2048 pixels square, 2 warm-up and
    /// 7 timed runs, default parameters.
    pub fn new(source: ExemplarSource) -> Self {
        Benchmark {
            source: Some(source),
            sizes: [256, 512, 1024, 2048].map(|n| [n, n]).to_vec(),
            runs: 7,
            warmup: 2,
            params: SynthParams::default(),
            field: None,
            per_pass: false,
            progress: Box::new(|_| {}),
        }
    }

    /// The output sizes, `[width, height]` each.
    pub fn sizes(mut self, sizes: &[[u32; 2]]) -> Self {
        self.sizes = sizes.to_vec();
        self
    }

    /// Timed runs per size (at least 1).
    pub fn runs(mut self, runs: u32) -> Self {
        self.runs = runs.max(1);
        self
    }

    /// Untimed warm-up runs per size.
    pub fn warmup(mut self, warmup: u32) -> Self {
        self.warmup = warmup;
        self
    }

    /// The synthesis parameters (seed, schedule, standalone, ...); size and field are
    /// set per size.
    pub fn params(mut self, params: SynthParams) -> Self {
        self.params = params;
        self
    }

    /// Anisometric synthesis: the field for an output of the given width and height.
    pub fn field(mut self, field: impl Fn(u32, u32) -> Result<Field> + 'a) -> Self {
        self.field = Some(Box::new(field));
        self
    }

    /// Also time every dispatch on its own ([`SizeRow::passes`]).
    pub fn per_pass(mut self, per_pass: bool) -> Self {
        self.per_pass = per_pass;
        self
    }

    /// Called as the benchmark advances.
    pub fn progress(mut self, f: impl FnMut(BenchmarkProgress) + 'a) -> Self {
        self.progress = Box::new(f);
        self
    }

    /// Runs the benchmark on a headless device. A size that fails has its error in its
    /// row; the others still run.
    pub fn run(mut self) -> Result<BenchmarkTable> {
        let ctx = GpuContext::headless()?;
        let source = self.source.take().expect("given to Benchmark::new");
        // An exemplar the device cannot hold is refused before the analysis.
        source.check_fits(&ctx, AnalysisOptions::default().k)?;
        let (analysis, timing) = match source {
            ExemplarSource::Analysis(a) => (a, AnalysisTiming::Loaded),
            ExemplarSource::Image(ex) => self.analyse(&ex)?,
        };
        let t = Instant::now();
        let synthesizer = GpuSynthesizer::new(&ctx, Arc::new(analysis))?;
        let upload = t.elapsed();
        let a = synthesizer.analysis();
        let mut table = BenchmarkTable {
            adapter: ctx.describe(),
            exemplar_size: [a.width, a.height],
            channels: a.channels,
            levels: a.levels.len(),
            k: a.k,
            tileable: a.tileable,
            analysis: timing,
            upload,
            second_finest_passes: self.params.second_finest_passes.unwrap_or_else(|| {
                crate::passes::plan::default_second_finest_passes(
                    self.params.passes,
                    self.field.is_some(),
                    false,
                    crate::passes::plan::ExemplarShape::of(a),
                )
            }),
            rows: Vec::new(),
        };
        for &[w, h] in &self.sizes.clone() {
            (self.progress)(BenchmarkProgress::Size([w, h]));
            let params = SynthParams {
                width: w,
                height: h,
                field: match &self.field {
                    Some(f) => Some(f(w, h)?),
                    None => None,
                },
                ..self.params.clone()
            };
            let fits = check_output_size(&ctx, w, h, BENCH_HINT).is_ok();
            let result = check_output_size(&ctx, w, h, BENCH_HINT).and_then(|()| {
                let gpu = time_runs(self.warmup, self.runs, || {
                    synthesizer.synthesize(&params).map_err(with_hint)?;
                    ctx.take_uncaptured_errors()
                })?;
                let whole = time_runs(self.warmup.min(1), self.runs, || {
                    synthesizer.synthesize_to_host(&params).map_err(with_hint)?;
                    ctx.take_uncaptured_errors()
                })?;
                Ok((gpu, whole))
            });
            (self.progress)(BenchmarkProgress::SizeDone);
            let passes = (self.per_pass && fits).then(|| self.profile(&ctx, &synthesizer, &params));
            table.rows.push(SizeRow {
                size: [w, h],
                result,
                passes,
            });
        }
        Ok(table)
    }

    /// Analyses `ex`: three times for a small exemplar (the median is reported), once
    /// for a large one.
    fn analyse(&mut self, ex: &crate::Exemplar) -> Result<(crate::Analysis, AnalysisTiming)> {
        let opts = AnalysisOptions::default();
        let runs = if ex.width as u64 * ex.height as u64 <= REPEAT_ANALYSIS_PIXELS {
            ANALYSIS_RUNS
        } else {
            1
        };
        let mut times = Vec::new();
        let mut result = None;
        for run in 1..=runs {
            let t = Instant::now();
            let a = if runs == 1 {
                analysis::analyze(ex, &opts, |p| {
                    (self.progress)(BenchmarkProgress::Analysis(p))
                })?
            } else {
                (self.progress)(BenchmarkProgress::AnalysisRun { run, runs });
                analysis::analyze(ex, &opts, |_| {})?
            };
            times.push(t.elapsed());
            result = Some(a);
        }
        (self.progress)(BenchmarkProgress::AnalysisDone);
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
        let timing = AnalysisTiming::Analysed {
            timing: Timing::of(times),
            runs,
            threads,
        };
        Ok((result.expect("at least one run"), timing))
    }

    /// Per level and pass kind, the median over the timed runs of the dispatch times.
    fn profile(
        &mut self,
        ctx: &GpuContext,
        synthesizer: &GpuSynthesizer,
        params: &SynthParams,
    ) -> Result<PassTable> {
        let total = self.warmup + self.runs;
        let mut runs = Vec::new();
        for i in 0..total {
            (self.progress)(BenchmarkProgress::PassRun {
                run: i + 1,
                runs: total,
            });
            let r = synthesizer.profile(params).map_err(with_hint);
            let r = r.and_then(|r| ctx.take_uncaptured_errors().map(|()| r));
            let r = match r {
                Ok(r) => r,
                Err(e) => {
                    (self.progress)(BenchmarkProgress::SizeDone);
                    return Err(e);
                }
            };
            if i >= self.warmup {
                runs.push(r);
            }
        }
        (self.progress)(BenchmarkProgress::SizeDone);
        Ok(PassTable::from_runs(&runs))
    }
}

/// Runs `f` `warmup` times untimed, then `runs` times timed.
fn time_runs(warmup: u32, runs: u32, mut f: impl FnMut() -> Result<()>) -> Result<Timing> {
    for _ in 0..warmup {
        f()?;
    }
    let mut times = Vec::with_capacity(runs as usize);
    for _ in 0..runs {
        let t = Instant::now();
        f()?;
        times.push(t.elapsed());
    }
    Ok(Timing::of(times))
}

/// An "output too large" error with the benchmark's advice.
fn with_hint(e: Error) -> Error {
    match e {
        Error::TooLarge {
            what: "output",
            width,
            height,
            limit,
            ..
        } => Error::TooLarge {
            what: "output",
            width,
            height,
            limit,
            hint: BENCH_HINT,
        },
        other => other,
    }
}
