//! Files refused before they are decoded (truncated JPEGs, devices, pipes, analysis
//! files) and maps with non-finite samples.

use std::path::Path;

use image::{DynamicImage, ImageBuffer, Rgb};
use texsyn::image_io::{load_exemplar, load_material_map};
use texsyn::Error;

use crate::common::TempDir;
use crate::helpers::*;

/// The JPEG decoder fills a truncated file's missing part with grey without an error, so
/// truncation is detected before decoding; a complete JPEG, with or without data after
/// its end (a motion photo's video, an MPF image), still loads.
#[test]
fn truncated_jpegs_devices_and_analysis_files_are_refused() {
    let dir = TempDir::new("jpeg");
    let img = ImageBuffer::from_fn(96, 80, |x, y| {
        Rgb([(x * 7 + y) as u8, (y * 3) as u8, (x ^ y) as u8])
    });
    let good = dir.join("good.jpg");
    save(&DynamicImage::ImageRgb8(img), &good);
    let bytes = std::fs::read(&good).unwrap();
    assert!(!texsyn::image_io::jpeg_lacks_end(&bytes));
    load_exemplar(&good).unwrap();

    let mut trailer = bytes.clone();
    trailer.extend_from_slice(b"\x00\x00\x00\x18ftypmp42 some appended video data");
    let tpath = dir.join("trailer.jpg");
    std::fs::write(&tpath, &trailer).unwrap();
    load_exemplar(&tpath).unwrap();

    for len in [bytes.len() / 3, bytes.len() / 2, bytes.len() - 2] {
        assert!(texsyn::image_io::jpeg_lacks_end(&bytes[..len]), "{len}");
        let cut = dir.join(&format!("cut{len}.jpg"));
        std::fs::write(&cut, &bytes[..len]).unwrap();
        let reason = bad_image(load_exemplar(&cut), &cut);
        assert!(reason.contains("truncated"), "{reason}");
    }

    // A device is refused at once (it would never end).
    let zero = Path::new("/dev/zero");
    if zero.exists() {
        let reason = bad_image(load_exemplar(zero), zero);
        assert!(reason.contains("not a regular file"), "{reason}");
        match texsyn::image_io::read_file_capped(zero, 1 << 20, "meshes") {
            Err(Error::Io { source, .. }) => {
                assert!(
                    source.to_string().contains("not a regular file"),
                    "{source}"
                )
            }
            other => panic!("{other:?}"),
        }
    }

    // So is a named pipe with no writer, before it is opened (opening it would block
    // until something writes to it): as an image, a file read whole, an analysis file.
    let fifo = dir.join("pipe.png");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success());
    if made {
        let reason = bad_image(load_exemplar(&fifo), &fifo);
        assert!(reason.contains("not a regular file"), "{reason}");
        let e = texsyn::image_io::read_file_capped(&fifo, 1 << 20, "meshes").unwrap_err();
        assert!(e.to_string().contains("not a regular file"), "{e}");
        let e = texsyn::Analysis::load(&fifo).unwrap_err();
        assert!(e.to_string().contains("not a regular file"), "{e}");
        assert!(texsyn::is_analysis_file(&fifo).is_err());
    } else {
        eprintln!("no mkfifo here: the named-pipe case is not tested");
    }

    // An analysis file given where an image belongs says what it is.
    let tsa = dir.join("x.tsa");
    let mut head = b"TEXSYNA\0".to_vec();
    head.extend_from_slice(&[0u8; 64]);
    std::fs::write(&tsa, &head).unwrap();
    let reason = bad_image(load_exemplar(&tsa), &tsa);
    assert!(reason.contains("analysis file"), "{reason}");
}

/// Material maps, feature masks and evaluated images with NaN or infinite samples are
/// refused (they would be clamped silently).
#[test]
fn non_finite_maps_are_refused() {
    let dir = TempDir::new("nan");
    let mut img = image::Rgb32FImage::from_pixel(32, 32, Rgb([0.5, 0.5, 0.5]));
    img.put_pixel(3, 5, Rgb([0.5, f32::NAN, 0.5]));
    let nan = dir.join("nan.exr");
    DynamicImage::ImageRgb32F(img.clone()).save(&nan).unwrap();
    match load_material_map(&nan) {
        Err(Error::BadImage { reason, .. }) => assert!(reason.contains("(3, 5)"), "{reason}"),
        other => panic!("{other:?}"),
    }
    assert!(texsyn::analysis::FeatureMask::load(&nan).is_err());
    img.put_pixel(3, 5, Rgb([0.5, f32::INFINITY, 0.5]));
    let decoded = DynamicImage::ImageRgb32F(img);
    assert!(texsyn::image_io::check_finite(&decoded, &nan, "map").is_err());
    let fine = DynamicImage::ImageRgb32F(image::Rgb32FImage::from_pixel(4, 4, Rgb([0.2; 3])));
    texsyn::image_io::check_finite(&fine, &nan, "map").unwrap();
}
