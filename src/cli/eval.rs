//! `texsyn eval`: quality figures of a synthesized image against its exemplar, as JSON.

use std::path::{Path, PathBuf};

use clap::Args;

use texsyn::{Evaluation, EvaluationNote};

use super::{CliResult, TileArgs, Ui};

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
    let mut evaluation = Evaluation::open(&args.exemplar)?;
    ui.warn_if_animation(&args.exemplar);
    if let Some(flow) = &args.flow {
        // The same checks as `advect` (a centre given in pixels, a core radius of 0).
        let flow = flow.load()?;
        flow.validate()?;
        let dt = super::time_step(args.dt)?;
        let report = evaluation
            .frames(&args.image, flow, dt)
            .energy_every(args.energy_every)
            .run()?;
        return ui.out(report.to_json());
    }
    // The energy map's path is checked before any work.
    if let Some(path) = &args.energy_map {
        super::check_output_dir(path)?;
        super::synth::check_save_extension(path)?;
        let mut inputs: Vec<(&str, &Path)> = vec![
            ("exemplar", &args.exemplar),
            ("image evaluated", &args.image),
        ];
        inputs.extend(args.coords.as_deref().map(|c| ("coordinate map", c)));
        inputs.extend(args.feature_mask.as_deref().map(|m| ("feature mask", m)));
        inputs.extend(super::field::FieldSpec::input(&args.field));
        super::check_outputs_not_inputs(&[path], &inputs)?;
        evaluation = evaluation.energy_map(args.energy_scale);
    }
    evaluation = evaluation
        .image_path(&args.image)
        .tileable(args.tile.get())
        .tolerance(args.tolerance)
        .on_note(|note| {
            if note == EvaluationNote::FractionalCoords {
                ui.info(
                    "note: the coordinate map is fractional (an anisometric synthesis?): the \
                     verbatim figures count exact integer copies; give --field SPEC (the field \
                     it was synthesized along) for the Jacobian figures instead",
                )
            }
        });
    if let Some(path) = &args.coords {
        evaluation = evaluation.coords_path(path);
    }
    if let Some(path) = &args.feature_mask {
        evaluation = evaluation.feature_mask_path(path);
    }
    if let Some(spec) = &args.field {
        evaluation = evaluation.field(|w, h| {
            spec.resolve([0, 0], w, h)
                .map_err(|e| texsyn::Error::InvalidParameter(e.to_string()))
        });
    }
    let report = evaluation.run()?;
    // Written before the figures are printed, so that a failed write prints none.
    if let (Some(path), Some(map)) = (&args.energy_map, report.energy_map()) {
        texsyn::image_io::save_image_atomic(path, map.width, map.height, 1, &map.rgba)?;
    }
    ui.out(report.to_json())
}
