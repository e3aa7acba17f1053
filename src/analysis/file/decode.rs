//! Reading an analysis file: from memory or streamed from disk, every value checked
//! before anything is allocated.

use super::*;

impl Analysis {
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
