//! [`Evaluation`]: the quality figures of a synthesized image, or of a folder of
//! advected frames, against its exemplar, with a stable JSON form (what `texsyn eval`
//! prints). The figures themselves are in [`crate::quality`].

mod frames;

use std::path::{Path, PathBuf};

use crate::analysis::{Exemplar, FeatureMask};
use crate::error::{Error, Result};
use crate::field::Field;
use crate::flow::Flow;
use crate::quality::{
    self, json_num, CoordMap, FeatureBreakage, FloatImage, JacobianReport, QualityReport,
    TemporalReport,
};

/// A value given directly, or the file to read it from when the evaluation runs.
enum Input<T> {
    Path(PathBuf),
    Value(T),
}

/// A coordinate map: `width`, `height` and one exemplar position per pixel.
type Coords = (u32, u32, Vec<[f32; 2]>);

/// The field for a coordinate map of a width and height.
type FieldFor<'a> = Box<dyn FnOnce(u32, u32) -> Result<Field> + 'a>;

/// Something worth telling the user that is not an error.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum EvaluationNote {
    /// The coordinate map holds fractional coordinates (an anisometric synthesis?) and
    /// no field was given: the verbatim figures count exact integer copies only, and a
    /// field would give the Jacobian figures instead.
    FractionalCoords,
}

/// The figures of one synthesized image against its exemplar, or (with
/// [`Evaluation::frames`]) of a folder of advected frames.
///
/// ```no_run
/// use texsyn::Evaluation;
/// let report = Evaluation::open("assets/gravel.png".as_ref())?
///     .image_path("out.png")
///     .coords_path("out.exr")
///     .run()?;
/// println!("{}", report.to_json());
/// # Ok::<(), texsyn::Error>(())
/// ```
pub struct Evaluation<'a> {
    exemplar: Exemplar,
    image: Option<Input<FloatImage>>,
    coords: Option<Input<Coords>>,
    tileable: Option<bool>,
    field: Option<FieldFor<'a>>,
    tolerance: f64,
    feature_mask: Option<Input<FeatureMask>>,
    energy_scale: Option<f32>,
    frames: Option<(PathBuf, Flow, f32)>,
    energy_every: usize,
    on_note: Box<dyn FnMut(EvaluationNote) + 'a>,
}

/// What [`Evaluation::run`] found.
#[derive(Clone, Debug)]
pub enum EvaluationReport {
    /// The figures of one image.
    Image(Box<ImageFigures>),
    /// The temporal figures of a folder of frames.
    Frames(FrameFigures),
}

/// The figures of one image ([`EvaluationReport::Image`]).
#[derive(Clone, Debug)]
pub struct ImageFigures {
    /// Energy, histogram and (with a coordinate map) verbatim and repetition figures.
    pub quality: QualityReport,
    /// [`quality::wrap_seam_ratio`] of the image.
    pub wrap_seam_ratio: f64,
    /// With a coordinate map and a feature mask: how the features survive.
    pub features: Option<FeatureBreakage>,
    /// With a coordinate map and a field: how the texture follows the field.
    pub jacobian: Option<JacobianReport>,
    /// With [`Evaluation::energy_map`]: where the texture energy lies.
    pub energy_map: Option<EnergyMapImage>,
}

/// The temporal figures of a folder of frames ([`EvaluationReport::Frames`]).
#[derive(Clone, Debug)]
pub struct FrameFigures {
    /// How many frames were read.
    pub frames: usize,
    /// The figures per pair of frames and per frame.
    pub temporal: TemporalReport,
}

/// The full-resolution texture energy as a grey image of the output's size: each pixel
/// the energy of the window centred on it, white at the scale given; the border, which
/// has no full window, black.
#[derive(Clone, Debug)]
pub struct EnergyMapImage {
    /// Width in pixels (the evaluated image's).
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// RGBA8, row-major, grey (R = G = B): save it with 1 channel.
    pub rgba: Vec<u8>,
}

impl<'a> Evaluation<'a> {
    /// An evaluation against `exemplar`; give it the image ([`Self::image`] or
    /// [`Self::image_path`]) or a folder of frames ([`Self::frames`]).
    pub fn new(exemplar: Exemplar) -> Self {
        Evaluation {
            exemplar,
            image: None,
            coords: None,
            tileable: None,
            field: None,
            tolerance: 0.15,
            feature_mask: None,
            energy_scale: None,
            frames: None,
            energy_every: 10,
            on_note: Box::new(|_| {}),
        }
    }

    /// [`Self::new`] with the exemplar image read from `path`; an analysis file is
    /// refused, since the figures compare pixels.
    pub fn open(path: &Path) -> Result<Self> {
        if super::is_analysis_file(path)? {
            return Err(Error::InvalidParameter(format!(
                "{} is an analysis file; eval needs the exemplar image itself (the one given to `texsyn analyze`)",
                path.display()
            )));
        }
        crate::image_io::load_exemplar(path).map(Self::new)
    }

    /// The image to evaluate.
    pub fn image(mut self, image: FloatImage) -> Self {
        self.image = Some(Input::Value(image));
        self
    }

    /// The image to evaluate, read when the evaluation runs.
    pub fn image_path(mut self, path: impl Into<PathBuf>) -> Self {
        self.image = Some(Input::Path(path.into()));
        self
    }

    /// The coordinate map the image was synthesized with (`width` x `height`, one
    /// exemplar position per pixel): adds the verbatim-copy and repetition figures.
    pub fn coords(mut self, width: u32, height: u32, coords: Vec<[f32; 2]>) -> Self {
        self.coords = Some(Input::Value((width, height, coords)));
        self
    }

    /// [`Self::coords`] from a coordinate-map OpenEXR (as `texsyn synth --coords-out`
    /// writes it).
    pub fn coords_path(mut self, path: impl Into<PathBuf>) -> Self {
        self.coords = Some(Input::Path(path.into()));
        self
    }

    /// Whether exemplar coordinates wrap around; `None` (the default): detected from the
    /// exemplar's seams, as the analysis does.
    pub fn tileable(mut self, tileable: Option<bool>) -> Self {
        self.tileable = tileable;
        self
    }

    /// With a coordinate map: the field the image was synthesized along, made for the
    /// map's width and height. Gives the Jacobian figures instead of the verbatim ones.
    pub fn field(mut self, field: impl FnOnce(u32, u32) -> Result<Field> + 'a) -> Self {
        self.field = Some(Box::new(field));
        self
    }

    /// Relative Frobenius tolerance of the Jacobian figures (default 0.15).
    pub fn tolerance(mut self, tolerance: f64) -> Self {
        self.tolerance = tolerance;
        self
    }

    /// With a coordinate map: the exemplar's feature mask, for the feature figures.
    pub fn feature_mask(mut self, mask: FeatureMask) -> Self {
        self.feature_mask = Some(Input::Value(mask));
        self
    }

    /// [`Self::feature_mask`] read from an image when the evaluation runs.
    pub fn feature_mask_path(mut self, path: impl Into<PathBuf>) -> Self {
        self.feature_mask = Some(Input::Path(path.into()));
        self
    }

    /// Also make the energy map ([`ImageFigures::energy_map`]), white at `scale` (a mean
    /// squared difference per channel).
    pub fn energy_map(mut self, scale: f32) -> Self {
        self.energy_scale = Some(scale);
        self
    }

    /// Temporal figures instead: `folder` holds consecutive `frame_NNNNN.png` files (as
    /// `texsyn advect` writes them) advected along `flow` with time step `dt`.
    pub fn frames(mut self, folder: impl Into<PathBuf>, flow: Flow, dt: f32) -> Self {
        self.frames = Some((folder.into(), flow, dt));
        self
    }

    /// With [`Self::frames`]: texture energy every `k`-th frame (0: the first and the
    /// last only; default 10).
    pub fn energy_every(mut self, k: usize) -> Self {
        self.energy_every = k;
        self
    }

    /// Called with what is worth telling the user but is no error.
    pub fn on_note(mut self, f: impl FnMut(EvaluationNote) + 'a) -> Self {
        self.on_note = Box::new(f);
        self
    }

    /// Computes the figures.
    pub fn run(mut self) -> Result<EvaluationReport> {
        if let Some((folder, flow, dt)) = self.frames.take() {
            let exemplar = FloatImage::from_exemplar(&self.exemplar);
            return frames::run(&exemplar, &folder, &flow, dt, self.energy_every)
                .map(EvaluationReport::Frames);
        }
        self.run_image()
            .map(|f| EvaluationReport::Image(Box::new(f)))
    }

    fn run_image(mut self) -> Result<ImageFigures> {
        let invalid = |m: String| Error::InvalidParameter(m);
        let (output, image_name) = match self.image.take() {
            Some(Input::Path(p)) => (load_image(&p)?, p.display().to_string()),
            Some(Input::Value(img)) => (img, "the image".to_string()),
            None => return Err(invalid("no image to evaluate".into())),
        };
        let exemplar = &self.exemplar;
        let mask = match self.feature_mask.take() {
            Some(Input::Path(path)) => {
                let mask = FeatureMask::load(&path)?;
                mask.check_size(exemplar.width, exemplar.height)?;
                Some(mask)
            }
            Some(Input::Value(mask)) => {
                mask.check_size(exemplar.width, exemplar.height)?;
                Some(mask)
            }
            None => None,
        };
        let coords = match self.coords.take() {
            None => None,
            Some(input) => {
                let (name, (w, h, c)) = match input {
                    Input::Path(p) => (
                        p.display().to_string(),
                        crate::image_io::load_coords_exr_f32(&p)?,
                    ),
                    Input::Value(v) => ("the coordinate map".to_string(), v),
                };
                let magnified = (2..=8).find(|f| (w * f, h * f) == (output.width, output.height));
                if (w, h) != (output.width, output.height) {
                    return Err(invalid(format!(
                        "{name} is {w}x{h} but {image_name} is {}x{}: give the coordinate map written together with the image{}",
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
                // Synthesized coordinates are exemplar positions: anything far outside
                // is not a coordinate map of this exemplar (another file, another one).
                let (ew, eh) = (exemplar.width as f32, exemplar.height as f32);
                if let Some(v) = c
                    .iter()
                    .find(|v| !(v[0] >= -1.0 && v[0] <= ew && v[1] >= -1.0 && v[1] <= eh))
                {
                    return Err(invalid(format!(
                        "{name}: coordinate ({}, {}) lies outside the {}x{} exemplar: give the coordinate \
                         map written with --coords-out for this exemplar",
                        v[0], v[1], exemplar.width, exemplar.height
                    )));
                }
                if self.field.is_none()
                    && c.iter().any(|v| v[0].fract() != 0.0 || v[1].fract() != 0.0)
                {
                    (self.on_note)(EvaluationNote::FractionalCoords);
                }
                Some((w, h, c))
            }
        };
        let tileable = self
            .tileable
            .unwrap_or_else(|| crate::analysis::detect_tileable(exemplar));
        let ex_size = [exemplar.width, exemplar.height];
        let exemplar = FloatImage::from_exemplar(exemplar);
        let jacobian = match (self.field.take(), &coords) {
            (Some(field), Some((w, h, c))) => {
                if !(self.tolerance > 0.0 && self.tolerance.is_finite()) {
                    return Err(invalid("--tolerance must be a positive number".into()));
                }
                let field = field(*w, *h)?;
                let t = self.tolerance;
                Some(quality::jacobian_fidelity(
                    c,
                    *w,
                    *h,
                    ex_size,
                    [0, 0],
                    &field,
                    t,
                )?)
            }
            _ => None,
        };
        // Verbatim figures count exact integer copies: meaningless along a field.
        let rounded: Option<Vec<[i32; 2]>> = match (&jacobian, &coords) {
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
        let quality = quality::evaluate(&exemplar, &output, quality::DEFAULT_RADIUS, map)?;
        let wrap_seam_ratio = quality::wrap_seam_ratio(&output)?;
        let features = match (&mask, &coords) {
            (Some(mask), Some((w, h, c))) => {
                Some(quality::feature_breakage(mask, c, *w, *h, tileable)?)
            }
            _ => None,
        };
        let energy_map = match self.energy_scale {
            Some(scale) => Some(energy_map(&exemplar, &output, scale)?),
            None => None,
        };
        Ok(ImageFigures {
            quality,
            wrap_seam_ratio,
            features,
            jacobian,
            energy_map,
        })
    }
}

impl EvaluationReport {
    /// The JSON form: [`ImageFigures::to_json`] or [`FrameFigures::to_json`].
    pub fn to_json(&self) -> String {
        match self {
            EvaluationReport::Image(f) => f.to_json(),
            EvaluationReport::Frames(f) => f.to_json(),
        }
    }

    /// The energy map, when one was asked for.
    pub fn energy_map(&self) -> Option<&EnergyMapImage> {
        match self {
            EvaluationReport::Image(f) => f.energy_map.as_ref(),
            EvaluationReport::Frames(_) => None,
        }
    }
}

impl ImageFigures {
    /// [`QualityReport::to_json`] with `"wrap_seam_ratio"` and, when computed,
    /// `"features"` and `"jacobian"` added; non-finite numbers are `null`.
    pub fn to_json(&self) -> String {
        let mut json = self.quality.to_json();
        json.pop();
        json.push_str(&format!(
            ",\"wrap_seam_ratio\":{}",
            json_num(self.wrap_seam_ratio)
        ));
        if let Some(b) = &self.features {
            json.push_str(&format!(",\"features\":{}", b.to_json()));
        }
        if let Some(j) = &self.jacobian {
            json.push_str(&format!(",\"jacobian\":{}", j.to_json()));
        }
        json.push('}');
        json
    }
}

impl FrameFigures {
    /// `{"frames":..,"mean_warped_diff":..,"mean_unwarped_diff":..,"mean_pops":..,
    /// "warped_diff":[..],"pops":[..],"energy":[[frame,energy],..],"sharpness":[..]}`;
    /// non-finite numbers are `null`.
    pub fn to_json(&self) -> String {
        let r = &self.temporal;
        let list = |v: &[f64]| v.iter().map(|x| json_num(*x)).collect::<Vec<_>>().join(",");
        let energy = r
            .energy
            .iter()
            .map(|(t, e)| format!("[{t},{}]", json_num(*e)))
            .collect::<Vec<_>>()
            .join(",");
        format!(
            "{{\"frames\":{},\"mean_warped_diff\":{},\"mean_unwarped_diff\":{},\"mean_pops\":{},\"warped_diff\":[{}],\"pops\":[{}],\"energy\":[{}],\"sharpness\":[{}]}}",
            self.frames,
            json_num(r.mean_warped_diff()),
            json_num(r.mean_unwarped_diff()),
            json_num(r.mean_pops()),
            list(&r.warped_diff),
            list(&r.pops),
            energy,
            list(&r.sharpness)
        )
    }
}

/// Any image texsyn reads, as floats; non-finite samples (a float EXR) are refused,
/// since every figure would silently skip or absorb them.
fn load_image(path: &Path) -> Result<FloatImage> {
    let img = crate::image_io::open_image(path)?;
    crate::image_io::check_finite(&img, path, "image evaluated")?;
    Ok(FloatImage::from_dynamic(&img))
}

/// The per-window texture energy, centred on the output's pixels.
fn energy_map(exemplar: &FloatImage, output: &FloatImage, scale: f32) -> Result<EnergyMapImage> {
    if !(scale > 0.0 && scale.is_finite()) {
        return Err(Error::InvalidParameter(format!(
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
    Ok(EnergyMapImage {
        width: w,
        height: h,
        rgba,
    })
}
