//! Host-side render inputs: the shader's uniform and vertex layouts, and the mesh and
//! texture data checked against the device's limits and prepared for upload.

use glam::Vec3;

use super::SurfaceTexture;
use crate::error::{Error, Result};
use crate::surface::mesh::Mesh;

/// Uniform block `Params` of mesh.wgsl.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct Params {
    pub(super) mode: u32,
    pub(super) factor: f32,
    pub(super) atlas_size: [f32; 2],
    pub(super) hi_size: [f32; 2],
    pub(super) _pad: [f32; 2],
}

/// Uniform block `View` of mesh.wgsl.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct ViewUniform {
    pub(super) view_proj: [[f32; 4]; 4],
    pub(super) view: [[f32; 4]; 4],
    pub(super) light: [f32; 4],
}

/// One interleaved vertex: position, normal, uv.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct Vertex {
    pub(super) position: [f32; 3],
    pub(super) normal: [f32; 3],
    pub(super) uv: [f32; 2],
}

/// Magnified mode's per-texel maps: (coords, jacobian, width, height).
pub(super) type Maps<'a> = (&'a [[f32; 2]], &'a [[f32; 4]], u32, u32);

/// Host-side texture data, checked, ready to upload.
pub(super) struct TextureData<'a> {
    pub(super) params: Params,
    /// Mip chain of the sampled texture (colour atlas or high-resolution exemplar).
    pub(super) mips: Vec<(u32, u32, Vec<u8>)>,
    /// Magnified mode: the coordinate and Jacobian maps.
    pub(super) maps: Option<Maps<'a>>,
    /// Repeat (exemplar) or clamp (atlas).
    pub(super) repeat: bool,
}

pub(super) fn too_large(what: &'static str, width: u32, height: u32, max: u32) -> Error {
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

pub(super) fn check_size(what: &'static str, width: u32, height: u32, max: u32) -> Result<()> {
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

pub(super) fn check_len(
    what: &str,
    len: usize,
    width: u32,
    height: u32,
    per_texel: &str,
) -> Result<()> {
    let expected = width as u64 * height as u64;
    if len as u64 != expected {
        return Err(Error::InvalidParameter(format!(
            "render: {what} has {len} {per_texel}, expected {width}x{height} = {expected}"
        )));
    }
    Ok(())
}

pub(super) fn check_texture<'a>(texture: &SurfaceTexture<'a>, max: u32) -> Result<TextureData<'a>> {
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
pub(super) fn mip_chain(rgba: &[u8], width: u32, height: u32) -> Vec<(u32, u32, Vec<u8>)> {
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
pub(super) fn mesh_vertices(mesh: &Mesh) -> Result<Vec<Vertex>> {
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
}
