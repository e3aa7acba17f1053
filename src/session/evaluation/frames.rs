//! The temporal figures of a folder of advected frames ([`super::Evaluation::frames`]),
//! read one frame at a time so that memory stays flat for long sequences.

use std::path::{Path, PathBuf};

use super::{load_image, FrameFigures};
use crate::error::{Error, Result};
use crate::flow::Flow;
use crate::quality::{FloatImage, TemporalFigures};

/// The figures of the `frame_NNNNN.png` files in `folder`, advected along `flow` with
/// time step `dt`; texture energy every `energy_every`-th frame (0: first and last).
pub(super) fn run(
    exemplar: &FloatImage,
    folder: &Path,
    flow: &Flow,
    dt: f32,
    energy_every: usize,
) -> Result<FrameFigures> {
    let invalid = |m: String| Error::InvalidParameter(m);
    if !folder.is_dir() {
        return Err(invalid(format!(
            "{}: with --flow, give the folder of frames `texsyn advect -o FOLDER` wrote",
            folder.display()
        )));
    }
    let mut paths: Vec<PathBuf> = std::fs::read_dir(folder)
        .map_err(|e| invalid(format!("cannot read {}: {e}", folder.display())))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("frame_") && n.ends_with(".png"))
        })
        .collect();
    // By frame number: `advect` pads to 5 digits, so frame 100000 sorts before 99999 as
    // text; names without a number come first and fail the consecutive check below.
    let index = |p: &PathBuf| -> Option<u64> {
        let n = p.file_name()?.to_str()?;
        n.strip_prefix("frame_")?.strip_suffix(".png")?.parse().ok()
    };
    paths.sort_by_key(|p| (index(p), p.clone()));
    if paths.len() < 2 {
        return Err(invalid(format!(
            "{}: needs at least two frame_*.png files",
            folder.display()
        )));
    }
    // The flow is applied frame by frame: a gap (frames written every K steps) would
    // compare frames K steps apart as if they were 1.
    for pair in paths.windows(2) {
        match (index(&pair[0]), index(&pair[1])) {
            (Some(a), Some(b)) if b == a + 1 => {}
            _ => {
                return Err(invalid(format!(
                    "{}: the frames are not consecutive ({} then {}); eval --flow needs every frame (advect --every 1)",
                    folder.display(),
                    pair[0].file_name().unwrap_or_default().to_string_lossy(),
                    pair[1].file_name().unwrap_or_default().to_string_lossy()
                )))
            }
        }
    }
    let first = load_image(&paths[0])?;
    let (w, h) = (first.width, first.height);
    // A field of another size than the frames is an error, not a silently ignored flow.
    flow.sample(w, h, 0.0)?;
    let every = match energy_every {
        0 => usize::MAX,
        k => k,
    };
    let mut figures =
        TemporalFigures::new(exemplar, every).starting_at(index(&paths[0]).unwrap_or(0) as usize);
    figures.push(first, &[])?;
    for path in paths.iter().skip(1) {
        // The frame's own number is its time (a folder may start after frame 0).
        let t = index(path).unwrap_or(0);
        let frame = load_image(path)?;
        if (frame.width, frame.height) != (w, h) {
            return Err(invalid(format!(
                "{} is {}x{}, the first frame {w}x{h}: the frames must all have one size",
                path.display(),
                frame.width,
                frame.height
            )));
        }
        let v = flow.sample(w, h, t as f32)?;
        figures.push(frame, &displacement(&v, dt))?;
    }
    Ok(FrameFigures {
        frames: paths.len(),
        temporal: figures.finish()?,
    })
}

/// Per-frame displacement: velocity times the time step, clamped to the largest step a
/// frame takes.
fn displacement(velocity: &[[f32; 2]], dt: f32) -> Vec<[f32; 2]> {
    let m = crate::passes::advect::MAX_SPEED;
    velocity
        .iter()
        .map(|p| p.map(|c| (c * dt).clamp(-m, m)))
        .collect()
}
