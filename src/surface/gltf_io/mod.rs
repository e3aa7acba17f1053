//! glTF 2.0 input and output for surface synthesis: [`load_mesh`] reads a `.gltf` (with
//! external or embedded buffers) or a `.glb` into one world-space [`Mesh`];
//! [`write_glb`] writes a textured mesh as a self-contained binary glTF.
//!
//! Loading instantiates every mesh primitive reachable from the default scene (from the
//! root nodes of every scene when there is no default scene, from every parentless node
//! when there are no scenes), with the full node hierarchy applied: positions by the
//! world matrix, normals by its inverse transpose, tangents by its linear part (`w`
//! flipped, and triangle winding reversed, under a mirroring transform, as the glTF
//! specification requires). Skins and morph targets are ignored (the rest pose is used).
//!
//! Documented repairs, counted in [`LoadReport`]: triangle strips and fans become
//! triangle lists; points and lines primitives are skipped (an error when nothing else
//! is left); attributes that only some primitives have (`TEXCOORD_0`, `TANGENT`) are
//! dropped from the merged mesh, and normals are recomputed when any primitive lacks
//! them ([`Mesh::validate_and_repair`]).
//!
//! Every problem in a file is an [`Error::BadMesh`] naming the file and, where it helps,
//! what to do; the parser never panics on bad input: the GLB container, buffer sources
//! and every accessor's byte range are checked before any data is read.

mod buffers;
mod container;
mod primitive;
mod scene;
mod write;

use std::path::Path;

use image::RgbaImage;

use crate::error::{Error, Result};
use crate::surface::mesh::{Mesh, RepairReport};
use buffers::load_buffers;
use container::{parse_document, split_container, GLB_MAGIC};
use scene::assemble;

pub use write::{encode_glb, write_glb};

/// What [`load_mesh`] found and changed.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LoadReport {
    /// Triangle primitives loaded (a mesh instanced by several nodes counts once per
    /// node).
    pub primitives: usize,
    /// Points and lines primitives skipped.
    pub skipped_non_triangle: usize,
    /// Of [`primitives`](Self::primitives), the triangle strips and fans converted to
    /// triangle lists.
    pub converted_strips_fans: usize,
    /// What [`Mesh::validate_and_repair`] changed.
    pub repair: RepairReport,
}

impl LoadReport {
    /// A one-line account of `mesh` as loaded: `(V vertices, T triangles, P
    /// primitive(s)` and what was skipped, dropped or computed, in parentheses.
    pub fn summary(&self, mesh: &Mesh) -> String {
        let mut s = format!(
            "({} vertices, {} triangles, {} primitive(s)",
            mesh.positions.len(),
            mesh.triangles.len(),
            self.primitives
        );
        if self.skipped_non_triangle > 0 {
            s += &format!(
                ", {} non-triangle primitive(s) skipped",
                self.skipped_non_triangle
            );
        }
        if self.repair.dropped_degenerate > 0 {
            s += &format!(
                ", {} degenerate triangles dropped",
                self.repair.dropped_degenerate
            );
        }
        if self.repair.computed_normals {
            s += ", normals computed";
        }
        s + ")"
    }
}

/// Textures to embed as a glTF PBR metallic-roughness material. Each is an RGBA8 image;
/// images whose alpha is 255 everywhere are stored as RGB PNGs.
#[derive(Clone, Debug)]
pub struct MaterialImages {
    /// `baseColorTexture` (sRGB).
    pub base_color: RgbaImage,
    /// `normalTexture`: tangent-space normal map (linear, +Y up as glTF defines it).
    pub normal: Option<RgbaImage>,
    /// `metallicRoughnessTexture`: roughness in G, metalness in B (linear). Without it the
    /// material is a non-metal with roughness 1.
    pub metallic_roughness: Option<RgbaImage>,
    /// `occlusionTexture`: ambient occlusion in R (linear).
    pub occlusion: Option<RgbaImage>,
}

/// Loads every triangle primitive of the default scene (or of all scenes' root nodes if
/// there is no default scene), with node transforms (full hierarchy, matrix or TRS)
/// applied to positions, normals (inverse transpose) and tangents, merged into one mesh
/// and passed through [`Mesh::validate_and_repair`].
///
/// A file that cannot be read is [`Error::Io`]; anything wrong with its content (or with
/// the buffers it references) is [`Error::BadMesh`].
pub fn load_mesh(path: &Path) -> Result<(Mesh, LoadReport)> {
    let bytes = crate::image_io::read_file_capped(
        path,
        crate::image_io::MAX_MESH_FILE_BYTES,
        "mesh files",
    )?;
    let bad = |reason: String| Error::BadMesh {
        path: path.to_path_buf(),
        reason,
    };
    let (json_bytes, bin) = split_container(&bytes).map_err(bad)?;
    let document = parse_document(json_bytes, bytes.starts_with(GLB_MAGIC)).map_err(bad)?;
    let buffers = load_buffers(&document, path, bin).map_err(bad)?;
    let (mut mesh, mut report) = assemble(&document, &buffers).map_err(bad)?;
    report.repair = mesh.validate_and_repair().map_err(|e| match e {
        Error::BadMesh { reason, .. } => bad(reason),
        Error::InvalidParameter(reason) => bad(reason),
        other => other,
    })?;
    Ok((mesh, report))
}
