//! The pass pipelines: the bind group layout every pass shares, the compute pipelines
//! built lazily per pass and [`Variant`], and building them ahead of a synthesis.

use std::sync::{Arc, Mutex};

use super::output::OUTPUT_FORMAT;
use super::{GpuSynthesizer, Variant};
use crate::analysis::Analysis;
use crate::error::{Error, Result};
use crate::gpu::shaders::{self, ShaderSource};
use crate::gpu::GpuContext;
use crate::passes::common::PassParams;
use crate::passes::plan::{Dispatch, PassKind, SynthPlan};
use crate::passes::SynthParams;

/// Bytes of one level's projection matrix in the uniform buffer (64 x vec4<i32>; a
/// multiple of the 256-byte dynamic-offset alignment).
pub(super) const PROJ_BYTES: u64 = 64 * 16;

/// A compute pipeline built on first use, per [`Variant`]: a synthesis needs only a few
/// of the passes' pipelines, and building one is slow on CPU drivers.
pub(super) struct LazyPipeline {
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
    pub(super) fn get(
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

/// The bind group layout every pass shares and the pipelines of every pass, built on
/// first use. One per device ([`GpuContext`] keeps it), so that every synthesizer on a
/// device shares compiled pipelines, and so that they can be built ahead of time
/// ([`GpuContext::prepare_pipelines`]) while the host does other work.
pub(crate) struct PassPipelines {
    pub(super) layout: wgpu::BindGroupLayout,
    pub(super) pipeline_layout: wgpu::PipelineLayout,
    upsample: LazyPipeline,
    jitter: LazyPipeline,
    correct: LazyPipeline,
    gather: LazyPipeline,
    upsample_aniso: LazyPipeline,
    correct_aniso: LazyPipeline,
    gather_aniso: LazyPipeline,
    pub(super) gather_map: LazyPipeline,
    pub(super) magnify: LazyPipeline,
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
    /// The shared layout; no pipeline is built yet.
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
    pub(super) fn get(
        &self,
        ctx: &GpuContext,
        kind: PassKind,
        variant: Variant,
    ) -> wgpu::ComputePipeline {
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
    /// own while this one builds the others and then runs `alongside` (host work): the
    /// corrections' pipelines take the longest to build.
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
        // synthesis has two (with and without the similarity sets).
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

impl GpuSynthesizer {
    /// Builds the pipelines a synthesis of `params` uses now rather than while its first
    /// submission is recorded (see [`GpuContext::prepare_pipelines`]), e.g. to time them
    /// apart or to build them while the application does other work. An anisometric
    /// plan's Jacobian field is rasterized and uploaded too (kept for the synthesis that
    /// follows with the same field and regions), and so is the `qe` table when its
    /// corrections read it. Optional; the synthesis is the same either way.
    pub fn prepare(&self, params: &SynthParams) -> Result<()> {
        let ctx = &self.context;
        // The Jacobian field alongside, which the synthesis then finds in its cache, and
        // beside it the `qe` table if a correction reads it.
        self.pipelines
            .prepare_plan(ctx, &self.analysis, params, |plan| {
                std::thread::scope(|s| {
                    let qe = s.spawn(|| {
                        ctx.scoped(|| {
                            self.qe_for(&plan.schedule(&self.analysis));
                        })
                    });
                    let jacobians = ctx.scoped(|| {
                        self.jacobian_buffers(plan);
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
        plan: &SynthPlan,
        schedules: &[Vec<Dispatch>],
    ) -> Result<()> {
        let ctx = &self.context;
        let mut dispatches = Vec::new();
        for schedule in schedules {
            let (_, reads_fine) = self.fine_reads(schedule);
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
}
