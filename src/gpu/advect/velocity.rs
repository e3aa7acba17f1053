//! Velocity input of an advection: host velocities quantized on the host, or a velocity
//! buffer or texture the caller owns quantized on the GPU into the advection's velocity
//! buffer, then one frame recorded.

use std::sync::Arc;

use super::Advection;
use crate::error::{Error, Result};
use crate::gpu::shaders;
use crate::gpu::GpuContext;

pub use crate::passes::velocity::quantize_velocity;

impl Advection {
    pub(super) fn check_dt(dt: f32) -> Result<()> {
        if !dt.is_finite() || dt <= 0.0 {
            return Err(Error::InvalidParameter(format!(
                "time step {dt}: it must be a positive number"
            )));
        }
        Ok(())
    }

    /// One frame from host velocities (one per output pixel, row-major, pixels per unit
    /// time), submitted to the queue. Errors on a wrong count, a non-finite value or a
    /// `dt` that is not positive and finite (skip the call for a paused frame).
    pub fn step(&mut self, velocity: &[[f32; 2]], dt: f32) -> Result<()> {
        // A handle of its own: the frame below borrows `self` mutably.
        let synthesizer = Arc::clone(&self.synthesizer);
        let ctx = &synthesizer.context;
        self.upload_velocity(velocity, dt)?;
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        self.record_frame(&mut encoder)?;
        ctx.scoped(|| ctx.queue.submit([encoder.finish()]))?;
        Ok(())
    }

    /// Checks `dt` and the host velocities (count, finite), quantizes them and writes
    /// them to the velocity buffer.
    pub(super) fn upload_velocity(&self, velocity: &[[f32; 2]], dt: f32) -> Result<()> {
        let ctx = &self.synthesizer.context;
        Self::check_dt(dt)?;
        let n = self.params.width as usize * self.params.height as usize;
        if velocity.len() != n {
            return Err(Error::InvalidParameter(format!(
                "velocity field has {} vectors; the output is {}x{} = {n} pixels",
                velocity.len(),
                self.params.width,
                self.params.height
            )));
        }
        if let Some(i) = velocity
            .iter()
            .position(|v| !v[0].is_finite() || !v[1].is_finite())
        {
            return Err(Error::InvalidParameter(format!(
                "velocity at pixel ({}, {}) is not finite ({:?})",
                i % self.params.width as usize,
                i / self.params.width as usize,
                velocity[i]
            )));
        }
        let q: Vec<[i32; 2]> = velocity.iter().map(|&v| quantize_velocity(v, dt)).collect();
        ctx.scoped(|| {
            ctx.queue
                .write_buffer(&self.velocity, 0, bytemuck::cast_slice(&q))
        })
    }

    /// One frame from a velocity buffer the caller owns, recorded into the caller's
    /// encoder: nothing goes through the host. The buffer holds one `vec2<f32>` (output
    /// pixels per unit of time) per output pixel, row-major with a stride of the output's
    /// width; only its first `width * height` entries are read. It must come from the
    /// same device and have usage STORAGE, and be unmapped when the encoder is submitted.
    /// Non-finite components count as 0. Every check (size, usage, a destroyed or invalid
    /// buffer, or one from another device of the same `wgpu::Instance`) runs before
    /// anything is recorded, so an error leaves the encoder usable; a buffer still mapped
    /// is found only by the caller's submit (wgpu tells no earlier). A buffer from
    /// another `wgpu::Instance` cannot be detected (wgpu resolves it among this device's
    /// objects): never pass one. `dt` must be positive and finite (an error otherwise;
    /// skip the call for a paused frame).
    pub fn encode_step(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        velocity: &wgpu::Buffer,
        dt: f32,
    ) -> Result<()> {
        Self::check_dt(dt)?;
        let n = self.params.width as u64 * self.params.height as u64;
        if velocity.size() < n * 8 {
            return Err(Error::InvalidParameter(format!(
                "velocity buffer holds {} bytes; the output needs {} (vec2<f32> per pixel)",
                velocity.size(),
                n * 8
            )));
        }
        if !velocity.usage().contains(wgpu::BufferUsages::STORAGE) {
            return Err(Error::InvalidParameter(format!(
                "the velocity buffer's usage is {:?}; create it with BufferUsages::STORAGE \
                 (it is read by a compute shader)",
                velocity.usage()
            )));
        }
        // Only the pixels' velocities: a larger buffer may exceed the binding limit, and
        // the rest is not read.
        let input = wgpu::BindingResource::Buffer(wgpu::BufferBinding {
            buffer: velocity,
            offset: 0,
            size: std::num::NonZeroU64::new(n * 8),
        });
        self.record_quantize(encoder, &self.quantize, &self.quantize_layout, input, dt)?;
        self.record_frame(encoder)
    }

    /// [`Self::encode_step`] from a velocity texture the caller owns (e.g. a fluid
    /// simulation's output), recorded into the caller's encoder: nothing goes through the
    /// host. Red and green of mip level 0 are the x and y velocity (output pixels per unit
    /// of time, y down), one texel per output pixel: a 2D texture of the output's size,
    /// one layer, not multisampled, in a float format of two or four channels
    /// (`Rg32Float`, `Rgba32Float`, `Rg16Float`, `Rgba16Float`), with usage
    /// TEXTURE_BINDING, from the same device. The frame is the one [`Self::step`] makes
    /// from the same velocities (tested). Non-finite components count as 0. The checks
    /// run before anything is recorded, as in [`Self::encode_step`].
    pub fn encode_step_texture(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        velocity: &wgpu::Texture,
        dt: f32,
    ) -> Result<()> {
        let ctx = &self.synthesizer.context;
        Self::check_dt(dt)?;
        let (w, h) = (self.params.width, self.params.height);
        let size = velocity.size();
        if velocity.dimension() != wgpu::TextureDimension::D2
            || (size.width, size.height, size.depth_or_array_layers) != (w, h, 1)
        {
            return Err(Error::InvalidParameter(format!(
                "the velocity texture is {:?} of {}x{}x{}; the output needs a 2D texture of \
                 {w}x{h}, one layer (a texel per pixel)",
                velocity.dimension(),
                size.width,
                size.height,
                size.depth_or_array_layers
            )));
        }
        use wgpu::TextureFormat as F;
        if !matches!(
            velocity.format(),
            F::Rg32Float | F::Rgba32Float | F::Rg16Float | F::Rgba16Float
        ) || velocity.sample_count() != 1
        {
            return Err(Error::InvalidParameter(format!(
                "the velocity texture's format is {:?} ({} samples); give Rg32Float, \
                 Rgba32Float, Rg16Float or Rgba16Float, not multisampled (red, green = x, y \
                 velocity in pixels per unit time)",
                velocity.format(),
                velocity.sample_count()
            )));
        }
        if !velocity
            .usage()
            .contains(wgpu::TextureUsages::TEXTURE_BINDING)
        {
            return Err(Error::InvalidParameter(format!(
                "the velocity texture's usage is {:?}; create it with \
                 TextureUsages::TEXTURE_BINDING (a compute shader reads it)",
                velocity.usage()
            )));
        }
        if self.texture_quantize.is_none() {
            let built = ctx.scoped(|| {
                quantize_pipeline(
                    ctx,
                    wgpu::BindingType::Texture {
                        // Not filterable: takes the 32-bit float formats too.
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    shaders::VELOCITY_TEXTURE,
                )
            })?;
            self.texture_quantize = Some(built);
        }
        // A view of mip level 0 in its own error scope: a destroyed texture, or one from
        // another device of this instance, fails here.
        let view = ctx.scoped(|| {
            velocity.create_view(&wgpu::TextureViewDescriptor {
                label: Some("texsyn velocity"),
                base_mip_level: 0,
                mip_level_count: Some(1),
                ..Default::default()
            })
        })?;
        let (pipeline, layout) = self.texture_quantize.as_ref().expect("built above");
        let input = wgpu::BindingResource::TextureView(&view);
        self.record_quantize(encoder, pipeline, layout, input, dt)?;
        self.record_frame(encoder)
    }

    /// Records the quantization of the caller's velocities (`input`, binding 1 of
    /// `layout`) into the advection's velocity buffer. The bind group first, in its own
    /// error scope: an input that is destroyed, invalid or from another device of this
    /// instance fails there, before anything is recorded.
    fn record_quantize(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::ComputePipeline,
        layout: &wgpu::BindGroupLayout,
        input: wgpu::BindingResource,
        dt: f32,
    ) -> Result<()> {
        let ctx = &self.synthesizer.context;
        let n = self.params.width as u64 * self.params.height as u64;
        let group = ctx.scoped(|| {
            let uniform = crate::passes::velocity::VelocityParams {
                count: n as u32,
                dt,
                width: self.params.width,
                _pad: 0,
            };
            let params = crate::gpu::buffer_init(
                &ctx.device,
                &wgpu::util::BufferInitDescriptor {
                    label: Some("texsyn velocity params"),
                    contents: bytemuck::bytes_of(&uniform),
                    usage: wgpu::BufferUsages::UNIFORM,
                },
            );
            ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("texsyn velocity"),
                layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: params.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: input,
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: self.velocity.as_entire_binding(),
                    },
                ],
            })
        })?;
        ctx.scoped(|| {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &group, &[]);
            let groups = (n as u32).div_ceil(64);
            pass.dispatch_workgroups(groups.min(65535), groups.div_ceil(65535), 1);
        })
    }
}

/// The pipeline and bind group layout that quantize a caller's velocities: binding 0
/// the parameters (uniform), 1 the input (`input`: a storage buffer or a texture), 2 the
/// advection's velocity buffer (`shaders/shared/velocity.wgsl`).
pub(super) fn quantize_pipeline(
    ctx: &GpuContext,
    input: wgpu::BindingType,
    shader: shaders::ShaderSource,
) -> (wgpu::ComputePipeline, wgpu::BindGroupLayout) {
    let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty,
        count: None,
    };
    let layout = ctx
        .device
        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("texsyn velocity"),
            entries: &[
                entry(
                    0,
                    wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                ),
                entry(1, input),
                entry(
                    2,
                    wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: false },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                ),
            ],
        });
    let pipeline_layout = ctx
        .device
        .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("texsyn velocity"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
    let module = ctx
        .device
        .create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(shader.file),
            source: wgpu::ShaderSource::Wgsl(shader.source.into()),
        });
    let pipeline = ctx
        .device
        .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("texsyn velocity"),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some(shader.entry_point),
            compilation_options: Default::default(),
            cache: None,
        });
    (pipeline, layout)
}
