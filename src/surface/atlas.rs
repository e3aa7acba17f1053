//! The texture atlas that surface synthesis runs in: the mesh's own `TEXCOORD_0` when
//! it is a valid atlas (inside [0, 1], no overlapping charts, gutters wide enough for the
//! indirection band), otherwise one built with xatlas.
//!
//! Atlas texel coordinates: `uv * size`, x right, y down (glTF's v points down the
//! image), texel `(i, j)` covers `[i, i+1) x [j, j+1)`, its centre is `(i+0.5, j+0.5)`.

use glam::Vec2;

use super::mesh::Mesh;
use crate::error::{Error, Result};

/// Where the atlas comes from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum AtlasSource {
    /// Keep the mesh's `TEXCOORD_0` if it is a valid atlas, otherwise generate one.
    #[default]
    Auto,
    /// Keep `TEXCOORD_0`; an error if it is missing or unusable.
    Keep,
    /// Always generate one with xatlas.
    Generate,
}

/// How to obtain the atlas: its size, gutter and source.
#[derive(Clone, Debug, PartialEq)]
pub struct AtlasOptions {
    /// Atlas side in texels (square).
    pub size: u32,
    /// Free texels required between charts at the finest level.
    pub gutter: u32,
    /// Keep the mesh's own uvs, generate an atlas, or decide automatically.
    pub source: AtlasSource,
}

impl Default for AtlasOptions {
    fn default() -> Self {
        Self::for_size(1024)
    }
}

impl AtlasOptions {
    /// Options for a `size` atlas: exact indirection bands on the 3 finest levels from
    /// 512 texels up, 2 from 128, 1 below (smaller atlases cannot spare the gutter).
    pub fn for_size(size: u32) -> Self {
        let exact = match size {
            512.. => 3,
            128..512 => 2,
            _ => 1,
        };
        Self {
            size,
            gutter: default_gutter(exact),
            source: AtlasSource::Auto,
        }
    }
}

/// Gutter (finest texels between charts) that gives every one of the `exact_levels`
/// finest synthesis levels its own 2-texel indirection band on both sides of a gap:
/// `4 * 2^(exact_levels - 1)` plus one texel for rounding. Coarser levels share gutter
/// texels between neighbouring charts (nearest chart wins), which their jitter hides.
pub fn default_gutter(exact_levels: u32) -> u32 {
    4 * (1 << exact_levels.saturating_sub(1)) + 1
}

/// A mesh with an atlas parameterization.
#[derive(Clone, Debug)]
pub struct Atlas {
    /// Atlas side in texels (square).
    pub size: u32,
    /// The mesh, vertices split where charts are cut; `uvs` is the atlas.
    pub mesh: Mesh,
    /// Chart index of every triangle.
    pub chart_of_triangle: Vec<u32>,
    /// Number of charts.
    pub chart_count: u32,
    /// True if xatlas built it; `note` says why the input's was not used.
    pub generated: bool,
    /// Why the input mesh's own atlas was not kept (empty when it was).
    pub note: String,
    /// For each vertex of `mesh`, the vertex of the mesh the atlas was built from that
    /// it was split from (the identity where the mesh's own atlas is kept): per-vertex
    /// data of the input mesh maps onto the atlas mesh through it.
    pub source_vertex: Vec<u32>,
    /// Vertices of the mesh the atlas was built from.
    pub source_vertex_count: usize,
}

impl Atlas {
    /// Corner positions of triangle `t` in atlas texels (finest level).
    pub fn uv_texels(&self, t: usize) -> [Vec2; 3] {
        let uvs = self.mesh.uvs.as_ref().expect("an atlas mesh has uvs");
        let s = self.size as f32;
        self.mesh.triangles[t].map(|v| uvs[v as usize] * s)
    }

    /// Fraction of the atlas texels whose centre lies in a chart.
    pub fn coverage(&self) -> f64 {
        let ids = rasterize(self, 0);
        ids.iter().filter(|&&t| t != NONE).count() as f64 / ids.len() as f64
    }
}

/// "No triangle" in a raster.
pub const NONE: u32 = u32::MAX;

/// Builds the atlas per `opts`.
pub fn build_atlas(mesh: &Mesh, opts: &AtlasOptions) -> Result<Atlas> {
    mesh.check()?;
    if mesh.normals.len() != mesh.positions.len() {
        return Err(Error::InvalidParameter(format!(
            "mesh has {} normals for {} positions; Mesh::validate_and_repair computes the \
             missing ones",
            mesh.normals.len(),
            mesh.positions.len()
        )));
    }
    if !(8..=16384).contains(&opts.size) {
        return Err(Error::InvalidParameter(format!(
            "atlas size {}: use 8 to 16384 texels",
            opts.size
        )));
    }
    let keep_reason = match (&mesh.uvs, opts.source) {
        (_, AtlasSource::Generate) => Some("an atlas was requested".to_string()),
        (None, AtlasSource::Keep) => {
            return Err(Error::InvalidParameter(
                "the mesh has no TEXCOORD_0 to keep; let texsyn build an atlas".into(),
            ))
        }
        (None, _) => Some("the mesh has no TEXCOORD_0".to_string()),
        (Some(_), _) => match check_existing(mesh, opts) {
            Ok(atlas) => return Ok(atlas),
            Err(why) if opts.source == AtlasSource::Keep => {
                return Err(Error::InvalidParameter(format!(
                    "the mesh's TEXCOORD_0 is not a usable atlas: {why}"
                )))
            }
            Err(why) => Some(format!("its TEXCOORD_0 is not a usable atlas ({why})")),
        },
    };
    let reason = keep_reason.unwrap_or_default();
    let mut atlas = generate(mesh, opts).map_err(|e| match e {
        Error::InvalidParameter(m) if !cfg!(feature = "xatlas") => {
            Error::InvalidParameter(format!("{reason}, and {m}"))
        }
        e => e,
    })?;
    atlas.note = reason;
    Ok(atlas)
}

/// Charts of an existing parameterization: triangles connected across edges whose two
/// vertices have the same position and uv on both sides.
fn charts_of_uvs(mesh: &Mesh) -> (Vec<u32>, u32) {
    let uvs = mesh.uvs.as_ref().unwrap();
    let key = |v: u32| {
        let p = mesh.positions[v as usize];
        let u = uvs[v as usize];
        [p.x, p.y, p.z, u.x, u.y].map(f32::to_bits)
    };
    let mut edges: std::collections::HashMap<([u32; 5], [u32; 5]), Vec<u32>> =
        std::collections::HashMap::new();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for i in 0..3 {
            let (a, b) = (key(tri[i]), key(tri[(i + 1) % 3]));
            let k = if a < b { (a, b) } else { (b, a) };
            edges.entry(k).or_default().push(t as u32);
        }
    }
    let n = mesh.triangles.len();
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn find(p: &mut [u32], mut x: u32) -> u32 {
        while p[x as usize] != x {
            p[x as usize] = p[p[x as usize] as usize];
            x = p[x as usize];
        }
        x
    }
    for ts in edges.values() {
        for w in ts.windows(2) {
            let (a, b) = (find(&mut parent, w[0]), find(&mut parent, w[1]));
            if a != b {
                parent[a.max(b) as usize] = a.min(b);
            }
        }
    }
    let mut ids = vec![NONE; n];
    let mut chart = vec![0u32; n];
    let mut count = 0;
    for (t, ch) in chart.iter_mut().enumerate() {
        let r = find(&mut parent, t as u32) as usize;
        if ids[r] == NONE {
            ids[r] = count;
            count += 1;
        }
        *ch = ids[r];
    }
    (chart, count)
}

/// Validates the mesh's own uvs as an atlas of `opts.size` with `opts.gutter`.
fn check_existing(mesh: &Mesh, opts: &AtlasOptions) -> std::result::Result<Atlas, String> {
    let uvs = mesh.uvs.as_ref().unwrap();
    if let Some(u) = uvs
        .iter()
        .find(|u| !u.is_finite() || u.x < 0.0 || u.y < 0.0 || u.x > 1.0 || u.y > 1.0)
    {
        return Err(format!("a uv ({}, {}) lies outside [0, 1]", u.x, u.y));
    }
    let (chart_of_triangle, chart_count) = charts_of_uvs(mesh);
    let atlas = Atlas {
        size: opts.size,
        mesh: mesh.clone(),
        chart_of_triangle,
        chart_count,
        generated: false,
        note: String::new(),
        source_vertex: (0..mesh.positions.len() as u32).collect(),
        source_vertex_count: mesh.positions.len(),
    };
    let s = opts.size as f32;
    let flat = (0..mesh.triangles.len())
        .filter(|&t| {
            let [a, b, c] = atlas.uv_texels(t);
            ((b - a).perp_dot(c - a)).abs() < 1e-6 * s
        })
        .count();
    if flat > 0 {
        return Err(format!("{flat} triangles have no area in uv space"));
    }
    let (ids, overlaps) = rasterize_counting(&atlas, 0);
    if overlaps > 0 {
        return Err(format!(
            "atlas texels are covered by more than one triangle ({overlaps} second coverings: overlapping or mirrored-onto-itself charts)"
        ));
    }
    let chart_raster: Vec<u32> = ids
        .iter()
        .map(|&t| {
            if t == NONE {
                NONE
            } else {
                atlas.chart_of_triangle[t as usize]
            }
        })
        .collect();
    if let Some(d) = seam_near_border(mesh, opts.size, opts.gutter) {
        return Err(format!(
            "a chart seam comes within {d:.1} texels of the atlas border at {0}x{0} (the uvs \
             wrap around or fill the atlas); the indirection band across it needs {1} (let \
             texsyn build an atlas, or leave a margin in the uvs)",
            opts.size, opts.gutter
        ));
    }
    if let Some(gap) = narrowest_gap(&chart_raster, opts.size, opts.gutter) {
        return Err(format!(
            "charts come within {gap} texels of each other at {0}x{0}; the indirection band needs {1} (use a larger atlas, or let texsyn build one)",
            opts.size, opts.gutter
        ));
    }
    Ok(atlas)
}

/// The nearest distance (texels, < `gutter`) from the atlas border of a seam edge: an
/// edge whose two triangles meet in 3D but not in uv space (two charts, or a chart that
/// wraps around onto itself, as a sphere's u = 0 and u = 1). The indirection band across
/// it lies in the gutter around it, which the border cuts off (the texture is sampled
/// clamped there): a visible line. Boundary edges of an open mesh need no band.
fn seam_near_border(mesh: &Mesh, size: u32, gutter: u32) -> Option<f32> {
    let uvs = mesh.uvs.as_ref()?;
    let (weld, _) = mesh.welded_vertex_ids();
    let adjacency = mesh.triangle_adjacency();
    let s = size as f32;
    let g = gutter as f32;
    let mut nearest: Option<f32> = None;
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for (e, other) in adjacency[t].iter().enumerate() {
            let Some(o) = *other else { continue };
            let (a, b) = (tri[e], tri[(e + 1) % 3]);
            let other = &mesh.triangles[o as usize];
            let same_uv = |v: u32| {
                other
                    .iter()
                    .find(|&&w| weld[w as usize] == weld[v as usize])
                    .is_some_and(|&w| uvs[w as usize] == uvs[v as usize])
            };
            if same_uv(a) && same_uv(b) {
                continue;
            }
            for v in [a, b] {
                let p = uvs[v as usize] * s;
                let d = p.x.min(p.y).min(s - p.x).min(s - p.y);
                if d < g && nearest.is_none_or(|n| d < n) {
                    nearest = Some(d);
                }
            }
        }
    }
    nearest
}

/// Smallest Chebyshev distance (< `gutter`) between texels of different charts, or None
/// if every pair is at least `gutter` apart. Multi-source BFS, fronts carry chart ids.
fn narrowest_gap(chart: &[u32], size: u32, gutter: u32) -> Option<u32> {
    let n = size as i32;
    let mut owner = chart.to_vec();
    let mut dist = vec![u32::MAX; chart.len()];
    let mut front: Vec<usize> = Vec::new();
    for (i, &c) in chart.iter().enumerate() {
        if c != NONE {
            dist[i] = 0;
            front.push(i);
        }
    }
    let mut best: Option<u32> = None;
    let mut d = 0;
    while !front.is_empty() && d < gutter {
        let mut next = Vec::new();
        for &i in &front {
            let (x, y) = ((i as i32) % n, (i as i32) / n);
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let (qx, qy) = (x + dx, y + dy);
                    if qx < 0 || qy < 0 || qx >= n || qy >= n {
                        continue;
                    }
                    let q = (qy * n + qx) as usize;
                    if owner[q] == NONE {
                        owner[q] = owner[i];
                        dist[q] = d + 1;
                        next.push(q);
                    } else if owner[q] != owner[i] {
                        // Two fronts meet: the charts are dist[i] + dist[q] + 1 apart.
                        let gap = dist[i] + dist[q] + 1;
                        if gap < gutter + 1 {
                            best = Some(best.map_or(gap - 1, |b| b.min(gap - 1)));
                        }
                    }
                }
            }
        }
        front = next;
        d += 1;
    }
    best
}

/// Triangle id per texel of level `steps` (texel centre inside the triangle), NONE
/// outside. Ties on shared edges go to the lower id.
pub fn rasterize(atlas: &Atlas, steps: u32) -> Vec<u32> {
    rasterize_counting(atlas, steps).0
}

/// [`rasterize`], plus the number of texels covered by triangles of more than one chart.
pub fn rasterize_counting(atlas: &Atlas, steps: u32) -> (Vec<u32>, usize) {
    let size = level_size(atlas.size, steps) as i32;
    let scale = 1.0 / (1u32 << steps) as f32;
    let mut ids = vec![NONE; (size * size) as usize];
    let mut overlaps = 0;
    for t in 0..atlas.mesh.triangles.len() {
        let c = atlas.uv_texels(t).map(|p| p * scale);
        let lo = c[0].min(c[1]).min(c[2]);
        let hi = c[0].max(c[1]).max(c[2]);
        let x0 = (lo.x - 0.5).ceil().max(0.0) as i32;
        let y0 = (lo.y - 0.5).ceil().max(0.0) as i32;
        let x1 = ((hi.x - 0.5).floor() as i32).min(size - 1);
        let y1 = ((hi.y - 0.5).floor() as i32).min(size - 1);
        let area = (c[1] - c[0]).perp_dot(c[2] - c[0]);
        if area == 0.0 {
            continue;
        }
        for y in y0..=y1 {
            for x in x0..=x1 {
                let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let w = barycentric_2d(c, area, p);
                if w.iter().all(|&v| v >= -1e-6) {
                    let i = (y * size + x) as usize;
                    if ids[i] == NONE {
                        ids[i] = t as u32;
                    } else if atlas.chart_of_triangle[ids[i] as usize] != atlas.chart_of_triangle[t]
                        || w.iter().all(|&v| v > 1e-3)
                    {
                        overlaps += 1;
                    }
                }
            }
        }
    }
    (ids, overlaps)
}

/// Barycentric coordinates of `p` in the 2D triangle `c` (signed area `area`).
pub fn barycentric_2d(c: [Vec2; 3], area: f32, p: Vec2) -> [f32; 3] {
    let w0 = (c[1] - p).perp_dot(c[2] - p) / area;
    let w1 = (c[2] - p).perp_dot(c[0] - p) / area;
    [w0, w1, 1.0 - w0 - w1]
}

/// Side of level `steps` of an atlas of `size` (halved, rounded up).
pub fn level_size(size: u32, steps: u32) -> u32 {
    let mut s = size;
    for _ in 0..steps {
        s = s.div_ceil(2);
    }
    s
}

/// Without the `xatlas` feature there is no atlas generator.
#[cfg(not(feature = "xatlas"))]
fn generate(_mesh: &Mesh, _opts: &AtlasOptions) -> Result<Atlas> {
    Err(Error::InvalidParameter(
        "this build of texsyn cannot generate an atlas (its `xatlas` feature is off): give the \
         mesh a usable TEXCOORD_0 atlas, or build texsyn with the `xatlas` feature"
            .into(),
    ))
}

/// One xatlas packing: vertices, indices, per-triangle charts, chart count and the
/// packed extent in xatlas texels (padding included).
#[cfg(feature = "xatlas")]
type Packed = (Vec<xatlas_rs::Vertex>, Vec<u32>, Vec<u32>, u32, f64);

/// Runs xatlas: charts, parameterization, packing into one `size` x `size` atlas with
/// `gutter` texels between charts.
#[cfg(feature = "xatlas")]
fn generate(mesh: &Mesh, opts: &AtlasOptions) -> Result<Atlas> {
    // xatlas works in the mesh's units; normalize so its tolerances see a unit-sized
    // mesh whatever the modelling scale (uvs do not depend on the scale). The area is
    // measured after normalizing, in f64: a valid mesh modelled at 1e-15 units has
    // triangle areas that underflow in f32.
    let (lo, hi) = mesh.bounding_box();
    let unit = 1.0 / (hi - lo).as_dvec3().length().max(f64::MIN_POSITIVE);
    let normalized: Vec<glam::DVec3> = mesh
        .positions
        .iter()
        .map(|p| (p.as_dvec3() - lo.as_dvec3()) * unit)
        .collect();
    let area: f64 = mesh
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| normalized[i as usize]);
            0.5 * (b - a).cross(c - a).length()
        })
        .sum();
    if !area.is_finite() || area <= 0.0 {
        return Err(Error::InvalidParameter(
            "the mesh has no surface area to build an atlas on (every triangle is \
             degenerate, or its coordinates are not finite)"
                .into(),
        ));
    }
    // The f32 factor the packing always used, unless the extent underflows in f32.
    let extent32 = (hi - lo).length();
    let unit32 = if extent32.is_normal() {
        1.0 / extent32
    } else {
        unit as f32
    };
    let positions: Vec<f32> = mesh
        .positions
        .iter()
        .flat_map(|p| ((*p - lo) * unit32).to_array())
        .collect();
    let normals: Vec<f32> = mesh.normals.iter().flat_map(|p| p.to_array()).collect();
    let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
    let bytes = |v: &[f32]| -> Vec<u8> { bytemuck::cast_slice(v).to_vec() };
    let pos_bytes = bytes(&positions);
    let nrm_bytes = bytes(&normals);
    let idx_bytes: Vec<u8> = bytemuck::cast_slice(&indices).to_vec();
    let n = opts.size as f64;
    // Texels per world unit: aim at ~60% of the atlas covered, then correct by what the
    // packer achieved (the final uvs are rescaled to the atlas, which scales the gutter
    // too, so the padding asked for is adjusted to land on `gutter` after rescaling).
    let mut tpu = (0.6 * n * n / area).sqrt();
    let mut best: Option<Packed> = None;
    // xatlas's random placement puts a chart it found no room for after `attempts` tries
    // at (0, 0), onto another chart (a cube at 512 or 1024: two faces shared, mirrored,
    // one texture). Each packing is checked, and after an overlap the placement is
    // exhaustive (attempts 0), slower but exact.
    let mut exhaustive = false;
    let mut overlapped = 0usize;
    for _attempt in 0..6 {
        let padding = opts.gutter + 1;
        let mut xa = xatlas_rs::Xatlas::new();
        xa.add_mesh(&xatlas_rs::MeshDecl {
            vertex_count: mesh.positions.len() as u32,
            vertex_position_data: &pos_bytes,
            vertex_position_stride: 12,
            vertex_normal_data: if normals.len() == positions.len() {
                &nrm_bytes
            } else {
                &[]
            },
            vertex_normal_stride: 12,
            index_count: indices.len() as u32,
            index_data: &idx_bytes,
            index_format: xatlas_rs::IndexFormat::Uint32,
            ..Default::default()
        });
        xa.generate_simple(
            xatlas_rs::ChartOptions::default(),
            xatlas_rs::PackOptions {
                attempts: if exhaustive { 0 } else { 64 },
                texels_per_unit: tpu as f32,
                resolution: 0,
                max_chart_size: opts.size,
                block_align: false,
                conservative: true,
                padding,
            },
        );
        let meshes = xa.meshes();
        let Some(m) = meshes.first() else {
            return Err(Error::InvalidParameter("xatlas produced no mesh".into()));
        };
        let verts: Vec<xatlas_rs::Vertex> = m
            .vertices
            .iter()
            .map(|v| xatlas_rs::Vertex {
                atlas_index: v.atlas_index,
                uv: v.uv,
                xref: v.xref,
            })
            .collect();
        let idx = m.indices.to_vec();
        // Chart of each output vertex (vertices are split at chart boundaries).
        let mut chart_of_vertex = vec![NONE; verts.len()];
        for (c, chart) in m.charts.iter().enumerate() {
            for &v in chart.indices {
                if let Some(slot) = chart_of_vertex.get_mut(v as usize) {
                    *slot = c as u32;
                }
            }
        }
        let chart_count = m.charts.len() as u32;
        drop(meshes);
        drop(xa);
        if verts.iter().any(|v| v.atlas_index != 0) || idx.len() != indices.len() {
            return Err(Error::InvalidParameter(format!(
                "xatlas could not place every triangle in one atlas ({} of {} indices)",
                idx.len(),
                indices.len()
            )));
        }
        let extent = verts
            .iter()
            .map(|v| v.uv[0].max(v.uv[1]) as f64)
            .fold(0.0, f64::max)
            + padding as f64;
        let chart_of_triangle: Vec<u32> = idx
            .chunks(3)
            .map(|t| chart_of_vertex[t[0] as usize])
            .collect();
        if chart_of_triangle.contains(&NONE) {
            return Err(Error::InvalidParameter(
                "xatlas left triangles outside every chart".into(),
            ));
        }
        let scale = 1.0 / extent.max(n) as f32;
        let probe = Atlas {
            size: opts.size,
            mesh: Mesh {
                positions: vec![glam::Vec3::ZERO; verts.len()],
                normals: Vec::new(),
                uvs: Some(
                    verts
                        .iter()
                        .map(|v| Vec2::new(v.uv[0], v.uv[1]) * scale)
                        .collect(),
                ),
                tangents: None,
                triangles: idx.chunks(3).map(|t| [t[0], t[1], t[2]]).collect(),
            },
            chart_of_triangle: chart_of_triangle.clone(),
            chart_count,
            generated: true,
            note: String::new(),
            source_vertex: Vec::new(),
            source_vertex_count: mesh.positions.len(),
        };
        let (_, overlaps) = rasterize_counting(&probe, 0);
        if overlaps > 0 {
            overlapped = overlaps;
            exhaustive = true;
            continue;
        }
        let ratio = n / extent;
        best = Some((verts, idx, chart_of_triangle, chart_count, extent));
        if (0.9..=1.0).contains(&ratio) {
            break;
        }
        // Aim slightly under the atlas so the rescale rarely shrinks the gutter.
        tpu *= ratio * 0.985;
    }
    let Some((verts, idx, chart_of_triangle, chart_count, extent)) = best else {
        return Err(Error::InvalidParameter(format!(
            "xatlas packed overlapping charts at {0}x{0} ({overlapped} second coverings of \
             texels) \
             however it was asked; try another --atlas-size, or give the mesh its own \
             TEXCOORD_0 atlas",
            opts.size
        )));
    };
    let scale = 1.0 / extent.max(n) as f32;
    let pick = |xref: u32| xref as usize;
    let out = Mesh {
        positions: verts.iter().map(|v| mesh.positions[pick(v.xref)]).collect(),
        normals: verts.iter().map(|v| mesh.normals[pick(v.xref)]).collect(),
        uvs: Some(
            verts
                .iter()
                .map(|v| Vec2::new(v.uv[0], v.uv[1]) * scale)
                .collect(),
        ),
        tangents: mesh
            .tangents
            .as_ref()
            .map(|t| verts.iter().map(|v| t[pick(v.xref)]).collect()),
        triangles: idx.chunks(3).map(|t| [t[0], t[1], t[2]]).collect(),
    };
    Ok(Atlas {
        size: opts.size,
        mesh: out,
        chart_of_triangle,
        chart_count,
        generated: true,
        note: String::new(),
        source_vertex: verts.iter().map(|v| v.xref).collect(),
        source_vertex_count: mesh.positions.len(),
    })
}
