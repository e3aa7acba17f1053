//! `synth`, `analyze`, `eval` and `bench` on the bundled exemplar: outputs, windows,
//! seeds, the analysis file, help texts.

use std::path::Path;

use crate::common::cli::{fails, ok, texsyn, text, GRAVEL};
use crate::common::images::image_size as png_size;
use crate::common::TempDir;
use crate::json;

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
