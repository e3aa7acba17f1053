//! Surface synthesis in a texture atlas: the indirection maps, GPU = CPU, seams.

use std::sync::{Arc, OnceLock};

use glam::{Vec2, Vec3};
use texsyn::analysis::{analyze, Analysis, AnalysisOptions};
use texsyn::gpu::synth::GpuSynthesizer;
use texsyn::passes::plan::{PassKind, SynthPlan};
use texsyn::passes::run_cpu_surface;
use texsyn::surface::atlas::{build_atlas, AtlasOptions, AtlasSource};
use texsyn::surface::mesh::Mesh;
use texsyn::surface::pipeline::{self, SurfaceOptions};
use texsyn::surface::seams::seam_report;
use texsyn::SynthParams;

fn analysis(size: u32) -> Arc<Analysis> {
    type Cache = std::sync::Mutex<Vec<(u32, Arc<Analysis>)>>;
    static CACHE: OnceLock<Cache> = OnceLock::new();
    let mut c = CACHE.get_or_init(Default::default).lock().unwrap();
    if let Some((_, a)) = c.iter().find(|(s, _)| *s == size) {
        return a.clone();
    }
    let a = Arc::new(
        analyze(
            &common::gravel_crop(size),
            &AnalysisOptions::default(),
            |_| {},
        )
        .unwrap(),
    );
    c.push((size, a.clone()));
    a
}

fn prepared(mesh: &Mesh, atlas: u32, levels: usize) -> pipeline::PreparedSurface {
    let mut mesh = mesh.clone();
    mesh.validate_and_repair().unwrap();
    let opts = SurfaceOptions {
        atlas: AtlasOptions::for_size(atlas),
        ..SurfaceOptions::default()
    };
    pipeline::prepare(&mesh, levels, &opts).unwrap()
}

/// Two unit squares side by side in the xz plane (x in [0,1] and [1,2]) as two charts:
/// the left one laid out as is, the right one rotated 90 degrees and moved elsewhere in
/// the atlas, so crossing the shared edge needs the unfolding map.
fn two_chart_plane() -> Mesh {
    let p = |x: f32, z: f32| Vec3::new(x, 0.0, z);
    // Left chart: uv = (0.1 + 0.3 x, 0.1 + 0.3 z).
    let l = |x: f32, z: f32| Vec2::new(0.1 + 0.3 * x, 0.1 + 0.3 * z);
    // Right chart: rotated, uv = (0.9 - 0.3 z, 0.6 + 0.3 (x - 1)).
    let r = |x: f32, z: f32| Vec2::new(0.9 - 0.3 * z, 0.6 + 0.3 * (x - 1.0));
    let pts = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)];
    let mut positions = Vec::new();
    let mut uvs = Vec::new();
    for &(x, z) in &pts {
        positions.push(p(x, z));
        uvs.push(l(x, z));
    }
    for &(x, z) in &pts {
        positions.push(p(x + 1.0, z));
        uvs.push(r(x + 1.0, z));
    }
    // Normals +y; triangles counter-clockwise seen from +y.
    let tri = |o: u32| [[o, o + 2, o + 1], [o, o + 3, o + 2]];
    let mut triangles = tri(0).to_vec();
    triangles.extend(tri(4));
    Mesh {
        normals: vec![Vec3::Y; positions.len()],
        positions,
        uvs: Some(uvs),
        tangents: None,
        triangles,
    }
}

/// A generated atlas never lays two charts on the same texels: xatlas's random placement
/// put a chart it found no room for at (0, 0), so a cube at 512 or 1024 had two faces
/// sharing (mirroring) one texture. Each packing is now checked and packed again
/// exhaustively.
#[test]
fn generated_atlases_do_not_overlap() {
    let mut cube = Mesh::cube(2.0, 1);
    cube.uvs = None;
    cube.validate_and_repair().unwrap();
    for size in [320, 512, 1024] {
        let atlas = build_atlas(&cube, &AtlasOptions::for_size(size)).unwrap();
        let (_, overlaps) = texsyn::surface::atlas::rasterize_counting(&atlas, 0);
        assert_eq!(overlaps, 0, "{size}: {overlaps} texels covered twice");
    }
}

/// A mesh's own atlas whose seam runs along the atlas border (a sphere's u = 0 and u = 1)
/// has no room for the indirection band across it: refused (so `Auto` builds one with
/// xatlas) instead of leaving a visible line; the same uvs with a margin are kept.
#[test]
fn own_atlases_with_a_seam_on_the_border_are_refused() {
    // An open tube whose uvs wrap around it: the seam vertices at u = 0 and u = 1 share
    // bit-identical positions; the rims are open boundaries.
    let n = 16u32;
    let (mut positions, mut normals, mut uvs, mut triangles) = (vec![], vec![], vec![], vec![]);
    for j in 0..=1u32 {
        for i in 0..=n {
            let a = (i % n) as f32 / n as f32 * std::f32::consts::TAU;
            positions.push(Vec3::new(a.cos(), j as f32 * 2.0, a.sin()));
            normals.push(Vec3::new(a.cos(), 0.0, a.sin()));
            uvs.push(Vec2::new(i as f32 / n as f32, j as f32));
        }
    }
    for i in 0..n {
        let (a, b, c, d) = (i, i + 1, n + 2 + i, n + 1 + i);
        triangles.push([a, c, b]);
        triangles.push([a, d, c]);
    }
    let mut sphere = Mesh {
        positions,
        normals,
        uvs: Some(uvs),
        tangents: None,
        triangles,
    };
    sphere.validate_and_repair().unwrap();
    let keep = AtlasOptions {
        size: 128,
        gutter: 5,
        source: AtlasSource::Keep,
    };
    let e = build_atlas(&sphere, &keep).unwrap_err().to_string();
    assert!(e.contains("atlas border"), "{e}");
    let auto = build_atlas(
        &sphere,
        &AtlasOptions {
            source: AtlasSource::Auto,
            ..keep.clone()
        },
    )
    .unwrap();
    assert!(auto.generated);
    for uv in sphere.uvs.as_mut().unwrap() {
        *uv = Vec2::splat(0.1) + *uv * 0.8;
    }
    let kept = build_atlas(&sphere, &keep).unwrap();
    assert!(!kept.generated);
}

#[test]
fn indirection_lands_on_the_same_surface_point() {
    let mesh = two_chart_plane();
    let atlas = build_atlas(
        &mesh,
        &AtlasOptions {
            size: 64,
            gutter: 5,
            source: AtlasSource::Keep,
        },
    )
    .unwrap();
    assert_eq!(atlas.chart_count, 2);
    let field = texsyn::surface::tangent_field::TangentField::build(
        &atlas.mesh,
        None,
        &texsyn::surface::tangent_field::DirectionSource::Up(Vec3::Z),
        &texsyn::surface::tangent_field::ScaleSource::Constant(1.0 / 19.2),
    )
    .unwrap();
    let (domain, report) = texsyn::surface::maps::build_domain(&atlas, &field, 1).unwrap();
    assert!(report.crossed > 0, "{report:?}");
    let level = &domain.levels[0];
    let size = 64.0f32;
    // Atlas texel -> world point, per chart (the inverse of the layouts above).
    let world_left = |u: Vec2| Vec2::new((u.x / size - 0.1) / 0.3, (u.y / size - 0.1) / 0.3);
    let world_right = |u: Vec2| Vec2::new(1.0 + (u.y / size - 0.6) / 0.3, (0.9 - u.x / size) / 0.3);
    let centre = |i: u32| Vec2::new((i % 64) as f32 + 0.5, (i / 64) as f32 + 0.5);
    let mut checked = 0;
    for e in &level.fill[..level.band as usize] {
        let d = centre(e.dst);
        // Gutter texels just right of the left chart (x beyond its right edge, within
        // its z range): they stand for points of the right square.
        let w = world_left(d);
        if !(w.x > 1.0 && w.x < 1.15 && w.y > 0.05 && w.y < 0.95) {
            continue;
        }
        let src = centre(e.src) + Vec2::new(e.off[0] as f32, e.off[1] as f32) / 16.0;
        let got = world_right(src);
        assert!(
            got.distance(w) < 0.01,
            "texel {} stands for {w:?} but reads the right chart at {got:?}",
            e.dst
        );
        checked += 1;
    }
    assert!(checked >= 10, "only {checked} band texels checked");
}

#[test]
fn atlas_synthesis_gpu_matches_cpu() {
    let a = analysis(32);
    let prep = prepared(&Mesh::cube(1.0, 2), 64, a.levels.len());
    // The finest level's correction is off by default; on here so that it is covered.
    let base = SynthParams {
        finest_passes: 1,
        ..Default::default()
    };
    let params = pipeline::atlas_params(&prep, &base);
    let plan = SynthPlan::new(&a, &params).unwrap();
    let schedule = plan.schedule(&a);
    assert!(schedule.iter().any(|d| d.kind == PassKind::Fill));
    let jac = plan.jacobians();
    let surface = plan.surface_words().0;
    // Pass by pass at a few points (after fills and corrections), then the whole run.
    let synth = GpuSynthesizer::new(ctx(), a.clone()).unwrap();
    let mut cpu = vec![[0i32; 2]; plan.coord_count as usize];
    let mut done = 0;
    let checkpoints: Vec<usize> = schedule
        .iter()
        .enumerate()
        .filter(|(i, d)| d.kind == PassKind::Fill && i % 7 == 0)
        .map(|(i, _)| i + 1)
        .take(4)
        .collect();
    assert!(!checkpoints.is_empty());
    for &end in &checkpoints {
        run_cpu_surface(&a, &schedule[done..end], &mut cpu, &jac, &surface);
        done = end;
        let gpu = synth.run_prefix(&params, end).unwrap();
        assert!(gpu == cpu, "GPU and CPU differ after dispatch {end}");
    }
    let cpu_out = texsyn::passes::synthesize_cpu(&a, &params).unwrap();
    let gpu_out = synth.synthesize_to_host(&params).unwrap();
    assert_eq!(gpu_out.coords, cpu_out.coords);
    assert_eq!(gpu_out.colors, cpu_out.colors);
    // Deterministic: the same bytes again; another seed differs.
    assert_eq!(
        synth.synthesize_to_host(&params).unwrap().colors,
        gpu_out.colors
    );
    let other = SynthParams { seed: 9, ..params };
    assert_ne!(
        synth.synthesize_to_host(&other).unwrap().colors,
        gpu_out.colors
    );
}

/// Seam visibility with and without the indirection maps, on meshes with many seams.
#[test]
fn seams_are_no_more_visible_than_texel_steps() {
    let a = analysis(64);
    let synth = GpuSynthesizer::new(ctx(), a.clone()).unwrap();
    for (name, mesh) in [
        ("sphere", Mesh::uv_sphere(1.0, 24, 12)),
        ("cube", Mesh::cube(1.0, 3)),
        ("torus", Mesh::torus(1.0, 0.4, 32, 16)),
    ] {
        let prep = prepared(&mesh, 128, a.levels.len());
        let (s, _) = pipeline::synthesize(&synth, &prep, &SynthParams::default(), &[]).unwrap();
        let with = seam_report(&prep.atlas, &s.colors);
        // The same synthesis with every gutter texel copying itself: no indirection.
        let mut d = (*prep.domain).clone();
        for l in &mut d.levels {
            for e in &mut l.fill {
                e.src = e.dst;
                e.off = [0, 0];
            }
        }
        let mut plain = prep.clone();
        plain.domain = Arc::new(d);
        let (s2, _) = pipeline::synthesize(&synth, &plain, &SynthParams::default(), &[]).unwrap();
        let without = seam_report(&prep.atlas, &s2.colors);
        eprintln!("{name}: with indirection {with:?}\n   without {without:?}");
        assert!(
            with.seam_edges > 10 && with.samples > 100,
            "{name}: {with:?}"
        );
        assert!(with.ratio <= 1.5, "{name}: seam ratio {} > 1.5", with.ratio);
        assert!(
            with.ratio < without.ratio,
            "{name}: indirection does not help ({} vs {})",
            with.ratio,
            without.ratio
        );
    }
}

#[test]
fn open_meshes_and_bad_surface_inputs() {
    let a = analysis(32);
    // An open mesh: walks stop at the boundary instead of failing.
    let mut plane = Mesh::plane(2.0, 2.0, 3);
    plane.uvs = None;
    let prep = prepared(&plane, 64, a.levels.len());
    assert!(prep.report.boundary > 0);
    let synth = GpuSynthesizer::new(ctx(), a.clone()).unwrap();
    pipeline::synthesize(&synth, &prep, &SynthParams::default(), &[]).unwrap();

    let mut sphere = Mesh::uv_sphere(1.0, 12, 6);
    sphere.validate_and_repair().unwrap();
    let bad_size = SurfaceOptions {
        atlas: AtlasOptions {
            size: 4,
            ..AtlasOptions::default()
        },
        ..SurfaceOptions::default()
    };
    let e = pipeline::prepare(&sphere, 5, &bad_size)
        .unwrap_err()
        .to_string();
    assert!(e.contains("atlas size"), "{e}");
    // A mesh modelled at a tiny scale (1e-15 units across: its triangle areas underflow
    // in f32) is refused with what to do; one a micrometre across still works.
    let mut tiny = Mesh::plane(1e-15, 1e-15, 2);
    tiny.validate_and_repair().unwrap();
    let opts64 = SurfaceOptions {
        atlas: AtlasOptions {
            size: 64,
            ..AtlasOptions::default()
        },
        ..SurfaceOptions::default()
    };
    let e = pipeline::prepare(&tiny, 5, &opts64)
        .unwrap_err()
        .to_string();
    assert!(e.contains("scale it up"), "{e}");
    let mut small = Mesh::plane(1e-6, 1e-6, 2);
    small.validate_and_repair().unwrap();
    pipeline::prepare(&small, 5, &opts64).unwrap();
    for s in [1e6f32, 0.0, -1.0, f32::NAN] {
        let opts = SurfaceOptions {
            atlas: AtlasOptions {
                size: 64,
                ..AtlasOptions::default()
            },
            scale: Some(texsyn::surface::tangent_field::ScaleSource::Constant(s)),
            ..SurfaceOptions::default()
        };
        assert!(
            pipeline::prepare(&sphere, 5, &opts).is_err(),
            "texel size {s}"
        );
    }
    let keep = SurfaceOptions {
        atlas: AtlasOptions {
            size: 64,
            source: AtlasSource::Keep,
            ..AtlasOptions::default()
        },
        ..SurfaceOptions::default()
    };
    let e = pipeline::prepare(&sphere, 5, &keep)
        .unwrap_err()
        .to_string();
    assert!(e.contains("TEXCOORD_0"), "{e}");
    // Overlapping uvs are refused when kept, replaced otherwise.
    let mut overlapping = two_chart_plane();
    let uvs = overlapping.uvs.as_mut().unwrap();
    for i in 4..8 {
        uvs[i] = uvs[i - 4];
    }
    let e = pipeline::prepare(&overlapping, 5, &keep)
        .unwrap_err()
        .to_string();
    assert!(e.contains("not a usable atlas"), "{e}");
    let auto = SurfaceOptions {
        atlas: AtlasOptions {
            size: 64,
            ..AtlasOptions::default()
        },
        ..SurfaceOptions::default()
    };
    let p = pipeline::prepare(&overlapping, 5, &auto).unwrap();
    assert!(
        p.atlas.generated && p.atlas.note.contains("TEXCOORD_0"),
        "{}",
        p.atlas.note
    );
}

mod common;
use common::ctx;

/// `texsyn surface` end to end on the bundled bunny, and its bad inputs.
#[test]
fn surface_cli_end_to_end_and_bad_inputs() {
    let dir = common::TempDir::new("surface-cli");
    let run = |args: &[&str]| {
        common::cli::command(&common::repo())
            .args(args)
            .env("XDG_RUNTIME_DIR", std::env::temp_dir())
            .output()
            .unwrap()
    };
    let out = dir.path("bunny.glb");
    let render = dir.path("views.png");
    let atlas = dir.path("atlas.png");
    let o = run(&[
        "surface",
        "assets/meshes/bunny.glb",
        "assets/gravel.png",
        "-o",
        out.to_str().unwrap(),
        "--atlas-size",
        "256",
        "--render",
        render.to_str().unwrap(),
        "--views",
        "2",
        "--view-size",
        "128",
        "--atlas-out",
        atlas.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert!(
        stderr.contains("seams:") && stderr.contains("preprocessing"),
        "{stderr}"
    );
    let views = image::open(&render).unwrap().to_rgba8();
    assert_eq!(views.dimensions(), (256, 128));
    // The mesh covers a good part of each view and is textured (not flat).
    let lum: Vec<f32> = views
        .pixels()
        .filter(|p| p.0[..3] != [64, 64, 64])
        .map(|p| p.0[0] as f32)
        .collect();
    assert!(lum.len() > 256 * 128 / 8, "only {} mesh pixels", lum.len());
    let mean = lum.iter().sum::<f32>() / lum.len() as f32;
    let var = lum.iter().map(|v| (v - mean).powi(2)).sum::<f32>() / lum.len() as f32;
    assert!(var > 100.0, "render looks flat (variance {var})");
    assert_eq!(
        image::open(&atlas).unwrap().to_rgba8().dimensions(),
        (256, 256)
    );
    // The written .glb loads back with the atlas, and passes the Khronos validator.
    let (mesh, _) = texsyn::surface::gltf_io::load_mesh(&out).unwrap();
    assert!(mesh.uvs.is_some() && mesh.triangles.len() == 3674);
    if let Some(report) = common::khronos_validate(&out) {
        assert!(report.contains(" 0 errors"), "{report}");
    }

    // Material maps: a normal map made from the exemplar's gradients, the exemplar as
    // roughness and occlusion; all three end up in the material and the file validates.
    let grey = image::open("assets/gravel.png").unwrap().to_luma8();
    let (w, h) = grey.dimensions();
    let normal_map = image::RgbaImage::from_fn(w, h, |x, y| {
        let at = |x: i64, y: i64| {
            grey.get_pixel(x.rem_euclid(w as i64) as u32, y.rem_euclid(h as i64) as u32)
                .0[0] as f32
                / 255.0
        };
        let (x, y) = (x as i64, y as i64);
        let n = glam::Vec3::new(
            at(x - 1, y) - at(x + 1, y),
            at(x, y - 1) - at(x, y + 1),
            0.5,
        )
        .normalize();
        let b = |v: f32| ((v * 0.5 + 0.5) * 255.0).round() as u8;
        image::Rgba([b(n.x), b(n.y), b(n.z), 255])
    });
    let normal_path = dir.path("normal.png");
    normal_map.save(&normal_path).unwrap();
    let out2 = dir.path("materials.glb");
    let o = run(&[
        "surface",
        "assets/meshes/bunny.glb",
        "assets/gravel.png",
        "-o",
        out2.to_str().unwrap(),
        "--atlas-size",
        "128",
        "--normal-map",
        normal_path.to_str().unwrap(),
        "--roughness-map",
        "assets/gravel.png",
        "--occlusion-map",
        "assets/gravel.png",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let bytes = std::fs::read(&out2).unwrap();
    let text = String::from_utf8_lossy(&bytes);
    for key in [
        "normalTexture",
        "metallicRoughnessTexture",
        "occlusionTexture",
        "TANGENT",
    ] {
        assert!(text.contains(key), "{key} missing from the material");
    }
    if let Some(report) = common::khronos_validate(&out2) {
        assert!(report.contains(" 0 errors"), "{report}");
    }

    // Bad inputs: a clear message, non-zero exit, nothing written.
    let bad = dir.path("bad.glb");
    std::fs::write(&bad, b"glTF\x02\x00\x00\x00garbage").unwrap();
    let target = dir.path("never.glb");
    for (args, expect) in [
        (
            vec!["surface", "missing.glb", "assets/gravel.png"],
            "missing.glb",
        ),
        (
            vec!["surface", bad.to_str().unwrap(), "assets/gravel.png"],
            "bad.glb",
        ),
        (
            vec!["surface", "assets/meshes/bunny.glb", "nope.png"],
            "nope.png",
        ),
        (
            vec![
                "surface",
                "assets/meshes/bunny.glb",
                "assets/gravel.png",
                "--texel-size",
                "1e9",
            ],
            "texel size",
        ),
        (
            vec![
                "surface",
                "assets/meshes/bunny.glb",
                "assets/gravel.png",
                "--atlas-size",
                "4",
            ],
            "8..=16384",
        ),
        (
            vec![
                "surface",
                "assets/meshes/bunny.glb",
                "assets/gravel.png",
                "--keep-uvs",
            ],
            "TEXCOORD_0",
        ),
        (
            vec![
                "surface",
                "assets/meshes/bunny.glb",
                "assets/gravel.png",
                "--normal-map",
                "assets/meshes/README.md",
            ],
            "README.md",
        ),
    ] {
        let mut a = args.clone();
        a.extend(["-o", target.to_str().unwrap()]);
        let o = run(&a);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(stderr.contains(expect), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
        assert!(!target.exists());
    }
    let o = run(&[
        "surface",
        "assets/meshes/bunny.glb",
        "assets/gravel.png",
        "-o",
        dir.path("out.png").to_str().unwrap(),
    ]);
    assert!(String::from_utf8_lossy(&o.stderr).contains(".glb"));
    let leftovers: Vec<_> = std::fs::read_dir(&dir.0)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("tmp") || n.starts_with('.'))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
}

/// `surface --magnify` with material maps: the maps are magnified with the colours
/// (a roughness map equal to the exemplar's grey comes out equal to the base colour).
#[test]
fn surface_cli_magnifies_material_maps() {
    let dir = common::TempDir::new("surface-magnify");
    let out = dir.path("m.glb");
    let o = common::cli::command(&common::repo())
        .args([
            "surface",
            "assets/meshes/bunny.glb",
            "assets/gravel.png",
            "-o",
            out.to_str().unwrap(),
            "--atlas-size",
            "64",
            "--magnify",
            "2",
            "--roughness-map",
            "assets/gravel.png",
            "-q",
        ])
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (doc, _, images) = gltf::import(&out).unwrap();
    let m = doc.materials().next().unwrap();
    let pbr = m.pbr_metallic_roughness();
    let base = &images[pbr.base_color_texture().unwrap().texture().source().index()];
    let rough = &images[pbr
        .metallic_roughness_texture()
        .unwrap()
        .texture()
        .source()
        .index()];
    assert_eq!((base.width, base.height), (128, 128));
    assert_eq!((rough.width, rough.height), (128, 128));
    let channels = |d: &gltf::image::Data| match d.format {
        gltf::image::Format::R8G8B8A8 => 4,
        gltf::image::Format::R8G8B8 => 3,
        other => panic!("unexpected image format {other:?}"),
    };
    let (cb, cr) = (channels(base), channels(rough));
    for i in 0..128 * 128 {
        // Roughness is packed in green; the grey exemplar's colour in every channel.
        assert_eq!(base.pixels[i * cb], rough.pixels[i * cr + 1], "texel {i}");
    }
}
