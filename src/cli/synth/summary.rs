//! `synth`'s summary on stderr: the outputs, the copy guard's choice and the time of
//! each step.

use texsyn::{Session, SynthesisTiming, Texture};

use super::SynthArgs;
use crate::cli::{fmt_duration, Ui};

/// The outputs, the copy guard's choice and the time of each step.
pub fn print(
    ui: &Ui,
    args: &SynthArgs,
    session: &Session,
    texture: &Texture,
    write: std::time::Duration,
) {
    let [width, height] = args.size;
    let out_size = (texture.width(), texture.height());
    let magnified = if out_size != (width, height) {
        format!(", magnified from {width}x{height}")
    } else {
        String::new()
    };
    let placement = if args.standalone && !texture.assembled_from_windows() {
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
    if let Some(guard) = texture.copy_guard() {
        let mut line = guard.summary.clone();
        if let Some([pw, ph]) = guard.measured_elsewhere {
            // The guard bounds the copies of its probe window only.
            line.push_str(&format!(
                "\nnote: the copy guard measured the {pw}x{ph} window at the origin, not this \
                 one; tiles of a larger texture can copy more than the budget between them. \
                 For a copy bounded at any size and place, use --copy-budget 0"
            ));
        }
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
    let built = session.timings();
    match built.analysis {
        None => ui.info(format!(
            "time: load analysis file {}",
            fmt_duration(built.read)
        )),
        Some(a) => ui.info(format!(
            "time: load image {}, analysis {}",
            fmt_duration(built.read),
            fmt_duration(a)
        )),
    }
    ui.info(format!("      device {}", fmt_duration(built.device)));
    ui.info(format!(
        "      GPU upload {} (pipelines {} alongside), preparation {}",
        fmt_duration(built.upload),
        fmt_duration(built.pipelines),
        fmt_duration(built.prepare)
    ));
    let ran = texture.timings();
    if let Some(g) = ran.copy_guard {
        ui.info(format!(
            "      copy guard probes (synthesis + read-back) {}",
            fmt_duration(g)
        ));
    }
    let px = width as f64 * height as f64;
    match ran.synthesis {
        SynthesisTiming::Separate {
            synthesis,
            readback,
        } => {
            ui.info(format!(
                "      synthesis (GPU, synchronized) {} ({:.3} Mpixel/s)",
                fmt_duration(synthesis),
                px / synthesis.as_secs_f64() / 1e6
            ));
            ui.info(format!(
                "      read-back {}, write {}",
                fmt_duration(readback),
                fmt_duration(write)
            ));
            return;
        }
        SynthesisTiming::Combined {
            synthesis_readback,
            reused_probe: false,
        } => ui.info(format!(
            "      synthesis + read-back of colours and coordinates {}",
            fmt_duration(synthesis_readback)
        )),
        _ => ui.info("      synthesis: the copy guard's probe"),
    }
    ui.info(format!("      write {}", fmt_duration(write)));
}
