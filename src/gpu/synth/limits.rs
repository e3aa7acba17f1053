//! What fits the device: its limits checked against an exemplar, an output and a plan
//! before any work is recorded, and the errors that say so.

use super::GpuSynthesizer;
use crate::error::{Error, Result};
use crate::gpu::GpuContext;
use crate::passes::plan::SynthPlan;
use crate::passes::SynthParams;

impl GpuSynthesizer {
    /// The plan this synthesizer runs for `params` on `ctx`: [`SynthPlan::new`], except
    /// that a tileable output made on a torus ([`crate::passes::plan::Torus`]) whose
    /// pyramid and Jacobians do not fit the device keeps the output's own periods
    /// (the plan [`SynthPlan::with_torus`] makes without the torus, whose sides that are
    /// not multiples of 4 show a faint seam at the wrap) where that one fits.
    pub fn plan_for(&self, params: &SynthParams) -> Result<SynthPlan> {
        let plan = SynthPlan::new(&self.analysis, params)?;
        if plan.torus.is_some() && self.check_output(&plan).is_err() {
            let exact = SynthPlan::with_torus(&self.analysis, params, false)?;
            if self.check_output(&exact).is_ok() {
                return Ok(exact);
            }
        }
        Ok(plan)
    }

    /// Refuses a context other than the one this synthesizer was made on (or a clone of
    /// it): its buffers and pipelines would be bound on that context's device (a
    /// validation error that spoils the device's cached pipelines, or a panic in wgpu
    /// across instances). Two contexts made with [`GpuContext::from_device`] from the
    /// same device count as different: clone the first instead.
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

    /// Checks a plan's output (size, coordinate pyramid or Jacobians, dispatch counts)
    /// against the device limits before any work is recorded; checks the context too.
    pub(crate) fn check_output(&self, plan: &SynthPlan) -> Result<()> {
        let ctx = &self.context;
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

    /// Whether `params` can be synthesized in one piece on this device (its coordinate
    /// pyramid, Jacobians and dispatches within the device's limits).
    pub fn fits(&self, params: &SynthParams) -> bool {
        self.plan_for(params)
            .is_ok_and(|plan| self.check_output(&plan).is_ok())
    }
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

/// [`Error::TooLarge`] from its parts.
pub(super) fn too_large(
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
