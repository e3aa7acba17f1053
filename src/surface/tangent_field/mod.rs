//! Tangent fields: where the exemplar's axes go on the surface, and at what scale.
//!
//! Surface synthesis (Lefebvre & Hoppe 2006, section 6) needs, at every surface point, a
//! tangent frame `F = [t*s, b*s]`: `t` is the surface direction that the exemplar's +x axis
//! follows, `b = t x n` the direction of the exemplar's +y axis (image y points down, so
//! with this choice the texture is not mirrored when seen from outside, from the side the
//! normal points to), and `s` the size of one exemplar texel in world units.
//!
//! A [`TangentField`] stores one unit tangent and one scale per triangle corner, not per
//! vertex: an n-fold symmetric field can then be "combed" per triangle (each corner takes
//! the representative, among its n rotations, closest to corner 0's, so interpolation
//! inside the triangle is smooth) and a random field can change abruptly between
//! regions. [`TangentField::frame`] interpolates them at any point of a triangle.
//!
//! The direction sources ([`DirectionSource`]) work on the mesh's vertices welded by exact
//! position (glTF meshes split vertices at uv seams;
//! [`Mesh::cube`](crate::surface::mesh::Mesh::cube) has one set of vertices per face), with
//! one area-weighted normal per welded vertex, so the field is continuous across seams and
//! chart boundaries.

mod field;
mod graph;
mod random;
mod text;

use glam::Vec3;

pub use field::TangentField;
pub use text::{parse_constraints, read_constraints, DirectionSpec};

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

/// Help for the CLI's direction option (the syntax that [`DirectionSource`] parses).
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

/// Help for the CLI's scale option (the syntax that [`ScaleSource`] parses).
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
    /// the topology forces them (on large meshes this needs many iterations).
    Symmetric {
        /// Order of the symmetry: 1, 2, 4 or 6.
        n: u32,
        /// World up vector of the starting field.
        up: Vec3,
        /// Relaxation iterations.
        iterations: u32,
    },
    /// Isotropic textures: one random direction per region, from `seed` and the region
    /// id. Regions are the per-triangle ids given to [`TangentField::build`] (chart ids)
    /// or, when none are given, groups grown from the lowest unassigned triangle across
    /// edges to triangles whose normal is within [`REGION_ANGLE_DEGREES`] of the seed
    /// triangle's. The direction lies in the plane of the region's mean normal and is
    /// projected to each triangle.
    RandomPerRegion {
        /// Seed of the random directions.
        seed: u32,
    },
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
        /// World axis along which the scale varies.
        axis: Vec3,
        /// Scale at the low end of the mesh's extent.
        at_min: f32,
        /// Scale at the high end of the mesh's extent.
        at_max: f32,
    },
}
