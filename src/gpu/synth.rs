//! Synthesis on the GPU: uploads an [`Analysis`] once, then runs the plan's dispatches
//! (upsample, jitter, correction subpasses per level, gather) in one compute pass per
//! call. Results stay on the GPU (a `wgpu::Texture`) or are read back to the host.

use std::sync::{Arc, Mutex};

use super::context::GpuContext;
use super::shaders::{self, ShaderSource};
use crate::analysis::{Analysis, LevelData, DIM};
use crate::error::{Error, Result};
use crate::passes::common::{PassParams, PARAMS_STRIDE};
use crate::passes::plan::{Dispatch, PassKind, SynthPlan};
use crate::passes::{SynthParams, Synthesis};

/// Bytes of one level's projection matrix in the uniform buffer (64 x vec4<i32>; a
/// multiple of the 256-byte dynamic-offset alignment).
const PROJ_BYTES: u64 = 64 * 16;

/// Format of the synthesized colour texture. It holds the exemplar's bytes as they are,
/// i.e. sRGB-encoded colours for ordinary images; a storage texture cannot have an sRGB
/// format, so view it as [`OUTPUT_FORMAT_SRGB`] ([`GpuSynthesis::srgb_view`]) to have
/// the sampler decode to linear.
pub const OUTPUT_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// The sRGB view format of the output texture (listed in its `view_formats` on every
/// backend but GL, which cannot reinterpret formats).
pub const OUTPUT_FORMAT_SRGB: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

/// The most pixels [`GpuSynthesizer::synthesize_in_windows`] assembles (16384 x 16384:
/// 1 GiB of colours and 2 GiB of coordinates on the host).
pub const MAX_WINDOWED_PIXELS: usize = 1 << 28;

/// A synthesized texture on the GPU.
pub struct GpuSynthesis {
    /// RGBA8 colours (`Rgba8Unorm` holding sRGB-encoded bytes; usages: storage, texture
    /// binding, copy source). Sample it through [`Self::srgb_view`] to get linear colours.
    pub texture: wgpu::Texture,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

/// An sRGB view of a texsyn output texture, for sampling (texture binding only), or
/// `None` on the GL backend (decode in the shader there). See [`GpuSynthesis::srgb_view`].
pub fn srgb_view(ctx: &GpuContext, texture: &wgpu::Texture) -> Option<wgpu::TextureView> {
    ctx.supports_view_formats().then(|| {
        texture.create_view(&wgpu::TextureViewDescriptor {
            label: Some("texsyn output (sRGB)"),
            format: Some(OUTPUT_FORMAT_SRGB),
            usage: Some(wgpu::TextureUsages::TEXTURE_BINDING),
            ..Default::default()
        })
    })
}

impl GpuSynthesis {
    /// A view of the colours as [`OUTPUT_FORMAT_SRGB`], so that sampling in a shader
    /// returns linear values (what lighting and blending need); `None` on the GL
    /// backend, which cannot reinterpret formats (decode in the shader there).
    pub fn srgb_view(&self, ctx: &GpuContext) -> Option<wgpu::TextureView> {
        srgb_view(ctx, &self.texture)
    }

    /// Copies the texture back to the host as tightly packed RGBA8 rows (waits for the
    /// GPU). For when the pixels are needed after all; `synthesize_to_host` does the
    /// synthesis and this read-back in one submission. After
    /// [`GpuSynthesizer::encode`], call it only once the encoder is submitted: before,
    /// the texture is still blank (zeros), which this cannot tell from a result. `ctx`
    /// must be the context the texture was made on (the synthesizer's, or a clone): this
    /// struct does not record it, and wgpu panics on another instance's device.
    pub fn read_rgba8(&self, ctx: &GpuContext) -> Result<Vec<u8>> {
        let (w, h) = (self.width, self.height);
        let row = (w as u64 * 4).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT as u64);
        let buffer = ctx.scoped(|| {
            let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("texsyn texture readback"),
                size: row * h as u64,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let mut encoder = ctx.device.create_command_encoder(&Default::default());
            encoder.copy_texture_to_buffer(
                self.texture.as_image_copy(),
                wgpu::TexelCopyBufferInfo {
                    buffer: &buffer,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(row as u32),
                        rows_per_image: Some(h),
                    },
                },
                self.texture.size(),
            );
            ctx.queue.submit([encoder.finish()]);
            buffer
        })?;
        let data = read_buffer(ctx, &buffer)?;
        let mut out = Vec::with_capacity(w as usize * h as usize * 4);
        for y in 0..h as usize {
            let start = y * row as usize;
            out.extend_from_slice(&data[start..start + w as usize * 4]);
        }
        Ok(out)
    }
}

/// An extra map gathered through the synthesized coordinates (material sets).
pub(crate) struct MapTarget<'a> {
    colors: &'a wgpu::Buffer,
    view: &'a wgpu::TextureView,
    /// `PassParams::map_kind`: 0 plain, 1 normals with green down, 2 with green up.
    map_kind: u32,
    /// > 1: the magnify pass with a high-resolution exemplar of `hi_size`.
    magnify: u32,
    hi_size: [i32; 2],
}

/// An exemplar-aligned extra map (normal, height, roughness...) to resynthesize through
/// the same coordinates as the colours.
#[derive(Clone, Debug)]
pub struct ExtraMap {
    /// RGBA8, row-major, the exemplar's size.
    pub pixels: Vec<[u8; 4]>,
    /// Tangent-space normals (x, y in red, green): rotated with the texture along a field.
    pub normal: bool,
    /// For normal maps: green is y *down* the image (the DirectX convention). `false`
    /// (the default): green is y up, the convention of OpenGL, glTF and Blender.
    pub green_down: bool,
}

impl ExtraMap {
    /// `PassParams::map_kind` of this map.
    pub fn map_kind(&self) -> u32 {
        match (self.normal, self.green_down) {
            (false, _) => 0,
            (true, true) => 1,
            (true, false) => 2,
        }
    }
}

/// A magnified synthesis with its material sets, on the host
/// ([`GpuSynthesizer::synthesize_magnified_with_maps`]).
#[derive(Clone, Debug)]
pub struct MagnifiedSynthesis {
    /// Magnified size: `factor` times the synthesized window.
    pub width: u32,
    pub height: u32,
    pub factor: u32,
    /// Magnified colours from the high-resolution exemplar, RGBA8, `width x height`.
    pub colors: Vec<[u8; 4]>,
    /// Each extra map, magnified the same way, RGBA8, `width x height`.
    pub maps: Vec<Vec<[u8; 4]>>,
    /// The synthesis at its own resolution (coordinates in the analysed exemplar's
    /// pixels, and its colours).
    pub synthesis: Synthesis,
}

/// The coordinate pyramid, kept between calls of the same or smaller size. Sharing it
/// is safe even for several syntheses recorded into one encoder: they run in order.
struct Scratch {
    entries: u64,
    coords: wgpu::Buffer,
}

/// An exemplar uploaded to a device, ready to synthesize any number of textures.
pub struct GpuSynthesizer {
    analysis: Arc<Analysis>,
    /// The context everything here was made on (a clone): calls with another context
    /// are refused ([`Self::check_context`]).
    context: GpuContext,
    /// The device's pass pipelines, shared by every synthesizer on it.
    pipelines: Arc<PassPipelines>,
    /// 16-byte stand-in for the velocity binding outside advection.
    no_velocity: wgpu::Buffer,
    et: wgpu::Buffer,
    /// Uploaded on first use ([`Self::qe_for`]): only the projected distance reads it, and
    /// a default isometric synthesis uses the full distance on every corrected level.
    qe: Mutex<Option<wgpu::Buffer>>,
    /// 16-byte stand-in for `qe` in the bind groups of schedules that never read it.
    no_qe: wgpu::Buffer,
    offsets: wgpu::Buffer,
    proj: wgpu::Buffer,
    colors: wgpu::Buffer,
    scratch: Mutex<Option<Scratch>>,
    /// Per level, its quarter-pixel tables, built on first use (advection frames read
    /// those of their most corrected level; `None` if they do not fit the device's
    /// buffer limits: the shader then interpolates, same numbers).
    fine: Vec<std::sync::OnceLock<Option<FineTables>>>,
    /// The last rasterized Jacobian field and the regions it covers: a frame loop that
    /// keeps its field and window reuses it instead of rasterizing again.
    /// With the surface buffer of atlas synthesis (a placeholder otherwise).
    jacobians: Mutex<Option<(JacobianKey, wgpu::Buffer, wgpu::Buffer)>>,
    /// [`Self::set_progress`]'s callback: (levels done, levels in all).
    /// The progress callback, in a lock of its own: the slot's lock is held only to
    /// clone it out, so the callback may call [`Self::set_progress`] or synthesize.
    progress: Mutex<Option<Arc<Mutex<LevelProgress>>>>,
}

/// An analysis level's `Et` and `qe` interpolated at every quarter pixel
/// ([`crate::passes::correct_aniso::quarter_table`]), bound in place of the whole tables
/// for the corrections that read quarter pixels (`PassParams::quarter`): one read of 16
/// bytes where bilinear interpolation reads four. 16 times the level's tables (8 MiB
/// for a 128x128 exemplar), built and uploaded on first use only.
pub(crate) struct FineTables {
    /// `et_base` of the level they were built for.
    et_base: u32,
    et: wgpu::Buffer,
    qe: wgpu::Buffer,
}

impl FineTables {
    /// Builds the tables for a level, or `None` if it has no tables or a table exceeds
    /// the device's buffer limits.
    fn build(ctx: &GpuContext, a: &Analysis, level_index: usize) -> Option<Self> {
        let level = a.levels.get(level_index).filter(|l| !l.et.is_empty())?;
        let px = a.width as u64 * a.height as u64;
        let bytes = px << (2 * crate::passes::common::QUARTER_BITS) << 4;
        let limits = ctx.limits();
        if bytes
            > limits
                .max_storage_buffer_binding_size
                .min(limits.max_buffer_size)
        {
            return None;
        }
        // What the table reads depend on: the exemplar's size and wrapping.
        let p = PassParams {
            ex_size: [a.width as i32, a.height as i32],
            tileable: a.tileable as i32,
            quarter: 1,
            et_base: a.table_base(level_index) as u32,
            ..Default::default()
        };
        let (et, qe) = std::thread::scope(|s| {
            let et = s.spawn(|| crate::passes::correct_aniso::quarter_table(&p, &level.et));
            let qe = crate::passes::correct_aniso::quarter_table(&p, &level.qe);
            (et.join().expect("quarter table thread"), qe)
        });
        let init = |label: &str, t: &[[i16; DIM]]| {
            crate::gpu::buffer_init(
                &ctx.device,
                &wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents: bytemuck::cast_slice(t),
                    usage: wgpu::BufferUsages::STORAGE,
                },
            )
        };
        Some(Self {
            et_base: p.et_base,
            et: init("texsyn fine et", &et),
            qe: init("texsyn fine qe", &qe),
        })
    }
}

/// A callback told `(levels done, levels in all)` during a synthesis.
pub type LevelProgress = Box<dyn FnMut(u32, u32) + Send>;

/// What a rasterized Jacobian buffer depends on: the field, the regions, and the atlas
/// domain (by identity: a domain is immutable once shared).
type JacobianKey = (
    Option<crate::field::Field>,
    Vec<([i32; 2], [u32; 2])>,
    Option<usize>,
);

/// The switches compiled into a pass pipeline as WGSL overrides (`shaders/shared/
/// common.wgsl`): a pipeline per combination in use, so that CPU drivers do not run the
/// branches a dispatch never takes. Bits 0-10: the flags of [`Self::FLAGS`]; bits 11-13:
/// the similarity-set size k - 1; bit 14 DRIFT, bit 15 LONG_FADE.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Variant(u16);

impl Variant {
    const FLAGS: [&'static str; 11] = [
        "TILEABLE",
        "FULL_DISTANCE",
        "KSET_INTERP",
        "MASKED",
        "PERIODIC",
        "QUARTER",
        "FINE_TABLES",
        "IDENTITY_J",
        "NEAREST",
        "SEAM_BLEND",
        "COHERENT_SKIP",
    ];
    const K_SHIFT: u32 = 11;
    /// The bits only the correction passes read: FULL_DISTANCE, KSET_INTERP, QUARTER,
    /// FINE_TABLES, COHERENT_SKIP and k.
    const CORRECTION_ONLY: u16 = 0b11_1100_0110_0110;
    /// The bits only the gathers read: NEAREST and SEAM_BLEND.
    const GATHER_ONLY: u16 = 0b11 << 8;
    const SEAM_BLEND: u16 = 1 << 9;
    const FINE_TABLES: u16 = 1 << 6;
    const IDENTITY_J: u16 = 1 << 7;
    /// Above k's bits: `params.drift != 0`, which only the anisometric upsampling
    /// branches on (an advection frame's drift phase). As a uniform branch it cost every
    /// synthesis along a field about a tenth of its time on lavapipe (measured: bench
    /// 512x512, `rotate:30` 104-108 ms against 92-93 ms, swirl 126-132 against 114-115).
    const DRIFT: u16 = 1 << 14;
    /// `params.fade_frames > 1`, which only the fade pass branches on.
    const LONG_FADE: u16 = 1 << 15;
    const K_MASK: u16 = 0b111;

    /// The switches of a dispatch, from the parameters the CPU mirror reads
    /// (FINE_TABLES off: see [`Self::with_fine_tables`]).
    pub(crate) fn of(p: &PassParams) -> Self {
        let flags = [
            p.tileable != 0,
            p.full_distance != 0,
            p.kset_interp != 0,
            p.masked != 0,
            p.periodic != 0,
            p.quarter != 0,
            false,
            false,
            p.nearest != 0,
            p.seam_blend != 0,
            p.coherent_skip != 0,
        ];
        let k = (p.k.clamp(1, crate::analysis::MAX_K as i32) - 1) as u16;
        let high = if p.drift != 0 { Self::DRIFT } else { 0 }
            | if p.fade_frames > 1 {
                Self::LONG_FADE
            } else {
                0
            };
        Self(
            flags
                .iter()
                .enumerate()
                .fold((k << Self::K_SHIFT) | high, |v, (i, &b)| {
                    v | (u16::from(b) << i)
                }),
        )
    }

    /// The same, reading the level's quarter-pixel tables ([`FineTables`]).
    fn with_fine_tables(self) -> Self {
        Self(self.0 | Self::FINE_TABLES)
    }

    /// The switches of a dispatch of `plan`: [`Self::of`], plus IDENTITY_J where the
    /// plan's Jacobians are all the identity ([`SynthPlan::identity_jacobians`]), so that
    /// the passes use the constant instead of reading it.
    fn of_dispatch(plan: &SynthPlan, d: &Dispatch) -> Self {
        let v = Self::of(&d.params);
        if plan.identity_jacobians() {
            Self(v.0 | Self::IDENTITY_J)
        } else {
            v
        }
    }

    /// The switches only the correction passes read are reset for the others, so they
    /// share one pipeline across levels.
    fn for_kind(self, kind: PassKind) -> Self {
        // DRIFT only matters to the anisometric upsampling, LONG_FADE to the fade.
        let v = if kind == PassKind::UpsampleAniso {
            self.0 & !Self::LONG_FADE
        } else if kind == PassKind::Fade {
            self.0
        } else {
            self.0 & !(Self::DRIFT | Self::LONG_FADE)
        };
        match kind {
            PassKind::Correct | PassKind::CorrectAniso => Self(v & !Self::GATHER_ONLY),
            PassKind::Gather | PassKind::GatherAniso => Self(v & !Self::CORRECTION_ONLY),
            // The resampling rounds to whole texels where the gather reads the nearest.
            PassKind::Resample | PassKind::Fade => {
                Self(v & !(Self::CORRECTION_ONLY | Self::SEAM_BLEND))
            }
            _ => Self(v & !(Self::CORRECTION_ONLY | Self::GATHER_ONLY)),
        }
    }

    /// The override values of this variant.
    fn constants(self) -> Vec<(&'static str, f64)> {
        let mut c: Vec<(&str, f64)> = Self::FLAGS
            .iter()
            .enumerate()
            .map(|(i, &name)| (name, f64::from((self.0 >> i) & 1)))
            .collect();
        c.push((
            "K",
            f64::from(((self.0 >> Self::K_SHIFT) & Self::K_MASK) + 1),
        ));
        c.push(("DRIFT", f64::from(u16::from(self.0 & Self::DRIFT != 0))));
        c.push((
            "LONG_FADE",
            f64::from(u16::from(self.0 & Self::LONG_FADE != 0)),
        ));
        c
    }
}

/// A compute pipeline built on first use, per [`Variant`]: a synthesis needs 5 of the
/// 12 passes' pipelines, and building one costs ~10 ms on lavapipe (measured: 130 ms for
/// all of them at start-up).
struct LazyPipeline {
    shader: &'static ShaderSource,
    module: std::sync::OnceLock<wgpu::ShaderModule>,
    /// The variants in use (a few of the 2^16 possible): each its own cell, so that
    /// two threads build different variants at once and the same one only once.
    cells: Mutex<std::collections::HashMap<u16, Arc<std::sync::OnceLock<wgpu::ComputePipeline>>>>,
}

impl LazyPipeline {
    /// Variants built so far.
    fn built(&self) -> usize {
        let cells = self.cells.lock().unwrap_or_else(|e| e.into_inner());
        cells.values().filter(|c| c.get().is_some()).count()
    }

    fn new(shader: &'static ShaderSource) -> Self {
        Self {
            shader,
            module: std::sync::OnceLock::new(),
            cells: Default::default(),
        }
    }

    /// The pipeline, built now if needed (inside the caller's error scope).
    fn get(
        &self,
        ctx: &GpuContext,
        layout: &wgpu::PipelineLayout,
        variant: Variant,
    ) -> wgpu::ComputePipeline {
        let cell = self
            .cells
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .entry(variant.0)
            .or_default()
            .clone();
        let pipeline = cell.get_or_init(|| {
            let s = self.shader;
            let module = self.module.get_or_init(|| {
                ctx.device
                    .create_shader_module(wgpu::ShaderModuleDescriptor {
                        label: Some(s.file),
                        source: wgpu::ShaderSource::Wgsl(s.source.into()),
                    })
            });
            let constants = variant.constants();
            ctx.device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(s.name),
                    layout: Some(layout),
                    module,
                    entry_point: Some(s.entry_point),
                    compilation_options: wgpu::PipelineCompilationOptions {
                        constants: &constants,
                        // Only fade.wgsl has workgroup memory, and every invocation writes
                        // its slot before any reads it: zeroing it first costs a pass over
                        // it and a barrier.
                        zero_initialize_workgroup_memory: false,
                    },
                    cache: None,
                })
        });
        pipeline.clone()
    }
}

/// The bind group layout every pass shares and the pipelines of the 12 passes, built on
/// first use. One per device ([`GpuContext`] keeps it), so that every synthesizer on a
/// device shares compiled pipelines, and so that they can be built ahead of time
/// ([`GpuContext::prepare_pipelines`]) while the host does other work.
pub(crate) struct PassPipelines {
    layout: wgpu::BindGroupLayout,
    pipeline_layout: wgpu::PipelineLayout,
    upsample: LazyPipeline,
    jitter: LazyPipeline,
    correct: LazyPipeline,
    gather: LazyPipeline,
    upsample_aniso: LazyPipeline,
    correct_aniso: LazyPipeline,
    gather_aniso: LazyPipeline,
    gather_map: LazyPipeline,
    magnify: LazyPipeline,
    fill: LazyPipeline,
    advect: LazyPipeline,
    drift: LazyPipeline,
    distortion: LazyPipeline,
    resample: LazyPipeline,
    fade: LazyPipeline,
}

impl PassPipelines {
    /// Pipelines (pass and variant) built so far.
    pub(crate) fn built(&self) -> usize {
        [
            &self.upsample,
            &self.jitter,
            &self.correct,
            &self.gather,
            &self.upsample_aniso,
            &self.correct_aniso,
            &self.gather_aniso,
            &self.gather_map,
            &self.magnify,
            &self.fill,
            &self.advect,
            &self.drift,
            &self.distortion,
            &self.resample,
            &self.fade,
        ]
        .iter()
        .map(|p| p.built())
        .sum()
    }
}

impl std::fmt::Debug for PassPipelines {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PassPipelines").finish_non_exhaustive()
    }
}

impl PassPipelines {
    pub(crate) fn new(device: &wgpu::Device) -> Self {
        let mut entries = vec![wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: true,
                min_binding_size: wgpu::BufferSize::new(std::mem::size_of::<PassParams>() as u64),
            },
            count: None,
        }];
        entries.push(storage_entry(1, false));
        entries.push(storage_entry(8, true));
        entries.push(storage_entry(9, true));
        entries.push(storage_entry(10, true));
        for b in [2, 3, 4, 6] {
            entries.push(storage_entry(b, true));
        }
        entries.push(wgpu::BindGroupLayoutEntry {
            binding: 5,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: true,
                min_binding_size: wgpu::BufferSize::new(PROJ_BYTES),
            },
            count: None,
        });
        entries.push(wgpu::BindGroupLayoutEntry {
            binding: 7,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::StorageTexture {
                access: wgpu::StorageTextureAccess::WriteOnly,
                format: OUTPUT_FORMAT,
                view_dimension: wgpu::TextureViewDimension::D2,
            },
            count: None,
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("texsyn passes"),
            entries: &entries,
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("texsyn passes"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        Self {
            layout,
            pipeline_layout,
            upsample: LazyPipeline::new(&shaders::UPSAMPLE),
            jitter: LazyPipeline::new(&shaders::JITTER),
            correct: LazyPipeline::new(&shaders::CORRECT),
            gather: LazyPipeline::new(&shaders::GATHER),
            upsample_aniso: LazyPipeline::new(&shaders::UPSAMPLE_ANISO),
            correct_aniso: LazyPipeline::new(&shaders::CORRECT_ANISO),
            gather_aniso: LazyPipeline::new(&shaders::GATHER_ANISO),
            gather_map: LazyPipeline::new(&shaders::GATHER_MAP),
            magnify: LazyPipeline::new(&shaders::MAGNIFY),
            fill: LazyPipeline::new(&shaders::FILL),
            advect: LazyPipeline::new(&shaders::ADVECT),
            drift: LazyPipeline::new(&shaders::DRIFT),
            distortion: LazyPipeline::new(&shaders::DISTORTION),
            resample: LazyPipeline::new(&shaders::RESAMPLE),
            fade: LazyPipeline::new(&shaders::FADE),
        }
    }

    /// The pipeline of a pass, built now if needed.
    fn get(&self, ctx: &GpuContext, kind: PassKind, variant: Variant) -> wgpu::ComputePipeline {
        let lazy = match kind {
            PassKind::Upsample => &self.upsample,
            PassKind::Jitter => &self.jitter,
            PassKind::Correct => &self.correct,
            PassKind::Gather => &self.gather,
            PassKind::UpsampleAniso => &self.upsample_aniso,
            PassKind::CorrectAniso => &self.correct_aniso,
            PassKind::GatherAniso => &self.gather_aniso,
            PassKind::Fill => &self.fill,
            PassKind::Advect => &self.advect,
            PassKind::Drift => &self.drift,
            PassKind::Distortion => &self.distortion,
            PassKind::Resample => &self.resample,
            PassKind::Fade => &self.fade,
        };
        lazy.get(ctx, &self.pipeline_layout, variant.for_kind(kind))
    }

    /// Builds the pipelines these dispatches use (each once), inside one error scope, on
    /// this thread ([`GpuSynthesizer::prepare`] runs two of these side by side).
    pub(crate) fn prepare_dispatches(
        &self,
        ctx: &GpuContext,
        dispatches: impl IntoIterator<Item = (PassKind, Variant)>,
    ) -> Result<()> {
        let mut todo: Vec<(PassKind, Variant)> = Vec::new();
        for (kind, variant) in dispatches {
            let v = variant.for_kind(kind);
            if !todo.contains(&(kind, v)) {
                todo.push((kind, v));
            }
        }
        ctx.scoped(|| {
            for &(kind, v) in &todo {
                self.get(ctx, kind, v);
            }
        })
    }

    /// Builds these dispatches' pipelines, each correction variant's on a thread of its
    /// own while this one builds the others and then runs `alongside` (host work). The
    /// correction's pipeline takes the longest to build (lavapipe: 21 ms, 49 ms
    /// anisometric, against 10 and 18 ms for all the others).
    pub(crate) fn prepare_split(
        &self,
        ctx: &GpuContext,
        dispatches: impl IntoIterator<Item = (PassKind, Variant)>,
        alongside: impl FnOnce() -> Result<()>,
    ) -> Result<()> {
        let (heavy, light): (Vec<_>, Vec<_>) = dispatches
            .into_iter()
            .partition(|(kind, _)| matches!(kind, PassKind::Correct | PassKind::CorrectAniso));
        // One thread per correction variant: with `SynthParams::sets_every` above 1 a
        // synthesis has two (with and without the similarity sets), and one after the
        // other they took twice as long.
        let mut heavy_variants: Vec<(PassKind, Variant)> = Vec::new();
        for (kind, variant) in heavy {
            let kv = (kind, variant.for_kind(kind));
            if !heavy_variants.contains(&kv) {
                heavy_variants.push(kv);
            }
        }
        std::thread::scope(|scope| {
            let corrections: Vec<_> = heavy_variants
                .iter()
                .map(|&kv| scope.spawn(move || self.prepare_dispatches(ctx, [kv])))
                .collect();
            let mut result = self
                .prepare_dispatches(ctx, light)
                .and_then(|()| alongside());
            for c in corrections {
                let built = c
                    .join()
                    .unwrap_or_else(|_| Err(Error::Gpu("building a pipeline panicked".into())));
                result = result.and(built);
            }
            result
        })
    }

    /// Builds the pipelines a synthesis of `params` from `analysis` uses, running
    /// `alongside(&plan)` meanwhile (no synthesizer needed: see
    /// [`GpuContext::prepare_synthesis`] and [`GpuSynthesizer::prepare`]).
    pub(crate) fn prepare_plan(
        &self,
        ctx: &GpuContext,
        analysis: &Analysis,
        params: &SynthParams,
        alongside: impl FnOnce(&SynthPlan) -> Result<()>,
    ) -> Result<()> {
        let plan = SynthPlan::new(analysis, params)?;
        let schedule = plan.schedule(analysis);
        self.prepare_split(
            ctx,
            schedule
                .iter()
                .map(|d| (d.kind, Variant::of_dispatch(&plan, d))),
            || alongside(&plan),
        )
    }

    /// Builds the pipelines of a plain 2D synthesis (isometric or anisometric).
    pub(crate) fn prepare(&self, ctx: &GpuContext, anisometric: bool) -> Result<()> {
        let kinds = if anisometric {
            [
                PassKind::UpsampleAniso,
                PassKind::Jitter,
                PassKind::CorrectAniso,
                PassKind::GatherAniso,
            ]
        } else {
            [
                PassKind::Upsample,
                PassKind::Jitter,
                PassKind::Correct,
                PassKind::Gather,
            ]
        };
        // The usual variants: a non-tileable exemplar, k = 2, the full distance on the
        // coarse levels (the finest level is not corrected by default). Others are built
        // when first used.
        let usual = PassParams {
            k: 2,
            seam_blend: 1,
            ..Default::default()
        };
        let plain = Variant::of(&usual);
        let full = Variant::of(&PassParams {
            full_distance: 1,
            ..usual
        });
        self.prepare_split(
            ctx,
            kinds.map(|k| {
                let correction = matches!(k, PassKind::Correct | PassKind::CorrectAniso);
                (k, if correction { full } else { plain })
            }),
            || Ok(()),
        )
    }
}

fn storage_entry(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

fn too_large(
    what: &'static str,
    width: u32,
    height: u32,
    limit: String,
    hint: &'static str,
) -> Error {
    Error::TooLarge {
        what,
        width,
        height,
        limit,
        hint,
    }
}

/// A coordinate buffer of `count` entries (every level of a plan, then its flag region:
/// `SynthPlan::coord_buffer_len`).
fn coords_buffer(ctx: &GpuContext, count: u64, label: &str) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: (count * 8).max(16),
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// A storage buffer holding one part of every level's tables, concatenated (the layout
/// the passes index with `et_base` / `off_base`), written straight into a buffer mapped at
/// creation: no concatenated copy on the host. Each copy of fresh memory costs its page
/// faults, which on a CPU device were most of the upload (a 400 px exemplar's 55 MB of
/// tables). Where the device can map storage buffers (a CPU device, see
/// `GpuContext::headless`) the buffer is written in place; wgpu otherwise writes it to a
/// staging buffer and copies, twice the memory touched.
fn levels_buffer(
    ctx: &GpuContext,
    a: &Analysis,
    label: &str,
    part: &dyn Fn(&LevelData) -> &[u8],
) -> Result<wgpu::Buffer> {
    let device = &ctx.device;
    let usage = if device
        .features()
        .contains(wgpu::Features::MAPPABLE_PRIMARY_BUFFERS)
    {
        wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::MAP_WRITE
    } else {
        wgpu::BufferUsages::STORAGE
    };
    let len: usize = a.levels.iter().map(|l| part(l).len()).sum();
    let size = len.max(16).next_multiple_of(4);
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: size as u64,
        usage,
        mapped_at_creation: true,
    });
    {
        let mut view = buffer
            .get_mapped_range_mut(..)
            .map_err(|e| Error::Gpu(format!("uploading the analysis: {e}")))?;
        let mut at = 0;
        for l in &a.levels {
            let b = part(l);
            view.slice(at..at + b.len()).copy_from_slice(b);
            at += b.len();
        }
        // The rest (padding) is zero: mapped-at-creation memory starts zeroed.
    }
    buffer.unmap();
    Ok(buffer)
}

/// Bytes of a buffer holding `data`, never empty (WebGPU rejects 0-sized bindings).
fn padded<T: bytemuck::Pod>(data: &[T]) -> Vec<u8> {
    let mut b = bytemuck::cast_slice(data).to_vec();
    b.resize(b.len().max(16).next_multiple_of(4), 0);
    b
}

impl GpuSynthesizer {
    /// Uploads the analysis (its `qe` tables wait for the first synthesis that reads
    /// them, or for [`Self::prepare`]). Fails with a clear error if the exemplar tables
    /// exceed the device's buffer limits.
    pub fn new(ctx: &GpuContext, analysis: Arc<Analysis>) -> Result<Self> {
        let a = &*analysis;
        a.validate()?;
        check_exemplar_fits(ctx, a.width, a.height, a.k)?;
        let device = &ctx.device;
        ctx.scoped(|| {
            let mut proj: Vec<i32> = Vec::with_capacity(a.levels.len() * 256);
            for l in &a.levels {
                // Per diagonal block j, per column c: rows 0-3 then rows 4-7 (the layout
                // project_diagonal in correct.wgsl reads).
                for j in 0..4 {
                    for c in 0..DIM {
                        for r in 0..DIM {
                            proj.push(l.proj[r][j * DIM + c] as i32);
                        }
                    }
                }
            }
            // `qe` waits for a synthesis that reads it (`qe_for`).
            let et = levels_buffer(ctx, a, "texsyn et", &|l| bytemuck::cast_slice(&l.et))?;
            let offsets = levels_buffer(ctx, a, "texsyn offsets", &|l| {
                bytemuck::cast_slice(&l.offsets)
            })?;
            let init = |label: &str, contents: &[u8]| {
                crate::gpu::buffer_init(
                    device,
                    &wgpu::util::BufferInitDescriptor {
                        label: Some(label),
                        contents,
                        usage: wgpu::BufferUsages::STORAGE,
                    },
                )
            };
            let proj = crate::gpu::buffer_init(
                device,
                &wgpu::util::BufferInitDescriptor {
                    label: Some("texsyn proj"),
                    contents: bytemuck::cast_slice(&proj),
                    usage: wgpu::BufferUsages::UNIFORM,
                },
            );
            let colors = init("texsyn colors", &padded(&a.colors));

            Ok(Self {
                context: ctx.clone(),
                pipelines: ctx.pass_pipelines(),
                no_velocity: init("texsyn no velocity", &[0u8; 16]),
                et,
                qe: Mutex::new(None),
                no_qe: init("texsyn qe (not uploaded)", &[0u8; 16]),
                offsets,
                proj,
                colors,
                analysis: analysis.clone(),
                scratch: Mutex::new(None),
                fine: (0..analysis.levels.len())
                    .map(|_| std::sync::OnceLock::new())
                    .collect(),
                jacobians: Mutex::new(None),
                progress: Mutex::new(None),
            })
        })?
    }

    pub fn analysis(&self) -> &Analysis {
        &self.analysis
    }

    /// The `qe` binding for `schedule`: the uploaded tables (uploaded now if not yet)
    /// when a correction of it uses the projected distance, else whatever is there (a
    /// 16-byte stand-in until the first upload). Called inside the caller's error scope
    /// ([`GpuContext::scoped`]): a buffer the device cannot create is reported there (the
    /// stand-in is bound meanwhile and the upload tried again next time).
    fn qe_for(&self, ctx: &GpuContext, schedule: &[Dispatch]) -> wgpu::Buffer {
        let mut qe = self.qe.lock().unwrap_or_else(|e| e.into_inner());
        let needed = schedule.iter().any(|d| {
            matches!(d.kind, PassKind::Correct | PassKind::CorrectAniso)
                && d.params.full_distance == 0
        });
        if needed && qe.is_none() {
            *qe = levels_buffer(ctx, &self.analysis, "texsyn qe", &|l| {
                bytemuck::cast_slice(&l.qe)
            })
            .ok();
        }
        qe.clone().unwrap_or_else(|| self.no_qe.clone())
    }

    /// A level's quarter-pixel tables, built and uploaded now if not yet (inside the
    /// caller's error scope); `None` if it has none or they exceed the device's limits.
    /// [`crate::gpu::advect::Advection::new`] calls it so that the first frame does not
    /// pay for them.
    /// The quarter-pixel tables `schedule`'s corrections read (built now; `None` where
    /// none do or they do not fit), and which dispatches read them: those that read
    /// quarter pixels at the schedule's most corrected level
    /// ([`crate::passes::plan::quarter_tables_level`]), read from its supersampled tables
    /// instead of `et` and `qe` (a variant of their own).
    fn fine_reads<'a>(
        &'a self,
        ctx: &GpuContext,
        schedule: &[Dispatch],
    ) -> (Option<&'a FineTables>, impl Fn(&Dispatch) -> bool + 'a) {
        let level = crate::passes::plan::quarter_tables_level(schedule, &self.analysis);
        let fine = level.and_then(|l| self.fine_tables(ctx, l));
        let et_base = fine.map(|f| f.et_base);
        let reads = move |d: &Dispatch| {
            Some(d.level) == level
                && Some(d.params.et_base) == et_base
                && d.reads_quarter_tables(&self.analysis)
        };
        (fine, reads)
    }

    pub(crate) fn fine_tables(&self, ctx: &GpuContext, level: usize) -> Option<&FineTables> {
        self.fine
            .get(level)?
            .get_or_init(|| FineTables::build(ctx, &self.analysis, level))
            .as_ref()
    }

    /// Checks an output size against the device limits before any work is recorded.
    /// Refuses a context other than the one this synthesizer was made on (or a clone of
    /// it): its buffers and pipelines would be bound on that context's device (a
    /// validation error that spoils the device's cached pipelines, or a panic in wgpu
    /// across instances). Two contexts made with [`GpuContext::from_device`] from the
    /// same device count as different: clone the first instead.
    /// The plan this synthesizer runs for `params` on `ctx`: [`SynthPlan::new`], except
    /// that a tileable output made on a torus ([`crate::passes::plan::Torus`]) whose
    /// pyramid and Jacobians do not fit the device keeps the output's own periods
    /// (the plan [`SynthPlan::with_torus`] makes without the torus, whose sides that are
    /// not multiples of 4 show a faint seam at the wrap) where that one fits.
    pub fn plan_for(&self, ctx: &GpuContext, params: &SynthParams) -> Result<SynthPlan> {
        let plan = SynthPlan::new(&self.analysis, params)?;
        if plan.torus.is_some() && self.check_output(ctx, &plan).is_err() {
            let exact = SynthPlan::with_torus(&self.analysis, params, false)?;
            if self.check_output(ctx, &exact).is_ok() {
                return Ok(exact);
            }
        }
        Ok(plan)
    }

    pub fn check_context(&self, ctx: &GpuContext) -> Result<()> {
        if !self.context.same_as(ctx) {
            return Err(Error::InvalidParameter(
                "this synthesizer was made on another GpuContext than the one given; use \
                 the context it was created with, or a clone of it (a second \
                 GpuContext::from_device on the same device counts as another)"
                    .into(),
            ));
        }
        Ok(())
    }

    pub(crate) fn check_output(&self, ctx: &GpuContext, plan: &SynthPlan) -> Result<()> {
        self.check_context(ctx)?;
        let limits = ctx.limits();
        let p = &plan.params;
        let max_dim = limits.max_texture_dimension_2d;
        if p.width > max_dim || p.height > max_dim {
            return Err(too_large(
                "output",
                p.width,
                p.height,
                format!("at most {max_dim} pixels a side"),
                "synthesize it in windows (SynthParams::origin) and assemble them",
            ));
        }
        // Coordinates (8 bytes per pixel of every level, then the flag region), or the
        // Jacobians (16 bytes per pixel of every level).
        let bytes = if p.anisometric() {
            plan.coord_count * 16
        } else {
            plan.coord_buffer_len() * 8
        };
        let max = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        if bytes > max {
            return Err(too_large(
                "output",
                p.width,
                p.height,
                format!(
                    "its coordinate pyramid (or Jacobian field) needs {} in one buffer, the device allows {}",
                    fmt_bytes(bytes),
                    fmt_bytes(max)
                ),
                "synthesize it in windows (SynthParams::origin) and assemble them",
            ));
        }
        let groups = limits.max_compute_workgroups_per_dimension as u64 * 8;
        let fin = plan.levels.last().unwrap();
        if fin.size[0] as u64 > groups || fin.size[1] as u64 > groups {
            return Err(too_large(
                "output",
                p.width,
                p.height,
                format!("at most {groups} pixels a side per dispatch"),
                "synthesize it in windows",
            ));
        }
        Ok(())
    }

    fn scratch_for(
        &self,
        ctx: &GpuContext,
        plan: &SynthPlan,
    ) -> std::sync::MutexGuard<'_, Option<Scratch>> {
        let mut guard = self.scratch.lock().unwrap_or_else(|e| e.into_inner());
        let len = plan.coord_buffer_len();
        let fits = guard.as_ref().is_some_and(|s| s.entries >= len);
        if !fits {
            let coords = coords_buffer(ctx, len, "texsyn coords");
            *guard = Some(Scratch {
                entries: len,
                coords,
            });
        }
        guard
    }

    /// Reports the progress of long syntheses: while set, [`Self::synthesize`],
    /// [`Self::synthesize_to_host`], [`Self::synthesize_with_maps`] and the magnified
    /// variants submit each level on its own, wait for it and call `f(levels done,
    /// levels in all)`. That costs one GPU round trip per level (a few milliseconds on
    /// lavapipe, but idle time on a real GPU), so set it for outputs that take seconds,
    /// and `None` to go back to one submission. [`Self::encode`] never splits (it does
    /// not submit). Results are the same bytes either way.
    ///
    /// The callback may call into this synthesizer (set another callback, or
    /// synthesize): nothing is locked while it runs but the callback itself, and a
    /// synthesis that finds it running (a synthesis called from inside it, or one on
    /// another thread reporting at that moment) skips that report.
    pub fn set_progress(&self, f: Option<LevelProgress>) {
        *self.progress.lock().unwrap_or_else(|e| e.into_inner()) =
            f.map(|f| Arc::new(Mutex::new(f)));
    }

    /// [`Self::record`] for the calls that submit the encoder themselves: with a
    /// progress callback set, every level but the last is submitted and waited for
    /// here (the caller's encoder then holds the last level, the map passes and
    /// whatever it adds).
    #[allow(clippy::too_many_arguments)]
    fn record_reporting(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        plan: &SynthPlan,
        schedule: &[Dispatch],
        target: &wgpu::TextureView,
        maps: &[MapTarget<'_>],
    ) -> Result<wgpu::Buffer> {
        let hook = self
            .progress
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone();
        let Some(report) = hook else {
            return ctx.scoped(|| self.record(ctx, encoder, plan, schedule, target, false, maps));
        };
        // Every level but the last is submitted and waited for here. Between those
        // submissions another thread may submit work of its own (an `encode` on this
        // synthesizer, say): the coordinates live in a buffer of this call's, not in the
        // shared scratch buffer.
        let coords = ctx.scoped(|| coords_buffer(ctx, plan.coord_buffer_len(), "texsyn coords"))?;
        let state = Some((&coords, &self.no_velocity));
        let levels: Vec<&[Dispatch]> = schedule.chunk_by(|a, b| a.level == b.level).collect();
        let (last, earlier) = match levels.split_last() {
            Some((last, earlier)) => (*last, earlier),
            None => (&[][..], &[][..]),
        };
        for level in earlier {
            ctx.scoped(|| {
                self.record_with(ctx, encoder, plan, level, target, false, &[], state);
                let done = std::mem::replace(
                    encoder,
                    ctx.device.create_command_encoder(&Default::default()),
                );
                ctx.queue.submit([done.finish()]);
            })?;
            wait(ctx)?;
            // Busy: called from inside itself, or reporting another synthesis.
            if let Ok(mut f) = report.try_lock() {
                f(level[0].level as u32 + 1, plan.levels.len() as u32);
            }
        }
        ctx.scoped(|| self.record_with(ctx, encoder, plan, last, target, false, maps, state))
    }

    /// Records the first `count` dispatches of the synthesis into `encoder`, writing
    /// colours to `target`. Returns the plan and the coordinate buffer.
    #[allow(clippy::too_many_arguments)]
    fn record(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        plan: &SynthPlan,
        schedule: &[Dispatch],
        target: &wgpu::TextureView,
        clear: bool,
        maps: &[MapTarget<'_>],
    ) -> wgpu::Buffer {
        self.record_with(ctx, encoder, plan, schedule, target, clear, maps, None)
    }

    /// [`Self::record`] on the caller's coordinate and velocity buffers (advection keeps
    /// its coordinates between frames) instead of the shared scratch buffer.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn record_with(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        plan: &SynthPlan,
        schedule: &[Dispatch],
        target: &wgpu::TextureView,
        clear: bool,
        maps: &[MapTarget<'_>],
        state: Option<(&wgpu::Buffer, &wgpu::Buffer)>,
    ) -> wgpu::Buffer {
        let guard;
        let coords_buffer = match state {
            Some((coords, _)) => coords,
            None => {
                guard = self.scratch_for(ctx, plan);
                &guard.as_ref().unwrap().coords
            }
        };
        let velocity_buffer = state.map_or(&self.no_velocity, |(_, v)| v);
        if clear {
            encoder.clear_buffer(coords_buffer, 0, None);
        }
        // Map gathers run after the whole schedule with the gather's parameters.
        let gather_params = schedule.last().map(|d| d.params).unwrap_or_default();
        let entries: Vec<PassParams> = schedule
            .iter()
            .map(|d| d.params)
            .chain(maps.iter().map(|m| PassParams {
                map_kind: m.map_kind,
                magnify: m.magnify.max(1),
                hi_size: m.hi_size,
                ..gather_params
            }))
            .collect();
        let mut bytes = vec![0u8; entries.len().max(1) * PARAMS_STRIDE as usize];
        for (i, e) in entries.iter().enumerate() {
            let o = i * PARAMS_STRIDE as usize;
            bytes[o..o + std::mem::size_of::<PassParams>()].copy_from_slice(bytemuck::bytes_of(e));
        }
        let (jac, surface) = self.jacobian_buffers(ctx, plan);
        // Parameters live in their own buffer per call: a later call must not overwrite
        // them before this one's commands have run.
        let params = crate::gpu::buffer_init(
            &ctx.device,
            &wgpu::util::BufferInitDescriptor {
                label: Some("texsyn params"),
                contents: &bytes,
                usage: wgpu::BufferUsages::UNIFORM,
            },
        );
        // Corrections that read quarter pixels at the schedule's most corrected level
        // (quarter_tables_level) read them from its supersampled tables when those fit
        // (a second bind group: the tables replace `et` and `qe`, so no binding is added
        // to the layout).
        let (fine, reads_fine) = self.fine_reads(ctx, schedule);
        let make_bind_group =
            |colors: &wgpu::Buffer,
             target: &wgpu::TextureView,
             (et, qe): (&wgpu::Buffer, &wgpu::Buffer)| {
                ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("texsyn passes"),
                    layout: &self.pipelines.layout,
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 0,
                            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                                buffer: &params,
                                offset: 0,
                                size: wgpu::BufferSize::new(
                                    std::mem::size_of::<PassParams>() as u64
                                ),
                            }),
                        },
                        wgpu::BindGroupEntry {
                            binding: 1,
                            resource: coords_buffer.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 2,
                            resource: et.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 3,
                            resource: qe.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 4,
                            resource: self.offsets.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 5,
                            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                                buffer: &self.proj,
                                offset: 0,
                                size: wgpu::BufferSize::new(PROJ_BYTES),
                            }),
                        },
                        wgpu::BindGroupEntry {
                            binding: 6,
                            resource: colors.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 7,
                            resource: wgpu::BindingResource::TextureView(target),
                        },
                        wgpu::BindGroupEntry {
                            binding: 8,
                            resource: jac.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 9,
                            resource: surface.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 10,
                            resource: velocity_buffer.as_entire_binding(),
                        },
                    ],
                })
            };
        let qe = self.qe_for(ctx, schedule);
        let tables = (&self.et, &qe);
        let bind_group = make_bind_group(&self.colors, target, tables);
        let fine_group = fine.map(|f| (f, make_bind_group(&self.colors, target, (&f.et, &f.qe))));
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("texsyn synthesis"),
                timestamp_writes: None,
            });
            for (i, d) in schedule.iter().enumerate() {
                let mut variant = Variant::of_dispatch(plan, d);
                let mut group = &bind_group;
                if let Some((_, g)) = &fine_group {
                    if reads_fine(d) {
                        variant = variant.with_fine_tables();
                        group = g;
                    }
                }
                let pipeline = self.pipelines.get(ctx, d.kind, variant);
                let [tx, ty] = d.threads();
                if tx == 0 || ty == 0 {
                    continue;
                }
                pass.set_pipeline(&pipeline);
                pass.set_bind_group(
                    0,
                    group,
                    &[
                        (i as u64 * PARAMS_STRIDE) as u32,
                        d.level as u32 * PROJ_BYTES as u32,
                    ],
                );
                pass.dispatch_workgroups(tx.div_ceil(8), ty.div_ceil(8), 1);
            }
            for (m, map) in maps.iter().enumerate() {
                let group = make_bind_group(map.colors, map.view, tables);
                let level = plan.levels.len() - 1;
                let variant = Variant::of(&gather_params).for_kind(PassKind::Gather);
                let lazy = if map.magnify > 1 {
                    &self.pipelines.magnify
                } else {
                    &self.pipelines.gather_map
                };
                pass.set_pipeline(&lazy.get(ctx, &self.pipelines.pipeline_layout, variant));
                pass.set_bind_group(
                    0,
                    &group,
                    &[
                        ((schedule.len() + m) as u64 * PARAMS_STRIDE) as u32,
                        level as u32 * PROJ_BYTES as u32,
                    ],
                );
                let f = map.magnify.max(1);
                let [tx, ty] = [plan.params.width * f, plan.params.height * f];
                pass.dispatch_workgroups(tx.div_ceil(8), ty.div_ceil(8), 1);
            }
        }
        coords_buffer.clone()
    }

    /// The Jacobian field rasterized on the host for this plan's regions (a placeholder
    /// for isometric synthesis) and the atlas surface buffer, from the cache when the
    /// last plan had the same field and regions.
    fn jacobian_buffers(&self, ctx: &GpuContext, plan: &SynthPlan) -> (wgpu::Buffer, wgpu::Buffer) {
        let key: JacobianKey = (
            plan.params.field.clone(),
            plan.levels
                .iter()
                .map(|l| (l.origin, l.size))
                // A torus's output region (its Jacobians are the field's, the levels'
                // scaled).
                .chain(plan.torus.map(|t| ([-1, -1], t.output)))
                .collect(),
            plan.params
                .surface
                .as_ref()
                .map(|d| Arc::as_ptr(d) as usize),
        );
        let mut cached = self.jacobians.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((k, jac, surface)) = cached.as_ref() {
            if *k == key {
                return (jac.clone(), surface.clone());
            }
        }
        let init = |label: &str, words: &[u8]| {
            crate::gpu::buffer_init(
                &ctx.device,
                &wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents: if words.is_empty() { &[0u8; 16] } else { words },
                    usage: wgpu::BufferUsages::STORAGE,
                },
            )
        };
        let jac = init("texsyn jacobians", bytemuck::cast_slice(&plan.jacobians()));
        let surface = init(
            "texsyn atlas surface",
            bytemuck::cast_slice(&plan.surface_words().0),
        );
        *cached = Some((key, jac.clone(), surface.clone()));
        (jac, surface)
    }

    pub(crate) fn output_texture(
        &self,
        ctx: &GpuContext,
        width: u32,
        height: u32,
    ) -> wgpu::Texture {
        ctx.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("texsyn output"),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: OUTPUT_FORMAT,
            usage: wgpu::TextureUsages::STORAGE_BINDING
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
            view_formats: if ctx.supports_view_formats() {
                &[OUTPUT_FORMAT_SRGB]
            } else {
                &[]
            },
        })
    }

    /// Records a whole synthesis into the caller's encoder; the returned texture holds
    /// the colours once the caller submits the encoder. Nothing is read back.
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        params: &SynthParams,
    ) -> Result<GpuSynthesis> {
        self.encode_inner(ctx, encoder, params, false)
    }

    /// [`Self::encode`]; with `submitting` (the caller submits right after), levels may
    /// be submitted early for [`Self::set_progress`].
    fn encode_inner(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        params: &SynthParams,
        submitting: bool,
    ) -> Result<GpuSynthesis> {
        let plan = self.plan_for(ctx, params)?;
        self.check_output(ctx, &plan)?;
        let schedule = plan.schedule(&self.analysis);
        let texture = ctx.scoped(|| self.output_texture(ctx, params.width, params.height))?;
        let view = texture.create_view(&Default::default());
        if submitting {
            self.record_reporting(ctx, encoder, &plan, &schedule, &view, &[])?;
        } else {
            ctx.scoped(|| self.record(ctx, encoder, &plan, &schedule, &view, false, &[]))?;
        }
        Ok(GpuSynthesis {
            texture,
            width: params.width,
            height: params.height,
        })
    }

    /// Builds the pipelines a synthesis of `params` uses now rather than while its first
    /// submission is recorded (see [`GpuContext::prepare_pipelines`]), e.g. to time them
    /// apart or to build them while the application does other work. An anisometric
    /// plan's Jacobian field is rasterized and uploaded too (kept for the synthesis that
    /// follows with the same field and regions), and so is the `qe` table when its
    /// corrections read it. Optional; the synthesis is the same either way.
    pub fn prepare(&self, ctx: &GpuContext, params: &SynthParams) -> Result<()> {
        self.check_context(ctx)?;
        // The Jacobian field (20-30 ms at 512x512 on the host) alongside, which the
        // synthesis then finds in its cache, and beside it the `qe` table if a
        // correction reads it (anisometric synthesis: 15-25 ms for a 400 px exemplar).
        self.pipelines
            .prepare_plan(ctx, &self.analysis, params, |plan| {
                std::thread::scope(|s| {
                    let qe = s.spawn(|| {
                        ctx.scoped(|| {
                            self.qe_for(ctx, &plan.schedule(&self.analysis));
                        })
                    });
                    let jacobians = ctx.scoped(|| {
                        self.jacobian_buffers(ctx, plan);
                    });
                    let qe = qe
                        .join()
                        .unwrap_or_else(|_| Err(Error::Gpu("uploading qe panicked".into())));
                    jacobians.and(qe)
                })
            })
    }

    /// Builds the pipelines `schedules` (each a whole submission's schedule of `plan`,
    /// which decides the dispatches reading quarter-pixel tables) dispatch now, the
    /// corrections each on a thread of its own, rather than while a submission using
    /// them is recorded ([`crate::gpu::advect::Advection`] prepares its frames' with it).
    pub(crate) fn prepare_schedules(
        &self,
        ctx: &GpuContext,
        plan: &SynthPlan,
        schedules: &[Vec<Dispatch>],
    ) -> Result<()> {
        let mut dispatches = Vec::new();
        for schedule in schedules {
            let (_, reads_fine) = self.fine_reads(ctx, schedule);
            dispatches.extend(schedule.iter().map(|d| {
                let variant = Variant::of_dispatch(plan, d);
                let variant = if reads_fine(d) {
                    variant.with_fine_tables()
                } else {
                    variant
                };
                (d.kind, variant)
            }));
        }
        dispatches.sort_unstable_by_key(|&(kind, v)| (kind as u32, v.0));
        dispatches.dedup();
        self.pipelines.prepare_split(ctx, dispatches, || Ok(()))
    }

    /// Synthesizes and submits; returns when the GPU has finished.
    pub fn synthesize(&self, ctx: &GpuContext, params: &SynthParams) -> Result<GpuSynthesis> {
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        let out = self.encode_inner(ctx, &mut encoder, params, true)?;
        ctx.scoped(|| ctx.queue.submit([encoder.finish()]))?;
        wait(ctx)?;
        Ok(out)
    }

    /// Synthesizes and reads colours and coordinates back to the host.
    pub fn synthesize_to_host(&self, ctx: &GpuContext, params: &SynthParams) -> Result<Synthesis> {
        self.synthesize_with_maps(ctx, params, &[]).map(|(s, _)| s)
    }

    /// Synthesizes, resynthesizes extra exemplar-aligned maps (material sets) through
    /// the same coordinates, and reads everything back, in one submission. Returns the
    /// synthesis and each map's RGBA8 pixels over the output window.
    pub fn synthesize_with_maps(
        &self,
        ctx: &GpuContext,
        params: &SynthParams,
        maps: &[ExtraMap],
    ) -> Result<(Synthesis, Vec<Vec<[u8; 4]>>)> {
        let (s, _, m) = self.synthesize_maps_inner(ctx, params, maps, None, None)?;
        Ok((s, m))
    }

    /// Whether `params` can be synthesized in one piece on this device (its coordinate
    /// pyramid, Jacobians and dispatches within the device's limits).
    pub fn fits(&self, ctx: &GpuContext, params: &SynthParams) -> bool {
        self.plan_for(ctx, params)
            .is_ok_and(|plan| self.check_output(ctx, &plan).is_ok())
    }

    /// [`Self::synthesize_with_maps`] for outputs of any size: the output is synthesized
    /// in square windows (the largest power of two up to 2048 pixels a side that the
    /// device takes in one piece), read back and assembled on the host. Windows of the
    /// infinite texture agree wherever they overlap, so the result is the same, byte for
    /// byte, as one synthesis of the whole output on a device large enough for it.
    /// `progress(done, total)` is called after each window. Not for periodic
    /// (`tileable_output`) or surface outputs, which are one piece by nature: those are
    /// [`Error::InvalidParameter`].
    pub fn synthesize_in_windows(
        &self,
        ctx: &GpuContext,
        params: &SynthParams,
        maps: &[ExtraMap],
        mut progress: impl FnMut(usize, usize),
    ) -> Result<(Synthesis, Vec<Vec<[u8; 4]>>)> {
        if params.tileable_output || params.surface.is_some() {
            return Err(Error::InvalidParameter(
                "a periodic or surface output is one synthesis; it cannot be split into windows"
                    .into(),
            ));
        }
        let (w, h) = (params.width, params.height);
        // Windows must fit together: each is exact (see `synthesize_in_windows_sized`).
        let window = |side: u32| SynthParams {
            width: side.min(w),
            height: side.min(h),
            standalone: false,
            ..params.clone()
        };
        let mut side = 2048u32;
        while side > 16 && !self.fits(ctx, &window(side)) {
            side /= 2;
        }
        self.synthesize_in_windows_sized(ctx, params, maps, side, &mut progress)
    }

    /// [`Self::synthesize_in_windows`] with windows `side` pixels a side (each must fit
    /// the device; see [`Self::fits`]).
    pub fn synthesize_in_windows_sized(
        &self,
        ctx: &GpuContext,
        params: &SynthParams,
        maps: &[ExtraMap],
        side: u32,
        progress: &mut dyn FnMut(usize, usize),
    ) -> Result<(Synthesis, Vec<Vec<[u8; 4]>>)> {
        if params.width == 0 || params.height == 0 || side == 0 {
            return Err(Error::InvalidParameter(format!(
                "output {}x{} in windows of {side}: sizes must be at least 1",
                params.width, params.height
            )));
        }
        let (w, h) = (params.width as usize, params.height as usize);
        let pixels = w
            .checked_mul(h)
            .filter(|&n| n <= MAX_WINDOWED_PIXELS)
            .ok_or_else(|| {
                Error::InvalidParameter(format!(
                    "output {w}x{h}: at most {} Mpixel are assembled in memory; synthesize \
                     windows of it (SynthParams::origin) and store them separately",
                    MAX_WINDOWED_PIXELS >> 20
                ))
            })?;
        let side = side.max(1) as usize;
        let (nx, ny) = (w.div_ceil(side), h.div_ceil(side));
        let mut out = Synthesis {
            width: params.width,
            height: params.height,
            coords: vec![[0, 0]; pixels],
            colors: vec![[0; 4]; pixels],
            coord_frac: 0,
        };
        let mut out_maps = vec![vec![[0u8; 4]; pixels]; maps.len()];
        for ty in 0..ny {
            for tx in 0..nx {
                let (x0, y0) = (tx * side, ty * side);
                let (tw, th) = (side.min(w - x0), side.min(h - y0));
                let origin = [
                    params.origin[0].checked_add(x0 as i32),
                    params.origin[1].checked_add(y0 as i32),
                ];
                let [Some(ox), Some(oy)] = origin else {
                    return Err(Error::InvalidParameter(
                        "the output reaches past the supported texture area".into(),
                    ));
                };
                // Exact windows, whatever `params.standalone` says: a standalone
                // piece would not meet its neighbours.
                let p = SynthParams {
                    width: tw as u32,
                    height: th as u32,
                    origin: [ox, oy],
                    standalone: false,
                    ..params.clone()
                };
                let (s, m) = self.synthesize_with_maps(ctx, &p, maps)?;
                out.coord_frac = s.coord_frac;
                for y in 0..th {
                    let dst = (y0 + y) * w + x0;
                    out.coords[dst..dst + tw].copy_from_slice(&s.coords[y * tw..][..tw]);
                    out.colors[dst..dst + tw].copy_from_slice(&s.colors[y * tw..][..tw]);
                    for (o, src) in out_maps.iter_mut().zip(&m) {
                        o[dst..dst + tw].copy_from_slice(&src[y * tw..][..tw]);
                    }
                }
                progress(ty * nx + tx + 1, nx * ny);
            }
        }
        Ok((out, out_maps))
    }

    /// [`Self::synthesize_magnified`] with material sets, read back to the host in one
    /// submission: the colours and every extra map rendered `factor` times larger from
    /// their high-resolution versions (each `hi_width` x `hi_height`, `factor` times the
    /// analysed exemplar; normal maps rotate with the field as in
    /// [`Self::synthesize_with_maps`]), and the synthesis itself (coordinates and
    /// colours at the synthesized resolution).
    #[allow(clippy::too_many_arguments)]
    pub fn synthesize_magnified_with_maps(
        &self,
        ctx: &GpuContext,
        params: &SynthParams,
        hi: &[[u8; 4]],
        hi_width: u32,
        hi_height: u32,
        factor: u32,
        maps: &[ExtraMap],
    ) -> Result<MagnifiedSynthesis> {
        self.check_magnify(ctx, params, (hi, hi_width, hi_height), factor)?;
        let (synthesis, colors, maps) = self.synthesize_maps_inner(
            ctx,
            params,
            maps,
            Some((hi, hi_width, hi_height, factor)),
            None,
        )?;
        Ok(MagnifiedSynthesis {
            width: params.width * factor,
            height: params.height * factor,
            factor,
            colors: colors.unwrap_or_default(),
            maps,
            synthesis,
        })
    }

    /// Checks a magnification request (factor, high-resolution size, magnified output
    /// size against the device).
    fn check_magnify(
        &self,
        ctx: &GpuContext,
        params: &SynthParams,
        (hi, hi_width, hi_height): (&[[u8; 4]], u32, u32),
        factor: u32,
    ) -> Result<()> {
        let a = &self.analysis;
        if ![2, 4, 8].contains(&factor) {
            return Err(Error::InvalidParameter(format!(
                "magnification {factor}: use 2, 4 or 8"
            )));
        }
        if (hi_width, hi_height) != (a.width * factor, a.height * factor)
            || hi.len() != hi_width as usize * hi_height as usize
        {
            return Err(Error::InvalidParameter(format!(
                "the high-resolution exemplar is {hi_width}x{hi_height} ({} pixels given); \
                 magnifying {factor}x needs {}x{}",
                hi.len(),
                a.width * factor,
                a.height * factor
            )));
        }
        let max_dim = ctx.limits().max_texture_dimension_2d;
        let (w, h) = (
            params.width.saturating_mul(factor),
            params.height.saturating_mul(factor),
        );
        if w > max_dim || h > max_dim {
            return Err(too_large(
                "magnified output",
                w,
                h,
                format!("at most {max_dim} pixels a side"),
                "magnify less, or synthesize smaller windows and assemble them",
            ));
        }
        Ok(())
    }

    /// Shared by the map syntheses: with `magnify`, the colours (from `hi`) and the maps
    /// (high-resolution, `hi`'s size) are rendered magnified and the magnified colours
    /// are returned too.
    #[allow(clippy::type_complexity)]
    fn synthesize_maps_inner(
        &self,
        ctx: &GpuContext,
        params: &SynthParams,
        maps: &[ExtraMap],
        magnify: Option<(&[[u8; 4]], u32, u32, u32)>,
        resume: Option<(&wgpu::Buffer, usize)>,
    ) -> Result<(Synthesis, Option<Vec<[u8; 4]>>, Vec<Vec<[u8; 4]>>)> {
        let a = &self.analysis;
        let (map_w, map_h, f) = match magnify {
            Some((_, hw, hh, f)) => (hw, hh, f),
            None => (a.width, a.height, 1),
        };
        for (i, m) in maps.iter().enumerate() {
            if m.pixels.len() != map_w as usize * map_h as usize {
                return Err(Error::InvalidParameter(format!(
                    "extra map {} has {} pixels; it must have the {}exemplar's size {map_w}x{map_h}",
                    i + 1,
                    m.pixels.len(),
                    if f > 1 { "high-resolution " } else { "" },
                )));
            }
        }
        let plan = self.plan_for(ctx, params)?;
        self.check_output(ctx, &plan)?;
        let schedule = plan.schedule(&self.analysis);
        let (w, h) = (params.width, params.height);
        let (bw, bh) = (w.saturating_mul(f), h.saturating_mul(f));
        // Everything comes back in one read-back buffer: check it before any work.
        {
            let pitch = |w: u32| (w as u64 * 4).next_multiple_of(256);
            let (_, out_row, out_offset) = plan.output_region();
            let fin = (out_offset[1] + h) as u64 * out_row as u64;
            let count = maps.len() as u64 + magnify.is_some() as u64;
            let need = (pitch(w) * h as u64 + fin * 8).next_multiple_of(256)
                + pitch(bw) * bh as u64 * count;
            let max = ctx.limits().max_buffer_size;
            if need > max {
                return Err(too_large(
                    "output",
                    w,
                    h,
                    format!(
                        "with {count} map(s) its read-back needs {} in one buffer, the device allows {}",
                        fmt_bytes(need),
                        fmt_bytes(max)
                    ),
                    "resynthesize fewer maps at once, or smaller windows (SynthParams::origin)",
                ));
            }
        }
        let texture = ctx.scoped(|| self.output_texture(ctx, w, h))?;
        let view = texture.create_view(&Default::default());
        // Sources of the map passes: the high-resolution colours first when magnifying.
        let sources: Vec<(&[[u8; 4]], u32)> = magnify
            .map(|(hi, ..)| (hi, 0))
            .into_iter()
            .chain(maps.iter().map(|m| (&m.pixels[..], m.map_kind())))
            .collect();
        let (map_buffers, map_textures) = ctx.scoped(|| {
            let buffers: Vec<wgpu::Buffer> = sources
                .iter()
                .map(|(pixels, _)| {
                    crate::gpu::buffer_init(
                        &ctx.device,
                        &wgpu::util::BufferInitDescriptor {
                            label: Some("texsyn extra map"),
                            contents: bytemuck::cast_slice(pixels),
                            usage: wgpu::BufferUsages::STORAGE,
                        },
                    )
                })
                .collect::<Vec<_>>();
            let textures: Vec<wgpu::Texture> = sources
                .iter()
                .map(|_| self.output_texture(ctx, bw, bh))
                .collect();
            (buffers, textures)
        })?;
        let map_views: Vec<wgpu::TextureView> = map_textures
            .iter()
            .map(|t| t.create_view(&Default::default()))
            .collect();
        let targets: Vec<MapTarget> = sources
            .iter()
            .enumerate()
            .map(|(i, (_, map_kind))| MapTarget {
                colors: &map_buffers[i],
                view: &map_views[i],
                map_kind: *map_kind,
                magnify: f,
                hi_size: if f > 1 {
                    [map_w as i32, map_h as i32]
                } else {
                    [0, 0]
                },
            })
            .collect();
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        let coords = match resume {
            // The rest of a schedule whose first dispatches already ran on `coords`.
            Some((coords, start)) => ctx.scoped(|| {
                self.record_with(
                    ctx,
                    &mut encoder,
                    &plan,
                    &schedule[start.min(schedule.len())..],
                    &view,
                    false,
                    &targets,
                    Some((coords, &self.no_velocity)),
                );
                coords.clone()
            })?,
            None => self.record_reporting(ctx, &mut encoder, &plan, &schedule, &view, &targets)?,
        };
        // The output's coordinates: the finest level's region, or a torus's resampled
        // output (`SynthPlan::output_region`), whole rows from the window's first.
        let (out_base, out_row, out_offset) = plan.output_region();
        let fin_bytes = (out_offset[1] + h) as u64 * out_row as u64 * 8;
        let pitch =
            |w: u32| (w as u64 * 4).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT as u64);
        let (row, big_row) = (pitch(w), pitch(bw));
        let image_bytes = row * h as u64;
        let big_bytes = big_row * bh as u64;
        let copy_image = |encoder: &mut wgpu::CommandEncoder,
                          t: &wgpu::Texture,
                          rb: &wgpu::Buffer,
                          offset: u64,
                          (w, h, row): (u32, u32, u64)| {
            encoder.copy_texture_to_buffer(
                wgpu::TexelCopyTextureInfo {
                    texture: t,
                    mip_level: 0,
                    origin: wgpu::Origin3d::ZERO,
                    aspect: wgpu::TextureAspect::All,
                },
                wgpu::TexelCopyBufferInfo {
                    buffer: rb,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset,
                        bytes_per_row: Some(row as u32),
                        rows_per_image: Some(h),
                    },
                },
                wgpu::Extent3d {
                    width: w,
                    height: h,
                    depth_or_array_layers: 1,
                },
            );
        };
        // Layout: colour rows, the finest level's coordinates, then each map's rows.
        let maps_offset = (image_bytes + fin_bytes).next_multiple_of(256);
        let readback = ctx.scoped(|| {
            let rb = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("texsyn readback"),
                size: maps_offset + big_bytes * sources.len() as u64,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            copy_image(&mut encoder, &texture, &rb, 0, (w, h, row));
            encoder.copy_buffer_to_buffer(
                &coords,
                out_base as u64 * 8,
                &rb,
                image_bytes,
                fin_bytes,
            );
            for (i, t) in map_textures.iter().enumerate() {
                copy_image(
                    &mut encoder,
                    t,
                    &rb,
                    maps_offset + big_bytes * i as u64,
                    (bw, bh, big_row),
                );
            }
            ctx.queue.submit([encoder.finish()]);
            rb
        })?;
        let bytes = read_buffer(ctx, &readback)?;
        let rows = |offset: usize, w: u32, h: u32, row: u64| {
            let mut out = Vec::with_capacity((w * h) as usize);
            for y in 0..h as usize {
                let r =
                    &bytes[offset + y * row as usize..offset + y * row as usize + w as usize * 4];
                out.extend(r.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]));
            }
            out
        };
        let colors = rows(0, w, h, row);
        let mut map_pixels: Vec<Vec<[u8; 4]>> = (0..sources.len())
            .map(|i| {
                rows(
                    (maps_offset + big_bytes * i as u64) as usize,
                    bw,
                    bh,
                    big_row,
                )
            })
            .collect();
        let big_colors = magnify.map(|_| map_pixels.remove(0));
        let level_coords: &[[i32; 2]] =
            bytemuck::cast_slice(&bytes[image_bytes as usize..(image_bytes + fin_bytes) as usize]);
        let mut window = Vec::with_capacity((w * h) as usize);
        for y in 0..h {
            let start = ((y + out_offset[1]) * out_row + out_offset[0]) as usize;
            window.extend_from_slice(&level_coords[start..start + w as usize]);
        }
        Ok((
            Synthesis {
                width: w,
                height: h,
                coords: window,
                colors,
                coord_frac: if plan.params.anisometric() {
                    crate::passes::common::COORD_FRAC
                } else {
                    0
                },
            },
            big_colors,
            map_pixels,
        ))
    }

    /// Synthesizes the window and renders it magnified `factor` (2, 4 or 8) times from
    /// `hi`, the exemplar at `factor` times the analysed resolution (RGBA8 rows of
    /// `hi_width` x `hi_height` = factor x the analysis size). Returns the magnified
    /// texture (`factor * width` x `factor * height`), on the GPU.
    pub fn synthesize_magnified(
        &self,
        ctx: &GpuContext,
        params: &SynthParams,
        hi: &[[u8; 4]],
        hi_width: u32,
        hi_height: u32,
        factor: u32,
    ) -> Result<GpuSynthesis> {
        let a = &self.analysis;
        self.check_magnify(ctx, params, (hi, hi_width, hi_height), factor)?;
        let plan = self.plan_for(ctx, params)?;
        self.check_output(ctx, &plan)?;
        let (w, h) = (params.width * factor, params.height * factor);
        let schedule = plan.schedule(a);
        let (big, big_view, scratch_view, hi_buffer) = ctx.scoped(|| {
            let scratch = self.output_texture(ctx, params.width, params.height);
            let scratch_view = scratch.create_view(&Default::default());
            let big = self.output_texture(ctx, w, h);
            let big_view = big.create_view(&Default::default());
            let hi_buffer = crate::gpu::buffer_init(
                &ctx.device,
                &wgpu::util::BufferInitDescriptor {
                    label: Some("texsyn high-resolution exemplar"),
                    contents: bytemuck::cast_slice(hi),
                    usage: wgpu::BufferUsages::STORAGE,
                },
            );
            (big, big_view, scratch_view, hi_buffer)
        })?;
        let target = MapTarget {
            colors: &hi_buffer,
            view: &big_view,
            map_kind: 0,
            magnify: factor,
            hi_size: [hi_width as i32, hi_height as i32],
        };
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        self.record_reporting(
            ctx,
            &mut encoder,
            &plan,
            &schedule,
            &scratch_view,
            &[target],
        )?;
        ctx.scoped(|| ctx.queue.submit([encoder.finish()]))?;
        wait(ctx)?;
        Ok(GpuSynthesis {
            texture: big,
            width: w,
            height: h,
        })
    }

    /// Times every dispatch of a synthesis on its own (submit + wait per dispatch, so
    /// the total exceeds a normal synthesis by the per-submission overhead). Returns
    /// the schedule's (kind, level) and the wall time of each dispatch, in order.
    pub fn profile(
        &self,
        ctx: &GpuContext,
        params: &SynthParams,
    ) -> Result<Vec<(PassKind, usize, std::time::Duration)>> {
        let plan = self.plan_for(ctx, params)?;
        self.check_output(ctx, &plan)?;
        let schedule = plan.schedule(&self.analysis);
        let texture = ctx.scoped(|| self.output_texture(ctx, params.width, params.height))?;
        let view = texture.create_view(&Default::default());
        let mut out = Vec::with_capacity(schedule.len());
        for (i, d) in schedule.iter().enumerate() {
            let mut encoder = ctx.device.create_command_encoder(&Default::default());
            ctx.scoped(|| {
                self.record(
                    ctx,
                    &mut encoder,
                    &plan,
                    &schedule[i..=i],
                    &view,
                    i == 0,
                    &[],
                );
            })?;
            let buffer = encoder.finish();
            let t = std::time::Instant::now();
            ctx.scoped(|| ctx.queue.submit([buffer]))?;
            wait(ctx)?;
            out.push((d.kind, d.level, t.elapsed()));
        }
        Ok(out)
    }

    /// The copy guard's probe ([`crate::gpu::copy_guard`]), synthesized in stages: at
    /// each checkpoint `(up, limit)` (the level `up` levels above the finest, coarsest
    /// first) the synthesis so far is read back and the largest verbatim copy of the
    /// output's window at that level is measured
    /// ([`crate::quality::verbatim_stats_at_spacing`]); above `limit` the probe stops
    /// there. Otherwise it finishes and its copy is measured on the output. The stages
    /// run on a coordinate buffer of their own (another synthesis on this synthesizer
    /// between two submissions must not overwrite them) and give the bytes of one
    /// [`Self::synthesize_to_host`].
    pub(crate) fn synthesize_probe(
        &self,
        ctx: &GpuContext,
        params: &SynthParams,
        checkpoints: &[(u32, f64)],
    ) -> Result<ProbeRun> {
        let a = &*self.analysis;
        let plan = self.plan_for(ctx, params)?;
        self.check_output(ctx, &plan)?;
        let schedule = plan.schedule(a);
        let last = plan.levels.len() - 1;
        let (coords, texture) = ctx.scoped(|| {
            let coords = coords_buffer(ctx, plan.coord_buffer_len(), "texsyn probe coords");
            // The checkpoints' stages write no colours (the gather is the last dispatch).
            (coords, self.output_texture(ctx, 1, 1))
        })?;
        let view = texture.create_view(&Default::default());
        let mut start = 0;
        for &(up, limit) in checkpoints {
            // A tileable output made on a torus is measured on its resampled output only
            // (its levels are the torus's, not the output's halved).
            if up == 0 || up as usize > last || plan.torus.is_some() {
                continue;
            }
            let l = last - up as usize;
            let end = match schedule.iter().rposition(|d| d.level == l) {
                Some(i) if i + 1 > start => i + 1,
                _ => continue,
            };
            // The output's window at level `l`, as the plan derives the regions.
            let (mut lo, mut hi) = (
                params.origin,
                [
                    params.origin[0] + params.width as i32,
                    params.origin[1] + params.height as i32,
                ],
            );
            for _ in 0..up {
                lo = [lo[0].div_euclid(2), lo[1].div_euclid(2)];
                hi = [(hi[0] - 1).div_euclid(2) + 1, (hi[1] - 1).div_euclid(2) + 1];
            }
            let lp = &plan.levels[l];
            let x0 = (lo[0] - lp.origin[0]) as usize;
            let y0 = (lo[1] - lp.origin[1]) as usize;
            let (w, h) = ((hi[0] - lo[0]) as usize, (hi[1] - lo[1]) as usize);
            let level_bytes = lp.size[0] as u64 * lp.size[1] as u64 * 8;
            let mut encoder = ctx.device.create_command_encoder(&Default::default());
            let readback = ctx.scoped(|| {
                self.record_with(
                    ctx,
                    &mut encoder,
                    &plan,
                    &schedule[start..end],
                    &view,
                    false,
                    &[],
                    Some((&coords, &self.no_velocity)),
                );
                let rb = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("texsyn probe readback"),
                    size: level_bytes.max(16),
                    usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                });
                encoder.copy_buffer_to_buffer(
                    &coords,
                    lp.coord_base as u64 * 8,
                    &rb,
                    0,
                    level_bytes,
                );
                ctx.queue.submit([encoder.finish()]);
                rb
            })?;
            start = end;
            let bytes = read_buffer(ctx, &readback)?;
            let level: &[[i32; 2]] = bytemuck::cast_slice(&bytes[..level_bytes as usize]);
            let mut window = Vec::with_capacity(w * h);
            for y in 0..h {
                let row = (y0 + y) * lp.size[0] as usize + x0;
                window.extend_from_slice(&level[row..row + w]);
            }
            let copy = crate::quality::verbatim_stats_at_spacing(
                &window, w as u32, h as u32, a.width, a.height, a.tileable, lp.spacing,
            )?
            .largest_region_fraction;
            if copy > limit {
                return Ok(ProbeRun::Stopped {
                    copy,
                    spacing: lp.spacing,
                });
            }
        }
        let (synthesis, _, _) =
            self.synthesize_maps_inner(ctx, params, &[], None, Some((&coords, start)))?;
        // Whole texels (a torus's isometric output has them in fixed point).
        let texels: Vec<[i32; 2]> = synthesis
            .coords
            .iter()
            .map(|c| c.map(|v| v >> synthesis.coord_frac))
            .collect();
        let copy = crate::quality::verbatim_stats(
            &texels,
            synthesis.width,
            synthesis.height,
            a.width,
            a.height,
            a.tileable,
        )?
        .largest_region_fraction;
        Ok(ProbeRun::Done { synthesis, copy })
    }

    /// Test hook: runs only the first `count` dispatches of the schedule and returns the
    /// whole coordinate array (every level), to compare with the CPU mirror pass by pass.
    pub fn run_prefix(
        &self,
        ctx: &GpuContext,
        params: &SynthParams,
        count: usize,
    ) -> Result<Vec<[i32; 2]>> {
        let plan = self.plan_for(ctx, params)?;
        self.check_output(ctx, &plan)?;
        let schedule = plan.schedule(&self.analysis);
        let schedule = &schedule[..count.min(schedule.len())];
        let texture = ctx.scoped(|| self.output_texture(ctx, params.width, params.height))?;
        let view = texture.create_view(&Default::default());
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        let bytes = plan.coord_count * 8;
        let readback = ctx.scoped(|| {
            // Cleared first so levels not yet written read as zeros, as on the CPU.
            let coords = self.record(ctx, &mut encoder, &plan, schedule, &view, true, &[]);
            let rb = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("texsyn coords readback"),
                size: bytes,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            encoder.copy_buffer_to_buffer(&coords, 0, &rb, 0, bytes);
            ctx.queue.submit([encoder.finish()]);
            rb
        })?;
        let data = read_buffer(ctx, &readback)?;
        Ok(bytemuck::cast_slice(&data).to_vec())
    }
}

/// What [`GpuSynthesizer::synthesize_probe`] found.
pub(crate) enum ProbeRun {
    /// Stopped at a checkpoint: the largest copy measured at the level whose pixels step
    /// `spacing` exemplar pixels was above its limit.
    Stopped { copy: f64, spacing: u32 },
    /// Synthesized to the end; `copy` is the output's largest verbatim copy.
    Done { synthesis: Synthesis, copy: f64 },
}

/// The limits every texsyn pipeline needs, checked before any is built (a downlevel
/// device would otherwise fail in wgpu's validation): 8 storage buffers and a storage
/// texture per stage, and workgroups of 64 invocations (8x8 for the passes, 64x1 for
/// advection's velocity upload): WebGPU's defaults.
pub(crate) fn check_device_limits(limits: &wgpu::Limits) -> Result<()> {
    if limits.max_storage_buffers_per_shader_stage < 8
        || limits.max_storage_textures_per_shader_stage < 1
    {
        return Err(Error::Gpu(format!(
            "the device allows {} storage buffers and {} storage textures per shader stage; \
             texsyn needs 8 and 1: create the device with at least wgpu::Limits::default()",
            limits.max_storage_buffers_per_shader_stage,
            limits.max_storage_textures_per_shader_stage
        )));
    }
    if limits.max_compute_invocations_per_workgroup < 64
        || limits.max_compute_workgroup_size_x < 64
        || limits.max_compute_workgroup_size_y < 8
    {
        return Err(Error::Gpu(format!(
            "the device allows compute workgroups of {} invocations ({} x {}); texsyn needs \
             64 (64 x 8): create the device with at least wgpu::Limits::default()",
            limits.max_compute_invocations_per_workgroup,
            limits.max_compute_workgroup_size_x,
            limits.max_compute_workgroup_size_y
        )));
    }
    Ok(())
}

/// A byte count for messages: MiB with a decimal under 10 MiB, KiB under 1 MiB, so that
/// a need and a limit never print the same while they differ.
pub(crate) fn fmt_bytes(b: u64) -> String {
    if b < 1 << 20 {
        format!("{:.1} KiB", b as f64 / 1024.0)
    } else if b < 10 << 20 {
        format!("{:.2} MiB", b as f64 / (1u64 << 20) as f64)
    } else {
        format!("{} MiB", b >> 20)
    }
}

/// Checks, before any analysis, that an exemplar of this size fits the device's
/// buffer limits (its per-level tables live in single storage buffers).
pub fn check_exemplar_fits(ctx: &GpuContext, width: u32, height: u32, k: u32) -> Result<()> {
    let limits = ctx.limits();
    check_device_limits(&limits)?;
    let px = width as u64 * height as u64;
    let levels = crate::analysis::level_count(width, height) as u64 + 1;
    // Level 0 has no et/qe tables (LevelData::et).
    let table_bytes = px * (levels - 1) * 16;
    let offset_bytes = px * levels * 4 * (k.saturating_sub(1) as u64);
    let max = limits
        .max_storage_buffer_binding_size
        .min(limits.max_buffer_size);
    let biggest = table_bytes.max(offset_bytes);
    if biggest > max {
        return Err(too_large(
            "exemplar",
            width,
            height,
            format!(
                "its tables need {} in one buffer, the device allows {}",
                fmt_bytes(biggest),
                fmt_bytes(max)
            ),
            if offset_bytes > table_bytes {
                "use a smaller k or a smaller exemplar"
            } else {
                "use a smaller exemplar: downsample it, or keep its detail with \
                 `synth --magnify F` (analysis on a 1/F copy, colours from the full image)"
            },
        ));
    }
    Ok(())
}

pub(crate) fn wait(ctx: &GpuContext) -> Result<()> {
    ctx.device
        .poll(wgpu::PollType::wait_indefinitely())
        .map(|_| ())
        .map_err(|e| Error::Gpu(format!("waiting for the GPU: {e}")))
}

pub(crate) fn read_buffer(ctx: &GpuContext, buffer: &wgpu::Buffer) -> Result<Vec<u8>> {
    read_mapped(
        buffer,
        || wait(ctx),
        "buffer mapping was cancelled",
        "reading back results",
    )
}

/// Maps `buffer` for reading, runs `wait` (a device poll that lets the mapping
/// complete) and copies the contents out: the one read-back sequence of the
/// synthesizer ([`read_buffer`]) and the mesh renderer, which word their errors
/// differently: `cancelled` when the mapping is dropped, `"{failed}: {e}"` when it fails.
pub(crate) fn read_mapped(
    buffer: &wgpu::Buffer,
    wait: impl FnOnce() -> Result<()>,
    cancelled: &str,
    failed: &str,
) -> Result<Vec<u8>> {
    let (tx, rx) = std::sync::mpsc::channel();
    buffer.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = tx.send(r);
    });
    wait()?;
    rx.recv()
        .map_err(|_| Error::Gpu(cancelled.into()))?
        .map_err(|e| Error::Gpu(format!("{failed}: {e}")))?;
    let data = buffer
        .get_mapped_range(..)
        .map_err(|e| Error::Gpu(format!("{failed}: {e}")))?
        .to_vec();
    buffer.unmap();
    Ok(data)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn variant_constants_follow_the_parameters() {
        let p = PassParams {
            tileable: 1,
            full_distance: 1,
            periodic: 1,
            k: 3,
            ..Default::default()
        };
        let v = Variant::of(&p);
        let c = v.constants();
        let get = |n: &str| c.iter().find(|(name, _)| *name == n).unwrap().1;
        assert_eq!(
            [
                get("TILEABLE"),
                get("FULL_DISTANCE"),
                get("KSET_INTERP"),
                get("MASKED"),
                get("PERIODIC"),
                get("K")
            ],
            [1.0, 1.0, 0.0, 0.0, 1.0, 3.0]
        );
        // Other passes keep the exemplar and output switches, not the correction's.
        let g = v.for_kind(PassKind::Gather).constants();
        let get = |n: &str| g.iter().find(|(name, _)| *name == n).unwrap().1;
        assert_eq!(
            [
                get("TILEABLE"),
                get("FULL_DISTANCE"),
                get("PERIODIC"),
                get("K")
            ],
            [1.0, 0.0, 1.0, 1.0]
        );
        assert_eq!(v.for_kind(PassKind::CorrectAniso), v);
        // The gathers' switches reach the gathers only.
        let w = Variant::of(&PassParams {
            nearest: 1,
            seam_blend: 1,
            ..p
        });
        let on = |v: Variant, n: &str| v.constants().iter().find(|(name, _)| *name == n).unwrap().1;
        for kind in [PassKind::Gather, PassKind::GatherAniso] {
            assert_eq!(
                [
                    on(w.for_kind(kind), "NEAREST"),
                    on(w.for_kind(kind), "SEAM_BLEND")
                ],
                [1.0, 1.0]
            );
        }
        for kind in [PassKind::CorrectAniso, PassKind::Upsample, PassKind::Advect] {
            assert_eq!(
                [
                    on(w.for_kind(kind), "NEAREST"),
                    on(w.for_kind(kind), "SEAM_BLEND")
                ],
                [0.0, 0.0]
            );
        }
        assert_eq!(w.for_kind(PassKind::Correct), v);
    }
}
