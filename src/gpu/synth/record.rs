//! Recording a schedule's dispatches into a compute pass: the per-call parameter buffer,
//! the bind groups, the map gathers after the schedule, and the level-by-level
//! submission that reports progress.

use super::buffers::coords_buffer;
use super::pipelines::PROJ_BYTES;
use super::{wait, GpuSynthesizer, Variant};
use crate::error::Result;
use crate::passes::common::{PassParams, PARAMS_STRIDE};
use crate::passes::plan::{Dispatch, PassKind, SynthPlan};

/// An extra map gathered through the synthesized coordinates (material sets).
pub(crate) struct MapTarget<'a> {
    /// The map's pixels (RGBA8, the exemplar's size or `hi_size`).
    pub(super) colors: &'a wgpu::Buffer,
    /// Where the gathered map is written.
    pub(super) view: &'a wgpu::TextureView,
    /// `PassParams::map_kind`: 0 plain, 1 normals with green down, 2 with green up.
    pub(super) map_kind: u32,
    /// > 1: the magnify pass with a high-resolution exemplar of `hi_size`.
    pub(super) magnify: u32,
    /// Size of the high-resolution map when magnifying, else zero.
    pub(super) hi_size: [i32; 2],
}

impl GpuSynthesizer {
    /// [`Self::record`] for the calls that submit the encoder themselves: with a
    /// progress callback set, every level but the last is submitted and waited for
    /// here (the caller's encoder then holds the last level, the map passes and
    /// whatever it adds).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn record_reporting(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        plan: &SynthPlan,
        schedule: &[Dispatch],
        target: &wgpu::TextureView,
        maps: &[MapTarget<'_>],
    ) -> Result<wgpu::Buffer> {
        let ctx = &self.context;
        let hook = self
            .progress
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone();
        let Some(report) = hook else {
            return ctx.scoped(|| self.record(encoder, plan, schedule, target, false, maps));
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
                self.record_with(encoder, plan, level, target, false, &[], state);
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
        ctx.scoped(|| self.record_with(encoder, plan, last, target, false, maps, state))
    }

    /// Records `schedule`'s dispatches, then the gathers of `maps`, into `encoder` on
    /// the shared coordinate pyramid (zeroed first with `clear`), writing colours to
    /// `target`. Returns the coordinate buffer.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn record(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        plan: &SynthPlan,
        schedule: &[Dispatch],
        target: &wgpu::TextureView,
        clear: bool,
        maps: &[MapTarget<'_>],
    ) -> wgpu::Buffer {
        self.record_with(encoder, plan, schedule, target, clear, maps, None)
    }

    /// [`Self::record`] on the caller's coordinate and velocity buffers (advection keeps
    /// its coordinates between frames) instead of the shared scratch buffer.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn record_with(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        plan: &SynthPlan,
        schedule: &[Dispatch],
        target: &wgpu::TextureView,
        clear: bool,
        maps: &[MapTarget<'_>],
        state: Option<(&wgpu::Buffer, &wgpu::Buffer)>,
    ) -> wgpu::Buffer {
        let ctx = &self.context;
        let guard;
        let coords_buffer = match state {
            Some((coords, _)) => coords,
            None => {
                guard = self.scratch_for(plan);
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
        let (jac, surface) = self.jacobian_buffers(plan);
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
        let (fine, reads_fine) = self.fine_reads(schedule);
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
        let qe = self.qe_for(schedule);
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
}
