//! Coordinate maps in OpenEXR: round trips, rounding, two-channel maps.

use image::{DynamicImage, ImageBuffer, Rgba};
use texsyn::image_io::{
    load_coords_exr, load_coords_exr_f32, save_coords_exr_atomic, save_image_atomic,
};
use texsyn::Error;

use crate::common::TempDir;
use crate::helpers::*;

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
