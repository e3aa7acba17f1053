//! Messages to the user: progress and summaries on stderr, results on stdout, and the
//! formatting of durations, sizes and channel counts.

use std::io::{IsTerminal, Write};
use std::path::Path;
use std::time::Duration;

use texsyn::analysis::{Progress, Stage};

use super::{fail, CliResult};

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
    pub(super) fn new(quiet: bool) -> Self {
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
