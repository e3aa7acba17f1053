//! Image output in every supported format, and its refused parameters.

use image::DynamicImage;
use texsyn::image_io::{load_exemplar, save_image_atomic};
use texsyn::Error;

use crate::common::TempDir;
use crate::helpers::*;

#[test]
fn save_image_png_grey_rgb_rgba() {
    let dir = TempDir::new("saveimg");
    let (w, h) = (19, 16);
    let rgba = pattern_rgba(w, h);

    let p1 = dir.join("g.png");
    save_image_atomic(&p1, w, h, 1, &rgba).unwrap();
    let img = image::open(&p1).unwrap();
    assert!(matches!(img, DynamicImage::ImageLuma8(_)));
    assert_eq!(
        img.to_luma8().into_raw(),
        rgba.chunks(4).map(|p| p[0]).collect::<Vec<_>>()
    );

    let p3 = dir.join("c.png");
    save_image_atomic(&p3, w, h, 3, &rgba).unwrap();
    let img = image::open(&p3).unwrap();
    assert!(matches!(img, DynamicImage::ImageRgb8(_)));
    let rgb: Vec<u8> = rgba.chunks(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
    assert_eq!(img.to_rgb8().into_raw(), rgb);

    let p4 = dir.join("a.png");
    save_image_atomic(&p4, w, h, 4, &rgba).unwrap();
    let img = image::open(&p4).unwrap();
    assert!(matches!(img, DynamicImage::ImageRgba8(_)));
    assert_eq!(img.to_rgba8().into_raw(), rgba);

    // No extension: PNG.
    let p0 = dir.join("noext");
    save_image_atomic(&p0, w, h, 3, &rgba).unwrap();
    assert_eq!(
        image::ImageReader::open(&p0)
            .unwrap()
            .with_guessed_format()
            .unwrap()
            .format(),
        Some(image::ImageFormat::Png)
    );

    assert_eq!(dir.entries(), vec!["a.png", "c.png", "g.png", "noext"]);
}

#[test]
fn save_image_every_supported_extension() {
    let dir = TempDir::new("saveall");
    let (w, h) = (16, 16);
    let rgba = pattern_rgba(w, h);
    let lossless = [
        "png", "bmp", "tga", "tif", "tiff", "webp", "pnm", "ppm", "pam",
    ];
    for ext in [
        "png", "jpg", "jpeg", "bmp", "tga", "tif", "tiff", "webp", "gif", "pnm", "ppm", "pgm",
        "pam", "exr", "hdr",
    ] {
        for channels in [1, 3, 4] {
            let path = dir.join(&format!("out{channels}.{ext}"));
            save_image_atomic(&path, w, h, channels, &rgba)
                .unwrap_or_else(|e| panic!("{ext} with {channels} channels: {e}"));
            let ex = load_exemplar(&path)
                .unwrap_or_else(|e| panic!("reading back {ext}/{channels}: {e}"));
            assert_eq!((ex.width, ex.height), (w, h), "{ext}");
            // The PNM family: binary PGM/PPM that every reader takes, PAM only for .pam.
            let magic = std::fs::read(&path).unwrap()[..2].to_vec();
            let expect: Option<&[u8]> = match (ext, channels) {
                ("pgm", _) | ("pnm", 1) => Some(b"P5"),
                ("ppm", _) | ("pnm", _) => Some(b"P6"),
                ("pam", _) => Some(b"P7"),
                _ => None,
            };
            if let Some(m) = expect {
                assert_eq!(magic, m, "{ext} with {channels} channels");
            }
            if lossless.contains(&ext) && channels == 3 {
                let rgb: Vec<[u8; 4]> = rgba.chunks(4).map(|p| [p[0], p[1], p[2], 255]).collect();
                assert_eq!(ex.colors, rgb, "{ext}");
            }
        }
    }
    assert!(
        !dir.entries().iter().any(|n| n.starts_with('.')),
        "temporary files left: {:?}",
        dir.entries()
    );
}

#[test]
fn save_image_rejects_bad_parameters() {
    let dir = TempDir::new("savebad");
    let rgba = pattern_rgba(4, 4);
    match save_image_atomic(&dir.join("x.xyz"), 4, 4, 3, &rgba) {
        Err(Error::InvalidParameter(msg)) => {
            assert!(
                msg.contains(".xyz") && msg.contains("png") && msg.contains("jpg"),
                "{msg}"
            );
        }
        other => panic!("expected InvalidParameter, got {other:?}"),
    }
    assert!(matches!(
        save_image_atomic(&dir.join("x.png"), 4, 4, 5, &rgba),
        Err(Error::InvalidParameter(_))
    ));
    // 2 channels: grey + alpha (material maps keep their alpha).
    save_image_atomic(&dir.join("la.png"), 4, 4, 2, &rgba).unwrap();
    let la = image::open(dir.join("la.png")).unwrap();
    assert_eq!(la.color(), image::ColorType::La8);
    let _ = std::fs::remove_file(dir.join("la.png"));
    assert!(matches!(
        save_image_atomic(&dir.join("x.png"), 4, 5, 3, &rgba),
        Err(Error::InvalidParameter(_))
    ));
    assert!(matches!(
        save_image_atomic(&dir.join("x.png"), 0, 0, 3, &[]),
        Err(Error::InvalidParameter(_))
    ));
    assert!(dir.entries().is_empty());
}
