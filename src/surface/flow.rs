//! Velocities for advection over a surface: 3D vectors on the mesh (per vertex, or a
//! preset flow in world space) projected to the tangent planes and mapped into the atlas,
//! `v_atlas = pinv(Jf) v`, per atlas texel inside the charts (atlas texels per unit
//! time). The gutters need none: the fill pass rewrites them after every pass, so the
//! advected texture crosses chart seams through the indirection maps.

use glam::{Vec2, Vec3};

use super::atlas::{barycentric_2d, rasterize, NONE};
use super::maps::SurfaceGeometry;
use super::pipeline::PreparedSurface;
use crate::error::{Error, Result};
use crate::flow::Flow;

/// Atlas velocities from one 3D vector per vertex of the atlas mesh (world units per
/// unit time; `prepared.atlas.mesh`, whose vertices are split where charts are cut: for
/// vectors per vertex of the mesh given to [`super::pipeline::prepare`], see
/// [`atlas_velocity_from_mesh_vertices`]).
pub fn atlas_velocity_from_vertices(
    prepared: &PreparedSurface,
    per_vertex: &[Vec3],
) -> Result<Vec<[f32; 2]>> {
    let mesh = &prepared.atlas.mesh;
    if per_vertex.len() != mesh.positions.len() {
        return Err(Error::InvalidParameter(format!(
            "{} velocity vectors for {} vertices",
            per_vertex.len(),
            mesh.positions.len()
        )));
    }
    if per_vertex.iter().any(|v| !v.is_finite()) {
        return Err(Error::InvalidParameter(
            "per-vertex velocities contain NaN or infinite values".into(),
        ));
    }
    Ok(project(prepared, |t, w| {
        let [a, b, c] = mesh.triangles[t];
        per_vertex[a as usize] * w[0]
            + per_vertex[b as usize] * w[1]
            + per_vertex[c as usize] * w[2]
    }))
}

/// Atlas velocities from one 3D vector per vertex of the mesh the surface was prepared
/// from (world units per unit time): as [`atlas_velocity_from_vertices`], the vectors
/// first carried onto the atlas mesh's vertices, which are split where charts are cut
/// ([`super::atlas::Atlas::source_vertex`]).
pub fn atlas_velocity_from_mesh_vertices(
    prepared: &PreparedSurface,
    per_vertex: &[Vec3],
) -> Result<Vec<[f32; 2]>> {
    let atlas = &prepared.atlas;
    if per_vertex.len() != atlas.source_vertex_count {
        return Err(Error::InvalidParameter(format!(
            "{} velocity vectors for the mesh's {} vertices",
            per_vertex.len(),
            atlas.source_vertex_count
        )));
    }
    let carried = atlas
        .source_vertex
        .iter()
        .map(|&v| per_vertex.get(v as usize).copied())
        .collect::<Option<Vec<Vec3>>>()
        .ok_or_else(|| {
            Error::InvalidParameter("the atlas refers to a vertex the mesh lacks".into())
        })?;
    atlas_velocity_from_vertices(prepared, &carried)
}

/// Atlas velocities of a preset flow at time `t`, interpreted on the surface: `vortex`
/// turns about the world y axis through the mesh's centre at OMEGA radians per unit time
/// (with a core radius, a Lamb-Oseen vortex about that axis, the radius a fraction of the
/// mesh's larger horizontal extent); `uniform:VX,VY` drifts along world x and y, `source`
/// flows away from the centre (towards it when negative), `gusts` drifts in the xz plane
/// turning with time; speeds are in exemplar texels per unit time. Image flows are 2D only.
pub fn atlas_velocity(prepared: &PreparedSurface, flow: &Flow, t: f32) -> Result<Vec<[f32; 2]>> {
    let mesh = &prepared.atlas.mesh;
    let (lo, hi) = mesh.bounding_box();
    let centre = (lo + hi) * 0.5;
    // The core radius of a Lamb-Oseen vortex is a fraction of the mesh's larger
    // horizontal extent (the 2D flow's is of the output's smaller side).
    let extent = (hi.x - lo.x).max(hi.z - lo.z);
    let unit = prepared
        .texel_size
        .unwrap_or_else(|| super::pipeline::auto_texel_size(&prepared.atlas));
    let at = |p: Vec3| -> Vec3 {
        match flow {
            Flow::Uniform { vx, vy } => Vec3::new(*vx, *vy, 0.0) * unit,
            Flow::Vortex { omega, .. } => Vec3::Y.cross(p - centre) * *omega,
            Flow::LambOseen { omega, core, .. } => {
                let d = p - centre;
                let rc = core * extent;
                let rate = crate::flow::lamb_oseen_rate(*omega, rc, d.x * d.x + d.z * d.z);
                Vec3::Y.cross(d) * rate
            }
            Flow::Source { strength, .. } => (p - centre).normalize_or_zero() * *strength * unit,
            Flow::Gusts { speed, turn } => {
                let a = turn * t;
                Vec3::new(a.cos(), 0.0, a.sin()) * *speed * unit
            }
            Flow::Map { .. } => Vec3::ZERO,
        }
    };
    if matches!(flow, Flow::Map { .. }) {
        return Err(Error::InvalidParameter(
            "image flows are 2D; on a mesh use vortex, uniform, source or gusts, or per-vertex vectors through the library".into(),
        ));
    }
    let v = project(prepared, |tri, w| {
        let [a, b, c] = mesh.corners(tri);
        at(a * w[0] + b * w[1] + c * w[2])
    });
    crate::flow::finite_velocities(v, t)
}

/// Per chart texel: the 3D vector `v(triangle, barycentric)`, projected to the
/// triangle's plane and mapped to atlas texels with the pseudo-inverse of `Jf`.
fn project(prepared: &PreparedSurface, v: impl Fn(usize, [f32; 3]) -> Vec3) -> Vec<[f32; 2]> {
    let atlas = &prepared.atlas;
    let size = atlas.size as usize;
    let ids = rasterize(atlas, 0);
    let geometry = SurfaceGeometry::new(atlas);
    let mut out = vec![[0.0f32; 2]; size * size];
    for (i, &t) in ids.iter().enumerate() {
        if t == NONE {
            continue;
        }
        let t = t as usize;
        let (uv, det, [jx, jy]) = geometry.triangle(t);
        if det == 0.0 {
            continue;
        }
        let centre = Vec2::new((i % size) as f32 + 0.5, (i / size) as f32 + 0.5);
        let w = barycentric_2d(uv, det, centre);
        let vec = v(t, w);
        // pinv(Jf) v = (Jf^T Jf)^-1 Jf^T v (the normal component drops out).
        let (a, b, c) = (jx.dot(jx), jx.dot(jy), jy.dot(jy));
        let g = a * c - b * b;
        if g.abs() < 1e-30 {
            continue;
        }
        let (r1, r2) = (jx.dot(vec), jy.dot(vec));
        out[i] = [(c * r1 - b * r2) / g, (a * r2 - b * r1) / g];
    }
    out
}
