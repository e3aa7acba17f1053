//! glTF input and output (src/surface/gltf_io.rs): round trip through write_glb and
//! load_mesh, the bundled bunny, node transforms, strips and fans, and clear errors for
//! bad files. Every .glb written is checked with the Khronos glTF validator
//! (tools/validate_gltf.mjs) when it is installed (`cd tools && npm install`); with
//! TEXSYN_REQUIRE_GLTF_VALIDATOR=1 (as in .ci/run) a missing validator fails the tests.

use glam::{Vec2, Vec3, Vec4};
use image::{Rgba, RgbaImage};
use texsyn::surface::gltf_io::{load_mesh, write_glb, LoadReport, MaterialImages};
use texsyn::surface::Mesh;
use texsyn::Error;

// ---------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------

mod common;
use common::{khronos_validate, repo, run_validator, TempDir};

fn solid(w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 4]) -> RgbaImage {
    RgbaImage::from_fn(w, h, |x, y| Rgba(f(x, y)))
}

/// Unit cube, 4 vertices per face (24 vertices, 12 triangles), with per-face normals,
/// uvs covering [0, 1] and tangents along +u.
fn cube() -> Mesh {
    let faces: [(Vec3, Vec3, Vec3); 6] = [
        // (normal, u axis, v axis (down the image))
        (Vec3::X, Vec3::NEG_Z, Vec3::NEG_Y),
        (Vec3::NEG_X, Vec3::Z, Vec3::NEG_Y),
        (Vec3::Y, Vec3::X, Vec3::Z),
        (Vec3::NEG_Y, Vec3::X, Vec3::NEG_Z),
        (Vec3::Z, Vec3::X, Vec3::NEG_Y),
        (Vec3::NEG_Z, Vec3::NEG_X, Vec3::NEG_Y),
    ];
    let mut m = Mesh::default();
    let mut uvs = Vec::new();
    let mut tangents = Vec::new();
    for (n, u, v) in faces {
        let base = m.positions.len() as u32;
        for (su, sv) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
            m.positions.push(0.5 * n + (su - 0.5) * u + (sv - 0.5) * v);
            m.normals.push(n);
            uvs.push(Vec2::new(su, sv));
            // u and v (down) with n: bitangent (up the image) = -v = cross(n, u) * w.
            let w = if n.cross(u).dot(-v) > 0.0 { 1.0 } else { -1.0 };
            tangents.push(u.extend(w));
        }
        // Counter-clockwise seen from outside: (u, v) is clockwise seen from n when v
        // points down, so go 0 -> 3 -> 2.
        let ccw = (u.cross(v)).dot(n) > 0.0;
        if ccw {
            m.triangles.push([base, base + 1, base + 2]);
            m.triangles.push([base, base + 2, base + 3]);
        } else {
            m.triangles.push([base, base + 2, base + 1]);
            m.triangles.push([base, base + 3, base + 2]);
        }
    }
    m.uvs = Some(uvs);
    m.tangents = Some(tangents);
    m
}

fn assert_close3(a: &[Vec3], b: &[Vec3], eps: f32, what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: lengths");
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        assert!(
            (*x - *y).abs().max_element() <= eps,
            "{what} {i}: {x} vs {y}"
        );
    }
}

/// A small glTF JSON document with one mesh, built by hand: each primitive is
/// (positions, optional u32 indices, mode, optional normals). All data goes into one
/// buffer, returned as bytes; `buffer_uri` is written as the buffer's uri. `nodes` and
/// `scene_nodes` are JSON text (mesh 0 is the mesh).
struct Prim {
    positions: Vec<[f32; 3]>,
    indices: Option<Vec<u32>>,
    mode: u32,
    normals: Option<Vec<[f32; 3]>>,
    tangents: Option<Vec<[f32; 4]>>,
}

fn tri_prim(positions: Vec<[f32; 3]>, indices: Vec<u32>) -> Prim {
    Prim {
        positions,
        indices: Some(indices),
        mode: 4,
        normals: None,
        tangents: None,
    }
}

fn gltf_doc(prims: &[Prim], nodes: &str, scene_nodes: &str, buffer_uri: &str) -> (String, Vec<u8>) {
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut prim_json = Vec::new();
    let mut add = |bin: &mut Vec<u8>, bytes: Vec<u8>, accessor: String| -> usize {
        let offset = bin.len();
        bin.extend_from_slice(&bytes);
        views.push(format!(
            r#"{{"buffer":0,"byteOffset":{offset},"byteLength":{}}}"#,
            bytes.len()
        ));
        accessors.push(accessor.replace("VIEW", &(views.len() - 1).to_string()));
        accessors.len() - 1
    };
    for p in prims {
        let lo = p.positions.iter().fold([f32::INFINITY; 3], |a, v| {
            [a[0].min(v[0]), a[1].min(v[1]), a[2].min(v[2])]
        });
        let hi = p.positions.iter().fold([f32::NEG_INFINITY; 3], |a, v| {
            [a[0].max(v[0]), a[1].max(v[1]), a[2].max(v[2])]
        });
        let bytes: Vec<u8> = p
            .positions
            .iter()
            .flatten()
            .flat_map(|f| f.to_le_bytes())
            .collect();
        let pos = add(
            &mut bin,
            bytes,
            format!(
                r#"{{"bufferView":VIEW,"componentType":5126,"count":{},"type":"VEC3","min":{lo:?},"max":{hi:?}}}"#,
                p.positions.len()
            ),
        );
        let mut attrs = format!(r#""POSITION":{pos}"#);
        if let Some(n) = &p.normals {
            let bytes: Vec<u8> = n.iter().flatten().flat_map(|f| f.to_le_bytes()).collect();
            let a = add(
                &mut bin,
                bytes,
                format!(
                    r#"{{"bufferView":VIEW,"componentType":5126,"count":{},"type":"VEC3"}}"#,
                    n.len()
                ),
            );
            attrs.push_str(&format!(r#","NORMAL":{a}"#));
        }
        if let Some(t) = &p.tangents {
            let bytes: Vec<u8> = t.iter().flatten().flat_map(|f| f.to_le_bytes()).collect();
            let a = add(
                &mut bin,
                bytes,
                format!(
                    r#"{{"bufferView":VIEW,"componentType":5126,"count":{},"type":"VEC4"}}"#,
                    t.len()
                ),
            );
            attrs.push_str(&format!(r#","TANGENT":{a}"#));
        }
        let mut prim = format!(r#"{{"attributes":{{{attrs}}},"mode":{}"#, p.mode);
        if let Some(idx) = &p.indices {
            let bytes: Vec<u8> = idx.iter().flat_map(|i| i.to_le_bytes()).collect();
            let a = add(
                &mut bin,
                bytes,
                format!(
                    r#"{{"bufferView":VIEW,"componentType":5125,"count":{},"type":"SCALAR"}}"#,
                    idx.len()
                ),
            );
            prim.push_str(&format!(r#","indices":{a}"#));
        }
        prim.push('}');
        prim_json.push(prim);
    }
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":{scene_nodes}}}],"nodes":{nodes},
"meshes":[{{"primitives":[{}]}}],"accessors":[{}],"bufferViews":[{}],
"buffers":[{{"uri":"{buffer_uri}","byteLength":{}}}]}}"#,
        prim_json.join(","),
        accessors.join(","),
        views.join(","),
        bin.len()
    );
    (json, bin)
}

/// Writes `prims` as `name.gltf` + `mesh.bin` in `dir` and loads it.
fn load_doc(
    dir: &TempDir,
    name: &str,
    prims: &[Prim],
    nodes: &str,
    scene_nodes: &str,
) -> texsyn::Result<(Mesh, LoadReport)> {
    let (json, bin) = gltf_doc(prims, nodes, scene_nodes, &format!("{name}.bin"));
    std::fs::write(dir.join(&format!("{name}.bin")), bin).unwrap();
    let path = dir.join(&format!("{name}.gltf"));
    std::fs::write(&path, json).unwrap();
    load_mesh(&path)
}

fn one_triangle() -> Prim {
    tri_prim(
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        vec![0, 1, 2],
    )
}

fn bad_mesh_reason(r: texsyn::Result<(Mesh, LoadReport)>) -> String {
    match r {
        Err(e @ Error::BadMesh { .. }) => {
            println!("{e}");
            e.to_string()
        }
        Err(other) => panic!("expected Error::BadMesh, got {other:?}"),
        Ok((m, _)) => panic!("expected an error, loaded {} triangles", m.triangles.len()),
    }
}

// ---------------------------------------------------------------------------------------
// Round trip and validator
// ---------------------------------------------------------------------------------------

#[test]
fn round_trip_cube_all_maps_validates() {
    let dir = TempDir::new("roundtrip");
    let mesh = cube();
    let material = MaterialImages {
        // Some alpha below 255: stored as RGBA.
        base_color: solid(8, 8, |x, y| {
            [x as u8 * 30, y as u8 * 30, 100, 200 + x as u8]
        }),
        normal: Some(solid(8, 8, |x, _| [128, 128 + x as u8, 255, 255])),
        metallic_roughness: Some(solid(4, 4, |_, y| [0, 100 + y as u8, 20, 255])),
        occlusion: Some(solid(4, 2, |x, _| [200 + x as u8, 0, 0, 255])),
    };
    let path = dir.join("cube.glb");
    write_glb(&path, &mesh, &material).unwrap();
    assert_eq!(dir.files(), vec!["cube.glb"], "no temporary file is left");

    let (back, report) = load_mesh(&path).unwrap();
    assert_eq!(report.primitives, 1);
    assert_eq!(report.skipped_non_triangle, 0);
    assert_eq!(report.converted_strips_fans, 0);
    assert_eq!(report.repair.dropped_degenerate, 0);
    assert!(!report.repair.computed_normals);
    assert_eq!(back.triangles, mesh.triangles);
    assert_close3(&back.positions, &mesh.positions, 0.0, "position");
    assert_close3(&back.normals, &mesh.normals, 1e-6, "normal");
    let (uvs, uvs0) = (back.uvs.as_ref().unwrap(), mesh.uvs.as_ref().unwrap());
    assert_eq!(uvs, uvs0);
    let (t, t0) = (
        back.tangents.as_ref().unwrap(),
        mesh.tangents.as_ref().unwrap(),
    );
    for (a, b) in t.iter().zip(t0) {
        assert!((*a - *b).abs().max_element() < 1e-6, "tangent {a} vs {b}");
    }

    // The material: textures, sampler, embedded PNGs with the same pixels.
    let (doc, buffers, images) = gltf::import(&path).unwrap();
    assert_eq!(doc.materials().len(), 1);
    let m = doc.materials().next().unwrap();
    let pbr = m.pbr_metallic_roughness();
    let tex = |t: gltf::texture::Texture| {
        let s = t.sampler();
        assert_eq!(s.mag_filter(), Some(gltf::texture::MagFilter::Linear));
        assert_eq!(
            s.min_filter(),
            Some(gltf::texture::MinFilter::LinearMipmapLinear)
        );
        assert_eq!(s.wrap_s(), gltf::texture::WrappingMode::ClampToEdge);
        assert_eq!(s.wrap_t(), gltf::texture::WrappingMode::ClampToEdge);
        match t.source().source() {
            gltf::image::Source::View { mime_type, .. } => assert_eq!(mime_type, "image/png"),
            other => panic!("image is not in a buffer view: {other:?}"),
        }
        t.source().index()
    };
    let pixels = |i: usize, want: &RgbaImage| {
        let d = &images[i];
        assert_eq!((d.width, d.height), want.dimensions());
        let rgba: Vec<u8> = match d.format {
            gltf::image::Format::R8G8B8A8 => d.pixels.clone(),
            gltf::image::Format::R8G8B8 => d
                .pixels
                .chunks(3)
                .flat_map(|p| [p[0], p[1], p[2], 255])
                .collect(),
            f => panic!("unexpected PNG format {f:?}"),
        };
        assert_eq!(&rgba, want.as_raw());
    };
    pixels(
        tex(pbr.base_color_texture().unwrap().texture()),
        &material.base_color,
    );
    pixels(
        tex(pbr.metallic_roughness_texture().unwrap().texture()),
        material.metallic_roughness.as_ref().unwrap(),
    );
    pixels(
        tex(m.normal_texture().unwrap().texture()),
        material.normal.as_ref().unwrap(),
    );
    pixels(
        tex(m.occlusion_texture().unwrap().texture()),
        material.occlusion.as_ref().unwrap(),
    );
    assert_eq!(pbr.metallic_factor(), 1.0);
    assert_eq!(buffers.len(), 1);

    if let Some(report) = khronos_validate(&path) {
        assert!(
            report.contains(": 0 errors, 0 warnings,"),
            "the validator warns about our file:\n{report}"
        );
    }
}

#[test]
fn round_trip_quad_base_color_and_normal_map_validates() {
    let dir = TempDir::new("quad");
    let mut mesh = Mesh {
        positions: vec![
            Vec3::new(-1.0, -1.0, 0.25),
            Vec3::new(1.0, -1.0, 0.25),
            Vec3::new(1.0, 1.0, 0.25),
            Vec3::new(-1.0, 1.0, 0.25),
        ],
        normals: vec![Vec3::Z; 4],
        uvs: Some(vec![
            Vec2::new(0.0, 1.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(0.0, 0.0),
        ]),
        tangents: None,
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    };
    // Not-quite-unit normals are written normalized (the validator requires unit length).
    mesh.normals[1] = Vec3::new(0.0, 0.0, 2.0);
    let material = MaterialImages {
        base_color: solid(8, 8, |x, y| [(x * 32) as u8, (y * 32) as u8, 7, 255]),
        normal: Some(solid(8, 8, |_, _| [128, 128, 255, 255])),
        metallic_roughness: None,
        occlusion: None,
    };
    let path = dir.join("quad.glb");
    // Over an existing file.
    std::fs::write(&path, b"old contents").unwrap();
    write_glb(&path, &mesh, &material).unwrap();
    assert_eq!(dir.files(), vec!["quad.glb"]);

    let (back, report) = load_mesh(&path).unwrap();
    assert_eq!(report.primitives, 1);
    assert_eq!(back.positions, mesh.positions);
    assert_eq!(back.triangles, mesh.triangles);
    assert_eq!(back.uvs, mesh.uvs);
    // A normal map without tangents: the writer adds the uv frame (+u is +X here; v runs
    // down the image along -Y, so the bitangent cross(n, t) * w = +Y needs w = +1).
    let tangents = back.tangents.expect("tangents written for the normal map");
    for t in &tangents {
        assert!(
            t.abs_diff_eq(Vec4::new(1.0, 0.0, 0.0, 1.0), 1e-6),
            "tangent {t}"
        );
    }
    assert_close3(&back.normals, &[Vec3::Z; 4], 1e-6, "normal");

    let (doc, _, _) = gltf::import(&path).unwrap();
    let m = doc.materials().next().unwrap();
    assert!(m.normal_texture().is_some());
    assert!(m.occlusion_texture().is_none());
    assert!(m
        .pbr_metallic_roughness()
        .metallic_roughness_texture()
        .is_none());
    assert_eq!(m.pbr_metallic_roughness().metallic_factor(), 0.0);

    if let Some(report) = khronos_validate(&path) {
        assert!(
            report.contains(": 0 errors, 0 warnings,"),
            "the validator warns about our file:\n{report}"
        );
    }
}

#[test]
fn tangents_generated_for_a_normal_map_follow_the_uvs() {
    let dir = TempDir::new("gentangents");
    let with = cube();
    let mut without = with.clone();
    without.tangents = None;
    let material = MaterialImages {
        base_color: solid(4, 4, |_, _| [200, 100, 50, 255]),
        normal: Some(solid(4, 4, |_, _| [128, 128, 255, 255])),
        metallic_roughness: None,
        occlusion: None,
    };
    let path = dir.join("gen.glb");
    write_glb(&path, &without, &material).unwrap();
    let (back, _) = load_mesh(&path).unwrap();
    let (got, want) = (back.tangents.unwrap(), with.tangents.unwrap());
    for (i, (a, b)) in got.iter().zip(&want).enumerate() {
        assert!(a.abs_diff_eq(*b, 1e-6), "tangent {i}: {a} vs {b}");
    }
    // Without a normal map, nothing is invented.
    let plain = MaterialImages {
        normal: None,
        ..material
    };
    write_glb(&path, &without, &plain).unwrap();
    assert!(load_mesh(&path).unwrap().0.tangents.is_none());
}

/// The validator check is not a no-op: it fails a broken file (exit 1, errors listed).
#[test]
fn validator_rejects_a_broken_file() {
    let dir = TempDir::new("validator");
    let path = dir.join("broken.glb");
    let mut glb = std::fs::read(repo().join("assets/meshes/bunny.glb")).unwrap();
    glb.truncate(glb.len() - 100);
    std::fs::write(&path, &glb).unwrap();
    if let Some((code, text)) = run_validator(&path) {
        assert_eq!(code, Some(1), "{text}");
        assert!(!text.contains(" 0 errors"), "{text}");
    }
}

#[test]
fn write_glb_errors_leave_nothing_behind() {
    let dir = TempDir::new("writeerr");
    let material = MaterialImages {
        base_color: solid(2, 2, |_, _| [1, 2, 3, 255]),
        normal: None,
        metallic_roughness: None,
        occlusion: None,
    };
    // A directory that does not exist.
    let missing = dir.join("no/such/dir/out.glb");
    let e = write_glb(&missing, &cube(), &material).unwrap_err();
    assert!(matches!(e, Error::Write { .. }), "{e:?}");
    assert!(e.to_string().contains("does not exist"), "{e}");
    assert!(dir.files().is_empty(), "left behind: {:?}", dir.files());

    // No uvs: refused before anything is written.
    let mut no_uvs = cube();
    no_uvs.uvs = None;
    let path = dir.join("x.glb");
    let e = write_glb(&path, &no_uvs, &material).unwrap_err();
    assert!(matches!(e, Error::InvalidParameter(_)), "{e:?}");
    assert!(e.to_string().contains("uvs"), "{e}");
    // An empty image.
    let empty = MaterialImages {
        base_color: RgbaImage::new(0, 0),
        ..material.clone()
    };
    assert!(matches!(
        write_glb(&path, &cube(), &empty),
        Err(Error::InvalidParameter(_))
    ));
    // Mismatched normals.
    let mut few_normals = cube();
    few_normals.normals.pop();
    assert!(matches!(
        write_glb(&path, &few_normals, &material),
        Err(Error::InvalidParameter(_))
    ));
    assert!(dir.files().is_empty(), "left behind: {:?}", dir.files());

    // The target is a directory.
    let e = write_glb(&dir.0, &cube(), &material).unwrap_err();
    assert!(matches!(e, Error::Write { .. }), "{e:?}");
    assert!(dir.files().is_empty(), "left behind: {:?}", dir.files());
}

// ---------------------------------------------------------------------------------------
// Loading
// ---------------------------------------------------------------------------------------

#[test]
fn bundled_bunny() {
    let path = repo().join("assets/meshes/bunny.glb");
    let (mesh, report) = load_mesh(&path).unwrap();
    assert_eq!(mesh.positions.len(), 1839);
    assert_eq!(mesh.triangles.len(), 3674);
    assert_eq!(mesh.normals.len(), 1839);
    assert!(mesh.uvs.is_none());
    assert!(mesh.tangents.is_none());
    assert_eq!(report.primitives, 1);
    assert_eq!(report.skipped_non_triangle, 0);
    assert_eq!(report.repair.dropped_degenerate, 0);
    assert!(!report.repair.computed_normals);
    assert_eq!(report.repair.non_manifold_edges, 0);
    for n in &mesh.normals {
        assert!((n.length() - 1.0).abs() < 1e-3);
    }
}

#[test]
fn node_hierarchy_trs_and_matrix() {
    let dir = TempDir::new("nodes");
    // Parent: translation (10, 0, 0) and scale 2; child: a matrix translating by
    // (0, 1, 0). World = T(10,0,0) S(2) T(0,1,0).
    let nodes = r#"[
        {"children":[1],"translation":[10,0,0],"scale":[2,2,2]},
        {"mesh":0,"matrix":[1,0,0,0, 0,1,0,0, 0,0,1,0, 0,1,0,1]}
    ]"#;
    let (mesh, report) = load_doc(&dir, "a", &[one_triangle()], nodes, "[0]").unwrap();
    assert_eq!(report.primitives, 1);
    assert_close3(
        &mesh.positions,
        &[
            Vec3::new(10.0, 2.0, 0.0),
            Vec3::new(12.0, 2.0, 0.0),
            Vec3::new(10.0, 4.0, 0.0),
        ],
        1e-5,
        "position",
    );
    assert_eq!(mesh.triangles, vec![[0, 1, 2]]);
    // No NORMAL in the file: computed (+Z for this counter-clockwise triangle).
    assert!(report.repair.computed_normals);
    assert_close3(&mesh.normals, &[Vec3::Z; 3], 1e-5, "normal");

    // A rotation of 90 degrees about Z and a non-uniform scale, with normals: normals use
    // the inverse transpose. Node: scale (1, 3, 1) then rotate.
    let mut prim = tri_prim(
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
        vec![0, 2, 1],
    );
    // A plane y = x / 3 ... use a tilted normal in the xy-plane: n = (1, 1, 0)/sqrt 2.
    let s = 0.5f32.sqrt();
    prim.normals = Some(vec![[s, s, 0.0]; 3]);
    let half = (std::f32::consts::FRAC_PI_4).sin();
    let nodes = format!(r#"[{{"mesh":0,"rotation":[0,0,{half},{half}],"scale":[1,3,1]}}]"#);
    let (mesh, _) = load_doc(&dir, "b", &[prim], &nodes, "[0]").unwrap();
    // Inverse transpose of R S is R S^-1: (1, 1/3, 0) normalized, then rotated by 90
    // degrees about Z: (-1/3, 1, 0) normalized.
    let want = Vec3::new(-1.0 / 3.0, 1.0, 0.0).normalize();
    assert_close3(&mesh.normals, &[want; 3], 1e-5, "normal");
    assert_close3(
        &mesh.positions,
        &[
            Vec3::ZERO,
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        ],
        1e-5,
        "position",
    );
}

#[test]
fn mirroring_node_flips_winding_and_tangent_sign() {
    let dir = TempDir::new("mirror");
    let nodes = r#"[{"mesh":0},{"mesh":0,"scale":[-1,1,1],"translation":[5,0,0]}]"#;
    let mut prim = one_triangle();
    prim.normals = Some(vec![[0.0, 0.0, 1.0]; 3]);
    prim.tangents = Some(vec![[1.0, 0.0, 0.0, 1.0]; 3]);
    let (mesh, report) = load_doc(&dir, "m", &[prim], nodes, "[0,1]").unwrap();
    assert_eq!(report.primitives, 2, "the mesh is instanced by both nodes");
    assert_eq!(mesh.positions.len(), 6);
    // Both instances still face +Z: the mirrored one has its winding reversed.
    assert_eq!(mesh.triangles, vec![[0, 1, 2], [3, 5, 4]]);
    for t in 0..2 {
        assert!(
            mesh.face_normal(t).abs_diff_eq(Vec3::Z, 1e-6),
            "triangle {t}"
        );
    }
    assert!(!report.repair.computed_normals);
    assert_close3(&mesh.normals, &[Vec3::Z; 6], 1e-6, "normal");
    // The mirrored tangent points along -X, and w flips so that the bitangent
    // cross(n, t) * w stays +Y (the mirror does not move y).
    let t = mesh.tangents.unwrap();
    for (i, t) in t.iter().enumerate() {
        let want = if i < 3 {
            Vec4::new(1.0, 0.0, 0.0, 1.0)
        } else {
            Vec4::new(-1.0, 0.0, 0.0, -1.0)
        };
        assert!(t.abs_diff_eq(want, 1e-6), "tangent {i}: {t}");
        assert!((mesh.normals[i].cross(t.truncate()) * t.w).abs_diff_eq(Vec3::Y, 1e-6));
    }
}

#[test]
fn strips_and_fans_become_triangles_and_lines_are_skipped() {
    let dir = TempDir::new("modes");
    let quad = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 0.0],
    ];
    let strip = Prim {
        positions: quad.clone(),
        indices: None,
        mode: 5,
        normals: None,
        tangents: None,
    };
    // Fan around (0,0): (0,0) (1,0) (1,1) (0,1).
    let fan = Prim {
        positions: vec![
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [1.0, 1.0, 1.0],
            [0.0, 1.0, 1.0],
        ],
        indices: Some(vec![0, 1, 2, 3]),
        mode: 6,
        normals: None,
        tangents: None,
    };
    let lines = Prim {
        positions: quad,
        indices: Some(vec![0, 1, 1, 2]),
        mode: 1,
        normals: None,
        tangents: None,
    };
    let (mesh, report) =
        load_doc(&dir, "s", &[strip, fan, lines], r#"[{"mesh":0}]"#, "[0]").unwrap();
    assert_eq!(report.primitives, 2);
    assert_eq!(report.converted_strips_fans, 2);
    assert_eq!(report.skipped_non_triangle, 1);
    assert_eq!(mesh.positions.len(), 8);
    // glTF: strip p_i = {v_i, v_(i+1+i%2), v_(i+2-i%2)}; fan p_i = {v_(i+1), v_(i+2), v_0}.
    assert_eq!(
        mesh.triangles,
        vec![[0, 1, 2], [1, 3, 2], [5, 6, 4], [6, 7, 4]]
    );
    for t in 0..4 {
        assert!(
            mesh.face_normal(t).abs_diff_eq(Vec3::Z, 1e-6),
            "triangle {t}"
        );
    }
}

#[test]
fn merged_primitives_drop_attributes_some_lack() {
    let dir = TempDir::new("merge");
    let mut with_normals = one_triangle();
    with_normals.normals = Some(vec![[0.0, 0.0, 1.0]; 3]);
    let mut second = one_triangle();
    second.positions.iter_mut().for_each(|p| p[2] = 1.0);
    let (mesh, report) =
        load_doc(&dir, "g", &[with_normals, second], r#"[{"mesh":0}]"#, "[0]").unwrap();
    assert_eq!(report.primitives, 2);
    assert_eq!(mesh.triangles, vec![[0, 1, 2], [3, 4, 5]]);
    assert!(
        report.repair.computed_normals,
        "one primitive has no NORMAL"
    );
    assert_eq!(mesh.normals.len(), 6);
    assert!(mesh.uvs.is_none());
}

#[test]
fn missing_external_buffer_is_named() {
    let dir = TempDir::new("missingbin");
    let (json, _) = gltf_doc(&[one_triangle()], r#"[{"mesh":0}]"#, "[0]", "mesh.bin");
    let path = dir.join("scene.gltf");
    std::fs::write(&path, json).unwrap();
    let msg = bad_mesh_reason(load_mesh(&path));
    assert!(msg.contains("'mesh.bin'"), "{msg}");
    assert!(msg.contains("does not exist"), "{msg}");
    assert!(msg.contains("scene.gltf"), "{msg}");
}

#[test]
fn missing_file_is_io_error() {
    let dir = TempDir::new("nofile");
    match load_mesh(&dir.join("nothing.glb")) {
        Err(Error::Io { path, .. }) => assert!(path.ends_with("nothing.glb")),
        other => panic!("expected Error::Io, got {other:?}"),
    }
}

#[test]
fn corrupt_and_truncated_files() {
    let dir = TempDir::new("corrupt");
    let bunny = std::fs::read(repo().join("assets/meshes/bunny.glb")).unwrap();
    let path = dir.join("t.glb");

    // Cut in half: the header's length is larger than the file.
    std::fs::write(&path, &bunny[..bunny.len() / 2]).unwrap();
    let msg = bad_mesh_reason(load_mesh(&path));
    assert!(msg.contains("truncated"), "{msg}");

    // Cut in half with the header's length patched to match: the BIN chunk is short.
    let mut cut = bunny[..bunny.len() / 2].to_vec();
    let len = cut.len() as u32;
    cut[8..12].copy_from_slice(&len.to_le_bytes());
    std::fs::write(&path, &cut).unwrap();
    let msg = bad_mesh_reason(load_mesh(&path));
    assert!(msg.contains("truncated"), "{msg}");

    // Every prefix fails cleanly (never a panic).
    for n in [0, 3, 11, 12, 19, 20, 100, bunny.len() - 1] {
        std::fs::write(&path, &bunny[..n]).unwrap();
        bad_mesh_reason(load_mesh(&path));
    }

    // Flipped bytes in the JSON chunk.
    let mut garbled = bunny.clone();
    for b in &mut garbled[20..60] {
        *b = b'#';
    }
    std::fs::write(&path, &garbled).unwrap();
    let msg = bad_mesh_reason(load_mesh(&path));
    assert!(msg.contains("JSON"), "{msg}");

    // Corrupt .gltf JSON, and not glTF at all.
    let gltf = dir.join("c.gltf");
    std::fs::write(&gltf, br#"{"asset": {"version": "2.0"}, "meshes": [ "#).unwrap();
    let msg = bad_mesh_reason(load_mesh(&gltf));
    assert!(msg.contains("invalid glTF JSON"), "{msg}");
    std::fs::write(&gltf, b"\x89PNG\r\n\x1a\n").unwrap();
    let msg = bad_mesh_reason(load_mesh(&gltf));
    assert!(msg.contains("not a glTF file"), "{msg}");
    // Valid JSON but not glTF.
    std::fs::write(&gltf, br#"{"hello": 1}"#).unwrap();
    bad_mesh_reason(load_mesh(&gltf));
}

#[test]
fn only_lines_is_an_error_saying_so() {
    let dir = TempDir::new("lines");
    let lines = Prim {
        positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        indices: Some(vec![0, 1, 1, 2]),
        mode: 1,
        normals: None,
        tangents: None,
    };
    let msg = bad_mesh_reason(load_doc(&dir, "l", &[lines], r#"[{"mesh":0}]"#, "[0]"));
    assert!(msg.contains("no triangles"), "{msg}");
    assert!(msg.contains("points or lines"), "{msg}");
}

#[test]
fn out_of_range_data_is_an_error() {
    let dir = TempDir::new("range");
    // A vertex index past the vertex count.
    let prim = tri_prim(
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        vec![0, 1, 7],
    );
    let msg = bad_mesh_reason(load_doc(&dir, "i", &[prim], r#"[{"mesh":0}]"#, "[0]"));
    assert!(msg.contains("index 7"), "{msg}");
    assert!(msg.contains("out of range"), "{msg}");

    // An accessor whose count reaches past its buffer view.
    let (json, bin) = gltf_doc(&[one_triangle()], r#"[{"mesh":0}]"#, "[0]", "r.bin");
    let json = json.replacen(
        r#""count":3,"type":"VEC3""#,
        r#""count":300,"type":"VEC3""#,
        1,
    );
    std::fs::write(dir.join("r.bin"), bin).unwrap();
    std::fs::write(dir.join("r.gltf"), json).unwrap();
    let msg = bad_mesh_reason(load_mesh(&dir.join("r.gltf")));
    assert!(msg.contains("out of range"), "{msg}");

    // A POSITION attribute naming an accessor that does not exist.
    let (json, bin) = gltf_doc(&[one_triangle()], r#"[{"mesh":0}]"#, "[0]", "p.bin");
    let json = json.replacen(r#""POSITION":0"#, r#""POSITION":42"#, 1);
    std::fs::write(dir.join("p.bin"), bin).unwrap();
    std::fs::write(dir.join("p.gltf"), json).unwrap();
    let msg = bad_mesh_reason(load_mesh(&dir.join("p.gltf")));
    assert!(msg.contains("accessor 42"), "{msg}");

    // A buffer shorter than it declares.
    let (json, bin) = gltf_doc(&[one_triangle()], r#"[{"mesh":0}]"#, "[0]", "s.bin");
    std::fs::write(dir.join("s.bin"), &bin[..bin.len() - 4]).unwrap();
    std::fs::write(dir.join("s.gltf"), json).unwrap();
    let msg = bad_mesh_reason(load_mesh(&dir.join("s.gltf")));
    assert!(msg.contains("truncated"), "{msg}");

    // A node cycle.
    let msg = bad_mesh_reason(load_doc(
        &dir,
        "c",
        &[one_triangle()],
        r#"[{"mesh":0,"children":[1]},{"children":[0]}]"#,
        "[0]",
    ));
    assert!(
        msg.contains("cycle") || msg.contains("child of both"),
        "{msg}"
    );
}

#[test]
fn data_uri_buffers_and_no_default_scene() {
    let dir = TempDir::new("datauri");
    let (json, bin) = gltf_doc(&[one_triangle()], r#"[{"mesh":0}]"#, "[0]", "BIN");
    // Encode the buffer as base64 by hand (standard alphabet, padded).
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut b64 = String::new();
    for c in bin.chunks(3) {
        let v = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                b64.push(A[(v >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                b64.push('=');
            }
        }
    }
    let json = json
        .replace(
            r#""uri":"BIN""#,
            &format!(r#""uri":"data:application/octet-stream;base64,{b64}""#),
        )
        // No default scene: the roots of all scenes are loaded.
        .replace(r#""scene":0,"#, "");
    let path = dir.join("d.gltf");
    std::fs::write(&path, json).unwrap();
    let (mesh, _) = load_mesh(&path).unwrap();
    assert_eq!(mesh.positions.len(), 3);
    assert_eq!(mesh.triangles, vec![[0, 1, 2]]);
}

#[test]
fn loaded_bunny_writes_a_valid_glb() {
    // load -> planar uvs -> write -> validate -> load: the whole path on a real mesh.
    let dir = TempDir::new("bunnyout");
    let (mut mesh, _) = load_mesh(&repo().join("assets/meshes/bunny.glb")).unwrap();
    let (lo, hi) = mesh.bounding_box();
    let uvs = mesh
        .positions
        .iter()
        .map(|p| {
            let t = (*p - lo) / (hi - lo);
            Vec2::new(t.x, 1.0 - t.y)
        })
        .collect();
    mesh.uvs = Some(uvs);
    let material = MaterialImages {
        base_color: solid(16, 16, |x, y| [(x * 16) as u8, (y * 16) as u8, 64, 255]),
        // Tangents are generated from the (here planar, partly degenerate) uvs.
        normal: Some(solid(16, 16, |_, _| [128, 128, 255, 255])),
        metallic_roughness: None,
        occlusion: None,
    };
    let path = dir.join("bunny_out.glb");
    write_glb(&path, &mesh, &material).unwrap();
    let (back, _) = load_mesh(&path).unwrap();
    assert_eq!(back.positions, mesh.positions);
    assert_eq!(back.triangles, mesh.triangles);
    assert_eq!(back.uvs, mesh.uvs);
    for t in back.tangents.unwrap() {
        assert!(t.is_finite() && (t.truncate().length() - 1.0).abs() < 1e-5 && t.w.abs() == 1.0);
    }
    if let Some(report) = khronos_validate(&path) {
        assert!(
            report.contains(": 0 errors, 0 warnings,"),
            "the validator warns about our file:\n{report}"
        );
    }
}

/// Deterministic mutations of the bunny (JSON numbers, JSON bytes, binary data): every
/// load ends in a mesh or an error, never a panic.
#[test]
fn mutated_files_never_panic() {
    let dir = TempDir::new("mutate");
    let bunny = std::fs::read(repo().join("assets/meshes/bunny.glb")).unwrap();
    let json_len = u32::from_le_bytes(bunny[12..16].try_into().unwrap()) as usize;
    let json = 20..20 + json_len;
    let digits: Vec<usize> = json
        .clone()
        .filter(|&i| bunny[i].is_ascii_digit())
        .collect();
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    let mut next = move |n: usize| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state % n as u64) as usize
    };
    let path = dir.join("m.glb");
    let (mut loaded, mut failed) = (0, 0);
    for round in 0..300 {
        let mut b = bunny.clone();
        for _ in 0..1 + next(3) {
            match round % 3 {
                0 => b[digits[next(digits.len())]] = b'0' + next(10) as u8,
                1 => b[json.start + next(json_len)] = next(256) as u8,
                _ => b[20 + json_len + next(bunny.len() - 20 - json_len)] = next(256) as u8,
            }
        }
        std::fs::write(&path, &b).unwrap();
        match load_mesh(&path) {
            Ok(_) => loaded += 1,
            Err(Error::BadMesh { .. }) => failed += 1,
            Err(e) => panic!("round {round}: unexpected error kind {e:?}"),
        }
    }
    assert!(loaded > 0 && failed > 0, "loaded {loaded}, failed {failed}");
}
