//! The analysis file (`texsyn analyze` output): a versioned, checksummed binary dump of
//! an [`Analysis`].
//!
//! # Layout (all integers little-endian)
//!
//! ```text
//! offset  size  field
//! 0       8     magic  b"TEXSYNA\0"
//! 8       4     u32    format version (FORMAT_VERSION = 4)
//! 12      8     u64    payload length P in bytes
//! 20      P     payload (below)
//! 20+P    8     u64    checksum of the P payload bytes: FNV-1a 64 in four lanes
//!                      of u64 words (version 2: plain FNV-1a 64; see `Checksum`)
//! ```
//!
//! Payload, version 4 (version 1 lacked the trailer after the levels; versions 2 and 3
//! had no padding before the tables):
//!
//! ```text
//! u32 width, u32 height, u32 channels, u8 tileable (0|1), u32 k
//! u64 n_colors,  n_colors x [u8; 4]        RGBA8, row-major (n_colors == width*height)
//! u32 n_levels                              (== level_count(width, height) + 1)
//! n_levels x level:
//!     u32 spacing                           (== 2^(n_levels-1-l))
//!     u32 margin
//!     u32 shift                             (< 32)
//!     f32 residual_variance                 (IEEE bits)
//!     f32 runtime_residual_variance
//!     8 x 32 i16 proj                       row-major
//!     u64 n_et, pad, n_et x 8 i16           (n_et == width*height, or 0 where no synthesis
//!                                           corrects: level 0, or the finest level when its
//!                                           offsets are left out; older files write them)
//!     u64 n_qe, pad, n_qe x 8 i16           (n_qe == n_et)
//!     u64 n_offsets, pad, n_offsets x 2 i16 (n_offsets == width*height*(k-1); 0 allowed on
//!                                           the finest level: its sets left out)
//! u8  appearance space                      (0 = neighborhood, 1 = color)
//! u8  feature mask used: 0 none, 1 in the appearance vectors, 2 in the similarity sets
//!     only (FeatureMode::Sets; older texsyn builds refuse 2 with a clear error), 3 in
//!     both (FeatureMode::Both, the sets and a share of the weight in the appearance
//!     vectors; older builds refuse 3 with a clear error)
//! f32 feature weight, f32 feature clamp (dmax), f32 mask coverage   (all 0 without a mask)
//! ```
//!
//! `pad` is 0-15 zero bytes, so that every table starts at a multiple of 16 bytes from
//! the start of the file: a mapped file's tables are used in place
//! ([`Analysis::load_mapped`]), which needs them aligned.
//!
//! Counts are element counts, not byte counts. The file must end right after the
//! checksum. Decoding checks the magic, the version, the length, the checksum and then
//! every decoded value (sizes 16..=65536, channels 1 or 3, k in 1..=MAX_K, level count,
//! spacings, shifts, every count) before allocating anything, so a corrupt or crafted file
//! gives [`Error::BadAnalysisFile`], never a panic or an allocation larger than the file.

use std::io::Write;
use std::path::Path;
use std::sync::Arc;

use crate::analysis::feature::{FEATURE_CLAMP_RANGE, MAX_FEATURE_WEIGHT};
use crate::analysis::{
    level_count, Analysis, AppearanceSpace, FeatureInfo, FeatureMode, LevelData, Table, DIM, MAX_K,
};
use crate::error::{Error, Result};

mod decode;
mod encode;
mod hash;
mod validate;

use hash::{checksum, Checksum};

/// First 8 bytes of every analysis file.
pub const MAGIC: [u8; 8] = *b"TEXSYNA\0";
/// Version of the layout written by this texsyn; the only one it reads.
pub const FORMAT_VERSION: u32 = 4;
/// Every table starts at a multiple of this many bytes from the start of the file.
const TABLE_ALIGN: u64 = 16;

/// Whether the file at `path` starts with [`MAGIC`], i.e. is an analysis file rather than
/// an image (a missing or unreadable file, or one that is not a regular file, is an
/// error).
pub fn is_analysis_file(path: &Path) -> Result<bool> {
    use std::io::Read;
    let mut f = crate::image_io::open_regular(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mut head = [0u8; 8];
    let mut n = 0;
    while n < head.len() {
        match f.read(&mut head[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(source) => {
                return Err(Error::Io {
                    path: path.to_path_buf(),
                    source,
                })
            }
        }
    }
    Ok(n == head.len() && head == MAGIC)
}

/// Zero bytes before a table whose count ends at payload offset `payload_pos`.
fn table_padding(payload_pos: u64) -> u64 {
    let at = HEADER_LEN as u64 + payload_pos;
    (TABLE_ALIGN - at % TABLE_ALIGN) % TABLE_ALIGN
}
/// Magic + version + payload length.
const HEADER_LEN: usize = 8 + 4 + 8;
const CHECKSUM_LEN: usize = 8;
/// Largest accepted exemplar side.
const MAX_SIDE: u32 = 65536;
const MIN_SIDE: u32 = 16;

const RERUN: &str = "re-run `texsyn analyze`";
/// Appearance space, feature flag, weight, clamp, coverage.
const APPEARANCE_TRAILER_LEN: u64 = 1 + 1 + 3 * 4;

// ---------------------------------------------------------------------------------------
// Checksum
// ---------------------------------------------------------------------------------------

const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
const FNV_PRIME: u64 = 0x0000_0100_0000_01b3;
/// Bytes per block of the checksum: four lanes of one u64 word each.
const BLOCK: usize = 32;

#[cfg(test)]
mod tests {
    use super::*;

    /// Streamed in pieces of any length, the checksum is the one-shot one.
    #[test]
    fn checksum_streams_in_any_pieces() {
        let bytes: Vec<u8> = (0..1000u32)
            .map(|i| (i.wrapping_mul(2654435761u32) >> 13) as u8)
            .collect();
        for len in [0, 1, 31, 32, 33, 64, 100, 1000] {
            let one = checksum(&bytes[..len]);
            for step in [1, 3, 7, 32, 33, 250] {
                let mut h = Checksum::new();
                for piece in bytes[..len].chunks(step) {
                    h.update(piece);
                }
                assert_eq!(h.finish(), one, "len {len}, pieces of {step}");
            }
        }
        // Every byte counts, whole blocks and tail alike.
        let mut b = bytes.clone();
        b[5] ^= 1;
        assert_ne!(checksum(&b), checksum(&bytes));
        let mut b = bytes.clone();
        b[999] ^= 0x80;
        assert_ne!(checksum(&b), checksum(&bytes));
        // Lanes are not interchangeable: swapping two words changes the sum.
        let mut b = bytes.clone();
        b.copy_within(0..8, 8);
        b[..8].copy_from_slice(&bytes[8..16]);
        assert_ne!(checksum(&b), checksum(&bytes));
    }
}
