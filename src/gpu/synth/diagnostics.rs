//! Diagnostics: per-dispatch timing and the test hook that runs a schedule's prefix.

use super::{read_buffer, wait, GpuSynthesizer};
use crate::error::Result;
use crate::passes::plan::PassKind;
use crate::passes::SynthParams;

impl GpuSynthesizer {
    /// Times every dispatch of a synthesis on its own (submit + wait per dispatch, so
    /// the total exceeds a normal synthesis by the per-submission overhead). Returns
    /// the schedule's (kind, level) and the wall time of each dispatch, in order.
    pub fn profile(
        &self,
        params: &SynthParams,
    ) -> Result<Vec<(PassKind, usize, std::time::Duration)>> {
        let ctx = &self.context;
        let plan = self.plan_for(params)?;
        self.check_output(&plan)?;
        let schedule = plan.schedule(&self.analysis);
        let texture = ctx.scoped(|| self.output_texture(params.width, params.height))?;
        let view = texture.create_view(&Default::default());
        let mut out = Vec::with_capacity(schedule.len());
        for (i, d) in schedule.iter().enumerate() {
            let mut encoder = ctx.device.create_command_encoder(&Default::default());
            ctx.scoped(|| {
                self.record(&mut encoder, &plan, &schedule[i..=i], &view, i == 0, &[]);
            })?;
            let buffer = encoder.finish();
            let t = std::time::Instant::now();
            ctx.scoped(|| ctx.queue.submit([buffer]))?;
            wait(ctx)?;
            out.push((d.kind, d.level, t.elapsed()));
        }
        Ok(out)
    }

    /// Test hook: runs only the first `count` dispatches of the schedule and returns the
    /// whole coordinate array (every level), to compare with the CPU mirror pass by pass.
    pub fn run_prefix(&self, params: &SynthParams, count: usize) -> Result<Vec<[i32; 2]>> {
        let ctx = &self.context;
        let plan = self.plan_for(params)?;
        self.check_output(&plan)?;
        let schedule = plan.schedule(&self.analysis);
        let schedule = &schedule[..count.min(schedule.len())];
        let texture = ctx.scoped(|| self.output_texture(params.width, params.height))?;
        let view = texture.create_view(&Default::default());
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        let bytes = plan.coord_count * 8;
        let readback = ctx.scoped(|| {
            // Cleared first so levels not yet written read as zeros, as on the CPU.
            let coords = self.record(&mut encoder, &plan, schedule, &view, true, &[]);
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
