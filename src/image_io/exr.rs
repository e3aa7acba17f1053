//! 1- and 2-channel OpenEXRs, which the `image` crate refuses, read with the `exr` crate.

use std::io::BufReader;
use std::path::Path;

use image::DynamicImage;

use super::read::open_regular;

/// A 1- or 2-channel OpenEXR read with the `exr` crate (see [`open_image`](super::open_image)).
pub(super) struct FewChannelExr {
    pub(super) width: u32,
    pub(super) height: u32,
    /// The channel names, in the order of `data` (see [`open_image`](super::open_image) for
    /// the rule).
    pub(super) names: Vec<String>,
    /// 2 channels, the second of which is alpha.
    pub(super) alpha: bool,
    /// Row-major, `names.len()` interleaved samples per pixel, 0 outside the data window.
    pub(super) data: Vec<f32>,
}

impl FewChannelExr {
    pub(super) fn channels(&self) -> usize {
        self.names.len()
    }

    /// Float RGB: `(v, v, v)` for 1 channel, `(a, b, 0)` for 2.
    pub(super) fn to_image(&self) -> DynamicImage {
        let rgb: Vec<f32> = if self.channels() == 1 {
            self.data.iter().flat_map(|&v| [v; 3]).collect()
        } else {
            self.data
                .chunks_exact(2)
                .flat_map(|p| [p[0], p[1], 0.0])
                .collect()
        };
        DynamicImage::ImageRgb32F(
            image::Rgb32FImage::from_raw(self.width, self.height, rgb)
                .expect("buffer sized for the image"),
        )
    }
}

/// The most bytes a 1- or 2-channel EXR may take to decode (the `image` crate's default
/// allocation limit).
const MAX_EXR_ALLOC: u64 = 512 * 1024 * 1024;

/// The last `.`-separated part of an EXR channel name (`diffuse.R` -> `R`).
pub(super) fn channel_base(name: &str) -> &str {
    name.rsplit('.').next().unwrap_or(name)
}

/// Runs `f` (exr crate code on untrusted input), turning a panic into an error message.
fn no_panic<T>(
    f: impl FnOnce() -> std::result::Result<T, String>,
) -> std::result::Result<T, String> {
    crate::error::catch_quietly(f)
        .unwrap_or_else(|()| Err("the OpenEXR decoder failed on this file (corrupt data)".into()))
}

/// Channel names of the first non-deep layer of an EXR, or `None` when its header cannot
/// be read.
pub(super) fn exr_channel_names(path: &Path) -> Option<Vec<String>> {
    no_panic(|| {
        let file = open_regular(path).map_err(|e| e.to_string())?;
        let meta = exr::meta::MetaData::read_from_buffered(BufReader::new(file), false)
            .map_err(|e| e.to_string())?;
        let header = meta.headers.iter().find(|h| !h.deep).ok_or("")?;
        Ok(header
            .channels
            .list
            .iter()
            .map(|c| c.name.to_string())
            .collect())
    })
    .ok()
}

/// Reads a 1- or 2-channel EXR (see [`open_image`](super::open_image)); errors are the
/// reason, in words.
pub(super) fn read_few_channel_exr(path: &Path) -> std::result::Result<FewChannelExr, String> {
    use exr::prelude::traits::*;
    let exr_err = |e: exr::error::Error| match e {
        exr::error::Error::Io(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            format!("the file is truncated ({io})")
        }
        // What the exr crate says when a chunk lies past the end of the file.
        exr::error::Error::Invalid(m) if m.contains("missing bytes") => {
            format!("the file is truncated or corrupt ({m})")
        }
        e => e.to_string(),
    };
    let open = || {
        open_regular(path)
            .map(BufReader::new)
            .map_err(|e| e.to_string())
    };
    no_panic(|| {
        // Size check before any pixel buffer is allocated.
        let meta = exr::meta::MetaData::read_from_buffered(open()?, false).map_err(exr_err)?;
        let header = meta
            .headers
            .iter()
            .find(|h| !h.deep)
            .ok_or("the OpenEXR holds only deep data, which texsyn does not read")?;
        if header
            .channels
            .list
            .iter()
            .any(|c| c.sampling != exr::math::Vec2(1, 1))
        {
            return Err("subsampled OpenEXR channels are not supported".into());
        }
        let display = header.shared_attributes.display_window;
        let data_bytes = header.layer_size.area() as u128 * header.channels.bytes_per_pixel as u128;
        let out_bytes = display.size.area() as u128 * 12;
        if data_bytes + out_bytes > MAX_EXR_ALLOC as u128 {
            return Err(format!(
                "the {}x{} OpenEXR needs more than {} MiB to decode",
                display.size.width(),
                display.size.height(),
                MAX_EXR_ALLOC >> 20
            ));
        }

        let img = exr::prelude::read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .first_valid_layer()
            .all_attributes()
            .non_parallel()
            .from_buffered(open()?)
            .map_err(exr_err)?;
        let layer = &img.layer_data;
        let display = img.attributes.display_window;
        let (w, h) = (display.size.width(), display.size.height());
        if w == 0 || h == 0 || w > u32::MAX as usize || h > u32::MAX as usize {
            return Err(format!("the OpenEXR's display window is {w}x{h}"));
        }
        let list = &layer.channel_data.list;
        let mut order: Vec<usize> = (0..list.len()).collect();
        order.sort_by(|&a, &b| list[a].name.to_string().cmp(&list[b].name.to_string()));
        let base = |i: usize| channel_base(&list[i].name.to_string()).to_ascii_uppercase();
        let mut alpha = false;
        match order.len() {
            1 => {}
            2 => {
                let (b0, b1) = (base(order[0]), base(order[1]));
                if b0 == "G" && b1 == "R" {
                    order.swap(0, 1);
                } else if b0 == "A" && b1 != "A" {
                    order.swap(0, 1);
                    alpha = true;
                } else if b1 == "A" && b0 != "A" {
                    alpha = true;
                }
            }
            n => return Err(format!("expected 1 or 2 channels, the layer has {n}")),
        }
        let (lw, lh) = (layer.size.width(), layer.size.height());
        if order.iter().any(|&i| list[i].sample_data.len() != lw * lh) {
            return Err("a channel holds the wrong number of samples (corrupt file)".into());
        }
        let c = order.len();
        let mut data = vec![0f32; w * h * c];
        // Data window pixel (x, y) is display pixel (x + dx, y + dy).
        let dx = layer.attributes.layer_position.x() as i64 - display.position.x() as i64;
        let dy = layer.attributes.layer_position.y() as i64 - display.position.y() as i64;
        for y in 0..lh {
            let ty = y as i64 + dy;
            if ty < 0 || ty >= h as i64 {
                continue;
            }
            for x in 0..lw {
                let tx = x as i64 + dx;
                if tx < 0 || tx >= w as i64 {
                    continue;
                }
                let to = (ty as usize * w + tx as usize) * c;
                for (k, &ch) in order.iter().enumerate() {
                    data[to + k] = list[ch]
                        .sample_data
                        .value_by_flat_index(y * lw + x)
                        .to_f32();
                }
            }
        }
        Ok(FewChannelExr {
            width: w as u32,
            height: h as u32,
            names: order.iter().map(|&i| list[i].name.to_string()).collect(),
            alpha,
            data,
        })
    })
}
