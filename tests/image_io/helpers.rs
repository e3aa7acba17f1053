//! What the image tests share: writing test images (an RGBA pattern, float OpenEXRs of
//! any channels) and the reason of a refused image.

use std::path::Path;

use image::DynamicImage;
use texsyn::Error;

/// Saves `img` at `path` (the format from its extension).
pub fn save(img: &DynamicImage, path: &Path) {
    img.save(path).unwrap();
}

/// The reason of a `BadImage` error about `path` (panics on anything else).
pub fn bad_image(r: texsyn::Result<texsyn::Exemplar>, path: &Path) -> String {
    match r {
        Err(Error::BadImage { path: p, reason }) => {
            assert_eq!(p, path);
            assert!(!reason.is_empty());
            reason
        }
        other => panic!("expected BadImage for {}, got {other:?}", path.display()),
    }
}

/// A `w` x `h` RGBA8 gradient pattern with varying alpha.
pub fn pattern_rgba(w: u32, h: u32) -> Vec<u8> {
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

/// Writes a float OpenEXR with the given channels (`w * h` row-major samples each).
pub fn write_exr(path: &Path, w: usize, h: usize, channels: &[(&str, Vec<f32>)]) {
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

/// The float RGB buffer of a decoded image (panics on any other kind).
pub fn rgb32f(img: &DynamicImage) -> &image::Rgb32FImage {
    match img {
        DynamicImage::ImageRgb32F(b) => b,
        other => panic!("expected float RGB, got {:?}", other.color()),
    }
}
