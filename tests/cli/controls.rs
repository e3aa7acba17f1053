//! The synthesis controls on the command line (`--field`, `--also`, `--magnify`,
//! `--standalone`, `--appearance`, `--tileable-output`) end to end, and their bad input.

use crate::common::cli::{fails, ok, texsyn, text, GRAVEL};
use crate::common::images::image_size as png_size;
use crate::common::TempDir;

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
    fails_with(&["--field", "scale:-1"], 1, "negative scale");
    fails_with(&["--field", "scale:100"], 1, "outside 0.125..8");
    fails_with(
        &["--field", "constant:0,1,0.1,0"],
        1,
        "scale 0.1 is outside",
    );
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
