//! The welded-vertex graph on which direction fields are built and relaxed: local
//! tangent frames, parallel transport between neighbours, n-RoSy relaxation and
//! singularity detection.

use std::collections::HashMap;
use std::f32::consts::TAU;

use glam::{Quat, Vec3};

use super::field::face_or_vertex_normal;
use crate::surface::mesh::Mesh;

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
pub(super) struct Graph {
    /// Node of each mesh vertex.
    pub(super) id: Vec<u32>,
    pub(super) count: usize,
    /// First mesh vertex of each node.
    pub(super) rep: Vec<u32>,
    pub(super) pos: Vec<Vec3>,
    pub(super) normal: Vec<Vec3>,
    /// Reference tangent `e` of each node's frame (`f = n x e`); angles are measured
    /// counter-clockwise about `n` from `e`.
    pub(super) e: Vec<Vec3>,
    pub(super) used: Vec<bool>,
    /// Per node p: neighbours q with the angle `rho` such that a direction at angle `a`
    /// in q's frame, carried to p by the minimal rotation between the normals, has angle
    /// `a + rho` in p's frame.
    pub(super) nbrs: Vec<Vec<(u32, f32)>>,
    /// Triangles as node triples.
    pub(super) tris: Vec<[u32; 3]>,
}

impl Graph {
    pub(super) fn new(mesh: &Mesh) -> Graph {
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

    pub(super) fn f(&self, p: usize) -> Vec3 {
        self.normal[p].cross(self.e[p])
    }

    pub(super) fn angle_of(&self, p: usize, d: Vec3) -> f32 {
        d.dot(self.f(p)).atan2(d.dot(self.e[p]))
    }

    pub(super) fn dir_of(&self, p: usize, a: f32) -> Vec3 {
        self.e[p] * a.cos() + self.f(p) * a.sin()
    }

    /// `rho` of carrying q's frame to p (see `nbrs`).
    pub(super) fn transport(&self, q: usize, p: usize) -> f32 {
        let r = Quat::from_rotation_arc(self.normal[q], self.normal[p]);
        self.angle_of(p, r * self.e[q])
    }

    /// Gauss-Seidel relaxation of an n-RoSy field given as angles.
    pub(super) fn relax(&self, theta: &mut [f32], n: u32, fixed: &[bool], iterations: u32) {
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
    pub(super) fn corners_from_angles(&self, mesh: &Mesh, theta: &[f32], n: u32) -> Vec<[Vec3; 3]> {
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

    /// Singular vertices and their index; see
    /// [`TangentField::singularities`](super::TangentField::singularities).
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
    pub(super) fn singularities(&self, theta: &[f32], n: u32) -> Vec<(u32, f32)> {
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
pub(super) fn up_angles(g: &Graph, up: Vec3) -> Vec<f32> {
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
pub(super) fn constraint_angles(
    g: &Graph,
    mesh: &Mesh,
    list: &[(Vec3, Vec3)],
) -> (Vec<f32>, Vec<bool>) {
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
