//! One- and two-channel OpenEXRs (read with the exr crate; the image crate refuses
//! them): as exemplars, direction-scale fields and velocities, and when corrupt.

use std::path::Path;

use image::{DynamicImage, ImageBuffer};
use texsyn::image_io::{load_coords_exr_f32, load_exemplar, load_material_map, open_image};
use texsyn::Error;

use crate::common::TempDir;
use crate::helpers::*;

#[test]
fn grey_exr_loads_as_grey_exemplar() {
    let dir = TempDir::new("exr-grey");
    let (w, h) = (19usize, 16usize);
    let v: Vec<f32> = (0..w * h)
        .map(|i| ((i * 7 + i / w * 3) % 17) as f32 / 16.0)
        .collect();
    for name in ["Y", "Z"] {
        let path = dir.join(&format!("grey-{name}.exr"));
        write_exr(&path, w, h, &[(name, v.clone())]);
        let ex = load_exemplar(&path).unwrap();
        assert_eq!((ex.width, ex.height, ex.channels), (19, 16, 1), "{name}");
        assert_eq!(ex.values, v, "{name}");
        let q = |x: f32| (x * 255.0).round() as u8;
        assert!(ex
            .colors
            .iter()
            .zip(&v)
            .all(|(c, &x)| *c == [q(x), q(x), q(x), 255]));

        // Auxiliary inputs: grey replicated into float RGB; a material map is grey.
        let img = open_image(&path).unwrap();
        assert_eq!(rgb32f(&img).get_pixel(3, 2).0, [v[2 * w + 3]; 3]);
        let (mw, mh, mc, px) = load_material_map(&path).unwrap();
        assert_eq!((mw, mh, mc), (19, 16, 1));
        assert_eq!(px[7], [q(v[7]), q(v[7]), q(v[7]), 255]);
    }

    // The float rules of other float exemplars: a few samples out of range are clamped,
    // NaN is an error naming the pixel.
    let mut c = v.clone();
    c[0] = -0.2;
    c[1] = 1.3;
    let path = dir.join("clamped.exr");
    write_exr(&path, w, h, &[("Y", c)]);
    let ex = load_exemplar(&path).unwrap();
    assert_eq!(&ex.values[..3], &[0.0, 1.0, v[2]]);
    let mut n = v.clone();
    n[w + 4] = f32::NAN;
    let path = dir.join("nan.exr");
    write_exr(&path, w, h, &[("Y", n)]);
    let err = load_exemplar(&path).unwrap_err().to_string();
    assert!(err.contains("(4, 1)") && err.contains("NaN"), "{err}");
    let hdr: Vec<f32> = v.iter().map(|x| x * 4.0 + 2.0).collect();
    let path = dir.join("hdr.exr");
    write_exr(&path, w, h, &[("Y", hdr)]);
    let err = load_exemplar(&path).unwrap_err().to_string();
    assert!(err.contains("tone-map"), "{err}");
}

#[test]
fn two_channel_exr_reads_first_two_channels() {
    let dir = TempDir::new("exr-two");
    let (w, h) = (8usize, 5usize);
    let a: Vec<f32> = (0..w * h).map(|i| (i % w) as f32 + 0.25).collect();
    let b: Vec<f32> = (0..w * h).map(|i| -((i / w) as f32) * 1.5 - 3.0).collect();
    // R, G (stored sorted G, R) -> (R, G); X, Y and U, V -> alphabetical; Y, A -> (Y, A).
    for (n0, n1) in [
        ("R", "G"),
        ("X", "Y"),
        ("U", "V"),
        ("Y", "A"),
        ("flow.R", "flow.G"),
    ] {
        let path = dir.join(&format!("two-{n0}{n1}.exr"));
        write_exr(&path, w, h, &[(n0, a.clone()), (n1, b.clone())]);
        let img = open_image(&path).unwrap();
        assert_eq!((img.width(), img.height()), (8, 5));
        let px = rgb32f(&img);
        for (i, p) in px.pixels().enumerate() {
            assert_eq!(p.0, [a[i], b[i], 0.0], "{n0},{n1} pixel {i}");
        }
    }
    // The reverse: G holds `a`, R holds `b` -> channel 0 is still R.
    let path = dir.join("swapped.exr");
    write_exr(&path, w, h, &[("G", a.clone()), ("R", b.clone())]);
    assert_eq!(
        rgb32f(&open_image(&path).unwrap()).get_pixel(2, 3).0,
        [b[26], a[26], 0.0]
    );
}

#[test]
fn two_channel_exr_as_exemplar() {
    let dir = TempDir::new("exr-two-ex");
    let (w, h) = (16usize, 17usize);
    let y: Vec<f32> = (0..w * h).map(|i| (i % 13) as f32 / 12.0).collect();
    let alpha = vec![0.5f32; w * h];

    // Grey + alpha: grey exemplar from Y, alpha ignored; as a material map, alpha kept.
    let path = dir.join("ya.exr");
    write_exr(&path, w, h, &[("Y", y.clone()), ("A", alpha.clone())]);
    let ex = load_exemplar(&path).unwrap();
    assert_eq!((ex.width, ex.height, ex.channels), (16, 17, 1));
    assert_eq!(ex.values, y);
    let (_, _, mc, px) = load_material_map(&path).unwrap();
    assert_eq!(mc, 2);
    let g = (y[6] * 255.0).round() as u8;
    assert_eq!(px[6], [g, g, g, 128]);

    // A field (R, G): refused with what an exemplar needs.
    let path = dir.join("rg.exr");
    write_exr(&path, w, h, &[("R", y.clone()), ("G", alpha)]);
    let reason = bad_image(load_exemplar(&path), &path);
    assert!(
        reason.contains("2-channel") && reason.contains("R, G") && reason.contains("RGB"),
        "{reason}"
    );

    // NaN in grey + alpha: refused like any float exemplar.
    let mut n = y.clone();
    n[3] = f32::NAN;
    let path = dir.join("ya-nan.exr");
    write_exr(&path, w, h, &[("Y", n), ("A", vec![1.0; w * h])]);
    let err = load_exemplar(&path).unwrap_err().to_string();
    assert!(err.contains("(3, 0)") && err.contains("NaN"), "{err}");
}

#[test]
fn truncated_or_corrupt_few_channel_exr_is_an_error() {
    let dir = TempDir::new("exr-cut");
    let (w, h) = (32usize, 32usize);
    let v: Vec<f32> = (0..w * h).map(|i| (i % 97) as f32 / 96.0).collect();
    let good = dir.join("good.exr");
    write_exr(&good, w, h, &[("Y", v.clone())]);
    assert_eq!(load_exemplar(&good).unwrap().values, v);
    let two = dir.join("two.exr");
    write_exr(&two, w, h, &[("R", v.clone()), ("G", v.clone())]);

    // Cut inside the pixel data (the header is whole): the exr crate's path says so.
    let bytes = std::fs::read(&good).unwrap();
    let cut = dir.join("cut-pixels.exr");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let reason = bad_image(load_exemplar(&cut), &cut);
    assert!(
        reason.contains("1-channel") && reason.contains("truncated"),
        "{reason}"
    );

    for src in [&good, &two] {
        let bytes = std::fs::read(src).unwrap();
        for len in [3, 8, 40, bytes.len() / 3, bytes.len() / 2, bytes.len() - 7] {
            let cut = dir.join(&format!("cut{len}.exr"));
            std::fs::write(&cut, &bytes[..len]).unwrap();
            for r in [
                load_exemplar(&cut).map(|_| ()),
                open_image(&cut).map(|_| ()),
            ] {
                match r {
                    Err(Error::BadImage { path, reason }) => {
                        assert_eq!(path, cut);
                        assert!(!reason.is_empty());
                    }
                    other => panic!("{}: expected BadImage, got {other:?}", cut.display()),
                }
            }
        }
        // Garbage in the pixel data: an error or (where it still decodes) an image, never
        // a panic.
        for seed in 0..8usize {
            let mut corrupt = bytes.clone();
            let start = 320 + seed * (corrupt.len() - 400) / 8;
            for (k, b) in corrupt[start..start + 48].iter_mut().enumerate() {
                *b ^= (0x5a + k * 31 + seed * 7) as u8;
            }
            let cpath = dir.join(&format!("corrupt{seed}.exr"));
            std::fs::write(&cpath, &corrupt).unwrap();
            match open_image(&cpath) {
                Ok(img) => assert_eq!((img.width(), img.height()), (32, 32)),
                Err(Error::BadImage { path, .. }) => assert_eq!(path, cpath),
                Err(e) => panic!("expected BadImage, got {e:?}"),
            }
        }
    }
}

/// Direction-and-scale fields (`--field image:F`) from EXRs: one channel is the angle
/// alone (as a grey image), two are angle and log scale.
#[test]
fn direction_scale_fields_from_one_and_two_channel_exrs() {
    use texsyn::field::{jacobian_of_transform, load_direction_scale_image};
    let dir = TempDir::new("exr-field");
    let (w, h) = (5usize, 3usize);
    let angle = vec![0.25f32; w * h];
    let log_scale = vec![0.5f32 + 1.0 / 6.0; w * h];
    let one = dir.join("angle.exr");
    write_exr(&one, w, h, &[("Y", angle.clone())]);
    let two = dir.join("angle-scale.exr");
    write_exr(&two, w, h, &[("R", angle), ("G", log_scale)]);
    let quarter = std::f64::consts::FRAC_PI_2;
    for (path, scale) in [(&one, 1.0), (&two, 2.0)] {
        let map = load_direction_scale_image(path).unwrap();
        assert_eq!((map.width, map.height), (w as u32, h as u32));
        let want = jacobian_of_transform(quarter, [scale; 2], 0.0);
        for j in &map.jacobians {
            assert!(
                (0..4).all(|i| (j[i / 2][i % 2] - want[i / 2][i % 2]).abs() < 1e-5),
                "{}: {j:?} instead of {want:?}",
                path.display()
            );
        }
    }
}

#[test]
fn one_channel_exr_is_refused_where_two_values_are_needed() {
    let dir = TempDir::new("exr-one-value");
    let (w, h) = (16usize, 16usize);
    let path = dir.join("y.exr");
    write_exr(&path, w, h, &[("Y", vec![0.25; w * h])]);
    let e = load_coords_exr_f32(&path).unwrap_err().to_string();
    assert!(e.contains("needs two"), "{e}");
    let e = texsyn::flow::Flow::load(&path).unwrap_err().to_string();
    assert!(e.contains("needs two"), "{e}");
    let e = texsyn::field::load_jacobian_exr(&path)
        .unwrap_err()
        .to_string();
    assert!(e.contains("it has 1"), "{e}");
    // A grey PNG is no velocity field either; an RGB one is.
    let grey = dir.join("grey.png");
    save(&DynamicImage::ImageLuma8(ImageBuffer::new(8, 8)), &grey);
    assert!(texsyn::flow::Flow::load(&grey).is_err());
    let rgb = dir.join("rgb.png");
    save(&DynamicImage::ImageRgb8(ImageBuffer::new(8, 8)), &rgb);
    assert!(texsyn::flow::Flow::load(&rgb).is_ok());
}

/// A velocity image's values are read by what the file holds, not by its name: an EXR
/// named `.png` holds pixels per unit time as they are, an 8-bit PNG named `.exr` holds
/// 0..1 mapped to -8..8.
#[test]
fn velocity_images_are_read_by_content_not_name() {
    use texsyn::flow::Flow;
    let dir = TempDir::new("flow-by-content");
    let (w, h) = (4usize, 2usize);
    let exr = dir.join("velocity.png");
    write_exr(
        &exr,
        w,
        h,
        &[("R", vec![1.0; w * h]), ("G", vec![-0.5; w * h])],
    );
    let png = dir.join("velocity.exr");
    let mut rgb = ImageBuffer::new(w as u32, h as u32);
    for p in rgb.pixels_mut() {
        *p = image::Rgb([192u8, 64, 0]);
    }
    let written = dir.join("written.png");
    save(&DynamicImage::ImageRgb8(rgb), &written);
    std::fs::rename(&written, &png).unwrap();
    let sampled = |path: &Path| Flow::load(path).unwrap().sample(4, 2, 0.0).unwrap()[0];
    assert_eq!(sampled(&exr), [1.0, -0.5]);
    let v = sampled(&png);
    let want = [(192.0 / 255.0 - 0.5) * 16.0, (64.0 / 255.0 - 0.5) * 16.0];
    assert!(
        (v[0] - want[0]).abs() < 1e-4 && (v[1] - want[1]).abs() < 1e-4,
        "{v:?}"
    );
}
