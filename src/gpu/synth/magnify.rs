//! Magnification: a synthesis rendered 2, 4 or 8 times larger from a high-resolution
//! copy of the exemplar, on the GPU or read back with its material sets.

use super::limits::too_large;
use super::record::MapTarget;
use super::{wait, ExtraMap, GpuSynthesis, GpuSynthesizer};
use crate::error::{Error, Result};
use crate::passes::{SynthParams, Synthesis};

/// A magnified synthesis with its material sets, on the host
/// ([`GpuSynthesizer::synthesize_magnified_with_maps`]).
#[derive(Clone, Debug)]
pub struct MagnifiedSynthesis {
    /// Magnified width: `factor` times the synthesized window's.
    pub width: u32,
    /// Magnified height: `factor` times the synthesized window's.
    pub height: u32,
    /// The magnification: 2, 4 or 8.
    pub factor: u32,
    /// Magnified colours from the high-resolution exemplar, RGBA8, `width x height`.
    pub colors: Vec<[u8; 4]>,
    /// Each extra map, magnified the same way, RGBA8, `width x height`.
    pub maps: Vec<Vec<[u8; 4]>>,
    /// The synthesis at its own resolution (coordinates in the analysed exemplar's
    /// pixels, and its colours).
    pub synthesis: Synthesis,
}

impl GpuSynthesizer {
    /// [`Self::synthesize_magnified`] with material sets, read back to the host in one
    /// submission: the colours and every extra map rendered `factor` times larger from
    /// their high-resolution versions (each `hi_width` x `hi_height`, `factor` times the
    /// analysed exemplar; normal maps rotate with the field as in
    /// [`Self::synthesize_with_maps`]), and the synthesis itself (coordinates and
    /// colours at the synthesized resolution).
    #[allow(clippy::too_many_arguments)]
    pub fn synthesize_magnified_with_maps(
        &self,
        params: &SynthParams,
        hi: &[[u8; 4]],
        hi_width: u32,
        hi_height: u32,
        factor: u32,
        maps: &[ExtraMap],
    ) -> Result<MagnifiedSynthesis> {
        self.check_magnify(params, (hi, hi_width, hi_height), factor)?;
        let (synthesis, colors, maps) = self.synthesize_maps_inner(
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
        params: &SynthParams,
        (hi, hi_width, hi_height): (&[[u8; 4]], u32, u32),
        factor: u32,
    ) -> Result<()> {
        let ctx = &self.context;
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

    /// Synthesizes the window and renders it magnified `factor` (2, 4 or 8) times from
    /// `hi`, the exemplar at `factor` times the analysed resolution (RGBA8 rows of
    /// `hi_width` x `hi_height` = factor x the analysis size). Returns the magnified
    /// texture (`factor * width` x `factor * height`), on the GPU.
    pub fn synthesize_magnified(
        &self,
        params: &SynthParams,
        hi: &[[u8; 4]],
        hi_width: u32,
        hi_height: u32,
        factor: u32,
    ) -> Result<GpuSynthesis> {
        let ctx = &self.context;
        let a = &self.analysis;
        self.check_magnify(params, (hi, hi_width, hi_height), factor)?;
        let plan = self.plan_for(params)?;
        self.check_output(&plan)?;
        let (w, h) = (params.width * factor, params.height * factor);
        let schedule = plan.schedule(a);
        let (big, big_view, scratch_view, hi_buffer) = ctx.scoped(|| {
            let scratch = self.output_texture(params.width, params.height);
            let scratch_view = scratch.create_view(&Default::default());
            let big = self.output_texture(w, h);
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
        self.record_reporting(&mut encoder, &plan, &schedule, &scratch_view, &[target])?;
        ctx.scoped(|| ctx.queue.submit([encoder.finish()]))?;
        wait(ctx)?;
        Ok(GpuSynthesis {
            texture: big,
            width: w,
            height: h,
        })
    }
}
