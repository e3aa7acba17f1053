//! Host-side maps of atlas synthesis, per pyramid level:
//! - the chart mask (texel centre inside a triangle at that level's resolution);
//! - the desired Jacobian `J = pinv(F) Jf` per texel, `Jf` the triangle's 3x2
//!   d(surface)/d(atlas texel) and `F = [t s, b s]` the tangent frame;
//! - the indirection map: for every gutter texel, the same surface point in the chart
//!   it belongs to, found by unfolding across chart edges (over as many triangles as it
//!   takes), and the chart texel nearest to it.
//!
//! A gutter texel belongs to the chart of its nearest chart texel. With gutters of
//! [`super::atlas::default_gutter`] the finest levels' 2-texel bands never meet; at
//! coarser levels the nearest chart wins.

use glam::{Vec2, Vec3};

use super::atlas::{barycentric_2d, level_size, rasterize, Atlas, NONE};
use super::tangent_field::TangentField;
use crate::error::{Error, Result};
use crate::field::{clamp_singular, quantize, Mat2};
use crate::passes::fill::{AtlasDomain, AtlasLevel, FillEntry, FILL_OFFSET_FRAC, FILL_OFFSET_MAX};

/// Per-triangle geometry the walk and the Jacobians need.
struct Tri {
    /// Atlas corners (finest texels) and 3D corners.
    uv: [Vec2; 3],
    p: [Vec3; 3],
    uv_area: f32,
    /// d(surface)/d(atlas x), d(surface)/d(atlas y) (world units per finest texel).
    jf: [Vec3; 2],
}

/// What building the maps found, for reporting.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MapsReport {
    /// Per level, finest first: texels inside a chart.
    pub inside: Vec<usize>,
    /// Per level, finest first: gutter texels given an indirection entry.
    pub entries: Vec<usize>,
    /// Of which in the 2-texel band refilled after every pass.
    pub band: Vec<usize>,
    /// Gutter walks (all levels) that crossed at least one chart seam.
    pub crossed: usize,
    /// Gutter walks that stopped on a mesh boundary or an edge they could not unfold across.
    pub boundary: usize,
    /// Gutter walks that gave up (still short of their target after 256 triangles).
    pub gave_up: usize,
    /// Texels whose Jacobian had to be clamped to the supported stretch (1/8..8).
    pub clamped: usize,
}

/// Builds the atlas domain of `levels` pyramid levels (finest first).
pub fn build_domain(
    atlas: &Atlas,
    field: &TangentField,
    levels: usize,
) -> Result<(AtlasDomain, MapsReport)> {
    let geo = SurfaceGeometry::new(atlas);
    let (tris, adjacency) = (&geo.tris, &geo.adjacency);
    let mut report = MapsReport::default();
    let mut out = Vec::with_capacity(levels);
    for steps in 0..levels as u32 {
        let level = build_level(atlas, field, tris, adjacency, steps, &mut report)?;
        out.push(level);
    }
    Ok((AtlasDomain { levels: out }, report))
}

/// The desired Jacobian at barycentric point `w` of triangle `t`: exemplar pixels per
/// finest atlas texel.
fn jacobian(mesh_t: usize, tri: &Tri, field: &TangentField, atlas: &Atlas, w: [f32; 3]) -> Mat2 {
    let (t, b, s) = field.frame(&atlas.mesh, mesh_t, w);
    let inv_s = 1.0 / s as f64;
    [
        [
            t.dot(tri.jf[0]) as f64 * inv_s,
            t.dot(tri.jf[1]) as f64 * inv_s,
        ],
        [
            b.dot(tri.jf[0]) as f64 * inv_s,
            b.dot(tri.jf[1]) as f64 * inv_s,
        ],
    ]
}

fn build_level(
    atlas: &Atlas,
    field: &TangentField,
    tris: &[Tri],
    adjacency: &[[Option<u32>; 3]],
    steps: u32,
    report: &mut MapsReport,
) -> Result<AtlasLevel> {
    let size = level_size(atlas.size, steps) as usize;
    let h = (1u32 << steps) as f32;
    let ids = rasterize(atlas, steps);
    let n = size * size;
    let centre = |i: usize| Vec2::new((i % size) as f32 + 0.5, (i / size) as f32 + 0.5);

    // Jacobians of chart texels (parallel rows: a frame and an SVD per texel).
    let rows = crate::analysis::par_ranges(size, 0, |rows| {
        let mut jac = Vec::with_capacity(rows.len() * size);
        let mut clamped = 0usize;
        for y in rows {
            for x in 0..size {
                let i = y * size + x;
                let t = ids[i];
                if t == NONE {
                    jac.push([0; 4]);
                    continue;
                }
                let tri = &tris[t as usize];
                let p = centre(i) * h;
                let w = barycentric_2d(tri.uv, tri.uv_area, p);
                let j = jacobian(t as usize, tri, field, atlas, w);
                let c = clamp_singular(&j);
                if c != j {
                    clamped += 1;
                }
                jac.push(quantize(&c));
            }
        }
        (jac, clamped)
    });
    let mut jac = Vec::with_capacity(n);
    for (j, c) in rows {
        jac.extend(j);
        report.clamped += c;
    }
    let mut inside = vec![0u32; n.div_ceil(32)];
    let mut count = 0;
    for (i, &t) in ids.iter().enumerate() {
        if t != NONE {
            inside[i >> 5] |= 1 << (i & 31);
            count += 1;
        }
    }
    if count == 0 && steps == 0 {
        return Err(Error::InvalidParameter(
            "no atlas texel lies inside a chart: the atlas is too small for this mesh; use a \
             larger atlas (256 texels or more for most meshes)"
                .into(),
        ));
    }
    report.inside.push(count);

    // Nearest chart texel of every texel (two-pass propagation of the nearest site).
    let nearest = nearest_sites(&ids, size);

    // Indirection entries for every gutter texel that has a chart texel at all.
    let chart = |t: u32| atlas.chart_of_triangle[t as usize];
    let results = crate::analysis::par_ranges(n, 0, |range| {
        let mut entries = Vec::new();
        let mut rest = Vec::new();
        let mut stats = [0usize; 3];
        for i in range {
            if ids[i] != NONE || nearest[i] == NONE {
                continue;
            }
            let s0 = nearest[i] as usize;
            let t0 = ids[s0];
            // Walk in finest texels from the chart texel's centre to this texel's centre.
            let walk = walk(
                tris,
                adjacency,
                &atlas.chart_of_triangle,
                t0,
                centre(s0) * h,
                centre(i) * h,
            );
            stats[0] += walk.crossed as usize;
            stats[1] += walk.boundary as usize;
            stats[2] += walk.gave_up as usize;
            let target = walk.point / h;
            // The chart texel of the end triangle's chart nearest to the point.
            let c_end = chart(walk.tri);
            let (tx, ty) = (target.x.floor() as i64, target.y.floor() as i64);
            let mut src = None;
            let mut best = f32::INFINITY;
            for r in 0..=2i64 {
                for dy in -r..=r {
                    for dx in -r..=r {
                        if dx.abs().max(dy.abs()) != r {
                            continue;
                        }
                        let (x, y) = (tx + dx, ty + dy);
                        if x < 0 || y < 0 || x >= size as i64 || y >= size as i64 {
                            continue;
                        }
                        let q = y as usize * size + x as usize;
                        if ids[q] == NONE || chart(ids[q]) != c_end {
                            continue;
                        }
                        let d = centre(q).distance_squared(target);
                        if d < best {
                            best = d;
                            src = Some(q);
                        }
                    }
                }
                if src.is_some() {
                    break;
                }
            }
            // Nothing of that chart nearby (a chart thinner than a texel at this
            // level): extrapolate the nearest chart texel's own coordinates instead.
            let (src, off) = match src {
                Some(q) => (q, target - centre(q)),
                None => (s0, centre(i) - centre(s0)),
            };
            let fx = (1 << FILL_OFFSET_FRAC) as f32;
            let q = |v: f32| ((v * fx).round() as i32).clamp(-FILL_OFFSET_MAX, FILL_OFFSET_MAX);
            let entry = FillEntry {
                dst: i as u32,
                src: src as u32,
                off: [q(off.x), q(off.y)],
            };
            // The correction reads immediate neighbours only; a 2-texel band is ample.
            let (dx, dy) = (
                (i % size) as i64 - (s0 % size) as i64,
                (i / size) as i64 - (s0 / size) as i64,
            );
            if dx.abs().max(dy.abs()) <= 2 {
                entries.push(entry);
            } else {
                rest.push(entry);
            }
        }
        (entries, rest, stats)
    });
    let mut fill = Vec::new();
    let mut far = Vec::new();
    for (e, r, s) in results {
        fill.extend(e);
        far.extend(r);
        report.crossed += s[0];
        report.boundary += s[1];
        report.gave_up += s[2];
    }
    let band = fill.len() as u32;
    fill.extend(far);
    report.entries.push(fill.len());
    report.band.push(band as usize);
    // Gutter texels carry their nearest chart texel's Jacobian: their coordinates
    // continue that chart's (magnification reads it there).
    for i in 0..n {
        if ids[i] == NONE && nearest[i] != NONE {
            jac[i] = jac[nearest[i] as usize];
        } else if ids[i] == NONE {
            jac[i] = quantize(&crate::field::IDENTITY);
        }
    }
    Ok(AtlasLevel {
        size: [size as u32; 2],
        jac,
        inside,
        fill,
        band,
    })
}

/// Index of the nearest texel with `ids != NONE` for every texel (NONE if there is
/// none): forward and backward raster sweeps propagating the nearest site, as in
/// 8-point sequential Euclidean distance transforms (exact up to rare ties).
fn nearest_sites(ids: &[u32], size: usize) -> Vec<u32> {
    let mut site: Vec<u32> = ids
        .iter()
        .enumerate()
        .map(|(i, &t)| if t != NONE { i as u32 } else { NONE })
        .collect();
    let d2 = |i: usize, s: u32| {
        let (x, y) = ((i % size) as i64, (i / size) as i64);
        let (sx, sy) = ((s as usize % size) as i64, (s as usize / size) as i64);
        (x - sx).pow(2) + (y - sy).pow(2)
    };
    let relax = |site: &mut Vec<u32>, i: usize, nbrs: &[(i64, i64)]| {
        let (x, y) = ((i % size) as i64, (i / size) as i64);
        let mut best = site[i];
        let mut bd = if best == NONE { i64::MAX } else { d2(i, best) };
        for &(dx, dy) in nbrs {
            let (qx, qy) = (x + dx, y + dy);
            if qx < 0 || qy < 0 || qx >= size as i64 || qy >= size as i64 {
                continue;
            }
            let s = site[qy as usize * size + qx as usize];
            if s != NONE {
                let d = d2(i, s);
                if d < bd {
                    bd = d;
                    best = s;
                }
            }
        }
        site[i] = best;
    };
    const FWD: [(i64, i64); 4] = [(-1, -1), (0, -1), (1, -1), (-1, 0)];
    const BWD: [(i64, i64); 4] = [(1, 1), (0, 1), (-1, 1), (1, 0)];
    for _ in 0..2 {
        for i in 0..size * size {
            relax(&mut site, i, &FWD);
        }
        for i in (0..size * size).rev() {
            relax(&mut site, i, &BWD);
        }
    }
    site
}

/// Where a walk over the surface ended.
pub struct WalkEnd {
    /// Triangle the walk ended in (index into the atlas mesh).
    pub tri: u32,
    /// End point in `tri`'s chart's atlas texels (finest level): the target, or where
    /// the walk stopped.
    pub point: Vec2,
    /// Whether the walk crossed at least one chart seam (unfolding into another chart).
    pub crossed: bool,
    /// Whether it stopped early on a mesh boundary, a non-manifold edge or a degenerate
    /// triangle; `point` is then on the edge where it stopped.
    pub boundary: bool,
    /// Whether it gave up after 256 triangles without reaching the target.
    pub gave_up: bool,
}

/// Walks the straight segment from `from` (inside triangle `start`) to `to`, both in
/// `start`'s chart's atlas texels, over the surface: inside a chart the atlas is
/// continuous; across a chart seam the next triangle is unfolded about the shared edge
/// into the current triangle's plane, which gives the affine map from this chart's atlas
/// to the next one's, and the rest of the segment continues there. Ends at `to` (in the
/// frame of the chart it reached), or on a mesh boundary / non-manifold edge.
fn walk(
    tris: &[Tri],
    adjacency: &[[Option<u32>; 3]],
    chart_of_triangle: &[u32],
    start: u32,
    from: Vec2,
    to: Vec2,
) -> WalkEnd {
    let mut t = start as usize;
    let (mut p, mut x) = (from, to);
    let mut crossed = false;
    for _ in 0..256 {
        let tri = &tris[t];
        let bx = barycentric_2d(tri.uv, tri.uv_area, x);
        if bx.iter().all(|&v| v >= -1e-5) {
            return WalkEnd {
                tri: t as u32,
                point: x,
                crossed,
                boundary: false,
                gave_up: false,
            };
        }
        let bp = barycentric_2d(tri.uv, tri.uv_area, p);
        // Leave through the edge opposite the corner whose coordinate reaches 0 first.
        let mut exit_corner = 0;
        let mut exit_t = f32::INFINITY;
        for j in 0..3 {
            if bx[j] < 0.0 {
                let denom = bp[j] - bx[j];
                let s = if denom > 0.0 {
                    (bp[j] / denom).max(0.0)
                } else {
                    0.0
                };
                if s < exit_t {
                    exit_t = s;
                    exit_corner = j;
                }
            }
        }
        let exit = p + (x - p) * exit_t.min(1.0);
        let edge = (exit_corner + 1) % 3;
        let Some(next) = adjacency[t][edge] else {
            return WalkEnd {
                tri: t as u32,
                point: exit,
                crossed,
                boundary: true,
                gave_up: false,
            };
        };
        let next = next as usize;
        let (a, b) = (edge, (edge + 1) % 3);
        let nt = &tris[next];
        // Corners of `next` on the shared edge, by position.
        let find = |q: Vec3| {
            (0..3).min_by(|&i, &j| {
                nt.p[i]
                    .distance_squared(q)
                    .total_cmp(&nt.p[j].distance_squared(q))
            })
        };
        let (na, nb) = (find(tri.p[a]).unwrap(), find(tri.p[b]).unwrap());
        let nc = 3 - na - nb;
        let same_chart = chart_of_triangle[t] == chart_of_triangle[next];
        let continuous = same_chart
            && nt.uv[na].distance_squared(tri.uv[a]) < 1e-6
            && nt.uv[nb].distance_squared(tri.uv[b]) < 1e-6;
        if !continuous {
            crossed = true;
            match unfold_map(tri, a, b, nt, na, nb, nc) {
                Some(m) => {
                    p = m(exit);
                    x = m(x);
                }
                None => {
                    return WalkEnd {
                        tri: t as u32,
                        point: exit,
                        crossed,
                        boundary: true,
                        gave_up: false,
                    }
                }
            }
        } else {
            p = exit;
        }
        t = next;
    }
    WalkEnd {
        tri: t as u32,
        point: p,
        crossed,
        boundary: false,
        gave_up: true,
    }
}

/// The affine map from `tri`'s atlas frame to `nt`'s, unfolding `nt` about the shared
/// edge (`tri` corners a, b = `nt` corners na, nb; nc is `nt`'s third corner).
fn unfold_map(
    tri: &Tri,
    a: usize,
    b: usize,
    nt: &Tri,
    na: usize,
    nb: usize,
    nc: usize,
) -> Option<impl Fn(Vec2) -> Vec2> {
    let c = 3 - a - b;
    let e = tri.p[b] - tri.p[a];
    let e2 = e.length_squared();
    if e2 == 0.0 {
        return None;
    }
    let along = |q: Vec3| (q - tri.p[a]).dot(e) / e2;
    // In-plane unit vector perpendicular to the edge, towards tri's third corner.
    let to_c = tri.p[c] - tri.p[a];
    let m = (to_c - e * along(tri.p[c])).normalize_or_zero();
    let to_nc = nt.p[nc] - tri.p[a];
    let alpha = along(nt.p[nc]);
    let dist = (to_nc - e * alpha).length();
    let q = tri.p[a] + e * alpha - m * dist;
    // q's atlas position in tri's frame: tri's affine map of its own plane.
    let uv_q = {
        let (q1, q2) = (tri.p[1] - tri.p[0], tri.p[2] - tri.p[0]);
        let v = q - tri.p[0];
        let (g11, g12, g22) = (q1.dot(q1), q1.dot(q2), q2.dot(q2));
        let det = g11 * g22 - g12 * g12;
        if det.abs() < 1e-20 {
            return None;
        }
        let (r1, r2) = (v.dot(q1), v.dot(q2));
        let w1 = (g22 * r1 - g12 * r2) / det;
        let w2 = (g11 * r2 - g12 * r1) / det;
        tri.uv[0] + (tri.uv[1] - tri.uv[0]) * w1 + (tri.uv[2] - tri.uv[0]) * w2
    };
    // Affine: (uv_a, uv_b, uv_q) in tri's frame -> (nt uv na, nb, nc).
    let s1 = tri.uv[b] - tri.uv[a];
    let s2 = uv_q - tri.uv[a];
    let det = s1.perp_dot(s2);
    if det.abs() < 1e-12 {
        return None;
    }
    let d1 = nt.uv[nb] - nt.uv[na];
    let d2 = nt.uv[nc] - nt.uv[na];
    let (origin_src, origin_dst) = (tri.uv[a], nt.uv[na]);
    Some(move |x: Vec2| {
        let v = x - origin_src;
        // Coordinates of v in the basis (s1, s2).
        let k1 = v.perp_dot(s2) / det;
        let k2 = s1.perp_dot(v) / det;
        origin_dst + d1 * k1 + d2 * k2
    })
}

/// The geometry helpers, exposed for the seam measurements and tests.
pub struct SurfaceGeometry {
    tris: Vec<Tri>,
    adjacency: Vec<[Option<u32>; 3]>,
}

impl SurfaceGeometry {
    /// Per-triangle atlas corners, `Jf` and triangle adjacency of `atlas`'s mesh.
    pub fn new(atlas: &Atlas) -> Self {
        let mesh = &atlas.mesh;
        let tris = (0..mesh.triangles.len())
            .map(|t| {
                let uv = atlas.uv_texels(t);
                let p = mesh.corners(t);
                let (e1, e2) = (uv[1] - uv[0], uv[2] - uv[0]);
                let det = e1.perp_dot(e2);
                let (q1, q2) = (p[1] - p[0], p[2] - p[0]);
                let inv = if det != 0.0 {
                    [[e2.y / det, -e2.x / det], [-e1.y / det, e1.x / det]]
                } else {
                    [[0.0; 2]; 2]
                };
                Tri {
                    uv,
                    p,
                    uv_area: det,
                    jf: [
                        q1 * inv[0][0] + q2 * inv[1][0],
                        q1 * inv[0][1] + q2 * inv[1][1],
                    ],
                }
            })
            .collect();
        Self {
            tris,
            adjacency: mesh.triangle_adjacency(),
        }
    }

    /// Triangle `t`'s atlas corners (finest texels), their signed area, and `Jf`'s
    /// columns d(surface)/d(atlas x), d(surface)/d(atlas y) (zero for a flat triangle).
    pub fn triangle(&self, t: usize) -> ([Vec2; 3], f32, [Vec3; 2]) {
        let tri = &self.tris[t];
        (tri.uv, tri.uv_area, tri.jf)
    }

    /// Walks the straight segment from `from` (inside triangle `start`) to `to`, both in
    /// `start`'s chart's atlas texels (finest level), over the surface of `atlas`: across a
    /// chart seam the next triangle is unfolded about the shared edge and the segment
    /// continues in that chart's frame. `atlas` must be the one this geometry was built from.
    pub fn walk(&self, atlas: &Atlas, start: u32, from: Vec2, to: Vec2) -> WalkEnd {
        walk(
            &self.tris,
            &self.adjacency,
            &atlas.chart_of_triangle,
            start,
            from,
            to,
        )
    }
}
