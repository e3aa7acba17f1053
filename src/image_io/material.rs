//! Material maps (`--also`): images resynthesized alongside the exemplar, alpha included.

use std::path::Path;

use super::decode::{check_finite, check_finite_samples, decode_any, Decoded};
use super::exemplar::{f32_to_unit, grey8};
use crate::error::Result;

/// A material map (`--also`): its size, its channel count as stored (1 grey, 2 grey +
/// alpha, 3 RGB, 4 RGBA) and its pixels as RGBA8 (grey replicated into RGB; alpha kept, 255
/// where there is none). Unlike [`load_exemplar`](super::load_exemplar), alpha is data here
/// (opacity, packed roughness...), so it is resynthesized and written back. A 1-channel
/// OpenEXR is grey, a 2-channel one with an alpha (`A`) channel grey + alpha, any other
/// 2-channel one RGB with the two channels in R and G and B = 0 (floats clamped to [0, 1]).
pub fn load_material_map(path: &Path) -> Result<(u32, u32, u32, Vec<[u8; 4]>)> {
    let img = match decode_any(path)? {
        Decoded::Image(img) => {
            check_finite(&img, path, "material map")?;
            img
        }
        Decoded::Exr(exr) if exr.channels() == 1 || exr.alpha => {
            check_finite_samples(&exr.data, exr.channels(), exr.width, path, "material map")?;
            let to8 = |v: f32| (f32_to_unit(v) * 255.0).round() as u8;
            let pixels = if exr.channels() == 1 {
                exr.data.iter().map(|&v| grey8(to8(v))).collect()
            } else {
                exr.data
                    .chunks_exact(2)
                    .map(|p| {
                        let g = to8(p[0]);
                        [g, g, g, to8(p[1])]
                    })
                    .collect()
            };
            return Ok((exr.width, exr.height, exr.channels() as u32, pixels));
        }
        Decoded::Exr(exr) => {
            check_finite_samples(&exr.data, exr.channels(), exr.width, path, "material map")?;
            exr.to_image()
        }
    };
    let channels = img.color().channel_count() as u32;
    let pixels = img.to_rgba8().pixels().map(|p| p.0).collect();
    Ok((img.width(), img.height(), channels.clamp(1, 4), pixels))
}
