//! A texture that moves along a flow, frame by frame (Lefebvre & Hoppe 2006, section 7),
//! in 2D or over a mesh's atlas: one builder takes the exemplar, the output, the flow
//! and the scheme, sets up the device, the analysis, the atlas and the
//! [`Advection`](crate::gpu::advect::Advection), and gives a session that the caller
//! pulls frames from; per-frame costs and the temporal figures come with the summary.
//!
//! ```no_run
//! use texsyn::flow::Flow;
//! use texsyn::AdvectSession;
//!
//! let mut session = AdvectSession::builder()
//!     .exemplar_path("assets/gravel.png")
//!     .size(256, 256)
//!     .flow(Flow::Vortex { cx: 0.5, cy: 0.5, omega: 0.01 })
//!     .frames(60)
//!     .on_note(|note| eprintln!("{note}"))
//!     .build()?;
//! while let Some(frame) = session.next_frame()? {
//!     let path = format!("frame_{:05}.png", frame.index);
//!     texsyn::image_io::save_image_atomic(std::path::Path::new(&path), frame.width, frame.height, 4, &frame.rgba)?;
//! }
//! for line in session.finish()?.figure_lines() {
//!     println!("{line}");
//! }
//! # Ok::<(), texsyn::Error>(())
//! ```

use std::path::{Path, PathBuf};
use std::sync::Arc;

mod report;
mod run;
pub use report::{AdvectCosts, AdvectNote, AdvectSummary, SchemeReason};
pub use run::{AdvectFrame, AdvectSession};

use crate::analysis::{self, AnalysisOptions, Progress};
use crate::error::{Error, Result};
use crate::field::Field;
use crate::flow::Flow;
use crate::gpu::advect::{AdvectOptions, Advection};
use crate::gpu::synth::GpuSynthesizer;
use crate::gpu::GpuContext;
use crate::passes::advect::KEEP_LOOK_FADE;
use crate::quality::TemporalFigures;
use crate::surface::mesh::Mesh;
use crate::SynthParams;

use super::{check_output_size, ExemplarSource};

/// The scheme as asked for: keep the texture's look or carry it, and the knobs of
/// [`AdvectOptions`]. Knobs left `None` follow the chosen scheme
/// ([`AdvectOptions::keep_look`] or [`AdvectOptions::default`]); with neither `keep_look`
/// nor `carry`, the session keeps the look where the desired Jacobian is the same
/// everywhere (2D without a field or with a constant one) and nothing asks for the
/// paper's scheme, and carries the texture elsewhere, as
/// [`AdvectOptions::recommended`] does.
#[derive(Clone, Debug, Default)]
pub struct AdvectScheme {
    /// Keep the look under turning flows by remaking the texture as it moves.
    pub keep_look: bool,
    /// Carry the texture with the flow (the paper's scheme).
    pub carry: bool,
    /// Levels each frame works on ([`AdvectOptions::levels`]).
    pub levels: Option<usize>,
    /// Distortion threshold ([`AdvectOptions::threshold`]).
    pub threshold: Option<f32>,
    /// Correction passes per advected level and frame (default: the paper scheme's).
    pub passes: Option<u32>,
    /// Correction passes of the coarsest advected level ([`AdvectOptions::coarsest_passes`]).
    pub coarsest_passes: Option<u32>,
    /// Score the similarity sets on every N-th correction ([`AdvectOptions::sets_every`]).
    pub sets_every: Option<u32>,
    /// Frames a renewal fades in over (default: [`KEEP_LOOK_FADE`] when keeping the look,
    /// else 0).
    pub fade: Option<u32>,
    /// Mean colour change for a pixel to fade ([`AdvectOptions::fade_change`]).
    pub fade_change: Option<u32>,
    /// Anchored renewals' grid spacing, 0: off ([`AdvectOptions::anchor_spacing`]).
    pub anchor_spacing: u32,
    /// Share of anchored renewals upsampled anyway ([`AdvectOptions::anchor_upsample`]).
    pub anchor_upsample: Option<f32>,
    /// Advect and correct the finest level too (asks for the paper's scheme).
    pub advect_finest: bool,
    /// Levels below the finest re-synthesized every frame (asks for the paper's scheme).
    pub resynthesize: usize,
    /// Interpolate the exemplar bilinearly at the advected coordinates.
    pub bilinear: bool,
    /// Score the similarity-set candidates bilinearly.
    pub interpolate_sets: bool,
    /// Read the exemplar tables exactly, not at the nearest quarter pixel.
    pub exact_reads: bool,
    /// Also correct the pixels inside coherent patches.
    pub correct_coherent: bool,
}

impl AdvectScheme {
    /// The options this scheme gives where the desired Jacobian is constant or not, and
    /// why the scheme is what it is.
    fn resolve(&self, constant_jacobian: bool) -> (AdvectOptions, SchemeReason) {
        // An explicit level count below keep-look's least (3) asks for the texture carried.
        let keep_look = self.keep_look
            || (constant_jacobian
                && !self.carry
                && !self.advect_finest
                && self.resynthesize == 0
                && self.levels.is_none_or(|l| l >= 3));
        let reason = if keep_look {
            if self.keep_look {
                SchemeReason::KeepLookAsked
            } else {
                SchemeReason::KeepLookDefault
            }
        } else if self.carry {
            SchemeReason::CarryAsked
        } else if self.advect_finest {
            SchemeReason::AdvectFinest
        } else if self.resynthesize > 0 {
            SchemeReason::Resynthesize
        } else if constant_jacobian {
            SchemeReason::FewLevels
        } else {
            SchemeReason::CarryDefault
        };
        let preset = if keep_look {
            AdvectOptions::keep_look()
        } else {
            AdvectOptions::default()
        };
        let options = AdvectOptions {
            levels: self.levels.unwrap_or(preset.levels),
            threshold: self.threshold.unwrap_or(preset.threshold),
            passes: self.passes.unwrap_or(AdvectOptions::default().passes),
            coarsest_passes: self.coarsest_passes,
            nearest: !self.bilinear,
            interpolate_sets: self.interpolate_sets,
            quarter_reads: !self.exact_reads,
            skip_coherent: !self.correct_coherent,
            sets_every: self.sets_every.unwrap_or(preset.sets_every),
            upsample_finest: !self.advect_finest,
            resynthesize: self.resynthesize,
            keep_look,
            fade: self
                .fade
                .unwrap_or(if keep_look { KEEP_LOOK_FADE } else { 0 }),
            fade_change: self.fade_change.unwrap_or(preset.fade_change),
            anchor_spacing: self.anchor_spacing,
            anchor_upsample: self.anchor_upsample.unwrap_or(preset.anchor_upsample),
        };
        (options, reason)
    }
}

enum SourceRequest {
    None,
    Path { path: PathBuf, mapped: bool },
    Given(ExemplarSource),
}

enum MeshRequest {
    Path(PathBuf),
    Given(Mesh),
}

enum SchemeRequest {
    Scheme(AdvectScheme),
    Options(AdvectOptions),
}

/// What [`AdvectSessionBuilder::on_note`] takes.
type NoteCallback<'a> = Box<dyn FnMut(&AdvectNote) + 'a>;

/// Builds an [`AdvectSession`]: an exemplar, a 2D size or a mesh, a flow; the rest has
/// defaults. The callbacks (`'a`) are called only while [`Self::build`] runs.
pub struct AdvectSessionBuilder<'a> {
    source: SourceRequest,
    tileable: Option<bool>,
    size: [u32; 2],
    mesh: Option<MeshRequest>,
    atlas_size: u32,
    flow: Option<Flow>,
    dt: f32,
    field: Option<Field>,
    seed: u32,
    scheme: SchemeRequest,
    frames: Option<u32>,
    energy_every: usize,
    compare_cost: bool,
    profile_passes: bool,
    context: Option<GpuContext>,
    progress: Option<Box<dyn FnMut(Progress) + 'a>>,
    notes: Option<NoteCallback<'a>>,
}

/// The atlas side of a mesh advection unless [`AdvectSessionBuilder::atlas_size`] says.
pub const DEFAULT_ATLAS_SIZE: u32 = 512;

impl AdvectSession {
    /// A builder: give it an exemplar, a flow and a size or a mesh, then
    /// [`AdvectSessionBuilder::build`].
    ///
    /// ```no_run
    /// use texsyn::{AdvectScheme, AdvectSession};
    /// let mut session = AdvectSession::builder()
    ///     .exemplar_path("assets/gravel.png")
    ///     .mesh_path("bunny.glb")
    ///     .atlas_size(512)
    ///     .flow("gusts".parse().map_err(texsyn::Error::InvalidParameter)?)
    ///     .scheme(AdvectScheme { fade: Some(1), ..Default::default() })
    ///     .frames(100)
    ///     .build()?;
    /// while let Some(frame) = session.next_frame()? {
    ///     let render = session.preview(frame)?; // two views of the textured mesh
    ///     # let _ = render;
    /// }
    /// # Ok::<(), texsyn::Error>(())
    /// ```
    pub fn builder<'a>() -> AdvectSessionBuilder<'a> {
        AdvectSessionBuilder {
            source: SourceRequest::None,
            tileable: None,
            size: [256, 256],
            mesh: None,
            atlas_size: DEFAULT_ATLAS_SIZE,
            flow: None,
            dt: 1.0,
            field: None,
            seed: SynthParams::default().seed,
            scheme: SchemeRequest::Scheme(AdvectScheme::default()),
            frames: None,
            energy_every: 0,
            compare_cost: false,
            profile_passes: false,
            context: None,
            progress: None,
            notes: None,
        }
    }
}

impl<'a> AdvectSessionBuilder<'a> {
    /// The exemplar: an image file, or an analysis file (`texsyn analyze`), told apart by
    /// content.
    pub fn exemplar_path(mut self, path: impl AsRef<Path>) -> Self {
        self.source = SourceRequest::Path {
            path: path.as_ref().to_path_buf(),
            mapped: false,
        };
        self
    }

    /// [`Self::exemplar_path`], with an analysis file memory-mapped rather than read (a
    /// faster start for large files).
    ///
    /// # Safety
    ///
    /// The file must not be truncated or modified in place while the session is being
    /// built (see [`crate::Analysis::load_mapped`]); texsyn replaces analysis files by
    /// renaming a new one over them, which leaves a mapping intact.
    pub unsafe fn exemplar_path_mapped(mut self, path: impl AsRef<Path>) -> Self {
        self.source = SourceRequest::Path {
            path: path.as_ref().to_path_buf(),
            mapped: true,
        };
        self
    }

    /// An exemplar already opened: an image in memory or an analysis.
    pub fn exemplar_source(mut self, source: ExemplarSource) -> Self {
        self.source = SourceRequest::Given(source);
        self
    }

    /// Force tileable (wrap-around) or non-tileable handling of an exemplar image
    /// (default: detected); an analysis file must have been analysed the same way.
    pub fn tileable(mut self, tileable: Option<bool>) -> Self {
        self.tileable = tileable;
        self
    }

    /// 2D output size in pixels (default 256x256; at least 5x5).
    pub fn size(mut self, width: u32, height: u32) -> Self {
        self.size = [width, height];
        self
    }

    /// Advect over this mesh's atlas (.gltf/.glb) instead of a 2D output.
    pub fn mesh_path(mut self, path: impl AsRef<Path>) -> Self {
        self.mesh = Some(MeshRequest::Path(path.as_ref().to_path_buf()));
        self
    }

    /// Advect over this mesh's atlas (it is validated and repaired first).
    pub fn mesh(mut self, mesh: Mesh) -> Self {
        self.mesh = Some(MeshRequest::Given(mesh));
        self
    }

    /// The atlas side with a mesh (default [`DEFAULT_ATLAS_SIZE`]).
    pub fn atlas_size(mut self, size: u32) -> Self {
        self.atlas_size = size;
        self
    }

    /// The flow (required). On a mesh, 3D velocities projected into the atlas; a vortex
    /// or a source turns about the mesh's centre there.
    pub fn flow(mut self, flow: Flow) -> Self {
        self.flow = Some(flow);
        self
    }

    /// Time step: a frame moves the texture by velocity * dt (default 1).
    pub fn dt(mut self, dt: f32) -> Self {
        self.dt = dt;
        self
    }

    /// A Jacobian field to synthesize along (2D only).
    pub fn field(mut self, field: Option<Field>) -> Self {
        self.field = field;
        self
    }

    /// Random seed of frame 0 (default 1).
    pub fn seed(mut self, seed: u32) -> Self {
        self.seed = seed;
        self
    }

    /// The scheme to choose the options by (default: [`AdvectScheme::default`], the
    /// recommended scheme).
    pub fn scheme(mut self, scheme: AdvectScheme) -> Self {
        self.scheme = SchemeRequest::Scheme(scheme);
        self
    }

    /// Exactly these options, no choice made.
    pub fn options(mut self, options: AdvectOptions) -> Self {
        self.scheme = SchemeRequest::Options(options);
        self
    }

    /// Frames to advect after the first; [`AdvectSession::next_frame`] gives `None`
    /// after them (default: no end).
    pub fn frames(mut self, frames: u32) -> Self {
        self.frames = Some(frames);
        self
    }

    /// Texture energy every `k` frames in the summary (0, the default: the first and
    /// the last frame only).
    pub fn energy_every(mut self, k: usize) -> Self {
        self.energy_every = k;
        self
    }

    /// Also time whole syntheses of the same output (interleaved with the frames, one
    /// every 8), so that the summary gives a frame's cost as a share of one (default off).
    pub fn compare_cost(mut self, on: bool) -> Self {
        self.compare_cost = on;
        self
    }

    /// Time every dispatch of each frame (one submission per dispatch, slower); the
    /// summary then holds the per-pass times (default off).
    pub fn profile_passes(mut self, on: bool) -> Self {
        self.profile_passes = on;
        self
    }

    /// Run on the caller's device instead of creating a headless one.
    pub fn context(mut self, context: GpuContext) -> Self {
        self.context = Some(context);
        self
    }

    /// Called as the analysis goes (see [`crate::SessionBuilder::on_progress`]).
    pub fn on_progress(mut self, f: impl FnMut(Progress) + 'a) -> Self {
        self.progress = Some(Box::new(f));
        self
    }

    /// Called with each note as it arises (the adapter, the scheme chosen, options that
    /// have no effect, ...); [`AdvectSession::notes`] keeps them too.
    pub fn on_note(mut self, f: impl FnMut(&AdvectNote) + 'a) -> Self {
        self.notes = Some(Box::new(f));
        self
    }

    /// Checks the request (the cheap checks first), opens and analyses the exemplar,
    /// creates or takes the device, prepares the atlas of a mesh, and synthesizes
    /// frame 0; [`AdvectSession::next_frame`] then gives it and the frames after it.
    pub fn build(self) -> Result<AdvectSession> {
        let mut notes = Vec::new();
        let mut on_note = self.notes;
        let mut note = |n: AdvectNote| {
            if let Some(f) = on_note.as_mut() {
                f(&n);
            }
            notes.push(n);
        };
        let mut flow = self.flow.ok_or_else(|| {
            Error::InvalidParameter("no flow given: call AdvectSessionBuilder::flow".into())
        })?;
        if !(self.dt.is_finite() && self.dt > 0.0) {
            return Err(Error::InvalidParameter(format!(
                "time step {}: give a positive finite number",
                self.dt
            )));
        }
        let on_mesh = self.mesh.is_some();
        if on_mesh {
            // On a mesh a vortex or a source turns about the mesh's centre: a centre
            // given in the flow is not used, so it is neither checked nor kept.
            if let Some(c) = flow.centre().filter(|c| *c != [0.5, 0.5]) {
                note(AdvectNote::CentreNotUsed { centre: c });
                flow = flow.with_centre([0.5, 0.5]);
            }
        }
        flow.validate()?;
        // The rule of SynthParams::constant_jacobian, read from the request because the
        // options are checked before the analysis and the atlas that the parameters need.
        let constant_jacobian =
            !on_mesh && matches!(self.field, None | Some(Field::Constant { .. }));
        let (options, reason) = match &self.scheme {
            SchemeRequest::Scheme(s) => s.resolve(constant_jacobian),
            SchemeRequest::Options(o) => (*o, SchemeReason::Options),
        };
        options.check()?;
        if let SchemeRequest::Scheme(s) = &self.scheme {
            // Knobs that act only with another: said, not silently ignored.
            if s.fade_change.is_some() && options.fade == 0 {
                note(AdvectNote::FadeChangeWithoutFade);
            }
            if s.anchor_upsample.is_some() && options.anchor_spacing == 0 {
                note(AdvectNote::AnchorUpsampleWithoutAnchor);
            }
        }
        // The temporal figures use 5x5 windows: refuse what they cannot measure before
        // any frame is made.
        let [width, height] = self.size;
        if !on_mesh && (width < 5 || height < 5) {
            return Err(Error::InvalidParameter(format!(
                "--size {width}x{height}: advection needs an output of at least 5x5 pixels"
            )));
        }
        let source = open_source(self.source, self.tileable, &mut note)?;
        let ctx = match self.context {
            Some(c) => c,
            None => GpuContext::headless()?,
        };
        note(AdvectNote::Adapter(ctx.describe()));
        note(AdvectNote::Scheme {
            keep_look: options.keep_look,
            fade: options.fade,
            reason,
        });
        let size_hint = if on_mesh {
            "advection keeps the whole atlas in one synthesis: give a smaller --atlas-size"
        } else {
            "advection keeps each whole frame in one synthesis: give a smaller --size"
        };
        if !on_mesh {
            // Before anything of the output's size is allocated on the host.
            check_output_size(&ctx, width, height, size_hint)?;
            // A flow image must have the output's size (on a mesh it is refused by the
            // atlas projection): checked before the analysis.
            flow.sample(width, height, 0.0)?;
        }
        source.check_fits(&ctx, AnalysisOptions::default().k)?;
        let analysis = match source {
            ExemplarSource::Analysis(a) => a,
            ExemplarSource::Image(ex) => {
                let options = AnalysisOptions {
                    tileable: self.tileable,
                    ..AnalysisOptions::default()
                };
                let mut progress = self.progress;
                analysis::analyze(&ex, &options, |p| {
                    if let Some(f) = progress.as_mut() {
                        f(p)
                    }
                })?
            }
        };
        // The temporal figures see what `texsyn eval --flow` sees in the written frames:
        // the colours (grey where the exemplar is grey, so that grey figures stay grey).
        let grey = analysis.colors.iter().all(|c| c[0] == c[1] && c[1] == c[2]);
        let exemplar_image =
            run::to_float(grey, analysis.width, analysis.height, &analysis.colors)?;
        let levels = analysis.levels.len();
        let synthesizer = Arc::new(GpuSynthesizer::new(&ctx, Arc::new(analysis))?);

        // 2D output, or a surface: the atlas plus what turns 3D flow into atlas velocities.
        let mut surface = None;
        let mut params = SynthParams {
            width,
            height,
            seed: self.seed,
            field: if on_mesh { None } else { self.field },
            ..SynthParams::default()
        };
        if let Some(request) = self.mesh {
            let mut mesh = match request {
                MeshRequest::Path(p) => load_mesh_file(&p)?,
                MeshRequest::Given(m) => m,
            };
            mesh.validate_and_repair()?;
            let opts = crate::surface::pipeline::SurfaceOptions {
                atlas: crate::surface::atlas::AtlasOptions::for_size(self.atlas_size),
                ..Default::default()
            };
            let prepared = crate::surface::pipeline::prepare(&mesh, levels, &opts)?;
            params = crate::surface::pipeline::atlas_params(&prepared, &params);
            surface = Some(prepared);
        }
        let mut timer = self.compare_cost.then(|| run::SynthesisTimer {
            frame0_params: Advection::synthesis_params(&params),
            params: params.clone(),
            size_hint,
            runs: Vec::new(),
        });
        if let Some(timer) = &mut timer {
            timer.start(&synthesizer)?;
        }
        let advection = Advection::new(synthesizer.clone(), &params, options)
            .map_err(|e| run::with_hint(e, size_hint))?;
        Ok(AdvectSession {
            ctx,
            advection,
            synthesizer,
            surface,
            flow,
            dt: self.dt,
            params,
            options,
            grey,
            frames: self.frames,
            next: 0,
            figures: Some(TemporalFigures::new(
                &exemplar_image,
                match self.energy_every {
                    0 => usize::MAX,
                    k => k,
                },
            )),
            timer,
            costs: Vec::new(),
            passes: self.profile_passes.then(Vec::new),
            notes,
            constant_jacobian,
        })
    }
}

/// Opens the exemplar the request names, with a note for an animated image (its first
/// frame is used) and a check that an analysis file was analysed as asked.
fn open_source(
    request: SourceRequest,
    tileable: Option<bool>,
    note: &mut impl FnMut(AdvectNote),
) -> Result<ExemplarSource> {
    let (path, mapped) = match request {
        SourceRequest::None => {
            return Err(Error::InvalidParameter(
                "no exemplar given: call exemplar_path or exemplar_source".into(),
            ))
        }
        SourceRequest::Given(source) => return Ok(source),
        SourceRequest::Path { path, mapped } => (path, mapped),
    };
    let source = if mapped {
        // SAFETY: the contract of `exemplar_path_mapped`, which set `mapped`.
        unsafe { ExemplarSource::open_mapped(&path)? }
    } else {
        ExemplarSource::open(&path)?
    };
    if let ExemplarSource::Image(_) = &source {
        if let Some(frames @ 2..) = crate::image_io::animation_frames(&path) {
            note(AdvectNote::AnimatedExemplar {
                path: path.clone(),
                frames,
            });
        }
    }
    source.check_matches(&path, None, tileable)?;
    Ok(source)
}

/// Reads a glTF mesh file (the `gltf` feature).
#[cfg(feature = "gltf")]
fn load_mesh_file(path: &Path) -> Result<Mesh> {
    Ok(crate::surface::gltf_io::load_mesh(path)?.0)
}

/// Without the `gltf` feature there is no mesh reader: a mesh must be given in memory.
#[cfg(not(feature = "gltf"))]
fn load_mesh_file(path: &Path) -> Result<Mesh> {
    Err(Error::InvalidParameter(format!(
        "{}: reading meshes needs texsyn's `gltf` feature; pass the mesh in memory \
         (AdvectSessionBuilder::mesh) instead",
        path.display()
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scheme_keeps_the_look_only_where_the_jacobian_is_constant() {
        let auto = AdvectScheme::default();
        let (o, why) = auto.resolve(true);
        assert!(o.keep_look && o.fade == KEEP_LOOK_FADE);
        assert_eq!(why, SchemeReason::KeepLookDefault);
        assert_eq!(o.levels, AdvectOptions::keep_look().levels);
        let (o, why) = auto.resolve(false);
        assert!(!o.keep_look && o.fade == 0);
        assert_eq!(why, SchemeReason::CarryDefault);
        let two = AdvectScheme {
            levels: Some(2),
            ..Default::default()
        };
        assert_eq!(two.resolve(true).1, SchemeReason::FewLevels);
        let asked = AdvectScheme {
            keep_look: true,
            fade: Some(0),
            ..Default::default()
        };
        let (o, why) = asked.resolve(false);
        assert!(o.keep_look && o.fade == 0);
        assert_eq!(why, SchemeReason::KeepLookAsked);
        assert_eq!(
            AdvectNote::Scheme {
                keep_look: o.keep_look,
                fade: o.fade,
                reason: why
            }
            .to_string(),
            "advection: keeping the look, renewals not faded (--keep-look)"
        );
    }
}
