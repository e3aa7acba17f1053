//! Test meshes, mesh validation/repair, adjacency, and tangent fields (surface synthesis).

use std::f32::consts::PI;

use glam::{Vec3, Vec4};
use texsyn::surface::mesh::{Mesh, RepairReport};
use texsyn::surface::tangent_field::{
    parse_constraints, DirectionSource, ScaleSource, TangentField, DIRECTION_HELP, SCALE_HELP,
};

fn rel_err(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// Every (triangle, edge) has a neighbour, and the relation is symmetric.
fn assert_closed(mesh: &Mesh, name: &str) {
    let adj = mesh.triangle_adjacency();
    assert_eq!(adj.len(), mesh.triangles.len());
    for (t, edges) in adj.iter().enumerate() {
        for (i, nb) in edges.iter().enumerate() {
            let nb = nb.unwrap_or_else(|| panic!("{name}: triangle {t} edge {i} has no neighbour"));
            assert_ne!(nb as usize, t);
            assert!(
                adj[nb as usize].contains(&Some(t as u32)),
                "{name}: adjacency {t} -> {nb} is not symmetric"
            );
            // The neighbour really shares the edge's two positions.
            let [a, b] = [
                mesh.positions[mesh.triangles[t][i] as usize],
                mesh.positions[mesh.triangles[t][(i + 1) % 3] as usize],
            ];
            let other = mesh.corners(nb as usize);
            assert!(other.contains(&a) && other.contains(&b), "{name}: {t} {i}");
        }
    }
}

/// Winding agrees with the vertex normals (counter-clockwise seen from outside).
fn assert_winding_matches_normals(mesh: &Mesh, name: &str) {
    for t in 0..mesh.triangles.len() {
        let fnorm = mesh.face_normal(t);
        let vn: Vec3 = mesh.triangles[t]
            .iter()
            .map(|&v| mesh.normals[v as usize])
            .sum();
        assert!(
            fnorm.dot(vn) > 0.0,
            "{name}: triangle {t} winding disagrees with normals"
        );
    }
    for n in &mesh.normals {
        assert!(
            (n.length() - 1.0).abs() < 1e-4,
            "{name}: normal {n} is not unit"
        );
    }
}

fn centroid(mesh: &Mesh) -> Vec3 {
    mesh.positions.iter().copied().sum::<Vec3>() / mesh.positions.len() as f32
}

#[test]
fn generated_meshes_closed_open_areas_normals() {
    let sphere = Mesh::uv_sphere(2.0, 64, 32);
    assert_eq!(sphere.positions.len(), 64 * 31 + 2);
    assert!(sphere.uvs.is_none());
    assert_closed(&sphere, "sphere");
    assert_winding_matches_normals(&sphere, "sphere");
    assert!(rel_err(sphere.surface_area(), 4.0 * std::f64::consts::PI * 4.0) < 0.01);
    let c = centroid(&sphere);
    for (p, n) in sphere.positions.iter().zip(&sphere.normals) {
        assert!(n.dot(*p - c) > 0.0, "sphere normal points inward");
        assert!((p.length() - 2.0).abs() < 1e-5);
    }
    let (lo, hi) = sphere.bounding_box();
    assert!((lo + Vec3::splat(2.0)).abs().max_element() < 1e-5);
    assert!((hi - Vec3::splat(2.0)).abs().max_element() < 1e-5);

    let torus = Mesh::torus(3.0, 1.0, 64, 32);
    assert_closed(&torus, "torus");
    assert_winding_matches_normals(&torus, "torus");
    let analytic = 4.0 * std::f64::consts::PI.powi(2) * 3.0;
    assert!(rel_err(torus.surface_area(), analytic) < 0.01);
    for (p, n) in torus.positions.iter().zip(&torus.normals) {
        // Outward: away from the tube's centre circle.
        let centre = Vec3::new(p.x, 0.0, p.z).normalize() * 3.0;
        assert!(n.dot(*p - centre) > 0.99);
    }

    let cube = Mesh::cube(2.0, 5);
    assert_eq!(cube.triangles.len(), 6 * 25 * 2);
    assert_eq!(cube.positions.len(), 6 * 36);
    assert_closed(&cube, "cube");
    assert_winding_matches_normals(&cube, "cube");
    assert!(rel_err(cube.surface_area(), 24.0) < 1e-5);
    for (t, tri) in cube.triangles.iter().enumerate() {
        // Flat faces: the vertex normals are the face normal; it points outward.
        for &v in tri {
            assert!(cube.normals[v as usize].dot(cube.face_normal(t)) > 0.9999);
        }
        let mid = cube.corners(t).iter().copied().sum::<Vec3>() / 3.0;
        assert!(cube.face_normal(t).dot(mid) > 0.0);
    }
    // 6 charts: welding by position joins them.
    let (_, welded) = cube.welded_vertex_ids();
    assert_eq!(welded, 6 * 16 + 12 * 4 + 8); // 6 (n-1)^2 + 12 (n-1) + 8

    let plane = Mesh::plane(4.0, 2.0, 8);
    assert_winding_matches_normals(&plane, "plane");
    assert!(rel_err(plane.surface_area(), 8.0) < 1e-5);
    let uvs = plane.uvs.as_ref().expect("plane has uvs");
    assert_eq!(uvs.len(), plane.positions.len());
    for (uv, p) in uvs.iter().zip(&plane.positions) {
        assert!(uv.min_element() >= 0.0 && uv.max_element() <= 1.0);
        assert!((uv.x - (p.x / 4.0 + 0.5)).abs() < 1e-6 && (uv.y - (p.z / 2.0 + 0.5)).abs() < 1e-6);
    }
    for n in &plane.normals {
        assert_eq!(*n, Vec3::Y);
    }
    let adj = plane.triangle_adjacency();
    let boundary = adj.iter().flatten().filter(|e| e.is_none()).count();
    assert_eq!(boundary, 4 * 8, "plane boundary edges");

    // The generators already pass validation untouched.
    for mut m in [sphere, torus, cube, plane] {
        let before = m.clone();
        let report = m.validate_and_repair().unwrap();
        assert_eq!(report, RepairReport::default());
        assert!(m == before, "validation changed a generated mesh");
    }
}

#[test]
fn adjacency_welds_split_vertices_and_skips_non_manifold() {
    // Two triangles sharing an edge through duplicated (split) vertices.
    let mut m = Mesh {
        positions: vec![
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            // Copies of 1 and 2 (a uv seam), and a fourth point.
            Vec3::X,
            Vec3::Y,
            Vec3::new(1.0, 1.0, 0.0),
        ],
        triangles: vec![[0, 1, 2], [3, 5, 4]],
        ..Default::default()
    };
    let adj = m.triangle_adjacency();
    assert_eq!(adj[0], [None, Some(1), None]);
    assert_eq!(adj[1], [None, None, Some(0)]);
    // A third triangle on the same edge makes it non-manifold: no neighbour there.
    m.positions.push(Vec3::new(0.5, 0.5, 1.0));
    m.triangles.push([1, 2, 6]);
    let adj = m.triangle_adjacency();
    assert_eq!(adj[0], [None, None, None]);
    assert_eq!(adj[2][0], None);
    let report = m.validate_and_repair().unwrap();
    assert_eq!(report.non_manifold_edges, 1);
    assert!(report.computed_normals);
    // -0.0 and 0.0 weld.
    let m = Mesh {
        positions: vec![
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::new(-0.0, 1.0, 0.0),
            Vec3::new(-1.0, 0.0, -0.0),
        ],
        triangles: vec![[0, 1, 2], [0, 3, 4]],
        ..Default::default()
    };
    assert_eq!(m.triangle_adjacency()[0][2], Some(1));
}

#[test]
fn repair_drops_degenerates_computes_normals_and_rejects_bad_input() {
    let mut m = Mesh::plane(1.0, 1.0, 2);
    let n0 = m.triangles.len();
    m.normals.clear();
    // Repeated index; zero area (collinear); a far too thin sliver.
    m.triangles.push([0, 0, 1]);
    m.triangles.push([0, 1, 2]); // vertices 0,1,2 lie on one line (x = -0.5)
    let report = m.validate_and_repair().unwrap();
    assert_eq!(report.dropped_degenerate, 2);
    assert!(report.computed_normals);
    assert_eq!(m.triangles.len(), n0);
    assert_eq!(m.normals.len(), m.positions.len());
    for n in &m.normals {
        assert!((*n - Vec3::Y).length() < 1e-6, "computed normal {n}");
    }

    // Degeneracy is decided per triangle: a unit square far from a square a million times
    // larger keeps its triangles (the old mesh-relative threshold dropped them).
    let mut far = Mesh::plane(1.0, 1.0, 1);
    let big = Mesh::plane(1e6, 1e6, 1);
    let base = far.positions.len() as u32;
    far.positions
        .extend(big.positions.iter().map(|p| *p + Vec3::new(1e7, 0.0, 0.0)));
    far.normals.extend(big.normals.iter().copied());
    far.uvs = None;
    far.triangles
        .extend(big.triangles.iter().map(|t| t.map(|i| i + base)));
    let n_far = far.triangles.len();
    let report = far.validate_and_repair().unwrap();
    assert_eq!(report.dropped_degenerate, 0);
    assert_eq!(far.triangles.len(), n_far);

    // Coordinates whose products overflow f32 are refused with the vertex named.
    let mut huge = Mesh::plane(1.0, 1.0, 1);
    huge.positions[1].x = 1e38;
    let e = huge.validate_and_repair().unwrap_err().to_string();
    assert!(e.contains("vertex 1") && e.contains("1e38"), "{e}");

    // Only the zero normals are recomputed; the others are kept.
    let mut s = Mesh::uv_sphere(1.0, 16, 8);
    s.normals[5] = Vec3::ZERO;
    let kept = s.normals[6];
    let report = s.validate_and_repair().unwrap();
    assert!(report.computed_normals);
    assert_eq!(s.normals[6], kept);
    assert!(s.normals[5].dot(s.positions[5]) > 0.95);

    let err = |m: &mut Mesh| m.validate_and_repair().unwrap_err().to_string();
    let mut bad = Mesh::plane(1.0, 1.0, 2);
    bad.positions[3].y = f32::NAN;
    assert!(
        err(&mut bad).contains("non-finite position"),
        "{}",
        err(&mut bad)
    );
    let mut bad = Mesh::plane(1.0, 1.0, 2);
    bad.normals[1] = Vec3::new(f32::INFINITY, 0.0, 0.0);
    assert!(err(&mut bad).contains("normal"));
    let mut bad = Mesh::plane(1.0, 1.0, 2);
    bad.triangles[2][1] = 99;
    let msg = err(&mut bad);
    assert!(msg.contains("99") && msg.contains("9 vertices"), "{msg}");
    let mut bad = Mesh::plane(1.0, 1.0, 2);
    bad.uvs.as_mut().unwrap().pop();
    assert!(err(&mut bad).contains("uvs"));
    let mut bad = Mesh::plane(1.0, 1.0, 2);
    bad.tangents = Some(vec![Vec4::X; 3]);
    assert!(err(&mut bad).contains("tangents"));
    let mut bad = Mesh::plane(1.0, 1.0, 2);
    bad.triangles.clear();
    assert!(err(&mut bad).contains("no triangles"));
    let mut bad = Mesh::plane(1.0, 1.0, 2);
    bad.triangles = vec![[0, 1, 2], [3, 3, 4]];
    assert!(err(&mut bad).contains("all triangles are degenerate"));
}

/// Checks that every frame is orthonormal and tangent to the face, at the corners and
/// the centre of every triangle.
fn assert_frames_orthonormal(mesh: &Mesh, field: &TangentField, name: &str) {
    for t in 0..mesh.triangles.len() {
        let n = mesh.face_normal(t);
        for bary in [
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0 / 3.0; 3],
            [0.2, 0.5, 0.3],
        ] {
            let (tt, b, s) = field.frame(mesh, t, bary);
            assert!(
                (tt.length() - 1.0).abs() < 1e-4,
                "{name}: |t| = {}",
                tt.length()
            );
            assert!((b.length() - 1.0).abs() < 1e-4, "{name}: |b|");
            assert!(
                tt.dot(b).abs() < 1e-4 && tt.dot(n).abs() < 1e-4 && b.dot(n).abs() < 1e-4,
                "{name}"
            );
            // b = t x n: seen from outside (n towards the viewer) t is "right" and b is
            // "down", as x and y in the exemplar image (y down), so t x b = -n: the
            // texture is not mirrored.
            assert!((b - tt.cross(n)).length() < 1e-4, "{name}: b != t x n");
            assert!(tt.cross(b).dot(n) < -0.999, "{name}: frame is mirrored");
            assert!(s > 0.0 && s.is_finite());
        }
    }
}

#[test]
fn up_field_on_sphere() {
    let mesh = Mesh::uv_sphere(1.0, 48, 24);
    let up = Vec3::Y;
    let field = TangentField::build(
        &mesh,
        None,
        &DirectionSource::Up(up),
        &ScaleSource::Constant(0.01),
    )
    .unwrap();
    assert_eq!(field.symmetry(), 1);
    assert_frames_orthonormal(&mesh, &field, "up sphere");
    let mut checked = 0;
    for t in 0..mesh.triangles.len() {
        let n = mesh.face_normal(t);
        if n.dot(up).abs() > 0.9 {
            continue;
        }
        let (_, b, s) = field.frame(&mesh, t, [1.0 / 3.0; 3]);
        let up_proj = (up - n * n.dot(up)).normalize();
        assert!(b.dot(-up_proj) > 0.99, "b = {b} does not point down (-up)");
        assert_eq!(s, 0.01);
        checked += 1;
    }
    assert!(checked > mesh.triangles.len() / 2);
    // Singularities: the two poles (index +1 each), nothing else far from them.
    let sing = field.singularities();
    assert!(!sing.is_empty());
    let mut north = false;
    let mut south = false;
    for &v in &sing {
        let p = mesh.positions[v as usize];
        assert!(p.y.abs() > 0.95, "singularity at {p}, far from the poles");
        north |= p.y > 0.0;
        south |= p.y < 0.0;
    }
    assert!(north && south, "{sing:?}");
    let total: f32 = field.singularity_indices().iter().map(|s| s.1).sum();
    assert!(
        (total - 2.0).abs() < 1e-4,
        "index sum {total} (Euler characteristic 2)"
    );

    // Another up vector: singularities move with it.
    let field = TangentField::build(
        &mesh,
        None,
        &DirectionSource::Up(Vec3::X),
        &ScaleSource::Constant(1.0),
    )
    .unwrap();
    for &v in &field.singularities() {
        let p = mesh.positions[v as usize];
        assert!(p.x.abs() > 0.9, "singularity at {p} for up = +x");
    }
}

/// Angle differences (degrees, modulo 360/n) between the tangents at the centres of
/// adjacent triangles, each carried to the other's plane by the minimal rotation between
/// the face normals: (mean, mean and max over pairs of triangles farther than `far` from
/// every point of `avoid`, number of differences above 10 degrees).
fn adjacent_differences(
    mesh: &Mesh,
    field: &TangentField,
    n: u32,
    avoid: &[Vec3],
    far: f32,
) -> (f32, f32, f32, usize) {
    let adj = mesh.triangle_adjacency();
    let period = 2.0 * PI / n as f32;
    let centre = |t: usize| mesh.corners(t).iter().copied().sum::<Vec3>() / 3.0;
    let is_far = |p: Vec3| avoid.iter().all(|a| (p - *a).length() > far);
    let (mut sum, mut count, mut far_sum, mut far_count, mut far_max, mut big) =
        (0.0, 0, 0.0, 0, 0.0f32, 0);
    for (t, edges) in adj.iter().enumerate() {
        for nb in edges.iter().flatten() {
            let u = *nb as usize;
            let (nt, nu) = (mesh.face_normal(t), mesh.face_normal(u));
            let (tt, _, _) = field.frame(mesh, t, [1.0 / 3.0; 3]);
            let (tu, _, _) = field.frame(mesh, u, [1.0 / 3.0; 3]);
            let carried = glam::Quat::from_rotation_arc(nt, nu) * tt;
            let angle = carried.cross(tu).dot(nu).atan2(carried.dot(tu));
            let d = (angle - period * (angle / period).round())
                .abs()
                .to_degrees();
            sum += d;
            count += 1;
            if is_far(centre(t)) && is_far(centre(u)) {
                far_sum += d;
                far_count += 1;
                far_max = far_max.max(d);
            }
            big += (d > 10.0) as usize;
        }
    }
    (
        sum / count as f32,
        far_sum / far_count.max(1) as f32,
        far_max,
        big,
    )
}

#[test]
fn symmetric_field_on_cube_relaxes() {
    let mesh = Mesh::cube(2.0, 16);
    let up = Vec3::new(0.35, 1.0, 0.6);
    let scale = ScaleSource::Constant(0.05);
    let build = |iterations| {
        TangentField::build(
            &mesh,
            None,
            &DirectionSource::Symmetric {
                n: 4,
                up,
                iterations,
            },
            &scale,
        )
        .unwrap()
    };
    let before = build(0);
    let after = build(200);
    assert_eq!(after.symmetry(), 4);
    assert_frames_orthonormal(&mesh, &after, "symmetric cube");
    let corners: Vec<Vec3> = (0..8)
        .map(|i| {
            Vec3::new(
                if i & 1 == 0 { -1.0 } else { 1.0 },
                if i & 2 == 0 { -1.0 } else { 1.0 },
                if i & 4 == 0 { -1.0 } else { 1.0 },
            )
        })
        .collect();
    let (m0, f0, x0, b0) = adjacent_differences(&mesh, &before, 4, &corners, 0.3);
    let (m1, f1, x1, b1) = adjacent_differences(&mesh, &after, 4, &corners, 0.3);
    eprintln!(
        "cube 4-RoSy, adjacent triangles (mod 90 deg): mean {m0:.2} -> {m1:.2} deg; away from \
         the corners mean {f0:.2} -> {f1:.2}, max {x0:.2} -> {x1:.2}; jumps > 10 deg {b0} -> {b1}"
    );
    // Up projected to the faces jumps at every cube edge; relaxed, the field is smooth
    // except next to the corners, where the singularities are.
    assert!(m1 < 0.5 * m0 && m1 < 1.0, "mean {m0} -> {m1}");
    assert!(
        f1 < 0.5 * f0 && f1 < 0.6,
        "mean away from corners {f0} -> {f1}"
    );
    assert!(
        x1 < 0.25 * x0 && x1 < 3.0,
        "max away from corners {x0} -> {x1}"
    );
    assert!(b1 * 5 < b0 && b1 <= 8 * 6, "jumps {b0} -> {b1}");
    // The cube's corners are where a smooth 4-symmetric field must be singular: 8
    // singularities of index +1/4 (sum 2, the Euler characteristic), next to the corners.
    let sing = after.singularity_indices();
    eprintln!("cube singularities: {sing:?}");
    let total: f32 = sing.iter().map(|s| s.1).sum();
    assert!((total - 2.0).abs() < 1e-4, "index sum {total}");
    assert_eq!(sing.len(), 8);
    for &(v, k) in sing {
        assert_eq!(k, 0.25);
        let p = mesh.positions[v as usize];
        assert!(
            corners.iter().any(|c| (p - *c).length() < 0.3),
            "singularity at {p}"
        );
    }

    // Combing: within a triangle the corners agree modulo 90 degrees, so the
    // interpolated tangent stays near every corner's (up to the symmetry).
    for t in 0..mesh.triangles.len() {
        let c = after.corner_tangents(t);
        let n = mesh.face_normal(t);
        for i in 1..3 {
            let a = (c[0] - n * n.dot(c[0])).normalize();
            let b = (c[i] - n * n.dot(c[i])).normalize();
            assert!(a.dot(b) > 0.7, "triangle {t} corners not combed");
        }
    }

    // n = 2 and 6 run too; bad n is refused.
    for n in [1, 2, 6] {
        let f = TangentField::build(
            &mesh,
            None,
            &DirectionSource::Symmetric {
                n,
                up,
                iterations: 20,
            },
            &scale,
        )
        .unwrap();
        assert_frames_orthonormal(&mesh, &f, "symmetric n");
    }
    for n in [0, 3, 5, 8] {
        let e = TangentField::build(
            &mesh,
            None,
            &DirectionSource::Symmetric {
                n,
                up,
                iterations: 1,
            },
            &scale,
        );
        assert!(e.unwrap_err().to_string().contains("1, 2, 4 or 6"));
    }
}

#[test]
fn symmetric_fields_obey_poincare_hopf() {
    // Indices add up to the Euler characteristic: 2 on a sphere, whatever n.
    let sphere = Mesh::uv_sphere(1.0, 40, 20);
    for n in [1, 2, 4, 6] {
        let f = TangentField::build(
            &sphere,
            None,
            &DirectionSource::Symmetric {
                n,
                up: Vec3::new(0.2, 1.0, -0.1),
                iterations: 100,
            },
            &ScaleSource::Constant(0.1),
        )
        .unwrap();
        let sing = f.singularity_indices();
        let total: f32 = sing.iter().map(|s| s.1).sum();
        eprintln!(
            "sphere n = {n}: {} singular vertices, indices {:?}",
            sing.len(),
            sing.iter().map(|s| s.1).collect::<Vec<_>>()
        );
        assert!((total - 2.0).abs() < 1e-4, "n = {n}: index sum {total}");
        assert_frames_orthonormal(&sphere, &f, "symmetric sphere");
    }
}

#[test]
fn symmetric_field_on_torus_indices_cancel() {
    // A torus has Euler characteristic 0: the indices of any field cancel out. Up = +z
    // is parallel to the normal at 4 points of the torus (2 of index +1, 2 of index -1).
    let mesh = Mesh::torus(2.0, 0.7, 48, 24);
    let f = TangentField::build(
        &mesh,
        None,
        &DirectionSource::Symmetric {
            n: 2,
            up: Vec3::Z,
            iterations: 100,
        },
        &ScaleSource::Constant(0.1),
    )
    .unwrap();
    let total: f32 = f.singularity_indices().iter().map(|s| s.1).sum();
    assert!(total.abs() < 1e-4, "index sum {total} on a torus");
}

#[test]
fn constraint_field_matches_constraints() {
    // Plane: exact.
    let mesh = Mesh::plane(2.0, 2.0, 10);
    let c0 = (mesh.positions[0], Vec3::new(1.0, 0.3, 1.0));
    let c1 = (mesh.positions[120], Vec3::new(-1.0, 0.0, 2.0));
    let field = TangentField::build(
        &mesh,
        None,
        &DirectionSource::Constraints(vec![c0, c1]),
        &ScaleSource::Constant(0.02),
    )
    .unwrap();
    assert_frames_orthonormal(&mesh, &field, "constraints plane");
    for (p, d) in [c0, c1] {
        let want = Vec3::new(d.x, 0.0, d.z).normalize();
        let (v, t, corner) = find_corner(&mesh, p);
        let mut bary = [0.0; 3];
        bary[corner] = 1.0;
        let (tt, _, _) = field.frame(&mesh, t, bary);
        assert!(tt.dot(want) > 0.9999, "vertex {v}: {tt} vs {want}");
    }
    // Sphere: the constraint direction projected to the face plane, near a constraint.
    let mesh = Mesh::uv_sphere(1.0, 48, 24);
    let v = 48 * 10 + 7;
    let p = mesh.positions[v];
    let d = Vec3::Y;
    let field = TangentField::build(
        &mesh,
        None,
        &DirectionSource::Constraints(vec![(p, d)]),
        &ScaleSource::Constant(0.02),
    )
    .unwrap();
    let (_, t, corner) = find_corner(&mesh, p);
    let mut bary = [0.0; 3];
    bary[corner] = 1.0;
    let (tt, _, _) = field.frame(&mesh, t, bary);
    let n = mesh.face_normal(t);
    let want = (d - n * n.dot(d)).normalize();
    assert!(tt.dot(want) > 0.999, "{tt} vs {want}");
    assert!(TangentField::build(
        &mesh,
        None,
        &DirectionSource::Constraints(vec![]),
        &ScaleSource::Constant(1.0)
    )
    .is_err());
    assert!(TangentField::build(
        &mesh,
        None,
        &DirectionSource::Constraints(vec![(p, Vec3::ZERO)]),
        &ScaleSource::Constant(1.0)
    )
    .is_err());
}

/// (vertex, triangle, corner) of a triangle corner at position `p`.
fn find_corner(mesh: &Mesh, p: Vec3) -> (usize, usize, usize) {
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for (c, &v) in tri.iter().enumerate() {
            if mesh.positions[v as usize] == p {
                return (v as usize, t, c);
            }
        }
    }
    panic!("no corner at {p}");
}

#[test]
fn random_per_region_is_deterministic_and_per_region() {
    let mesh = Mesh::cube(1.0, 4);
    let build = |seed, regions: Option<&[u32]>| {
        TangentField::build(
            &mesh,
            regions,
            &DirectionSource::RandomPerRegion { seed },
            &ScaleSource::Constant(0.1),
        )
        .unwrap()
    };
    let tangents = |f: &TangentField| {
        (0..mesh.triangles.len())
            .map(|t| f.frame(&mesh, t, [0.3, 0.3, 0.4]).0)
            .collect::<Vec<_>>()
    };
    let a = tangents(&build(7, None));
    let b = tangents(&build(7, None));
    let c = tangents(&build(8, None));
    assert_eq!(a, b);
    assert_ne!(a, c);
    assert_frames_orthonormal(&mesh, &build(7, None), "random");
    assert!(build(7, None).singularities().is_empty());
    // Automatic regions on a cube = its 6 faces: constant per face, 6 different values.
    let per_face = 4 * 4 * 2;
    for f in 0..6 {
        for t in 0..per_face {
            assert!((a[f * per_face + t] - a[f * per_face]).length() < 1e-6);
        }
    }
    // Given regions: two halves of the plane.
    let plane = Mesh::plane(1.0, 1.0, 4);
    let regions: Vec<u32> = (0..plane.triangles.len() as u32)
        .map(|t| if t < 16 { 3 } else { 11 })
        .collect();
    let f = TangentField::build(
        &plane,
        Some(&regions),
        &DirectionSource::RandomPerRegion { seed: 1 },
        &ScaleSource::Constant(0.1),
    )
    .unwrap();
    let t: Vec<Vec3> = (0..plane.triangles.len())
        .map(|t| f.frame(&plane, t, [1.0 / 3.0; 3]).0)
        .collect();
    assert!(t[..16].iter().all(|v| (*v - t[0]).length() < 1e-6));
    assert!(t[16..].iter().all(|v| (*v - t[16]).length() < 1e-6));
    assert!((t[0] - t[16]).length() > 1e-3);
    let wrong = TangentField::build(
        &plane,
        Some(&regions[..3]),
        &DirectionSource::RandomPerRegion { seed: 1 },
        &ScaleSource::Constant(0.1),
    );
    assert!(wrong.is_err());
}

#[test]
fn mesh_tangents_and_scales() {
    let mut mesh = Mesh::plane(2.0, 2.0, 4);
    let scale = ScaleSource::Constant(0.5);
    let e = TangentField::build(&mesh, None, &DirectionSource::MeshTangents, &scale).unwrap_err();
    assert!(e.to_string().contains("TANGENT"), "{e}");
    // Tangents that are all zero (as NaN ones load) or along the normals: refused, not a
    // field of arbitrary fallback directions.
    for bad in [Vec4::new(0.0, 0.0, 0.0, 1.0), Vec4::new(0.0, 1.0, 0.0, 1.0)] {
        mesh.tangents = Some(vec![bad; mesh.positions.len()]);
        let e =
            TangentField::build(&mesh, None, &DirectionSource::MeshTangents, &scale).unwrap_err();
        assert!(e.to_string().contains("usable TANGENT"), "{e}");
    }
    mesh.tangents = Some(vec![Vec4::new(0.0, 0.1, 1.0, 1.0); mesh.positions.len()]);
    let f = TangentField::build(&mesh, None, &DirectionSource::MeshTangents, &scale).unwrap();
    let (t, b, s) = f.frame(&mesh, 3, [0.2, 0.2, 0.6]);
    assert!((t - Vec3::Z).length() < 1e-5 && (b - Vec3::Z.cross(Vec3::Y)).length() < 1e-5);
    assert_eq!(s, 0.5);

    // Linear along x from 1 (x = -1) to 3 (x = +1); per vertex.
    let lin = ScaleSource::Linear {
        axis: Vec3::new(2.0, 0.0, 0.0),
        at_min: 1.0,
        at_max: 3.0,
    };
    let f = TangentField::build(&mesh, None, &DirectionSource::Up(Vec3::Z), &lin).unwrap();
    for t in 0..mesh.triangles.len() {
        let [a, b, c] = mesh.corners(t);
        let w = [0.2, 0.3, 0.5];
        let x = a.x * w[0] + b.x * w[1] + c.x * w[2];
        let (_, _, s) = f.frame(&mesh, t, w);
        assert!((s - (2.0 + x)).abs() < 1e-5);
    }
    let per: Vec<f32> = (0..mesh.positions.len()).map(|v| 1.0 + v as f32).collect();
    let f = TangentField::build(
        &mesh,
        None,
        &DirectionSource::Up(Vec3::Z),
        &ScaleSource::PerVertex(per.clone()),
    )
    .unwrap();
    let tri = mesh.triangles[5];
    assert_eq!(f.frame(&mesh, 5, [0.0, 1.0, 0.0]).2, per[tri[1] as usize]);

    // Up = +z on the plane: the exemplar's -y follows +z.
    let (t, b, _) = f.frame(&mesh, 0, [1.0 / 3.0; 3]);
    assert!((b + Vec3::Z).length() < 1e-5, "{b}");
    assert!((t - Vec3::Z.cross(Vec3::Y)).length() < 1e-5, "{t}");

    // Errors.
    let up = DirectionSource::Up(Vec3::Y);
    for bad in [
        ScaleSource::Constant(0.0),
        ScaleSource::Constant(-1.0),
        ScaleSource::Constant(f32::NAN),
        ScaleSource::Constant(f32::INFINITY),
        ScaleSource::PerVertex(vec![1.0; 3]),
        ScaleSource::PerVertex({
            let mut p = per.clone();
            p[2] = 0.0;
            p
        }),
        ScaleSource::Linear {
            axis: Vec3::ZERO,
            at_min: 1.0,
            at_max: 2.0,
        },
        ScaleSource::Linear {
            axis: Vec3::X,
            at_min: 1.0,
            at_max: f32::NAN,
        },
    ] {
        assert!(
            TangentField::build(&mesh, None, &up, &bad).is_err(),
            "{bad:?} accepted"
        );
    }
    assert!(TangentField::build(&mesh, None, &DirectionSource::Up(Vec3::ZERO), &scale).is_err());
    assert!(TangentField::build(
        &mesh,
        None,
        &DirectionSource::Up(Vec3::new(f32::NAN, 0.0, 0.0)),
        &scale
    )
    .is_err());
    let mut no_normals = mesh.clone();
    no_normals.normals.clear();
    assert!(TangentField::build(&no_normals, None, &up, &scale).is_err());
    let mut empty = mesh.clone();
    empty.triangles.clear();
    assert!(TangentField::build(&empty, None, &up, &scale).is_err());
}

#[test]
fn up_field_on_plane_facing_up_uses_fallback() {
    // The whole plane faces +y: Up(+y) is singular everywhere; the fallback axis still
    // gives a valid, constant frame.
    let mesh = Mesh::plane(1.0, 1.0, 3);
    let f = TangentField::build(
        &mesh,
        None,
        &DirectionSource::Up(Vec3::Y),
        &ScaleSource::Constant(1.0),
    )
    .unwrap();
    assert_frames_orthonormal(&mesh, &f, "fallback");
    let t0 = f.frame(&mesh, 0, [1.0 / 3.0; 3]).0;
    for t in 0..mesh.triangles.len() {
        assert!((f.frame(&mesh, t, [0.1, 0.6, 0.3]).0 - t0).length() < 1e-5);
    }
}

#[test]
fn direction_and_scale_strings() {
    let parse = |s: &str| s.parse::<DirectionSource>();
    assert_eq!(parse("up").unwrap(), DirectionSource::Up(Vec3::Y));
    assert_eq!(parse("up:0,0,1").unwrap(), DirectionSource::Up(Vec3::Z));
    assert_eq!(parse("tangents").unwrap(), DirectionSource::MeshTangents);
    assert_eq!(
        parse("random").unwrap(),
        DirectionSource::RandomPerRegion { seed: 0 }
    );
    assert_eq!(
        parse("random:42").unwrap(),
        DirectionSource::RandomPerRegion { seed: 42 }
    );
    match parse("symmetric:4").unwrap() {
        DirectionSource::Symmetric { n: 4, up, .. } => assert_eq!(up, Vec3::Y),
        other => panic!("{other:?}"),
    }
    assert_eq!(
        parse("symmetric:2:1,0,0:17").unwrap(),
        DirectionSource::Symmetric {
            n: 2,
            up: Vec3::X,
            iterations: 17
        }
    );
    for s in [
        DirectionSource::Up(Vec3::Y),
        DirectionSource::Up(Vec3::new(0.1, -2.5, 1e-3)),
        DirectionSource::MeshTangents,
        DirectionSource::RandomPerRegion { seed: 9 },
        DirectionSource::Symmetric {
            n: 6,
            up: Vec3::new(1.0, 2.0, 3.0),
            iterations: 5,
        },
        parse("symmetric:1").unwrap(),
        parse("symmetric:4:0,0,1").unwrap(),
    ] {
        assert_eq!(parse(&s.to_string()).unwrap(), s, "{s}");
    }
    for bad in [
        "",
        "down",
        "up:1,2",
        "up:0,0,0",
        "up:a,b,c",
        "up:1,nan,0",
        "symmetric",
        "symmetric:3",
        "symmetric:x",
        "symmetric:4:0,1",
        "symmetric:4:0,1,0:z",
        "symmetric:4:0,1,0:100000001",
        "random:-1",
        "tangents:1",
        "constraints",
        "constraints:/nonexistent/texsyn-constraints.txt",
    ] {
        assert!(parse(bad).is_err(), "`{bad}` accepted");
    }

    // Constraint files.
    let dir = std::env::temp_dir().join(format!("texsyn-surface-mesh-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let good = dir.join("good.txt");
    std::fs::write(
        &good,
        "# point direction\n0 1 0  1 0 0\n\n0.5,0.5,0.5 0 0 -1 # trailing\n",
    )
    .unwrap();
    match parse(&format!("constraints:{}", good.display())).unwrap() {
        DirectionSource::Constraints(list) => assert_eq!(
            list,
            vec![(Vec3::Y, Vec3::X), (Vec3::splat(0.5), Vec3::NEG_Z)]
        ),
        other => panic!("{other:?}"),
    }
    let bad = dir.join("bad.txt");
    std::fs::write(&bad, "0 0 0 1 0 0\n# ok\n0 0 0 1 0\n").unwrap();
    let msg = parse(&format!("constraints:{}", bad.display()))
        .unwrap_err()
        .to_string();
    assert!(msg.contains("line 3"), "{msg}");
    std::fs::write(&bad, "0 0 0 1 0 0\n1 1 1 0 0 0\n").unwrap();
    let msg = parse(&format!("constraints:{}", bad.display()))
        .unwrap_err()
        .to_string();
    assert!(msg.contains("line 2") && msg.contains("zero"), "{msg}");
    std::fs::write(&bad, "# nothing\n").unwrap();
    assert!(parse(&format!("constraints:{}", bad.display())).is_err());
    std::fs::remove_dir_all(&dir).ok();
    assert!(parse_constraints("1 2 3 4 5 x", "inline")
        .unwrap_err()
        .to_string()
        .contains("inline line 1"));

    let scale = |s: &str| s.parse::<ScaleSource>();
    assert_eq!(scale("0.01").unwrap(), ScaleSource::Constant(0.01));
    assert_eq!(
        scale("linear:0,1,0:0.5:2").unwrap(),
        ScaleSource::Linear {
            axis: Vec3::Y,
            at_min: 0.5,
            at_max: 2.0
        }
    );
    for s in [
        ScaleSource::Constant(0.0125),
        ScaleSource::Linear {
            axis: Vec3::new(1.0, 0.5, 0.0),
            at_min: 0.25,
            at_max: 3.0,
        },
    ] {
        assert_eq!(scale(&s.to_string()).unwrap(), s);
    }
    for bad in [
        "",
        "0",
        "-1",
        "abc",
        "inf",
        "nan",
        "linear:0,1,0:1",
        "linear:0,0,0:1:2",
        "linear:0,1,0:0:2",
        "linear:0,1,0:1:x",
    ] {
        assert!(scale(bad).is_err(), "`{bad}` accepted");
    }
    assert!(DIRECTION_HELP.contains("symmetric:N") && SCALE_HELP.contains("linear:"));
}
