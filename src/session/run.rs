//! [`Session::run_reporting`]: one synthesis, by the cheapest route that gives what was
//! asked for (colours alone, with coordinates or material maps, magnified, or assembled
//! from windows), read back into a [`Texture`].

use std::time::{Duration, Instant};

use crate::error::{Error, Result};
use crate::gpu::synth::{ExtraMap, GpuSynthesizer};
use crate::passes::{SynthParams, Synthesis};

use super::{crop_rows, Event, Magnified, Session, SynthesizedMap, Texture};

/// Outputs of at least this many pixels (2048x2048) in one piece report each level to
/// [`SessionBuilder::on_level`](super::SessionBuilder::on_level).
pub const LONG_SYNTHESIS_PIXELS: u64 = 1 << 22;

/// How long the steps of [`Session::run`] took.
#[derive(Clone, Copy, Debug)]
pub struct RunTimings {
    /// The copy guard's probes (synthesis and read-back), if any ran.
    pub copy_guard: Option<Duration>,
    /// The synthesis and its read-back.
    pub synthesis: SynthesisTiming,
}

/// The synthesis's share of [`RunTimings`], by the route it took.
#[derive(Clone, Copy, Debug)]
pub enum SynthesisTiming {
    /// The colours alone: the synthesis (GPU, synchronized), then their read-back.
    Separate {
        /// Synthesis until the GPU finished.
        synthesis: Duration,
        /// Read-back of the colours.
        readback: Duration,
    },
    /// Colours read back with coordinates or maps, in one go (or windows).
    Combined {
        /// Synthesis and read-back together.
        synthesis_readback: Duration,
        /// The copy guard's probe was this synthesis (nothing more ran).
        reused_probe: bool,
    },
    /// The copy guard's probe was this synthesis, colours already on the host.
    Probe,
}

/// What the copy guard did for a run: the schedule it chose and the copy it measured.
#[derive(Clone, Debug)]
pub struct CopyGuardReport {
    /// Its choice and the probes' figures, in words.
    pub summary: String,
    /// `Some(probe size)` when it chose a stiller schedule from a probe window (at the
    /// origin, this size) that is not the output's: the output's copies are unmeasured.
    pub measured_elsewhere: Option<[u32; 2]>,
}

impl Session {
    /// [`Self::run`], telling `report` the progress of outputs assembled from windows
    /// ([`Event::Windows`]).
    ///
    /// ```no_run
    /// use texsyn::{Event, Session};
    /// let session = Session::builder()
    ///     .exemplar_path("assets/gravel.png")
    ///     .size(16384, 8192)
    ///     .coordinates(false)
    ///     .build()?;
    /// let texture = session.run_reporting(&mut |event| {
    ///     if let Event::Windows { done, total, .. } = event {
    ///         eprintln!("window {done}/{total}");
    ///     }
    /// })?;
    /// texture.save("large.png")?;
    /// # Ok::<(), texsyn::Error>(())
    /// ```
    pub fn run_reporting(&self, report: &mut dyn FnMut(Event<'_>)) -> Result<Texture> {
        self.run_inner(&self.params, report)
    }

    /// Whether an output with `params` is assembled from windows: it does not fit the
    /// device in one piece (and is neither periodic nor magnified).
    pub fn in_windows(&self, params: &SynthParams) -> bool {
        !params.tileable_output
            && self.magnified.is_none()
            && (super::check_output_size(
                &self.context,
                params.width,
                params.height,
                super::API_WINDOW_HINT,
            )
            .is_err()
                || !self.synthesizer.fits(params))
    }

    pub(super) fn run_inner(
        &self,
        params: &SynthParams,
        report: &mut dyn FnMut(Event<'_>),
    ) -> Result<Texture> {
        let s = &self.synthesizer;
        let windowed = self.in_windows(params);
        // The copy guard's probe (its synthesis is the result when it is the output's).
        let t = Instant::now();
        let choice = s.choose_schedule(params, self.copy_budget)?;
        let guard_time = (!choice.probes.is_empty()).then(|| t.elapsed());
        let copy_guard =
            (!choice.probes.is_empty() || choice.unprobed.is_some()).then(|| CopyGuardReport {
                summary: choice.describe(self.copy_budget),
                measured_elsewhere: (choice.params.extra_still_levels > 0
                    && !GpuSynthesizer::output_within_probe(params))
                .then(|| {
                    let probe = GpuSynthesizer::probe_params(params);
                    [probe.width, probe.height]
                }),
            });
        let chosen = choice.params;
        let probe = choice.result;
        let reporting_levels = self.report_levels(params, windowed);
        let maps = self.load_maps();
        let out = maps.and_then(|maps| self.synthesize(&chosen, probe, &maps, windowed, report));
        if reporting_levels {
            s.set_progress(None);
        }
        let (synthesis, magnified, map_pixels, timing) = out?;
        let maps = map_pixels
            .into_iter()
            .zip(&self.maps)
            .map(|(pixels, m)| SynthesizedMap {
                pixels: pixels.0,
                channels: pixels.1,
                normal: m.normal,
                green_down: m.green_down,
            })
            .collect();
        let a = self.analysis();
        Ok(Texture {
            synthesis,
            channels: a.channels,
            exemplar_size: [a.width, a.height],
            tileable: a.tileable,
            magnified,
            maps,
            windowed,
            copy_guard,
            timings: RunTimings {
                copy_guard: guard_time,
                synthesis: timing,
            },
        })
    }

    /// Installs the level callback for a long synthesis in one piece; whether it did.
    fn report_levels(&self, params: &SynthParams, windowed: bool) -> bool {
        let Some(f) = &self.levels else {
            return false;
        };
        if windowed || (params.width as u64 * params.height as u64) < LONG_SYNTHESIS_PIXELS {
            return false;
        }
        let (f, start) = (f.clone(), Instant::now());
        self.synthesizer
            .set_progress(Some(Box::new(move |done, total| {
                let mut f = f.lock().unwrap_or_else(|e| e.into_inner());
                f(done, total, start.elapsed())
            })));
        true
    }

    /// Every material map, read and checked against the exemplar (with magnification
    /// full-resolution, cropped as the exemplar was), with its channel count.
    fn load_maps(&self) -> Result<Vec<(ExtraMap, u32)>> {
        let a = self.analysis();
        let (ew, eh) = self.exemplar_size.unwrap_or((a.width, a.height));
        let mut out = Vec::with_capacity(self.maps.len());
        for m in &self.maps {
            let (mw, mh, channels, pixels) = crate::image_io::load_material_map(&m.path)
                .map_err(|e| Error::InvalidParameter(format!("--also: {e}")))?;
            if (mw, mh) != (ew, eh) {
                return Err(Error::InvalidParameter(format!(
                    "--also {}: {mw}x{mh} pixels, but the exemplar is {ew}x{eh}; extra maps must be aligned with it",
                    m.path.display(),
                )));
            }
            let pixels = match &self.magnified {
                Some(hi) => crop_rows(&pixels, ew, hi.width, hi.height),
                None => pixels,
            };
            out.push((
                ExtraMap {
                    pixels,
                    normal: m.normal,
                    green_down: m.green_down,
                },
                channels,
            ));
        }
        Ok(out)
    }

    /// The synthesis by its route: magnified colours alone on the GPU; colours with
    /// coordinates or maps in one go (or in windows); the copy guard's probe; colours
    /// alone.
    #[allow(clippy::type_complexity)]
    fn synthesize(
        &self,
        params: &SynthParams,
        mut probe: Option<Synthesis>,
        extra: &[(ExtraMap, u32)],
        windowed: bool,
        report: &mut dyn FnMut(Event<'_>),
    ) -> Result<(
        Synthesis,
        Option<super::MagnifiedImage>,
        Vec<(Vec<[u8; 4]>, u32)>,
        SynthesisTiming,
    )> {
        let (s, ctx) = (&self.synthesizer, &self.context);
        let combined = self.coordinates || !extra.is_empty() || windowed;
        // Colours alone: no coordinates (their fractional bits as a synthesis has them).
        let empty = || Synthesis {
            width: params.width,
            height: params.height,
            coords: Vec::new(),
            colors: Vec::new(),
            coord_frac: if params.field.is_some() { 8 } else { 0 },
        };
        if let (Some(hi), false) = (&self.magnified, combined) {
            let Magnified {
                pixels,
                width,
                height,
                factor,
            } = hi;
            let t = Instant::now();
            let gpu = s.synthesize_magnified(params, pixels, *width, *height, *factor)?;
            ctx.take_uncaptured_errors()?;
            let synthesis = t.elapsed();
            let t = Instant::now();
            let rgba8 = gpu.read_rgba8(ctx)?;
            let readback = t.elapsed();
            let image = super::MagnifiedImage {
                width: gpu.width,
                height: gpu.height,
                factor: *factor,
                colors: pixels_of(&rgba8),
            };
            let timing = SynthesisTiming::Separate {
                synthesis,
                readback,
            };
            return Ok((empty(), Some(image), Vec::new(), timing));
        }
        if combined {
            // Coordinates and maps come back with the synthesis, in one go.
            let t = Instant::now();
            let maps: Vec<ExtraMap> = extra.iter().map(|(m, _)| m.clone()).collect();
            let mut reused_probe = false;
            let (synthesis, magnified, map_pixels) = match &self.magnified {
                Some(hi) => {
                    let m = s.synthesize_magnified_with_maps(
                        params, &hi.pixels, hi.width, hi.height, hi.factor, &maps,
                    )?;
                    let image = super::MagnifiedImage {
                        width: m.width,
                        height: m.height,
                        factor: m.factor,
                        colors: m.colors,
                    };
                    (m.synthesis, Some(image), m.maps)
                }
                None if windowed => {
                    let start = Instant::now();
                    let (synthesis, maps) =
                        s.synthesize_in_windows(params, &maps, |done, total| {
                            report(Event::Windows {
                                done,
                                total,
                                elapsed: start.elapsed(),
                            })
                        })?;
                    (synthesis, None, maps)
                }
                None => match probe.take() {
                    Some(p) if maps.is_empty() => {
                        reused_probe = true;
                        (p, None, Vec::new())
                    }
                    _ => {
                        let (synthesis, maps) = s.synthesize_with_maps(params, &maps)?;
                        (synthesis, None, maps)
                    }
                },
            };
            ctx.take_uncaptured_errors()?;
            let timing = SynthesisTiming::Combined {
                synthesis_readback: t.elapsed(),
                reused_probe,
            };
            let map_pixels = map_pixels
                .into_iter()
                .zip(extra)
                .map(|(p, (_, channels))| (p, *channels))
                .collect();
            return Ok((synthesis, magnified, map_pixels, timing));
        }
        if let Some(p) = probe {
            // The probe was this very synthesis (colours already on the host).
            return Ok((p, None, Vec::new(), SynthesisTiming::Probe));
        }
        let t = Instant::now();
        let gpu = s.synthesize(params)?;
        ctx.take_uncaptured_errors()?;
        let synthesis = t.elapsed();
        let t = Instant::now();
        let rgba8 = gpu.read_rgba8(ctx)?;
        let readback = t.elapsed();
        let out = Synthesis {
            colors: pixels_of(&rgba8),
            ..empty()
        };
        let timing = SynthesisTiming::Separate {
            synthesis,
            readback,
        };
        Ok((out, None, Vec::new(), timing))
    }
}

/// RGBA8 bytes as pixels.
fn pixels_of(rgba8: &[u8]) -> Vec<[u8; 4]> {
    rgba8
        .chunks_exact(4)
        .map(|p| [p[0], p[1], p[2], p[3]])
        .collect()
}
