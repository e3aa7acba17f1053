//! The `texsyn` command line: argument parsing (clap derive) and the subcommands, a
//! thin layer over the library. Errors are printed as `error: <message>` and give exit
//! code 1; usage errors are clap's (exit code 2).

mod advect;
mod analyze;
mod args;
mod bench;
mod eval;
mod field;
mod frames;
mod interrupt;
mod output;
mod parse;
mod surface;
mod synth;
mod ui;

use clap::{Parser, Subcommand};

// The shared pieces, at the paths the subcommands name them by (`super::X`).
pub use args::{AppearanceArgs, FieldArg, ScheduleArgs, SeedArg, TileArgs};
pub use output::{
    check_distinct_outputs, check_output_dir, check_outputs_not_inputs, check_parent_dir,
    parse_named_output, takes_new_files,
};
pub use parse::{
    parse_coherence, parse_randomness, parse_size, parse_sizes, parse_window, time_step,
    Randomness, Sizes,
};
pub use ui::{channels_name, fmt_bytes, fmt_duration, stderr_line, Ui};

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
