//! The analysis file format: round trip, and clean errors (no panic, no huge
//! allocation) for every kind of damaged or crafted file. The `Analysis` is built by hand,
//! independent of the analysis computation.

mod common;
use common::TempDir;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::path::{Path, PathBuf};

use texsyn::analysis::file::FORMAT_VERSION;
use texsyn::analysis::{
    level_count, level_margin, Analysis, AppearanceSpace, FeatureInfo, FeatureMode, LevelData, DIM,
    MAX_K,
};
use texsyn::Error;

// ---- allocation tracking: the largest single allocation made by this thread ----------

struct Tracking;

thread_local! {
    static LARGEST: Cell<usize> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for Tracking {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = LARGEST.try_with(|m| m.set(m.get().max(layout.size())));
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let _ = LARGEST.try_with(|m| m.set(m.get().max(new_size)));
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Tracking = Tracking;

/// Runs `f` and returns its result with the largest single allocation it made.
fn largest_alloc<T>(f: impl FnOnce() -> T) -> (T, usize) {
    LARGEST.with(|m| m.set(0));
    let r = f();
    (r, LARGEST.with(|m| m.get()))
}

// ---- helpers ----------------------------------------------------------------------------

const HEADER_LEN: usize = 20;

struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> u32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 33) as u32
    }
    fn i16(&mut self) -> i16 {
        self.next() as u16 as i16
    }
}

fn synthetic(width: u32, height: u32, k: u32, tileable: bool, seed: u64) -> Analysis {
    let mut rng = Lcg(seed);
    let n = (width * height) as usize;
    let top = level_count(width, height);
    let colors = (0..n)
        .map(|_| {
            let v = rng.next().to_le_bytes();
            [v[0], v[1], v[2], 255]
        })
        .collect();
    let levels = (0..=top)
        .map(|l| {
            let spacing = 1u32 << (top - l);
            let mut proj = [[0i16; 4 * DIM]; DIM];
            for row in proj.iter_mut() {
                for v in row.iter_mut() {
                    *v = rng.i16();
                }
            }
            LevelData {
                spacing,
                margin: level_margin(width, height, spacing, tileable),
                et: (0..n).map(|_| std::array::from_fn(|_| rng.i16())).collect(),
                proj,
                qe: (0..n).map(|_| std::array::from_fn(|_| rng.i16())).collect(),
                shift: rng.next() % 32,
                offsets: (0..n * (k as usize - 1))
                    .map(|_| [rng.i16() % 16, rng.i16() % 16])
                    .collect(),
                residual_variance: (rng.next() % 1000) as f32 / 1000.0,
                runtime_residual_variance: (rng.next() % 1000) as f32 / 997.0,
            }
        })
        .collect();
    Analysis {
        width,
        height,
        channels: 3,
        tileable,
        k,
        colors,
        levels,
        appearance: if seed.is_multiple_of(2) {
            AppearanceSpace::Neighborhood
        } else {
            AppearanceSpace::Color
        },
        feature: seed.is_multiple_of(3).then_some(FeatureInfo {
            weight: 1.5,
            clamp: 8.0,
            coverage: 0.25,
            // Every mode round-trips (file flags 1, 2 and 3).
            mode: match seed % 9 {
                0 => FeatureMode::Both,
                3 => FeatureMode::Appearance,
                _ => FeatureMode::Sets,
            },
        }),
    }
}

/// The file's checksum, written from the format's description (src/analysis/file.rs):
/// FNV-1a 64 in four lanes of little-endian u64 words, a byte-wise tail, then byte-wise
/// FNV-1a over the lanes' and the tail's bytes.
fn checksum(bytes: &[u8]) -> u64 {
    const OFFSET: u64 = 0xcbf29ce484222325;
    const PRIME: u64 = 0x100000001b3;
    let bytewise = |mut h: u64, b: &[u8]| {
        for &x in b {
            h = (h ^ x as u64).wrapping_mul(PRIME);
        }
        h
    };
    let whole = bytes.len() / 32 * 32;
    let mut lanes = [OFFSET; 4];
    for (i, w) in bytes[..whole].chunks_exact(8).enumerate() {
        let w = u64::from_le_bytes(w.try_into().unwrap());
        lanes[i % 4] = (lanes[i % 4] ^ w).wrapping_mul(PRIME);
    }
    let tail = bytewise(OFFSET, &bytes[whole..]);
    let mut h = OFFSET;
    for v in lanes.iter().chain([&tail]) {
        h = bytewise(h, &v.to_le_bytes());
    }
    h
}

/// Wraps a payload into a complete file with a valid header and checksum.
fn wrap(payload: &[u8]) -> Vec<u8> {
    let mut v = b"TEXSYNA\0".to_vec();
    v.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    v.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    v.extend_from_slice(payload);
    v.extend_from_slice(&checksum(payload).to_le_bytes());
    v
}

fn payload_of(bytes: &[u8]) -> &[u8] {
    &bytes[HEADER_LEN..bytes.len() - 8]
}

fn p() -> PathBuf {
    PathBuf::from("test.tsa")
}

/// Decodes and expects `BadAnalysisFile` whose reason contains every one of `needles`;
/// also checks that decoding allocated at most `max_alloc` bytes at once.
fn expect_bad(bytes: &[u8], needles: &[&str], max_alloc: usize) -> String {
    let (r, largest) = largest_alloc(|| Analysis::from_bytes(bytes, &p()));
    let reason = match r {
        Err(Error::BadAnalysisFile { path, reason }) => {
            assert_eq!(path, p());
            reason
        }
        Err(e) => panic!("expected BadAnalysisFile, got {e:?}"),
        Ok(_) => panic!("expected an error for {needles:?}, decoding succeeded"),
    };
    for n in needles {
        assert!(reason.contains(n), "reason {reason:?} lacks {n:?}");
    }
    assert!(
        largest <= max_alloc,
        "decoding allocated {largest} bytes at once for {reason:?}"
    );
    // The same bytes as a file, through both file readers: the same error. `load`
    // streams well-formed files and falls back to the in-memory decoder for anything
    // else, so it may allocate at most the file and its read buffer on top;
    // `load_mapped` reads the file in place, no copy of it.
    let dir = TempDir::new("bad");
    let path = dir.root().join("bad.tsa");
    std::fs::write(&path, bytes).unwrap();
    type Loader = fn(&Path) -> Result<Analysis, Error>;
    // SAFETY: the file is this test's own and stays as it is.
    let mapped: Loader = |p| unsafe { Analysis::load_mapped(p) };
    let readers: [(&str, Loader, usize); 2] = [
        (
            "load",
            Analysis::load,
            max_alloc.max(bytes.len()) + (1 << 16) + 4096,
        ),
        ("load_mapped", mapped, max_alloc + 4096),
    ];
    for (name, load, limit) in readers {
        let (r, largest) = largest_alloc(|| load(&path));
        match r {
            Err(Error::BadAnalysisFile {
                path: at,
                reason: r,
            }) => {
                assert_eq!(at, path);
                assert_eq!(r, reason, "{name} and from_bytes disagree");
            }
            other => panic!("{name}: expected BadAnalysisFile, got {other:?}"),
        }
        assert!(
            largest <= limit,
            "{name} allocated {largest} bytes at once for {reason:?}"
        );
    }
    reason
}

// ---- tests ------------------------------------------------------------------------------

#[test]
fn round_trip_bytes_and_struct() {
    for (w, h, k, tileable) in [(16, 16, 3, false), (16, 16, 1, true), (40, 17, 2, false)] {
        let a = synthetic(w, h, k, tileable, 7 + w as u64);
        if w == 16 {
            assert_eq!(a.levels.len(), 5);
        }
        let bytes = a.to_bytes();
        assert_eq!(&bytes[..8], b"TEXSYNA\0");
        assert_eq!(u32::from_le_bytes(bytes[8..12].try_into().unwrap()), 4);
        let plen = u64::from_le_bytes(bytes[12..20].try_into().unwrap());
        assert_eq!(plen as usize + HEADER_LEN + 8, bytes.len());
        // The checksum is the documented one (the writer hashes in chunks of its own).
        let stored = u64::from_le_bytes(bytes[bytes.len() - 8..].try_into().unwrap());
        assert_eq!(stored, checksum(payload_of(&bytes)));
        let b = Analysis::from_bytes(&bytes, &p()).unwrap();
        assert_eq!(a, b);
        assert_eq!(b.to_bytes(), bytes);
    }
}

/// Every table starts at a multiple of 16 bytes from the start of the file, after zero
/// padding; a non-zero padding byte is an error, with the checksum right.
#[test]
fn tables_are_aligned_and_their_padding_checked() {
    let a = synthetic(40, 17, 3, false, 11);
    let bytes = a.to_bytes();
    // Walk the layout (module docs of src/analysis/file.rs) and check each table's start.
    let payload = payload_of(&bytes);
    let u64_at = |i: usize| u64::from_le_bytes(payload[i..i + 8].try_into().unwrap());
    let mut at = 17 + 8 + 40 * 17 * 4 + 4;
    let mut pads = Vec::new();
    for lv in &a.levels {
        at += 5 * 4 + 2 * 4 * DIM * DIM;
        for (n, size) in [
            (lv.et.len(), 2 * DIM),
            (lv.qe.len(), 2 * DIM),
            (lv.offsets.len(), 4),
        ] {
            assert_eq!(u64_at(at), n as u64);
            at += 8;
            let pad = (16 - (HEADER_LEN + at) % 16) % 16;
            assert!(payload[at..at + pad].iter().all(|&b| b == 0));
            pads.push((at, pad));
            at += pad;
            assert_eq!((HEADER_LEN + at) % 16, 0);
            at += n * size;
        }
    }
    assert_eq!(at + 2 + 12, payload.len());
    // A padding byte set, the checksum recomputed: refused, by every reader.
    let &(pad_at, _) = pads.iter().find(|(_, pad)| *pad > 0).unwrap();
    let mut pl = payload.to_vec();
    pl[pad_at] = 1;
    expect_bad(
        &wrap(&pl),
        &["level 0 et: the padding before its values is not zero"],
        1 << 16,
    );
}

/// `load_mapped`: the same analysis as `load`, its tables views of the file; changing a
/// table copies it; replacing the file (as `save` does) leaves a mapped analysis intact.
#[test]
fn mapped_load_uses_the_file_in_place() {
    let dir = TempDir::new("mapped");
    let path = dir.root().join("a.tsa");
    let a = synthetic(40, 17, 3, false, 12);
    a.save(&path).unwrap();
    // SAFETY: the file is only replaced by `save` (a rename) below, never truncated.
    let m = unsafe { Analysis::load_mapped(&path) }.unwrap();
    assert_eq!(m, a);
    assert_eq!(m, Analysis::load(&path).unwrap());
    for lv in &m.levels {
        for (mapped, len) in [
            (lv.et.is_mapped(), lv.et.len()),
            (lv.qe.is_mapped(), lv.qe.len()),
            (lv.offsets.is_mapped(), lv.offsets.len()),
        ] {
            assert_eq!(mapped, len > 0, "a table of {len} values");
        }
    }
    assert_eq!(m.to_bytes(), a.to_bytes());
    // A change copies the table: the clone and the file keep their values.
    let mut changed = m.clone();
    assert!(changed.levels[2].et.is_mapped());
    changed.levels[2].et[5][3] ^= 0x155;
    assert!(!changed.levels[2].et.is_mapped() && m.levels[2].et.is_mapped());
    assert_ne!(changed, m);
    assert_eq!(m, a);
    assert_eq!(std::fs::read(&path).unwrap(), a.to_bytes());
    // The file replaced by another analysis: the mapped one still reads the old file.
    let b = synthetic(40, 17, 3, false, 13);
    b.save(&path).unwrap();
    assert_eq!(m, a);
    assert_eq!(Analysis::load(&path).unwrap(), b);
    // Empty and missing files: the errors `load` gives.
    let empty = dir.root().join("empty.tsa");
    std::fs::write(&empty, b"").unwrap();
    // SAFETY: as above.
    match unsafe { Analysis::load_mapped(&empty) } {
        Err(Error::BadAnalysisFile { reason, .. }) => assert!(reason.contains("empty"), "{reason}"),
        other => panic!("expected BadAnalysisFile, got {other:?}"),
    }
    // SAFETY: as above.
    match unsafe { Analysis::load_mapped(&dir.root().join("missing.tsa")) } {
        Err(Error::Io { .. }) => {}
        other => panic!("expected Io, got {other:?}"),
    }
}

#[test]
fn save_load_round_trip_and_overwrite() {
    let dir = TempDir::new("saveload");
    let path = dir.root().join("a.tsa");
    let a = synthetic(16, 16, 2, false, 1);
    a.save(&path).unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), a.to_bytes());
    assert_eq!(Analysis::load(&path).unwrap(), a);
    // Overwrite with a different analysis.
    let b = synthetic(20, 16, 3, true, 2);
    b.save(&path).unwrap();
    assert_eq!(Analysis::load(&path).unwrap(), b);
    // Only the file itself is in the directory: no temporary left behind.
    let names: Vec<_> = std::fs::read_dir(dir.root())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, vec![std::ffi::OsString::from("a.tsa")]);
    // Every feature mode survives the file (flags 1, 2 and 3).
    for (seed, mode) in [
        (3, FeatureMode::Appearance),
        (6, FeatureMode::Sets),
        (9, FeatureMode::Both),
    ] {
        let c = synthetic(16, 16, 2, false, seed);
        assert_eq!(c.feature.map(|f| f.mode), Some(mode));
        c.save(&path).unwrap();
        assert_eq!(Analysis::load(&path).unwrap(), c);
    }
}

#[test]
fn save_to_missing_directory_is_write_error() {
    let dir = TempDir::new("savemissing");
    let path = dir.root().join("nope").join("a.tsa");
    let a = synthetic(16, 16, 2, false, 1);
    match a.save(&path) {
        Err(Error::Write { path: p, .. }) => assert_eq!(p, path),
        other => panic!("expected Write error, got {other:?}"),
    }
    assert!(!path.exists());
}

#[test]
fn truncated_at_many_lengths() {
    let bytes = synthetic(16, 16, 2, false, 3).to_bytes();
    let total = bytes.len();
    for len in [1, 4, 7] {
        expect_bad(&bytes[..len], &["truncated", "texsyn analyze"], 4096);
    }
    for len in [8, 11, 12, 19] {
        expect_bad(
            &bytes[..len],
            &[
                "truncated: expected at least 28 bytes",
                &format!("found {len}"),
            ],
            4096,
        );
    }
    for len in [20, 21, 100, total / 2, total - 9, total - 8, total - 1] {
        expect_bad(
            &bytes[..len],
            &[
                &format!("truncated: expected {total} bytes, found {len}"),
                "texsyn analyze",
            ],
            4096,
        );
    }
    // One byte too many is not accepted either.
    let mut long = bytes.clone();
    long.push(0);
    expect_bad(&long, &["trailing data"], 4096);
}

#[test]
fn bad_magic() {
    let mut bytes = synthetic(16, 16, 2, false, 4).to_bytes();
    bytes[0] = b'X';
    expect_bad(&bytes, &["not a texsyn analysis file (bad magic)"], 4096);
    expect_bad(
        b"\x89PNG\r\n\x1a\n rest of a png",
        &["not a texsyn analysis file (bad magic)"],
        4096,
    );
    expect_bad(b"hello", &["bad magic"], 4096);
}

#[test]
fn wrong_version() {
    let mut bytes = synthetic(16, 16, 2, false, 5).to_bytes();
    bytes[8..12].copy_from_slice(&7u32.to_le_bytes());
    expect_bad(
        &bytes,
        &[
            "analysis file version 7 is not supported by this texsyn (expects 4)",
            "re-run `texsyn analyze`",
        ],
        4096,
    );
    // The version is reported even when the rest of the file has another layout.
    expect_bad(
        b"TEXSYNA\0\x05\0\0\0",
        &["version 5 is not supported"],
        4096,
    );
    // Files of the previous layouts (version 1, without the appearance settings;
    // version 2, with the byte-wise checksum; version 3, without the tables' padding).
    for v in 1..=3u8 {
        expect_bad(
            &[b"TEXSYNA\0".as_slice(), &[v, 0, 0, 0]].concat(),
            &[
                &format!("version {v} is not supported"),
                "expects 4",
                "re-run `texsyn analyze`",
            ],
            4096,
        );
    }
}

#[test]
fn flipped_byte_is_checksum_error() {
    let bytes = synthetic(16, 16, 2, false, 6).to_bytes();
    for pos in [
        HEADER_LEN,
        HEADER_LEN + 1000,
        bytes.len() - 9,
        bytes.len() - 1,
    ] {
        let mut b = bytes.clone();
        b[pos] ^= 0x10;
        expect_bad(
            &b,
            &["checksum mismatch: the file is corrupt; re-run `texsyn analyze`"],
            4096,
        );
    }
}

#[test]
fn empty_and_missing_files() {
    let dir = TempDir::new("emptymissing");
    let empty = dir.root().join("empty.tsa");
    std::fs::write(&empty, b"").unwrap();
    match Analysis::load(&empty) {
        Err(Error::BadAnalysisFile { path, reason }) => {
            assert_eq!(path, empty);
            assert!(reason.contains("empty"), "{reason}");
        }
        other => panic!("expected BadAnalysisFile, got {other:?}"),
    }
    let missing = dir.root().join("missing.tsa");
    match Analysis::load(&missing) {
        Err(Error::Io { path, source }) => {
            assert_eq!(path, missing);
            assert_eq!(source.kind(), std::io::ErrorKind::NotFound);
        }
        other => panic!("expected Io, got {other:?}"),
    }
}

/// Files with a valid header and checksum but absurd content: rejected before any large
/// allocation.
#[test]
fn crafted_absurd_lengths() {
    const LIMIT: usize = 1 << 16;
    let le32 = |v: u32| v.to_le_bytes();

    // Huge but in-range size, colour count matching it, no data behind it.
    let mut pl = Vec::new();
    for v in [65536u32, 65536, 3] {
        pl.extend_from_slice(&le32(v));
    }
    pl.push(0);
    pl.extend_from_slice(&le32(8));
    pl.extend_from_slice(&(65536u64 * 65536).to_le_bytes());
    expect_bad(
        &wrap(&pl),
        &["colors needs", "bytes but the payload has only 0 left"],
        LIMIT,
    );

    // Colour count that overflows when multiplied by the element size.
    let mut pl2 = pl[..17].to_vec();
    pl2.extend_from_slice(&u64::MAX.to_le_bytes());
    expect_bad(
        &wrap(&pl2),
        &["colors has 18446744073709551615 entries"],
        LIMIT,
    );

    // Absurd sizes.
    for (w, h) in [(u32::MAX, 16), (16, 0), (15, 16), (65537, 16)] {
        let mut pl = Vec::new();
        for v in [w, h, 3, 0] {
            pl.extend_from_slice(&le32(v));
        }
        expect_bad(&wrap(&pl), &["outside 16..=65536"], LIMIT);
    }

    // Absurd payload length in the header.
    let mut b = b"TEXSYNA\0".to_vec();
    b.extend_from_slice(&le32(FORMAT_VERSION));
    b.extend_from_slice(&u64::MAX.to_le_bytes());
    b.extend_from_slice(&[0; 8]);
    expect_bad(&b, &["texsyn analyze"], LIMIT);
    let mut b = b"TEXSYNA\0".to_vec();
    b.extend_from_slice(&le32(FORMAT_VERSION));
    b.extend_from_slice(&(1u64 << 40).to_le_bytes());
    b.extend_from_slice(&[0; 8]);
    expect_bad(
        &b,
        &["truncated: expected 1099511627804 bytes, found 28"],
        LIMIT,
    );

    // A valid beginning, then a level whose `et` count is huge.
    let a = synthetic(16, 16, 2, false, 9);
    let good = a.to_bytes();
    let payload = payload_of(&good);
    // width, height, channels, tileable, k, n_colors, colors, n_levels, then level 0:
    // spacing, margin, shift, 2 f32, proj, n_et.
    let n_et_at = 17 + 8 + 16 * 16 * 4 + 4 + 5 * 4 + 2 * 4 * DIM * DIM;
    assert_eq!(
        u64::from_le_bytes(payload[n_et_at..n_et_at + 8].try_into().unwrap()),
        256
    );
    for n in [257u64, 1 << 40, u64::MAX] {
        let mut pl = payload.to_vec();
        pl[n_et_at..n_et_at + 8].copy_from_slice(&n.to_le_bytes());
        expect_bad(
            &wrap(&pl),
            &["level 0 et has", "entries, expected 256"],
            LIMIT,
        );
    }
    // Payload cut right after a count: the elements are missing.
    let cut = &payload[..n_et_at + 8 + 10];
    expect_bad(&wrap(cut), &["level 0 et needs 256 x 16 bytes"], LIMIT);
    // Extra bytes at the end of the payload.
    let mut pl = payload.to_vec();
    pl.extend_from_slice(&[0; 3]);
    expect_bad(&wrap(&pl), &["3 unexpected bytes"], 1 << 20);
}

/// Decoded values that the synthesis would choke on: each rejected with a message.
#[test]
fn crafted_invalid_values() {
    let base = synthetic(16, 16, 2, false, 10);
    let check = |a: Analysis, needle: &str| {
        expect_bad(&a.to_bytes(), &[needle, "re-run `texsyn analyze`"], 1 << 20);
    };

    let mut a = base.clone();
    a.channels = 2;
    check(a, "channels is 2, expected 1 or 3");

    let mut a = base.clone();
    a.k = 0;
    check(a, "k is 0, expected 1..=8");

    let mut a = synthetic(16, 16, MAX_K + 1, false, 11);
    a.k = MAX_K + 1;
    check(a, "k is 9");

    let mut a = base.clone();
    a.levels.pop();
    check(a, "level count is 4, expected 5");

    let mut a = base.clone();
    a.levels[2].spacing = 3;
    check(a, "level 2 spacing is 3, expected 4");

    let mut a = base.clone();
    a.levels[1].shift = 32;
    check(a, "level 1 shift is 32, expected < 32");

    let mut a = base.clone();
    a.levels[0].margin = 8;
    check(a, "level 0 margin 8 leaves no valid region");

    let mut a = base.clone();
    a.colors.pop();
    check(a, "colors has 255 entries, expected 256");

    let mut a = base.clone();
    a.levels[3].qe.to_mut().push([0; DIM]);
    check(a, "level 3 qe has 257 entries");

    // Only the finest level (4 here) may go without its similarity sets.
    let mut a = base.clone();
    a.levels[3].offsets = Default::default();
    check(a, "level 3 offsets has 0 entries, expected 256");
    let mut a = base.clone();
    a.levels[4].offsets.to_mut().truncate(1);
    check(a, "level 4 offsets has 1 entries, expected 256");
    let mut a = base.clone();
    a.levels[4].offsets = Default::default();
    let back = Analysis::from_bytes(&a.to_bytes(), Path::new("lean.tsa")).unwrap();
    assert!(!back.has_finest_sets() && back == a);
    // Without its sets the finest level may go without its et/qe tables too, and level
    // 0 (never corrected) may go without them always; other levels, never.
    a.levels[4].et = Default::default();
    a.levels[4].qe = Default::default();
    a.levels[0].et = Default::default();
    a.levels[0].qe = Default::default();
    let back = Analysis::from_bytes(&a.to_bytes(), Path::new("lean.tsa")).unwrap();
    assert!(!back.has_tables(4) && !back.has_tables(0) && back.has_tables(1) && back == a);
    let mut b = a.clone();
    b.levels[0].qe = base.levels[0].qe.clone();
    check(b, "level 0 qe has 256 entries, expected 0");
    let mut b = a.clone();
    b.levels[4].offsets = base.levels[4].offsets.clone();
    check(b, "level 4 has similarity sets but no et/qe tables");
    let mut b = base.clone();
    b.levels[2].et = Default::default();
    b.levels[2].qe = Default::default();
    check(b, "level 2 et has 0 entries, expected 256");

    // Tileable flag other than 0/1.
    let bytes = base.to_bytes();
    let mut pl = payload_of(&bytes).to_vec();
    pl[12] = 2;
    expect_bad(&wrap(&pl), &["tileable flag is 2"], 1 << 20);

    // Appearance settings (the last 14 bytes: space, flag, weight, clamp, coverage).
    let at = pl.len() - 14;
    let mut p2 = payload_of(&bytes).to_vec();
    p2[at] = 2;
    expect_bad(&wrap(&p2), &["appearance space is 2"], 1 << 20);
    let mut p2 = payload_of(&bytes).to_vec();
    p2[at + 1] = 5;
    expect_bad(
        &wrap(&p2),
        &["feature flag is 5, expected 0, 1, 2 or 3"],
        1 << 20,
    );
    let mut p2 = payload_of(&bytes).to_vec();
    p2[at + 2..at + 6].copy_from_slice(&1.0f32.to_le_bytes());
    expect_bad(&wrap(&p2), &["no feature mask is flagged"], 1 << 20);
    for (weight, clamp, coverage, needle) in [
        (f32::NAN, 8.0, 0.5, "feature weight is NaN"),
        (-1.0, 8.0, 0.5, "feature weight is -1"),
        (1.0, 0.0, 0.5, "feature clamp is 0"),
        (1.0, 8.0, 1.5, "feature coverage is 1.5"),
    ] {
        let mut a = base.clone();
        a.feature = Some(FeatureInfo {
            weight,
            clamp,
            coverage,
            mode: FeatureMode::Sets,
        });
        check(a, needle);
    }
}
