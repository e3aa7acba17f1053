//! Headless offscreen rendering of a textured mesh into an image (the CLI's
//! `--render views.png`, and tests).
//!
//! The mesh is drawn with wgpu (shader `shaders/render/mesh.wgsl`) into an offscreen
//! target, 4x multisampled, with a 32-bit depth buffer, and read back. Nothing here needs
//! a window or a surface; lavapipe is enough.
//!
//! # Conventions
//!
//! * **uv.** The mesh's `uvs` are the atlas `TEXCOORD_0` in glTF's convention: [0, 1],
//!   v pointing down the image, so atlas texel (i, j) (row j of the row-major atlas) is
//!   centred at `((i + 0.5) / w, (j + 0.5) / h)`. The same convention holds for
//!   [`SurfaceTexture::Magnified`], whose continuous atlas position is `x = uv * (w, h)`
//!   (texel units, texel centres at `i + 0.5`).
//! * **Colour encoding.** texsyn's colours are sRGB-encoded bytes. Every texture and the
//!   target are `Rgba8Unorm`: filtering, mipmapping and lighting operate on the encoded
//!   values, and the output bytes are `round(stored * shade)` (a texel lit at full
//!   strength shows exactly its stored byte). This is not physically correct (shading
//!   should happen on linear values) but keeps the preview faithful to the stored
//!   texture. The output is opaque: alpha is 255 everywhere, the atlas alpha is ignored.
//! * **Lighting.** Lambert with a key directional light fixed in view space (it moves
//!   with the camera, from the upper left, see [`LIGHT_DIRECTION`]) plus an ambient term
//!   [`AMBIENT`]: `shade = AMBIENT + (1 - AMBIENT) * max(0, n . l)` with `n` the
//!   interpolated mesh normal turned towards the viewer (two-sided: open meshes seen
//!   from behind are lit like their front). [`shade`] is the same formula on the CPU.
//! * **Cameras.** [`render_views`] orbits the mesh: azimuths `i * 360 / views` degrees
//!   starting on +Z (glTF's front) and turning towards +X, elevation
//!   [`ORBIT_ELEVATION_DEG`], vertical field of view [`ORBIT_FOV_DEG`], +Y up, looking at
//!   the centre of the mesh's bounding box from the smallest common distance at which
//!   every vertex is in every view (plus a margin).
//!   Near and far planes always come from the bounding sphere of the bounding box.
//! * **Image layout.** Row 0 of the output is the top of the image (camera `up` points
//!   up); views are placed left to right.

mod camera;
mod draw;
mod inputs;

use glam::Vec3;

use super::mesh::Mesh;
use crate::error::{Error, Result};
use crate::gpu::GpuContext;
use draw::render_cameras;

pub use camera::{orbit_cameras, shade};

/// Direction towards the key light in view space (x right, y up, z towards the viewer);
/// normalised before use. It comes from the upper left, in front of the mesh.
pub const LIGHT_DIRECTION: [f32; 3] = [-0.4, 0.5, 1.0];
/// Ambient term: the shade of a surface facing away from the key light.
pub const AMBIENT: f32 = 0.3;
/// Elevation of the [`render_views`] cameras above the centre of the mesh's bounding box.
pub const ORBIT_ELEVATION_DEG: f32 = 20.0;
/// Vertical (and, the views being square, horizontal) field of view of the
/// [`render_views`] cameras.
pub const ORBIT_FOV_DEG: f32 = 35.0;

/// Options of [`render_views`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RenderOptions {
    /// Width and height of each (square) view in pixels.
    pub view_size: u32,
    /// Number of views around the mesh.
    pub views: u32,
    /// Background colour (sRGB-encoded bytes, like the texture).
    pub background: [u8; 3],
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            view_size: 256,
            views: 4,
            background: [64, 64, 64],
        }
    }
}

/// The texture to put on the mesh.
#[derive(Clone, Copy, Debug)]
pub enum SurfaceTexture<'a> {
    /// A colour atlas (RGBA8, row-major, `width * height * 4` bytes), sampled bilinearly
    /// with mipmaps (a box-filtered mip chain built on the CPU; trilinear filtering).
    Color {
        /// The atlas, `width * height * 4` bytes.
        rgba: &'a [u8],
        /// Atlas width in texels.
        width: u32,
        /// Atlas height in texels.
        height: u32,
    },
    /// Magnification in the fragment shader (Lefebvre & Hoppe 2006, section 5), from
    /// synthesized exemplar coordinates over the atlas and a high-resolution exemplar.
    ///
    /// * `coords[j * width + i]`: the synthesized exemplar position S of atlas texel
    ///   (i, j), in pixels of the LOW-resolution exemplar, as a *continuous* position:
    ///   exemplar pixel k covers [k, k + 1) and is centred at k + 0.5. (An integer
    ///   exemplar index k from the synthesis is the position k + 0.5.) Texels outside the
    ///   charts need usable values too, since bilinear blending near chart borders reads
    ///   them.
    /// * `jacobian[j * width + i]`: `[j00, j01, j10, j11]`, d(exemplar) / d(atlas) in
    ///   exemplar pixels per atlas texel, column 0 = derivative along atlas x.
    /// * `hi_rgba`: the high-resolution exemplar (RGBA8, `hi_width * hi_height * 4`
    ///   bytes), `factor` times larger than the low-resolution one (factor = hi width /
    ///   low width). It is treated as tiling.
    ///
    /// The colour at continuous atlas position x (texel units, centres at i + 0.5)
    /// blends the 4 nearest atlas texels q with bilinear weights w_q:
    /// `sum_q w_q * hi(factor * (S[q] + J[q] * (x - centre(q))))`, where `hi(p)` samples
    /// the high-resolution exemplar bilinearly at continuous position p (pixel k centred
    /// at k + 0.5), wrapping around. Near the atlas border the missing neighbours are
    /// replaced by the edge texel (whose S and J then extrapolate). When the view
    /// minifies the exemplar, the mip level follows the gradient `factor * J[q] * dx`.
    Magnified {
        /// Synthesized exemplar position of every atlas texel.
        coords: &'a [[f32; 2]],
        /// d(exemplar) / d(atlas) of every atlas texel.
        jacobian: &'a [[f32; 4]],
        /// Atlas width in texels.
        width: u32,
        /// Atlas height in texels.
        height: u32,
        /// The high-resolution exemplar, `hi_width * hi_height * 4` bytes.
        hi_rgba: &'a [u8],
        /// High-resolution exemplar width in pixels.
        hi_width: u32,
        /// High-resolution exemplar height in pixels.
        hi_height: u32,
        /// High-resolution over low-resolution exemplar width.
        factor: f32,
    },
}

/// A perspective camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Position of the camera.
    pub eye: Vec3,
    /// Point looked at.
    pub target: Vec3,
    /// Up direction of the image.
    pub up: Vec3,
    /// Vertical field of view in degrees (views are square, so also the horizontal one).
    pub fov_y_deg: f32,
}

/// The most views [`render_views`] draws side by side.
pub const MAX_VIEWS: u32 = 16;

/// Render `mesh` textured with `texture` from `opts.views` cameras orbiting it (see
/// [`orbit_cameras`]), into one image of the views side by side
/// (`views * view_size` x `view_size`).
///
/// Errors: [`Error::InvalidParameter`] for a mesh without uvs, without triangles or with
/// inconsistent arrays, for texture data of the wrong length, or for zero sizes;
/// [`Error::TooLarge`] when a texture or the output exceeds the device's
/// `max_texture_dimension_2d`; [`Error::Gpu`] for any wgpu error (validation errors are
/// bugs). The work runs inside [`GpuContext::scoped`], and the context's uncaptured errors
/// are collected afterwards ([`GpuContext::take_uncaptured_errors`]), so an error that
/// escaped an earlier scope on the same context also surfaces here.
pub fn render_views(
    ctx: &GpuContext,
    mesh: &Mesh,
    texture: &SurfaceTexture,
    opts: &RenderOptions,
) -> Result<image::RgbaImage> {
    if !(1..=MAX_VIEWS).contains(&opts.views) {
        return Err(Error::InvalidParameter(format!(
            "render: {} views; give 1 to {MAX_VIEWS}",
            opts.views
        )));
    }
    let cameras = orbit_cameras(mesh, opts.views);
    render_cameras(
        ctx,
        mesh,
        texture,
        &cameras,
        opts.view_size,
        opts.background,
    )
}

/// Render one square view of `size` x `size` pixels with an explicit camera. Errors as
/// for [`render_views`].
pub fn render_view(
    ctx: &GpuContext,
    mesh: &Mesh,
    texture: &SurfaceTexture,
    camera: &Camera,
    size: u32,
    background: [u8; 3],
) -> Result<image::RgbaImage> {
    render_cameras(
        ctx,
        mesh,
        texture,
        std::slice::from_ref(camera),
        size,
        background,
    )
}
