//! `texsyn eval`: quality figures of a synthesized image against its exemplar, as JSON.

use std::path::{Path, PathBuf};

use clap::Args;

use texsyn::quality::{self, CoordMap, FloatImage};

use super::{fail, CliResult, TileArgs, Ui};

/// Print quality figures of a synthesized image against its exemplar as JSON on stdout
#[derive(Args, Debug)]
#[command(
    long_about = "Print quality figures of a synthesized image against its exemplar as JSON on stdout.\n\n\
                  texture_energy: mean squared difference of each 7x7 output neighbourhood to the \
                  nearest exemplar neighbourhood, at full, half and quarter resolution (null \
                  where the images are too small; both downsampled from their origin); \
                  texture_energy_any_phase: the same, with the output's half and quarter \
                  resolution windows matched against the exemplar downsampled at every grid \
                  offset (4 and 16), so that the figures do not swing with the parity of where \
                  large patches were copied from; histogram_emd: earth mover's distance \
                  between the colour histograms, per channel and mean; verbatim (with \
                  --coords): how much of the output is verbatim copy of the exemplar \
                  (coherent neighbour pairs, largest copied region), else null; repetition \
                  (with --coords): the share of pixels whose exemplar pixel recurs at one same \
                  displacement (8-pixel bins, 24 px and more; 0 = no repeated layout, near 1 = \
                  a tiling of the exemplar), and that displacement; \
                  wrap_seam_ratio: how visible the seam is when the image is tiled (mean \
                  difference across its wrap-around edges over the mean difference between \
                  neighbouring pixels; about 1 or below tiles seamlessly); jacobian (with \
                  --field): how well the texture follows the field; features (with \
                  --feature-mask): how the exemplar's features survive. Lower energy and EMD \
                  are better."
)]
pub struct EvalArgs {
    /// The exemplar image (not an analysis file: the figures compare pixels)
    pub exemplar: PathBuf,

    /// The synthesized image
    pub image: PathBuf,

    /// Coordinate map written by `texsyn synth --coords-out`, for the verbatim-copy figures
    #[arg(long, value_name = "FILE.exr")]
    pub coords: Option<PathBuf>,

    /// Whether exemplar coordinates wrap around (for --coords); default: detected from
    /// the exemplar's seams, as the analysis does
    #[command(flatten)]
    pub tile: TileArgs,

    /// With --coords: how well the texture follows this field (as `synth --field`)
    ///
    /// The field the image was synthesized along (same SPEC as `texsyn synth --field`,
    /// window 0,0): with --coords, reports how well the texture follows it ("jacobian":
    /// fraction of pixels whose finite-difference Jacobian is within --tolerance of the
    /// field, over all pixels and away from patch seams) instead of the verbatim figures
    #[arg(long, value_name = "SPEC", value_parser = super::field::parse_field,
          requires = "coords")]
    pub field: Option<super::field::FieldSpec>,

    /// With --coords: how the exemplar's features survive (as `synth --feature-mask`)
    ///
    /// Feature mask of the exemplar (as for `texsyn synth --feature-mask`): with --coords,
    /// reports how the features survive ("features": share of the resynthesized mask in
    /// fragments under 20 px against the exemplar mask's share, coverage, and the 7x7
    /// texture energy of the resynthesized mask)
    #[arg(long, value_name = "FILE", requires = "coords")]
    pub feature_mask: Option<PathBuf>,

    /// Temporal figures of a folder of advected frames along this flow (as `advect --flow`)
    ///
    /// Temporal coherence of an advected sequence: IMAGE is then a folder of frames
    /// (frame_00000.png, ... as `texsyn advect` writes them, consecutive) advected along
    /// this flow (same SPEC as `texsyn advect --flow`); reports the flow-warped and plain
    /// frame-to-frame differences, the popping (the fraction of 8x8 blocks whose mean
    /// warped change exceeds 0.15 of full scale, per pair of frames), texture energy per
    /// --energy-every frames and the sharpness (high-frequency energy relative to the
    /// exemplar's) per frame. 2D frames only: the frames of `advect --mesh` are renders
    /// that a 2D flow does not move; advect prints their figures, measured over the atlas
    #[arg(long, value_name = "SPEC", value_parser = super::advect::parse_flow,
          conflicts_with_all = ["coords", "field"])]
    pub flow: Option<super::advect::FlowArg>,

    /// Time step of --flow (velocity * dt per frame)
    #[arg(
        long,
        default_value_t = 1.0,
        requires = "flow",
        allow_hyphen_values = true
    )]
    pub dt: f64,

    /// Also write where the texture energy lies, as a grey image of the output's size
    ///
    /// Also write where the full-resolution texture energy lies, as a grey image of the
    /// output's size (each pixel: the energy of the 7x7 window centred on it; the
    /// 3-pixel border, which has no full window, is black)
    #[arg(long, value_name = "FILE.png", conflicts_with = "flow")]
    pub energy_map: Option<PathBuf>,

    /// Relative Frobenius tolerance of the Jacobian figures
    #[arg(long, value_name = "T", default_value_t = 0.15, allow_hyphen_values = true,
          value_parser = parse_positive::<f64>, help_heading = super::ADVANCED,
          hide_short_help = true)]
    pub tolerance: f64,

    /// With --flow: texture energy every K-th frame (0: the first and the last only)
    ///
    /// With --flow: texture energy (of 5x5 windows, as `texsyn advect` prints it; plain
    /// eval's is of 7x7) on the first frame, every K-th from frame 0 and the last; 0: the
    /// first and the last only
    #[arg(long, value_name = "K", default_value_t = 10, requires = "flow",
          help_heading = super::ADVANCED, hide_short_help = true)]
    pub energy_every: usize,

    /// Energy shown as white in --energy-map
    ///
    /// Energy shown as white in --energy-map (a mean squared difference per channel;
    /// fixed, so maps of different images compare)
    #[arg(
        long,
        value_name = "E",
        default_value_t = 0.02,
        requires = "energy_map",
        allow_hyphen_values = true,
        value_parser = parse_positive::<f32>,
        help_heading = super::ADVANCED,
        hide_short_help = true
    )]
    pub energy_scale: f32,
}

/// A positive, finite number (a usage error otherwise, like any malformed option).
fn parse_positive<T>(s: &str) -> Result<T, String>
where
    T: std::str::FromStr + Into<f64> + Copy,
{
    let v: T = s
        .trim()
        .parse()
        .map_err(|_| format!("\"{s}\" is not a number"))?;
    let f: f64 = v.into();
    if f > 0.0 && f.is_finite() {
        Ok(v)
    } else {
        Err(format!("{s}: give a positive number"))
    }
}

pub fn run(ui: &Ui, args: EvalArgs) -> CliResult<()> {
    if texsyn::session::is_analysis_file(&args.exemplar)? {
        return Err(fail(format!(
            "{} is an analysis file; eval needs the exemplar image itself (the one given to `texsyn analyze`)",
            args.exemplar.display()
        )));
    }
    let exemplar = ui.load_exemplar(&args.exemplar)?;
    if let Some(flow) = &args.flow {
        // The same checks as `advect` (a centre given in pixels, a core radius of 0).
        let flow = flow.load()?;
        flow.validate()?;
        return temporal(ui, &args, &exemplar, &flow);
    }
    // The energy map's path is checked before any work.
    if let Some(path) = &args.energy_map {
        super::check_output_dir(path)?;
        super::synth::check_save_extension(path)?;
        let mut inputs: Vec<(&str, &std::path::Path)> = vec![
            ("exemplar", &args.exemplar),
            ("image evaluated", &args.image),
        ];
        inputs.extend(args.coords.as_deref().map(|c| ("coordinate map", c)));
        inputs.extend(args.feature_mask.as_deref().map(|m| ("feature mask", m)));
        inputs.extend(super::field::FieldSpec::input(&args.field));
        super::check_outputs_not_inputs(&[path], &inputs)?;
    }
    let output = load_image(&args.image)?;
    let mask = match &args.feature_mask {
        Some(path) => {
            let mask = texsyn::analysis::FeatureMask::load(path)?;
            mask.check_size(exemplar.width, exemplar.height)?;
            Some(mask)
        }
        None => None,
    };

    let coords = match &args.coords {
        None => None,
        Some(path) => {
            let (w, h, c) = texsyn::image_io::load_coords_exr_f32(path)?;
            let magnified = (2..=8).find(|f| (w * f, h * f) == (output.width, output.height));
            if (w, h) != (output.width, output.height) {
                return Err(fail(format!(
                    "{} is {w}x{h} but {} is {}x{}: give the coordinate map written together with the image{}",
                    path.display(),
                    args.image.display(),
                    output.width,
                    output.height,
                    match magnified {
                        Some(f) => format!(
                            " (if the image is a --magnify {f} output, the map has one coordinate \
                             per synthesized pixel: evaluate the image without --coords)"
                        ),
                        None => String::new(),
                    }
                )));
            }
            // Synthesized coordinates are exemplar positions: anything far outside is not
            // a coordinate map of this exemplar (another file, another exemplar).
            let (ew, eh) = (exemplar.width as f32, exemplar.height as f32);
            if let Some(v) = c
                .iter()
                .find(|v| !(v[0] >= -1.0 && v[0] <= ew && v[1] >= -1.0 && v[1] <= eh))
            {
                return Err(fail(format!(
                    "{}: coordinate ({}, {}) lies outside the {}x{} exemplar: give the coordinate \
                     map written with --coords-out for this exemplar",
                    path.display(),
                    v[0],
                    v[1],
                    exemplar.width,
                    exemplar.height
                )));
            }
            if args.field.is_none() && c.iter().any(|v| v[0].fract() != 0.0 || v[1].fract() != 0.0)
            {
                ui.info(
                    "note: the coordinate map is fractional (an anisometric synthesis?): the \
                     verbatim figures count exact integer copies; give --field SPEC (the field \
                     it was synthesized along) for the Jacobian figures instead",
                );
            }
            Some((w, h, c))
        }
    };
    let tileable = args
        .tile
        .get()
        .unwrap_or_else(|| texsyn::analysis::detect_tileable(&exemplar));
    let ex_size = [exemplar.width, exemplar.height];
    let exemplar = FloatImage::from_exemplar(&exemplar);
    let jacobian = match (&args.field, &coords) {
        (Some(spec), Some((w, h, c))) => {
            if !(args.tolerance > 0.0 && args.tolerance.is_finite()) {
                return Err(fail("--tolerance must be a positive number"));
            }
            let field = spec.resolve([0, 0], *w, *h)?;
            Some(quality::jacobian_fidelity(
                c,
                *w,
                *h,
                ex_size,
                [0, 0],
                &field,
                args.tolerance,
            )?)
        }
        _ => None,
    };
    // Verbatim figures count exact integer copies: meaningless along a field.
    let rounded: Option<Vec<[i32; 2]>> = match (&args.field, &coords) {
        (None, Some((_, _, c))) => Some(
            c.iter()
                .map(|v| [v[0].round() as i32, v[1].round() as i32])
                .collect(),
        ),
        _ => None,
    };
    let map = match (&rounded, &coords) {
        (Some(r), Some((w, h, _))) => Some(CoordMap {
            coords: r,
            width: *w,
            height: *h,
            tileable,
        }),
        _ => None,
    };

    let report = quality::evaluate(&exemplar, &output, quality::DEFAULT_RADIUS, map)?;
    let wrap_seam = quality::wrap_seam_ratio(&output)?;
    let mut json = report.to_json();
    json.pop();
    json.push_str(&format!(
        ",\"wrap_seam_ratio\":{}}}",
        json_number(wrap_seam)
    ));
    if let (Some(mask), Some((w, h, c))) = (&mask, &coords) {
        let b = quality::feature_breakage(mask, c, *w, *h, tileable)?;
        json.pop();
        json.push_str(&format!(",\"features\":{}}}", b.to_json()));
    }
    if let Some(j) = jacobian {
        json.pop();
        json.push_str(&format!(",\"jacobian\":{}}}", j.to_json()));
    }
    // Written last, so a failed evaluation leaves no map behind.
    if let Some(path) = &args.energy_map {
        write_energy_map(path, &exemplar, &output, args.energy_scale)?;
    }
    ui.out(json)
}

/// `eval --flow`: the temporal figures of a folder of frames.
fn temporal(
    ui: &Ui,
    args: &EvalArgs,
    exemplar: &texsyn::Exemplar,
    flow: &texsyn::flow::Flow,
) -> CliResult<()> {
    let dt = super::time_step(args.dt)?;
    if !args.image.is_dir() {
        return Err(fail(format!(
            "{}: with --flow, give the folder of frames `texsyn advect -o FOLDER` wrote",
            args.image.display()
        )));
    }
    let mut paths: Vec<PathBuf> = std::fs::read_dir(&args.image)
        .map_err(|e| fail(format!("cannot read {}: {e}", args.image.display())))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("frame_") && n.ends_with(".png"))
        })
        .collect();
    // By frame number: `advect` pads to 5 digits, so frame 100000 sorts before 99999 as
    // text; names without a number come first and fail the consecutive check below.
    let index = |p: &PathBuf| -> Option<u64> {
        let n = p.file_name()?.to_str()?;
        n.strip_prefix("frame_")?.strip_suffix(".png")?.parse().ok()
    };
    paths.sort_by_key(|p| (index(p), p.clone()));
    if paths.len() < 2 {
        return Err(fail(format!(
            "{}: needs at least two frame_*.png files",
            args.image.display()
        )));
    }
    // The flow is applied frame by frame: a gap (advect --every K) would compare frames
    // K steps apart as if they were 1.
    for pair in paths.windows(2) {
        match (index(&pair[0]), index(&pair[1])) {
            (Some(a), Some(b)) if b == a + 1 => {}
            _ => {
                return Err(fail(format!(
                    "{}: the frames are not consecutive ({} then {}); eval --flow needs every frame (advect --every 1)",
                    args.image.display(),
                    pair[0].file_name().unwrap_or_default().to_string_lossy(),
                    pair[1].file_name().unwrap_or_default().to_string_lossy()
                )))
            }
        }
    }
    // One frame at a time: memory stays flat for long sequences.
    let first = load_image(&paths[0])?;
    let (w, h) = (first.width, first.height);
    // A field of another size than the frames is an error, not a silently ignored flow.
    flow.sample(w, h, 0.0)?;
    let mut figures = quality::TemporalFigures::new(
        &FloatImage::from_exemplar(exemplar),
        match args.energy_every {
            0 => usize::MAX,
            k => k,
        },
    )
    .starting_at(index(&paths[0]).unwrap_or(0) as usize);
    figures.push(first, &[])?;
    for path in paths.iter().skip(1) {
        // The frame's own number is its time (a folder may start after frame 0).
        let t = index(path).unwrap_or(0);
        let frame = load_image(path)?;
        if (frame.width, frame.height) != (w, h) {
            return Err(fail(format!(
                "{} is {}x{}, the first frame {w}x{h}: the frames must all have one size",
                path.display(),
                frame.width,
                frame.height
            )));
        }
        let v = flow.sample(w, h, t as f32)?;
        figures.push(frame, &super::advect::displacement(&v, dt))?;
    }
    let frames = paths.len();
    let report = figures.finish()?;
    let list = |v: &[f64]| {
        v.iter()
            .map(|x| json_number(*x))
            .collect::<Vec<_>>()
            .join(",")
    };
    let energy = report
        .energy
        .iter()
        .map(|(t, e)| format!("[{t},{}]", json_number(*e)))
        .collect::<Vec<_>>()
        .join(",");
    ui.out(format!(
        "{{\"frames\":{},\"mean_warped_diff\":{},\"mean_unwarped_diff\":{},\"mean_pops\":{},\"warped_diff\":[{}],\"pops\":[{}],\"energy\":[{}],\"sharpness\":[{}]}}",
        frames,
        json_number(report.mean_warped_diff()),
        json_number(report.mean_unwarped_diff()),
        json_number(report.mean_pops()),
        list(&report.warped_diff),
        list(&report.pops),
        energy,
        list(&report.sharpness)
    ))
}

fn json_number(v: f64) -> String {
    if v.is_finite() {
        format!("{v}")
    } else {
        "null".into()
    }
}

/// Any image texsyn reads (the library's hardened decoding: decoder panics, truncated
/// JPEGs, devices refused), as floats; non-finite samples (a float EXR) are refused, since
/// every figure would silently skip or absorb them.
fn load_image(path: &Path) -> CliResult<FloatImage> {
    let img = texsyn::image_io::open_image(path)?;
    texsyn::image_io::check_finite(&img, path, "image evaluated")?;
    Ok(FloatImage::from_dynamic(&img))
}

/// `--energy-map`: the per-window texture energy, centred on the output's pixels.
fn write_energy_map(
    path: &Path,
    exemplar: &FloatImage,
    output: &FloatImage,
    scale: f32,
) -> CliResult<()> {
    if !(scale > 0.0 && scale.is_finite()) {
        return Err(fail(format!(
            "--energy-scale {scale}: give a positive number"
        )));
    }
    let r = quality::DEFAULT_RADIUS;
    let map = quality::texture_energy_map(exemplar, output, r)?;
    let grey = map.to_grey8(scale);
    let (w, h) = (output.width, output.height);
    let mut rgba = vec![0u8; w as usize * h as usize * 4];
    for y in 0..map.height {
        for x in 0..map.width {
            let v = grey[(y * map.width + x) as usize];
            let i = (((y + r) * w + x + r) * 4) as usize;
            rgba[i..i + 3].fill(v);
            rgba[i + 3] = 255;
        }
    }
    texsyn::image_io::save_image_atomic(path, w, h, 1, &rgba)?;
    Ok(())
}
