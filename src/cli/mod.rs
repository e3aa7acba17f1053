//! The `texsyn` command line: argument parsing (clap derive) and the subcommands, a
//! thin layer over the library. Errors are printed as `error: <message>` and give exit
//! code 1; usage errors are clap's (exit code 2).

mod advect;
mod analyze;
mod bench;
mod eval;
mod field;
mod frames;
mod interrupt;
mod surface;
mod synth;

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::time::Duration;

use clap::{Args, Parser, Subcommand};

use texsyn::analysis::{Progress, Stage};

/// Errors of the CLI: the library's errors and a few of its own, all printed with
/// their `Display`.
pub type CliError = Box<dyn std::error::Error + Send + Sync>;
pub type CliResult<T> = std::result::Result<T, CliError>;

/// An error message of the CLI itself.
pub fn fail(message: impl Into<String>) -> CliError {
    message.into().into()
}

#[derive(Parser, Debug)]
#[command(
    name = "texsyn",
    version,
    about = "Real-time appearance-space texture synthesis (Lefebvre & Hoppe 2006) on the GPU",
    long_about = "Real-time appearance-space texture synthesis (Lefebvre & Hoppe 2006) on the GPU.\n\n\
                  The GPU adapter is chosen automatically (discrete, integrated, then CPU \
                  implementations such as lavapipe); set TEXSYN_BACKEND (vulkan, gl, metal, dx12) \
                  and TEXSYN_ADAPTER (part of an adapter name, or its index) to choose.",
    propagate_version = true
)]
pub struct Cli {
    /// No progress or summaries on stderr (errors are still printed)
    #[arg(short, long, global = true)]
    pub quiet: bool,

    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    Analyze(analyze::AnalyzeArgs),
    Synth(synth::SynthArgs),
    Eval(eval::EvalArgs),
    Bench(bench::BenchArgs),
    Surface(surface::SurfaceArgs),
    Advect(advect::AdvectArgs),
}

/// Help heading of the options that shape the output's content.
pub const LOOK: &str = "Look";
/// Help heading of the options that say what the output is and where it goes.
pub const OUTPUT: &str = "Output";
/// Help heading of the options that guide the synthesis (fields, masks, the exemplar).
pub const CONTROLS: &str = "Controls";
/// Help heading of the tuning knobs, shown by `--help` only.
pub const ADVANCED: &str = "Advanced";

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

/// Checks the loaded `--feature-mask` (if any) against the exemplar it goes with: its
/// size first, then that it is not blank. The analysis accepts a blank mask (it changes
/// nothing), but given on the command line one is a mistake (an empty or inverted export).
pub fn check_feature_mask(
    options: &texsyn::AnalysisOptions,
    width: u32,
    height: u32,
) -> CliResult<()> {
    if let Some(mask) = &options.feature_mask {
        mask.check_size(width, height)?;
        mask.check_not_blank()?;
    }
    Ok(())
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

/// Leaves `value` (a device, an uploaded exemplar) to the end of the process instead of
/// dropping it. Called on a command's success path, when only the exit is left: the OS
/// takes back a device and its memory at once, while the destructors tear down the
/// driver and free the tables piece by piece, which takes longer than the work itself
/// for small outputs.
pub fn leave_to_exit<T>(value: T) {
    std::mem::forget(value);
}

/// Runs the CLI and returns the process exit code.
pub fn main() -> i32 {
    interrupt::install();
    let cli = Cli::parse();
    let ui = Ui::new(cli.quiet);
    let result = match cli.command {
        Command::Analyze(a) => analyze::run(&ui, a),
        Command::Synth(a) => synth::run(&ui, a),
        Command::Eval(a) => eval::run(&ui, a),
        Command::Bench(a) => bench::run(&ui, a),
        Command::Surface(a) => surface::run(&ui, a),
        Command::Advect(a) => advect::run(&ui, a),
    };
    match result {
        Ok(()) => 0,
        Err(e) => {
            ui.end_progress();
            stderr_line(format_args!("error: {e}"));
            1
        }
    }
}

// ---------------------------------------------------------------------------------------
// Output to the user
// ---------------------------------------------------------------------------------------

/// One line on stderr. Unlike `eprintln!`, a closed or broken stderr (`texsyn ... 2>&1 |
/// head -1`) does not panic: messages are lost, the work and its exit code are not.
pub fn stderr_line(args: std::fmt::Arguments) {
    let _ = writeln!(std::io::stderr().lock(), "{args}");
}

/// Where messages go: progress and summaries to stderr (unless quiet), results to stdout.
pub struct Ui {
    pub quiet: bool,
    /// stderr is a terminal: progress lines are overwritten in place.
    tty: bool,
    /// A `\r` progress line is open on stderr.
    open_line: std::cell::Cell<bool>,
}

impl Ui {
    fn new(quiet: bool) -> Self {
        Ui {
            quiet,
            tty: std::io::stderr().is_terminal(),
            open_line: std::cell::Cell::new(false),
        }
    }

    /// A line of information on stderr (silenced by `--quiet`).
    pub fn info(&self, line: impl AsRef<str>) {
        if !self.quiet {
            self.end_progress();
            stderr_line(format_args!("{}", line.as_ref()));
        }
    }

    /// A progress line: overwritten in place on a terminal, one line each otherwise.
    pub fn progress(&self, line: impl AsRef<str>) {
        if self.quiet {
            return;
        }
        if self.tty {
            // Clear to the end of the line: the new text may be shorter.
            let mut err = std::io::stderr().lock();
            let _ = write!(err, "\r{}\x1b[K", line.as_ref()).and_then(|_| err.flush());
            self.open_line.set(true);
        } else {
            stderr_line(format_args!("{}", line.as_ref()));
        }
    }

    /// Ends an open `\r` progress line.
    pub fn end_progress(&self) {
        if self.open_line.replace(false) {
            stderr_line(format_args!(""));
        }
    }

    /// Analysis progress callback: `analysing level 3/8` after each level and, while a
    /// level is under way, `analysing level 4/8: similarity sets 40%` (every step on a
    /// terminal; otherwise only when 5 s have passed without a line, so that logs of
    /// small exemplars stay one line per level and large ones never go quiet).
    pub fn analysis_progress(&self) -> impl FnMut(Progress) + '_ {
        let mut last = std::time::Instant::now();
        move |p: Progress| {
            if p.stage == Stage::LevelDone {
                self.progress(format!("analysing level {}/{}", p.done, p.total));
                last = std::time::Instant::now();
                if p.done == p.total {
                    self.end_progress();
                }
                return;
            }
            if !self.tty && last.elapsed() < std::time::Duration::from_secs(5) {
                return;
            }
            last = std::time::Instant::now();
            let percent = if p.fraction > 0.0 {
                format!(" {:.0}%", 100.0 * p.fraction)
            } else {
                String::new()
            };
            let level = if p.stage == Stage::Stack {
                String::new()
            } else {
                format!(" level {}/{}:", p.done + 1, p.total)
            };
            self.progress(format!("analysing{level} {}{percent}", p.stage.name()));
        }
    }

    /// Loads an exemplar image, with a warning when it is an animation (only its first
    /// frame is used).
    pub fn load_exemplar(&self, path: &Path) -> texsyn::Result<texsyn::Exemplar> {
        let ex = texsyn::image_io::load_exemplar(path)?;
        self.warn_if_animation(path);
        Ok(ex)
    }

    /// A warning when the image at `path` is an animation: texsyn uses its first frame.
    pub fn warn_if_animation(&self, path: &Path) {
        if let Some(n @ 2..) = texsyn::image_io::animation_frames(path) {
            self.info(format!(
                "warning: {} is an animation of {n} frames; texsyn uses its first frame \
                 (extract another frame to use it)",
                path.display()
            ));
        }
    }

    /// A result on stdout (never silenced); a closed stdout is an error, not a panic.
    pub fn out(&self, text: impl AsRef<str>) -> CliResult<()> {
        let mut stdout = std::io::stdout().lock();
        writeln!(stdout, "{}", text.as_ref())
            .and_then(|_| stdout.flush())
            .map_err(|e| fail(format!("cannot write to standard output: {e}")))
    }
}

// ---------------------------------------------------------------------------------------
// Value parsers and helpers shared by the subcommands
// ---------------------------------------------------------------------------------------

/// `--dt` of `advect` and `eval --flow`, read as f64 so that a step too large for the
/// frames' f32 arithmetic is named as such (as f32 it would read as `inf`).
pub fn time_step(dt: f64) -> CliResult<f32> {
    if dt.is_nan() || dt <= 0.0 {
        return Err(fail(format!(
            "--dt {dt}: the time step must be a positive number"
        )));
    }
    if dt > f32::MAX as f64 {
        return Err(fail(format!(
            "--dt {dt:e}: too large for 32-bit floats (at most {:e}; a frame moves at most {} \
             pixels anyway)",
            f32::MAX,
            texsyn::passes::advect::MAX_SPEED
        )));
    }
    if (dt as f32) <= 0.0 {
        return Err(fail(format!(
            "--dt {dt:e}: too small for 32-bit floats (it rounds to 0): give a positive \
             step of at least {:e}",
            f32::from_bits(1)
        )));
    }
    Ok(dt as f32)
}

/// A seed: an integer in `0..=u32::MAX`. Negative and other values get a message
/// naming the range (clap's default for `u32` says only "invalid digit").
pub fn parse_seed(s: &str) -> Result<u32, String> {
    s.trim()
        .parse::<u32>()
        .map_err(|_| format!("seed \"{s}\": give an integer from 0 to {}", u32::MAX))
}

/// `N` or `NxM` (also `N×M` / `NXM`), both at least 1.
pub fn parse_size(s: &str) -> Result<[u32; 2], String> {
    let t = s.trim();
    let usage = || format!("\"{s}\" is not a size: expected N or NxM, e.g. 512 or 1024x768");
    let parts: Vec<&str> = t.split(['x', 'X', '×']).collect();
    let side = |p: &str| -> Result<u32, String> {
        let p = p.trim();
        if p.is_empty() || !p.bytes().all(|b| b.is_ascii_digit()) {
            return Err(usage());
        }
        let v: u32 = p.parse().map_err(|_| {
            format!(
                "size \"{s}\": {p} is too large (at most {} pixels a side)",
                u32::MAX
            )
        })?;
        if v == 0 {
            return Err(format!("size \"{s}\": width and height must be at least 1"));
        }
        Ok(v)
    };
    match parts.as_slice() {
        [n] => {
            let n = side(n)?;
            Ok([n, n])
        }
        [w, h] => Ok([side(w)?, side(h)?]),
        _ => Err(usage()),
    }
}

/// A list of sizes (a newtype: clap treats a bare `Vec` field as repeated values).
#[derive(Clone, Debug, PartialEq)]
pub struct Sizes(pub Vec<[u32; 2]>);

/// A comma-separated list of sizes.
pub fn parse_sizes(s: &str) -> Result<Sizes, String> {
    let sizes: Vec<[u32; 2]> = s.split(',').map(parse_size).collect::<Result<_, _>>()?;
    if sizes.is_empty() {
        return Err("give at least one size".into());
    }
    Ok(Sizes(sizes))
}

/// Per-level randomness values (a newtype, see [`Sizes`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Randomness(pub Vec<f32>);

/// `R` or `R0,R1,...`: finite values in [0, 2].
pub fn parse_randomness(s: &str) -> Result<Randomness, String> {
    let mut out = Vec::new();
    for part in s.split(',') {
        let p = part.trim();
        let v: f32 = p.parse().map_err(|_| {
            format!("\"{p}\" is not a number (expected R or R0,R1,... with values in [0, 2])")
        })?;
        if !v.is_finite() || !(0.0..=2.0).contains(&v) {
            return Err(format!("randomness {p} must be between 0 and 2"));
        }
        out.push(v);
    }
    Ok(Randomness(out))
}

/// `X,Y` (integers, may be negative).
pub fn parse_window(s: &str) -> Result<[i32; 2], String> {
    let usage = || {
        format!("\"{s}\" is not a window origin: expected X,Y (integers, e.g. 0,0 or -512,1024)")
    };
    let parts: Vec<&str> = s.split(',').collect();
    let [x, y] = parts.as_slice() else {
        return Err(usage());
    };
    let x: i32 = x.trim().parse().map_err(|_| usage())?;
    let y: i32 = y.trim().parse().map_err(|_| usage())?;
    // Keep well inside i32 so the plan's margins cannot overflow.
    const LIMIT: i32 = 1 << 28;
    if x.unsigned_abs() > LIMIT as u32 || y.unsigned_abs() > LIMIT as u32 {
        return Err(format!(
            "window origin {x},{y}: coordinates must lie within +-{LIMIT}"
        ));
    }
    Ok([x, y])
}

/// Coherence in [0, 1].
pub fn parse_coherence(s: &str) -> Result<f32, String> {
    let v: f32 = s
        .trim()
        .parse()
        .map_err(|_| format!("\"{s}\" is not a number"))?;
    if !v.is_finite() || !(0.0..=4.0).contains(&v) {
        return Err(format!("coherence {s} must be between 0 and 4"));
    }
    Ok(v)
}

/// Checks, before any work, that `path` can be created: its directory exists.
/// (The file itself is only written, atomically, once the work has succeeded.)
/// `dir`, where `path` is to be written, must be an existing directory.
pub fn check_parent_dir(path: &Path, dir: &Path) -> CliResult<()> {
    if dir.is_dir() {
        return Ok(());
    }
    Err(fail(if dir.exists() {
        format!(
            "cannot write {}: {} is not a directory",
            path.display(),
            dir.display()
        )
    } else {
        format!(
            "cannot write {}: directory {} does not exist; create it first",
            path.display(),
            dir.display()
        )
    }))
}

/// An output that must be a named file or folder: `-` (standard output for `synth`'s
/// image) is refused rather than taken for a file named `-`.
pub fn parse_named_output(s: &str) -> Result<PathBuf, String> {
    if s == "-" {
        return Err(
            "`-` (standard output) is only for synth's image; give a file or folder \
                    name (./- for one named `-`)"
                .into(),
        );
    }
    Ok(PathBuf::from(s))
}

pub fn check_output_dir(path: &Path) -> CliResult<()> {
    if path.file_name().is_none() {
        return Err(fail(format!(
            "cannot write {}: the path does not name a file",
            path.display()
        )));
    }
    if path.is_dir() {
        return Err(fail(format!(
            "cannot write {}: it is a directory; give a file name",
            path.display()
        )));
    }
    if std::fs::symlink_metadata(path).is_ok() && !path.exists() {
        return Err(fail(format!(
            "cannot write {}: it is a symbolic link to a missing path; remove it or give \
             another name",
            path.display()
        )));
    }
    // A device or pipe (`-o /dev/null`) is written to as it is, not replaced (opening a
    // pipe now would wait for its reader: the write reports any error).
    if std::fs::metadata(path).is_ok_and(|m| !m.is_file()) {
        return Ok(());
    }
    // A symlink names the file it points to (which is replaced), in that file's directory.
    let resolved;
    let path = match std::fs::canonicalize(path) {
        Ok(p) if std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink()) => {
            resolved = p;
            resolved.as_path()
        }
        _ => path,
    };
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    check_parent_dir(path, &dir)?;
    // Probe that the directory takes new files (read-only mounts, /proc, permissions):
    // failing now costs nothing, failing after the work would leave other outputs half
    // written.
    takes_new_files(&dir).map_err(|e| {
        fail(format!(
            "cannot write {}: the directory {} does not take new files ({e}); choose a \
             writable folder",
            path.display(),
            dir.display()
        ))
    })
}

/// Whether `dir` takes new files: a probe file is created and removed.
pub fn takes_new_files(dir: &Path) -> std::io::Result<()> {
    let probe = dir.join(format!(".texsyn-probe-{}", std::process::id()));
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// Refuses two outputs of one command that name the same file (the later write would
/// silently replace the earlier one).
pub fn check_distinct_outputs(paths: &[&Path]) -> CliResult<()> {
    let key = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    for (i, a) in paths.iter().enumerate() {
        for b in &paths[..i] {
            if key(a) == key(b) {
                return Err(fail(format!(
                    "{} is given for two outputs; give each output its own file",
                    a.display()
                )));
            }
        }
    }
    Ok(())
}

/// Refuses an output that names one of the command's own inputs: the output would
/// silently replace it (an exemplar, a coordinate map, a mesh). Inputs are labelled for
/// the message, e.g. `("exemplar", path)`. An output that does not exist yet cannot be
/// an input; existing files are compared as files (links and `./x` vs `x` included).
pub fn check_outputs_not_inputs(outputs: &[&Path], inputs: &[(&str, &Path)]) -> CliResult<()> {
    for out in outputs {
        let Ok(out_meta) = std::fs::metadata(out) else {
            continue;
        };
        for (what, input) in inputs {
            let Ok(in_meta) = std::fs::metadata(input) else {
                continue;
            };
            if same_file(out, &out_meta, input, &in_meta) {
                return Err(fail(format!(
                    "{} is also the {what}, an input: writing it would replace the input; \
                     give the output another name",
                    out.display()
                )));
            }
        }
    }
    Ok(())
}

#[cfg(unix)]
fn same_file(_: &Path, a: &std::fs::Metadata, _: &Path, b: &std::fs::Metadata) -> bool {
    use std::os::unix::fs::MetadataExt;
    a.dev() == b.dev() && a.ino() == b.ino()
}

#[cfg(not(unix))]
fn same_file(a: &Path, _: &std::fs::Metadata, b: &Path, _: &std::fs::Metadata) -> bool {
    matches!((std::fs::canonicalize(a), std::fs::canonicalize(b)), (Ok(x), Ok(y)) if x == y)
}

/// `12.3 ms`, `1.23 s`, `850 us`.
pub fn fmt_duration(d: Duration) -> String {
    let s = d.as_secs_f64();
    if s >= 10.0 {
        format!("{s:.1} s")
    } else if s >= 1.0 {
        format!("{s:.2} s")
    } else if s >= 1e-3 {
        format!("{:.1} ms", s * 1e3)
    } else {
        format!("{:.0} us", s * 1e6)
    }
}

/// `1.5 MiB`, `12 KiB`, `100 B`.
pub fn fmt_bytes(n: u64) -> String {
    if n >= 1 << 20 {
        format!("{:.1} MiB", n as f64 / (1u64 << 20) as f64)
    } else if n >= 1 << 10 {
        format!("{:.1} KiB", n as f64 / 1024.0)
    } else {
        format!("{n} B")
    }
}

/// `grey` / `RGB`.
pub fn channels_name(channels: u32) -> &'static str {
    if channels == 1 {
        "grey"
    } else {
        "RGB"
    }
}

/// Hint of the "output too large" errors.
pub const WINDOW_HINT: &str = "synthesize it in windows (--window X,Y) and assemble them";

/// The error the library gives for an output larger than the device, checked early:
/// before the analysis (the library checks once the plan exists, i.e. after it) and
/// before the plan (which rejects huge outputs with a less specific message). The
/// buffer check is a lower bound (the finest level alone); the library checks the
/// whole pyramid.
pub fn check_output_size(
    ctx: &texsyn::gpu::GpuContext,
    width: u32,
    height: u32,
) -> texsyn::Result<()> {
    check_output_size_hint(ctx, width, height, WINDOW_HINT)
}

/// The largest buffer a synthesis can bind in one piece (its coordinate pyramid and
/// Jacobian field live in one buffer each).
pub fn max_buffer_binding(ctx: &texsyn::gpu::GpuContext) -> u64 {
    let limits = ctx.limits();
    limits
        .max_storage_buffer_binding_size
        .min(limits.max_buffer_size)
}

/// [`check_output_size`] with the advice to give when the size is too large.
pub fn check_output_size_hint(
    ctx: &texsyn::gpu::GpuContext,
    width: u32,
    height: u32,
    hint: &'static str,
) -> texsyn::Result<()> {
    let limits = ctx.limits();
    let max_dim = limits.max_texture_dimension_2d;
    let too_large = |limit: String| texsyn::Error::TooLarge {
        what: "output",
        width,
        height,
        limit,
        hint,
    };
    if width > max_dim || height > max_dim {
        return Err(too_large(format!("at most {max_dim} pixels a side")));
    }
    let bytes = width as u64 * height as u64 * 8;
    let max = max_buffer_binding(ctx);
    if bytes > max {
        return Err(too_large(format!(
            "its coordinate pyramid needs more than {} MiB in one buffer, the device allows {} MiB",
            bytes >> 20,
            max >> 20
        )));
    }
    Ok(())
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes() {
        assert_eq!(parse_size("64"), Ok([64, 64]));
        assert_eq!(parse_size("64x32"), Ok([64, 32]));
        assert_eq!(parse_size(" 7X9 "), Ok([7, 9]));
        for bad in [
            "0",
            "0x5",
            "5x0",
            "",
            "x",
            "abc",
            "5x",
            "x5",
            "1x2x3",
            "-4",
            "+4",
            "4.5",
            "99999999999",
        ] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
        assert_eq!(
            parse_sizes("256,512x128"),
            Ok(Sizes(vec![[256, 256], [512, 128]]))
        );
        assert!(parse_sizes("256,,512").is_err());
    }

    #[test]
    fn randomness_and_window() {
        assert_eq!(parse_randomness("0.5"), Ok(Randomness(vec![0.5])));
        assert_eq!(
            parse_randomness("1,0.5, 0"),
            Ok(Randomness(vec![1.0, 0.5, 0.0]))
        );
        for bad in ["", "nan", "inf", "-0.1", "2.5", "1,,2", "a"] {
            assert!(parse_randomness(bad).is_err(), "{bad}");
        }
        assert_eq!(parse_window("-5,7"), Ok([-5, 7]));
        for bad in [
            "",
            "1",
            "1,2,3",
            "a,b",
            "1.5,2",
            "999999999,0",
            "-2147483648,0",
            "0,-2147483648",
        ] {
            assert!(parse_window(bad).is_err(), "{bad}");
        }
        assert!(parse_coherence("4.5").is_err());
        assert_eq!(parse_coherence("0.25"), Ok(0.25));
    }
}
