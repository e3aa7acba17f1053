//! [`SessionBuilder::build_reporting`]: the steps from a request to an exemplar on the
//! GPU, cheapest checks first so that a mistake does not cost an analysis.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use crate::analysis::{self, Analysis, AnalysisOptions, Exemplar};
use crate::error::{Error, Result};
use crate::gpu::synth::{GpuSynthesizer, MAX_WINDOWED_PIXELS};
use crate::gpu::GpuContext;

use super::builder::{SessionBuilder, Source};
use super::{BuildTimings, Event, ExemplarSource, Magnified, Session};

/// What reading the source gives: the (possibly downsampled) exemplar or analysis, the
/// full-resolution colours when magnifying, and the exemplar image's own size.
struct Input {
    source: ExemplarSource,
    /// The file the source was read from, for messages.
    path: Option<std::path::PathBuf>,
    magnified: Option<Magnified>,
    full_size: Option<(u32, u32)>,
    read: Duration,
}

fn invalid(message: String) -> Error {
    Error::InvalidParameter(message)
}

impl SessionBuilder {
    /// [`Self::build`], telling `report` what happens: a warning about the exemplar, the
    /// device, the analysis's progress, the analysed exemplar and notes about the output
    /// (see [`Event`]).
    ///
    /// ```no_run
    /// use texsyn::{Event, Session};
    /// let session = Session::builder()
    ///     .exemplar_path("assets/gravel.png")
    ///     .build_reporting(&mut |event| match event {
    ///         Event::Analysis(p) => eprintln!("analysing level {}/{}", p.done, p.total),
    ///         Event::Device(ctx) => eprintln!("adapter: {}", ctx.describe()),
    ///         _ => {}
    ///     })?;
    /// # Ok::<(), texsyn::Error>(())
    /// ```
    pub fn build_reporting(mut self, report: &mut dyn FnMut(Event<'_>)) -> Result<Session> {
        if let Source::None = self.source {
            return Err(invalid(
                "no exemplar given: call exemplar_path, exemplar or analysis".into(),
            ));
        }
        // The device is created on a thread of its own while the input is read: loading
        // the driver is mostly waiting, and reading an analysis file is the other large
        // part of the fixed cost. Joined before any error is returned, so that no exit
        // happens in the middle of the driver's start-up.
        let given = self.context.take();
        let device = given.is_none().then(|| {
            std::thread::spawn(|| {
                let t = Instant::now();
                (GpuContext::headless(), t.elapsed())
            })
        });
        let input = self.read_input(report);
        let (context, device_time) = match (given, device) {
            (Some(c), _) => (Ok(c), Duration::ZERO),
            (None, Some(thread)) => thread.join().map_err(|_| {
                Error::Gpu("creating the device failed (its thread panicked)".into())
            })?,
            (None, None) => unreachable!("a device thread runs when no context is given"),
        };
        let input = input?;
        let ctx = context?;
        report(Event::Device(&ctx));
        self.build_on(ctx, input, device_time, report)
    }

    /// Reads the source and checks the request against it: an analysis file must agree
    /// with the options given, magnification needs an image.
    fn read_input(&mut self, report: &mut dyn FnMut(Event<'_>)) -> Result<Input> {
        let t = Instant::now();
        let (source, path) = match std::mem::replace(&mut self.source, Source::None) {
            Source::None => unreachable!("checked in build_reporting"),
            Source::Exemplar(e) => (ExemplarSource::Image(e), None),
            Source::Analysis(a) => (ExemplarSource::Analysis(a), None),
            Source::Path { path, mapped } => {
                let source = if mapped {
                    // SAFETY: the contract of `exemplar_path_mapped`.
                    unsafe { ExemplarSource::open_mapped(&path)? }
                } else {
                    ExemplarSource::open(&path)?
                };
                if let ExemplarSource::Image(_) = source {
                    if let Some(w) = super::source::animation_warning(&path) {
                        report(Event::Warning(w));
                    }
                }
                source.check_matches(&path, self.k_given, self.options.tileable)?;
                (source, Some(path))
            }
        };
        let read = t.elapsed();
        if let (ExemplarSource::Analysis(a), Some(path)) = (&source, &path) {
            // The appearance space is fixed by the analysis: options that would change
            // it are refused rather than silently ignored.
            if self.feature_mask_path.is_some() || self.options.feature_mask.is_some() {
                return Err(invalid(format!(
                    "--feature-mask applies when analysing an image; {} is an analysis file: re-run `texsyn analyze --feature-mask ...`",
                    path.display()
                )));
            }
            if self.appearance_given.is_some_and(|g| g != a.appearance) {
                return Err(invalid(format!(
                    "--appearance does not match the analysis file {}; drop it or re-run `texsyn analyze --appearance ...`",
                    path.display()
                )));
            }
        }
        // Magnification: analyse a downsampled copy, keep the full colours.
        let full_size = source.image_size();
        let (source, magnified) = match self.magnify {
            None => (source, None),
            Some(_) if matches!(source, ExemplarSource::Analysis(_)) => {
                return Err(invalid(
                    "--magnify needs the exemplar image (its full-resolution colours), not an analysis file".into(),
                ))
            }
            Some(f) => {
                let (small, hi) = source.magnify(f)?;
                (small, Some(hi))
            }
        };
        Ok(Input {
            source,
            path,
            magnified,
            full_size,
            read,
        })
    }

    /// The steps once the device is there: size checks, the analysis, validation, the
    /// upload (pipelines built alongside) and the preparation.
    fn build_on(
        mut self,
        ctx: GpuContext,
        input: Input,
        device: Duration,
        report: &mut dyn FnMut(Event<'_>),
    ) -> Result<Session> {
        let params = std::mem::take(&mut self.params);
        let (width, height) = (params.width, params.height);
        // An output larger than the device takes in one piece is synthesized in windows
        // and assembled (the same bytes); a periodic or magnified one cannot be split.
        let mut windowed = false;
        if let Err(e) = super::check_output_size(&ctx, width, height, super::API_WINDOW_HINT) {
            if params.tileable_output || self.magnify.is_some() {
                return Err(e);
            }
            windowed = true;
        }
        if windowed && width as usize * height as usize > MAX_WINDOWED_PIXELS {
            return Err(invalid(format!(
                "--size {width}x{height}: outputs larger than the device takes in one piece are \
                 assembled in memory, at most {} Mpixel (16384x16384); synthesize parts of it \
                 with --window X,Y and a smaller --size",
                MAX_WINDOWED_PIXELS >> 20
            )));
        }
        input.source.check_fits(&ctx, self.options.k)?;
        let (analysis, from_file, analysis_time) = match input.source {
            ExemplarSource::Analysis(a) => (a, input.path.is_some(), None),
            ExemplarSource::Image(ex) => {
                let t = Instant::now();
                let a = self.analyse(&ex, input.full_size, report)?;
                (a, false, Some(t.elapsed()))
            }
        };
        report(Event::Exemplar {
            analysis: &analysis,
            from_file,
        });
        // Validate the parameters before uploading.
        if !self.copy_budget.is_finite() || !(0.0..=1.0).contains(&self.copy_budget) {
            return Err(invalid(format!(
                "copy budget {} must be between 0 and 1",
                self.copy_budget
            )));
        }
        analysis.validate()?;
        crate::passes::SynthPlan::new(&analysis, &params)?;

        // The pipelines are built on another thread while the analysis uploads (both
        // take tens of milliseconds on a CPU device; a large exemplar's upload is mostly
        // page faults).
        let t = Instant::now();
        let analysis = Arc::new(analysis);
        let (synthesizer, pipelines) = std::thread::scope(|scope| {
            let pipelines = scope.spawn(|| {
                let t = Instant::now();
                (ctx.prepare_synthesis(&analysis, &params), t.elapsed())
            });
            let synthesizer = GpuSynthesizer::new(&ctx, analysis.clone());
            (synthesizer, pipelines.join())
        });
        let upload = t.elapsed();
        let synthesizer = synthesizer?;
        let (built, pipelines) = pipelines.map_err(|_| {
            Error::Gpu("building the pipelines failed (their thread panicked)".into())
        })?;
        built?;
        if let Some(note) = super::tileable_note(&synthesizer, &params)? {
            report(Event::Note(note));
        }
        // The library's check covers the whole pyramid (the one above, the finest level).
        windowed |= !params.tileable_output && self.magnify.is_none() && !synthesizer.fits(&params);
        // The rest of the preparation (a field's Jacobians), before the synthesis so that
        // the timings tell them apart. Windows build theirs as they go.
        let t = Instant::now();
        if !windowed {
            synthesizer.prepare(&params)?;
        }
        let prepare = t.elapsed();
        Ok(Session {
            context: ctx,
            synthesizer: Arc::new(synthesizer),
            params,
            copy_budget: self.copy_budget,
            magnified: input.magnified,
            exemplar_size: input.full_size,
            maps: self.maps,
            coordinates: self.coordinates,
            levels: self.levels.map(|f| Arc::new(Mutex::new(f))),
            timings: BuildTimings {
                read: input.read,
                analysis: analysis_time,
                device,
                upload,
                pipelines,
                prepare,
            },
        })
    }

    /// Analyses `ex` (downsampled when magnifying; `full_size` is the image's own size)
    /// with the builder's options and feature mask.
    fn analyse(
        &mut self,
        ex: &Exemplar,
        full_size: Option<(u32, u32)>,
        report: &mut dyn FnMut(Event<'_>),
    ) -> Result<Analysis> {
        let mut options: AnalysisOptions = self.options.clone();
        let from_file = self.feature_mask_path.is_some();
        if let Some(path) = &self.feature_mask_path {
            let mask = analysis::FeatureMask::load(path)
                .map_err(|e| invalid(format!("--feature-mask: {e}")))?;
            options.feature_mask = Some(mask);
        }
        // With magnification the mask may be given at the full exemplar's size, like the
        // material maps: it is downsampled as the exemplar was.
        if let (Some(f), Some(mask), Some((fw, fh))) =
            (self.magnify, &options.feature_mask, full_size)
        {
            if (mask.width / f, mask.height / f) == (ex.width, ex.height) && f > 1 {
                options.feature_mask = Some(mask.downsample(f)?);
            } else if (mask.width, mask.height) != (ex.width, ex.height) {
                return Err(invalid(format!(
                    "--feature-mask: {}x{} pixels, but the exemplar is {fw}x{fh}; give the \
                     mask at the exemplar's size",
                    mask.width, mask.height
                )));
            }
        }
        // A blank mask changes nothing; read from a file, it is a mistake (an empty or
        // inverted export).
        if let (Some(mask), true) = (&options.feature_mask, from_file) {
            mask.check_size(ex.width, ex.height)?;
            mask.check_not_blank()?;
        }
        let mut stored = self.progress.take();
        let a = analysis::analyze(ex, &options, |p| {
            if let Some(f) = stored.as_mut() {
                f(p);
            }
            report(Event::Analysis(p));
        });
        self.progress = stored;
        a
    }
}
