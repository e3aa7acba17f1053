//! Surface synthesis as one request (Lefebvre & Hoppe 2006, section 6): a mesh and an
//! exemplar in; the texture synthesized directly in the mesh's atlas, following a
//! tangent field, seamless across chart edges; a textured glTF, the atlas image and
//! renders out.
//!
//! ```no_run
//! use texsyn::SurfaceSession;
//!
//! let session = SurfaceSession::builder()
//!     .mesh_path("assets/meshes/bunny.glb")
//!     .exemplar_path("assets/gravel.png")
//!     .atlas_size(512)
//!     .seed(7)
//!     .build()?; // device, analysis, atlas, tangent field and maps
//! let textured = session.run()?; // the synthesis in the atlas
//! textured.save("bunny.glb")?; // geometry, atlas uvs and the texture as its material
//! let views = textured.render(&Default::default())?;
//! texsyn::image_io::save_image_atomic("views.png".as_ref(), views.width(), views.height(), 4, views.as_raw())?;
//! # Ok::<(), texsyn::Error>(())
//! ```

#![cfg(feature = "gltf")]

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use super::{crop_rows, ExemplarSource, Magnified};
use crate::analysis::{self, Analysis, AnalysisOptions, Exemplar, Progress};
use crate::error::{Error, Result};
use crate::gpu::synth::{ExtraMap, GpuSynthesizer};
use crate::gpu::GpuContext;
use crate::passes::SynthParams;
use crate::surface::atlas::{AtlasOptions, AtlasSource};
use crate::surface::gltf_io;
use crate::surface::pipeline::{self, PrepareTimings, PreparedSurface, SurfaceOptions};
use crate::surface::tangent_field::{DirectionSource, ScaleSource};
use crate::surface::Mesh;

mod textured;
pub use textured::TexturedSurface;

enum MeshInput {
    None,
    Path(PathBuf),
    Mesh(Box<Mesh>),
}

enum ExemplarInput {
    None,
    Path(PathBuf),
    Source(Box<ExemplarSource>),
}

/// A material map aligned with the exemplar (same size; with magnification, the size
/// of the full-resolution exemplar), synthesized in the same coordinates as the colours.
#[derive(Clone, Debug)]
pub struct SurfaceMap {
    /// The map's pixels (its [`Exemplar::colors`] are used).
    pub image: Exemplar,
    /// What messages call it (its file name).
    pub name: String,
}

impl SurfaceMap {
    /// A map already in memory; `name` is what messages call it.
    pub fn new(image: Exemplar, name: impl Into<String>) -> Self {
        SurfaceMap {
            image,
            name: name.into(),
        }
    }

    /// Loads the image at `path`.
    pub fn open(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        Ok(Self::new(
            crate::image_io::load_exemplar(path)?,
            path.display().to_string(),
        ))
    }
}

/// What [`SurfaceBuilder::build`] reports as it goes, to the
/// [`on_progress`](SurfaceBuilder::on_progress) callback. `Display` gives a line for
/// the user.
#[non_exhaustive]
pub enum SurfaceEvent<'a> {
    /// The device the work runs on.
    Device(&'a GpuContext),
    /// The exemplar analysis (when the exemplar is an image).
    Analysis(Progress),
    /// The atlas, tangent field and per-level maps are being built (seconds to minutes
    /// for large meshes).
    Preparing,
    /// The atlas, field and maps are ready.
    Prepared {
        /// What was built.
        surface: &'a PreparedSurface,
        /// The magnification (1 without), to state the texel size in full-resolution
        /// exemplar texels.
        magnify: u32,
    },
}

impl fmt::Display for SurfaceEvent<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SurfaceEvent::Device(ctx) => write!(f, "adapter: {}", ctx.describe()),
            SurfaceEvent::Analysis(p) => write!(
                f,
                "analysing level {}/{}: {} {:.0}%",
                (p.done + 1).min(p.total),
                p.total,
                p.stage.name(),
                100.0 * p.fraction
            ),
            SurfaceEvent::Preparing => write!(f, "preparing the atlas, field and maps..."),
            SurfaceEvent::Prepared { surface, magnify } => {
                let atlas = &surface.atlas;
                write!(
                    f,
                    "atlas: {0}x{0}, {1} charts, {2:.0}% covered, {3}",
                    atlas.size,
                    atlas.chart_count,
                    atlas.coverage() * 100.0,
                    if atlas.generated {
                        format!("built with xatlas ({})", atlas.note)
                    } else {
                        "the mesh's TEXCOORD_0".to_string()
                    }
                )?;
                if let Some(s) = surface.texel_size {
                    write!(
                        f,
                        "\ntexel size: {:.5} world units per exemplar texel",
                        s / *magnify as f32
                    )?;
                }
                let singular = surface.field.singularities().len();
                if singular > 0 {
                    write!(f, "\nfield: {singular} singular vertices")?;
                }
                if surface.report.clamped > 0 {
                    write!(
                        f,
                        "\nnote: {} atlas texels ask for more than 8x stretch; clamped",
                        surface.report.clamped
                    )?;
                }
                Ok(())
            }
        }
    }
}

type ProgressFn<'p> = Box<dyn FnMut(SurfaceEvent<'_>) + 'p>;

/// Builds a [`SurfaceSession`]: a mesh, an exemplar and options.
pub struct SurfaceBuilder<'p> {
    mesh: MeshInput,
    exemplar: ExemplarInput,
    atlas_size: u32,
    atlas_source: AtlasSource,
    direction: DirectionSource,
    texel_size: Option<ScaleSource>,
    magnify: Option<u32>,
    normal: Option<SurfaceMap>,
    normal_green_down: bool,
    roughness: Option<SurfaceMap>,
    occlusion: Option<SurfaceMap>,
    params: SynthParams,
    tileable: Option<bool>,
    context: Option<GpuContext>,
    progress: Option<ProgressFn<'p>>,
}

/// A mesh prepared for synthesis (atlas, tangent field, per-level maps) and an analysed
/// exemplar on a GPU: [`Self::run`] synthesizes the texture.
pub struct SurfaceSession {
    context: GpuContext,
    synthesizer: GpuSynthesizer,
    prepared: PreparedSurface,
    params: SynthParams,
    magnified: Option<Magnified>,
    /// Normal, roughness and occlusion maps, cropped as the exemplar was.
    maps: [Option<ExtraMap>; 3],
    timings: SurfaceTimings,
}

/// Wall-clock time of the steps of [`SurfaceBuilder::build`].
#[derive(Clone, Copy, Debug, Default)]
pub struct SurfaceTimings {
    /// The exemplar analysis (zero for an analysis file).
    pub analysis: Duration,
    /// The atlas, field and maps together.
    pub prepare: Duration,
    /// Each step of the preparation.
    pub prepare_steps: PrepareTimings,
    /// Uploading the analysis to the GPU.
    pub upload: Duration,
}

impl SurfaceSession {
    /// A builder: give it a mesh (`mesh_path` or `mesh`) and an exemplar
    /// (`exemplar_path`, `exemplar`, `analysis` or `exemplar_source`), then options, then
    /// [`SurfaceBuilder::build`].
    ///
    /// ```no_run
    /// use texsyn::SurfaceSession;
    /// use texsyn::surface::tangent_field::DirectionSource;
    ///
    /// SurfaceSession::builder()
    ///     .mesh(texsyn::surface::Mesh::torus(1.0, 0.4, 64, 32))
    ///     .exemplar_path("assets/brick.png")
    ///     .direction(DirectionSource::Symmetric { n: 2, up: glam::Vec3::Y, iterations: 200 })
    ///     .on_progress(|event| eprintln!("{event}"))
    ///     .build()?
    ///     .run()?
    ///     .save("torus.glb")?;
    /// # Ok::<(), texsyn::Error>(())
    /// ```
    pub fn builder<'p>() -> SurfaceBuilder<'p> {
        SurfaceBuilder {
            mesh: MeshInput::None,
            exemplar: ExemplarInput::None,
            atlas_size: 1024,
            atlas_source: AtlasSource::Auto,
            direction: DirectionSource::Up(glam::Vec3::Y),
            texel_size: None,
            magnify: None,
            normal: None,
            normal_green_down: false,
            roughness: None,
            occlusion: None,
            params: SynthParams::default(),
            tileable: None,
            context: None,
            progress: None,
        }
    }

    /// The atlas, field and maps.
    pub fn prepared(&self) -> &PreparedSurface {
        &self.prepared
    }

    /// The mesh with its atlas uvs (what the glTF holds).
    pub fn mesh(&self) -> &Mesh {
        &self.prepared.atlas.mesh
    }

    /// The exemplar analysis the synthesis reads.
    pub fn analysis(&self) -> &Analysis {
        self.synthesizer.analysis()
    }

    /// The GPU device and queue (the caller's, or a headless one).
    pub fn context(&self) -> &GpuContext {
        &self.context
    }

    /// How long each step of [`SurfaceBuilder::build`] took.
    pub fn timings(&self) -> &SurfaceTimings {
        &self.timings
    }
}

impl<'p> SurfaceBuilder<'p> {
    /// The mesh: a `.gltf` (with its buffers) or `.glb` file, every triangle primitive
    /// of its scene ([`gltf_io::load_mesh`]).
    pub fn mesh_path(mut self, path: impl AsRef<Path>) -> Self {
        self.mesh = MeshInput::Path(path.as_ref().to_path_buf());
        self
    }

    /// A mesh in memory (its `uvs`, if any, may be kept as the atlas).
    pub fn mesh(mut self, mesh: Mesh) -> Self {
        self.mesh = MeshInput::Mesh(Box::new(mesh));
        self
    }

    /// The exemplar: an image file, or a saved analysis (`texsyn analyze`), told apart
    /// by content.
    pub fn exemplar_path(mut self, path: impl AsRef<Path>) -> Self {
        self.exemplar = ExemplarInput::Path(path.as_ref().to_path_buf());
        self
    }

    /// An exemplar image already in memory.
    pub fn exemplar(self, exemplar: Exemplar) -> Self {
        self.exemplar_source(ExemplarSource::Image(exemplar))
    }

    /// An analysis made earlier; skips the analysis (no magnification: that needs the
    /// image).
    pub fn analysis(self, analysis: Analysis) -> Self {
        self.exemplar_source(ExemplarSource::Analysis(analysis))
    }

    /// An exemplar opened with [`ExemplarSource::open`].
    pub fn exemplar_source(mut self, source: ExemplarSource) -> Self {
        self.exemplar = ExemplarInput::Source(Box::new(source));
        self
    }

    /// Atlas side in texels (default 1024; small meshes need more texels than charts).
    pub fn atlas_size(mut self, size: u32) -> Self {
        self.atlas_size = size;
        self
    }

    /// Keep the mesh's uvs as the atlas when usable (default), always build a new one,
    /// or insist on the mesh's.
    pub fn atlas_source(mut self, source: AtlasSource) -> Self {
        self.atlas_source = source;
        self
    }

    /// Where the exemplar's x axis goes on the surface (default: up along +y).
    pub fn direction(mut self, direction: DirectionSource) -> Self {
        self.direction = direction;
        self
    }

    /// World units per exemplar texel, counted in texels of the full-resolution
    /// exemplar also with [`Self::magnify`] (default: one exemplar texel per atlas texel
    /// on average).
    pub fn texel_size(mut self, scale: ScaleSource) -> Self {
        self.texel_size = Some(scale);
        self
    }

    /// Magnify 2, 4 or 8 times: synthesize with the exemplar downsampled that many times
    /// and read the colours (and maps) from the full one; the texture is that many times
    /// larger than the atlas. Needs an exemplar image.
    pub fn magnify(mut self, factor: u32) -> Self {
        self.magnify = Some(factor);
        self
    }

    /// A tangent-space normal map, embedded as the material's normal texture (rotated
    /// with the field).
    pub fn normal_map(mut self, map: SurfaceMap) -> Self {
        self.normal = Some(map);
        self
    }

    /// The normal map has green = y down (DirectX); the embedded texture is converted to
    /// glTF's green up (default `false`: green up).
    pub fn normal_green_down(mut self, on: bool) -> Self {
        self.normal_green_down = on;
        self
    }

    /// A roughness map (grey; red channel used), embedded as the material's
    /// metallic-roughness texture (roughness in green, metallic 0).
    pub fn roughness_map(mut self, map: SurfaceMap) -> Self {
        self.roughness = Some(map);
        self
    }

    /// An ambient-occlusion map (grey; red channel used).
    pub fn occlusion_map(mut self, map: SurfaceMap) -> Self {
        self.occlusion = Some(map);
        self
    }

    /// Random seed (default 1): the same seed gives the same bytes.
    pub fn seed(mut self, seed: u32) -> Self {
        self.params.seed = seed;
        self
    }

    /// Per-level randomness (index = level, coarsest first; the last value repeats).
    pub fn randomness(mut self, r: Vec<f32>) -> Self {
        self.params.randomness = r;
        self
    }

    /// Correction passes per coarse level (see [`SynthParams::passes`]).
    pub fn passes(mut self, passes: u32) -> Self {
        self.params.passes = passes;
        self
    }

    /// Bias towards coherent candidates, 0 to 4 (see [`SynthParams::coherence`]).
    pub fn coherence(mut self, c: f32) -> Self {
        self.params.coherence = c;
        self
    }

    /// Force tileable (wrap-around) or non-tileable handling of an exemplar image;
    /// default: detected.
    pub fn tileable(mut self, tileable: bool) -> Self {
        self.tileable = Some(tileable);
        self
    }

    /// Run on the caller's device instead of creating a headless one.
    pub fn context(mut self, context: GpuContext) -> Self {
        self.context = Some(context);
        self
    }

    /// Called as the work goes (see [`SurfaceEvent`]).
    pub fn on_progress(mut self, f: impl FnMut(SurfaceEvent<'_>) + 'p) -> Self {
        self.progress = Some(Box::new(f));
        self
    }

    /// Loads the inputs, creates or takes the device, checks that the atlas fits it,
    /// analyses the exemplar, builds the atlas, tangent field and maps, and uploads the
    /// analysis.
    pub fn build(self) -> Result<SurfaceSession> {
        let mut progress = self.progress;
        let mut emit = |e: SurfaceEvent<'_>| {
            if let Some(f) = progress.as_mut() {
                f(e)
            }
        };
        let mut mesh = match self.mesh {
            MeshInput::None => return Err(missing("mesh: call mesh_path or mesh")),
            MeshInput::Path(p) => gltf_io::load_mesh(&p)?.0,
            MeshInput::Mesh(m) => *m,
        };
        mesh.validate_and_repair()?;
        let mut source = match self.exemplar {
            ExemplarInput::None => {
                return Err(missing(
                    "exemplar: call exemplar_path, exemplar, analysis or exemplar_source",
                ))
            }
            ExemplarInput::Path(p) => ExemplarSource::open(&p)?,
            ExemplarInput::Source(s) => *s,
        };
        // Material maps are aligned with the exemplar as given (full resolution when
        // magnified: they are magnified with the colours).
        let full_size = source.image_size();
        let mut magnified = None;
        if let Some(f) = self.magnify {
            let (small, hi) = source.magnify(f)?;
            source = small;
            magnified = Some(hi);
        }
        let magnify = self.magnify.unwrap_or(1);

        let context = match self.context {
            Some(c) => c,
            None => GpuContext::headless()?,
        };
        emit(SurfaceEvent::Device(&context));
        check_atlas_fits(&context, self.atlas_size, magnify)?;
        let t = Instant::now();
        source.check_fits(&context, AnalysisOptions::default().k)?;
        let analysis = match source {
            ExemplarSource::Analysis(a) => a,
            ExemplarSource::Image(ex) => {
                let options = AnalysisOptions {
                    tileable: self.tileable,
                    // The atlas synthesis leaves the finest level uncorrected: its
                    // similarity sets would go unread (same bytes without them).
                    finest_sets: false,
                    ..AnalysisOptions::default()
                };
                analysis::analyze(&ex, &options, |p| emit(SurfaceEvent::Analysis(p)))?
            }
        };
        let analysis_time = t.elapsed();
        let (map_w, map_h) = match (&magnified, full_size) {
            (Some(_), Some(size)) => size,
            _ => (analysis.width, analysis.height),
        };
        let material = [&self.normal, &self.roughness, &self.occlusion];
        for map in material.iter().copied().flatten() {
            let (w, h) = (map.image.width, map.image.height);
            if (w, h) != (map_w, map_h) {
                return Err(Error::InvalidParameter(format!(
                    "{} is {w}x{h}, the exemplar {map_w}x{map_h}: material maps must be \
                     aligned with it",
                    map.name,
                )));
            }
        }

        let options = SurfaceOptions {
            atlas: AtlasOptions {
                source: self.atlas_source,
                ..AtlasOptions::for_size(self.atlas_size)
            },
            direction: self.direction,
            // The synthesis's exemplar texel is `magnify` full-resolution texels.
            scale: self.texel_size.map(|s| scale_by(s, magnify as f32)),
        };
        emit(SurfaceEvent::Preparing);
        let t = Instant::now();
        let prepared = pipeline::prepare(&mesh, analysis.levels.len(), &options)?;
        let prepare_time = t.elapsed();
        emit(SurfaceEvent::Prepared {
            surface: &prepared,
            magnify,
        });

        let t = Instant::now();
        let synthesizer = GpuSynthesizer::new(&context, Arc::new(analysis))?;
        let upload_time = t.elapsed();
        let extra = |map: &Option<SurfaceMap>, normal: bool| {
            map.as_ref().map(|m| ExtraMap {
                // Cropped as the exemplar was (to a multiple of the magnification).
                pixels: match &magnified {
                    Some(hi) => crop_rows(&m.image.colors, m.image.width, hi.width, hi.height),
                    None => m.image.colors.clone(),
                },
                normal,
                green_down: normal && self.normal_green_down,
            })
        };
        let maps = [
            extra(&self.normal, true),
            extra(&self.roughness, false),
            extra(&self.occlusion, false),
        ];
        Ok(SurfaceSession {
            context,
            synthesizer,
            timings: SurfaceTimings {
                analysis: analysis_time,
                prepare: prepare_time,
                prepare_steps: prepared.timings,
                upload: upload_time,
            },
            prepared,
            params: self.params,
            magnified,
            maps,
        })
    }
}

fn missing(what: &str) -> Error {
    Error::InvalidParameter(format!("no {what}"))
}

/// `scale` in units `factor` times larger.
fn scale_by(scale: ScaleSource, factor: f32) -> ScaleSource {
    match scale {
        ScaleSource::Constant(v) => ScaleSource::Constant(v * factor),
        ScaleSource::PerVertex(v) => {
            ScaleSource::PerVertex(v.into_iter().map(|x| x * factor).collect())
        }
        ScaleSource::Linear {
            axis,
            at_min,
            at_max,
        } => ScaleSource::Linear {
            axis,
            at_min: at_min * factor,
            at_max: at_max * factor,
        },
    }
}

/// Refuses an atlas the device cannot synthesize before the mesh work (minutes for
/// large atlases): the synthesis keeps a coordinate pyramid and a Jacobian per texel
/// (16 bytes, about 4/3 of the atlas over all levels) in one buffer, and the texture
/// (times the magnification) must fit the device's texture size. The messages name the
/// command line's options.
fn check_atlas_fits(ctx: &GpuContext, atlas: u32, magnify: u32) -> Result<()> {
    let limits = ctx.limits();
    let side = atlas as u64 * magnify as u64;
    if side > limits.max_texture_dimension_2d as u64 {
        return Err(Error::InvalidParameter(format!(
            "--atlas-size {atlas}{}: the atlas texture would be {side} texels a side, the device allows {}; give a smaller --atlas-size",
            if magnify > 1 { format!(" with --magnify {magnify}") } else { String::new() },
            limits.max_texture_dimension_2d
        )));
    }
    let bytes = (atlas as u64).pow(2) * 16 * 4 / 3;
    let max = limits
        .max_storage_buffer_binding_size
        .min(limits.max_buffer_size);
    if bytes > max {
        return Err(Error::InvalidParameter(format!(
            "--atlas-size {atlas}: its synthesis needs about {} MiB in one buffer, the device allows {} MiB; give a smaller --atlas-size (at most about {})",
            bytes >> 20,
            max >> 20,
            (((max * 3 / 4) / 16) as f64).sqrt() as u64
        )));
    }
    Ok(())
}
