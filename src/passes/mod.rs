//! CPU mirrors of the WGSL passes, one module per shader of the same name
//! (`shaders/upsample.wgsl` <-> `upsample.rs`), plus the synthesis plan that both the
//! GPU and the CPU follow. All arithmetic is integer, so GPU and CPU agree bit for bit.

pub mod common;
pub mod correct;
pub mod gather;
pub mod jitter;
pub mod plan;
pub mod upsample;

pub use plan::{DistanceMode, LevelPlan, SynthParams, SynthPlan};

use crate::analysis::Analysis;
use crate::error::Result;
use plan::{Dispatch, PassKind};

/// A synthesized window: exemplar coordinates and RGBA8 colours, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Synthesis {
    pub width: u32,
    pub height: u32,
    pub coords: Vec<[i32; 2]>,
    pub colors: Vec<[u8; 4]>,
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
/// (every level's region). Returns the gather result if a gather dispatch ran.
pub fn run_cpu(
    analysis: &Analysis,
    schedule: &[Dispatch],
    coords: &mut [[i32; 2]],
) -> Option<Synthesis> {
    let mut out = None;
    for d in schedule {
        match d.kind {
            PassKind::Upsample => upsample::run(&d.params, coords),
            PassKind::Jitter => jitter::run(&d.params, coords),
            PassKind::Correct => correct::run(&d.params, &level_tables(analysis, d.level), coords),
            PassKind::Gather => {
                let (c, col) = gather::run(&d.params, coords, &analysis.colors);
                out = Some(Synthesis {
                    width: d.params.window_size[0] as u32,
                    height: d.params.window_size[1] as u32,
                    coords: c,
                    colors: col,
                });
            }
        }
    }
    out
}

/// The whole synthesis on the CPU (the reference the GPU is tested against).
pub fn synthesize_cpu(analysis: &Analysis, params: &SynthParams) -> Result<Synthesis> {
    let plan = SynthPlan::new(analysis, params)?;
    let schedule = plan.schedule(analysis);
    let mut coords = vec![[0i32; 2]; plan.coord_count as usize];
    Ok(run_cpu(analysis, &schedule, &mut coords).expect("schedule ends with a gather"))
}
