//! Offscreen rendering of textured meshes (`texsyn::surface::render`) on whatever adapter
//! the machine has (lavapipe in CI): texture orientation and lighting, depth test,
//! magnification conventions, errors and determinism.

mod common;
use common::fresh_ctx as context;

use std::f32::consts::TAU;

use glam::{Vec2, Vec3};
use texsyn::surface::render::{
    render_view, render_views, shade, Camera, RenderOptions, SurfaceTexture,
};
use texsyn::surface::Mesh;
use texsyn::Error;

const BACKGROUND: [u8; 3] = [10, 20, 30];

/// A square in the plane z = `z`, centred on the z axis, facing +Z, with glTF uvs
/// (v down): the top-left corner (-h, +h) has uv `uv0`, the bottom-right one `uv1`.
fn quad(z: f32, half: f32, uv0: Vec2, uv1: Vec2) -> Mesh {
    let h = half;
    Mesh {
        positions: vec![
            Vec3::new(-h, h, z),
            Vec3::new(-h, -h, z),
            Vec3::new(h, -h, z),
            Vec3::new(h, h, z),
        ],
        normals: vec![Vec3::Z; 4],
        uvs: Some(vec![
            uv0,
            Vec2::new(uv0.x, uv1.y),
            uv1,
            Vec2::new(uv1.x, uv0.y),
        ]),
        tangents: None,
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    }
}

fn full_quad(z: f32, half: f32) -> Mesh {
    quad(z, half, Vec2::ZERO, Vec2::ONE)
}

/// Concatenate two meshes (triangles of `a` first).
fn concat(a: &Mesh, b: &Mesh) -> Mesh {
    let n = a.positions.len() as u32;
    let mut m = a.clone();
    m.positions.extend(&b.positions);
    m.normals.extend(&b.normals);
    m.uvs
        .as_mut()
        .unwrap()
        .extend(b.uvs.as_ref().unwrap().iter());
    m.triangles
        .extend(b.triangles.iter().map(|t| t.map(|i| i + n)));
    m
}

/// Looking down -Z from (0, 0, `distance`), +Y up.
fn front_camera(distance: f32, fov_y_deg: f32) -> Camera {
    Camera {
        eye: Vec3::new(0.0, 0.0, distance),
        target: Vec3::ZERO,
        up: Vec3::Y,
        fov_y_deg,
    }
}

fn pixel(img: &image::RgbaImage, x: u32, y: u32) -> [u8; 4] {
    img.get_pixel(x, y).0
}

fn lit(c: [u8; 3], shade: f32) -> [u8; 3] {
    c.map(|v| (v as f32 * shade).round() as u8)
}

fn assert_close(got: [u8; 4], want: [u8; 3], tol: u8, what: &str) {
    let ok = (0..3).all(|c| got[c].abs_diff(want[c]) <= tol) && got[3] == 255;
    assert!(
        ok,
        "{what}: got {got:?}, expected {want:?} (+-{tol}), alpha 255"
    );
}

/// 3x3 cells of 16 texels, each its own colour: red encodes the column, green the row.
fn cell_atlas() -> (Vec<u8>, u32, u32) {
    let (w, h) = (48u32, 48u32);
    let mut rgba = Vec::with_capacity((w * h * 4) as usize);
    for y in 0..h {
        for x in 0..w {
            rgba.extend_from_slice(&cell_colour(x / 16, y / 16));
            rgba.push(255);
        }
    }
    (rgba, w, h)
}

fn cell_colour(cx: u32, cy: u32) -> [u8; 3] {
    [(40 + cx * 90) as u8, (30 + cy * 100) as u8, 150]
}

#[test]
fn textured_plane_shows_its_texels_lit_and_the_background_around_it() {
    let ctx = context();
    let (rgba, w, h) = cell_atlas();
    let texture = SurfaceTexture::Color {
        rgba: &rgba,
        width: w,
        height: h,
    };
    // fov 90 degrees at distance 2: the view spans [-2, 2]^2 in the plane z = 0, the
    // quad [-1, 1]^2 covers the central half of the 128x128 view (pixels 32..96).
    let size = 128;
    let img = render_view(
        &ctx,
        &full_quad(0.0, 1.0),
        &texture,
        &front_camera(2.0, 90.0),
        size,
        BACKGROUND,
    )
    .expect("render");
    assert_eq!(img.dimensions(), (size, size));
    let s = shade(Vec3::Z);
    assert!(s > 0.5 && s < 1.0, "shade {s}");

    // Pixel (px, py) centre -> world x = ((px + 0.5) / 128 * 2 - 1) * 2, y likewise with
    // the image's y pointing down; uv = ((x + 1) / 2, (1 - y) / 2). Cell centres at
    // uv = (2c + 1) / 6 land on pixels 42, 64, 85.
    for (cy, py) in [(0, 42), (1, 64), (2, 85)] {
        for (cx, px) in [(0, 42), (1, 64), (2, 85)] {
            assert_close(
                pixel(&img, px, py),
                lit(cell_colour(cx, cy), s),
                1,
                &format!("pixel ({px}, {py}), cell ({cx}, {cy})"),
            );
        }
    }
    // Outside the quad: the background, exactly.
    for (x, y) in [(0, 0), (127, 127), (5, 64), (64, 120), (127, 0), (30, 64)] {
        assert_close(
            pixel(&img, x, y),
            BACKGROUND,
            0,
            &format!("background ({x}, {y})"),
        );
    }
}

#[test]
fn nearer_surface_wins_whatever_the_triangle_order() {
    let ctx = context();
    // Left texel red, right texel green; each quad samples one texel centre.
    let rgba = [220, 30, 30, 255, 30, 200, 40, 255];
    let texture = SurfaceTexture::Color {
        rgba: &rgba,
        width: 2,
        height: 1,
    };
    let red = Vec2::new(0.25, 0.5);
    let green = Vec2::new(0.75, 0.5);
    let near = quad(0.5, 0.5, red, red);
    let far = quad(0.0, 1.5, green, green);
    let camera = front_camera(2.0, 90.0);
    let s = shade(Vec3::Z);
    let mut images = Vec::new();
    for mesh in [concat(&near, &far), concat(&far, &near)] {
        let img = render_view(&ctx, &mesh, &texture, &camera, 128, BACKGROUND).expect("render");
        // Centre: both quads, the near one (red) wins.
        assert_close(pixel(&img, 64, 64), lit([220, 30, 30], s), 1, "centre");
        // World x = 1 on the far quad (pixel 96): only the far quad (green).
        assert_close(
            pixel(&img, 100, 64),
            lit([30, 200, 40], s),
            1,
            "far quad only",
        );
        assert_close(pixel(&img, 2, 2), BACKGROUND, 0, "corner");
        images.push(img);
    }
    assert!(
        images[0] == images[1],
        "the triangle order changed the image"
    );
}

/// A smooth, non-symmetric RGBA8 test exemplar.
fn exemplar(w: u32, h: u32) -> Vec<u8> {
    let mut rgba = Vec::with_capacity((w * h * 4) as usize);
    for y in 0..h {
        for x in 0..w {
            let (fx, fy) = (x as f32 / w as f32, y as f32 / h as f32);
            let r = 128.0 + 100.0 * (fx * TAU * 3.0).sin() * (fy * TAU).cos();
            let g = 40.0 + 180.0 * fx * fy;
            let b = ((x * 7 + y * 13) % 64) as f32 * 3.0 + 20.0;
            rgba.extend_from_slice(&[r as u8, g as u8, b as u8, 255]);
        }
    }
    rgba
}

/// Compare two renders over the whole view: max and mean absolute difference.
fn differences(a: &image::RgbaImage, b: &image::RgbaImage) -> (u8, f64) {
    assert_eq!(a.dimensions(), b.dimensions());
    let mut max = 0u8;
    let mut sum = 0u64;
    for (p, q) in a.as_raw().iter().zip(b.as_raw()) {
        let d = p.abs_diff(*q);
        max = max.max(d);
        sum += d as u64;
    }
    (max, sum as f64 / a.as_raw().len() as f64)
}

/// Magnified mode against the colour mode: atlas 32x32, high-resolution exemplar 64x64
/// (factor 2). `map` gives, for an atlas texel (i, j), the exemplar position S of its
/// centre and the Jacobian; `expected` is the colour atlas (64x64) the magnification
/// should reproduce.
fn magnified_matches(map: impl Fn(u32, u32) -> ([f32; 2], [f32; 4]), expected: &[u8], what: &str) {
    let ctx = context();
    let (w, h, hi) = (32u32, 32u32, 64u32);
    let hi_rgba = exemplar(hi, hi);
    let mut coords = Vec::new();
    let mut jacobian = Vec::new();
    for j in 0..h {
        for i in 0..w {
            let (s, jac) = map(i, j);
            coords.push(s);
            jacobian.push(jac);
        }
    }
    let magnified = SurfaceTexture::Magnified {
        coords: &coords,
        jacobian: &jacobian,
        width: w,
        height: h,
        hi_rgba: &hi_rgba,
        hi_width: hi,
        hi_height: hi,
        factor: 2.0,
    };
    let color = SurfaceTexture::Color {
        rgba: expected,
        width: hi,
        height: hi,
    };
    // The quad [-1, 1]^2 at distance 1 with a 60 degree fov: the view sees its central
    // part (uv in [0.21, 0.79]), away from the atlas border where the colour mode clamps
    // and the magnified one wraps; ~3.5 pixels per high-resolution texel (no mip level).
    let mesh = full_quad(0.0, 1.0);
    let camera = front_camera(1.0, 60.0);
    let a = render_view(&ctx, &mesh, &magnified, &camera, 128, BACKGROUND).expect("magnified");
    let b = render_view(&ctx, &mesh, &color, &camera, 128, BACKGROUND).expect("colour");
    let (max, mean) = differences(&a, &b);
    println!("{what}: max difference {max}, mean {mean:.4}");
    assert!(max <= 3 && mean < 0.5, "{what}: max {max}, mean {mean}");
}

#[test]
fn magnified_identity_matches_the_high_resolution_exemplar() {
    let expected = exemplar(64, 64);
    magnified_matches(
        |i, j| ([i as f32 + 0.5, j as f32 + 0.5], [1.0, 0.0, 0.0, 1.0]),
        &expected,
        "identity",
    );
}

#[test]
fn magnified_follows_the_jacobian_layout() {
    // A quarter turn: S(x) = (x.y, 32 - x.x), so dS/dx = [[0, 1], [-1, 0]]
    // ([j00, j01, j10, j11] = [0, 1, -1, 0]). The colour seen at atlas position y (in
    // 64ths) is the exemplar at (y.y, 64 - y.x): expected texel (i, j) = hi(j, 63 - i).
    let hi = exemplar(64, 64);
    let mut expected = vec![0u8; hi.len()];
    for j in 0..64usize {
        for i in 0..64usize {
            let src = ((63 - i) * 64 + j) * 4;
            expected[(j * 64 + i) * 4..][..4].copy_from_slice(&hi[src..src + 4]);
        }
    }
    magnified_matches(
        |i, j| {
            (
                [j as f32 + 0.5, 32.0 - (i as f32 + 0.5)],
                [0.0, 1.0, -1.0, 0.0],
            )
        },
        &expected,
        "quarter turn",
    );
}

#[test]
fn mesh_without_uvs_is_an_invalid_parameter() {
    let ctx = context();
    let mut mesh = full_quad(0.0, 1.0);
    mesh.uvs = None;
    let rgba = [255u8; 4];
    let texture = SurfaceTexture::Color {
        rgba: &rgba,
        width: 1,
        height: 1,
    };
    let err = render_views(&ctx, &mesh, &texture, &RenderOptions::default()).unwrap_err();
    assert!(matches!(err, Error::InvalidParameter(_)), "{err}");
    assert!(err.to_string().contains("texture coordinates"), "{err}");
}

#[test]
fn atlas_past_the_device_limit_is_too_large() {
    let ctx = context();
    let max = ctx.limits().max_texture_dimension_2d;
    let mesh = full_quad(0.0, 1.0);
    let rgba = vec![0u8; (max as usize + 1) * 4];
    let texture = SurfaceTexture::Color {
        rgba: &rgba,
        width: max + 1,
        height: 1,
    };
    let err = render_view(
        &ctx,
        &mesh,
        &texture,
        &front_camera(2.0, 60.0),
        64,
        BACKGROUND,
    )
    .unwrap_err();
    assert!(matches!(err, Error::TooLarge { .. }), "{err}");
    assert!(
        err.to_string().contains("max_texture_dimension_2d"),
        "{err}"
    );

    let coords = vec![[0.0f32; 2]; max as usize + 1];
    let jacobian = vec![[1.0f32, 0.0, 0.0, 1.0]; max as usize + 1];
    let hi = [128u8; 16];
    let texture = SurfaceTexture::Magnified {
        coords: &coords,
        jacobian: &jacobian,
        width: 1,
        height: max + 1,
        hi_rgba: &hi,
        hi_width: 2,
        hi_height: 2,
        factor: 2.0,
    };
    let err = render_view(
        &ctx,
        &mesh,
        &texture,
        &front_camera(2.0, 60.0),
        64,
        BACKGROUND,
    )
    .unwrap_err();
    assert!(matches!(err, Error::TooLarge { .. }), "{err}");

    // So is an output wider than the limit.
    let texture = SurfaceTexture::Color {
        rgba: &rgba[..4],
        width: 1,
        height: 1,
    };
    let opts = RenderOptions {
        view_size: max / 2 + 1,
        views: 2,
        background: BACKGROUND,
    };
    let err = render_views(&ctx, &mesh, &texture, &opts).unwrap_err();
    assert!(matches!(err, Error::TooLarge { .. }), "{err}");
}

/// A unit cube, 4 vertices per face, each face mapped to its own cell of a 3x2 atlas.
fn cube() -> Mesh {
    let mut mesh = Mesh {
        uvs: Some(Vec::new()),
        ..Mesh::default()
    };
    let faces = [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
    for (f, n) in faces.iter().enumerate() {
        let u = if n.y.abs() > 0.5 { Vec3::X } else { Vec3::Y };
        let v = n.cross(u);
        let base = mesh.positions.len() as u32;
        let cell = Vec2::new((f % 3) as f32, (f / 3) as f32);
        for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            mesh.positions.push(*n + a * u + b * v);
            mesh.normals.push(*n);
            let t = Vec2::new((a + 1.0) * 0.4 + 0.1, (b + 1.0) * 0.4 + 0.1);
            mesh.uvs
                .as_mut()
                .unwrap()
                .push((cell + t) / Vec2::new(3.0, 2.0));
        }
        mesh.triangles.push([base, base + 1, base + 2]);
        mesh.triangles.push([base, base + 2, base + 3]);
    }
    mesh
}

#[test]
fn orbit_views_are_side_by_side_and_deterministic() {
    let ctx = context();
    let (w, h) = (96u32, 64u32);
    let mut rgba = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let cell = (x / 32) + 3 * (y / 32);
            let checker = ((x / 4) + (y / 4)) % 2 == 0;
            let c = [
                (cell * 40 + 30) as u8,
                (200 - cell * 30) as u8,
                if checker { 230 } else { 90 },
            ];
            rgba.extend_from_slice(&[c[0], c[1], c[2], 255]);
        }
    }
    let texture = SurfaceTexture::Color {
        rgba: &rgba,
        width: w,
        height: h,
    };
    let opts = RenderOptions {
        view_size: 128,
        views: 4,
        background: BACKGROUND,
    };
    let mesh = cube();
    let a = render_views(&ctx, &mesh, &texture, &opts).expect("render");
    let b = render_views(&ctx, &mesh, &texture, &opts).expect("render again");
    assert_eq!(a.dimensions(), (4 * 128, 128));
    assert!(a.as_raw() == b.as_raw(), "two renders differ");
    let out = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("render_cube_views.png");
    a.save(&out).expect("save");
    println!("wrote {}", out.display());

    let background = image::Rgba([BACKGROUND[0], BACKGROUND[1], BACKGROUND[2], 255]);
    let mut views = Vec::new();
    for v in 0..4 {
        let view = image::imageops::crop_imm(&a, v * 128, 0, 128, 128).to_image();
        // The cube is framed: its centre is covered, the corners are background.
        assert_ne!(*view.get_pixel(64, 64), background, "view {v} centre");
        for (x, y) in [(0, 0), (127, 0), (0, 127), (127, 127)] {
            assert_eq!(
                *view.get_pixel(x, y),
                background,
                "view {v} corner ({x}, {y})"
            );
        }
        let covered = view.pixels().filter(|p| **p != background).count();
        assert!(
            covered > 128 * 128 / 8,
            "view {v}: only {covered} pixels cover the cube"
        );
        views.push(view);
    }
    // Different azimuths see different faces.
    for v in 1..4 {
        assert!(views[v] != views[0], "view {v} equals view 0");
    }
}
