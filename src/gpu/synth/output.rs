//! The output texture: its format, its sRGB view, and [`GpuSynthesis`], the handle a
//! synthesis returns while its colours stay on the GPU.

use super::GpuSynthesizer;
use crate::gpu::GpuContext;

/// Format of the synthesized colour texture. It holds the exemplar's bytes as they are,
/// i.e. sRGB-encoded colours for ordinary images; a storage texture cannot have an sRGB
/// format, so view it as [`OUTPUT_FORMAT_SRGB`] ([`GpuSynthesis::srgb_view`]) to have
/// the sampler decode to linear.
pub const OUTPUT_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// The sRGB view format of the output texture (listed in its `view_formats` on every
/// backend but GL, which cannot reinterpret formats).
pub const OUTPUT_FORMAT_SRGB: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

/// A synthesized texture on the GPU.
pub struct GpuSynthesis {
    /// RGBA8 colours (`Rgba8Unorm` holding sRGB-encoded bytes; usages: storage, texture
    /// binding, copy source). Sample it through [`Self::srgb_view`] to get linear colours.
    pub texture: wgpu::Texture,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

/// An sRGB view of a texsyn output texture, for sampling (texture binding only), or
/// `None` on the GL backend (decode in the shader there). See [`GpuSynthesis::srgb_view`].
pub fn srgb_view(ctx: &GpuContext, texture: &wgpu::Texture) -> Option<wgpu::TextureView> {
    ctx.supports_view_formats().then(|| {
        texture.create_view(&wgpu::TextureViewDescriptor {
            label: Some("texsyn output (sRGB)"),
            format: Some(OUTPUT_FORMAT_SRGB),
            usage: Some(wgpu::TextureUsages::TEXTURE_BINDING),
            ..Default::default()
        })
    })
}

impl GpuSynthesis {
    /// A view of the colours as [`OUTPUT_FORMAT_SRGB`], so that sampling in a shader
    /// returns linear values (what lighting and blending need); `None` on the GL
    /// backend, which cannot reinterpret formats (decode in the shader there).
    pub fn srgb_view(&self, ctx: &GpuContext) -> Option<wgpu::TextureView> {
        srgb_view(ctx, &self.texture)
    }
}

impl GpuSynthesizer {
    /// A blank output texture of [`OUTPUT_FORMAT`] (storage, texture binding, copy
    /// source), viewable as [`OUTPUT_FORMAT_SRGB`] where the backend allows.
    pub(crate) fn output_texture(&self, width: u32, height: u32) -> wgpu::Texture {
        let ctx = &self.context;
        ctx.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("texsyn output"),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: OUTPUT_FORMAT,
            usage: wgpu::TextureUsages::STORAGE_BINDING
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
            view_formats: if ctx.supports_view_formats() {
                &[OUTPUT_FORMAT_SRGB]
            } else {
                &[]
            },
        })
    }
}
