//! The whole set of figures for one output ([`evaluate`], [`QualityReport`] and its
//! stable JSON form, printed by `texsyn eval`), and the shuffled-pixels baseline that
//! gives the figures a scale.

use super::common::{json_num, splitmix};
use super::energy::{coarse_energies, texture_energy};
use super::histogram::histogram_distance;
use super::image::FloatImage;
use super::repetition::{layout_repetition, LayoutRepetition};
use super::verbatim::{verbatim_stats, CoordMap, VerbatimStats};
use crate::error::Result;

/// All quality figures of one output.
#[derive(Clone, Debug, PartialEq)]
pub struct QualityReport {
    /// Neighbourhood radius of the texture energy.
    pub radius: u32,
    /// Exemplar `[width, height]` in pixels.
    pub exemplar_size: [u32; 2],
    /// Output `[width, height]` in pixels.
    pub output_size: [u32; 2],
    /// Channels compared (after matching).
    pub channels: u32,
    /// [`multiscale_energy`]: full, half, quarter resolution (`NaN` where too small).
    ///
    /// [`multiscale_energy`]: super::multiscale_energy
    pub energy: [f64; 3],
    /// The same at full resolution, and [`coarse_energy_any_phase`] at half and quarter.
    ///
    /// [`coarse_energy_any_phase`]: super::coarse_energy_any_phase
    pub energy_any_phase: [f64; 3],
    /// [`histogram_distance`] per channel.
    pub histogram: Vec<f64>,
    /// Mean of `histogram`.
    pub histogram_mean: f64,
    /// [`verbatim_stats`] when a coordinate map was given.
    pub verbatim: Option<VerbatimStats>,
    /// [`layout_repetition`] when a coordinate map was given.
    pub repetition: Option<LayoutRepetition>,
}

impl QualityReport {
    /// Stable JSON form:
    /// `{"radius":3,"exemplar":{"width":..,"height":..},"output":{..},"channels":3,
    /// "texture_energy":{"full":..,"half":..,"quarter":..},
    /// "texture_energy_any_phase":{"full":..,"half":..,"quarter":..},
    /// "histogram_emd":{"per_channel":[..],"mean":..},
    /// "verbatim":{"coherent_fraction":..,"largest_region_fraction":..,
    /// "largest_region_pixels":..,"regions":..} or null,
    /// "repetition":{"share":..,"vector":[dx,dy]} or null}`. Non-finite numbers are `null`.
    pub fn to_json(&self) -> String {
        let per_channel: Vec<String> = self.histogram.iter().map(|&v| json_num(v)).collect();
        let verbatim = match &self.verbatim {
            None => "null".to_string(),
            Some(v) => format!(
                "{{\"coherent_fraction\":{},\"largest_region_fraction\":{},\"largest_region_pixels\":{},\"regions\":{}}}",
                json_num(v.coherent_fraction),
                json_num(v.largest_region_fraction),
                v.largest_region_pixels,
                v.regions
            ),
        };
        let repetition = match &self.repetition {
            None => "null".to_string(),
            Some(r) => format!(
                "{{\"share\":{},\"vector\":[{},{}]}}",
                json_num(r.share),
                json_num(r.vector[0]),
                json_num(r.vector[1])
            ),
        };
        format!(
            "{{\"radius\":{},\"exemplar\":{{\"width\":{},\"height\":{}}},\"output\":{{\"width\":{},\"height\":{}}},\"channels\":{},\
             \"texture_energy\":{{\"full\":{},\"half\":{},\"quarter\":{}}},\
             \"texture_energy_any_phase\":{{\"full\":{},\"half\":{},\"quarter\":{}}},\
             \"histogram_emd\":{{\"per_channel\":[{}],\"mean\":{}}},\"verbatim\":{},\"repetition\":{}}}",
            self.radius,
            self.exemplar_size[0],
            self.exemplar_size[1],
            self.output_size[0],
            self.output_size[1],
            self.channels,
            json_num(self.energy[0]),
            json_num(self.energy[1]),
            json_num(self.energy[2]),
            json_num(self.energy_any_phase[0]),
            json_num(self.energy_any_phase[1]),
            json_num(self.energy_any_phase[2]),
            per_channel.join(","),
            json_num(self.histogram_mean),
            verbatim,
            repetition
        )
    }
}

/// Computes every figure: [`multiscale_energy`] with `radius` (use [`DEFAULT_RADIUS`]
/// for the standard 7x7 windows) and [`coarse_energy_any_phase`], [`histogram_distance`],
/// and [`verbatim_stats`] and [`layout_repetition`] when a coordinate map is given (its
/// exemplar size is `exemplar`'s).
///
/// [`multiscale_energy`]: super::multiscale_energy
/// [`coarse_energy_any_phase`]: super::coarse_energy_any_phase
/// [`DEFAULT_RADIUS`]: super::DEFAULT_RADIUS
pub fn evaluate(
    exemplar: &FloatImage,
    output: &FloatImage,
    radius: u32,
    coords: Option<CoordMap<'_>>,
) -> Result<QualityReport> {
    let full = texture_energy(exemplar, output, radius)?;
    let (grid, any) = coarse_energies(exemplar, output, radius)?;
    let energy = [full, grid[0], grid[1]];
    let energy_any_phase = [full, any[0], any[1]];
    let histogram = histogram_distance(exemplar, output)?;
    let histogram_mean = histogram.iter().sum::<f64>() / histogram.len().max(1) as f64;
    let (verbatim, repetition) = match coords {
        None => (None, None),
        Some(c) => (
            Some(verbatim_stats(
                c.coords,
                c.width,
                c.height,
                exemplar.width,
                exemplar.height,
                c.tileable,
            )?),
            Some(layout_repetition(
                c.coords,
                c.width,
                c.height,
                exemplar.width,
                exemplar.height,
                c.tileable,
            )?),
        ),
    };
    Ok(QualityReport {
        radius,
        exemplar_size: [exemplar.width, exemplar.height],
        output_size: [output.width, output.height],
        channels: exemplar.channels.max(output.channels),
        energy,
        energy_any_phase,
        histogram,
        histogram_mean,
        verbatim,
        repetition,
    })
}

/// The "shuffled pixels" baseline: a `width x height` image whose pixels are drawn
/// uniformly at random (with replacement) from the exemplar, deterministically from
/// `seed`. An unusable exemplar gives a black image of its channel count (1 or 3).
pub fn shuffled_baseline(exemplar: &FloatImage, width: u32, height: u32, seed: u64) -> FloatImage {
    let n = width as usize * height as usize;
    if exemplar.validate().is_err() {
        let c = if exemplar.channels == 1 { 1 } else { 3 };
        return FloatImage {
            width,
            height,
            channels: c,
            data: vec![0.0; n * c as usize],
        };
    }
    let c = exemplar.channels as usize;
    let m = exemplar.pixel_count() as u64;
    let mut state = seed ^ 0x7e85_5eed_0000_0001;
    let mut data = Vec::with_capacity(n * c);
    for _ in 0..n {
        let i = ((splitmix(&mut state) as u128 * m as u128) >> 64) as usize;
        data.extend_from_slice(&exemplar.data[i * c..(i + 1) * c]);
    }
    FloatImage {
        width,
        height,
        channels: exemplar.channels,
        data,
    }
}
