//! The synthesizer's working buffers: the analysis tables uploaded into storage buffers,
//! the shared coordinate pyramid, the quarter-pixel tables and the cached Jacobian field.

use std::sync::Arc;

use super::GpuSynthesizer;
use crate::analysis::{Analysis, LevelData, DIM};
use crate::error::{Error, Result};
use crate::gpu::GpuContext;
use crate::passes::common::PassParams;
use crate::passes::plan::{Dispatch, PassKind, SynthPlan};

/// The coordinate pyramid, kept between calls of the same or smaller size. Sharing it
/// is safe even for several syntheses recorded into one encoder: they run in order.
pub(super) struct Scratch {
    /// Capacity in coordinates.
    entries: u64,
    pub(super) coords: wgpu::Buffer,
}

/// A coordinate buffer of `count` entries (every level of a plan, then its flag region:
/// `SynthPlan::coord_buffer_len`).
pub(super) fn coords_buffer(ctx: &GpuContext, count: u64, label: &str) -> wgpu::Buffer {
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
/// creation: no concatenated copy on the host (each copy of fresh memory costs its page
/// faults, which on a CPU device are most of the upload). Where the device can map storage buffers (a CPU device, see
/// `GpuContext::headless`) the buffer is written in place; wgpu otherwise writes it to a
/// staging buffer and copies, twice the memory touched.
pub(super) fn levels_buffer(
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
pub(super) fn padded<T: bytemuck::Pod>(data: &[T]) -> Vec<u8> {
    let mut b = bytemuck::cast_slice(data).to_vec();
    b.resize(b.len().max(16).next_multiple_of(4), 0);
    b
}

/// An analysis level's `Et` and `qe` interpolated at every quarter pixel
/// ([`crate::passes::correct_aniso::quarter_table`]), bound in place of the whole tables
/// for the corrections that read quarter pixels (`PassParams::quarter`): one read of 16
/// bytes where bilinear interpolation reads four. 16 times the level's tables (8 MiB
/// for a 128x128 exemplar), built and uploaded on first use only.
pub(crate) struct FineTables {
    /// `et_base` of the level they were built for.
    et_base: u32,
    pub(super) et: wgpu::Buffer,
    pub(super) qe: wgpu::Buffer,
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

/// What a rasterized Jacobian buffer depends on: the field, the regions, and the atlas
/// domain (by identity: a domain is immutable once shared).
pub(super) type JacobianKey = (
    Option<crate::field::Field>,
    Vec<([i32; 2], [u32; 2])>,
    Option<usize>,
);

impl GpuSynthesizer {
    /// The shared coordinate pyramid, grown to `plan`'s size if smaller (held locked
    /// while a synthesis is recorded into it).
    pub(super) fn scratch_for(
        &self,
        plan: &SynthPlan,
    ) -> std::sync::MutexGuard<'_, Option<Scratch>> {
        let ctx = &self.context;
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

    /// The `qe` binding for `schedule`: the uploaded tables (uploaded now if not yet)
    /// when a correction of it uses the projected distance, else whatever is there (a
    /// 16-byte stand-in until the first upload). Called inside the caller's error scope
    /// ([`GpuContext::scoped`]): a buffer the device cannot create is reported there (the
    /// stand-in is bound meanwhile and the upload tried again next time).
    pub(super) fn qe_for(&self, schedule: &[Dispatch]) -> wgpu::Buffer {
        let ctx = &self.context;
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

    /// The quarter-pixel tables `schedule`'s corrections read (built now; `None` where
    /// none do or they do not fit), and which dispatches read them: those that read
    /// quarter pixels at the schedule's most corrected level
    /// ([`crate::passes::plan::quarter_tables_level`]), read from its supersampled tables
    /// instead of `et` and `qe` (a variant of their own).
    pub(super) fn fine_reads<'a>(
        &'a self,
        schedule: &[Dispatch],
    ) -> (Option<&'a FineTables>, impl Fn(&Dispatch) -> bool + 'a) {
        let level = crate::passes::plan::quarter_tables_level(schedule, &self.analysis);
        let fine = level.and_then(|l| self.fine_tables(l));
        let et_base = fine.map(|f| f.et_base);
        let reads = move |d: &Dispatch| {
            Some(d.level) == level
                && Some(d.params.et_base) == et_base
                && d.reads_quarter_tables(&self.analysis)
        };
        (fine, reads)
    }

    /// A level's quarter-pixel tables, built and uploaded now if not yet (inside the
    /// caller's error scope); `None` if it has none or they exceed the device's limits.
    /// [`crate::gpu::advect::Advection::new`] calls it so that the first frame does not
    /// pay for them.
    pub(crate) fn fine_tables(&self, level: usize) -> Option<&FineTables> {
        let ctx = &self.context;
        self.fine
            .get(level)?
            .get_or_init(|| FineTables::build(ctx, &self.analysis, level))
            .as_ref()
    }

    /// The Jacobian field rasterized on the host for this plan's regions (a placeholder
    /// for isometric synthesis) and the atlas surface buffer, from the cache when the
    /// last plan had the same field and regions.
    pub(super) fn jacobian_buffers(&self, plan: &SynthPlan) -> (wgpu::Buffer, wgpu::Buffer) {
        let ctx = &self.context;
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
}
