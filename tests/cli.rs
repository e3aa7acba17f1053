//! The `texsyn` binary end to end: synth / analyze / eval on the bundled exemplar, and
//! every kind of bad input exiting non-zero with a message and no output file. Needs a
//! GPU adapter (lavapipe in CI). Sizes are small so the file runs in seconds.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::atomic::{AtomicU32, Ordering};

const BIN: &str = env!("CARGO_BIN_EXE_texsyn");
const GRAVEL: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/gravel.png");

/// A fresh directory under the system temp dir, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> Self {
        static COUNTER: AtomicU32 = AtomicU32::new(0);
        let dir = std::env::temp_dir().join(format!(
            "texsyn-cli-test-{}-{}-{name}",
            std::process::id(),
            COUNTER.fetch_add(1, Ordering::Relaxed)
        ));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }

    fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }

    /// Names of the files in the directory, sorted.
    fn files(&self) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(&self.0)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Runs `texsyn args...` in `dir`.
fn texsyn(dir: &TempDir, args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .current_dir(&dir.0)
        .output()
        .expect("cannot run the texsyn binary")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// Runs and asserts success; returns stdout.
fn ok(dir: &TempDir, args: &[&str]) -> String {
    let out = texsyn(dir, args);
    assert!(
        out.status.success(),
        "texsyn {args:?} failed ({:?}):\n{}",
        out.status,
        text(&out.stderr)
    );
    text(&out.stdout)
}

/// Runs, asserts failure with exit code `code` and a stderr line `error: ...` containing
/// `needle` (case-insensitive), and that the directory holds exactly `files_before`
/// afterwards (no output, no temporary file).
fn fails(dir: &TempDir, args: &[&str], code: i32, needle: &str) {
    let before = dir.files();
    let out = texsyn(dir, args);
    let stderr = text(&out.stderr);
    assert_eq!(
        out.status.code(),
        Some(code),
        "texsyn {args:?}: stderr:\n{stderr}"
    );
    let error_line = stderr
        .lines()
        .find(|l| l.starts_with("error: ") && l.to_lowercase().contains(&needle.to_lowercase()));
    assert!(
        error_line.is_some(),
        "texsyn {args:?}: no `error: ...{needle}...` line in stderr:\n{stderr}"
    );
    assert!(
        !stderr.contains("panicked"),
        "texsyn {args:?} panicked:\n{stderr}"
    );
    assert_eq!(dir.files(), before, "texsyn {args:?} left files behind");
}

fn png_size(path: &Path) -> (u32, u32) {
    let img = image::open(path)
        .unwrap_or_else(|e| panic!("{} is not a readable image: {e}", path.display()));
    (img.width(), img.height())
}

#[test]
fn synth_analyze_and_eval() {
    let dir = TempDir::new("main");
    let read = |name: &str| std::fs::read(dir.path(name)).unwrap();

    // Happy path from the image.
    ok(
        &dir,
        &[
            "synth", GRAVEL, "-o", "out.png", "--size", "64", "--seed", "3",
        ],
    );
    assert_eq!(png_size(&dir.path("out.png")), (64, 64));
    assert!(read("out.png").starts_with(b"\x89PNG"));

    // analyze, with its summary.
    let out = texsyn(&dir, &["analyze", GRAVEL, "-o", "gravel.tsa"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let stderr = text(&out.stderr);
    for needle in [
        "analysing level 8/8",
        "128x128",
        "tileable: no (detected)",
        "levels: 8",
        "residual variance",
    ] {
        assert!(
            stderr.contains(needle),
            "analyze summary lacks {needle:?}:\n{stderr}"
        );
    }
    assert!(read("gravel.tsa").starts_with(b"TEXSYNA\0"));

    // From the analysis file: the same bytes as from the image.
    ok(
        &dir,
        &[
            "synth",
            "gravel.tsa",
            "-o",
            "from_file.png",
            "--size",
            "64",
            "--seed",
            "3",
        ],
    );
    assert_eq!(
        read("from_file.png"),
        read("out.png"),
        "analysis file and image give different outputs"
    );

    // Same seed twice: identical; another seed: different.
    ok(
        &dir,
        &[
            "synth",
            "gravel.tsa",
            "-o",
            "again.png",
            "--size",
            "64",
            "--seed",
            "3",
        ],
    );
    assert_eq!(read("again.png"), read("out.png"));
    ok(
        &dir,
        &[
            "synth",
            "gravel.tsa",
            "-o",
            "seed4.png",
            "--size",
            "64",
            "--seed",
            "4",
        ],
    );
    assert_ne!(
        read("seed4.png"),
        read("out.png"),
        "seeds 3 and 4 gave the same texture"
    );

    // Non-square, other options, a negative window, --quiet.
    let out = texsyn(
        &dir,
        &[
            "--quiet",
            "synth",
            "gravel.tsa",
            "-o",
            "opts.png",
            "--size",
            "40x24",
            "--randomness",
            "1,0.5,0.25",
            "--passes",
            "1",
            "--coherence",
            "0.5",
            "--window",
            "-100,37",
            "--k",
            "2",
            "--no-tileable",
        ],
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_eq!(png_size(&dir.path("opts.png")), (40, 24));
    let stderr = text(&out.stderr);
    assert!(
        !stderr.contains("adapter:") && !stderr.contains("time:"),
        "--quiet still printed:\n{stderr}"
    );

    // Windows of one infinite texture agree: the right half of a 64-wide window equals a
    // 32-wide window at x = 32.
    ok(
        &dir,
        &[
            "synth",
            "gravel.tsa",
            "-o",
            "right.png",
            "--size",
            "32x64",
            "--seed",
            "3",
            "--window",
            "32,0",
        ],
    );
    let full = image::open(dir.path("out.png")).unwrap().to_luma8();
    let right = image::open(dir.path("right.png")).unwrap().to_luma8();
    for y in 0..64 {
        for x in 0..32 {
            assert_eq!(
                full.get_pixel(x + 32, y),
                right.get_pixel(x, y),
                "window mismatch at ({x}, {y})"
            );
        }
    }

    // --coords-out: an EXR the library reads back, and the same image.
    ok(
        &dir,
        &[
            "synth",
            "gravel.tsa",
            "-o",
            "with_coords.png",
            "--size",
            "64",
            "--seed",
            "3",
            "--coords-out",
            "coords.exr",
        ],
    );
    assert_eq!(read("with_coords.png"), read("out.png"));
    let (w, h, coords) = texsyn::image_io::load_coords_exr(&dir.path("coords.exr")).unwrap();
    assert_eq!((w, h, coords.len()), (64, 64, 64 * 64));
    assert!(
        coords
            .iter()
            .all(|c| (0..128).contains(&c[0]) && (0..128).contains(&c[1])),
        "coordinates outside the exemplar"
    );

    // eval: JSON with the expected keys; verbatim figures only with --coords.
    let json = ok(&dir, &["eval", GRAVEL, "out.png", "--coords", "coords.exr"]);
    let v = json::parse(json.trim())
        .unwrap_or_else(|e| panic!("eval printed invalid JSON ({e}):\n{json}"));
    for (section, keys) in [
        ("texture_energy", &["full", "half", "quarter"][..]),
        ("texture_energy_any_phase", &["full", "half", "quarter"][..]),
        ("histogram_emd", &["mean"][..]),
        (
            "verbatim",
            &[
                "coherent_fraction",
                "largest_region_fraction",
                "largest_region_pixels",
                "regions",
            ][..],
        ),
    ] {
        for key in keys {
            let n = v
                .get(section)
                .and_then(|s| s.get(key))
                .and_then(json::Value::number);
            assert!(
                n.is_some_and(|n| n.is_finite() && n >= 0.0),
                "eval: {section}.{key} missing or not a number in {json}"
            );
        }
    }
    match v.get("histogram_emd").and_then(|h| h.get("per_channel")) {
        Some(json::Value::Array(a)) => assert!(
            !a.is_empty() && a.iter().all(|x| x.number().is_some()),
            "{json}"
        ),
        other => panic!("histogram_emd.per_channel is {other:?} in {json}"),
    }
    let json = ok(&dir, &["eval", GRAVEL, "seed4.png"]);
    let v = json::parse(json.trim())
        .unwrap_or_else(|e| panic!("eval printed invalid JSON ({e}):\n{json}"));
    assert_eq!(v.get("verbatim"), Some(&json::Value::Null), "{json}");
    assert!(v
        .get("texture_energy")
        .and_then(|s| s.get("full"))
        .and_then(json::Value::number)
        .is_some());

    // eval needs the image, not the analysis file.
    fails(
        &dir,
        &["eval", "gravel.tsa", "out.png"],
        1,
        "eval needs the exemplar image",
    );
    // A coordinate map of another size.
    ok(
        &dir,
        &[
            "synth",
            "gravel.tsa",
            "-o",
            "small.png",
            "--size",
            "32",
            "--coords-out",
            "small.exr",
        ],
    );
    fails(
        &dir,
        &["eval", GRAVEL, "out.png", "--coords", "small.exr"],
        1,
        "is 32x32",
    );
    // A map whose values are not positions in this exemplar.
    let mut far = image::Rgba32FImage::new(64, 64);
    far.put_pixel(5, 6, image::Rgba([1e9, 0.0, 0.0, 1.0]));
    image::DynamicImage::ImageRgba32F(far)
        .save(dir.path("far.exr"))
        .unwrap();
    fails(
        &dir,
        &["eval", GRAVEL, "out.png", "--coords", "far.exr"],
        1,
        "outside the 128x128 exemplar",
    );
    std::fs::remove_file(dir.path("far.exr")).unwrap();

    // Bad analysis files: flipped byte (checksum), wrong version, options that disagree.
    let mut bytes = read("gravel.tsa");
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x5a;
    std::fs::write(dir.path("corrupt.tsa"), &bytes).unwrap();
    fails(
        &dir,
        &["synth", "corrupt.tsa", "-o", "bad.png", "--size", "16"],
        1,
        "corrupt",
    );
    let mut bytes = read("gravel.tsa");
    bytes[8..12].copy_from_slice(&99u32.to_le_bytes());
    std::fs::write(dir.path("version.tsa"), &bytes).unwrap();
    fails(
        &dir,
        &["synth", "version.tsa", "-o", "bad.png", "--size", "16"],
        1,
        "version 99",
    );
    fails(
        &dir,
        &[
            "synth",
            "gravel.tsa",
            "-o",
            "bad.png",
            "--size",
            "16",
            "--k",
            "3",
        ],
        1,
        "does not match the analysis file",
    );
    fails(
        &dir,
        &[
            "synth",
            "gravel.tsa",
            "-o",
            "bad.png",
            "--size",
            "16",
            "--tileable",
        ],
        1,
        "does not match the analysis file",
    );

    // A failed run leaves an existing output untouched.
    let before = read("out.png");
    fails(
        &dir,
        &["synth", "corrupt.tsa", "-o", "out.png", "--size", "16"],
        1,
        "corrupt",
    );
    assert_eq!(read("out.png"), before);
}

#[test]
fn bad_inputs_fail_cleanly() {
    let dir = TempDir::new("bad");
    std::fs::write(dir.path("notes.txt"), "not an image\n").unwrap();
    std::fs::write(dir.path("empty.png"), b"").unwrap();
    image::GrayImage::new(1, 1)
        .save(dir.path("one.png"))
        .unwrap();
    image::GrayImage::new(8, 8)
        .save(dir.path("eight.png"))
        .unwrap();

    let synth = |exemplar: &str, extra: &[&str], code: i32, needle: &str| {
        let mut args = vec!["synth", exemplar, "-o", "out.png"];
        if !extra.contains(&"--size") {
            args.extend(["--size", "32"]);
        }
        args.extend(extra);
        fails(&dir, &args, code, needle);
    };
    synth("missing.png", &[], 1, "missing.png");
    synth("notes.txt", &[], 1, "not a readable image");
    synth("empty.png", &[], 1, "empty");
    synth("one.png", &[], 1, "1x1");
    synth("eight.png", &[], 1, "8x8");
    // The coordinate map is always OpenEXR: another extension would mislabel it.
    synth(
        GRAVEL,
        &["--coords-out", "coords.png"],
        1,
        "give a .exr file",
    );
    // An atlas the device cannot synthesize is refused before the mesh work.
    let bunny = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/meshes/bunny.glb");
    fails(
        &dir,
        &[
            "surface",
            bunny,
            GRAVEL,
            "-o",
            "b.glb",
            "--atlas-size",
            "16384",
        ],
        1,
        "give a smaller --atlas-size",
    );

    // Usage errors (clap: exit code 2).
    synth(GRAVEL, &["--size", "0"], 2, "at least 1");
    synth(GRAVEL, &["--size", "0x5"], 2, "at least 1");
    synth(GRAVEL, &["--size", "big"], 2, "expected N or NxM");
    synth(GRAVEL, &["--size", "4x4x4"], 2, "expected N or NxM");
    synth(GRAVEL, &["--randomness", "2.5"], 2, "between 0 and 2");
    synth(GRAVEL, &["--randomness", "nan"], 2, "between 0 and 2");
    synth(GRAVEL, &["--copy-budget", "1.5"], 2, "between 0 and 1");
    synth(GRAVEL, &["--copy-budget", "-0.1"], 2, "between 0 and 1");
    synth(GRAVEL, &["--copy-budget", "nan"], 2, "between 0 and 1");
    synth(GRAVEL, &["--seed", "4294967296"], 2, "--seed");
    synth(GRAVEL, &["--seed", "x"], 2, "--seed");
    // A negative seed names the range instead of being taken for an unknown flag.
    synth(
        GRAVEL,
        &["--seed", "-1"],
        2,
        "give an integer from 0 to 4294967295",
    );
    synth(GRAVEL, &["--passes", "17"], 2, "--passes");
    synth(
        GRAVEL,
        &["--second-finest-passes", "17"],
        2,
        "--second-finest-passes",
    );
    synth(
        GRAVEL,
        &["--tileable", "--no-tileable"],
        2,
        "cannot be used with",
    );
    fails(
        &dir,
        &["synth", GRAVEL, "--size", "16"],
        2,
        "required arguments",
    );
    fails(&dir, &["frobnicate"], 2, "frobnicate");

    // Output problems are found before any work.
    fails(
        &dir,
        &["synth", GRAVEL, "-o", "no/such/dir/out.png", "--size", "16"],
        1,
        "does not exist",
    );
    fails(
        &dir,
        &["synth", GRAVEL, "-o", "out.xyz", "--size", "16"],
        1,
        "unsupported image extension",
    );
    fails(
        &dir,
        &["analyze", GRAVEL, "-o", "no/such/dir/g.tsa"],
        1,
        "does not exist",
    );
    fails(
        &dir,
        &["analyze", GRAVEL, "-o", "g2.tsa", "--exclusion", "1000"],
        1,
        "use less than 64",
    );

    fails(
        &dir,
        &[
            "synth",
            GRAVEL,
            "-o",
            "out.png",
            "--size",
            "16",
            "--also",
            &format!("{GRAVEL}=./out.png"),
        ],
        1,
        "two outputs",
    );

    // An output that names one of the command's inputs is refused, and the input kept.
    std::fs::copy(GRAVEL, dir.path("ex.png")).unwrap();
    let original = std::fs::read(dir.path("ex.png")).unwrap();
    for args in [
        &["synth", "ex.png", "-o", "./ex.png", "--size", "16"][..],
        &[
            "synth",
            GRAVEL,
            "-o",
            "o.png",
            "--size",
            "16",
            "--also",
            "ex.png=ex.png",
        ],
        &["analyze", "ex.png", "-o", "ex.png"],
        &["eval", GRAVEL, "ex.png", "--energy-map", "ex.png"],
        &[
            "advect", "ex.png", "--flow", "vortex", "--frames", "1", "--size", "16", "-o", "ex.png",
        ],
    ] {
        fails(&dir, args, 1, "an input");
        assert_eq!(
            std::fs::read(dir.path("ex.png")).unwrap(),
            original,
            "{args:?}"
        );
    }
    std::fs::remove_file(dir.path("ex.png")).unwrap();

    // A folder that exists but cannot be written to (/proc refuses new files, even to root).
    if Path::new("/proc").is_dir() {
        fails(
            &dir,
            &[
                "synth",
                GRAVEL,
                "-o",
                "/proc/texsyn-out.png",
                "--size",
                "16",
            ],
            1,
            "does not take new files",
        );
    }

    // Larger than the device allows: in windows up to 16384x16384, beyond that refused;
    // a periodic output cannot be split.
    synth(
        GRAVEL,
        &["--size", "100000x100000"],
        1,
        "assembled in memory",
    );
    synth(
        GRAVEL,
        &["--size", "100000x16", "--tileable-output"],
        1,
        "larger than this device allows",
    );

    // analyze and eval with bad inputs.
    fails(&dir, &["analyze", "eight.png", "-o", "g.tsa"], 1, "8x8");
    fails(
        &dir,
        &["analyze", "missing.png", "-o", "g.tsa"],
        1,
        "missing.png",
    );
    fails(
        &dir,
        &["eval", GRAVEL, "notes.txt"],
        1,
        "not a readable image",
    );
    fails(&dir, &["eval", "one.png", GRAVEL], 1, "1x1");
    fails(
        &dir,
        &["bench", "empty.png", "--sizes", "16", "--runs", "1"],
        1,
        "empty",
    );
    fails(&dir, &["bench", GRAVEL, "--sizes", "0"], 2, "at least 1");
}

#[test]
fn help_for_every_subcommand() {
    let dir = TempDir::new("help");
    let top = ok(&dir, &["--help"]);
    for sub in ["analyze", "synth", "eval", "bench"] {
        assert!(top.contains(sub), "--help does not list {sub}:\n{top}");
        let help = ok(&dir, &[sub, "--help"]);
        assert!(help.contains("Usage: texsyn"), "{sub} --help:\n{help}");
        assert!(
            help.contains("--quiet"),
            "{sub} --help lacks the global --quiet:\n{help}"
        );
    }
    let synth = ok(&dir, &["synth", "--help"]);
    for opt in [
        "--size",
        "--seed",
        "--randomness",
        "--passes",
        "--k",
        "--coherence",
        "--tileable",
        "--no-tileable",
        "--window",
        "--coords-out",
    ] {
        assert!(synth.contains(opt), "synth --help lacks {opt}");
    }
    let bench = ok(&dir, &["bench", "--help"]);
    for opt in ["--sizes", "--runs", "--warmup"] {
        assert!(bench.contains(opt), "bench --help lacks {opt}");
    }
}

#[test]
fn bench_prints_a_table() {
    let dir = TempDir::new("bench");
    let out = texsyn(&dir, &["analyze", GRAVEL, "-o", "g.tsa", "--quiet"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    // A size the device cannot take shows its error in its row, the others still run,
    // and the exit status says the table is incomplete.
    let out = texsyn(
        &dir,
        &[
            "bench",
            "g.tsa",
            "--sizes",
            "16,24x8,100000",
            "--runs",
            "2",
            "--warmup",
            "1",
        ],
    );
    assert_eq!(out.status.code(), Some(1), "{}", text(&out.stderr));
    assert!(
        text(&out.stderr).contains("error: 1 of the sizes failed (100000x100000)"),
        "{}",
        text(&out.stderr)
    );
    let stdout = text(&out.stdout);
    let lines: Vec<&str> = stdout.lines().collect();
    assert!(lines[0].starts_with("adapter: "), "{stdout}");
    let row = |size: &str| {
        lines
            .iter()
            .find(|l| l.split_whitespace().next() == Some(size))
            .unwrap_or_else(|| panic!("no row for {size}:\n{stdout}"))
            .to_string()
    };
    for size in ["16x16", "24x8"] {
        let r = row(size);
        assert!(!r.contains("error"), "{r}");
        assert_eq!(r.split_whitespace().count(), 1 + 2 * 3 + 1 + 2, "row {r:?}");
    }
    assert!(
        row("100000x100000")
            .contains("error: output is 100000x100000, larger than this device allows"),
        "{stdout}"
    );
}

/// Just enough JSON to check `eval`'s output.
mod json {
    #[derive(Debug, PartialEq)]
    pub enum Value {
        Null,
        Bool(bool),
        Number(f64),
        String(String),
        Array(Vec<Value>),
        Object(Vec<(String, Value)>),
    }

    impl Value {
        pub fn get(&self, key: &str) -> Option<&Value> {
            match self {
                Value::Object(m) => m.iter().find(|(k, _)| k == key).map(|(_, v)| v),
                _ => None,
            }
        }
        pub fn number(&self) -> Option<f64> {
            match self {
                Value::Number(n) => Some(*n),
                _ => None,
            }
        }
    }

    pub fn parse(s: &str) -> Result<Value, String> {
        let b = s.as_bytes();
        let mut i = 0;
        let v = value(b, &mut i)?;
        ws(b, &mut i);
        if i != b.len() {
            return Err(format!("trailing characters at {i}"));
        }
        Ok(v)
    }

    fn ws(b: &[u8], i: &mut usize) {
        while *i < b.len() && b[*i].is_ascii_whitespace() {
            *i += 1;
        }
    }

    fn expect(b: &[u8], i: &mut usize, lit: &str) -> Result<(), String> {
        if b[*i..].starts_with(lit.as_bytes()) {
            *i += lit.len();
            Ok(())
        } else {
            Err(format!("expected {lit:?} at {i}"))
        }
    }

    fn value(b: &[u8], i: &mut usize) -> Result<Value, String> {
        ws(b, i);
        match b.get(*i) {
            None => Err("unexpected end".into()),
            Some(b'n') => expect(b, i, "null").map(|_| Value::Null),
            Some(b't') => expect(b, i, "true").map(|_| Value::Bool(true)),
            Some(b'f') => expect(b, i, "false").map(|_| Value::Bool(false)),
            Some(b'"') => string(b, i).map(Value::String),
            Some(b'[') => {
                *i += 1;
                let mut items = Vec::new();
                ws(b, i);
                if b.get(*i) == Some(&b']') {
                    *i += 1;
                    return Ok(Value::Array(items));
                }
                loop {
                    items.push(value(b, i)?);
                    ws(b, i);
                    match b.get(*i) {
                        Some(b',') => *i += 1,
                        Some(b']') => {
                            *i += 1;
                            return Ok(Value::Array(items));
                        }
                        _ => return Err(format!("expected , or ] at {i}")),
                    }
                }
            }
            Some(b'{') => {
                *i += 1;
                let mut members = Vec::new();
                ws(b, i);
                if b.get(*i) == Some(&b'}') {
                    *i += 1;
                    return Ok(Value::Object(members));
                }
                loop {
                    ws(b, i);
                    let k = string(b, i)?;
                    ws(b, i);
                    expect(b, i, ":")?;
                    members.push((k, value(b, i)?));
                    ws(b, i);
                    match b.get(*i) {
                        Some(b',') => *i += 1,
                        Some(b'}') => {
                            *i += 1;
                            return Ok(Value::Object(members));
                        }
                        _ => return Err(format!("expected , or }} at {i}")),
                    }
                }
            }
            Some(_) => {
                let start = *i;
                while *i < b.len()
                    && matches!(b[*i], b'-' | b'+' | b'.' | b'e' | b'E' | b'0'..=b'9')
                {
                    *i += 1;
                }
                let t = std::str::from_utf8(&b[start..*i]).unwrap();
                t.parse::<f64>()
                    .map(Value::Number)
                    .map_err(|_| format!("bad number {t:?} at {start}"))
            }
        }
    }

    fn string(b: &[u8], i: &mut usize) -> Result<String, String> {
        expect(b, i, "\"")?;
        let mut out = String::new();
        while let Some(&c) = b.get(*i) {
            *i += 1;
            match c {
                b'"' => return Ok(out),
                b'\\' => {
                    let e = *b.get(*i).ok_or("unterminated escape")?;
                    *i += 1;
                    out.push(match e {
                        b'n' => '\n',
                        b't' => '\t',
                        b'"' => '"',
                        b'\\' => '\\',
                        b'/' => '/',
                        _ => return Err(format!("unsupported escape at {i}")),
                    });
                }
                c => out.push(c as char),
            }
        }
        Err("unterminated string".into())
    }
}

#[test]
fn controls_end_to_end_and_their_bad_inputs() {
    let dir = TempDir::new("controls");
    // A field image of the wrong size, a NaN EXR field, a material map of the wrong
    // size, and a good map.
    image::RgbImage::new(10, 10)
        .save(dir.path("field10.png"))
        .unwrap();
    let mut nan = image::Rgba32FImage::from_pixel(24, 24, image::Rgba([1.0, 0.0, 0.0, 1.0]));
    nan.put_pixel(3, 4, image::Rgba([f32::NAN, 0.0, 0.0, 1.0]));
    image::DynamicImage::ImageRgba32F(nan)
        .save(dir.path("nan.exr"))
        .unwrap();
    image::GrayImage::new(20, 20)
        .save(dir.path("small_map.png"))
        .unwrap();
    image::GrayImage::from_fn(128, 128, |x, y| {
        image::Luma([((x * 7 + y * 3) % 256) as u8])
    })
    .save(dir.path("height.png"))
    .unwrap();
    ok(&dir, &["analyze", GRAVEL, "-o", "g.tsa"]);
    let said = texsyn(
        &dir,
        &[
            "synth",
            "g.tsa",
            "-o",
            "sa.png",
            "--size",
            "40x30",
            "--standalone",
        ],
    );
    assert!(said.status.success(), "{}", text(&said.stderr));
    assert!(
        text(&said.stderr).contains("seed 1, standalone)"),
        "{}",
        text(&said.stderr)
    );
    assert_eq!(png_size(&dir.path("sa.png")), (40, 30));

    let base = ["synth", GRAVEL, "-o", "out.png", "--size", "24"];
    let with = |extra: &[&str]| -> Vec<String> {
        base.iter().chain(extra).map(|s| s.to_string()).collect()
    };
    let fails_with = |extra: &[&str], code: i32, needle: &str| {
        let args = with(extra);
        let args: Vec<&str> = args.iter().map(|s| s.as_str()).collect();
        fails(&dir, &args, code, needle);
    };
    fails_with(&["--field", "image:field10.png"], 1, "must have that size");
    fails_with(&["--field", "exr:nan.exr"], 1, "NaN");
    fails_with(&["--field", "rotate:abc"], 2, "not a number");
    fails_with(&["--field", "scale:0"], 1, "zero scale");
    fails_with(&["--field", "twirl"], 2, "unknown field");
    fails_with(&["--field", "image:missing.png"], 1, "missing.png");
    fails_with(&["--also", "small_map.png=o.png"], 1, "aligned");
    fails_with(&["--also", "nothing"], 2, "IN=OUT");
    fails_with(&["--magnify", "3"], 2, "2, 4 or 8");
    fails_with(
        &["--tileable-output", "--window", "3,4"],
        2,
        "cannot be used",
    );
    fails_with(&["--standalone", "--window", "3,4"], 2, "cannot be used");
    fails_with(&["--standalone", "--tileable-output"], 2, "cannot be used");
    fails(
        &dir,
        &[
            "synth",
            "g.tsa",
            "-o",
            "out.png",
            "--size",
            "24",
            "--magnify",
            "2",
        ],
        1,
        "analysis file",
    );
    fails(
        &dir,
        &[
            "synth",
            "g.tsa",
            "-o",
            "out.png",
            "--size",
            "24",
            "--appearance",
            "color",
        ],
        1,
        "does not match",
    );
    // A file analysed in colour space synthesizes without repeating --appearance (the
    // flag's default must not be taken for a mismatch), and with a matching one.
    ok(
        &dir,
        &["analyze", GRAVEL, "--appearance", "color", "-o", "c.tsa"],
    );
    ok(&dir, &["synth", "c.tsa", "-o", "c.png", "--size", "24"]);
    ok(
        &dir,
        &[
            "synth",
            "c.tsa",
            "-o",
            "c.png",
            "--size",
            "24",
            "--appearance",
            "color",
        ],
    );
    fails(
        &dir,
        &[
            "synth",
            "c.tsa",
            "-o",
            "c2.png",
            "--size",
            "24",
            "--appearance",
            "neighborhood",
        ],
        1,
        "does not match",
    );
    fails(
        &dir,
        &[
            "synth",
            "g.tsa",
            "-o",
            "out.png",
            "--size",
            "24",
            "--feature-mask",
            "height.png",
        ],
        1,
        "analysis file",
    );

    // The controls work end to end.
    ok(
        &dir,
        &[
            "synth",
            GRAVEL,
            "-o",
            "f.png",
            "--size",
            "40x32",
            "--field",
            "swirl",
            "--also",
            "height.png=h.png",
            "--coords-out",
            "f.exr",
        ],
    );
    assert_eq!(png_size(&dir.path("f.png")), (40, 32));
    assert_eq!(png_size(&dir.path("h.png")), (40, 32));
    let json = ok(
        &dir,
        &[
            "eval", GRAVEL, "f.png", "--coords", "f.exr", "--field", "swirl",
        ],
    );
    assert!(json.contains("\"jacobian\":{"), "{json}");
    ok(
        &dir,
        &[
            "synth",
            GRAVEL,
            "-o",
            "m.png",
            "--size",
            "20",
            "--magnify",
            "2",
            "--coords-out",
            "m.exr",
        ],
    );
    assert_eq!(png_size(&dir.path("m.png")), (40, 40));
    // Magnification with material sets: the maps are full-resolution (the exemplar's
    // size) and come out magnified, with the coordinates of the same synthesis.
    ok(
        &dir,
        &[
            "synth",
            GRAVEL,
            "-o",
            "mm.png",
            "--size",
            "20",
            "--magnify",
            "2",
            "--also",
            "height.png=mh.png",
            "--coords-out",
            "mm.exr",
        ],
    );
    assert_eq!(png_size(&dir.path("mm.png")), (40, 40));
    assert_eq!(png_size(&dir.path("mh.png")), (40, 40));
    let same = |a: &str, b: &str| {
        std::fs::read(dir.path(a)).unwrap() == std::fs::read(dir.path(b)).unwrap()
    };
    assert!(same("mm.png", "m.png") && same("mm.exr", "m.exr"));
    // The coordinates of the magnified synthesis: one per pixel before magnification,
    // in the analysed (half-size) exemplar's pixels.
    let (w, h, c) = texsyn::image_io::load_coords_exr_f32(&dir.path("m.exr")).unwrap();
    assert_eq!((w, h), (20, 20));
    assert!(c
        .iter()
        .all(|v| v[0] >= -1.0 && v[0] <= 65.0 && v[1] >= -1.0 && v[1] <= 65.0));
    ok(
        &dir,
        &[
            "synth",
            GRAVEL,
            "-o",
            "t.png",
            "--size",
            "30",
            "--tileable-output",
        ],
    );
    let json = ok(&dir, &["eval", GRAVEL, "t.png"]);
    assert!(json.contains("\"wrap_seam_ratio\":"), "{json}");
}

/// Defects found by a bad-input review (2026-11-24): each must fail cleanly or be
/// handled, leaving nothing behind.
#[test]
fn review_findings_fail_cleanly() {
    let dir = TempDir::new("review");
    // eval --energy-map with a feature mask of the wrong size: no map left behind.
    ok(
        &dir,
        &[
            "synth",
            GRAVEL,
            "-o",
            "s.png",
            "--size",
            "32",
            "--coords-out",
            "s.exr",
            "-q",
        ],
    );
    image::GrayImage::from_pixel(16, 16, image::Luma([255]))
        .save(dir.path("mask16.png"))
        .unwrap();
    fails(
        &dir,
        &[
            "eval",
            GRAVEL,
            "s.png",
            "--coords",
            "s.exr",
            "--feature-mask",
            "mask16.png",
            "--energy-map",
            "em.png",
        ],
        1,
        "16x16",
    );

    // --also keeps a map's alpha channel (here alpha = 100 + x % 7, red = y).
    image::RgbaImage::from_fn(128, 128, |x, y| {
        image::Rgba([y as u8, 0, 0, 100 + (x % 7) as u8])
    })
    .save(dir.path("rgba_map.png"))
    .unwrap();
    ok(
        &dir,
        &[
            "synth",
            GRAVEL,
            "-o",
            "a.png",
            "--size",
            "32",
            "--also",
            "rgba_map.png=a_map.png",
            "-q",
        ],
    );
    let map = image::open(dir.path("a_map.png")).unwrap();
    assert_eq!(map.color(), image::ColorType::Rgba8);
    assert!(map
        .to_rgba8()
        .pixels()
        .all(|p| (100..107).contains(&p.0[3])));

    // An HDR exemplar is refused with what to do; NaN samples name the pixel.
    let hdr = image::Rgb32FImage::from_fn(32, 32, |x, y| image::Rgb([x as f32, y as f32, 0.5]));
    image::DynamicImage::ImageRgb32F(hdr)
        .save(dir.path("hdr.exr"))
        .unwrap();
    fails(
        &dir,
        &["synth", "hdr.exr", "-o", "h.png", "--size", "32"],
        1,
        "tone-map",
    );

    // advect: --field does not apply to a mesh (usage error); bad options are refused
    // before the analysis; a staging folder of a killed run is cleaned up.
    fails(
        &dir,
        &[
            "advect",
            GRAVEL,
            "--flow",
            "vortex",
            "--mesh",
            "m.glb",
            "--field",
            "rotate:30",
            "-o",
            "frames",
        ],
        2,
        "cannot be used with",
    );
    let start = std::time::Instant::now();
    fails(
        &dir,
        &[
            "advect", GRAVEL, "--flow", "vortex", "--levels", "0", "-o", "frames",
        ],
        1,
        "levels",
    );
    assert!(
        start.elapsed().as_secs_f64() < 5.0,
        "checked after the analysis"
    );
    // One level is only the finest, which is upsampled by default: nothing to advect.
    fails(
        &dir,
        &[
            "advect", GRAVEL, "--flow", "vortex", "--levels", "1", "-o", "frames",
        ],
        1,
        "--advect-finest",
    );
    fails(
        &dir,
        &[
            "advect",
            GRAVEL,
            "--flow",
            "vortex",
            "--resynthesize",
            "2",
            "-o",
            "frames",
        ],
        1,
        "at least 4 levels (--levels)",
    );
    // --keep-look remakes the advected levels itself.
    fails(
        &dir,
        &[
            "advect",
            GRAVEL,
            "--flow",
            "vortex",
            "--keep-look",
            "--resynthesize",
            "1",
            "-o",
            "frames",
        ],
        2,
        "cannot be used with",
    );
    fails(
        &dir,
        &[
            "advect",
            GRAVEL,
            "--flow",
            "vortex",
            "--keep-look",
            "--advect-finest",
            "-o",
            "frames",
        ],
        2,
        "cannot be used with",
    );
    // The scheme by default: the look kept (faded over 2 frames) in 2D without a field or
    // with a constant one, the texture carried along a varying field; --carry and
    // --keep-look choose. The default's frames are --keep-look --fade 2's, byte for byte.
    let frames_of = |out: &str, extra: &[&str]| -> (String, Vec<Vec<u8>>) {
        let mut a = vec![
            "advect", GRAVEL, "--flow", "vortex", "--frames", "2", "--size", "24", "-o", out,
        ];
        a.extend_from_slice(extra);
        let o = texsyn(&dir, &a);
        let stderr = text(&o.stderr);
        assert!(o.status.success(), "{a:?}: {stderr}");
        let bytes = (0..=2)
            .map(|t| std::fs::read(dir.path(&format!("{out}/frame_{t:05}.png"))).unwrap())
            .collect();
        let scheme = stderr
            .lines()
            .find(|l| l.starts_with("advection: "))
            .unwrap_or_else(|| panic!("{a:?}: no scheme line: {stderr}"))
            .to_string();
        (scheme, bytes)
    };
    let (auto, auto_frames) = frames_of("auto", &[]);
    assert!(
        auto.contains("keeping the look, renewals faded over 2 frames"),
        "{auto}"
    );
    assert!(auto.contains("the default here"), "{auto}");
    let (asked, asked_frames) = frames_of("asked", &["--keep-look", "--fade", "2"]);
    assert!(
        asked.contains("keeping the look") && !asked.contains("default"),
        "{asked}"
    );
    assert_eq!(auto_frames, asked_frames);
    let (rotated, _) = frames_of("rotated", &["--field", "rotate:30"]);
    assert!(rotated.contains("keeping the look"), "{rotated}");
    let (unfaded, unfaded_frames) = frames_of("unfaded", &["--fade", "0"]);
    assert!(unfaded.contains("renewals not faded"), "{unfaded}");
    assert_eq!(auto_frames[0], unfaded_frames[0]);
    assert_ne!(auto_frames[2], unfaded_frames[2]);
    let (carried, carried_frames) = frames_of("carried", &["--carry"]);
    assert!(
        carried.contains("carrying the texture (the paper's scheme, --carry)"),
        "{carried}"
    );
    assert_ne!(auto_frames[0], carried_frames[0]);
    let (swirl, _) = frames_of("swirl", &["--field", "swirl"]);
    assert!(
        swirl.contains("carrying the texture") && swirl.contains("varying field"),
        "{swirl}"
    );
    let (two, _) = frames_of("two-levels", &["--levels", "2"]);
    assert!(
        two.contains("carrying the texture") && two.contains("--levels below 3"),
        "{two}"
    );
    // Options that act only with another are said to have no effect.
    for (extra, needle) in [
        (
            &["--fade", "0", "--fade-change", "20"][..],
            "--fade-change has no effect",
        ),
        (
            &["--anchor-upsample", "0.3"][..],
            "--anchor-upsample has no effect",
        ),
    ] {
        let mut a = vec![
            "advect", GRAVEL, "--flow", "vortex", "--frames", "1", "--size", "16", "-o", "noted",
        ];
        a.extend_from_slice(extra);
        let o = texsyn(&dir, &a);
        let stderr = text(&o.stderr);
        assert!(o.status.success(), "{a:?}: {stderr}");
        assert!(stderr.contains(needle), "{a:?}: {stderr}");
        std::fs::remove_dir_all(dir.path("noted")).unwrap();
    }
    let (forced, _) = frames_of("forced", &["--field", "swirl", "--keep-look"]);
    assert!(
        forced.contains("renewals faded over 2 frames (--keep-look)"),
        "{forced}"
    );
    fails(
        &dir,
        &[
            "advect",
            GRAVEL,
            "--flow",
            "vortex",
            "--keep-look",
            "--carry",
            "-o",
            "frames",
        ],
        2,
        "cannot be used with",
    );
    fails(
        &dir,
        &[
            "advect",
            GRAVEL,
            "--flow",
            "vortex",
            "--sets-every",
            "0",
            "-o",
            "frames",
        ],
        1,
        "sets every",
    );
    for (spacing, share, needle) in [
        ("65", "0.5", "spacing of 0 (off) to 64"),
        ("4", "1.5", "share of 0 to 1"),
        ("4", "NaN", "share of NaN"),
    ] {
        fails(
            &dir,
            &[
                "advect",
                GRAVEL,
                "--flow",
                "vortex",
                "--anchor",
                spacing,
                "--anchor-upsample",
                share,
                "-o",
                "frames",
            ],
            1,
            needle,
        );
    }
    // PIDs never exceed 2^22 on Linux: this staging folder belongs to no live process.
    std::fs::create_dir(dir.path(".frames.partial-4194305")).unwrap();
    ok(
        &dir,
        &[
            "advect",
            GRAVEL,
            "--flow",
            "uniform:1,0",
            "--frames",
            "2",
            "--size",
            "16",
            "-o",
            "frames",
            "-q",
        ],
    );
    if Path::new("/proc/self").exists() {
        assert!(!dir.path(".frames.partial-4194305").exists());
    }
    assert!(dir.path("frames/frame_00002.png").exists());
    // From 16 frames on, the cost of the later half is reported too (a turning flow makes
    // frames dearer as it breaks the patches up); not for fewer frames.
    for (frames, late) in [("16", true), ("15", false)] {
        let out = texsyn(
            &dir,
            &[
                "advect", GRAVEL, "--flow", "vortex", "--frames", frames, "--size", "16", "-o",
                "late",
            ],
        );
        let stderr = text(&out.stderr);
        assert!(out.status.success(), "{stderr}");
        assert_eq!(
            stderr.contains("the last 8 frames alone:"),
            late,
            "{frames} frames:\n{stderr}"
        );
    }

    // A flow that moves everything out of view has no warped difference (null), not 0.
    let json = ok(
        &dir,
        &[
            "eval",
            GRAVEL,
            "frames",
            "--flow",
            "uniform:1,0",
            "--dt",
            "1000",
        ],
    );
    assert!(json.contains("\"mean_warped_diff\":null"), "{json}");
}

/// An animated GIF or PNG exemplar: its first frame is used, with a warning; a still
/// GIF gets none. `--also` inputs whose names contain `=`.
#[test]
fn animated_exemplars_warn_and_also_names_with_equals() {
    use image::codecs::gif::GifEncoder;
    use image::{Delay, Frame, RgbaImage};
    let dir = TempDir::new("anim");
    let frame = |shift: u32| {
        RgbaImage::from_fn(32, 32, |x, y| {
            let v = (((x * 7 + y * 13 + shift * 5) % 31) * 8) as u8;
            image::Rgba([v, 255 - v, (x * 8) as u8, 255])
        })
    };
    let frames: Vec<Frame> = (0..3)
        .map(|i| Frame::from_parts(frame(i), 0, 0, Delay::from_numer_denom_ms(100, 1)))
        .collect();
    {
        let f = std::fs::File::create(dir.path("anim.gif")).unwrap();
        GifEncoder::new(f).encode_frames(frames).unwrap();
    }
    frame(0).save(dir.path("still.gif")).unwrap();
    assert_eq!(
        texsyn::image_io::animation_frames(&dir.path("anim.gif")),
        Some(3)
    );
    assert_eq!(
        texsyn::image_io::animation_frames(&dir.path("still.gif")),
        Some(1)
    );
    assert_eq!(
        texsyn::image_io::animation_frames(Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/assets/gravel.png"
        ))),
        None
    );
    for (name, warned) in [("anim.gif", true), ("still.gif", false)] {
        let out = texsyn(&dir, &["synth", name, "-o", "o.png", "--size", "24"]);
        let stderr = text(&out.stderr);
        assert!(out.status.success(), "{stderr}");
        assert_eq!(
            stderr.contains("is an animation of 3 frames; texsyn uses its first frame"),
            warned,
            "{name}: {stderr}"
        );
    }

    // --also with '=' in the input's name: the split whose IN exists.
    frame(1).save(dir.path("rough=0.5.png")).unwrap();
    ok(
        &dir,
        &[
            "synth",
            "still.gif",
            "-o",
            "o2.png",
            "--size",
            "24",
            "--also",
            "rough=0.5.png=r=1.png",
        ],
    );
    assert_eq!(png_size(&dir.path("r=1.png")), (24, 24));
}

/// Findings of the fifteenth session's bad-input audit.
#[test]
fn audit_findings_fail_cleanly() {
    let dir = TempDir::new("audit");
    // Command lines as one string (no argument holds a space); `G` is the exemplar.
    let line = |s: &str| -> Vec<String> {
        s.split_whitespace()
            .map(|a| {
                if a == "G" {
                    GRAVEL.to_string()
                } else {
                    a.to_string()
                }
            })
            .collect()
    };
    image::RgbImage::from_pixel(20, 12, image::Rgb([128, 128, 0]))
        .save(dir.path("flow20.png"))
        .unwrap();
    let cases = [
        // A huge advection is refused before anything of its size is allocated.
        (
            "advect G --flow uniform:1,0 --frames 2 -o fr --size 100000",
            1,
            "give a smaller --size",
        ),
        // The most negative window origin is out of range, not an overflow.
        (
            "synth G -o o.png --size 16 --window=-2147483648,0",
            2,
            "within",
        ),
        // A missing --also map is named before the analysis.
        (
            "synth G -o o.png --size 16 --also nope.png=h.png",
            1,
            "--also: cannot read",
        ),
        ("advect G --flow uniform:1,0 --frames 2 -o .", 1, "by name"),
        ("advect G --flow image: --frames 2 -o fr", 2, "image:FILE"),
        // `-` is standard output for synth only: not a file or folder named `-`.
        ("analyze G -o -", 2, "only for synth"),
        (
            "advect G --flow vortex --frames 2 -o -",
            2,
            "only for synth",
        ),
        // A velocity map of another size than the output says which option to change.
        (
            "advect G --flow image:flow20.png --frames 2 --size 16 -o fr",
            1,
            "(--size 20x12)",
        ),
        // bench checks a preset field before any work.
        (
            "bench G --sizes 16 --runs 1 --warmup 0 --field scale:0",
            1,
            "zero scale",
        ),
    ];
    for (cmd, code, needle) in cases {
        let args = line(cmd);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        fails(&dir, &args, code, needle);
    }
    // eval --flow takes each frame's time from its number: a folder that starts at frame
    // 1 gives the same figures for the same pairs as the whole sequence.
    let advect = line("advect G --flow gusts:3,0.5 --frames 3 --size 24 -o all -q");
    ok(&dir, &advect.iter().map(String::as_str).collect::<Vec<_>>());
    std::fs::create_dir(dir.path("from1")).unwrap();
    for i in 1..=3 {
        let name = format!("frame_{i:05}.png");
        std::fs::copy(dir.path("all").join(&name), dir.path("from1").join(&name)).unwrap();
    }
    let figure = |folder: &str, key: &str| -> Vec<String> {
        let json = ok(&dir, &["eval", GRAVEL, folder, "--flow", "gusts:3,0.5"]);
        assert!(json.contains("\"mean_pops\":"), "{json}");
        let start = json.find(&format!("\"{key}\":[")).unwrap() + key.len() + 4;
        let end = start + json[start..].find(']').unwrap();
        json[start..end].split(',').map(str::to_string).collect()
    };
    assert_eq!(
        figure("all", "warped_diff")[1..],
        figure("from1", "warped_diff")[..]
    );
    // The popping too: one figure per pair of frames, each a fraction.
    let pops = figure("all", "pops");
    assert_eq!(pops.len(), 3);
    assert!(
        pops.iter()
            .all(|p| (0.0..=1.0).contains(&p.parse::<f64>().unwrap())),
        "{pops:?}"
    );
    assert_eq!(pops[1..], figure("from1", "pops")[..]);
    // The energies are labelled with the frames' own numbers, every K from frame 0.
    let json = ok(
        &dir,
        &[
            "eval",
            GRAVEL,
            "from1",
            "--flow",
            "gusts:3,0.5",
            "--energy-every",
            "2",
        ],
    );
    assert!(
        json.contains("\"energy\":[[1,") && json.contains("],[2,") && json.contains("],[3,"),
        "{json}"
    );
    // Numbers past five digits sort as numbers, not as text (frame_100000 after 99999).
    std::fs::create_dir(dir.path("big")).unwrap();
    for (i, n) in [(1, 99998u32), (2, 99999), (3, 100000)] {
        std::fs::copy(
            dir.path("all").join(format!("frame_{i:05}.png")),
            dir.path("big").join(format!("frame_{n:05}.png")),
        )
        .unwrap();
    }
    let json = ok(&dir, &["eval", GRAVEL, "big", "--flow", "gusts:3,0.5"]);
    assert!(
        json.contains("[99998,") && json.contains("[100000,"),
        "{json}"
    );
}

/// Windows of one field agree where they overlap once every position of the preset is
/// given: the perspective's reference row and vanishing column (they followed each
/// window, so no two windows agreed), and a swirl's centre.
#[test]
fn windows_along_a_field_agree_when_its_positions_are_given() {
    let dir = TempDir::new("field-windows");
    for field in ["perspective:-100,1.5,127,64", "swirl:40,30,50,0.5"] {
        let run = |out: &str, window: &str, size: &str| {
            ok(
                &dir,
                &[
                    "synth", GRAVEL, "-o", out, "--size", size, "--window", window, "--field",
                    field, "-q",
                ],
            );
            image::open(dir.path(out)).unwrap().to_luma8()
        };
        let a = run("a.png", "0,0", "96x80");
        let b = run("b.png", "40,24", "64x64");
        let mut differ = 0;
        for y in 24..80 {
            for x in 40..96 {
                differ += (a.get_pixel(x, y) != b.get_pixel(x - 40, y - 24)) as u32;
            }
        }
        assert_eq!(differ, 0, "{field}: {differ} pixels of the overlap differ");
    }
    // Magnified, a window whose far edge is an odd child: its last rows averaged a parent
    // that was not exact (9 pixels of row 65 differed at 2x).
    let run = |out: &str, window: &str, size: &str| {
        ok(
            &dir,
            &[
                "synth",
                GRAVEL,
                "-o",
                out,
                "--size",
                size,
                "--window",
                window,
                "--field",
                "swirl:40,40,50,0.8",
                "--magnify",
                "2",
                "-q",
            ],
        );
        image::open(dir.path(out)).unwrap().to_luma8()
    };
    let a = run("a.png", "-16,-16", "96x96");
    let b = run("b.png", "0,0", "32x33");
    let mut differ = 0;
    for y in 0..66 {
        for x in 0..64 {
            differ += (a.get_pixel(x + 32, y + 32) != b.get_pixel(x, y)) as u32;
        }
    }
    assert_eq!(
        differ, 0,
        "magnified: {differ} pixels of the overlap differ"
    );
}

/// A reader that goes away (`texsyn ... 2>&1 | head -1`) loses the messages, not the
/// work: before, the next progress line panicked ("failed printing to stderr", exit 101).
#[test]
fn a_closed_stderr_does_not_stop_the_run() {
    use std::process::Stdio;
    let dir = TempDir::new("closed-stderr");
    // The pipe's read end is closed before the child writes anything.
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let status = Command::new(BIN)
        .args(["analyze", GRAVEL, "-o", "a.tsa"])
        .current_dir(&dir.0)
        .stdout(Stdio::null())
        .stderr(writer)
        .status()
        .unwrap();
    assert_eq!(status.code(), Some(0));
    assert!(dir.path("a.tsa").is_file());
}

/// Outputs their format cannot hold, or an animation larger than the memory free, are
/// refused before the work: a GIF over 65535 pixels a side failed only after the whole
/// synthesis, an animation of too many frames with an allocation failure late in the run.
#[test]
fn outputs_their_format_or_memory_cannot_hold_are_refused_early() {
    let dir = TempDir::new("format-limits");
    fails(
        &dir,
        &["synth", GRAVEL, "-o", "wide.gif", "--size", "70000x16"],
        1,
        "GIF images are at most 65535 pixels a side",
    );
    fails(
        &dir,
        &[
            "synth",
            GRAVEL,
            "-o",
            "a.webp",
            "--size",
            "8200x8",
            "--magnify",
            "2",
        ],
        1,
        "WebP images are at most 16384 pixels a side and the output is 16400x16",
    );
    // 100001 frames of 1024x1024 RGBA: about 390 GiB kept for the encoder.
    fails(
        &dir,
        &[
            "advect", GRAVEL, "--flow", "vortex", "--frames", "100000", "--size", "1024", "-o",
            "anim.png",
        ],
        1,
        "is kept in memory until it is encoded",
    );
}

/// Ctrl-C or `kill` in the middle of an `advect` run into a frame folder: the process
/// exits with 128 + the signal and its staging folder (`.NAME.partial-PID`, there from
/// the start of the run) is removed; an existing output is left as it was.
#[cfg(target_os = "linux")]
#[test]
fn an_interrupted_run_removes_its_unfinished_outputs() {
    for (signal, code) in [("INT", 130), ("TERM", 143)] {
        let dir = TempDir::new("interrupt");
        std::fs::write(dir.path("keep.txt"), b"x").unwrap();
        let mut child = Command::new(BIN)
            .args([
                "advect", GRAVEL, "-o", "frames", "--flow", "vortex", "--size", "64", "--frames",
                "100000", "-q",
            ])
            .current_dir(&dir.0)
            .spawn()
            .unwrap();
        // Wait for the staging folder (at most 60 s on a slow machine).
        let start = std::time::Instant::now();
        while !dir
            .files()
            .iter()
            .any(|f| f.starts_with(".frames.partial-"))
        {
            if let Some(status) = child.try_wait().unwrap() {
                panic!("advect ended before it was interrupted: {status:?}");
            }
            assert!(
                start.elapsed().as_secs() < 60,
                "no staging folder appeared: {:?}",
                dir.files()
            );
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        let killed = Command::new("kill")
            .args([format!("-{signal}"), child.id().to_string()])
            .status()
            .unwrap();
        assert!(killed.success());
        let status = child.wait().unwrap();
        assert_eq!(status.code(), Some(code), "SIG{signal}: {status:?}");
        assert_eq!(dir.files(), vec!["keep.txt".to_string()], "SIG{signal}");
    }
}

/// `-o /dev/stdout` (or `-o -`) into a pipe: the link leads to a stream, which is written
/// through (it used to be followed to `pipe:[..]` and fail to create a temporary file
/// there; `-` made a file named `-`).
#[cfg(target_os = "linux")]
#[test]
fn output_to_dev_stdout_in_a_pipe() {
    let dir = TempDir::new("stdout");
    for target in ["/dev/stdout", "-"] {
        let out = texsyn(&dir, &["synth", GRAVEL, "-o", target, "--size", "32", "-q"]);
        assert!(out.status.success(), "{}", text(&out.stderr));
        assert!(
            out.stdout.starts_with(b"\x89PNG\r\n\x1a\n"),
            "{:?}",
            &out.stdout[..8.min(out.stdout.len())]
        );
        assert!(dir.files().is_empty(), "{:?}", dir.files());
    }
}

/// `advect --per-pass`: rows by level, and a pass that runs on some frames only shows its
/// mean per frame (marked), never "0 dispatches".
#[test]
fn advect_per_pass_table_is_by_level_without_zero_rows() {
    let dir = TempDir::new("perpass");
    let out = texsyn(
        &dir,
        &[
            "advect",
            GRAVEL,
            "-o",
            "fr",
            "--flow",
            "vortex",
            "--size",
            "64",
            "--frames",
            "5",
            "--per-pass",
            "-q",
        ],
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    let rows: Vec<Vec<&str>> = stdout
        .lines()
        .skip_while(|l| !l.trim_start().starts_with("level"))
        .skip(1)
        .map(|l| l.split_whitespace().collect::<Vec<_>>())
        .take_while(|r| r.len() >= 4 && r[0].parse::<usize>().is_ok())
        .collect();
    assert!(rows.len() >= 4, "{stdout}");
    let levels: Vec<usize> = rows.iter().map(|r| r[0].parse().unwrap()).collect();
    assert!(levels.windows(2).all(|w| w[0] <= w[1]), "{stdout}");
    for r in &rows {
        let d: f64 = r[2].trim_end_matches('*').parse().unwrap();
        assert!(d > 0.0, "{stdout}");
    }
}

/// Findings of the fifty-sixth session's bad-input sweep of `advect` and `eval --flow`:
/// each fails before any work, with what to do, and leaves nothing behind.
#[test]
fn advect_sweep_findings_fail_early() {
    let dir = TempDir::new("advect-sweep");
    let small = ["--frames", "2", "--size", "16", "-q"];
    let advect = |extra: &[&str]| -> Vec<String> {
        let mut a: Vec<String> = ["advect", GRAVEL].iter().map(|s| s.to_string()).collect();
        a.extend(extra.iter().chain(&small).map(|s| s.to_string()));
        a
    };
    let run = |args: Vec<String>, needle: &str| {
        let args: Vec<&str> = args.iter().map(|s| s.as_str()).collect();
        fails(&dir, &args, 1, needle);
    };
    ok(
        &dir,
        &[
            "advect",
            GRAVEL,
            "--flow",
            "uniform:1,0",
            "-o",
            "good",
            "--frames",
            "2",
            "--size",
            "16",
            "-q",
        ],
    );
    // eval checks the flow as advect does (a centre in pixels), and takes a negative
    // --dt to refuse it.
    fails(
        &dir,
        &["eval", GRAVEL, "good", "--flow", "source:10,0,1"],
        1,
        "fractions",
    );
    fails(
        &dir,
        &[
            "eval",
            GRAVEL,
            "good",
            "--flow",
            "uniform:1,0",
            "--dt",
            "-1",
        ],
        1,
        "time step",
    );
    // On a mesh the presets turn about the mesh's centre: a centre given in the spec is
    // not used, so a large one is not refused as pixels given by mistake.
    let bunny = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/meshes/bunny.glb");
    let out = texsyn(
        &dir,
        &[
            "advect",
            GRAVEL,
            "--mesh",
            bunny,
            "--atlas-size",
            "32",
            "--flow",
            "vortex:10,10,0.02",
            "--frames",
            "1",
            "-o",
            "mesh-centre",
        ],
    );
    let stderr = text(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("centre 10,10 is not used on a mesh"),
        "{stderr}"
    );
    assert!(stderr.contains("carrying the texture"), "{stderr}");
    assert!(dir.path("mesh-centre/frame_00001.png").exists());
    // A flat exemplar has no sharpness to measure: said so, not printed as NaN.
    image::RgbImage::from_pixel(24, 24, image::Rgb([120, 80, 40]))
        .save(dir.path("flat.png"))
        .unwrap();
    let flat = dir.path("flat.png");
    let out = texsyn(
        &dir,
        &[
            "advect",
            flat.to_str().unwrap(),
            "--flow",
            "vortex",
            "--frames",
            "2",
            "--size",
            "16",
            "-o",
            "flat-frames",
        ],
    );
    let stderr = text(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("sharpness: not measurable"), "{stderr}");
    assert!(!stderr.contains("NaN"), "{stderr}");
    // A step beyond f32 is named as too large, not as `inf`.
    for cmd in [
        advect(&["--flow", "vortex", "--dt", "1e39", "-o", "big-step"]),
        ["eval", GRAVEL, "good", "--flow", "vortex", "--dt", "1e39"]
            .map(String::from)
            .to_vec(),
    ] {
        let args: Vec<&str> = cmd.iter().map(|s| s.as_str()).collect();
        fails(&dir, &args, 1, "--dt 1e39: too large for 32-bit floats");
    }
    // And one that rounds to 0 as such, not accepted to fail after the synthesis.
    for cmd in [
        advect(&["--flow", "vortex", "--dt", "1e-50", "-o", "tiny-step"]),
        ["eval", GRAVEL, "good", "--flow", "vortex", "--dt", "1e-50"]
            .map(String::from)
            .to_vec(),
    ] {
        let args: Vec<&str> = cmd.iter().map(|s| s.as_str()).collect();
        fails(&dir, &args, 1, "--dt 1e-50: too small for 32-bit floats");
    }
    // Rates that overflow when sampled are refused up front, in advect and eval.
    // (A core radius makes the parser check the spec: a usage error.)
    for (spec, code) in [
        ("gusts:1,1e37", 1),
        ("vortex:0.5,0.5,1e38", 1),
        ("vortex:0.5,0.5,1e38,0.2", 2),
        ("source:0.5,0.5,-3e38", 1),
    ] {
        let args = advect(&["--flow", spec, "-o", "huge"]);
        let args: Vec<&str> = args.iter().map(|s| s.as_str()).collect();
        fails(&dir, &args, code, "at most 1e9");
        fails(
            &dir,
            &["eval", GRAVEL, "good", "--flow", spec],
            code,
            "at most 1e9",
        );
    }
    #[cfg(unix)]
    {
        // A link to nothing, as the frames' folder or the animation.
        std::os::unix::fs::symlink("/nonexistent/x", dir.path("dangling")).unwrap();
        std::os::unix::fs::symlink("/nonexistent/x", dir.path("dangling.png")).unwrap();
        run(
            advect(&["--flow", "uniform:1,0", "-o", "dangling"]),
            "symbolic link",
        );
        run(
            advect(&["--flow", "uniform:1,0", "-o", "dangling.png"]),
            "symbolic link",
        );
    }
    // More than 16 correction passes on the coarser advected levels.
    run(
        advect(&[
            "--flow",
            "vortex",
            "--keep-look",
            "--coarsest-passes",
            "17",
            "-o",
            "cp",
        ]),
        "17 on the coarsest advected level",
    );
    // A folder where a frame goes: refused before the frames, none of them replaced.
    std::fs::create_dir_all(dir.path("mix/frame_00001.png/x")).unwrap();
    std::fs::copy(
        dir.path("good/frame_00000.png"),
        dir.path("mix/frame_00000.png"),
    )
    .unwrap();
    let before = std::fs::read(dir.path("mix/frame_00000.png")).unwrap();
    run(
        advect(&["--flow", "uniform:1,0", "--seed", "9", "-o", "mix"]),
        "mix/frame_00001.png is a folder",
    );
    assert_eq!(
        std::fs::read(dir.path("mix/frame_00000.png")).unwrap(),
        before
    );
    // An input that is one of the output folder's frames (the run replaces them).
    let mut args: Vec<String> = [
        "advect",
        "good/frame_00000.png",
        "--flow",
        "uniform:1,0",
        "-o",
        "good",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    args.extend(small.iter().map(|s| s.to_string()));
    run(args, "is a frame of the output folder");
    run(
        advect(&[
            "--flow",
            "image:good/frame_00001.png",
            "-o",
            "./good/../good",
        ]),
        "is a frame of the output folder",
    );
}
