//! The GPU pass: uploads the mesh and textures, draws every view into a multisampled
//! offscreen target, resolves it and reads the image back.

use super::camera::{bounding_sphere, view_uniform};
use super::inputs::{check_texture, mesh_vertices, too_large, Vertex};
use super::{Camera, SurfaceTexture};
use crate::error::{Error, Result};
use crate::gpu::shaders::render::MESH as MESH_SHADER;
use crate::gpu::synth::read_mapped;
use crate::gpu::GpuContext;
use crate::surface::mesh::Mesh;

/// MSAA sample count of the offscreen target (resolved before read-back).
const SAMPLES: u32 = 4;
const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

pub(super) fn render_cameras(
    ctx: &GpuContext,
    mesh: &Mesh,
    texture: &SurfaceTexture,
    cameras: &[Camera],
    size: u32,
    background: [u8; 3],
) -> Result<image::RgbaImage> {
    let limits = ctx.limits();
    let max = limits.max_texture_dimension_2d;
    let vertices = mesh_vertices(mesh)?;
    let data = check_texture(texture, max)?;
    let views = u32::try_from(cameras.len()).unwrap_or(u32::MAX);
    if size == 0 || views == 0 {
        return Err(Error::InvalidParameter(format!(
            "render: {views} views of {size}x{size} pixels: nothing to render"
        )));
    }
    let width = views.saturating_mul(size);
    if width > max || size > max {
        return Err(too_large("rendered image", width, size, max));
    }
    let row_bytes = (width as u64 * 4).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT as u64);
    let (vertex_bytes, index_bytes) = (
        std::mem::size_of_val(vertices.as_slice()) as u64,
        mesh.triangles.len() as u64 * 12,
    );
    for (what, bytes) in [
        ("read-back buffer", row_bytes * size as u64),
        ("vertex buffer", vertex_bytes),
        ("index buffer", index_bytes),
    ] {
        if bytes > limits.max_buffer_size {
            return Err(Error::TooLarge {
                what: "rendered image or mesh",
                width,
                height: size,
                limit: format!(
                    "{what} of {bytes} bytes > max_buffer_size = {}",
                    limits.max_buffer_size
                ),
                hint: "render smaller views or fewer of them, or a smaller mesh",
            });
        }
    }
    let (centre, radius) = bounding_sphere(mesh);
    let view_uniforms = cameras
        .iter()
        .map(|c| view_uniform(c, centre, radius))
        .collect::<Result<Vec<_>>>()?;

    let device = &ctx.device;
    let queue = &ctx.queue;
    let readback = ctx.scoped(|| {
        let texture_2d = |label: &str, w: u32, h: u32, mips: u32, format: wgpu::TextureFormat| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width: w,
                    height: h,
                    depth_or_array_layers: 1,
                },
                mip_level_count: mips,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            })
        };
        let upload = |t: &wgpu::Texture, mip: u32, w: u32, h: u32, bytes: &[u8], texel: u32| {
            queue.write_texture(
                wgpu::TexelCopyTextureInfo {
                    texture: t,
                    mip_level: mip,
                    origin: wgpu::Origin3d::ZERO,
                    aspect: wgpu::TextureAspect::All,
                },
                bytes,
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(w * texel),
                    rows_per_image: Some(h),
                },
                wgpu::Extent3d {
                    width: w,
                    height: h,
                    depth_or_array_layers: 1,
                },
            );
        };

        // The sampled texture with its mip chain.
        let (w0, h0, _) = &data.mips[0];
        let color = texture_2d(
            "texsyn render texture",
            *w0,
            *h0,
            data.mips.len() as u32,
            COLOR_FORMAT,
        );
        for (level, (w, h, bytes)) in data.mips.iter().enumerate() {
            upload(&color, level as u32, *w, *h, bytes, 4);
        }
        // Coordinates and Jacobians (1x1 placeholders in colour mode).
        let (coords, jac) = match data.maps {
            Some((coords, jacobian, w, h)) => {
                let c = texture_2d(
                    "texsyn render coords",
                    w,
                    h,
                    1,
                    wgpu::TextureFormat::Rg32Float,
                );
                upload(&c, 0, w, h, bytemuck::cast_slice(coords), 8);
                let j = texture_2d(
                    "texsyn render jacobian",
                    w,
                    h,
                    1,
                    wgpu::TextureFormat::Rgba32Float,
                );
                upload(&j, 0, w, h, bytemuck::cast_slice(jacobian), 16);
                (c, j)
            }
            None => {
                let c = texture_2d(
                    "texsyn render coords",
                    1,
                    1,
                    1,
                    wgpu::TextureFormat::Rg32Float,
                );
                upload(&c, 0, 1, 1, &[0u8; 8], 8);
                let j = texture_2d(
                    "texsyn render jacobian",
                    1,
                    1,
                    1,
                    wgpu::TextureFormat::Rgba32Float,
                );
                upload(&j, 0, 1, 1, &[0u8; 16], 16);
                (c, j)
            }
        };
        let address = if data.repeat {
            wgpu::AddressMode::Repeat
        } else {
            wgpu::AddressMode::ClampToEdge
        };
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("texsyn render sampler"),
            address_mode_u: address,
            address_mode_v: address,
            address_mode_w: address,
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            mipmap_filter: wgpu::MipmapFilterMode::Linear,
            ..Default::default()
        });
        let params = crate::gpu::buffer_init(
            device,
            &wgpu::util::BufferInitDescriptor {
                label: Some("texsyn render params"),
                contents: bytemuck::bytes_of(&data.params),
                usage: wgpu::BufferUsages::UNIFORM,
            },
        );

        let texture_entry = |binding: u32, filterable: bool| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable },
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: false,
            },
            count: None,
        };
        let uniform_entry =
            |binding: u32, visibility: wgpu::ShaderStages| wgpu::BindGroupLayoutEntry {
                binding,
                visibility,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            };
        let layout0 = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("texsyn render texture"),
            entries: &[
                uniform_entry(0, wgpu::ShaderStages::FRAGMENT),
                texture_entry(1, true),
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
                texture_entry(3, false),
                texture_entry(4, false),
            ],
        });
        let layout1 = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("texsyn render view"),
            entries: &[uniform_entry(
                0,
                wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT,
            )],
        });
        let view_of = |t: &wgpu::Texture| t.create_view(&wgpu::TextureViewDescriptor::default());
        let (color_view, coords_view, jac_view) =
            (view_of(&color), view_of(&coords), view_of(&jac));
        let group0 = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("texsyn render texture"),
            layout: &layout0,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: params.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&color_view),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::Sampler(&sampler),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: wgpu::BindingResource::TextureView(&coords_view),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: wgpu::BindingResource::TextureView(&jac_view),
                },
            ],
        });
        let view_groups: Vec<wgpu::BindGroup> = view_uniforms
            .iter()
            .map(|u| {
                let buffer = crate::gpu::buffer_init(
                    device,
                    &wgpu::util::BufferInitDescriptor {
                        label: Some("texsyn render view"),
                        contents: bytemuck::bytes_of(u),
                        usage: wgpu::BufferUsages::UNIFORM,
                    },
                );
                device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("texsyn render view"),
                    layout: &layout1,
                    entries: &[wgpu::BindGroupEntry {
                        binding: 0,
                        resource: buffer.as_entire_binding(),
                    }],
                })
            })
            .collect();

        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(MESH_SHADER.file),
            source: wgpu::ShaderSource::Wgsl(MESH_SHADER.source.into()),
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("texsyn render"),
            bind_group_layouts: &[Some(&layout0), Some(&layout1)],
            immediate_size: 0,
        });
        let attributes = [
            wgpu::VertexAttribute {
                format: wgpu::VertexFormat::Float32x3,
                offset: 0,
                shader_location: 0,
            },
            wgpu::VertexAttribute {
                format: wgpu::VertexFormat::Float32x3,
                offset: 12,
                shader_location: 1,
            },
            wgpu::VertexAttribute {
                format: wgpu::VertexFormat::Float32x2,
                offset: 24,
                shader_location: 2,
            },
        ];
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(MESH_SHADER.name),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some(MESH_SHADER.vertex_entry),
                compilation_options: Default::default(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: std::mem::size_of::<Vertex>() as u64,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &attributes,
                })],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                strip_index_format: None,
                front_face: wgpu::FrontFace::Ccw,
                // Open meshes and inconsistent windings are common: draw both sides.
                cull_mode: None,
                unclipped_depth: false,
                polygon_mode: wgpu::PolygonMode::Fill,
                conservative: false,
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: wgpu::StencilState::default(),
                bias: wgpu::DepthBiasState::default(),
            }),
            multisample: wgpu::MultisampleState {
                count: SAMPLES,
                mask: !0,
                alpha_to_coverage_enabled: false,
            },
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some(MESH_SHADER.fragment_entry),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState::from(COLOR_FORMAT))],
            }),
            multiview_mask: None,
            cache: None,
        });

        let vertex_buffer = crate::gpu::buffer_init(
            device,
            &wgpu::util::BufferInitDescriptor {
                label: Some("texsyn render vertices"),
                contents: bytemuck::cast_slice(&vertices),
                usage: wgpu::BufferUsages::VERTEX,
            },
        );
        let index_buffer = crate::gpu::buffer_init(
            device,
            &wgpu::util::BufferInitDescriptor {
                label: Some("texsyn render indices"),
                contents: bytemuck::cast_slice(&mesh.triangles),
                usage: wgpu::BufferUsages::INDEX,
            },
        );

        let target = |label: &str, format, samples, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width,
                    height: size,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: samples,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let msaa = target(
            "texsyn render msaa",
            COLOR_FORMAT,
            SAMPLES,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        let resolved = target(
            "texsyn render resolved",
            COLOR_FORMAT,
            1,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        );
        let depth = target(
            "texsyn render depth",
            DEPTH_FORMAT,
            SAMPLES,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        let (msaa_view, resolved_view, depth_view) =
            (view_of(&msaa), view_of(&resolved), view_of(&depth));

        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("texsyn render"),
        });
        {
            let [r, g, b] = background.map(|c| c as f64 / 255.0);
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("texsyn render"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &msaa_view,
                    depth_slice: None,
                    resolve_target: Some(&resolved_view),
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color { r, g, b, a: 1.0 }),
                        store: wgpu::StoreOp::Discard,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &depth_view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &group0, &[]);
            pass.set_vertex_buffer(0, vertex_buffer.slice(..));
            pass.set_index_buffer(index_buffer.slice(..), wgpu::IndexFormat::Uint32);
            let index_count = mesh.triangles.len() as u32 * 3;
            for (i, group) in view_groups.iter().enumerate() {
                let x = i as u32 * size;
                pass.set_viewport(x as f32, 0.0, size as f32, size as f32, 0.0, 1.0);
                pass.set_scissor_rect(x, 0, size, size);
                pass.set_bind_group(1, group, &[]);
                pass.draw_indexed(0..index_count, 0, 0..1);
            }
        }
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("texsyn render readback"),
            size: row_bytes * size as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        encoder.copy_texture_to_buffer(
            resolved.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(row_bytes as u32),
                    rows_per_image: Some(size),
                },
            },
            resolved.size(),
        );
        queue.submit([encoder.finish()]);
        readback
    })?;

    let bytes = read_mapped(
        &readback,
        || ctx.wait_idle(),
        "render: buffer mapping was cancelled",
        "render: reading back the image",
    )?;
    ctx.take_uncaptured_errors()?;
    let mut out = Vec::with_capacity(width as usize * size as usize * 4);
    for y in 0..size as usize {
        let start = y * row_bytes as usize;
        out.extend_from_slice(&bytes[start..start + width as usize * 4]);
    }
    image::RgbaImage::from_raw(width, size, out)
        .ok_or_else(|| Error::Gpu("render: read-back has the wrong size".into()))
}
