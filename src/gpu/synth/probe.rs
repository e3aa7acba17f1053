//! The copy guard's probe: a synthesis read back at checkpoints to measure its largest
//! verbatim copy. The one place the GPU layer calls into [`crate::quality`].

use super::buffers::coords_buffer;
use super::{read_buffer, GpuSynthesizer};
use crate::error::Result;
use crate::passes::{SynthParams, Synthesis};

/// What [`GpuSynthesizer::synthesize_probe`] found.
pub(crate) enum ProbeRun {
    /// Stopped at a checkpoint: the largest copy measured at the level whose pixels step
    /// `spacing` exemplar pixels was above its limit.
    Stopped { copy: f64, spacing: u32 },
    /// Synthesized to the end; `copy` is the output's largest verbatim copy.
    Done { synthesis: Synthesis, copy: f64 },
}

impl GpuSynthesizer {
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
        params: &SynthParams,
        checkpoints: &[(u32, f64)],
    ) -> Result<ProbeRun> {
        let ctx = &self.context;
        let a = &*self.analysis;
        let plan = self.plan_for(params)?;
        self.check_output(&plan)?;
        let schedule = plan.schedule(a);
        let last = plan.levels.len() - 1;
        let (coords, texture) = ctx.scoped(|| {
            let coords = coords_buffer(ctx, plan.coord_buffer_len(), "texsyn probe coords");
            // The checkpoints' stages write no colours (the gather is the last dispatch).
            (coords, self.output_texture(1, 1))
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
            self.synthesize_maps_inner(params, &[], None, Some((&coords, start)))?;
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
}
