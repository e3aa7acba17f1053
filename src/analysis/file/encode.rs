//! Writing an analysis file: the payload, its padding and checksum.

use super::*;

/// Buffers small writes, hashes everything, forwards to `W` in large chunks.
pub(super) struct PayloadWriter<'a, W: Write> {
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
}
