//! Tangent fields: where the exemplar's axes go on the surface, and at what scale.
//!
//! Surface synthesis (paper section 6) needs, at every surface point, a tangent frame
//! `F = [t*s, b*s]`: `t` is the surface direction that the exemplar's +x axis follows,
//! `b = t x n` the direction of the exemplar's +y axis (image y points down, so with
//! this choice the texture is not mirrored when seen from outside, from the side the
//! normal points to), and `s` the size of one exemplar texel in world units.
//!
//! A [`TangentField`] stores one unit tangent and one scale per triangle corner, not per
//! vertex: an n-fold symmetric field can then be "combed" per triangle (each corner takes
//! the representative, among its n rotations, closest to corner 0's, so interpolation
//! inside the triangle is smooth) and a random field can change abruptly between
//! regions. [`TangentField::frame`] interpolates them at any point of a triangle.
//!
//! The direction sources ([`DirectionSource`]) work on the mesh's vertices welded by
//! exact position (glTF meshes split vertices at uv seams; [`Mesh::cube`] has one set of
//! vertices per face), with one area-weighted normal per welded vertex, so the field is
//! continuous across seams and chart boundaries.

use std::collections::HashMap;
use std::f32::consts::TAU;
use std::fmt;
use std::path::Path;
use std::str::FromStr;

use glam::{Quat, Vec3};

use super::mesh::Mesh;
use crate::error::{Error, Result};

/// Relaxation iterations of `symmetric:N` when the CLI string does not give them.
pub const DEFAULT_SYMMETRIC_ITERATIONS: u32 = 200;

/// Upper limit of the CLI's `symmetric:N:X,Y,Z:ITERATIONS` (each iteration visits every
/// face; more only costs time).
pub const MAX_SYMMETRIC_ITERATIONS: u32 = 100_000;

/// Relaxation iterations after the inverse-distance blend of [`DirectionSource::Constraints`].
pub const CONSTRAINT_ITERATIONS: u32 = 10;

/// Normals closer than this angle (degrees) to the seed triangle's belong to one region
/// of [`DirectionSource::RandomPerRegion`] when no regions are given.
pub const REGION_ANGLE_DEGREES: f32 = 30.0;

/// Help for the CLI's direction option (the syntax of [`DirectionSource::from_str`]).
pub const DIRECTION_HELP: &str = "\
where the exemplar's axes go on the surface:
  up                  the exemplar's up (-y) follows world +y projected to the surface (= up:0,1,0);
                      singular where the surface faces straight up or down
  up:X,Y,Z            the same with another world up vector
  tangents            the x axis follows the mesh's own glTF TANGENT attribute
  symmetric:N[:X,Y,Z[:ITERATIONS]]
                      smooth N-fold symmetric field (N = 1, 2, 4 or 6), relaxed from up:X,Y,Z
                      (default 0,1,0) for ITERATIONS iterations (default 200); for textures that
                      look the same rotated by 360/N degrees
  random[:SEED]       isotropic textures: a random direction per chart (or per group of
                      triangles facing within 30 degrees of each other), SEED default 0
  constraints:FILE    the x axis follows user directions: FILE has lines `px py pz dx dy dz`
                      (a surface point and a direction, world units; '#' starts a comment),
                      blended with inverse-distance-squared weights and smoothed";

/// Help for the CLI's scale option (the syntax of [`ScaleSource::from_str`]).
pub const SCALE_HELP: &str = "\
world units per exemplar texel:
  S                   the same everywhere (a number > 0)
  linear:X,Y,Z:S0:S1  varies linearly along the axis X,Y,Z over the mesh's extent: S0 at the
                      low end, S1 at the high end";

/// Where the exemplar's x axis (the field's `t`) goes on the surface.
#[derive(Clone, Debug, PartialEq)]
pub enum DirectionSource {
    /// Automatic smooth field: the exemplar's "up" (-y, so `b = -up`) follows `up`
    /// projected to each tangent plane, and `t = up_projected x n`. Singular where the
    /// normal is parallel to `up` (the poles of a sphere around `up`): there (projection
    /// shorter than 1e-4 of `up`) the fallback axis is used instead, the world axis (x,
    /// y or z, first on ties) least aligned with `up`.
    Up(Vec3),
    /// The mesh's own glTF TANGENT attribute (xyz projected to the vertex normal's
    /// plane; the bitangent sign w is ignored: the texture is never mirrored). An error
    /// if the mesh has no tangents.
    MeshTangents,
    /// User constraints `(surface point, direction)`, world space; the direction is
    /// where the exemplar's +x axis (`t`) goes. Every welded vertex gets the constraint
    /// directions projected to its tangent plane and blended with inverse
    /// distance-squared weights; then [`CONSTRAINT_ITERATIONS`] relaxation iterations
    /// (as in `Symmetric` with n = 1) smooth the field, keeping fixed the vertex nearest
    /// to each constraint point (with that constraint's projected direction).
    Constraints(Vec<(Vec3, Vec3)>),
    /// For textures with n-fold rotational symmetry (n = 1, 2, 4 or 6; Wei & Levoy 2001,
    /// section 3.1): start from `Up(up)` and relax as an n-RoSy field. Each welded vertex
    /// stores its direction as an angle in a local tangent frame, represented by the
    /// complex number exp(i*n*angle); an iteration replaces it (Gauss-Seidel, vertices
    /// in index order) by the average of itself and its neighbours, each neighbour's
    /// frame carried over by the minimal rotation between the two normals. In the first
    /// half of the iterations the averages keep their magnitude (a power iteration
    /// towards the smoothest field, through which singularities can move and cancel), in
    /// the second half they are renormalized to unit length. Singularities end up where
    /// the topology forces them (on large meshes this needs many iterations; the cost is
    /// about 10 ns per vertex and neighbour per iteration).
    Symmetric { n: u32, up: Vec3, iterations: u32 },
    /// Isotropic textures: one random direction per region, from `seed` and the region
    /// id. Regions are the per-triangle ids given to [`TangentField::build`] (chart ids)
    /// or, when none are given, groups grown from the lowest unassigned triangle across
    /// edges to triangles whose normal is within [`REGION_ANGLE_DEGREES`] of the seed
    /// triangle's. The direction lies in the plane of the region's mean normal and is
    /// projected to each triangle.
    RandomPerRegion { seed: u32 },
}

/// Size of one exemplar texel on the surface, in world units.
#[derive(Clone, Debug, PartialEq)]
pub enum ScaleSource {
    /// World units per exemplar texel, everywhere.
    Constant(f32),
    /// One value per mesh vertex.
    PerVertex(Vec<f32>),
    /// Varies linearly with position along `axis` between the mesh's extent along it:
    /// `at_min` at the low end, `at_max` at the high end (`at_min` everywhere if the
    /// mesh has no extent along `axis`).
    Linear {
        axis: Vec3,
        at_min: f32,
        at_max: f32,
    },
}

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

fn invalid(msg: String) -> Error {
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
fn face_or_vertex_normal(mesh: &Mesh, t: usize) -> Vec3 {
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

/// `x` wrapped to `(-period/2, period/2]`.
fn wrap(x: f32, period: f32) -> f32 {
    let y = x - period * (x / period).round();
    if y <= -0.5 * period {
        y + period
    } else {
        y
    }
}

/// Welded vertices ("nodes") with normals, local frames and neighbours.
struct Graph {
    /// Node of each mesh vertex.
    id: Vec<u32>,
    count: usize,
    /// First mesh vertex of each node.
    rep: Vec<u32>,
    pos: Vec<Vec3>,
    normal: Vec<Vec3>,
    /// Reference tangent `e` of each node's frame (`f = n x e`); angles are measured
    /// counter-clockwise about `n` from `e`.
    e: Vec<Vec3>,
    used: Vec<bool>,
    /// Per node p: neighbours q with the angle `rho` such that a direction at angle `a`
    /// in q's frame, carried to p by the minimal rotation between the normals, has angle
    /// `a + rho` in p's frame.
    nbrs: Vec<Vec<(u32, f32)>>,
    /// Triangles as node triples.
    tris: Vec<[u32; 3]>,
}

impl Graph {
    fn new(mesh: &Mesh) -> Graph {
        let (id, count) = mesh.welded_vertex_ids();
        let mut rep = vec![u32::MAX; count];
        let mut pos = vec![Vec3::ZERO; count];
        for (v, &i) in id.iter().enumerate() {
            if rep[i as usize] == u32::MAX {
                rep[i as usize] = v as u32;
                pos[i as usize] = mesh.positions[v];
            }
        }
        let tris: Vec<[u32; 3]> = mesh
            .triangles
            .iter()
            .map(|tri| tri.map(|v| id[v as usize]))
            .collect();
        let mut sum = vec![Vec3::ZERO; count];
        let mut used = vec![false; count];
        let mut adj: Vec<Vec<u32>> = vec![Vec::new(); count];
        for (t, tri) in tris.iter().enumerate() {
            let [a, b, c] = mesh.corners(t);
            let cross = (b - a).cross(c - a);
            for i in 0..3 {
                let p = tri[i] as usize;
                used[p] = true;
                sum[p] += cross;
                for q in [tri[(i + 1) % 3], tri[(i + 2) % 3]] {
                    if q as usize != p {
                        adj[p].push(q);
                    }
                }
            }
        }
        let normal: Vec<Vec3> = (0..count)
            .map(|p| {
                sum[p]
                    .try_normalize()
                    .or_else(|| mesh.normals[rep[p] as usize].try_normalize())
                    .unwrap_or(Vec3::Y)
            })
            .collect();
        let e: Vec<Vec3> = normal.iter().map(|n| n.any_orthonormal_vector()).collect();
        let mut g = Graph {
            id,
            count,
            rep,
            pos,
            normal,
            e,
            used,
            nbrs: Vec::new(),
            tris,
        };
        g.nbrs = adj
            .into_iter()
            .enumerate()
            .map(|(p, mut list)| {
                list.sort_unstable();
                list.dedup();
                list.into_iter()
                    .map(|q| (q, g.transport(q as usize, p)))
                    .collect()
            })
            .collect();
        g
    }

    fn f(&self, p: usize) -> Vec3 {
        self.normal[p].cross(self.e[p])
    }

    fn angle_of(&self, p: usize, d: Vec3) -> f32 {
        d.dot(self.f(p)).atan2(d.dot(self.e[p]))
    }

    fn dir_of(&self, p: usize, a: f32) -> Vec3 {
        self.e[p] * a.cos() + self.f(p) * a.sin()
    }

    /// `rho` of carrying q's frame to p (see `nbrs`).
    fn transport(&self, q: usize, p: usize) -> f32 {
        let r = Quat::from_rotation_arc(self.normal[q], self.normal[p]);
        self.angle_of(p, r * self.e[q])
    }

    /// Gauss-Seidel relaxation of an n-RoSy field given as angles.
    fn relax(&self, theta: &mut [f32], n: u32, fixed: &[bool], iterations: u32) {
        if iterations == 0 {
            return;
        }
        let nf = n as f32;
        // Each direction as the unit complex number exp(i n theta); the transport as a
        // precomputed rotation exp(i n rho) per neighbour.
        let mut z: Vec<(f32, f32)> = theta
            .iter()
            .map(|&a| ((nf * a).cos(), (nf * a).sin()))
            .collect();
        let rot: Vec<Vec<(u32, f32, f32)>> = self
            .nbrs
            .iter()
            .map(|list| {
                list.iter()
                    .map(|&(q, rho)| (q, (nf * rho).cos(), (nf * rho).sin()))
                    .collect()
            })
            .collect();
        // First half: plain averaging (magnitudes free, rescaled as a whole against
        // underflow), a power iteration towards the smoothest field, in which
        // singularities can move and cancel; second half: unit directions.
        let linear = iterations / 2;
        for it in 0..iterations {
            let mut max2 = 0.0f32;
            for p in 0..self.count {
                if fixed[p] || !self.used[p] || rot[p].is_empty() {
                    continue;
                }
                let (mut re, mut im) = z[p];
                for &(q, c, s) in &rot[p] {
                    let (qr, qi) = z[q as usize];
                    re += qr * c - qi * s;
                    im += qr * s + qi * c;
                }
                let len2 = re * re + im * im;
                if it < linear {
                    let w = 1.0 / (1 + rot[p].len()) as f32;
                    z[p] = (re * w, im * w);
                    max2 = max2.max(len2 * w * w);
                } else if len2 > 1e-24 {
                    let inv = len2.sqrt().recip();
                    z[p] = (re * inv, im * inv);
                }
            }
            if it < linear && max2 > 0.0 && max2 < 1e-6 {
                let k = max2.sqrt().recip();
                for v in z.iter_mut() {
                    *v = (v.0 * k, v.1 * k);
                }
            }
        }
        for p in 0..self.count {
            if !fixed[p] {
                theta[p] = z[p].1.atan2(z[p].0) / nf;
            }
        }
    }

    /// Per-corner unit tangents from per-node angles, each carried from its welded
    /// vertex's tangent plane into the triangle's plane by the minimal rotation between
    /// the two normals (the transport the relaxation uses, so angles to the triangle's
    /// edges are kept, unlike a projection). For n > 1 each triangle is then combed:
    /// corners 1 and 2 are rotated about the face normal by the multiple of 360/n that
    /// brings them closest to corner 0.
    fn corners_from_angles(&self, mesh: &Mesh, theta: &[f32], n: u32) -> Vec<[Vec3; 3]> {
        let period = TAU / n as f32;
        (0..mesh.triangles.len())
            .map(|t| {
                let nf = face_or_vertex_normal(mesh, t);
                let mut out = mesh.triangles[t].map(|v| {
                    let p = self.id[v as usize] as usize;
                    Quat::from_rotation_arc(self.normal[p], nf) * self.dir_of(p, theta[p])
                });
                if n > 1 {
                    for i in 1..3 {
                        let a = out[0].cross(out[i]).dot(nf).atan2(out[0].dot(out[i]));
                        let turn = wrap(a, period) - a;
                        if turn != 0.0 {
                            out[i] = Quat::from_axis_angle(nf, turn) * out[i];
                        }
                    }
                }
                out
            })
            .collect()
    }

    /// Singular vertices and their index; see [`TangentField::singularities`].
    ///
    /// Per triangle (corners a, b, c counter-clockwise): the turning of the field around
    /// it relative to the transport, `sum wrap(theta_next - theta_cur - rho)` (wrapped to
    /// half a period), plus the transport's holonomy around it (`sum rho` wrapped to
    /// (-pi, pi]: the signed area of the triangle of normals on the unit sphere), is a
    /// multiple k of 2*pi/n; k != 0 makes the triangle singular with index k/n. The
    /// holonomies add up to 2*pi times the Euler characteristic on a closed mesh and the
    /// turnings cancel, so the indices obey Poincare-Hopf. A singular triangle's index
    /// goes to its corner whose direction disagrees most with the other two (largest
    /// wrapped differences on its two edges); indices are added per welded vertex.
    fn singularities(&self, theta: &[f32], n: u32) -> Vec<(u32, f32)> {
        let nf = n as f32;
        let period = TAU / nf;
        let mut acc: HashMap<u32, f32> = HashMap::new();
        for tri in &self.tris {
            if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
                continue;
            }
            let mut d = [0.0f32; 3];
            let mut rho_sum = 0.0f32;
            for i in 0..3 {
                let a = tri[i] as usize;
                let b = tri[(i + 1) % 3] as usize;
                let rho = self.transport(a, b);
                rho_sum += rho;
                d[i] = wrap(theta[b] - (theta[a] + rho), period);
            }
            let holonomy = wrap(rho_sum, TAU);
            let k = (nf * (d[0] + d[1] + d[2] + holonomy) / TAU).round();
            if k == 0.0 {
                continue;
            }
            // Corner i has edges i-1 (into it) and i (out of it).
            let corner = (0..3)
                .max_by(|&i, &j| {
                    let si = d[(i + 2) % 3].abs() + d[i].abs();
                    let sj = d[(j + 2) % 3].abs() + d[j].abs();
                    si.total_cmp(&sj)
                })
                .unwrap_or(0);
            *acc.entry(tri[corner]).or_insert(0.0) += k;
        }
        let mut out: Vec<(u32, f32)> = acc
            .into_iter()
            .filter(|&(_, k)| k != 0.0)
            .map(|(p, k)| (self.rep[p as usize], k / nf))
            .collect();
        out.sort_unstable_by_key(|s| s.0);
        out
    }
}

/// `Up(up)` as node angles.
fn up_angles(g: &Graph, up: Vec3) -> Vec<f32> {
    let a = up.abs();
    let fallback = if a.x <= a.y && a.x <= a.z {
        Vec3::X
    } else if a.y <= a.z {
        Vec3::Y
    } else {
        Vec3::Z
    };
    (0..g.count)
        .map(|p| {
            let n = g.normal[p];
            let mut u = up - n * n.dot(up);
            if u.length() < 1e-4 {
                u = fallback - n * n.dot(fallback);
            }
            // b = -u (the exemplar's -y follows up), t = n x b = u x n.
            let t = u.normalize_or_zero().cross(n);
            g.angle_of(p, t)
        })
        .collect()
}

/// Inverse-distance-squared blend of the constraints; the nearest node of each
/// constraint is fixed to it.
fn constraint_angles(g: &Graph, mesh: &Mesh, list: &[(Vec3, Vec3)]) -> (Vec<f32>, Vec<bool>) {
    let (lo, hi) = mesh.bounding_box();
    let eps = 1e-12 * (hi - lo).length_squared() + f32::MIN_POSITIVE;
    let mut fixed = vec![false; g.count];
    let project = |p: usize, d: Vec3| {
        let n = g.normal[p];
        (d - n * n.dot(d)).try_normalize()
    };
    let mut theta: Vec<f32> = (0..g.count)
        .map(|p| {
            let mut sum = Vec3::ZERO;
            let mut nearest = (f32::INFINITY, None);
            for &(c, d) in list {
                let d2 = (g.pos[p] - c).length_squared();
                if let Some(dp) = project(p, d) {
                    sum += dp / (d2 + eps);
                    if d2 < nearest.0 {
                        nearest = (d2, Some(dp));
                    }
                }
            }
            let t = sum.try_normalize().or(nearest.1).unwrap_or_else(|| g.e[p]);
            g.angle_of(p, t)
        })
        .collect();
    // Pin the nearest used node of every constraint.
    let mut pinned: HashMap<usize, Vec3> = HashMap::new();
    for &(c, d) in list {
        let best = (0..g.count).filter(|&p| g.used[p]).min_by(|&a, &b| {
            (g.pos[a] - c)
                .length_squared()
                .total_cmp(&(g.pos[b] - c).length_squared())
        });
        if let Some(p) = best {
            if let Some(dp) = project(p, d) {
                *pinned.entry(p).or_insert(Vec3::ZERO) += dp;
            }
        }
    }
    for (p, d) in pinned {
        if let Some(d) = d.try_normalize() {
            theta[p] = g.angle_of(p, d);
            fixed[p] = true;
        }
    }
    (theta, fixed)
}

/// A well-mixed 64-bit hash (splitmix64 finalizer).
fn mix(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^ (x >> 31)
}

fn random_corners(mesh: &Mesh, regions: Option<&[u32]>, seed: u32) -> Vec<[Vec3; 3]> {
    let tcount = mesh.triangles.len();
    let normals: Vec<Vec3> = (0..tcount)
        .map(|t| face_or_vertex_normal(mesh, t))
        .collect();
    let region: Vec<u32> = match regions {
        Some(r) => r.to_vec(),
        None => {
            let adj = mesh.triangle_adjacency();
            let cos_max = REGION_ANGLE_DEGREES.to_radians().cos();
            let mut region = vec![u32::MAX; tcount];
            let mut next = 0u32;
            let mut stack = Vec::new();
            for s in 0..tcount {
                if region[s] != u32::MAX {
                    continue;
                }
                region[s] = next;
                stack.push(s);
                while let Some(t) = stack.pop() {
                    for nb in adj[t].iter().flatten() {
                        let nb = *nb as usize;
                        if region[nb] == u32::MAX && normals[nb].dot(normals[s]) >= cos_max {
                            region[nb] = next;
                            stack.push(nb);
                        }
                    }
                }
                next += 1;
            }
            region
        }
    };
    // Area-weighted mean normal per region, and its random direction.
    let mut mean: HashMap<u32, Vec3> = HashMap::new();
    for (t, &r) in region.iter().enumerate() {
        let [a, b, c] = mesh.corners(t);
        *mean.entry(r).or_insert(Vec3::ZERO) += (b - a).cross(c - a);
    }
    let dirs: HashMap<u32, Vec3> = mean
        .into_iter()
        .map(|(r, sum)| {
            let n = sum.normalize_or(Vec3::Y);
            let h = mix(((seed as u64) << 32) | r as u64);
            let angle = (h >> 40) as f32 / (1u64 << 24) as f32 * TAU;
            let e = n.any_orthonormal_vector();
            (r, e * angle.cos() + n.cross(e) * angle.sin())
        })
        .collect();
    (0..tcount)
        .map(|t| {
            let n = normals[t];
            let d = dirs[&region[t]];
            let tt = (d - n * n.dot(d))
                .try_normalize()
                .unwrap_or_else(|| n.any_orthonormal_vector());
            [tt; 3]
        })
        .collect()
}

// ---------------------------------------------------------------------------------------
// Text forms (CLI).

fn parse_f32(s: &str, what: &str) -> std::result::Result<f32, String> {
    let v: f32 = s
        .trim()
        .parse()
        .map_err(|_| format!("{what}: `{s}` is not a number"))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("{what}: `{s}` is not finite"))
    }
}

fn parse_vec3(s: &str, what: &str) -> std::result::Result<Vec3, String> {
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != 3 {
        return Err(format!("{what}: `{s}` is not three numbers X,Y,Z"));
    }
    let v = Vec3::new(
        parse_f32(parts[0], what)?,
        parse_f32(parts[1], what)?,
        parse_f32(parts[2], what)?,
    );
    if v == Vec3::ZERO {
        return Err(format!("{what}: `{s}` is the zero vector"));
    }
    Ok(v)
}

fn fmt_vec3(v: Vec3) -> String {
    format!("{},{},{}", v.x, v.y, v.z)
}

/// Parses constraint lines `px py pz dx dy dz` (numbers separated by white space or
/// commas; `#` starts a comment; blank lines are skipped). `name` is used in messages.
pub fn parse_constraints(text: &str, name: &str) -> Result<Vec<(Vec3, Vec3)>> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("");
        let fields: Vec<&str> = line
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|f| !f.is_empty())
            .collect();
        if fields.is_empty() {
            continue;
        }
        let here = format!("{name} line {}", i + 1);
        if fields.len() != 6 {
            return Err(invalid(format!(
                "{here}: expected 6 numbers `px py pz dx dy dz`, found {} fields",
                fields.len()
            )));
        }
        let mut v = [0.0f32; 6];
        for (k, f) in fields.iter().enumerate() {
            v[k] = parse_f32(f, &here).map_err(invalid)?;
        }
        let d = Vec3::new(v[3], v[4], v[5]);
        if d == Vec3::ZERO {
            return Err(invalid(format!("{here}: the direction is the zero vector")));
        }
        out.push((Vec3::new(v[0], v[1], v[2]), d));
    }
    if out.is_empty() {
        return Err(invalid(format!(
            "{name}: no constraints (expected lines `px py pz dx dy dz`)"
        )));
    }
    Ok(out)
}

/// Reads a constraint file; see [`parse_constraints`].
pub fn read_constraints(path: &Path) -> Result<Vec<(Vec3, Vec3)>> {
    // A text file of a few lines per constraint: 64 MiB is far more than any real list.
    let bytes = crate::image_io::read_file_capped(path, 64 << 20, "constraint files")?;
    let text = String::from_utf8(bytes).map_err(|_| Error::Io {
        path: path.to_path_buf(),
        source: std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            "not a UTF-8 text file (a constraint file holds lines of numbers)",
        ),
    })?;
    parse_constraints(&text, &path.display().to_string())
}

impl FromStr for DirectionSource {
    type Err = Error;

    /// The syntax of [`DIRECTION_HELP`]. `constraints:FILE` reads the file.
    fn from_str(s: &str) -> Result<Self> {
        let text = s.trim();
        let fail = |reason: String| {
            invalid(format!(
                "direction `{text}`: {reason}; expected up, up:X,Y,Z, tangents, \
                 symmetric:N[:X,Y,Z[:ITERATIONS]], random[:SEED] or constraints:FILE"
            ))
        };
        let (head, rest) = match text.split_once(':') {
            Some((h, r)) => (h, Some(r)),
            None => (text, None),
        };
        match (head.to_ascii_lowercase().as_str(), rest) {
            ("up", None) => Ok(DirectionSource::Up(Vec3::Y)),
            ("up", Some(r)) => Ok(DirectionSource::Up(parse_vec3(r, "up").map_err(fail)?)),
            ("tangents", None) => Ok(DirectionSource::MeshTangents),
            ("symmetric", Some(r)) => {
                let parts: Vec<&str> = r.split(':').collect();
                if parts.len() > 3 {
                    return Err(fail("too many fields".into()));
                }
                let n: u32 = parts[0]
                    .trim()
                    .parse()
                    .map_err(|_| fail(format!("N = `{}` is not a whole number", parts[0])))?;
                if !matches!(n, 1 | 2 | 4 | 6) {
                    return Err(fail(format!("N = {n}; use 1, 2, 4 or 6")));
                }
                let up = match parts.get(1) {
                    Some(v) => parse_vec3(v, "up").map_err(fail)?,
                    None => Vec3::Y,
                };
                let iterations = match parts.get(2) {
                    Some(v) => v
                        .trim()
                        .parse()
                        .map_err(|_| fail(format!("ITERATIONS = `{v}` is not a whole number")))?,
                    None => DEFAULT_SYMMETRIC_ITERATIONS,
                };
                if iterations > MAX_SYMMETRIC_ITERATIONS {
                    return Err(fail(format!(
                        "ITERATIONS = {iterations}; use 0 to {MAX_SYMMETRIC_ITERATIONS} (default {DEFAULT_SYMMETRIC_ITERATIONS})"
                    )));
                }
                Ok(DirectionSource::Symmetric { n, up, iterations })
            }
            ("symmetric", None) => Err(fail("give N (symmetric:N)".into())),
            ("random", None) => Ok(DirectionSource::RandomPerRegion { seed: 0 }),
            ("random", Some(r)) => Ok(DirectionSource::RandomPerRegion {
                seed: r.trim().parse().map_err(|_| {
                    fail(format!(
                        "SEED = `{r}` is not a whole number from 0 to {}",
                        u32::MAX
                    ))
                })?,
            }),
            ("constraints", Some(path)) if !path.trim().is_empty() => Ok(
                DirectionSource::Constraints(read_constraints(Path::new(path.trim()))?),
            ),
            ("constraints", _) => Err(fail("give a file (constraints:FILE)".into())),
            ("tangents", Some(_)) => Err(fail("`tangents` takes no argument".into())),
            _ => Err(fail("unknown direction source".into())),
        }
    }
}

impl fmt::Display for DirectionSource {
    /// The [`FromStr`] form, which parses back to the same value, except for
    /// `Constraints`, written `constraints(N pairs)` (its file name is not kept).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DirectionSource::Up(v) if *v == Vec3::Y => write!(f, "up"),
            DirectionSource::Up(v) => write!(f, "up:{}", fmt_vec3(*v)),
            DirectionSource::MeshTangents => write!(f, "tangents"),
            DirectionSource::Constraints(list) => write!(f, "constraints({} pairs)", list.len()),
            DirectionSource::Symmetric { n, up, iterations } => {
                if *iterations != DEFAULT_SYMMETRIC_ITERATIONS {
                    write!(f, "symmetric:{n}:{}:{iterations}", fmt_vec3(*up))
                } else if *up != Vec3::Y {
                    write!(f, "symmetric:{n}:{}", fmt_vec3(*up))
                } else {
                    write!(f, "symmetric:{n}")
                }
            }
            DirectionSource::RandomPerRegion { seed } => write!(f, "random:{seed}"),
        }
    }
}

impl FromStr for ScaleSource {
    type Err = Error;

    /// `S` (a number > 0) or `linear:AX,AY,AZ:S_MIN:S_MAX`.
    fn from_str(s: &str) -> Result<Self> {
        let text = s.trim();
        let fail = |reason: String| {
            invalid(format!(
                "scale `{text}`: {reason}; expected a number > 0 (world units per exemplar \
                 texel) or linear:AX,AY,AZ:S_MIN:S_MAX"
            ))
        };
        let positive = |v: f32, what: &str| {
            if v > 0.0 {
                Ok(v)
            } else {
                Err(fail(format!("{what} = {v} must be > 0")))
            }
        };
        if let Some(rest) = text
            .strip_prefix("linear:")
            .or_else(|| text.strip_prefix("LINEAR:"))
        {
            let parts: Vec<&str> = rest.split(':').collect();
            if parts.len() != 3 {
                return Err(fail("linear needs AXIS:S_MIN:S_MAX".into()));
            }
            let axis = parse_vec3(parts[0], "axis").map_err(fail)?;
            let at_min = positive(parse_f32(parts[1], "S_MIN").map_err(fail)?, "S_MIN")?;
            let at_max = positive(parse_f32(parts[2], "S_MAX").map_err(fail)?, "S_MAX")?;
            return Ok(ScaleSource::Linear {
                axis,
                at_min,
                at_max,
            });
        }
        let v = parse_f32(text, "scale").map_err(fail)?;
        Ok(ScaleSource::Constant(positive(v, "scale")?))
    }
}

impl fmt::Display for ScaleSource {
    /// The [`FromStr`] form, except for `PerVertex`, written `per-vertex(N values)`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ScaleSource::Constant(s) => write!(f, "{s}"),
            ScaleSource::PerVertex(v) => write!(f, "per-vertex({} values)", v.len()),
            ScaleSource::Linear {
                axis,
                at_min,
                at_max,
            } => write!(f, "linear:{}:{at_min}:{at_max}", fmt_vec3(*axis)),
        }
    }
}
