//! [`GpuSynthesizer`]: an analysed exemplar uploaded to a device, and its progress
//! reporting.

use std::sync::{Arc, Mutex};

use super::buffers::{levels_buffer, padded, FineTables, JacobianKey, Scratch};
use super::check_exemplar_fits;
use super::pipelines::PassPipelines;
use crate::analysis::{Analysis, DIM};
use crate::error::Result;
use crate::gpu::GpuContext;

/// An exemplar uploaded to a device, ready to synthesize any number of textures.
pub struct GpuSynthesizer {
    /// The analysed exemplar the buffers below were uploaded from.
    pub(super) analysis: Arc<Analysis>,
    /// The context everything here was made on (a clone); every call runs on it.
    pub(crate) context: GpuContext,
    /// The device's pass pipelines, shared by every synthesizer on it.
    pub(super) pipelines: Arc<PassPipelines>,
    /// 16-byte stand-in for the velocity binding outside advection.
    pub(super) no_velocity: wgpu::Buffer,
    /// Every level's `Et` table, concatenated (indexed by `PassParams::et_base`).
    pub(super) et: wgpu::Buffer,
    /// Uploaded on first use ([`Self::qe_for`]): only the projected distance reads it, and
    /// a default isometric synthesis uses the full distance on every corrected level.
    pub(super) qe: Mutex<Option<wgpu::Buffer>>,
    /// 16-byte stand-in for `qe` in the bind groups of schedules that never read it.
    pub(super) no_qe: wgpu::Buffer,
    /// Every level's similarity-set offsets, concatenated (indexed by `off_base`).
    pub(super) offsets: wgpu::Buffer,
    /// Every level's projection matrix, one [`PROJ_BYTES`](super::pipelines::PROJ_BYTES)
    /// block per level (bound at a dynamic offset).
    pub(super) proj: wgpu::Buffer,
    /// The exemplar's RGBA8 colours, which the gathers read.
    pub(super) colors: wgpu::Buffer,
    /// The shared coordinate pyramid ([`Self::scratch_for`]).
    pub(super) scratch: Mutex<Option<Scratch>>,
    /// Per level, its quarter-pixel tables, built on first use (advection frames read
    /// those of their most corrected level; `None` if they do not fit the device's
    /// buffer limits: the shader then interpolates, same numbers).
    pub(super) fine: Vec<std::sync::OnceLock<Option<FineTables>>>,
    /// The last rasterized Jacobian field and the regions it covers, with the surface
    /// buffer of atlas synthesis (a placeholder otherwise): a frame loop that keeps its
    /// field and window reuses them instead of rasterizing again.
    pub(super) jacobians: Mutex<Option<(JacobianKey, wgpu::Buffer, wgpu::Buffer)>>,
    /// [`Self::set_progress`]'s callback, in a lock of its own: the slot's lock is held
    /// only to clone it out, so the callback may call [`Self::set_progress`] or
    /// synthesize.
    pub(super) progress: Mutex<Option<Arc<Mutex<LevelProgress>>>>,
}

/// A callback told `(levels done, levels in all)` during a synthesis.
pub type LevelProgress = Box<dyn FnMut(u32, u32) + Send>;

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

    /// The analysis this synthesizer was made from (exemplar size, levels, tables).
    pub fn analysis(&self) -> &Analysis {
        &self.analysis
    }

    /// Reports the progress of long syntheses: while set, [`Self::synthesize`],
    /// [`Self::synthesize_to_host`], [`Self::synthesize_with_maps`] and the magnified
    /// variants submit each level on its own, wait for it and call `f(levels done,
    /// levels in all)`. That costs one GPU round trip per level (idle time on a real
    /// GPU), so set it for outputs that take seconds, and `None` to go back to one
    /// submission. [`Self::encode`] never splits (it does
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
}
