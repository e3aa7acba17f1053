//! The command line's feature mask and appearance options, and their errors.

use texsyn::analysis::{Analysis, AppearanceSpace, FeatureMode};

use crate::common::cli::texsyn;
use crate::common::TempDir;
use crate::helpers::*;

/// Runs `texsyn args...` in `dir` and checks that it fails with exit code `code`, an
/// error message (from its `error: ` line on, which clap continues on the following
/// lines) containing every needle, no panic, and no file left behind.
fn fails(dir: &TempDir, args: &[&str], code: i32, needles: &[&str]) {
    let before = dir.entries();
    let out = texsyn(dir, args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(code), "texsyn {args:?}: {stderr}");
    // The message starts with `error: ` (clap continues it on the following lines).
    let at = stderr
        .find("error: ")
        .unwrap_or_else(|| panic!("no error line:\n{stderr}"));
    let message = stderr[at..].to_lowercase();
    for n in needles {
        assert!(
            message.contains(&n.to_lowercase()),
            "texsyn {args:?}: the error lacks {n:?}; stderr:\n{stderr}"
        );
    }
    assert!(
        !stderr.contains("panicked"),
        "texsyn {args:?} panicked:\n{stderr}"
    );
    assert_eq!(dir.entries(), before, "texsyn {args:?} left files behind");
}

#[test]
fn cli_feature_mask_and_appearance() {
    let dir = TempDir::new("cli");
    let mask = dir.path("mask.png");
    write_mask_png(&mask, 128, 128, |_, y| y % 16 < 2);
    let small = dir.path("small.png");
    write_mask_png(&small, 64, 64, |_, y| y % 16 < 2);
    let blank = dir.path("blank.png");
    write_mask_png(&blank, 128, 128, |_, _| false);
    // Blank and of the wrong size: the size is the first thing to fix.
    let small_blank = dir.path("small_blank.png");
    write_mask_png(&small_blank, 64, 64, |_, _| true);
    let mask_s = mask.to_str().unwrap();
    let small_s = small.to_str().unwrap();
    let blank_s = blank.to_str().unwrap();

    // Errors: exit code, a clear message, no output file.
    for cmd in [
        &["analyze", BRICK, "-o", "a.tsa"][..],
        &["synth", BRICK, "-o", "out.png", "--size", "32"][..],
    ] {
        let with = |extra: &[&'static str]| -> Vec<String> {
            cmd.iter().chain(extra).map(|s| s.to_string()).collect()
        };
        let run = |args: Vec<String>, code, needles: &[&str]| {
            let a: Vec<&str> = args.iter().map(|s| s.as_str()).collect();
            fails(&dir, &a, code, needles)
        };
        run(
            with(&["--feature-mask", "no-such-mask.png"]),
            1,
            &["--feature-mask", "no-such-mask.png", "cannot read"],
        );
        let mut a = with(&["--feature-mask"]);
        a.push(small_s.to_string());
        run(a, 1, &["64x64", "exemplar is 128x128", "exemplar's size"]);
        // A blank mask would silently change nothing.
        let mut a = with(&["--feature-mask"]);
        a.push(blank_s.to_string());
        run(a, 1, &["no pixel is a feature", "blank.png"]);
        let mut a = with(&["--feature-mask"]);
        a.push(small_blank.to_str().unwrap().to_string());
        run(a, 1, &["64x64", "exemplar is 128x128", "exemplar's size"]);
        for w in ["-1", "nan", "inf", "abc"] {
            let mut a = with(&["--feature-weight", w, "--feature-mask"]);
            a.push(mask_s.to_string());
            run(a, 2, &["--feature-weight"]);
        }
        run(with(&["--feature-weight", "2"]), 2, &["--feature-mask"]);
        for c in ["0.1", "-1", "nan", "5000", "x"] {
            let mut a = with(&["--feature-clamp", c, "--feature-mask"]);
            a.push(mask_s.to_string());
            run(a, 2, &["--feature-clamp"]);
        }
        run(with(&["--feature-clamp", "2"]), 2, &["--feature-mask"]);
        run(with(&["--feature-mode", "sets"]), 2, &["--feature-mask"]);
        let mut a = with(&["--feature-mode", "paper", "--feature-mask"]);
        a.push(mask_s.to_string());
        run(a, 2, &["both, appearance or sets"]);
        run(
            with(&["--appearance", "rgb"]),
            2,
            &["neighborhood or color"],
        );
    }
    // A non-image mask.
    std::fs::write(dir.path("junk.png"), b"junk").unwrap();
    fails(
        &dir,
        &[
            "analyze",
            BRICK,
            "-o",
            "a.tsa",
            "--feature-mask",
            "junk.png",
        ],
        1,
        &["--feature-mask", "junk.png"],
    );

    // Success: the analysis records the settings; synth with a mask and colour space.
    let out = texsyn(
        &dir,
        &[
            "analyze",
            BRICK,
            "-o",
            "a.tsa",
            "--feature-mask",
            mask_s,
            "--feature-weight",
            "0.5",
            "--feature-clamp",
            "3",
            "--appearance",
            "color",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("appearance: color, feature mask covering 12.5%"),
        "{stderr}"
    );
    let a = Analysis::load(&dir.path("a.tsa")).unwrap();
    assert_eq!(a.appearance, AppearanceSpace::Color);
    let f = a.feature.unwrap();
    assert_eq!(
        (f.weight, f.clamp, f.coverage, f.mode),
        (0.5, 3.0, 0.125, FeatureMode::Both)
    );
    let out = texsyn(
        &dir,
        &[
            "analyze",
            BRICK,
            "-o",
            "s.tsa",
            "--feature-mask",
            mask_s,
            "--feature-mode",
            "sets",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stderr).contains("in the similarity sets only"));
    let s = Analysis::load(&dir.path("s.tsa")).unwrap();
    assert_eq!(s.feature.map(|f| f.mode), Some(FeatureMode::Sets));
    let out = texsyn(
        &dir,
        &[
            "synth",
            BRICK,
            "-o",
            "out.png",
            "--size",
            "48x32",
            "--feature-mask",
            mask_s,
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let img = image::open(dir.path("out.png")).unwrap();
    assert_eq!((img.width(), img.height()), (48, 32));

    // eval --feature-mask: the feature figures, from the coordinate map.
    let out = texsyn(
        &dir,
        &[
            "synth",
            BRICK,
            "-o",
            "o.png",
            "--size",
            "64",
            "--coords-out",
            "o.exr",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = texsyn(
        &dir,
        &[
            "eval",
            BRICK,
            "o.png",
            "--coords",
            "o.exr",
            "--feature-mask",
            mask_s,
            "--energy-map",
            "map.png",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json = String::from_utf8_lossy(&out.stdout);
    for key in [
        "\"features\":{\"fragment_fraction\":",
        "\"exemplar_coverage\":0.125",
        "\"mask_energy\":",
    ] {
        assert!(json.contains(key), "{key} missing from {json}");
    }
    let map = image::open(dir.path("map.png")).unwrap();
    assert_eq!((map.width(), map.height()), (64, 64));
    fails(
        &dir,
        &[
            "eval",
            BRICK,
            "o.png",
            "--coords",
            "o.exr",
            "--feature-mask",
            small_s,
        ],
        1,
        &["64x64", "exemplar's size"],
    );
    fails(
        &dir,
        &["eval", BRICK, "o.png", "--feature-mask", mask_s],
        2,
        &["--coords"],
    );
    fails(
        &dir,
        &[
            "eval",
            BRICK,
            "o.png",
            "--energy-map",
            "m2.png",
            "--energy-scale",
            "-1",
        ],
        2,
        &["--energy-scale", "positive"],
    );
    assert!(!dir.path("m2.png").exists());
}
