//! `texsyn advect` (and `eval --flow` on its frames): frame folders, animations, meshes,
//! the scheme it chooses, its reports, and its bad input.

use std::path::Path;

use crate::common::cli::{command, fails, ok, texsyn, text, BUNNY, GRAVEL};
use crate::common::images::image_size as png_size;
use crate::common::{repo, TempDir};

/// `advect`'s options: --field does not apply to a mesh (usage error); bad options are
/// refused before the analysis; the scheme chosen by default and by --carry/--keep-look;
/// a staging folder of a killed run is cleaned up; the later frames' cost is reported.
#[test]
fn advect_options_are_checked_before_the_analysis() {
    let dir = TempDir::new("advect-options");
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
    // Refused before the analysis: the run reports no analysis progress (which every
    // run that gets that far prints, `frames_of` below).
    let args = [
        "advect", GRAVEL, "--flow", "vortex", "--levels", "0", "-o", "frames",
    ];
    fails(&dir, &args, 1, "levels");
    let stderr = text(&texsyn(&dir, &args).stderr);
    assert!(
        !stderr.contains("analysing level"),
        "checked after the analysis:\n{stderr}"
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
        // The progress that a run refused before the analysis never shows (above).
        assert!(stderr.contains("analysing level"), "{a:?}: {stderr}");
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

/// Bad input to `advect` and `eval --flow` (flow specs, time steps, output folders that
/// are links, folders or hold the input): each fails before any work, with what to do,
/// and leaves nothing behind.
#[test]
fn advect_and_eval_flow_refuse_bad_input_before_any_work() {
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
    let bunny = BUNNY;
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

/// `texsyn advect` end to end (2D frames folder, GIF, a mesh) and its bad inputs.
#[test]
fn advect_writes_frames_animations_and_meshes_and_refuses_bad_input() {
    let dir = TempDir::new("advect-cli");
    // Run from the repository, so that `assets/...` paths are relative.
    let run = |args: &[&str]| {
        command(&repo())
            .args(args)
            .env("XDG_RUNTIME_DIR", std::env::temp_dir())
            .output()
            .unwrap()
    };
    let frames = dir.path("frames");
    let o = run(&[
        "advect",
        "assets/gravel.png",
        "--flow",
        "vortex:0.5,0.5,0.02",
        "--frames",
        "4",
        "--size",
        "64",
        "-o",
        frames.to_str().unwrap(),
        "--every",
        "2",
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    for f in ["frame_00000.png", "frame_00002.png", "frame_00004.png"] {
        assert!(frames.join(f).exists(), "{f} missing: {stderr}");
    }
    assert!(!frames.join("frame_00001.png").exists());
    // --keep-look runs end to end (its frames are compared with the CPU in the library).
    let kept = dir.path("kept");
    let o = run(&[
        "advect",
        "assets/gravel.png",
        "--flow",
        "vortex",
        "--frames",
        "2",
        "--size",
        "48",
        "--keep-look",
        "-o",
        kept.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(kept.join("frame_00002.png").exists());
    assert!(
        stderr.contains("cost per frame")
            && stderr.contains("warped by the flow")
            && stderr.contains("(last / first: x"),
        "{stderr}"
    );
    // eval --flow compares consecutive frames: frames 0, 2, 4 are refused.
    let o = run(&[
        "eval",
        "assets/gravel.png",
        frames.to_str().unwrap(),
        "--flow",
        "vortex:0.5,0.5,0.02",
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && stderr.contains("not consecutive"),
        "{stderr}"
    );
    // A second run into the same folder replaces the frames: none of the first run's is
    // left over, and no staging folder stays behind.
    let o = run(&[
        "advect",
        "assets/gravel.png",
        "--flow",
        "uniform:1,0",
        "--frames",
        "1",
        "--size",
        "32",
        "-q",
        "-o",
        frames.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut names: Vec<String> = std::fs::read_dir(&frames)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["frame_00000.png", "frame_00001.png"]);
    assert_eq!(png_size(&frames.join("frame_00001.png")), (32, 32));
    let o = run(&[
        "eval",
        "assets/gravel.png",
        frames.to_str().unwrap(),
        "--flow",
        "uniform:1,0",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // An animated PNG: every frame in one file.
    let apng = dir.path("anim.png");
    assert!(run(&[
        "advect",
        "assets/gravel.png",
        "--flow",
        "uniform:1,0",
        "--frames",
        "3",
        "--size",
        "32",
        "-q",
        "-o",
        apng.to_str().unwrap()
    ])
    .status
    .success());
    let bytes = std::fs::read(&apng).unwrap();
    let actl = bytes
        .windows(4)
        .position(|w| w == b"acTL")
        .expect("an acTL chunk");
    assert_eq!(
        u32::from_be_bytes(bytes[actl + 4..actl + 8].try_into().unwrap()),
        4
    );
    assert_eq!(bytes.windows(4).filter(|w| *w == b"fcTL").count(), 4);
    let gif = dir.path("bunny.gif");
    let o = run(&[
        "advect",
        "assets/gravel.png",
        "--mesh",
        "assets/meshes/bunny.glb",
        "--atlas-size",
        "128",
        "--flow",
        "vortex:0.5,0.5,0.05",
        "--frames",
        "2",
        "-o",
        gif.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(image::open(&gif).is_ok());
    // Exit 2: a malformed command line (clap's usage errors); exit 1: a run that fails,
    // as for a missing file named in `--field image:FILE`.
    for (args, expect, code) in [
        (vec!["--flow", "vortex", "--dt", "0"], "time step", 1),
        (vec!["--flow", "vortex", "--dt", "-1"], "time step", 1),
        (vec!["--flow", "uniform:nan,1"], "finite", 2),
        (vec!["--flow", "swirly"], "unknown flow", 2),
        (vec!["--flow", "vortex:0.5,0.5,0.02,0"], "core radius", 2),
        (vec!["--flow", "vortex:0.5,0.5,0.02,-0.1"], "core radius", 2),
        (vec!["--flow", "image:missing.png"], "missing.png", 1),
        // The fade's ranges are the parser's (0..=64, 0..=255), stated in its message.
        (vec!["--flow", "vortex", "--fade", "65"], "0..=64", 2),
        (vec!["--flow", "vortex", "--fade", "-1"], "0..=64", 2),
        (
            vec!["--flow", "vortex", "--fade", "1", "--fade-change", "300"],
            "0..=255",
            2,
        ),
        (
            vec!["--flow", "vortex", "--fade", "1", "--fade-change", "-5"],
            "0..=255",
            2,
        ),
        (
            vec!["--flow", "vortex:0.3,0.3"],
            "or 4 (CX,CY,OMEGA,CORE",
            2,
        ),
        // keep_look needs 3 levels: asked for, it says how to carry the texture instead.
        (
            vec!["--flow", "vortex", "--keep-look", "--levels", "2"],
            "--carry",
            1,
        ),
    ] {
        let mut a = vec![
            "advect",
            "assets/gravel.png",
            "--frames",
            "1",
            "--size",
            "32",
            "-o",
        ];
        let out = dir.path("bad");
        a.push(out.to_str().unwrap());
        a.extend(args.iter().copied());
        let o = run(&a);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(code), "{args:?}: {stderr}");
        assert!(stderr.contains(expect), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
        assert!(!out.exists(), "{args:?} left {} behind", out.display());
    }
    // Refused before any frame is written: outputs too small for the figures, and an
    // extension that is neither an animation nor a folder.
    for (out, size, expect) in [
        ("tiny.gif", "2", "at least 5x5"),
        ("tiny", "4x16", "at least 5x5"),
        ("frames.txt", "32", "without an extension"),
        ("no/such/frames", "32", "does not exist"),
    ] {
        let path = dir.path(out);
        let o = run(&[
            "advect",
            "assets/gravel.png",
            "--flow",
            "vortex",
            "--frames",
            "2",
            "--size",
            size,
            "-o",
            path.to_str().unwrap(),
        ]);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{out} {size} succeeded");
        assert!(stderr.contains(expect), "{out} {size}: {stderr}");
        assert!(
            !path.exists(),
            "{out} {size} left {} behind",
            path.display()
        );
    }
    // Nothing but what the successful runs wrote: no hidden staging folders.
    assert_eq!(dir.entries(), ["anim.png", "bunny.gif", "frames", "kept"]);
    // eval reads `--flow image:FILE` when it runs, too.
    let o = run(&[
        "eval",
        "assets/gravel.png",
        frames.to_str().unwrap(),
        "--flow",
        "image:missing.png",
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("missing.png"), "{stderr}");
}
