//! CPU mirrors of the WGSL passes, one module per shader of the same name
//! (`shaders/upsample.wgsl` <-> `upsample.rs`), plus the synthesis plan that both the
//! GPU and the CPU follow. All arithmetic is integer, so GPU and CPU agree bit for bit.

pub mod advect;
pub mod common;
pub mod correct;
pub mod correct_aniso;
pub mod distortion;
pub mod drift;
pub mod fade;
pub mod fill;
pub mod gather;
pub mod gather_aniso;
pub mod gather_map;
pub mod jitter;
pub mod magnify;
pub mod plan;
pub mod resample;
pub mod upsample;
pub mod upsample_aniso;
pub mod velocity;
pub mod velocity_texture;

pub use plan::{DistanceMode, LevelPlan, PassKind, SynthParams, SynthPlan};

use crate::analysis::Analysis;
use crate::error::Result;
use plan::Dispatch;

/// A synthesized window: exemplar coordinates and RGBA8 colours, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Synthesis {
    /// Window width in pixels.
    pub width: u32,
    /// Window height in pixels.
    pub height: u32,
    /// Exemplar coordinates in units of `2^-coord_frac` exemplar pixels.
    pub coords: Vec<[i32; 2]>,
    /// RGBA8 colours.
    pub colors: Vec<[u8; 4]>,
    /// 0 for isometric synthesis (integer pixels), [`common::COORD_FRAC`] for
    /// anisometric synthesis (continuous coordinates).
    pub coord_frac: u32,
}

impl Synthesis {
    /// Coordinates in exemplar pixels.
    pub fn coords_f32(&self) -> Vec<[f32; 2]> {
        let s = 1.0 / (1u32 << self.coord_frac) as f32;
        self.coords
            .iter()
            .map(|c| [c[0] as f32 * s, c[1] as f32 * s])
            .collect()
    }
}

/// Tables of one level, as slices of the analysis.
pub fn level_tables(analysis: &Analysis, level: usize) -> correct::LevelTables<'_> {
    let l = &analysis.levels[level];
    correct::LevelTables {
        et: &l.et,
        qe: &l.qe,
        offsets: &l.offsets,
        proj: &l.proj,
    }
}

/// Runs dispatches of a schedule on the CPU over the concatenated coordinate array
/// (every level's region) and, for anisometric plans, the Jacobians in the same layout
/// ([`SynthPlan::jacobians`]). Returns the gather result if a gather dispatch ran.
pub fn run_cpu(
    analysis: &Analysis,
    schedule: &[Dispatch],
    coords: &mut [[i32; 2]],
    jac: &[[i32; 4]],
) -> Option<Synthesis> {
    run_cpu_surface(analysis, schedule, coords, jac, &[])
}

/// [`run_cpu`] for atlas synthesis: `surface` is the plan's surface buffer
/// ([`SynthPlan::surface_words`]).
pub fn run_cpu_surface(
    analysis: &Analysis,
    schedule: &[Dispatch],
    coords: &mut [[i32; 2]],
    jac: &[[i32; 4]],
    surface: &[u32],
) -> Option<Synthesis> {
    run_cpu_frame(analysis, schedule, coords, jac, surface, &[])
}

/// [`run_cpu_surface`] with an advection frame's velocity field (1/1024 output pixel per
/// frame, one per output-window pixel); `coords` then also holds the flag region and the
/// drift ([`SynthPlan::coord_buffer_len`]), and with fading the fade state
/// ([`SynthPlan::advect_buffer_len`]`(true)` entries).
pub fn run_cpu_frame(
    analysis: &Analysis,
    schedule: &[Dispatch],
    coords: &mut [[i32; 2]],
    jac: &[[i32; 4]],
    surface: &[u32],
    velocity: &[[i32; 2]],
) -> Option<Synthesis> {
    let mut out = None;
    for d in schedule {
        let gathered = match d.kind {
            PassKind::Upsample => {
                upsample::run(&d.params, coords);
                None
            }
            PassKind::UpsampleAniso => {
                upsample_aniso::run(&d.params, coords, jac);
                None
            }
            PassKind::Jitter => {
                jitter::run(&d.params, coords);
                None
            }
            PassKind::Correct => {
                correct::run(&d.params, &level_tables(analysis, d.level), coords);
                None
            }
            PassKind::CorrectAniso => {
                correct_aniso::run(
                    &d.params,
                    &level_tables(analysis, d.level),
                    coords,
                    jac,
                    surface,
                );
                None
            }
            PassKind::Fill => {
                fill::run(&d.params, coords, jac, surface);
                None
            }
            PassKind::Advect => {
                advect::advect(&d.params, coords, jac, velocity);
                None
            }
            PassKind::Drift => {
                drift::drift(&d.params, coords, velocity);
                None
            }
            PassKind::Distortion => {
                distortion::distortion(&d.params, coords, jac, surface);
                None
            }
            PassKind::Resample => {
                resample::run(&d.params, coords, jac);
                None
            }
            PassKind::Fade => Some(fade::run(
                &d.params,
                coords,
                jac,
                velocity,
                &analysis.colors,
            )),
            PassKind::Gather => Some(gather::run(&d.params, coords, &analysis.colors)),
            PassKind::GatherAniso => {
                Some(gather_aniso::run(&d.params, coords, jac, &analysis.colors))
            }
        };
        if let Some((c, col)) = gathered {
            out = Some(Synthesis {
                width: d.params.window_size[0] as u32,
                height: d.params.window_size[1] as u32,
                coords: c,
                colors: col,
                coord_frac: d.params.coord_frac,
            });
        }
    }
    out
}

/// The whole synthesis on the CPU (the reference the GPU is tested against).
pub fn synthesize_cpu(analysis: &Analysis, params: &SynthParams) -> Result<Synthesis> {
    analysis.validate()?;
    let plan = SynthPlan::new(analysis, params)?;
    let schedule = plan.schedule(analysis);
    let mut coords = vec![[0i32; 2]; plan.coord_count as usize];
    let jac = plan.jacobians();
    let surface = plan.surface_words().0;
    Ok(
        run_cpu_surface(analysis, &schedule, &mut coords, &jac, &surface)
            .expect("schedule ends with a gather"),
    )
}
