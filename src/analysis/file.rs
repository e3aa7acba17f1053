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

use super::feature::{FEATURE_CLAMP_RANGE, MAX_FEATURE_WEIGHT};
use super::{
    level_count, Analysis, AppearanceSpace, FeatureInfo, FeatureMode, LevelData, Table, DIM, MAX_K,
};
use crate::error::{Error, Result};

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

fn fnv1a_bytes(mut h: u64, bytes: &[u8]) -> u64 {
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(FNV_PRIME);
    }
    h
}

/// The file's checksum (version 3), streaming: FNV-1a 64 in four lanes. The payload is
/// read as little-endian u64 words, word `i` going into lane `i % 4` as
/// `h = (h ^ word) * prime`; the bytes after the last whole 32-byte block go through
/// plain byte-wise FNV-1a (the tail); the result is byte-wise FNV-1a of the four lanes'
/// and then the tail's little-endian bytes. Every state starts at the FNV offset basis.
/// Why not plain FNV-1a (version 2): its one multiply per byte in a dependency chain
/// took 5.6 ms of the 10 ms load of a 4.6 MiB file; four lanes of words take 0.4 ms.
#[derive(Clone, Copy)]
struct Checksum {
    lanes: [u64; 4],
    pending: [u8; BLOCK],
    n_pending: usize,
}

impl Checksum {
    fn new() -> Self {
        Checksum {
            lanes: [FNV_OFFSET; 4],
            pending: [0; BLOCK],
            n_pending: 0,
        }
    }
    fn block(&mut self, block: &[u8]) {
        for (h, w) in self.lanes.iter_mut().zip(block.chunks_exact(8)) {
            *h = (*h ^ u64::from_le_bytes(w.try_into().unwrap())).wrapping_mul(FNV_PRIME);
        }
    }
    fn update(&mut self, mut bytes: &[u8]) {
        if self.n_pending > 0 {
            let take = (BLOCK - self.n_pending).min(bytes.len());
            self.pending[self.n_pending..self.n_pending + take].copy_from_slice(&bytes[..take]);
            self.n_pending += take;
            bytes = &bytes[take..];
            if self.n_pending < BLOCK {
                return;
            }
            let pending = self.pending;
            self.block(&pending);
            self.n_pending = 0;
        }
        let mut blocks = bytes.chunks_exact(BLOCK);
        for b in &mut blocks {
            self.block(b);
        }
        let rest = blocks.remainder();
        self.pending[..rest.len()].copy_from_slice(rest);
        self.n_pending = rest.len();
    }
    fn finish(&self) -> u64 {
        let tail = fnv1a_bytes(FNV_OFFSET, &self.pending[..self.n_pending]);
        let mut h = FNV_OFFSET;
        for v in self.lanes.iter().chain([&tail]) {
            h = fnv1a_bytes(h, &v.to_le_bytes());
        }
        h
    }
}

fn checksum(bytes: &[u8]) -> u64 {
    let mut h = Checksum::new();
    h.update(bytes);
    h.finish()
}

// ---------------------------------------------------------------------------------------
// Encoding
// ---------------------------------------------------------------------------------------

/// Buffers small writes, hashes everything, forwards to `W` in large chunks.
struct PayloadWriter<'a, W: Write> {
    out: &'a mut W,
    buf: Vec<u8>,
    hash: Checksum,
    written: u64,
}

const CHUNK: usize = 1 << 16;

impl<'a, W: Write> PayloadWriter<'a, W> {
    fn new(out: &'a mut W) -> Self {
        Self {
            out,
            buf: Vec::with_capacity(CHUNK),
            hash: Checksum::new(),
            written: 0,
        }
    }
    fn bytes(&mut self, b: &[u8]) -> std::io::Result<()> {
        self.buf.extend_from_slice(b);
        if self.buf.len() >= CHUNK {
            self.flush_buf()?;
        }
        Ok(())
    }
    fn flush_buf(&mut self) -> std::io::Result<()> {
        self.hash.update(&self.buf);
        self.written += self.buf.len() as u64;
        self.out.write_all(&self.buf)?;
        self.buf.clear();
        Ok(())
    }
    fn u8(&mut self, v: u8) -> std::io::Result<()> {
        self.bytes(&[v])
    }
    fn u32(&mut self, v: u32) -> std::io::Result<()> {
        self.bytes(&v.to_le_bytes())
    }
    fn u64(&mut self, v: u64) -> std::io::Result<()> {
        self.bytes(&v.to_le_bytes())
    }
    fn f32(&mut self, v: f32) -> std::io::Result<()> {
        self.bytes(&v.to_bits().to_le_bytes())
    }
    /// Bytes of the payload so far.
    fn position(&self) -> u64 {
        self.written + self.buf.len() as u64
    }
    /// A table: its element count, the padding that aligns it, its values.
    fn table<const N: usize>(&mut self, t: &[[i16; N]]) -> std::io::Result<()> {
        self.u64(t.len() as u64)?;
        let pad = table_padding(self.position()) as usize;
        self.bytes(&[0u8; TABLE_ALIGN as usize][..pad])?;
        self.i16s(t.as_flattened())
    }
    fn i16s(&mut self, vals: &[i16]) -> std::io::Result<()> {
        for chunk in vals.chunks(CHUNK / 2) {
            for &v in chunk {
                self.buf.extend_from_slice(&v.to_le_bytes());
            }
            if self.buf.len() >= CHUNK {
                self.flush_buf()?;
            }
        }
        Ok(())
    }
    /// Flushes and returns (payload bytes written, checksum).
    fn finish(mut self) -> std::io::Result<(u64, u64)> {
        self.flush_buf()?;
        Ok((self.written, self.hash.finish()))
    }
}

impl Analysis {
    /// Exact payload size in bytes (see the module doc).
    fn payload_len(&self) -> u64 {
        let mut n: u64 = 4 * 3 + 1 + 4; // width, height, channels, tileable, k
        n += 8 + 4 * self.colors.len() as u64;
        n += 4;
        // A table: its count, the padding after it, its bytes.
        let table = |n: u64, bytes: u64| {
            let counted = n + 8;
            counted + table_padding(counted) + bytes
        };
        for lv in &self.levels {
            n += 4 * 3 + 4 * 2; // spacing, margin, shift, two f32
            n += 2 * (4 * DIM * DIM) as u64; // proj
            n = table(n, 2 * DIM as u64 * lv.et.len() as u64);
            n = table(n, 2 * DIM as u64 * lv.qe.len() as u64);
            n = table(n, 4 * lv.offsets.len() as u64);
        }
        n + APPEARANCE_TRAILER_LEN
    }

    fn write_payload<W: Write>(&self, w: &mut PayloadWriter<'_, W>) -> std::io::Result<()> {
        w.u32(self.width)?;
        w.u32(self.height)?;
        w.u32(self.channels)?;
        w.u8(self.tileable as u8)?;
        w.u32(self.k)?;
        w.u64(self.colors.len() as u64)?;
        for chunk in self.colors.chunks(CHUNK / 4) {
            w.bytes(bytemuck::cast_slice(chunk))?;
        }
        w.u32(self.levels.len() as u32)?;
        for lv in &self.levels {
            w.u32(lv.spacing)?;
            w.u32(lv.margin)?;
            w.u32(lv.shift)?;
            w.f32(lv.residual_variance)?;
            w.f32(lv.runtime_residual_variance)?;
            w.i16s(lv.proj.as_flattened())?;
            w.table(&lv.et)?;
            w.table(&lv.qe)?;
            w.table(&lv.offsets)?;
        }
        w.u8(match self.appearance {
            AppearanceSpace::Neighborhood => 0,
            AppearanceSpace::Color => 1,
        })?;
        w.u8(match self.feature.map(|f| f.mode) {
            None => 0,
            Some(FeatureMode::Appearance) => 1,
            Some(FeatureMode::Sets) => 2,
            Some(FeatureMode::Both) => 3,
        })?;
        let f = self.feature.unwrap_or(FeatureInfo {
            weight: 0.0,
            clamp: 0.0,
            coverage: 0.0,
            mode: FeatureMode::Appearance,
        });
        w.f32(f.weight)?;
        w.f32(f.clamp)?;
        w.f32(f.coverage)?;
        Ok(())
    }

    /// Writes the whole file (header, payload, checksum) to `out`.
    fn write_file<W: Write>(&self, out: &mut W) -> std::io::Result<()> {
        let len = self.payload_len();
        out.write_all(&MAGIC)?;
        out.write_all(&FORMAT_VERSION.to_le_bytes())?;
        out.write_all(&len.to_le_bytes())?;
        let mut pw = PayloadWriter::new(out);
        self.write_payload(&mut pw)?;
        let (written, hash) = pw.finish()?;
        debug_assert_eq!(written, len, "payload_len disagrees with write_payload");
        out.write_all(&hash.to_le_bytes())?;
        Ok(())
    }

    /// The analysis file's bytes (see the module doc for the layout).
    pub fn to_bytes(&self) -> Vec<u8> {
        let total = HEADER_LEN as u64 + self.payload_len() + CHECKSUM_LEN as u64;
        let mut v = Vec::with_capacity(total as usize);
        self.write_file(&mut v)
            .expect("writing to a Vec cannot fail");
        v
    }

    /// Saves the analysis atomically (temporary file + rename): `path` either keeps its
    /// old content or gets the complete new file. Errors are [`Error::Write`].
    pub fn save(&self, path: &Path) -> Result<()> {
        crate::image_io::write_atomic(path, |w| {
            self.write_file(w).map_err(|e| Error::Write {
                path: path.to_path_buf(),
                reason: e.to_string(),
            })
        })
    }

    /// Loads an analysis file written by [`Analysis::save`]. A missing or unreadable file
    /// is [`Error::Io`]; anything wrong with the content is [`Error::BadAnalysisFile`].
    /// The tables are read into memory of their own; [`Analysis::load_mapped`] uses them
    /// in place.
    pub fn load(path: &Path) -> Result<Analysis> {
        let io = |source| Error::Io {
            path: path.to_path_buf(),
            source,
        };
        let file = crate::image_io::open_regular(path).map_err(io)?;
        if let Some(a) = Self::stream(file) {
            return Ok(a);
        }
        // Anything unusual (a short, corrupt or changing file): the in-memory path,
        // which checks the checksum before the content and so names the first problem.
        let bytes = std::fs::read(path).map_err(io)?;
        Self::from_bytes(&bytes, path)
    }

    /// A well-formed file decoded as it is read; `None` on any problem.
    fn stream(file: std::fs::File) -> Option<Analysis> {
        use std::io::Read;
        let len = file.metadata().ok()?.len();
        let mut file = std::io::BufReader::with_capacity(1 << 16, file);
        let mut header = [0u8; HEADER_LEN];
        file.read_exact(&mut header).ok()?;
        let payload_len = u64::from_le_bytes(header[12..20].try_into().unwrap());
        let well_formed = header[..8] == MAGIC
            && u32::from_le_bytes(header[8..12].try_into().unwrap()) == FORMAT_VERSION
            && payload_len.checked_add((HEADER_LEN + CHECKSUM_LEN) as u64) == Some(len);
        if !well_formed {
            return None;
        }
        let mut input = FileInput {
            file,
            len: payload_len,
            remaining: payload_len,
            hash: Checksum::new(),
        };
        let analysis = decode_payload(&mut input).ok()?;
        let mut stored = [0u8; CHECKSUM_LEN];
        input.file.read_exact(&mut stored).ok()?;
        let end = input.file.read(&mut [0u8; 1]).ok()? == 0;
        (end && input.hash.finish() == u64::from_le_bytes(stored)).then_some(analysis)
    }

    /// [`Analysis::load`], with the file mapped into memory: the tables are views of the
    /// file's pages ([`Table::is_mapped`]) instead of copies, which saves reading them
    /// into fresh memory (on lavapipe, a 53 MB file's load slowed the device creation
    /// beside it by 10-20 ms). The same checks and errors as `load`; a file that cannot
    /// be mapped is read as `load` reads it.
    ///
    /// # Safety
    ///
    /// The file must not be truncated or written in place while the analysis (or a
    /// clone of it) is alive: its tables read the file's pages, and a truncated file
    /// makes those reads fault (`SIGBUS`). Replacing the file (a new file renamed over
    /// it, as [`Analysis::save`] and `texsyn analyze` do) is safe: the mapping keeps the
    /// old one.
    pub unsafe fn load_mapped(path: &Path) -> Result<Analysis> {
        let file = crate::image_io::open_regular(path).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })?;
        // SAFETY: the caller's contract above.
        match unsafe { memmap2::Mmap::map(&file) } {
            Ok(map) => {
                let map = Arc::new(map);
                Self::decode(&map, Some(&map), path)
            }
            Err(_) => Self::load(path),
        }
    }

    /// Decodes an analysis file's bytes; `path_for_errors` only names the file in errors.
    pub fn from_bytes(bytes: &[u8], path_for_errors: &Path) -> Result<Analysis> {
        Self::decode(bytes, None, path_for_errors)
    }

    /// [`Analysis::from_bytes`]; with `map` (whose bytes `bytes` are), the tables are
    /// views of it.
    fn decode(
        bytes: &[u8],
        map: Option<&Arc<memmap2::Mmap>>,
        path_for_errors: &Path,
    ) -> Result<Analysis> {
        let bad = |reason: String| Error::BadAnalysisFile {
            path: path_for_errors.to_path_buf(),
            reason,
        };

        // Magic: a short file that is a prefix of the magic is truncated, else not ours.
        if bytes.len() < MAGIC.len() {
            if bytes.is_empty() {
                return Err(bad(format!(
                    "the file is empty (truncated: expected at least {} bytes, found 0); {RERUN}",
                    HEADER_LEN + CHECKSUM_LEN
                )));
            }
            if MAGIC.starts_with(bytes) {
                return Err(bad(truncated(HEADER_LEN + CHECKSUM_LEN, bytes.len())));
            }
            return Err(bad(bad_magic()));
        }
        if bytes[..8] != MAGIC {
            return Err(bad(bad_magic()));
        }
        if bytes.len() < 12 {
            return Err(bad(truncated(HEADER_LEN + CHECKSUM_LEN, bytes.len())));
        }
        let version = u32::from_le_bytes(bytes[8..12].try_into().unwrap());
        if version != FORMAT_VERSION {
            return Err(bad(format!(
                "analysis file version {version} is not supported by this texsyn (expects \
                 {FORMAT_VERSION}); {RERUN}"
            )));
        }
        if bytes.len() < HEADER_LEN {
            return Err(bad(truncated(HEADER_LEN + CHECKSUM_LEN, bytes.len())));
        }
        let payload_len = u64::from_le_bytes(bytes[12..20].try_into().unwrap());
        let expected = (HEADER_LEN as u64)
            .checked_add(payload_len)
            .and_then(|n| n.checked_add(CHECKSUM_LEN as u64));
        let Some(expected) = expected else {
            return Err(bad(format!(
                "corrupt header: payload length {payload_len} is impossible; {RERUN}"
            )));
        };
        if (bytes.len() as u64) < expected {
            return Err(bad(format!(
                "truncated: expected {expected} bytes, found {}; the file is incomplete, {RERUN}",
                bytes.len()
            )));
        }
        if (bytes.len() as u64) > expected {
            return Err(bad(format!(
                "trailing data: expected {expected} bytes, found {}; the file is corrupt, {RERUN}",
                bytes.len()
            )));
        }
        let payload_end = HEADER_LEN + payload_len as usize;
        let payload = &bytes[HEADER_LEN..payload_end];
        let stored = u64::from_le_bytes(bytes[payload_end..].try_into().unwrap());
        if checksum(payload) != stored {
            return Err(bad(format!(
                "checksum mismatch: the file is corrupt; {RERUN}"
            )));
        }

        decode_payload(&mut Reader {
            bytes: payload,
            pos: 0,
            map: map.map(|m| (m, HEADER_LEN)),
        })
        .map_err(|e| bad(format!("invalid content: {e}; {RERUN}")))
    }
}

fn bad_magic() -> String {
    "not a texsyn analysis file (bad magic); pass a file written by `texsyn analyze`".into()
}

fn truncated(expected_at_least: usize, found: usize) -> String {
    format!(
        "truncated: expected at least {expected_at_least} bytes, found {found}; the file is \
         incomplete, {RERUN}"
    )
}

// ---------------------------------------------------------------------------------------
// Decoding (after the checksum matched, so failures here mean a buggy or crafted file)
// ---------------------------------------------------------------------------------------

/// What the decoder reads from: the payload in memory ([`Reader`]) or streamed from the
/// file ([`FileInput`]). Every method names the field it reads, for the error.
trait Input {
    fn remaining(&self) -> u64;
    /// Bytes of the payload read so far.
    fn position(&self) -> u64;
    /// Fills `buf` with the next bytes.
    fn fill(&mut self, buf: &mut [u8], what: &str) -> std::result::Result<(), String>;
    /// The next `bytes` bytes as a table of `N`-wide i16 elements.
    fn table<const N: usize>(
        &mut self,
        bytes: usize,
        what: &str,
    ) -> std::result::Result<Table<[i16; N]>, String> {
        owned_table(self, bytes, what)
    }
    /// A table: a u64 element count that must equal `expected` (or be 0 where
    /// `may_be_empty`), the zero padding that aligns it, its `N`-wide i16 elements.
    fn i16_arrays_or_none<const N: usize>(
        &mut self,
        expected: u64,
        may_be_empty: bool,
        what: &str,
    ) -> std::result::Result<Table<[i16; N]>, String> {
        let n = self.count(expected, may_be_empty, 2 * N, what)?;
        let pad = table_padding(self.position()) as usize;
        if (pad + n) as u64 > self.remaining() {
            return Err(too_short(pad + n, what, self.remaining()));
        }
        let mut zeros = [0u8; TABLE_ALIGN as usize];
        self.fill(&mut zeros[..pad], what)?;
        if zeros.iter().any(|&b| b != 0) {
            return Err(format!("{what}: the padding before its values is not zero"));
        }
        self.table(n, what)
    }

    fn u8(&mut self, what: &str) -> std::result::Result<u8, String> {
        let mut b = [0u8; 1];
        self.fill(&mut b, what)?;
        Ok(b[0])
    }
    fn u32(&mut self, what: &str) -> std::result::Result<u32, String> {
        let mut b = [0u8; 4];
        self.fill(&mut b, what)?;
        Ok(u32::from_le_bytes(b))
    }
    fn u64(&mut self, what: &str) -> std::result::Result<u64, String> {
        let mut b = [0u8; 8];
        self.fill(&mut b, what)?;
        Ok(u64::from_le_bytes(b))
    }
    fn f32(&mut self, what: &str) -> std::result::Result<f32, String> {
        Ok(f32::from_bits(self.u32(what)?))
    }
    /// Reads a u64 element count, checks it equals `expected` and that its elements
    /// (`elem_size` bytes each) fit in what is left; allocates nothing. Returns the
    /// byte count.
    fn count(
        &mut self,
        expected: u64,
        may_be_empty: bool,
        elem_size: usize,
        what: &str,
    ) -> std::result::Result<usize, String> {
        let n = self.u64(what)?;
        if n != expected && !(may_be_empty && n == 0) {
            return Err(format!("{what} has {n} entries, expected {expected}"));
        }
        n.checked_mul(elem_size as u64)
            .filter(|&b| b <= self.remaining())
            .map(|b| b as usize)
            .ok_or_else(|| {
                format!(
                    "{what} needs {n} x {elem_size} bytes but the payload has only {} left",
                    self.remaining()
                )
            })
    }
}

/// The next `bytes` bytes of `input`, read straight into a vector of their own.
fn owned_table<const N: usize, I: Input + ?Sized>(
    input: &mut I,
    bytes: usize,
    what: &str,
) -> std::result::Result<Table<[i16; N]>, String> {
    let mut v = vec![[0i16; N]; bytes / (2 * N)];
    input.fill(bytemuck::cast_slice_mut(&mut v), what)?;
    if cfg!(target_endian = "big") {
        v.iter_mut().flatten().for_each(|x| *x = i16::from_le(*x));
    }
    Ok(v.into())
}

fn too_short(n: usize, what: &str, left: u64) -> String {
    format!("{what} needs {n} bytes but the payload has only {left} left")
}

struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
    /// The mapped file `bytes` lie in and their offset in it: tables become views.
    map: Option<(&'a Arc<memmap2::Mmap>, usize)>,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize, what: &str) -> std::result::Result<&'a [u8], String> {
        if self.bytes.len() - self.pos < n {
            return Err(too_short(n, what, (self.bytes.len() - self.pos) as u64));
        }
        let s = &self.bytes[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
}

impl Input for Reader<'_> {
    fn remaining(&self) -> u64 {
        (self.bytes.len() - self.pos) as u64
    }
    fn position(&self) -> u64 {
        self.pos as u64
    }
    fn table<const N: usize>(
        &mut self,
        bytes: usize,
        what: &str,
    ) -> std::result::Result<Table<[i16; N]>, String> {
        // In place where the file's bytes are the values (little-endian) and aligned.
        if let (Some((map, at)), true, true) = (self.map, bytes > 0, cfg!(target_endian = "little"))
        {
            if bytes <= self.bytes.len() - self.pos {
                if let Some(t) = Table::mapped(map.clone(), at + self.pos, bytes / (2 * N)) {
                    self.pos += bytes;
                    return Ok(t);
                }
            }
        }
        owned_table(self, bytes, what)
    }
    fn fill(&mut self, buf: &mut [u8], what: &str) -> std::result::Result<(), String> {
        buf.copy_from_slice(self.take(buf.len(), what)?);
        Ok(())
    }
}

/// The payload streamed from the file, hashed as it is read. Its arrays are read
/// straight into their final vectors: reading the whole file first and decoding it
/// copied every table twice, and on a CPU device the page faults of each copy of fresh
/// memory were most of the load (a 400 px exemplar's file is 55 MB).
struct FileInput<R: std::io::Read> {
    file: R,
    /// Payload length.
    len: u64,
    remaining: u64,
    hash: Checksum,
}

impl<R: std::io::Read> Input for FileInput<R> {
    fn remaining(&self) -> u64 {
        self.remaining
    }
    fn position(&self) -> u64 {
        self.len - self.remaining
    }
    fn fill(&mut self, buf: &mut [u8], what: &str) -> std::result::Result<(), String> {
        if (buf.len() as u64) > self.remaining {
            return Err(too_short(buf.len(), what, self.remaining));
        }
        self.file
            .read_exact(buf)
            .map_err(|e| format!("reading {what}: {e}"))?;
        self.hash.update(buf);
        self.remaining -= buf.len() as u64;
        Ok(())
    }
}

fn i16_at(b: &[u8], i: usize) -> i16 {
    i16::from_le_bytes([b[2 * i], b[2 * i + 1]])
}

fn decode_payload(r: &mut impl Input) -> std::result::Result<Analysis, String> {
    let width = r.u32("width")?;
    let height = r.u32("height")?;
    for (name, v) in [("width", width), ("height", height)] {
        if !(MIN_SIDE..=MAX_SIDE).contains(&v) {
            return Err(format!("{name} {v} is outside {MIN_SIDE}..={MAX_SIDE}"));
        }
    }
    let channels = r.u32("channels")?;
    if channels != 1 && channels != 3 {
        return Err(format!("channels is {channels}, expected 1 or 3"));
    }
    let tileable = match r.u8("tileable flag")? {
        0 => false,
        1 => true,
        t => return Err(format!("tileable flag is {t}, expected 0 or 1")),
    };
    let k = r.u32("k")?;
    if !(1..=MAX_K).contains(&k) {
        return Err(format!("k is {k}, expected 1..={MAX_K}"));
    }
    let pixels = width as u64 * height as u64;

    let n = r.count(pixels, false, 4, "colors")?;
    let mut colors = vec![[0u8; 4]; n / 4];
    r.fill(colors.as_flattened_mut(), "colors")?;

    let top = level_count(width, height);
    let n_levels = r.u32("level count")?;
    if n_levels != top + 1 {
        return Err(format!(
            "level count is {n_levels}, expected {} for a {width}x{height} exemplar",
            top + 1
        ));
    }

    let mut levels = Vec::with_capacity(n_levels as usize);
    for l in 0..n_levels {
        let lw = |f: &str| format!("level {l} {f}");
        let spacing = r.u32(&lw("spacing"))?;
        let expected_spacing = 1u32 << (top - l);
        if spacing != expected_spacing {
            return Err(format!(
                "level {l} spacing is {spacing}, expected {expected_spacing}"
            ));
        }
        let margin = r.u32(&lw("margin"))?;
        if margin.saturating_mul(2) >= width.min(height) {
            return Err(format!(
                "level {l} margin {margin} leaves no valid region in a {width}x{height} exemplar"
            ));
        }
        let shift = r.u32(&lw("shift"))?;
        if shift >= 32 {
            return Err(format!("level {l} shift is {shift}, expected < 32"));
        }
        let residual_variance = r.f32(&lw("residual variance"))?;
        let runtime_residual_variance = r.f32(&lw("runtime residual variance"))?;

        let mut proj_bytes = [0u8; 2 * 4 * DIM * DIM];
        r.fill(&mut proj_bytes, &lw("projection"))?;
        let mut proj = [[0i16; 4 * DIM]; DIM];
        for (i, row) in proj.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = i16_at(&proj_bytes, i * 4 * DIM + j);
            }
        }

        // Level 0 and a finest level without sets have no tables (LevelData::et);
        // validate() checks the combination.
        let finest = l + 1 == n_levels;
        let et = r.i16_arrays_or_none::<DIM>(pixels, l == 0 || finest, &lw("et"))?;
        let qe = r.i16_arrays_or_none::<DIM>(pixels, l == 0 || finest, &lw("qe"))?;
        let n_offsets = pixels * (k as u64 - 1);
        // The finest level's sets may be left out (AnalysisOptions::finest_sets).
        let offsets = r.i16_arrays_or_none::<2>(n_offsets, finest, &lw("offsets"))?;
        if et.is_empty() != qe.is_empty() {
            return Err(format!(
                "level {l} qe has {} entries, expected {}",
                qe.len(),
                et.len()
            ));
        }
        if finest && et.is_empty() && !offsets.is_empty() {
            return Err(format!("level {l} has similarity sets but no et/qe tables"));
        }

        levels.push(LevelData {
            spacing,
            margin,
            et,
            proj,
            qe,
            shift,
            offsets,
            residual_variance,
            runtime_residual_variance,
        });
    }

    let appearance = match r.u8("appearance space")? {
        0 => AppearanceSpace::Neighborhood,
        1 => AppearanceSpace::Color,
        a => return Err(format!("appearance space is {a}, expected 0 or 1")),
    };
    let has_feature = r.u8("feature flag")?;
    let (weight, clamp, coverage) = (
        r.f32("feature weight")?,
        r.f32("feature clamp")?,
        r.f32("feature coverage")?,
    );
    let feature = match has_feature {
        0 => {
            if (weight, clamp, coverage) != (0.0, 0.0, 0.0) {
                return Err("feature settings are present but no feature mask is flagged".into());
            }
            None
        }
        1..=3 => {
            if !(weight.is_finite() && (0.0..=MAX_FEATURE_WEIGHT).contains(&weight)) {
                return Err(format!(
                    "feature weight is {weight}, expected 0..={MAX_FEATURE_WEIGHT}"
                ));
            }
            if !(clamp.is_finite() && FEATURE_CLAMP_RANGE.contains(&clamp)) {
                return Err(format!(
                    "feature clamp is {clamp}, expected {}..={}",
                    FEATURE_CLAMP_RANGE.start(),
                    FEATURE_CLAMP_RANGE.end()
                ));
            }
            if !(0.0..=1.0).contains(&coverage) {
                return Err(format!("feature coverage is {coverage}, expected 0..=1"));
            }
            Some(FeatureInfo {
                weight,
                clamp,
                coverage,
                mode: match has_feature {
                    1 => FeatureMode::Appearance,
                    2 => FeatureMode::Sets,
                    _ => FeatureMode::Both,
                },
            })
        }
        f => return Err(format!("feature flag is {f}, expected 0, 1, 2 or 3")),
    };

    if r.remaining() != 0 {
        return Err(format!(
            "{} unexpected bytes after the appearance settings",
            r.remaining()
        ));
    }

    Ok(Analysis {
        width,
        height,
        channels,
        tileable,
        k,
        colors,
        levels,
        appearance,
        feature,
    })
}

impl Analysis {
    /// Checks that the public fields agree with each other as an analysis file must
    /// (sizes, k, the level pyramid, every table's length): [`Analysis::load`] does it
    /// for files, [`crate::gpu::synth::GpuSynthesizer::new`] and
    /// [`crate::passes::synthesize_cpu`] for analyses built or edited by hand, so those
    /// fail with [`Error::InvalidParameter`] instead of indexing out of bounds later.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(Error::InvalidParameter(format!("analysis: {m}")));
        let (width, height) = (self.width, self.height);
        if !(MIN_SIDE..=MAX_SIDE).contains(&width) || !(MIN_SIDE..=MAX_SIDE).contains(&height) {
            return bad(format!(
                "{width}x{height}: sides must be {MIN_SIDE}..={MAX_SIDE}"
            ));
        }
        if self.channels != 1 && self.channels != 3 {
            return bad(format!("{} channels, expected 1 or 3", self.channels));
        }
        if !(1..=MAX_K).contains(&self.k) {
            return bad(format!("k is {}, expected 1..={MAX_K}", self.k));
        }
        let pixels = width as usize * height as usize;
        if self.colors.len() != pixels {
            return bad(format!("{} colours for {pixels} pixels", self.colors.len()));
        }
        let top = level_count(width, height);
        if self.levels.len() != top as usize + 1 {
            return bad(format!(
                "{} levels, expected {} for a {width}x{height} exemplar",
                self.levels.len(),
                top + 1
            ));
        }
        for (l, level) in self.levels.iter().enumerate() {
            let expected_spacing = 1u32 << (top - l as u32);
            if level.spacing != expected_spacing {
                return bad(format!(
                    "level {l} spacing is {}, expected {expected_spacing}",
                    level.spacing
                ));
            }
            if level.margin.saturating_mul(2) >= width.min(height) {
                return bad(format!("level {l} margin {} is too large", level.margin));
            }
            if level.shift >= 32 {
                return bad(format!("level {l} shift is {}, expected < 32", level.shift));
            }
            let offsets = pixels * (self.k as usize - 1);
            // The finest level's sets may be left out (AnalysisOptions::finest_sets), and
            // with them its tables; level 0 never has tables (LevelData::et).
            let finest = l + 1 == self.levels.len();
            let tables = if level.et.is_empty() && (l == 0 || finest) {
                0
            } else {
                pixels
            };
            for (name, len, expected) in [
                ("et", level.et.len(), tables),
                ("qe", level.qe.len(), tables),
                ("offsets", level.offsets.len(), offsets),
            ] {
                if len != expected && !(finest && name == "offsets" && len == 0) {
                    return bad(format!(
                        "level {l} {name} has {len} entries, expected {expected}"
                    ));
                }
            }
            // A finest level without tables cannot have sets: they serve its correction.
            if finest && tables == 0 && !level.offsets.is_empty() {
                return bad(format!("level {l} has similarity sets but no et/qe tables"));
            }
        }
        Ok(())
    }
}

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
