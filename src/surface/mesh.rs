//! Triangle meshes for surface synthesis: one flat list of triangles in world space
//! (every glTF primitive with its node transform applied), plus the generated test
//! meshes.

use glam::{Vec2, Vec3, Vec4};

/// A triangle mesh in world space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<Vec3>,
    /// Unit vertex normals (computed, area-weighted, when the source has none).
    pub normals: Vec<Vec3>,
    /// `TEXCOORD_0` in glTF's convention: [0, 1], v pointing down the image.
    pub uvs: Option<Vec<Vec2>>,
    /// glTF `TANGENT`: xyz unit tangent, w = +-1 bitangent sign.
    pub tangents: Option<Vec<Vec4>>,
    pub triangles: Vec<[u32; 3]>,
}

impl Mesh {
    /// Corner positions of triangle `t`.
    pub fn corners(&self, t: usize) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[t];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// Triangle area in world units squared.
    pub fn triangle_area(&self, t: usize) -> f32 {
        let [a, b, c] = self.corners(t);
        0.5 * (b - a).cross(c - a).length()
    }

    pub fn surface_area(&self) -> f64 {
        (0..self.triangles.len())
            .map(|t| self.triangle_area(t) as f64)
            .sum()
    }
}

/// What [`Mesh::validate_and_repair`] changed (documented repairs, reported to the user).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RepairReport {
    /// Triangles dropped: repeated indices or (near) zero area.
    pub dropped_degenerate: usize,
    /// The source had no usable normals; area-weighted vertex normals were computed.
    pub computed_normals: bool,
    /// Edges shared by more than two triangles (kept; treated as boundaries when walking
    /// across charts).
    pub non_manifold_edges: usize,
}
