//! Exemplar loading, atomic writes, image and coordinate-map output.

mod common;
use common::TempDir;

use std::path::Path;

use image::{DynamicImage, ImageBuffer, Luma, LumaA, Rgb, Rgba};
use texsyn::image_io::{
    exemplar_from_image, load_coords_exr, load_coords_exr_f32, load_exemplar, load_material_map,
    open_image, save_coords_exr_atomic, save_image_atomic, write_atomic,
};
use texsyn::Error;

fn save(img: &DynamicImage, path: &Path) {
    img.save(path).unwrap();
}

fn bad_image(r: texsyn::Result<texsyn::Exemplar>, path: &Path) -> String {
    match r {
        Err(Error::BadImage { path: p, reason }) => {
            assert_eq!(p, path);
            assert!(!reason.is_empty());
            reason
        }
        other => panic!("expected BadImage for {}, got {other:?}", path.display()),
    }
}

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

#[test]
fn atomic_write_to_missing_directory() {
    let dir = TempDir::new("atomic-missing");
    let path = dir.join("no/such/dir/out.png");
    let r = write_atomic(&path, |w| {
        use std::io::Write;
        w.write_all(b"data").unwrap();
        Ok(())
    });
    match r {
        Err(Error::Write { path: p, reason }) => {
            assert_eq!(p, path);
            assert!(reason.contains("does not exist"), "{reason}");
        }
        other => panic!("expected Write, got {other:?}"),
    }
    assert!(!path.exists());
    assert!(dir.entries().is_empty());
}

#[test]
fn atomic_write_to_a_directory() {
    let dir = TempDir::new("atomic-dir");
    let target = dir.join("adir");
    std::fs::create_dir(&target).unwrap();
    let r = write_atomic(&target, |_| Ok(()));
    assert!(matches!(r, Err(Error::Write { .. })), "{r:?}");
    assert!(target.is_dir());
    assert_eq!(dir.entries(), vec!["adir".to_string()]);
    // Also through the image saver.
    let r = save_image_atomic(&dir.join("adir"), 1, 1, 4, &[0; 4]);
    assert!(matches!(r, Err(Error::Write { .. })), "{r:?}");
}

#[test]
fn failed_write_leaves_no_temp_and_keeps_old_content() {
    use std::io::Write;
    let dir = TempDir::new("atomic-fail");
    let path = dir.join("out.bin");
    std::fs::write(&path, b"old content").unwrap();

    // The writer fails half way.
    let r = write_atomic(&path, |w| {
        w.write_all(&[1; 100_000]).unwrap();
        Err(Error::InvalidParameter("simulated failure".into()))
    });
    match r {
        Err(Error::Write { path: p, reason }) => {
            assert_eq!(p, path);
            assert!(reason.contains("simulated failure"), "{reason}");
        }
        other => panic!("expected Write, got {other:?}"),
    }
    assert_eq!(std::fs::read(&path).unwrap(), b"old content");
    assert_eq!(dir.entries(), vec!["out.bin".to_string()]);

    // The writer panics.
    let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        let _ = write_atomic(&path, |w| {
            w.write_all(b"partial").unwrap();
            panic!("simulated panic");
        });
    }));
    assert!(r.is_err());
    assert_eq!(std::fs::read(&path).unwrap(), b"old content");
    assert_eq!(dir.entries(), vec!["out.bin".to_string()]);

    // A successful write replaces the content and leaves only the target.
    write_atomic(&path, |w| {
        w.write_all(b"new").map_err(|e| Error::Write {
            path: path.clone(),
            reason: e.to_string(),
        })
    })
    .unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), b"new");
    assert_eq!(dir.entries(), vec!["out.bin".to_string()]);
}

#[test]
fn write_to_empty_path_is_error() {
    let r = write_atomic(Path::new(""), |_| Ok(()));
    assert!(matches!(r, Err(Error::Write { .. })), "{r:?}");
}

fn pattern_rgba(w: u32, h: u32) -> Vec<u8> {
    (0..w * h)
        .flat_map(|i| {
            let (x, y) = (i % w, i / w);
            [
                (x * 9) as u8,
                (y * 5) as u8,
                ((x + y) * 3) as u8,
                (100 + x) as u8,
            ]
        })
        .collect()
}

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

#[test]
fn coords_exr_round_trip() {
    let dir = TempDir::new("exr");
    let (w, h) = (37u32, 23u32);
    let coords: Vec<[i32; 2]> = (0..w * h)
        .map(|i| [(i * 7919 % 4099) as i32, (i * 31 % 2053) as i32 - 5])
        .collect();
    let path = dir.join("coords.exr");
    save_coords_exr_atomic(&path, w, h, &coords).unwrap();

    let img = image::open(&path).unwrap();
    let f = img.to_rgb32f();
    assert_eq!(
        f.get_pixel(1, 0).0,
        [coords[1][0] as f32, coords[1][1] as f32, 0.0]
    );

    let (rw, rh, back) = load_coords_exr(&path).unwrap();
    assert_eq!((rw, rh), (w, h));
    assert_eq!(back, coords);

    // Overwrite in place.
    let zeros = vec![[0, 0]; (w * h) as usize];
    save_coords_exr_atomic(&path, w, h, &zeros).unwrap();
    assert_eq!(load_coords_exr(&path).unwrap().2, zeros);
    assert_eq!(dir.entries(), vec!["coords.exr"]);

    // Wrong length.
    assert!(matches!(
        save_coords_exr_atomic(&dir.join("bad.exr"), w, h, &coords[1..]),
        Err(Error::InvalidParameter(_))
    ));

    // An 8-bit image is not a coordinate map; a missing file is Io.
    let png = dir.join("p.png");
    save_image_atomic(&png, 4, 4, 3, &pattern_rgba(4, 4)).unwrap();
    assert!(matches!(load_coords_exr(&png), Err(Error::BadImage { .. })));
    assert!(matches!(
        load_coords_exr(&dir.join("none.exr")),
        Err(Error::Io { .. })
    ));
}

#[test]
fn coords_exr_rounds_to_nearest() {
    let dir = TempDir::new("exr-round");
    let path = dir.join("f.exr");
    let img = ImageBuffer::from_fn(2, 1, |x, _| Rgba([x as f32 + 0.6, 2.4, 0.0, 1.0]));
    DynamicImage::ImageRgba32F(img).save(&path).unwrap();
    let (w, h, c) = load_coords_exr(&path).unwrap();
    assert_eq!((w, h), (2, 1));
    assert_eq!(c, vec![[1, 2], [2, 2]]);
}

// ---------------------------------------------------------------------------------------
// 1- and 2-channel OpenEXRs (read with the exr crate; the image crate refuses them)
// ---------------------------------------------------------------------------------------

/// Writes a float OpenEXR with the given channels (`w * h` row-major samples each).
fn write_exr(path: &Path, w: usize, h: usize, channels: &[(&str, Vec<f32>)]) {
    use exr::prelude::*;
    let list: SmallVec<[AnyChannel<FlatSamples>; 4]> = channels
        .iter()
        .map(|(name, v)| {
            assert_eq!(v.len(), w * h);
            AnyChannel::new(*name, FlatSamples::F32(v.clone()))
        })
        .collect();
    let layer = Layer::new(
        (w, h),
        LayerAttributes::default(),
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(list),
    );
    Image::from_layer(layer).write().to_file(path).unwrap();
}

fn rgb32f(img: &DynamicImage) -> &image::Rgb32FImage {
    match img {
        DynamicImage::ImageRgb32F(b) => b,
        other => panic!("expected float RGB, got {:?}", other.color()),
    }
}

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
fn two_channel_coordinate_maps() {
    let dir = TempDir::new("exr-coords2");
    let (w, h) = (6usize, 4usize);
    let x: Vec<f32> = (0..w * h).map(|i| (i * 37 % 101) as f32 + 0.4).collect();
    let y: Vec<f32> = (0..w * h).map(|i| (i * 13 % 29) as f32 - 7.6).collect();
    for (nx, ny) in [("R", "G"), ("X", "Y")] {
        let path = dir.join(&format!("c-{nx}{ny}.exr"));
        write_exr(&path, w, h, &[(nx, x.clone()), (ny, y.clone())]);
        let (rw, rh, c) = load_coords_exr_f32(&path).unwrap();
        assert_eq!((rw, rh), (6, 4));
        let want: Vec<[f32; 2]> = x.iter().zip(&y).map(|(&a, &b)| [a, b]).collect();
        assert_eq!(c, want, "{nx},{ny}");
        let (_, _, r) = load_coords_exr(&path).unwrap();
        assert_eq!(r[1], [x[1].round() as i32, y[1].round() as i32]);
    }

    // NaN: refused, naming the file and the pixel.
    let mut n = y.clone();
    n[9] = f32::NAN;
    let path = dir.join("nan.exr");
    write_exr(&path, w, h, &[("R", x.clone()), ("G", n)]);
    match load_coords_exr_f32(&path) {
        Err(Error::BadImage { path: p, reason }) => {
            assert_eq!(p, path);
            assert!(
                reason.contains("pixel 9") && reason.contains("NaN"),
                "{reason}"
            );
        }
        other => panic!("expected BadImage, got {other:?}"),
    }
    assert!(matches!(
        load_coords_exr(&path),
        Err(Error::BadImage { .. })
    ));

    // Three channels that are not RGB: still refused, listing the channels.
    let path = dir.join("xyz.exr");
    write_exr(
        &path,
        w,
        h,
        &[("X", x.clone()), ("Y", y.clone()), ("Z", x.clone())],
    );
    match load_coords_exr_f32(&path) {
        Err(Error::BadImage { reason, .. }) => {
            assert!(
                reason.contains("X, Y, Z") && reason.contains("2-channel"),
                "{reason}"
            )
        }
        other => panic!("expected BadImage, got {other:?}"),
    }
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

#[cfg(unix)]
#[test]
fn atomic_write_follows_symlinks_keeps_devices_and_clears_stale_temporaries() {
    use std::io::Write;
    let dir = TempDir::new("atomic-special");
    let write = |path: &Path, data: &'static [u8]| {
        write_atomic(path, move |w| {
            w.write_all(data).unwrap();
            Ok(())
        })
    };
    // A symlink: the file it points to gets the content, the link stays.
    let real = dir.join("real.bin");
    let link = dir.join("link.bin");
    std::fs::write(&real, b"old").unwrap();
    std::os::unix::fs::symlink("real.bin", &link).unwrap();
    write(&link, b"new").unwrap();
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    assert_eq!(std::fs::read(&real).unwrap(), b"new");
    // A device is written to, not replaced.
    write(Path::new("/dev/null"), b"discarded").unwrap();
    use std::os::unix::fs::FileTypeExt;
    assert!(std::fs::metadata("/dev/null")
        .unwrap()
        .file_type()
        .is_char_device());
    // A temporary file of a process that is gone is removed by the next write to the
    // same target; one of a running process (pid 1) is kept.
    if Path::new("/proc/self").exists() {
        let stale = dir.join(".out.bin.4000000000.0.tmp");
        let live = dir.join(".out.bin.1.0.tmp");
        std::fs::write(&stale, b"partial").unwrap();
        std::fs::write(&live, b"partial").unwrap();
        write(&dir.join("out.bin"), b"data").unwrap();
        assert!(!stale.exists());
        assert!(live.exists());
    }
}

/// Several outputs are written all or nothing: when one cannot be written, the others
/// (which existed before) keep their old content and no temporary file is left.
#[test]
fn several_files_are_written_all_or_nothing() {
    use texsyn::image_io::write_files_atomic;
    let dir = TempDir::new("all-or-nothing");
    let a = dir.join("a.bin");
    std::fs::write(&a, b"old").unwrap();
    let missing = dir.join("no-such-dir").join("b.bin");
    let e = write_files_atomic(&[(&a, b"new"), (&missing, b"b")]).unwrap_err();
    assert!(matches!(e, Error::Write { .. }), "{e}");
    assert_eq!(std::fs::read(&a).unwrap(), b"old");
    assert_eq!(dir.entries(), vec!["a.bin".to_string()]);

    let b = dir.join("b.bin");
    write_files_atomic(&[(&a, b"new"), (&b, b"b")]).unwrap();
    assert_eq!(std::fs::read(&a).unwrap(), b"new");
    assert_eq!(std::fs::read(&b).unwrap(), b"b");
    assert_eq!(
        dir.entries(),
        vec!["a.bin".to_string(), "b.bin".to_string()]
    );
}

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
        assert!(texsyn::session::is_analysis_file(&fifo).is_err());
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
