//! Writing a textured mesh as a self-contained binary glTF (`.glb`).

use std::collections::BTreeMap;
use std::path::Path;

use glam::{Vec2, Vec3, Vec4};
use gltf::json;
use image::{ImageEncoder, RgbaImage};

use super::container::{CHUNK_BIN, CHUNK_JSON, GLB_MAGIC};
use super::MaterialImages;
use crate::error::{Error, Result};
use crate::surface::mesh::Mesh;

/// Writes a binary glTF (.glb): one mesh with one primitive (POSITION with min/max,
/// NORMAL, TEXCOORD_0, TANGENT when there are tangents (below), u32 indices), one node,
/// one scene, and a PBR material whose textures are `material`'s images, embedded as PNG
/// in buffer views and sampled with LINEAR_MIPMAP_LINEAR / LINEAR filtering and
/// CLAMP_TO_EDGE wrapping.
///
/// `mesh.uvs` must be `Some` and every attribute must have one entry per position.
/// Normals and tangents are written normalized (a zero normal becomes +Z, a zero tangent
/// +X; tangent `w` becomes +-1), as glTF requires. TANGENT is written when the mesh has
/// tangents, or when there is a normal map: then it is computed from the uvs (direction
/// of increasing u; the bitangent `cross(normal, tangent) * w` points up the image), so
/// that viewers do not each generate their own tangent frame.
///
/// The file is written to a temporary file in the same directory and renamed over
/// `path`: `path` never holds a partial file.
///
/// Errors: [`Error::InvalidParameter`] for an unusable mesh or image (nothing is written),
/// [`Error::Write`] when the file cannot be written.
pub fn write_glb(path: &Path, mesh: &Mesh, material: &MaterialImages) -> Result<()> {
    let bytes = encode_glb(mesh, material)?;
    crate::image_io::write_files_atomic(&[(path, &bytes)])
}

fn invalid(msg: String) -> Error {
    Error::InvalidParameter(format!("write_glb: {msg}"))
}

/// The binary glTF of `mesh` and `material`, in memory (what [`write_glb`] writes).
pub fn encode_glb(mesh: &Mesh, material: &MaterialImages) -> Result<Vec<u8>> {
    use json::validation::{Checked::Valid, USize64};

    let n = mesh.positions.len();
    if n == 0 || mesh.triangles.is_empty() {
        return Err(invalid("the mesh is empty".into()));
    }
    if u32::try_from(n).is_err() {
        return Err(invalid(format!("{n} vertices, more than 2^32")));
    }
    let Some(uvs) = mesh.uvs.as_ref() else {
        return Err(invalid(
            "the mesh has no texture coordinates (uvs); generate an atlas first".into(),
        ));
    };
    let check_len = |len: usize, what: &str| {
        if len == n {
            Ok(())
        } else {
            Err(invalid(format!(
                "the mesh has {len} {what} for {n} positions (run validate_and_repair first)"
            )))
        }
    };
    check_len(mesh.normals.len(), "normals")?;
    check_len(uvs.len(), "uvs")?;
    if let Some(t) = &mesh.tangents {
        check_len(t.len(), "tangents")?;
    }
    if let Some(k) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return Err(invalid(format!("position {k} is not finite")));
    }
    if let Some(k) = uvs.iter().position(|p| !p.is_finite()) {
        return Err(invalid(format!("uv {k} is not finite")));
    }
    if let Some((t, _)) = mesh
        .triangles
        .iter()
        .enumerate()
        .find(|(_, t)| t.iter().any(|&i| i as usize >= n))
    {
        return Err(invalid(format!(
            "triangle {t} has a vertex index out of range ({n} vertices)"
        )));
    }

    let mut root = json::Root {
        asset: json::Asset {
            generator: Some(format!("texsyn {}", env!("CARGO_PKG_VERSION"))),
            ..Default::default()
        },
        ..Default::default()
    };
    let buffer_index = json::Index::<json::Buffer>::new(0);
    let mut bin: Vec<u8> = Vec::new();

    // Appends `bytes` as a buffer view (4-byte aligned, so every accessor is aligned).
    let add_view = |root: &mut json::Root,
                    bin: &mut Vec<u8>,
                    bytes: &[u8],
                    target: Option<json::buffer::Target>| {
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let offset = bin.len();
        bin.extend_from_slice(bytes);
        root.push(json::buffer::View {
            buffer: buffer_index,
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            name: None,
            target: target.map(Valid),
            extensions: None,
            extras: Default::default(),
        })
    };
    let accessor = |view, count: usize, ct, ty, min, max| json::Accessor {
        buffer_view: Some(view),
        byte_offset: None,
        count: USize64::from(count),
        component_type: Valid(json::accessor::GenericComponentType(ct)),
        extensions: None,
        extras: Default::default(),
        type_: Valid(ty),
        min,
        max,
        name: None,
        normalized: false,
        sparse: None,
    };
    let floats =
        |v: &mut dyn Iterator<Item = f32>| -> Vec<u8> { v.flat_map(f32::to_le_bytes).collect() };
    use json::accessor::{ComponentType, Type};
    use json::buffer::Target;

    // Attributes.
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for &p in &mesh.positions {
        lo = lo.min(p);
        hi = hi.max(p);
    }
    let view = add_view(
        &mut root,
        &mut bin,
        &floats(&mut mesh.positions.iter().flat_map(|p| p.to_array())),
        Some(Target::ArrayBuffer),
    );
    let position = root.push(accessor(
        view,
        n,
        ComponentType::F32,
        Type::Vec3,
        Some(json::Value::from(lo.to_array().to_vec())),
        Some(json::Value::from(hi.to_array().to_vec())),
    ));
    let unit_normal = |v: Vec3| match v.try_normalize() {
        Some(u) => u,
        None => Vec3::Z,
    };
    let normals: Vec<Vec3> = mesh.normals.iter().map(|&v| unit_normal(v)).collect();
    let view = add_view(
        &mut root,
        &mut bin,
        &floats(&mut normals.iter().flat_map(|v| v.to_array())),
        Some(Target::ArrayBuffer),
    );
    let normal = root.push(accessor(
        view,
        n,
        ComponentType::F32,
        Type::Vec3,
        None,
        None,
    ));
    let view = add_view(
        &mut root,
        &mut bin,
        &floats(&mut uvs.iter().flat_map(|v| v.to_array())),
        Some(Target::ArrayBuffer),
    );
    let texcoord = root.push(accessor(
        view,
        n,
        ComponentType::F32,
        Type::Vec2,
        None,
        None,
    ));
    // A normal map needs a tangent frame; without one in the mesh, viewers would each
    // generate their own. Write the frame the uvs define instead (see `uv_tangents`).
    let tangents: Option<Vec<Vec4>> = match (&mesh.tangents, &material.normal) {
        (Some(t), _) => Some(
            t.iter()
                .map(|t| {
                    let xyz = t.truncate().try_normalize().unwrap_or(Vec3::X);
                    xyz.extend(if t.w < 0.0 { -1.0 } else { 1.0 })
                })
                .collect(),
        ),
        (None, Some(_)) => Some(uv_tangents(&mesh.positions, &normals, uvs, &mesh.triangles)),
        (None, None) => None,
    };
    let tangent = match &tangents {
        Some(t) => {
            let view = add_view(
                &mut root,
                &mut bin,
                &floats(&mut t.iter().flat_map(|t| t.to_array())),
                Some(Target::ArrayBuffer),
            );
            Some(root.push(accessor(
                view,
                n,
                ComponentType::F32,
                Type::Vec4,
                None,
                None,
            )))
        }
        None => None,
    };
    let index_bytes: Vec<u8> = mesh
        .triangles
        .iter()
        .flatten()
        .flat_map(|i| i.to_le_bytes())
        .collect();
    let view = add_view(
        &mut root,
        &mut bin,
        &index_bytes,
        Some(Target::ElementArrayBuffer),
    );
    let indices = root.push(accessor(
        view,
        mesh.triangles.len() * 3,
        ComponentType::U32,
        Type::Scalar,
        None,
        None,
    ));

    // Textures: one sampler, one PNG image and texture each.
    let sampler = root.push(json::texture::Sampler {
        mag_filter: Some(Valid(json::texture::MagFilter::Linear)),
        min_filter: Some(Valid(json::texture::MinFilter::LinearMipmapLinear)),
        wrap_s: Valid(json::texture::WrappingMode::ClampToEdge),
        wrap_t: Valid(json::texture::WrappingMode::ClampToEdge),
        ..Default::default()
    });
    let add_texture = |root: &mut json::Root,
                       bin: &mut Vec<u8>,
                       img: &RgbaImage,
                       name: &str|
     -> Result<json::Index<json::Texture>> {
        let png = encode_png(img, name)?;
        let view = add_view(root, bin, &png, None);
        let image = root.push(json::Image {
            buffer_view: Some(view),
            mime_type: Some(json::image::MimeType("image/png".into())),
            name: Some(name.into()),
            uri: None,
            extensions: None,
            extras: Default::default(),
        });
        Ok(root.push(json::Texture {
            name: Some(name.into()),
            sampler: Some(sampler),
            source: image,
            extensions: None,
            extras: Default::default(),
        }))
    };
    let info = |index| json::texture::Info {
        index,
        tex_coord: 0,
        extensions: None,
        extras: Default::default(),
    };
    let base_color = add_texture(&mut root, &mut bin, &material.base_color, "base_color")?;
    let metallic_roughness = match &material.metallic_roughness {
        Some(img) => Some(add_texture(&mut root, &mut bin, img, "metallic_roughness")?),
        None => None,
    };
    let normal_texture = match &material.normal {
        Some(img) => Some(json::material::NormalTexture {
            index: add_texture(&mut root, &mut bin, img, "normal")?,
            scale: 1.0,
            tex_coord: 0,
            extensions: None,
            extras: Default::default(),
        }),
        None => None,
    };
    let occlusion_texture = match &material.occlusion {
        Some(img) => Some(json::material::OcclusionTexture {
            index: add_texture(&mut root, &mut bin, img, "occlusion")?,
            strength: json::material::StrengthFactor(1.0),
            tex_coord: 0,
            extensions: None,
            extras: Default::default(),
        }),
        None => None,
    };
    let material_index = root.push(json::Material {
        name: Some("texsyn".into()),
        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
            base_color_texture: Some(info(base_color)),
            // Without a metallic-roughness texture: a rough dielectric.
            metallic_factor: json::material::StrengthFactor(if metallic_roughness.is_some() {
                1.0
            } else {
                0.0
            }),
            roughness_factor: json::material::StrengthFactor(1.0),
            metallic_roughness_texture: metallic_roughness.map(info),
            ..Default::default()
        },
        normal_texture,
        occlusion_texture,
        ..Default::default()
    });

    // Mesh, node, scene.
    let mut attributes = BTreeMap::new();
    attributes.insert(Valid(json::mesh::Semantic::Positions), position);
    attributes.insert(Valid(json::mesh::Semantic::Normals), normal);
    attributes.insert(Valid(json::mesh::Semantic::TexCoords(0)), texcoord);
    if let Some(t) = tangent {
        attributes.insert(Valid(json::mesh::Semantic::Tangents), t);
    }
    let mesh_index = root.push(json::Mesh {
        extensions: None,
        extras: Default::default(),
        name: Some("texsyn".into()),
        primitives: vec![json::mesh::Primitive {
            attributes,
            extensions: None,
            extras: Default::default(),
            indices: Some(indices),
            material: Some(material_index),
            mode: Valid(json::mesh::Mode::Triangles),
            targets: None,
        }],
        weights: None,
    });
    let node = root.push(json::Node {
        mesh: Some(mesh_index),
        name: Some("texsyn".into()),
        ..Default::default()
    });
    let scene = root.push(json::Scene {
        extensions: None,
        extras: Default::default(),
        name: None,
        nodes: vec![node],
    });
    root.scene = Some(scene);

    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    root.push(json::Buffer {
        byte_length: USize64::from(bin.len()),
        name: None,
        uri: None,
        extensions: None,
        extras: Default::default(),
    });

    let mut json_bytes = json::serialize::to_vec(&root)
        .map_err(|e| invalid(format!("cannot serialize the glTF JSON: {e}")))?;
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    let total = 12 + 8 + json_bytes.len() + 8 + bin.len();
    let Ok(total32) = u32::try_from(total) else {
        return Err(invalid(format!(
            "the file would be {total} bytes; binary glTF is limited to 4 GiB (use smaller \
             textures)"
        )));
    };
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(GLB_MAGIC);
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&total32.to_le_bytes());
    out.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_JSON.to_le_bytes());
    out.extend_from_slice(&json_bytes);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_BIN.to_le_bytes());
    out.extend_from_slice(&bin);
    Ok(out)
}

/// Per-vertex tangents from the uv parameterization, for meshes written with a normal
/// map but without tangents: `xyz` is the direction of increasing u (area-weighted over
/// the vertex's triangles, made orthogonal to the unit `normals`), and `w` makes
/// `cross(normal, xyz) * w` point up the image (decreasing v, glTF's convention for the
/// green channel of normal maps). Vertices without a usable uv gradient get an arbitrary
/// tangent perpendicular to the normal.
fn uv_tangents(
    positions: &[Vec3],
    normals: &[Vec3],
    uvs: &[Vec2],
    triangles: &[[u32; 3]],
) -> Vec<Vec4> {
    let mut du = vec![Vec3::ZERO; positions.len()];
    let mut dv = vec![Vec3::ZERO; positions.len()];
    for &[a, b, c] in triangles {
        let (a, b, c) = (a as usize, b as usize, c as usize);
        let (e1, e2) = (positions[b] - positions[a], positions[c] - positions[a]);
        let (t1, t2) = (uvs[b] - uvs[a], uvs[c] - uvs[a]);
        let r = t1.x * t2.y - t2.x * t1.y;
        let area = e1.cross(e2).length();
        if r.abs() < 1e-20 || area == 0.0 {
            continue;
        }
        // dP/du and dP/dv of the triangle, normalized, weighted by its area.
        let su = ((e1 * t2.y - e2 * t1.y) / r).normalize_or_zero() * area;
        let sv = ((e2 * t1.x - e1 * t2.x) / r).normalize_or_zero() * area;
        for v in [a, b, c] {
            du[v] += su;
            dv[v] += sv;
        }
    }
    normals
        .iter()
        .zip(du.iter().zip(&dv))
        .map(|(&n, (&u, &v))| {
            let t = (u - n * n.dot(u))
                .try_normalize()
                .unwrap_or_else(|| n.any_orthonormal_vector());
            let w = if n.cross(t).dot(-v) < 0.0 { -1.0 } else { 1.0 };
            t.extend(w)
        })
        .collect()
}

/// PNG bytes of `img`: RGB when it is opaque everywhere, RGBA otherwise.
fn encode_png(img: &RgbaImage, what: &str) -> Result<Vec<u8>> {
    let (w, h) = img.dimensions();
    if w == 0 || h == 0 {
        return Err(invalid(format!("the {what} image is empty ({w}x{h})")));
    }
    let mut out = Vec::new();
    let encoder = image::codecs::png::PngEncoder::new(&mut out);
    let result = if img.pixels().all(|p| p[3] == 255) {
        let rgb: Vec<u8> = img.pixels().flat_map(|p| [p[0], p[1], p[2]]).collect();
        encoder.write_image(&rgb, w, h, image::ExtendedColorType::Rgb8)
    } else {
        encoder.write_image(img.as_raw(), w, h, image::ExtendedColorType::Rgba8)
    };
    result.map_err(|e| invalid(format!("cannot encode the {what} image as PNG: {e}")))?;
    Ok(out)
}
