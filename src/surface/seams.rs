//! How visible the chart seams of a synthesized atlas are: along every seam edge (a mesh
//! edge where the atlas is cut), the colours on its two sides at the same surface
//! points, compared with the colour difference between neighbouring texels inside
//! charts. Each side is read only from its own chart's texels (bilinear weights of the
//! chart texels, renormalized), so the gutters' continued texture does not help.

use glam::Vec2;

use super::atlas::{rasterize, Atlas, NONE};

/// How visible chart seams are in a synthesized atlas ([`seam_report`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SeamReport {
    /// Mean absolute RGB difference (0-255) across seams, at the same surface points.
    pub seam: f64,
    /// Mean absolute RGB difference between horizontally or vertically adjacent texels
    /// of the same chart.
    pub interior: f64,
    /// `seam / interior`: 1 means a seam is as visible as any step between texels.
    pub ratio: f64,
    /// Mesh edges cut by the atlas (different charts or different uvs on the two sides).
    pub seam_edges: usize,
    /// Points sampled along those edges (every half texel).
    pub samples: usize,
}

impl std::fmt::Display for SeamReport {
    /// `N seam edges, colour step across seams S vs I between neighbouring texels
    /// (ratio R)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} seam edges, colour step across seams {:.2} vs {:.2} between neighbouring texels (ratio {:.2})",
            self.seam_edges, self.seam, self.interior, self.ratio
        )
    }
}

/// Measures `colors` (RGBA8, the atlas' finest level, row-major). Colours of another
/// count than the atlas' texels measure nothing: every figure NaN, no edges.
pub fn seam_report(atlas: &Atlas, colors: &[[u8; 4]]) -> SeamReport {
    let size = atlas.size as usize;
    if colors.len() != size * size {
        return SeamReport {
            seam: f64::NAN,
            interior: f64::NAN,
            ratio: f64::NAN,
            ..SeamReport::default()
        };
    }
    let ids = rasterize(atlas, 0);
    let chart_at = |i: usize| {
        if ids[i] == NONE {
            NONE
        } else {
            atlas.chart_of_triangle[ids[i] as usize]
        }
    };
    let diff = |a: [f64; 3], b: [f64; 3]| {
        ((a[0] - b[0]).abs() + (a[1] - b[1]).abs() + (a[2] - b[2]).abs()) / 3.0
    };
    let rgb = |i: usize| {
        let c = colors[i];
        [c[0] as f64, c[1] as f64, c[2] as f64]
    };
    // Interior: neighbouring texels of one chart.
    let (mut sum, mut n) = (0.0, 0usize);
    for y in 0..size {
        for x in 0..size {
            let i = y * size + x;
            let c = chart_at(i);
            if c == NONE {
                continue;
            }
            for j in [i + 1, i + size] {
                let ok = (j == i + 1 && x + 1 < size) || (j == i + size && y + 1 < size);
                if ok && chart_at(j) == c {
                    sum += diff(rgb(i), rgb(j));
                    n += 1;
                }
            }
        }
    }
    let interior = sum / n.max(1) as f64;

    // Colour of chart `c` at atlas point `x`, from that chart's texels only.
    let sample = |c: u32, x: Vec2| -> Option<[f64; 3]> {
        let f = x - Vec2::splat(0.5);
        let (x0, y0) = (f.x.floor() as i64, f.y.floor() as i64);
        let (fx, fy) = ((f.x - x0 as f32) as f64, (f.y - y0 as f32) as f64);
        let mut acc = [0.0; 3];
        let mut wsum = 0.0;
        for (dx, dy, w) in [
            (0, 0, (1.0 - fx) * (1.0 - fy)),
            (1, 0, fx * (1.0 - fy)),
            (0, 1, (1.0 - fx) * fy),
            (1, 1, fx * fy),
        ] {
            let (px, py) = (x0 + dx, y0 + dy);
            if px < 0 || py < 0 || px >= size as i64 || py >= size as i64 {
                continue;
            }
            let i = py as usize * size + px as usize;
            if chart_at(i) == c && w > 0.0 {
                let v = rgb(i);
                for k in 0..3 {
                    acc[k] += w * v[k];
                }
                wsum += w;
            }
        }
        (wsum > 1e-6).then(|| acc.map(|v| v / wsum))
    };
    let mesh = &atlas.mesh;
    let uvs = mesh.uvs.as_ref().expect("atlas mesh has uvs");
    let s = atlas.size as f32;
    let adjacency = mesh.triangle_adjacency();
    let (mut seam_sum, mut samples, mut edges) = (0.0, 0usize, 0usize);
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for e in 0..3 {
            let Some(t2) = adjacency[t][e] else { continue };
            let t2 = t2 as usize;
            if t2 < t {
                continue;
            }
            let (a, b) = (tri[e], tri[(e + 1) % 3]);
            let (pa, pb) = (mesh.positions[a as usize], mesh.positions[b as usize]);
            let other = mesh.triangles[t2];
            let find = |p: glam::Vec3| {
                *other
                    .iter()
                    .min_by(|&&i, &&j| {
                        mesh.positions[i as usize]
                            .distance_squared(p)
                            .total_cmp(&mesh.positions[j as usize].distance_squared(p))
                    })
                    .unwrap()
            };
            let (a2, b2) = (find(pa), find(pb));
            let (ua, ub) = (uvs[a as usize] * s, uvs[b as usize] * s);
            let (ua2, ub2) = (uvs[a2 as usize] * s, uvs[b2 as usize] * s);
            let (c1, c2) = (atlas.chart_of_triangle[t], atlas.chart_of_triangle[t2]);
            let cut =
                c1 != c2 || ua.distance_squared(ua2) > 1e-6 || ub.distance_squared(ub2) > 1e-6;
            if !cut {
                continue;
            }
            edges += 1;
            // Samples every half texel along the longer of the two images of the edge.
            let len = ua.distance(ub).max(ua2.distance(ub2));
            let k = ((len * 2.0).ceil() as usize).max(1);
            for i in 0..k {
                let f = (i as f32 + 0.5) / k as f32;
                let (x1, x2) = (ua.lerp(ub, f), ua2.lerp(ub2, f));
                if let (Some(v1), Some(v2)) = (sample(c1, x1), sample(c2, x2)) {
                    seam_sum += diff(v1, v2);
                    samples += 1;
                }
            }
        }
    }
    let seam = seam_sum / samples.max(1) as f64;
    SeamReport {
        seam,
        interior,
        ratio: if interior > 0.0 { seam / interior } else { 0.0 },
        seam_edges: edges,
        samples,
    }
}
