//! Bad input to `synth`, `analyze`, `eval` and `bench`: each run exits non-zero with an
//! `error: ...` line naming the problem, and leaves no file behind.

use std::path::Path;

use crate::common::cli::{fails, ok, BUNNY, GRAVEL};
use crate::common::TempDir;

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
    let bunny = BUNNY;
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

/// A feature mask of the wrong size for `eval --energy-map` and an HDR exemplar fail
/// cleanly, leaving nothing behind; `--also` keeps a map's alpha channel.
#[test]
fn mismatched_masks_and_hdr_exemplars_fail_cleanly() {
    let dir = TempDir::new("masks-hdr");
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
}

/// Command lines that cannot run (huge sizes, out-of-range windows, missing maps, `-`
/// where a file is needed, a velocity map of another size) fail before any work; `eval
/// --flow` numbers the frames of a folder by their names.
#[test]
fn impossible_command_lines_fail_before_any_work() {
    let dir = TempDir::new("impossible");
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
