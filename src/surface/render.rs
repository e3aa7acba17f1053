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

use glam::{Mat4, Vec3, Vec4};

use super::mesh::Mesh;
use crate::error::{Error, Result};
use crate::gpu::shaders::render::MESH as MESH_SHADER;
use crate::gpu::synth::read_mapped;
use crate::gpu::GpuContext;

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

/// MSAA sample count of the offscreen target (resolved before read-back).
const SAMPLES: u32 = 4;
const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

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
        rgba: &'a [u8],
        width: u32,
        height: u32,
    },
    /// Magnification in the fragment shader (paper section 5), from synthesized exemplar
    /// coordinates over the atlas and a high-resolution exemplar.
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
        coords: &'a [[f32; 2]],
        jacobian: &'a [[f32; 4]],
        width: u32,
        height: u32,
        hi_rgba: &'a [u8],
        hi_width: u32,
        hi_height: u32,
        factor: f32,
    },
}

/// A perspective camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: Vec3,
    pub target: Vec3,
    pub up: Vec3,
    /// Vertical field of view in degrees (views are square, so also the horizontal one).
    pub fov_y_deg: f32,
}

/// The bounding sphere of the mesh's bounding box: (centre, radius).
fn bounding_sphere(mesh: &Mesh) -> (Vec3, f32) {
    let mut min = Vec3::splat(f32::INFINITY);
    let mut max = Vec3::splat(f32::NEG_INFINITY);
    for p in &mesh.positions {
        min = min.min(*p);
        max = max.max(*p);
    }
    if !min.is_finite() || !max.is_finite() {
        return (Vec3::ZERO, 1.0);
    }
    let centre = 0.5 * (min + max);
    let radius = 0.5 * (max - min).length();
    (
        centre,
        radius.max(1e-6 * centre.length()).max(f32::MIN_POSITIVE),
    )
}

/// The cameras [`render_views`] uses: `views` cameras orbiting the mesh (see the module
/// documentation), all at the same distance from the centre of its bounding box: the
/// smallest at which every vertex is inside every view, plus a 5% margin.
pub fn orbit_cameras(mesh: &Mesh, views: u32) -> Vec<Camera> {
    let (centre, radius) = bounding_sphere(mesh);
    let tan = (ORBIT_FOV_DEG * 0.5).to_radians().tan() / 1.05;
    let elevation = ORBIT_ELEVATION_DEG.to_radians();
    let directions: Vec<Vec3> = (0..views)
        .map(|i| {
            let azimuth = (i as f32 * 360.0 / views as f32).to_radians();
            Vec3::new(
                elevation.cos() * azimuth.sin(),
                elevation.sin(),
                elevation.cos() * azimuth.cos(),
            )
        })
        .collect();
    // Vertex p (offset o from the centre) is in the view from centre + d * dir when
    // |o . right| and |o . up| <= tan * (d - o . dir).
    let mut distance = radius * 1e-3;
    for dir in &directions {
        let right = (-*dir).cross(Vec3::Y).normalize_or(Vec3::X);
        let up = right.cross(-*dir);
        for p in &mesh.positions {
            let o = *p - centre;
            let lateral = o.dot(right).abs().max(o.dot(up).abs());
            distance = distance.max(o.dot(*dir) + lateral / tan);
        }
    }
    if !distance.is_finite() {
        distance = radius / tan;
    }
    directions
        .iter()
        .map(|dir| Camera {
            eye: centre + distance * *dir,
            target: centre,
            up: Vec3::Y,
            fov_y_deg: ORBIT_FOV_DEG,
        })
        .collect()
}

/// The shade factor the renderer applies to a texel's colour, for a unit normal in view
/// space already turned towards the viewer: `AMBIENT + (1 - AMBIENT) * max(0, n . l)`.
pub fn shade(view_normal: Vec3) -> f32 {
    let l = Vec3::from(LIGHT_DIRECTION).normalize();
    AMBIENT + (1.0 - AMBIENT) * view_normal.dot(l).max(0.0)
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

/// Uniform block `Params` of mesh.wgsl.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    mode: u32,
    factor: f32,
    atlas_size: [f32; 2],
    hi_size: [f32; 2],
    _pad: [f32; 2],
}

/// Uniform block `View` of mesh.wgsl.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct ViewUniform {
    view_proj: [[f32; 4]; 4],
    view: [[f32; 4]; 4],
    light: [f32; 4],
}

/// One interleaved vertex: position, normal, uv.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Vertex {
    position: [f32; 3],
    normal: [f32; 3],
    uv: [f32; 2],
}

/// Magnified mode's per-texel maps: (coords, jacobian, width, height).
type Maps<'a> = (&'a [[f32; 2]], &'a [[f32; 4]], u32, u32);

/// Host-side texture data, checked, ready to upload.
struct TextureData<'a> {
    params: Params,
    /// Mip chain of the sampled texture (colour atlas or high-resolution exemplar).
    mips: Vec<(u32, u32, Vec<u8>)>,
    /// Magnified mode: the coordinate and Jacobian maps.
    maps: Option<Maps<'a>>,
    /// Repeat (exemplar) or clamp (atlas).
    repeat: bool,
}

fn too_large(what: &'static str, width: u32, height: u32, max: u32) -> Error {
    Error::TooLarge {
        what,
        width,
        height,
        limit: format!("max_texture_dimension_2d = {max}"),
        // Only the input that sets this size helps.
        hint: match what {
            "rendered image" => "use fewer --views or a smaller --view-size",
            "high-resolution exemplar" => "use a smaller --magnify or a smaller exemplar",
            _ => "use a smaller --atlas-size",
        },
    }
}

fn check_size(what: &'static str, width: u32, height: u32, max: u32) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(Error::InvalidParameter(format!(
            "render: {what} is {width}x{height}; it must not be empty"
        )));
    }
    if width > max || height > max {
        return Err(too_large(what, width, height, max));
    }
    Ok(())
}

fn check_len(what: &str, len: usize, width: u32, height: u32, per_texel: &str) -> Result<()> {
    let expected = width as u64 * height as u64;
    if len as u64 != expected {
        return Err(Error::InvalidParameter(format!(
            "render: {what} has {len} {per_texel}, expected {width}x{height} = {expected}"
        )));
    }
    Ok(())
}

fn check_texture<'a>(texture: &SurfaceTexture<'a>, max: u32) -> Result<TextureData<'a>> {
    match *texture {
        SurfaceTexture::Color {
            rgba,
            width,
            height,
        } => {
            check_size("colour atlas", width, height, max)?;
            if rgba.len() as u64 != width as u64 * height as u64 * 4 {
                return Err(Error::InvalidParameter(format!(
                    "render: colour atlas has {} bytes, expected {width}x{height}x4 = {}",
                    rgba.len(),
                    width as u64 * height as u64 * 4
                )));
            }
            Ok(TextureData {
                params: Params {
                    mode: 0,
                    factor: 1.0,
                    atlas_size: [width as f32, height as f32],
                    hi_size: [width as f32, height as f32],
                    _pad: [0.0; 2],
                },
                mips: mip_chain(rgba, width, height),
                maps: None,
                repeat: false,
            })
        }
        SurfaceTexture::Magnified {
            coords,
            jacobian,
            width,
            height,
            hi_rgba,
            hi_width,
            hi_height,
            factor,
        } => {
            check_size("coordinate atlas", width, height, max)?;
            check_size("high-resolution exemplar", hi_width, hi_height, max)?;
            check_len("coords", coords.len(), width, height, "entries")?;
            check_len("jacobian", jacobian.len(), width, height, "entries")?;
            if hi_rgba.len() as u64 != hi_width as u64 * hi_height as u64 * 4 {
                return Err(Error::InvalidParameter(format!(
                    "render: high-resolution exemplar has {} bytes, expected \
                     {hi_width}x{hi_height}x4 = {}",
                    hi_rgba.len(),
                    hi_width as u64 * hi_height as u64 * 4
                )));
            }
            if !(factor.is_finite() && factor > 0.0) {
                return Err(Error::InvalidParameter(format!(
                    "render: magnification factor {factor} must be positive"
                )));
            }
            Ok(TextureData {
                params: Params {
                    mode: 1,
                    factor,
                    atlas_size: [width as f32, height as f32],
                    hi_size: [hi_width as f32, hi_height as f32],
                    _pad: [0.0; 2],
                },
                mips: mip_chain(hi_rgba, hi_width, hi_height),
                maps: Some((coords, jacobian, width, height)),
                repeat: true,
            })
        }
    }
}

/// Box-filtered mip chain, level 0 first (a copy of `rgba`) down to 1x1. Each texel of
/// level n + 1 averages the 2x2 texels (2i..2i+1, 2j..2j+1) of level n, clamped to its
/// size (on encoded values, rounded to nearest).
fn mip_chain(rgba: &[u8], width: u32, height: u32) -> Vec<(u32, u32, Vec<u8>)> {
    let mut levels = vec![(width, height, rgba.to_vec())];
    while let Some((w, h, src)) = levels.last().filter(|(w, h, _)| *w > 1 || *h > 1) {
        let (w, h) = (*w as usize, *h as usize);
        let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
        let mut dst = vec![0u8; nw * nh * 4];
        for y in 0..nh {
            let (y0, y1) = ((2 * y).min(h - 1), (2 * y + 1).min(h - 1));
            for x in 0..nw {
                let (x0, x1) = ((2 * x).min(w - 1), (2 * x + 1).min(w - 1));
                for c in 0..4 {
                    let s = src[(y0 * w + x0) * 4 + c] as u32
                        + src[(y0 * w + x1) * 4 + c] as u32
                        + src[(y1 * w + x0) * 4 + c] as u32
                        + src[(y1 * w + x1) * 4 + c] as u32;
                    dst[(y * nw + x) * 4 + c] = ((s + 2) / 4) as u8;
                }
            }
        }
        levels.push((nw as u32, nh as u32, dst));
    }
    levels
}

/// Check the mesh and build its interleaved vertices.
fn mesh_vertices(mesh: &Mesh) -> Result<Vec<Vertex>> {
    let Some(uvs) = &mesh.uvs else {
        return Err(Error::InvalidParameter(
            "render: the mesh has no texture coordinates (TEXCOORD_0); build or load an \
             atlas parameterization first"
                .into(),
        ));
    };
    let n = mesh.positions.len();
    if uvs.len() != n {
        return Err(Error::InvalidParameter(format!(
            "render: the mesh has {n} positions but {} uvs",
            uvs.len()
        )));
    }
    if mesh.triangles.is_empty() {
        return Err(Error::InvalidParameter(
            "render: the mesh has no triangles".into(),
        ));
    }
    if let Some(t) = mesh
        .triangles
        .iter()
        .find(|t| t.iter().any(|&i| i as usize >= n))
    {
        return Err(Error::InvalidParameter(format!(
            "render: triangle {t:?} indexes a vertex past the {n} positions"
        )));
    }
    if mesh.positions.iter().any(|p| !p.is_finite()) {
        return Err(Error::InvalidParameter(
            "render: the mesh has non-finite positions".into(),
        ));
    }
    let normals = if mesh.normals.len() == n {
        mesh.normals.clone()
    } else {
        // Not expected (Mesh computes normals), but a preview should still work.
        let mut normals = vec![Vec3::ZERO; n];
        for t in 0..mesh.triangles.len() {
            let [a, b, c] = mesh.corners(t);
            let area_normal = (b - a).cross(c - a);
            for &i in &mesh.triangles[t] {
                normals[i as usize] += area_normal;
            }
        }
        normals.iter().map(|v| v.normalize_or_zero()).collect()
    };
    Ok((0..n)
        .map(|i| Vertex {
            position: mesh.positions[i].to_array(),
            normal: normals[i].to_array(),
            uv: uvs[i].to_array(),
        })
        .collect())
}

/// View uniforms of `camera` for a mesh with bounding sphere (centre, radius).
fn view_uniform(camera: &Camera, centre: Vec3, radius: f32) -> Result<ViewUniform> {
    let forward = camera.target - camera.eye;
    let fov_ok = camera.fov_y_deg.is_finite() && camera.fov_y_deg > 0.0 && camera.fov_y_deg < 180.0;
    if !fov_ok
        || !camera.eye.is_finite()
        || forward.length_squared() == 0.0
        || !forward.is_finite()
        || forward.cross(camera.up).length_squared() == 0.0
    {
        return Err(Error::InvalidParameter(format!(
            "render: invalid camera {camera:?} (eye and target must differ, up must not be \
             parallel to the view direction, fov in (0, 180) degrees)"
        )));
    }
    let view = Mat4::look_at_rh(camera.eye, camera.target, camera.up);
    // Depth range from the bounding sphere, along the view direction.
    let ahead = (centre - camera.eye).dot(forward.normalize());
    let far = (ahead + radius * 1.01).max(radius * 1e-3);
    let near = (ahead - radius * 1.01).max(far * 1e-4);
    let proj = Mat4::perspective_rh(camera.fov_y_deg.to_radians(), 1.0, near, far);
    let l = Vec3::from(LIGHT_DIRECTION).normalize();
    Ok(ViewUniform {
        view_proj: (proj * view).to_cols_array_2d(),
        view: view.to_cols_array_2d(),
        light: Vec4::new(l.x, l.y, l.z, AMBIENT).to_array(),
    })
}

fn render_cameras(
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mip_chain_halves_down_to_one_texel() {
        let rgba: Vec<u8> = (0..5 * 3 * 4).map(|i| (i * 3) as u8).collect();
        let chain = mip_chain(&rgba, 5, 3);
        let sizes: Vec<(u32, u32)> = chain.iter().map(|(w, h, _)| (*w, *h)).collect();
        assert_eq!(sizes, vec![(5, 3), (2, 1), (1, 1)]);
        for (w, h, bytes) in &chain {
            assert_eq!(bytes.len(), (*w * *h * 4) as usize);
        }
        // Level 1, texel 0: texels (0,0), (1,0), (0,1), (1,1) of level 0.
        let avg = |c: usize| {
            let t = |x: usize, y: usize| rgba[(y * 5 + x) * 4 + c] as u32;
            ((t(0, 0) + t(1, 0) + t(0, 1) + t(1, 1) + 2) / 4) as u8
        };
        assert_eq!(chain[1].2[0], avg(0));
        assert_eq!(chain[1].2[3], avg(3));
    }

    #[test]
    fn orbit_cameras_look_at_the_centre_from_the_same_distance() {
        let mesh = Mesh {
            positions: vec![Vec3::new(-1.0, 0.0, -2.0), Vec3::new(3.0, 2.0, 0.0)],
            ..Mesh::default()
        };
        let cams = orbit_cameras(&mesh, 4);
        assert_eq!(cams.len(), 4);
        let centre = Vec3::new(1.0, 1.0, -1.0);
        let d0 = (cams[0].eye - centre).length();
        for c in &cams {
            assert!((c.target - centre).length() < 1e-5);
            assert!(((c.eye - centre).length() - d0).abs() < 1e-4);
            assert!(c.eye.y > centre.y, "slight elevation");
        }
        // First view from +Z (glTF front), second from +X.
        assert!(cams[0].eye.z > centre.z && (cams[0].eye.x - centre.x).abs() < 1e-4);
        assert!(cams[1].eye.x > centre.x);
    }

    #[test]
    fn shade_is_one_facing_the_light() {
        let l = Vec3::from(LIGHT_DIRECTION).normalize();
        assert!((shade(l) - 1.0).abs() < 1e-6);
        assert!((shade(-l) - AMBIENT).abs() < 1e-6);
    }
}
