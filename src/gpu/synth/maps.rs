//! Material sets: extra exemplar-aligned maps gathered through the synthesized
//! coordinates, read back with the colours and coordinates in one submission.

use super::limits::{fmt_bytes, too_large};
use super::record::MapTarget;
use super::{read_buffer, GpuSynthesizer};
use crate::error::{Error, Result};
use crate::passes::{SynthParams, Synthesis};

/// An exemplar-aligned extra map (normal, height, roughness...) to resynthesize through
/// the same coordinates as the colours.
#[derive(Clone, Debug)]
pub struct ExtraMap {
    /// RGBA8, row-major, the exemplar's size.
    pub pixels: Vec<[u8; 4]>,
    /// Tangent-space normals (x, y in red, green): rotated with the texture along a field.
    pub normal: bool,
    /// For normal maps: green is y *down* the image (the DirectX convention). `false`
    /// (the default): green is y up, the convention of OpenGL, glTF and Blender.
    pub green_down: bool,
}

impl ExtraMap {
    /// `PassParams::map_kind` of this map.
    pub fn map_kind(&self) -> u32 {
        match (self.normal, self.green_down) {
            (false, _) => 0,
            (true, true) => 1,
            (true, false) => 2,
        }
    }
}

impl GpuSynthesizer {
    /// Synthesizes, resynthesizes extra exemplar-aligned maps (material sets) through
    /// the same coordinates, and reads everything back, in one submission. Returns the
    /// synthesis and each map's RGBA8 pixels over the output window.
    pub fn synthesize_with_maps(
        &self,
        params: &SynthParams,
        maps: &[ExtraMap],
    ) -> Result<(Synthesis, Vec<Vec<[u8; 4]>>)> {
        let (s, _, m) = self.synthesize_maps_inner(params, maps, None, None)?;
        Ok((s, m))
    }

    /// Shared by the map syntheses: with `magnify`, the colours (from `hi`) and the maps
    /// (high-resolution, `hi`'s size) are rendered magnified and the magnified colours
    /// are returned too; with `resume = (coords, start)` only the schedule from `start`
    /// runs, on the `coords` its earlier dispatches wrote (the copy guard's probe).
    #[allow(clippy::type_complexity)]
    pub(super) fn synthesize_maps_inner(
        &self,
        params: &SynthParams,
        maps: &[ExtraMap],
        magnify: Option<(&[[u8; 4]], u32, u32, u32)>,
        resume: Option<(&wgpu::Buffer, usize)>,
    ) -> Result<(Synthesis, Option<Vec<[u8; 4]>>, Vec<Vec<[u8; 4]>>)> {
        let ctx = &self.context;
        let a = &self.analysis;
        let (map_w, map_h, f) = match magnify {
            Some((_, hw, hh, f)) => (hw, hh, f),
            None => (a.width, a.height, 1),
        };
        for (i, m) in maps.iter().enumerate() {
            if m.pixels.len() != map_w as usize * map_h as usize {
                return Err(Error::InvalidParameter(format!(
                    "extra map {} has {} pixels; it must have the {}exemplar's size {map_w}x{map_h}",
                    i + 1,
                    m.pixels.len(),
                    if f > 1 { "high-resolution " } else { "" },
                )));
            }
        }
        let plan = self.plan_for(params)?;
        self.check_output(&plan)?;
        let schedule = plan.schedule(&self.analysis);
        let (w, h) = (params.width, params.height);
        let (bw, bh) = (w.saturating_mul(f), h.saturating_mul(f));
        // Everything comes back in one read-back buffer: check it before any work.
        {
            let pitch = |w: u32| (w as u64 * 4).next_multiple_of(256);
            let (_, out_row, out_offset) = plan.output_region();
            let fin = (out_offset[1] + h) as u64 * out_row as u64;
            let count = maps.len() as u64 + magnify.is_some() as u64;
            let need = (pitch(w) * h as u64 + fin * 8).next_multiple_of(256)
                + pitch(bw) * bh as u64 * count;
            let max = ctx.limits().max_buffer_size;
            if need > max {
                return Err(too_large(
                    "output",
                    w,
                    h,
                    format!(
                        "with {count} map(s) its read-back needs {} in one buffer, the device allows {}",
                        fmt_bytes(need),
                        fmt_bytes(max)
                    ),
                    "resynthesize fewer maps at once, or smaller windows (SynthParams::origin)",
                ));
            }
        }
        let texture = ctx.scoped(|| self.output_texture(w, h))?;
        let view = texture.create_view(&Default::default());
        // Sources of the map passes: the high-resolution colours first when magnifying.
        let sources: Vec<(&[[u8; 4]], u32)> = magnify
            .map(|(hi, ..)| (hi, 0))
            .into_iter()
            .chain(maps.iter().map(|m| (&m.pixels[..], m.map_kind())))
            .collect();
        let (map_buffers, map_textures) = ctx.scoped(|| {
            let buffers: Vec<wgpu::Buffer> = sources
                .iter()
                .map(|(pixels, _)| {
                    crate::gpu::buffer_init(
                        &ctx.device,
                        &wgpu::util::BufferInitDescriptor {
                            label: Some("texsyn extra map"),
                            contents: bytemuck::cast_slice(pixels),
                            usage: wgpu::BufferUsages::STORAGE,
                        },
                    )
                })
                .collect::<Vec<_>>();
            let textures: Vec<wgpu::Texture> = sources
                .iter()
                .map(|_| self.output_texture(bw, bh))
                .collect();
            (buffers, textures)
        })?;
        let map_views: Vec<wgpu::TextureView> = map_textures
            .iter()
            .map(|t| t.create_view(&Default::default()))
            .collect();
        let targets: Vec<MapTarget> = sources
            .iter()
            .enumerate()
            .map(|(i, (_, map_kind))| MapTarget {
                colors: &map_buffers[i],
                view: &map_views[i],
                map_kind: *map_kind,
                magnify: f,
                hi_size: if f > 1 {
                    [map_w as i32, map_h as i32]
                } else {
                    [0, 0]
                },
            })
            .collect();
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        let coords = match resume {
            // The rest of a schedule whose first dispatches already ran on `coords`.
            Some((coords, start)) => ctx.scoped(|| {
                self.record_with(
                    &mut encoder,
                    &plan,
                    &schedule[start.min(schedule.len())..],
                    &view,
                    false,
                    &targets,
                    Some((coords, &self.no_velocity)),
                );
                coords.clone()
            })?,
            None => self.record_reporting(&mut encoder, &plan, &schedule, &view, &targets)?,
        };
        // The output's coordinates: the finest level's region, or a torus's resampled
        // output (`SynthPlan::output_region`), whole rows from the window's first.
        let (out_base, out_row, out_offset) = plan.output_region();
        let fin_bytes = (out_offset[1] + h) as u64 * out_row as u64 * 8;
        let pitch =
            |w: u32| (w as u64 * 4).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT as u64);
        let (row, big_row) = (pitch(w), pitch(bw));
        let image_bytes = row * h as u64;
        let big_bytes = big_row * bh as u64;
        let copy_image = |encoder: &mut wgpu::CommandEncoder,
                          t: &wgpu::Texture,
                          rb: &wgpu::Buffer,
                          offset: u64,
                          (w, h, row): (u32, u32, u64)| {
            encoder.copy_texture_to_buffer(
                wgpu::TexelCopyTextureInfo {
                    texture: t,
                    mip_level: 0,
                    origin: wgpu::Origin3d::ZERO,
                    aspect: wgpu::TextureAspect::All,
                },
                wgpu::TexelCopyBufferInfo {
                    buffer: rb,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset,
                        bytes_per_row: Some(row as u32),
                        rows_per_image: Some(h),
                    },
                },
                wgpu::Extent3d {
                    width: w,
                    height: h,
                    depth_or_array_layers: 1,
                },
            );
        };
        // Layout: colour rows, the finest level's coordinates, then each map's rows.
        let maps_offset = (image_bytes + fin_bytes).next_multiple_of(256);
        let readback = ctx.scoped(|| {
            let rb = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("texsyn readback"),
                size: maps_offset + big_bytes * sources.len() as u64,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            copy_image(&mut encoder, &texture, &rb, 0, (w, h, row));
            encoder.copy_buffer_to_buffer(
                &coords,
                out_base as u64 * 8,
                &rb,
                image_bytes,
                fin_bytes,
            );
            for (i, t) in map_textures.iter().enumerate() {
                copy_image(
                    &mut encoder,
                    t,
                    &rb,
                    maps_offset + big_bytes * i as u64,
                    (bw, bh, big_row),
                );
            }
            ctx.queue.submit([encoder.finish()]);
            rb
        })?;
        let bytes = read_buffer(ctx, &readback)?;
        let rows = |offset: usize, w: u32, h: u32, row: u64| {
            let mut out = Vec::with_capacity((w * h) as usize);
            for y in 0..h as usize {
                let r =
                    &bytes[offset + y * row as usize..offset + y * row as usize + w as usize * 4];
                out.extend(r.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]));
            }
            out
        };
        let colors = rows(0, w, h, row);
        let mut map_pixels: Vec<Vec<[u8; 4]>> = (0..sources.len())
            .map(|i| {
                rows(
                    (maps_offset + big_bytes * i as u64) as usize,
                    bw,
                    bh,
                    big_row,
                )
            })
            .collect();
        let big_colors = magnify.map(|_| map_pixels.remove(0));
        let level_coords: &[[i32; 2]] =
            bytemuck::cast_slice(&bytes[image_bytes as usize..(image_bytes + fin_bytes) as usize]);
        let mut window = Vec::with_capacity((w * h) as usize);
        for y in 0..h {
            let start = ((y + out_offset[1]) * out_row + out_offset[0]) as usize;
            window.extend_from_slice(&level_coords[start..start + w as usize]);
        }
        Ok((
            Synthesis {
                width: w,
                height: h,
                coords: window,
                colors,
                coord_frac: if plan.params.anisometric() {
                    crate::passes::common::COORD_FRAC
                } else {
                    0
                },
            },
            big_colors,
            map_pixels,
        ))
    }
}
