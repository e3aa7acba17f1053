//! The plain entry points: record a synthesis into the caller's encoder, or run it and
//! wait, keeping the result on the GPU or reading it back.

use super::{wait, GpuSynthesis, GpuSynthesizer};
use crate::error::Result;
use crate::passes::{SynthParams, Synthesis};

impl GpuSynthesizer {
    /// Records a whole synthesis into the caller's encoder; the returned texture holds
    /// the colours once the caller submits the encoder. Nothing is read back.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        params: &SynthParams,
    ) -> Result<GpuSynthesis> {
        self.encode_inner(encoder, params, false)
    }

    /// [`Self::encode`]; with `submitting` (the caller submits right after), levels may
    /// be submitted early for [`Self::set_progress`].
    fn encode_inner(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        params: &SynthParams,
        submitting: bool,
    ) -> Result<GpuSynthesis> {
        let ctx = &self.context;
        let plan = self.plan_for(params)?;
        self.check_output(&plan)?;
        let schedule = plan.schedule(&self.analysis);
        let texture = ctx.scoped(|| self.output_texture(params.width, params.height))?;
        let view = texture.create_view(&Default::default());
        if submitting {
            self.record_reporting(encoder, &plan, &schedule, &view, &[])?;
        } else {
            ctx.scoped(|| self.record(encoder, &plan, &schedule, &view, false, &[]))?;
        }
        Ok(GpuSynthesis {
            texture,
            width: params.width,
            height: params.height,
        })
    }

    /// Synthesizes and submits; returns when the GPU has finished.
    pub fn synthesize(&self, params: &SynthParams) -> Result<GpuSynthesis> {
        let ctx = &self.context;
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        let out = self.encode_inner(&mut encoder, params, true)?;
        ctx.scoped(|| ctx.queue.submit([encoder.finish()]))?;
        wait(ctx)?;
        Ok(out)
    }

    /// Synthesizes and reads colours and coordinates back to the host.
    pub fn synthesize_to_host(&self, params: &SynthParams) -> Result<Synthesis> {
        self.synthesize_with_maps(params, &[]).map(|(s, _)| s)
    }
}
