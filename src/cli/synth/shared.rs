//! What `synth` shares with the other subcommands: reading the exemplar, magnifying it,
//! naming the options in size errors, and the output-format checks.

use std::path::Path;

use crate::cli::{CliResult, Ui};

/// Hint of the "output too large" errors.
pub const WINDOW_HINT: &str = "synthesize it in windows (--window X,Y) and assemble them";

pub use texsyn::ExemplarSource as Source;

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
    let source = unsafe { Source::open_mapped(path)? };
    if let Source::Image(_) = source {
        ui.warn_if_animation(path);
    }
    source.check_matches(path, k, tileable)?;
    Ok(source)
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
fn with_hint(e: texsyn::Error, hint: &'static str) -> texsyn::Error {
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

/// Rejects an output extension the library cannot write, before any work (the library
/// checks again when saving).
pub fn check_save_extension(path: &Path) -> CliResult<()> {
    Ok(texsyn::check_image_path(path)?)
}

/// An output of `width` x `height` must fit its format: checked before any work.
pub fn check_save_size(path: &Path, width: u64, height: u64) -> CliResult<()> {
    Ok(texsyn::check_image_size(path, width, height)?)
}

/// `--copy-budget F`: a fraction of the exemplar's area, 0..=1.
pub fn parse_copy_budget(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(f) if (0.0..=1.0).contains(&f) => Ok(f),
        _ => Err(format!(
            "'{s}': give a fraction of the exemplar's area between 0 and 1 (0 turns the copy guard off)"
        )),
    }
}

/// `--magnify F`: 2, 4 or 8.
pub fn parse_magnify(s: &str) -> Result<u32, String> {
    match s {
        "2" | "4" | "8" => Ok(s.parse().unwrap()),
        _ => Err(format!("'{s}': the magnification factor must be 2, 4 or 8")),
    }
}
