//! Files: loading exemplars, writing output images and coordinate maps, and the atomic
//! writer everything that texsyn writes goes through.
//!
//! * [`load_exemplar`] / [`exemplar_from_image`]: any format the `image` crate reads
//!   (PNG, JPEG, BMP, TGA, TIFF, WebP, GIF, PNM, HDR, OpenEXR), chosen by the file's
//!   content (the extension is only a fallback, e.g. for TGA, which has no signature).
//!   8-bit, 16-bit and float samples; grey, grey+alpha, RGB and RGBA. **Alpha is ignored**:
//!   grey and grey+alpha exemplars have 1 channel, everything else 3.
//! * 1- and 2-channel OpenEXRs, which the `image` crate refuses, are read with the `exr`
//!   crate (see [`open_image`] for the channel rule): a 1-channel EXR (`Y`, or any single
//!   channel) is a grey exemplar; a 2-channel one is grey + alpha when one channel is
//!   alpha (`A`), and a two-value field (flow, coordinate map, `R`/`G`) otherwise.
//! * [`write_atomic`]: write to a temporary file next to the target, fsync, rename over
//!   the target. A failed or interrupted write never leaves a partial file at the target.
//! * [`save_image_atomic`]: RGBA8 pixels to grey / RGB / RGBA in the format named by the
//!   extension.
//! * [`save_coords_exr_atomic`] / [`load_coords_exr`]: the synthesized exemplar
//!   coordinates as a 32-bit float OpenEXR (R = x, G = y, B = 0); a 2-channel (`R`, `G`)
//!   float EXR is read as well.

mod atomic;
mod coords;
mod decode;
mod exemplar;
mod exr;
mod material;
mod read;
mod write;

pub use atomic::{remove_temporaries, stage_file, write_atomic, write_files_atomic, StagedFile};
pub use coords::{
    encode_coords_exr_f32, load_coords_exr, load_coords_exr_f32, save_coords_exr_atomic,
    save_coords_exr_f32_atomic,
};
pub use decode::{
    animation_frames, check_finite, jpeg_lacks_end, open_image, open_image_exr_channels,
};
pub use exemplar::{downsample_exemplar, exemplar_from_image, load_exemplar};
pub use material::load_material_map;
pub use read::{open_regular, read_file_capped, MAX_MESH_FILE_BYTES};
pub use write::{encode_image, save_image_atomic, SUPPORTED_SAVE_EXTENSIONS};
