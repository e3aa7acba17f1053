//! Loading exemplars: formats decided by content, precision kept, alpha ignored, bad and
//! too small files refused.

use image::{DynamicImage, ImageBuffer, Luma, LumaA, Rgb, Rgba};
use texsyn::image_io::{exemplar_from_image, load_exemplar};
use texsyn::Error;

use crate::common::TempDir;
use crate::helpers::*;

#[test]
fn load_rgb8() {
    let dir = TempDir::new("rgb8");
    let img = ImageBuffer::from_fn(20, 17, |x, y| Rgb([(x * 10) as u8, (y * 13) as u8, 200]));
    let path = dir.join("rgb.png");
    save(&DynamicImage::ImageRgb8(img), &path);
    let ex = load_exemplar(&path).unwrap();
    assert_eq!((ex.width, ex.height, ex.channels), (20, 17, 3));
    assert_eq!(ex.values.len(), 20 * 17 * 3);
    assert_eq!(ex.colors.len(), 20 * 17);
    let i = (5 * 20 + 7) as usize; // x = 7, y = 5
    assert_eq!(ex.colors[i], [70, 65, 200, 255]);
    assert_eq!(
        &ex.values[3 * i..3 * i + 3],
        &[70.0 / 255.0, 65.0 / 255.0, 200.0 / 255.0]
    );
}

#[test]
fn load_grey16_keeps_precision() {
    let dir = TempDir::new("grey16");
    let img = ImageBuffer::from_fn(16, 16, |x, y| Luma([(x * 4096 + y * 3 + 1) as u16]));
    let path = dir.join("g16.png");
    save(&DynamicImage::ImageLuma16(img), &path);
    let ex = load_exemplar(&path).unwrap();
    assert_eq!((ex.width, ex.height, ex.channels), (16, 16, 1));
    assert_eq!(ex.values.len(), 256);
    let i = 2 * 16 + 3; // x = 3, y = 2
    let v = 3 * 4096 + 2 * 3 + 1;
    assert_eq!(ex.values[i], v as f32 / 65535.0);
    // Neighbouring 16-bit values stay distinct (no 8-bit round trip).
    assert_ne!(ex.values[0], ex.values[16]);
    let c = ((v as u32 * 255 + 32767) / 65535) as u8;
    assert_eq!(ex.colors[i], [c, c, c, 255]);
}

#[test]
fn load_rgba_ignores_alpha() {
    let dir = TempDir::new("rgba");
    let img = ImageBuffer::from_fn(16, 18, |x, y| Rgba([x as u8, y as u8, 9, (x * 16) as u8]));
    let path = dir.join("rgba.png");
    save(&DynamicImage::ImageRgba8(img), &path);
    let ex = load_exemplar(&path).unwrap();
    assert_eq!((ex.width, ex.height, ex.channels), (16, 18, 3));
    assert_eq!(ex.values.len(), 16 * 18 * 3);
    assert!(ex.colors.iter().all(|c| c[3] == 255));
    assert_eq!(ex.colors[16 + 2], [2, 1, 9, 255]);
}

#[test]
fn load_grey_alpha() {
    let dir = TempDir::new("greya");
    let img = ImageBuffer::from_fn(17, 16, |x, _| LumaA([(x * 15) as u8, 0]));
    let path = dir.join("ga.png");
    save(&DynamicImage::ImageLumaA8(img), &path);
    let ex = load_exemplar(&path).unwrap();
    assert_eq!((ex.width, ex.height, ex.channels), (17, 16, 1));
    assert_eq!(ex.values.len(), 17 * 16);
    assert_eq!(ex.colors[4], [60, 60, 60, 255]);
    assert_eq!(ex.values[4], 60.0 / 255.0);
}

#[test]
fn format_is_decided_by_content() {
    let dir = TempDir::new("content");
    let img = DynamicImage::ImageRgb8(ImageBuffer::from_fn(16, 16, |x, y| {
        Rgb([x as u8 * 8, y as u8 * 8, 0])
    }));
    let bmp = dir.join("real.bmp");
    save(&img, &bmp);
    let disguised = dir.join("disguised.png");
    std::fs::rename(&bmp, &disguised).unwrap();
    let ex = load_exemplar(&disguised).unwrap();
    assert_eq!((ex.width, ex.height, ex.channels), (16, 16, 3));
    assert_eq!(ex.colors[17], [8, 8, 0, 255]);
    let noext = dir.join("noext");
    std::fs::rename(&disguised, &noext).unwrap();
    assert_eq!(load_exemplar(&noext).unwrap(), ex);
}

#[test]
fn float_exemplar_is_clamped_or_refused() {
    // A few samples slightly out of [0, 1] (compression ringing): clamped.
    let img = DynamicImage::ImageRgb32F(ImageBuffer::from_fn(16, 16, |x, y| {
        let r = match (x, y) {
            (0, 0) => -0.1,
            (15, 0) => 1.2,
            _ => x as f32 / 15.0,
        };
        Rgb([r, 0.5, 0.25])
    }));
    let ex = exemplar_from_image(&img).unwrap();
    assert_eq!(ex.channels, 3);
    assert!(ex.values.iter().all(|v| (0.0..=1.0).contains(v)));
    assert_eq!(&ex.values[0..3], &[0.0, 0.5, 0.25]);
    assert_eq!(ex.values[15 * 3], 1.0);
    assert_eq!(ex.colors[15], [255, 128, 64, 255]);

    // NaN: an error naming the pixel.
    let nan = DynamicImage::ImageRgb32F(ImageBuffer::from_fn(16, 16, |x, y| {
        Rgb([0.5, if (x, y) == (3, 2) { f32::NAN } else { 0.5 }, 0.5])
    }));
    let err = exemplar_from_image(&nan).unwrap_err().to_string();
    assert!(err.contains("(3, 2)") && err.contains("NaN"), "{err}");

    // An HDR image (most samples above 1): refused with what to do, not washed out.
    let hdr = DynamicImage::ImageRgba32F(ImageBuffer::from_fn(16, 16, |x, _| {
        image::Rgba([x as f32 * 3.0, 0.5, 0.5, 1.0])
    }));
    let err = exemplar_from_image(&hdr).unwrap_err().to_string();
    assert!(
        err.contains("tone-map") && err.contains("up to 45"),
        "{err}"
    );
    // Negative samples: the message gives their range, not their magnitude.
    let neg = DynamicImage::ImageRgb32F(ImageBuffer::from_fn(16, 16, |x, _| {
        Rgb([-0.5 - x as f32 * 0.01, -0.5, -0.5])
    }));
    let err = exemplar_from_image(&neg).unwrap_err().to_string();
    assert!(err.contains("down to -0.65"), "{err}");
}

#[test]
fn missing_file_is_io_error() {
    let dir = TempDir::new("missing");
    let path = dir.join("nope.png");
    match load_exemplar(&path) {
        Err(Error::Io { path: p, source }) => {
            assert_eq!(p, path);
            assert_eq!(source.kind(), std::io::ErrorKind::NotFound);
        }
        other => panic!("expected Io, got {other:?}"),
    }
}

#[test]
fn empty_text_and_truncated_files_are_bad_images() {
    let dir = TempDir::new("bad");
    let empty = dir.join("empty.png");
    std::fs::write(&empty, b"").unwrap();
    bad_image(load_exemplar(&empty), &empty);

    let text = dir.join("text.png");
    std::fs::write(&text, b"this is not an image, just some text\n").unwrap();
    bad_image(load_exemplar(&text), &text);

    let unknown = dir.join("text.xyz");
    std::fs::write(&unknown, b"this is not an image, just some text\n").unwrap();
    let reason = bad_image(load_exemplar(&unknown), &unknown);
    assert!(reason.contains("format"), "{reason}");

    let good = dir.join("good.png");
    let img = ImageBuffer::from_fn(64, 64, |x, y| {
        Rgb([(x * 7 + y) as u8, (y * 3) as u8, (x ^ y) as u8])
    });
    save(&DynamicImage::ImageRgb8(img), &good);
    let bytes = std::fs::read(&good).unwrap();
    for len in [8, 30, bytes.len() / 2, bytes.len() - 20] {
        let cut = dir.join(&format!("cut{len}.png"));
        std::fs::write(&cut, &bytes[..len]).unwrap();
        bad_image(load_exemplar(&cut), &cut);
    }

    // Corrupt image data (checksums broken in the middle of the file).
    let mut corrupt = bytes.clone();
    let mid = corrupt.len() / 2;
    for b in &mut corrupt[mid..mid + 16] {
        *b ^= 0x5a;
    }
    let cpath = dir.join("corrupt.png");
    std::fs::write(&cpath, &corrupt).unwrap();
    bad_image(load_exemplar(&cpath), &cpath);

    // A directory is not an image.
    let sub = dir.join("sub.png");
    std::fs::create_dir(&sub).unwrap();
    assert!(load_exemplar(&sub).is_err());
}

#[test]
fn too_small_exemplars() {
    let dir = TempDir::new("small");
    for (w, h) in [(1, 1), (15, 15), (16, 15), (15, 64)] {
        let path = dir.join(&format!("s{w}x{h}.png"));
        save(&DynamicImage::ImageRgb8(ImageBuffer::new(w, h)), &path);
        match load_exemplar(&path) {
            Err(Error::ExemplarTooSmall { width, height, min }) => {
                assert_eq!((width, height, min), (w, h, 16));
            }
            other => panic!("expected ExemplarTooSmall for {w}x{h}, got {other:?}"),
        }
    }
    let ok = dir.join("ok.png");
    save(&DynamicImage::ImageLuma8(ImageBuffer::new(16, 16)), &ok);
    assert!(load_exemplar(&ok).is_ok());
}
