//! Triangle meshes for surface synthesis: one flat list of triangles in world space
//! (every glTF primitive with its node transform applied), plus the generated test
//! meshes.

use std::collections::HashMap;

use glam::{Vec2, Vec3, Vec4};

use crate::error::{Error, Result};

/// A triangle mesh in world space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Unit vertex normals (computed, area-weighted, when the source has none).
    pub normals: Vec<Vec3>,
    /// `TEXCOORD_0` in glTF's convention: [0, 1], v pointing down the image.
    pub uvs: Option<Vec<Vec2>>,
    /// glTF `TANGENT`: xyz unit tangent, w = +-1 bitangent sign.
    pub tangents: Option<Vec<Vec4>>,
    /// Vertex indices of every triangle.
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

    /// Total surface area in world units squared.
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

/// Exact-position key of a point: the bit patterns of its coordinates, with -0.0 folded
/// into 0.0 so both weld.
fn position_key(p: Vec3) -> [u32; 3] {
    [
        (p.x + 0.0).to_bits(),
        (p.y + 0.0).to_bits(),
        (p.z + 0.0).to_bits(),
    ]
}

fn invalid(msg: String) -> Error {
    Error::InvalidParameter(msg)
}

impl Mesh {
    /// Axis-aligned bounding box `(min, max)` of all positions (used or not);
    /// `(0, 0)` for a mesh without positions.
    pub fn bounding_box(&self) -> (Vec3, Vec3) {
        if self.positions.is_empty() {
            return (Vec3::ZERO, Vec3::ZERO);
        }
        self.positions.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        )
    }

    /// Unit geometric normal of triangle `t` from its winding (counter-clockwise seen
    /// from the front); zero for a degenerate triangle.
    pub fn face_normal(&self, t: usize) -> Vec3 {
        let [a, b, c] = self.corners(t);
        (b - a).cross(c - a).normalize_or_zero()
    }

    /// Welds vertices by exact position (glTF meshes split vertices at uv and normal
    /// seams). Returns `(id, count)`: `id[v]` is a dense id in `0..count`, shared by all
    /// vertices with bit-identical positions, numbered in order of first appearance.
    pub fn welded_vertex_ids(&self) -> (Vec<u32>, usize) {
        let mut map: HashMap<[u32; 3], u32> = HashMap::with_capacity(self.positions.len());
        let ids = self
            .positions
            .iter()
            .map(|&p| {
                let next = map.len() as u32;
                *map.entry(position_key(p)).or_insert(next)
            })
            .collect();
        (ids, map.len())
    }

    /// For triangle `t` and edge `i` (corners `i -> (i+1)%3`), the other triangle sharing
    /// that edge. Vertices are matched by exact position, so split vertices (uv or normal
    /// seams, the separate faces of [`Mesh::cube`]) still connect. `None` on boundary edges
    /// and on non-manifold edges (shared by more than two triangles). Indices must be in
    /// range (see [`Mesh::validate_and_repair`]).
    pub fn triangle_adjacency(&self) -> Vec<[Option<u32>; 3]> {
        let (ids, _) = self.welded_vertex_ids();
        let edges = self.welded_edge_map(&ids);
        let mut adj = vec![[None; 3]; self.triangles.len()];
        for uses in edges.values() {
            if let [(t0, e0), (t1, e1)] = uses[..] {
                if t0 != t1 {
                    adj[t0 as usize][e0 as usize] = Some(t1);
                    adj[t1 as usize][e1 as usize] = Some(t0);
                }
            }
        }
        adj
    }

    /// Undirected welded edge -> the (triangle, edge) pairs that use it. Edges whose two
    /// ends weld to the same point are left out.
    fn welded_edge_map(&self, ids: &[u32]) -> HashMap<(u32, u32), Vec<(u32, u8)>> {
        let mut edges: HashMap<(u32, u32), Vec<(u32, u8)>> =
            HashMap::with_capacity(self.triangles.len() * 3 / 2 + 1);
        for (t, tri) in self.triangles.iter().enumerate() {
            for i in 0..3 {
                let a = ids[tri[i] as usize];
                let b = ids[tri[(i + 1) % 3] as usize];
                if a == b {
                    continue;
                }
                edges
                    .entry((a.min(b), a.max(b)))
                    .or_default()
                    .push((t as u32, i as u8));
            }
        }
        edges
    }

    /// The checks of [`Self::validate_and_repair`] that need no repair: triangles exist
    /// and index existing vertices, every value is finite, `uvs` and `tangents` have one
    /// entry per position. Functions that take a [`Mesh`] call it first.
    pub fn check(&self) -> Result<()> {
        if self.triangles.is_empty() {
            return Err(invalid("mesh has no triangles".into()));
        }
        let n = self.positions.len();
        if let Some(i) = self.positions.iter().position(|p| !p.is_finite()) {
            return Err(invalid(format!(
                "mesh vertex {i} has a non-finite position ({}, {}, {}) (after the node \
                 transforms): repair the mesh (e.g. Blender's Mesh > Clean Up) and export it again",
                self.positions[i].x, self.positions[i].y, self.positions[i].z
            )));
        }
        // Areas and normals multiply two coordinates: beyond this they overflow f32.
        const MAX_COORD: f32 = 1e18;
        if let Some(i) = self
            .positions
            .iter()
            .position(|p| p.abs().max_element() > MAX_COORD)
        {
            let p = self.positions[i];
            return Err(invalid(format!(
                "mesh vertex {i} lies at ({:e}, {:e}, {:e}), beyond +-1e18 (after the node \
                 transforms), where areas and normals overflow: scale the mesh down and \
                 export it again",
                p.x, p.y, p.z
            )));
        }
        if let Some(i) = self.normals.iter().position(|v| !v.is_finite()) {
            let v = self.normals[i];
            return Err(invalid(format!(
                "mesh vertex {i} has a non-finite normal ({}, {}, {}): fix or drop the \
                 mesh's normals (texsyn computes them when there are none)",
                v.x, v.y, v.z
            )));
        }
        if let Some(uvs) = &self.uvs {
            if uvs.len() != n {
                return Err(invalid(format!(
                    "mesh has {} uvs for {n} positions (need one per position)",
                    uvs.len()
                )));
            }
            if let Some(i) = uvs.iter().position(|v| !v.is_finite()) {
                return Err(invalid(format!(
                    "mesh vertex {i} has a non-finite uv ({}, {})",
                    uvs[i].x, uvs[i].y
                )));
            }
        }
        if let Some(tangents) = &self.tangents {
            if tangents.len() != n {
                return Err(invalid(format!(
                    "mesh has {} tangents for {n} positions (need one per position)",
                    tangents.len()
                )));
            }
            if let Some(i) = tangents.iter().position(|v| !v.is_finite()) {
                let t = tangents[i];
                return Err(invalid(format!(
                    "mesh vertex {i} has a non-finite tangent ({}, {}, {}, {})",
                    t.x, t.y, t.z, t.w
                )));
            }
        }
        for (t, tri) in self.triangles.iter().enumerate() {
            if let Some(&bad) = tri.iter().find(|&&i| i as usize >= n) {
                return Err(invalid(format!(
                    "mesh triangle {t} uses vertex index {bad}, but the mesh has {n} vertices"
                )));
            }
        }
        Ok(())
    }

    /// Checks the mesh and repairs what can be repaired, in place.
    ///
    /// Errors (nothing is changed): no triangles, a vertex index out of range, a NaN or
    /// infinite position, normal, uv or tangent, `uvs` or `tangents` whose length differs
    /// from `positions`, every triangle degenerate.
    ///
    /// Repairs (reported): triangles with a repeated index, slivers (area at most
    /// `1e-12 * (longest edge)^2`: collinear corners) and specks (area at most `1e-24 *
    /// (bounding-box diagonal)^2`) are dropped; the test is per triangle, so a small part
    /// far from a large one keeps its triangles; when `normals` does not have one
    /// entry per position, area-weighted unit vertex normals are computed for all
    /// vertices (accumulated over vertices welded by exact position, so uv seams get no
    /// normal seam); when only some normals are zero-length, those are computed the same
    /// way and the others are kept (normalized). Edges shared by more than two triangles
    /// (vertices welded by exact position) are counted and kept. Unused vertices stay.
    pub fn validate_and_repair(&mut self) -> Result<RepairReport> {
        self.check()?;
        let n = self.positions.len();

        // Degenerate triangles. Areas in f64 so that the threshold is not lost in
        // single-precision rounding.
        let (lo, hi) = self.bounding_box();
        let diag2 = (hi - lo).as_dvec3().length_squared();
        let min_area = 1e-24 * diag2;
        let before = self.triangles.len();
        let positions = &self.positions;
        self.triangles.retain(|&[a, b, c]| {
            if a == b || b == c || a == c {
                return false;
            }
            let pa = positions[a as usize].as_dvec3();
            let pb = positions[b as usize].as_dvec3();
            let pc = positions[c as usize].as_dvec3();
            let area = 0.5 * (pb - pa).cross(pc - pa).length();
            let longest2 = (pb - pa)
                .length_squared()
                .max((pc - pb).length_squared())
                .max((pa - pc).length_squared());
            area > min_area && area > 1e-12 * longest2
        });
        let dropped = before - self.triangles.len();
        if self.triangles.is_empty() {
            return Err(invalid(format!(
                "all triangles are degenerate ({before} triangles, each with a repeated \
                 vertex or zero area)"
            )));
        }

        // Normals.
        let (ids, count) = self.welded_vertex_ids();
        let mut computed_normals = false;
        let recompute_all = self.normals.len() != n;
        let any_zero = self.normals.iter().any(|v| v.length_squared() < 1e-24);
        if recompute_all || any_zero {
            computed_normals = true;
            let welded = self.welded_area_normals(&ids, count);
            if recompute_all {
                self.normals = vec![Vec3::ZERO; n];
            }
            for v in 0..n {
                let current = self.normals[v];
                if recompute_all || current.length_squared() < 1e-24 {
                    self.normals[v] = welded[ids[v] as usize];
                }
            }
        }
        for v in self.normals.iter_mut() {
            if (v.length_squared() - 1.0).abs() > 1e-5 {
                *v = v.normalize_or(Vec3::Y);
            }
        }

        let non_manifold_edges = self
            .welded_edge_map(&ids)
            .values()
            .filter(|uses| uses.len() > 2)
            .count();
        Ok(RepairReport {
            dropped_degenerate: dropped,
            computed_normals,
            non_manifold_edges,
        })
    }

    /// Area-weighted unit normal per welded vertex; unused welded vertices, and those
    /// whose triangles cancel out, get the normal of their largest triangle or +y.
    fn welded_area_normals(&self, ids: &[u32], count: usize) -> Vec<Vec3> {
        let mut sum = vec![Vec3::ZERO; count];
        let mut largest = vec![(0.0f32, Vec3::Y); count];
        for t in 0..self.triangles.len() {
            let [a, b, c] = self.corners(t);
            let cross = (b - a).cross(c - a); // 2 * area * unit normal
            let len = cross.length();
            for &v in &self.triangles[t] {
                let id = ids[v as usize] as usize;
                sum[id] += cross;
                if len > largest[id].0 {
                    largest[id] = (len, cross / len);
                }
            }
        }
        sum.iter()
            .zip(&largest)
            .map(|(s, l)| s.try_normalize().unwrap_or(l.1))
            .collect()
    }

    /// A UV sphere centred at the origin, poles on the y axis: `segments` vertices
    /// around each of the `rings - 1` latitude rings (no duplicated seam column), one
    /// vertex at each pole with a fan of triangles. Normals are exact (position /
    /// radius); no uvs. `segments` is clamped to 3..=4096 and `rings` to 2..=4096.
    pub fn uv_sphere(radius: f32, segments: u32, rings: u32) -> Mesh {
        let segments = segments.clamp(3, 4096);
        let rings = rings.clamp(2, 4096);
        let mut normals = Vec::with_capacity((segments * (rings - 1) + 2) as usize);
        normals.push(Vec3::Y);
        for i in 1..rings {
            let theta = std::f32::consts::PI * i as f32 / rings as f32;
            for j in 0..segments {
                let phi = std::f32::consts::TAU * j as f32 / segments as f32;
                normals.push(Vec3::new(
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    theta.sin() * phi.sin(),
                ));
            }
        }
        normals.push(Vec3::NEG_Y);
        let south = normals.len() as u32 - 1;
        // Vertex (ring i in 1..rings, column j).
        let v = |i: u32, j: u32| 1 + (i - 1) * segments + j % segments;
        let mut triangles = Vec::with_capacity((2 * segments * (rings - 1)) as usize);
        for j in 0..segments {
            triangles.push([0, v(1, j + 1), v(1, j)]);
        }
        for i in 1..rings - 1 {
            for j in 0..segments {
                triangles.push([v(i, j), v(i, j + 1), v(i + 1, j + 1)]);
                triangles.push([v(i, j), v(i + 1, j + 1), v(i + 1, j)]);
            }
        }
        for j in 0..segments {
            triangles.push([v(rings - 1, j), v(rings - 1, j + 1), south]);
        }
        Mesh {
            positions: normals.iter().map(|&n| n * radius).collect(),
            normals,
            uvs: None,
            tangents: None,
            triangles,
        }
    }

    /// A torus around the y axis, centred at the origin: tube centre circle of radius
    /// `major`, tube radius `minor`; `segments` around the y axis, `sides` around the
    /// tube (each at least 3). No duplicated seam vertices; exact normals; no uvs.
    pub fn torus(major: f32, minor: f32, segments: u32, sides: u32) -> Mesh {
        let segments = segments.max(3);
        let sides = sides.max(3);
        let mut positions = Vec::with_capacity((segments * sides) as usize);
        let mut normals = Vec::with_capacity(positions.capacity());
        for i in 0..segments {
            let u = std::f32::consts::TAU * i as f32 / segments as f32;
            for j in 0..sides {
                let v = std::f32::consts::TAU * j as f32 / sides as f32;
                let n = Vec3::new(v.cos() * u.cos(), v.sin(), v.cos() * u.sin());
                let centre = Vec3::new(u.cos(), 0.0, u.sin()) * major;
                positions.push(centre + n * minor);
                normals.push(n);
            }
        }
        let idx = |i: u32, j: u32| (i % segments) * sides + j % sides;
        let mut triangles = Vec::with_capacity((2 * segments * sides) as usize);
        for i in 0..segments {
            for j in 0..sides {
                triangles.push([idx(i, j), idx(i, j + 1), idx(i + 1, j + 1)]);
                triangles.push([idx(i, j), idx(i + 1, j + 1), idx(i + 1, j)]);
            }
        }
        Mesh {
            positions,
            normals,
            uvs: None,
            tangents: None,
            triangles,
        }
    }

    /// An axis-aligned cube of edge `size` centred at the origin, each face split into
    /// `subdivisions` x `subdivisions` quads (1 to 2048). The 6 faces have their own
    /// vertices (flat normals; they connect through [`Mesh::triangle_adjacency`], which
    /// welds by position): a closed surface made of many charts. No uvs.
    pub fn cube(size: f32, subdivisions: u32) -> Mesh {
        let n = subdivisions.clamp(1, 2048);
        let h = 0.5 * size;
        // (normal, u, v) with u x v = normal, so quads (u, v) are counter-clockwise.
        let faces = [
            (Vec3::X, Vec3::Y, Vec3::Z),
            (Vec3::NEG_X, Vec3::Z, Vec3::Y),
            (Vec3::Y, Vec3::Z, Vec3::X),
            (Vec3::NEG_Y, Vec3::X, Vec3::Z),
            (Vec3::Z, Vec3::X, Vec3::Y),
            (Vec3::NEG_Z, Vec3::Y, Vec3::X),
        ];
        let per_face = (n + 1) * (n + 1);
        let mut mesh = Mesh::default();
        for (f, &(normal, u, v)) in faces.iter().enumerate() {
            let base = f as u32 * per_face;
            for i in 0..=n {
                for j in 0..=n {
                    let a = -h + size * i as f32 / n as f32;
                    let b = -h + size * j as f32 / n as f32;
                    mesh.positions.push(normal * h + u * a + v * b);
                    mesh.normals.push(normal);
                }
            }
            let idx = |i: u32, j: u32| base + i * (n + 1) + j;
            for i in 0..n {
                for j in 0..n {
                    mesh.triangles
                        .push([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)]);
                    mesh.triangles
                        .push([idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)]);
                }
            }
        }
        mesh
    }

    /// A `width` (x) by `depth` (z) rectangle in the xz plane centred at the origin,
    /// normal +y, split into `subdivisions` x `subdivisions` quads (at least 1): an open
    /// mesh with a boundary. With uvs in [0, 1]: u along +x, v along +z (glTF's v points
    /// down the image, so seen from above with -z up the image is not mirrored).
    pub fn plane(width: f32, depth: f32, subdivisions: u32) -> Mesh {
        let n = subdivisions.max(1);
        let mut mesh = Mesh::default();
        let mut uvs = Vec::with_capacity(((n + 1) * (n + 1)) as usize);
        for i in 0..=n {
            for j in 0..=n {
                let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
                mesh.positions
                    .push(Vec3::new((u - 0.5) * width, 0.0, (v - 0.5) * depth));
                mesh.normals.push(Vec3::Y);
                uvs.push(Vec2::new(u, v));
            }
        }
        let idx = |i: u32, j: u32| i * (n + 1) + j;
        for i in 0..n {
            for j in 0..n {
                mesh.triangles
                    .push([idx(i, j), idx(i, j + 1), idx(i + 1, j + 1)]);
                mesh.triangles
                    .push([idx(i, j), idx(i + 1, j + 1), idx(i + 1, j)]);
            }
        }
        mesh.uvs = Some(uvs);
        mesh
    }
}
