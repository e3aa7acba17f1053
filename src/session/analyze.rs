//! [`analyze_image`]: an exemplar image analysed once, for saving (`texsyn analyze`).

use std::path::Path;
use std::time::{Duration, Instant};

use crate::analysis::{self, Analysis, AnalysisOptions};
use crate::error::Result;

use super::Event;

/// An analysed exemplar image and how long each step took ([`analyze_image`]).
pub struct AnalyzedImage {
    /// The analysis, ready to save ([`Analysis::save`]) or synthesize from.
    pub analysis: Analysis,
    /// Reading and decoding the image.
    pub load: Duration,
    /// The analysis itself.
    pub analysis_time: Duration,
}

/// Reads the exemplar image at `path` and analyses it with `options`, telling `report`
/// a warning about the image ([`Event::Warning`]) and the analysis's progress
/// ([`Event::Analysis`]). A feature mask in `options` must have the image's size and
/// must not be blank (an empty or inverted export).
///
/// ```no_run
/// use texsyn::analyze_image;
/// let a = analyze_image("assets/gravel.png".as_ref(), &Default::default(), &mut |_| {})?;
/// a.analysis.save("gravel.texsyn".as_ref())?;
/// # Ok::<(), texsyn::Error>(())
/// ```
pub fn analyze_image(
    path: &Path,
    options: &AnalysisOptions,
    report: &mut dyn FnMut(Event<'_>),
) -> Result<AnalyzedImage> {
    let t = Instant::now();
    let exemplar = crate::image_io::load_exemplar(path)?;
    if let Some(w) = super::source::animation_warning(path) {
        report(Event::Warning(w));
    }
    let load = t.elapsed();
    if let Some(mask) = &options.feature_mask {
        mask.check_size(exemplar.width, exemplar.height)?;
        mask.check_not_blank()?;
    }
    let t = Instant::now();
    let analysis = analysis::analyze(&exemplar, options, |p| report(Event::Analysis(p)))?;
    Ok(AnalyzedImage {
        analysis,
        load,
        analysis_time: t.elapsed(),
    })
}
