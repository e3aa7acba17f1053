//! [`TangentField`]: building the per-corner field from a [`DirectionSource`] and a
//! [`ScaleSource`], and evaluating the frame at a point of a triangle.

use glam::Vec3;

use super::graph::{constraint_angles, up_angles, Graph};
use super::random::random_corners;
use super::{DirectionSource, ScaleSource, CONSTRAINT_ITERATIONS};
use crate::error::{Error, Result};
use crate::surface::mesh::Mesh;

/// Unit tangent `t` and scale `s` per triangle corner; see the module documentation.
#[derive(Clone, Debug)]
pub struct TangentField {
    corner_t: Vec<[Vec3; 3]>,
    corner_s: Vec<[f32; 3]>,
    symmetry: u32,
    singular: Vec<(u32, f32)>,
}

impl TangentField {
    /// Builds the field for `mesh` (which should have passed
    /// [`Mesh::validate_and_repair`]). `regions`: one id per triangle, used by
    /// [`DirectionSource::RandomPerRegion`] only.
    ///
    /// Errors: a scale that is not finite and > 0, a `PerVertex` list whose length is not
    /// the vertex count, a zero or non-finite vector, `n` not in {1, 2, 4, 6}, an empty
    /// constraint list, `MeshTangents` on a mesh without tangents, a mesh with no
    /// triangles, an index out of range or without one normal per vertex, a `regions`
    /// list whose length is not the triangle count.
    pub fn build(
        mesh: &Mesh,
        regions: Option<&[u32]>,
        dir: &DirectionSource,
        scale: &ScaleSource,
    ) -> Result<TangentField> {
        check_mesh(mesh)?;
        if let Some(r) = regions {
            if r.len() != mesh.triangles.len() {
                return Err(invalid(format!(
                    "{} region ids for {} triangles (need one per triangle)",
                    r.len(),
                    mesh.triangles.len()
                )));
            }
        }
        let vertex_scale = vertex_scales(mesh, scale)?;
        let corner_s: Vec<[f32; 3]> = mesh
            .triangles
            .iter()
            .map(|tri| tri.map(|v| vertex_scale[v as usize]))
            .collect();

        let (corner_t, symmetry, singular) = match dir {
            DirectionSource::Up(up) => {
                let up = check_vector(*up, "up vector")?;
                let g = Graph::new(mesh);
                let theta = up_angles(&g, up);
                let singular = g.singularities(&theta, 1);
                (g.corners_from_angles(mesh, &theta, 1), 1, singular)
            }
            DirectionSource::MeshTangents => {
                let tangents = mesh.tangents.as_ref().ok_or_else(|| {
                    invalid(
                        "direction `tangents`: the mesh has no TANGENT attribute; use \
                         another direction source (e.g. `up`)"
                            .into(),
                    )
                })?;
                if tangents.len() != mesh.positions.len() {
                    return Err(invalid(format!(
                        "mesh has {} tangents for {} vertices",
                        tangents.len(),
                        mesh.positions.len()
                    )));
                }
                let per_vertex: Vec<Option<Vec3>> = tangents
                    .iter()
                    .zip(&mesh.normals)
                    .map(|(t, n)| {
                        let t = t.truncate();
                        let n = n.normalize_or_zero();
                        (t - n * n.dot(t)).try_normalize()
                    })
                    .collect();
                // A few unusable tangents take a fallback below; none usable (all zero,
                // NaN in the file, or along the normals) would be a field of fallbacks.
                if per_vertex.iter().all(|t| t.is_none()) {
                    return Err(invalid(
                        "direction `tangents`: no vertex of the mesh has a usable TANGENT \
                         (every one is zero, not finite, or along its normal); fix the \
                         mesh's tangents or use another direction source (e.g. `up`)"
                            .into(),
                    ));
                }
                let g = Graph::new(mesh);
                // Per welded vertex: its first vertex's tangent (0 = the frame's
                // reference axis where that has none).
                let theta: Vec<f32> = (0..g.count)
                    .map(|p| match per_vertex[g.rep[p] as usize] {
                        Some(t) => g.angle_of(p, t),
                        None => 0.0,
                    })
                    .collect();
                let singular = g.singularities(&theta, 1);
                let corners = mesh
                    .triangles
                    .iter()
                    .enumerate()
                    .map(|(t, tri)| {
                        let n = face_or_vertex_normal(mesh, t);
                        tri.map(|v| {
                            per_vertex[v as usize].unwrap_or_else(|| n.any_orthonormal_vector())
                        })
                    })
                    .collect();
                (corners, 1, singular)
            }
            DirectionSource::Constraints(list) => {
                if list.is_empty() {
                    return Err(invalid(
                        "direction constraints: the list is empty (give at least one \
                         `point, direction` pair)"
                            .into(),
                    ));
                }
                let mut checked = Vec::with_capacity(list.len());
                for (i, &(p, d)) in list.iter().enumerate() {
                    if !p.is_finite() {
                        return Err(invalid(format!(
                            "direction constraint {}: point {p:?} is not finite",
                            i + 1
                        )));
                    }
                    let d = check_vector(d, &format!("direction constraint {} direction", i + 1))?;
                    checked.push((p, d));
                }
                let g = Graph::new(mesh);
                let (mut theta, fixed) = constraint_angles(&g, mesh, &checked);
                g.relax(&mut theta, 1, &fixed, CONSTRAINT_ITERATIONS);
                let singular = g.singularities(&theta, 1);
                (g.corners_from_angles(mesh, &theta, 1), 1, singular)
            }
            DirectionSource::Symmetric { n, up, iterations } => {
                let n = *n;
                if !matches!(n, 1 | 2 | 4 | 6) {
                    return Err(invalid(format!(
                        "symmetric direction field: n = {n}; use 1, 2, 4 or 6"
                    )));
                }
                let up = check_vector(*up, "up vector")?;
                let g = Graph::new(mesh);
                let mut theta = up_angles(&g, up);
                let fixed = vec![false; g.count];
                g.relax(&mut theta, n, &fixed, *iterations);
                let singular = g.singularities(&theta, n);
                (g.corners_from_angles(mesh, &theta, n), n, singular)
            }
            DirectionSource::RandomPerRegion { seed } => {
                let corners = random_corners(mesh, regions, *seed);
                (corners, 1, Vec::new())
            }
        };
        Ok(TangentField {
            corner_t,
            corner_s,
            symmetry,
            singular,
        })
    }

    /// Frame at barycentric point `(w0, w1, w2)` of triangle `t`: the corners' tangents
    /// and scales interpolated, the tangent projected to the triangle's plane and
    /// normalized. Returns `(t, b = t x n_face, s)`, `t` and `b` orthonormal and
    /// perpendicular to the face normal (from the winding; for a degenerate triangle
    /// the mean of its vertex normals). `s` is clamped to the corners' range. Panics
    /// only if `t` is not a triangle of `mesh`.
    pub fn frame(&self, mesh: &Mesh, t: usize, bary: [f32; 3]) -> (Vec3, Vec3, f32) {
        let n = face_or_vertex_normal(mesh, t);
        let ct = &self.corner_t[t];
        let cs = &self.corner_s[t];
        let dir = ct[0] * bary[0] + ct[1] * bary[1] + ct[2] * bary[2];
        let project = |d: Vec3| (d - n * n.dot(d)).try_normalize();
        let tangent = project(dir)
            .or_else(|| ct.iter().find_map(|&c| project(c)))
            .or_else(|| {
                let [a, b, _] = mesh.corners(t);
                project(b - a)
            })
            .unwrap_or_else(|| n.any_orthonormal_vector());
        let s = cs[0] * bary[0] + cs[1] * bary[1] + cs[2] * bary[2];
        let lo = cs[0].min(cs[1]).min(cs[2]);
        let hi = cs[0].max(cs[1]).max(cs[2]);
        let s = if s.is_finite() { s.clamp(lo, hi) } else { lo };
        (tangent, tangent.cross(n), s)
    }

    /// Singular vertices of the field (mesh vertex indices, the first of each welded
    /// position, ascending), for reporting. The field is tested per triangle: around a
    /// singular triangle it turns by a non-zero multiple of 360/n degrees (directions
    /// carried between corners by the minimal rotation between their normals, plus that
    /// transport's holonomy). The triangle's index goes to the corner that disagrees most
    /// with the other two, and indices are summed per vertex (a +1/-1 pair on one vertex
    /// cancels). On a closed mesh the indices add up to the Euler characteristic (2 for a
    /// sphere or cube, 0 for a torus). Always empty for `RandomPerRegion`.
    pub fn singularities(&self) -> Vec<u32> {
        self.singular.iter().map(|&(v, _)| v).collect()
    }

    /// [`Self::singularities`] with their index (a multiple of 1/n: +1 for a source, sink
    /// or vortex, -1 for a saddle, +-1/4 at the corners of a cube's 4-symmetric field).
    pub fn singularity_indices(&self) -> &[(u32, f32)] {
        &self.singular
    }

    /// Rotational symmetry of the field (n of `Symmetric`, 1 otherwise): the directions
    /// `t` rotated by multiples of 360/n degrees are equivalent.
    pub fn symmetry(&self) -> u32 {
        self.symmetry
    }

    /// Unit tangents at the three corners of triangle `t` (combed for n-fold fields).
    pub fn corner_tangents(&self, t: usize) -> [Vec3; 3] {
        self.corner_t[t]
    }

    /// Scales (world units per exemplar texel) at the three corners of triangle `t`.
    pub fn corner_scales(&self, t: usize) -> [f32; 3] {
        self.corner_s[t]
    }

    /// Number of triangles the field covers.
    pub fn triangle_count(&self) -> usize {
        self.corner_t.len()
    }
}

pub(super) fn invalid(msg: String) -> Error {
    Error::InvalidParameter(msg)
}

fn check_vector(v: Vec3, what: &str) -> Result<Vec3> {
    if !v.is_finite() {
        return Err(invalid(format!("{what} {v:?} is not finite")));
    }
    // Scaled first so that huge or tiny (but finite) components normalize too.
    let m = v.abs().max_element();
    (v / m).try_normalize().ok_or_else(|| {
        invalid(if m == 0.0 {
            format!("{what} is zero; give a non-zero vector")
        } else {
            format!("{what} {v:?} cannot be normalized; give components between 1e-30 and 1e30")
        })
    })
}

fn check_scale(s: f32, what: &str) -> Result<f32> {
    if s.is_finite() && s > 0.0 {
        Ok(s)
    } else {
        Err(invalid(format!(
            "{what} is {s}; the scale (world units per exemplar texel) must be a finite \
             number > 0"
        )))
    }
}

fn check_mesh(mesh: &Mesh) -> Result<()> {
    if mesh.triangles.is_empty() {
        return Err(invalid("tangent field: the mesh has no triangles".into()));
    }
    let n = mesh.positions.len();
    if mesh.triangles.iter().flatten().any(|&i| i as usize >= n) {
        return Err(invalid(
            "tangent field: a triangle index is out of range (run Mesh::validate_and_repair first)"
                .into(),
        ));
    }
    if mesh.normals.len() != n {
        return Err(invalid(format!(
            "tangent field: the mesh has {} normals for {n} vertices (run \
             Mesh::validate_and_repair first)",
            mesh.normals.len()
        )));
    }
    if mesh.positions.iter().any(|p| !p.is_finite()) {
        return Err(invalid(
            "tangent field: the mesh has a non-finite position".into(),
        ));
    }
    Ok(())
}

fn vertex_scales(mesh: &Mesh, scale: &ScaleSource) -> Result<Vec<f32>> {
    let n = mesh.positions.len();
    match scale {
        ScaleSource::Constant(s) => Ok(vec![check_scale(*s, "scale")?; n]),
        ScaleSource::PerVertex(list) => {
            if list.len() != n {
                return Err(invalid(format!(
                    "per-vertex scale: {} values for {n} vertices (need one per vertex)",
                    list.len()
                )));
            }
            for (i, &s) in list.iter().enumerate() {
                check_scale(s, &format!("scale of vertex {i}"))?;
            }
            Ok(list.clone())
        }
        ScaleSource::Linear {
            axis,
            at_min,
            at_max,
        } => {
            let axis = check_vector(*axis, "linear scale axis")?;
            let (a, b) = (
                check_scale(*at_min, "linear scale at the low end")?,
                check_scale(*at_max, "linear scale at the high end")?,
            );
            let proj: Vec<f32> = mesh.positions.iter().map(|p| p.dot(axis)).collect();
            let lo = proj.iter().copied().fold(f32::INFINITY, f32::min);
            let hi = proj.iter().copied().fold(f32::NEG_INFINITY, f32::max);
            Ok(proj
                .iter()
                .map(|&x| {
                    if hi > lo {
                        let f = ((x - lo) / (hi - lo)).clamp(0.0, 1.0);
                        a + (b - a) * f
                    } else {
                        a
                    }
                })
                .collect())
        }
    }
}

/// Geometric normal of triangle `t`, or the mean of its vertex normals when it has no
/// area, or +y.
pub(super) fn face_or_vertex_normal(mesh: &Mesh, t: usize) -> Vec3 {
    let n = mesh.face_normal(t);
    if n != Vec3::ZERO {
        return n;
    }
    mesh.triangles[t]
        .iter()
        .filter_map(|&v| mesh.normals.get(v as usize))
        .copied()
        .sum::<Vec3>()
        .normalize_or(Vec3::Y)
}
