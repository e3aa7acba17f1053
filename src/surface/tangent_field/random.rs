//! Random per-region directions for isotropic textures
//! ([`DirectionSource::RandomPerRegion`](super::DirectionSource::RandomPerRegion)).

use std::collections::HashMap;
use std::f32::consts::TAU;

use glam::Vec3;

use super::field::face_or_vertex_normal;
use super::REGION_ANGLE_DEGREES;
use crate::surface::mesh::Mesh;

/// A well-mixed 64-bit hash (splitmix64 finalizer).
fn mix(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^ (x >> 31)
}

pub(super) fn random_corners(mesh: &Mesh, regions: Option<&[u32]>, seed: u32) -> Vec<[Vec3; 3]> {
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
