//! The result of a surface synthesis: the material images, the textured glTF and
//! renders of it.

use std::path::Path;
use std::time::{Duration, Instant};

use image::RgbaImage;

use super::SurfaceSession;
use crate::error::{Error, Result};
use crate::passes::Synthesis;
use crate::surface::gltf_io::{self, MaterialImages};
use crate::surface::pipeline;
use crate::surface::render::{self, RenderOptions, SurfaceTexture};
use crate::surface::seams::{self, SeamReport};
use crate::surface::Mesh;

/// A mesh textured by [`SurfaceSession::run`]: its material images (the colour atlas and
/// any synthesized maps), ready to encode as a binary glTF or render.
pub struct TexturedSurface<'s> {
    session: &'s SurfaceSession,
    synthesis: Synthesis,
    material: MaterialImages,
    seams: SeamReport,
    synthesis_time: Duration,
}

impl SurfaceSession {
    /// Synthesizes the texture in the atlas (and the material maps in the same
    /// coordinates; magnified if asked) and reads it back. Gutter texels hold the
    /// texture continued across the chart seams.
    pub fn run(&self) -> Result<TexturedSurface<'_>> {
        let t = Instant::now();
        let extra: Vec<_> = self.maps.iter().flatten().cloned().collect();
        let n = self.prepared.atlas.size;
        // One synthesis: magnification returns the atlas synthesis too (for the seam
        // figures and the render), with the magnified colours and maps.
        let (synthesis, colors, maps, (width, height)) = match &self.magnified {
            Some(hi) => {
                let params = pipeline::atlas_params(&self.prepared, &self.params);
                let m = self.synthesizer.synthesize_magnified_with_maps(
                    &params, &hi.pixels, hi.width, hi.height, hi.factor, &extra,
                )?;
                (m.synthesis, m.colors, m.maps, (m.width, m.height))
            }
            None => {
                let (s, maps) =
                    pipeline::synthesize(&self.synthesizer, &self.prepared, &self.params, &extra)?;
                let colors = s.colors.clone();
                (s, colors, maps, (n, n))
            }
        };
        self.context.take_uncaptured_errors()?;
        let synthesis_time = t.elapsed();
        let seams = seams::seam_report(&self.prepared.atlas, &synthesis.colors);

        let to_image = |px: Vec<u8>| {
            RgbaImage::from_raw(width, height, px)
                .ok_or_else(|| Error::InvalidParameter("internal: image size mismatch".into()))
        };
        let base_color = to_image(colors.into_iter().flatten().collect())?;
        // The synthesized maps, in the order of `self.maps`' present entries.
        let mut synthesized = maps.into_iter();
        let mut next_map = |present: bool, pack: &dyn Fn([u8; 4]) -> [u8; 4]| {
            if !present {
                return Ok(None);
            }
            let m = synthesized
                .next()
                .ok_or_else(|| Error::InvalidParameter("internal: missing material map".into()))?;
            to_image(m.into_iter().flat_map(pack).collect()).map(Some)
        };
        // glTF normal textures have green up: a green-down map (rotated in its own
        // convention) has its green flipped.
        let green_down = self.maps[0].as_ref().is_some_and(|m| m.green_down);
        let normal = next_map(self.maps[0].is_some(), &|p| {
            if green_down {
                [p[0], 255 - p[1], p[2], p[3]]
            } else {
                p
            }
        })?;
        // glTF packs roughness in green (metallic in blue, 0 here), occlusion in red.
        let metallic_roughness = next_map(self.maps[1].is_some(), &|p| [0, p[0], 0, 255])?;
        let occlusion = next_map(self.maps[2].is_some(), &|p| [p[0], p[0], p[0], 255])?;
        Ok(TexturedSurface {
            session: self,
            synthesis,
            material: MaterialImages {
                base_color,
                normal,
                metallic_roughness,
                occlusion,
            },
            seams,
            synthesis_time,
        })
    }
}

impl TexturedSurface<'_> {
    /// The texture: the colour atlas (magnified: that many times larger).
    pub fn atlas_image(&self) -> &RgbaImage {
        &self.material.base_color
    }

    /// Every image of the material (colour, and the normal, metallic-roughness and
    /// occlusion textures synthesized from the maps given).
    pub fn material(&self) -> &MaterialImages {
        &self.material
    }

    /// The mesh with its atlas uvs.
    pub fn mesh(&self) -> &Mesh {
        self.session.mesh()
    }

    /// The synthesis in the atlas (at the atlas's size also when magnified): exemplar
    /// coordinates and colours per texel.
    pub fn synthesis(&self) -> &Synthesis {
        &self.synthesis
    }

    /// How visible the chart seams are in the atlas.
    pub fn seams(&self) -> &SeamReport {
        &self.seams
    }

    /// Time of the synthesis and its read-back.
    pub fn synthesis_time(&self) -> Duration {
        self.synthesis_time
    }

    /// The binary glTF: the geometry, the atlas uvs and the material.
    pub fn glb(&self) -> Result<Vec<u8>> {
        gltf_io::encode_glb(self.mesh(), &self.material)
    }

    /// Writes [`Self::glb`] to `path`, atomically.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<()> {
        crate::image_io::write_files_atomic(&[(path.as_ref(), &self.glb()?)])
    }

    /// Writes the glTF to `glb`, and the atlas image (PNG, or another format by
    /// extension) and a `render` made earlier where paths are given, all or nothing:
    /// every file is encoded and written to a temporary file before any is renamed over
    /// its target, so files that existed before stay as they were if any step fails.
    pub fn save_all(
        &self,
        glb: &Path,
        atlas_image: Option<&Path>,
        render: Option<(&Path, &RgbaImage)>,
    ) -> Result<()> {
        use crate::image_io::{encode_image, write_files_atomic};
        let encode = |path: &Path, img: &RgbaImage| {
            encode_image(path, img.width(), img.height(), 4, img.as_raw())
        };
        let mut files: Vec<(&Path, Vec<u8>)> = Vec::new();
        if let Some((path, img)) = render {
            files.push((path, encode(path, img)?));
        }
        if let Some(path) = atlas_image {
            files.push((path, encode(path, self.atlas_image())?));
        }
        files.push((glb, self.glb()?));
        write_files_atomic(&files.iter().map(|(p, b)| (*p, &b[..])).collect::<Vec<_>>())
    }

    /// Renders the textured mesh from `options.views` views orbiting it, side by side;
    /// a magnified texture is magnified per pixel in the fragment shader.
    pub fn render(&self, options: &RenderOptions) -> Result<RgbaImage> {
        let session = self.session;
        let n = session.prepared.atlas.size;
        let coords: Vec<[f32; 2]>;
        let jacobians: Vec<[f32; 4]>;
        let texture = match &session.magnified {
            Some(hi) => {
                // Integer exemplar positions are pixel centres in the synthesis.
                coords = self
                    .synthesis
                    .coords_f32()
                    .iter()
                    .map(|c| [c[0] + 0.5, c[1] + 0.5])
                    .collect();
                jacobians = pipeline::jacobians_f32(&session.prepared);
                SurfaceTexture::Magnified {
                    coords: &coords,
                    jacobian: &jacobians,
                    width: n,
                    height: n,
                    hi_rgba: bytemuck::cast_slice(&hi.pixels),
                    hi_width: hi.width,
                    hi_height: hi.height,
                    factor: hi.factor as f32,
                }
            }
            None => SurfaceTexture::Color {
                rgba: self.material.base_color.as_raw(),
                width: self.material.base_color.width(),
                height: self.material.base_color.height(),
            },
        };
        render::render_views(&session.context, self.mesh(), &texture, options)
    }
}
