//! What an advection session says: the notes of its set-up and the summary of its
//! frames (costs, temporal figures, and the hints they call for), as data with the
//! wording of `texsyn advect`.

use std::fmt;
use std::path::PathBuf;
use std::time::Duration;

use crate::passes::PassKind;
use crate::quality::TemporalReport;

/// Why the session keeps the look or carries the texture.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SchemeReason {
    /// Keeping the look was asked for.
    KeepLookAsked,
    /// Keeping the look is the default: the desired Jacobian is the same everywhere.
    KeepLookDefault,
    /// Carrying was asked for.
    CarryAsked,
    /// Advecting the finest level asks for the paper's scheme.
    AdvectFinest,
    /// Re-synthesized levels ask for the paper's scheme.
    Resynthesize,
    /// Fewer than 3 levels ask for the paper's scheme.
    FewLevels,
    /// Carrying is the default: on a mesh or along a varying field.
    CarryDefault,
    /// The options were given as they are.
    Options,
}

/// A note of the session's set-up, in the order they arise; `Display` gives the line
/// `texsyn advect` prints.
#[derive(Clone, Debug, PartialEq)]
pub enum AdvectNote {
    /// On a mesh a vortex or a source turns about the mesh's centre: the flow's own
    /// centre (not the middle) is not used.
    CentreNotUsed {
        /// The centre given, fractions of the size.
        centre: [f32; 2],
    },
    /// A fade-change threshold was given without fading.
    FadeChangeWithoutFade,
    /// An anchored renewals' upsampled share was given without anchored renewals.
    AnchorUpsampleWithoutAnchor,
    /// The exemplar image is an animation: its first frame is used.
    AnimatedExemplar {
        /// The image.
        path: PathBuf,
        /// Its frame count.
        frames: usize,
    },
    /// The GPU adapter the session runs on.
    Adapter(String),
    /// The scheme chosen.
    Scheme {
        /// Keeping the look (else carrying the texture).
        keep_look: bool,
        /// Frames a renewal fades in over (0: off).
        fade: u32,
        /// Why.
        reason: SchemeReason,
    },
}

impl fmt::Display for AdvectNote {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AdvectNote::CentreNotUsed { centre: c } => write!(
                f,
                "note: the flow's centre {},{} is not used on a mesh (its vortex or source is \
                 centred on the mesh's centre)",
                c[0], c[1]
            ),
            AdvectNote::FadeChangeWithoutFade => {
                f.write_str("note: --fade-change has no effect without fading (--fade 1 or more)")
            }
            AdvectNote::AnchorUpsampleWithoutAnchor => f.write_str(
                "note: --anchor-upsample has no effect without anchored renewals (--anchor N)",
            ),
            AdvectNote::AnimatedExemplar { path, frames } => write!(
                f,
                "warning: {} is an animation of {frames} frames; texsyn uses its first frame \
                 (extract another frame to use it)",
                path.display()
            ),
            AdvectNote::Adapter(a) => write!(f, "adapter: {a}"),
            AdvectNote::Scheme {
                keep_look: true,
                fade,
                reason,
            } => write!(
                f,
                "advection: keeping the look, {} (--keep-look{})",
                match fade {
                    0 => "renewals not faded".to_string(),
                    n => format!("renewals faded over {n} frame{}", plural(*n)),
                },
                match reason {
                    SchemeReason::KeepLookDefault =>
                        "; the default here, --carry carries the texture instead",
                    _ => "",
                }
            ),
            AdvectNote::Scheme { reason, .. } => write!(
                f,
                "advection: carrying the texture (the paper's scheme{})",
                match reason {
                    SchemeReason::CarryAsked => ", --carry",
                    SchemeReason::AdvectFinest => ", with --advect-finest",
                    SchemeReason::Resynthesize => ", with --resynthesize",
                    SchemeReason::FewLevels => ", with --levels below 3",
                    SchemeReason::CarryDefault =>
                        ", the default on a mesh or along a varying field",
                    _ => "",
                }
            ),
        }
    }
}

/// Per-frame costs of a session.
#[derive(Clone, Debug)]
pub struct AdvectCosts {
    /// Median GPU time of a step, synchronized.
    pub frame: Duration,
    /// The later half of a run of 16 frames or more: how many frames, their median.
    pub late: Option<(usize, Duration)>,
    /// Medians of a whole synthesis of the output and of one with the frames' plan
    /// (with [`compare_cost`](super::AdvectSessionBuilder::compare_cost)).
    pub synthesis: Option<(Duration, Duration)>,
    /// Per frame, each dispatch's kind, level and time (with
    /// [`profile_passes`](super::AdvectSessionBuilder::profile_passes)).
    pub passes: Option<Vec<Vec<(PassKind, usize, Duration)>>>,
}

/// What an advection session's frames cost and how they hold together over time.
#[derive(Clone, Debug)]
pub struct AdvectSummary {
    /// Per-frame costs.
    pub costs: AdvectCosts,
    /// Frame-to-frame differences, pops, texture energy and sharpness.
    pub figures: TemporalReport,
    pub(super) keep_look: bool,
    pub(super) constant_jacobian: bool,
    pub(super) preview_size: [u32; 2],
}

impl AdvectSummary {
    /// The cost lines: a frame's median as a share of a whole synthesis, and of the
    /// later frames alone.
    pub fn cost_lines(&self) -> Vec<String> {
        let c = &self.costs;
        let share = |d: Duration, of: Duration| 100.0 * d.as_secs_f64() / of.as_secs_f64();
        let mut lines = vec![format!(
            "cost per frame (GPU, synchronized, median{}): {}{}",
            if c.passes.is_some() {
                ", one submission per dispatch"
            } else {
                ""
            },
            fmt_duration(c.frame),
            match c.synthesis {
                Some((full, frame0)) => format!(
                    " = {:.0}% of a whole synthesis ({}), {:.0}% of a whole synthesis with \
                     the frames' plan ({}: anisometric, finest level corrected, no seam \
                     blending)",
                    share(c.frame, full),
                    fmt_duration(full),
                    share(c.frame, frame0),
                    fmt_duration(frame0)
                ),
                None => String::new(),
            }
        )];
        if let Some((n, late)) = c.late {
            lines.push(format!(
                "  the last {n} frames alone: {}{}",
                fmt_duration(late),
                match c.synthesis {
                    Some((full, _)) => format!(" = {:.0}% of a whole synthesis", share(late, full)),
                    None => String::new(),
                }
            ));
        }
        lines
    }

    /// The temporal figures' lines, with the hints they call for: the frame-to-frame
    /// difference, popping, texture energy and sharpness.
    pub fn figure_lines(&self) -> Vec<String> {
        let report = &self.figures;
        let mut lines = Vec::new();
        let warped = report.mean_warped_diff();
        let unwarped = report.mean_unwarped_diff();
        lines.push(if warped.is_finite() {
            format!("frame-to-frame difference, warped by the flow: {warped:.4} (unwarped {unwarped:.4})")
        } else {
            // The figures leave out a 4-pixel border (the flow brings new texture in).
            let why = if self.preview_size[0] < 9 || self.preview_size[1] < 9 {
                "frames under 9 pixels a side: the measure leaves out a 4-pixel border"
            } else {
                "the flow moves every pixel out of view between frames"
            };
            format!(
                "frame-to-frame difference, warped by the flow: not measurable ({why}){}",
                if unwarped.is_finite() {
                    format!("; unwarped {unwarped:.4}")
                } else {
                    String::new()
                }
            )
        });
        let pops = report.mean_pops();
        if pops.is_finite() {
            lines.push(format!(
                "popping: {:.2}% of the 8x8 blocks per frame change by more than 0.15 of full \
                 scale on average, warped by the flow",
                100.0 * pops
            ));
            if self.keep_look && pops > 0.02 && !self.constant_jacobian {
                lines.push(
                    "  --keep-look remakes the fine detail wherever the desired Jacobian changes \
                     along the flow, which on a mesh's atlas or along a varying --field is almost \
                     everywhere: without it (--carry, the default there) the texture is carried \
                     and pops far less (docs/advection.md)"
                        .into(),
                );
            }
        }
        let energies: Vec<String> = report
            .energy
            .iter()
            .map(|(t, e)| format!("frame {t}: {e:.5}"))
            .collect();
        // The last frame's energy over the first's: how much the texture degraded.
        let rise = match (report.energy.first(), report.energy.last()) {
            (Some(&(t0, e0)), Some(&(t1, e1))) if t1 > t0 && e0 > 0.0 => Some(e1 / e0),
            _ => None,
        };
        lines.push(match rise {
            Some(r) => format!(
                "texture energy: {} (last / first: x{r:.2})",
                energies.join(", ")
            ),
            None => format!("texture energy: {}", energies.join(", ")),
        });
        if let Some(r) = rise.filter(|&r| r > 1.2 && !self.keep_look) {
            lines.push(format!(
                "  the texture energy rose {r:.2}x: the flow breaks the texture up as it turns or \
                 stretches it; {} (docs/advection.md)",
                if self.constant_jacobian {
                    "--keep-look (the default here, unless --carry, --advect-finest, \
                     --resynthesize or --levels below 3 is given) remakes it as it moves and \
                     keeps its look"
                } else {
                    "--keep-look remakes it as it moves and keeps its look, but pops on a mesh or \
                     along a varying field"
                }
            ));
        }
        let (first, last) = (
            report.sharpness.first().copied().unwrap_or(f64::NAN),
            report.sharpness.last().copied().unwrap_or(f64::NAN),
        );
        lines.push(if first.is_finite() && last.is_finite() {
            format!(
                "sharpness (high-frequency energy / exemplar's): first {first:.3}, last {last:.3}"
            )
        } else {
            "sharpness: not measurable (the exemplar has no high frequencies to compare with)"
                .to_string()
        });
        lines
    }
}

fn plural(n: u32) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}

/// `12.3 ms`, `1.23 s`, `850 us`.
fn fmt_duration(d: Duration) -> String {
    let s = d.as_secs_f64();
    if s >= 10.0 {
        format!("{s:.1} s")
    } else if s >= 1.0 {
        format!("{s:.2} s")
    } else if s >= 1e-3 {
        format!("{:.1} ms", s * 1e3)
    } else {
        format!("{:.0} us", s * 1e6)
    }
}
