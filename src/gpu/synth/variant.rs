//! Pipeline variants: the switches a dispatch's parameters compile into its pipeline as
//! WGSL overrides, and which of them each pass reads.

use crate::passes::common::PassParams;
use crate::passes::plan::{Dispatch, PassKind, SynthPlan};

/// The switches compiled into a pass pipeline as WGSL overrides (`shaders/shared/
/// common.wgsl`): a pipeline per combination in use, so that CPU drivers do not run the
/// branches a dispatch never takes. Bits 0-10: the flags of [`Self::FLAGS`]; bits 11-13:
/// the similarity-set size k - 1; bit 14 DRIFT, bit 15 LONG_FADE.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Variant(pub(super) u16);

impl Variant {
    const FLAGS: [&'static str; 11] = [
        "TILEABLE",
        "FULL_DISTANCE",
        "KSET_INTERP",
        "MASKED",
        "PERIODIC",
        "QUARTER",
        "FINE_TABLES",
        "IDENTITY_J",
        "NEAREST",
        "SEAM_BLEND",
        "COHERENT_SKIP",
    ];
    const K_SHIFT: u32 = 11;
    /// The bits only the correction passes read: FULL_DISTANCE, KSET_INTERP, QUARTER,
    /// FINE_TABLES, COHERENT_SKIP and k.
    const CORRECTION_ONLY: u16 = 0b11_1100_0110_0110;
    /// The bits only the gathers read: NEAREST and SEAM_BLEND.
    const GATHER_ONLY: u16 = 0b11 << 8;
    const SEAM_BLEND: u16 = 1 << 9;
    const FINE_TABLES: u16 = 1 << 6;
    const IDENTITY_J: u16 = 1 << 7;
    /// Above k's bits: `params.drift != 0`, which only the anisometric upsampling
    /// branches on (an advection frame's drift phase): compiled in rather than a uniform
    /// branch, which slowed every synthesis along a field on CPU drivers.
    const DRIFT: u16 = 1 << 14;
    /// `params.fade_frames > 1`, which only the fade pass branches on.
    const LONG_FADE: u16 = 1 << 15;
    const K_MASK: u16 = 0b111;

    /// The switches of a dispatch, from the parameters the CPU mirror reads
    /// (FINE_TABLES off: see [`Self::with_fine_tables`]).
    pub(crate) fn of(p: &PassParams) -> Self {
        let flags = [
            p.tileable != 0,
            p.full_distance != 0,
            p.kset_interp != 0,
            p.masked != 0,
            p.periodic != 0,
            p.quarter != 0,
            false,
            false,
            p.nearest != 0,
            p.seam_blend != 0,
            p.coherent_skip != 0,
        ];
        let k = (p.k.clamp(1, crate::analysis::MAX_K as i32) - 1) as u16;
        let high = if p.drift != 0 { Self::DRIFT } else { 0 }
            | if p.fade_frames > 1 {
                Self::LONG_FADE
            } else {
                0
            };
        Self(
            flags
                .iter()
                .enumerate()
                .fold((k << Self::K_SHIFT) | high, |v, (i, &b)| {
                    v | (u16::from(b) << i)
                }),
        )
    }

    /// The same, reading the level's quarter-pixel tables ([`FineTables`](super::buffers::FineTables)).
    pub(super) fn with_fine_tables(self) -> Self {
        Self(self.0 | Self::FINE_TABLES)
    }

    /// The switches of a dispatch of `plan`: [`Self::of`], plus IDENTITY_J where the
    /// plan's Jacobians are all the identity ([`SynthPlan::identity_jacobians`]), so that
    /// the passes use the constant instead of reading it.
    pub(super) fn of_dispatch(plan: &SynthPlan, d: &Dispatch) -> Self {
        let v = Self::of(&d.params);
        if plan.identity_jacobians() {
            Self(v.0 | Self::IDENTITY_J)
        } else {
            v
        }
    }

    /// The switches only the correction passes read are reset for the others, so they
    /// share one pipeline across levels.
    pub(super) fn for_kind(self, kind: PassKind) -> Self {
        // DRIFT only matters to the anisometric upsampling, LONG_FADE to the fade.
        let v = if kind == PassKind::UpsampleAniso {
            self.0 & !Self::LONG_FADE
        } else if kind == PassKind::Fade {
            self.0
        } else {
            self.0 & !(Self::DRIFT | Self::LONG_FADE)
        };
        match kind {
            PassKind::Correct | PassKind::CorrectAniso => Self(v & !Self::GATHER_ONLY),
            PassKind::Gather | PassKind::GatherAniso => Self(v & !Self::CORRECTION_ONLY),
            // The resampling rounds to whole texels where the gather reads the nearest.
            PassKind::Resample | PassKind::Fade => {
                Self(v & !(Self::CORRECTION_ONLY | Self::SEAM_BLEND))
            }
            _ => Self(v & !(Self::CORRECTION_ONLY | Self::GATHER_ONLY)),
        }
    }

    /// The override values of this variant.
    pub(super) fn constants(self) -> Vec<(&'static str, f64)> {
        let mut c: Vec<(&str, f64)> = Self::FLAGS
            .iter()
            .enumerate()
            .map(|(i, &name)| (name, f64::from((self.0 >> i) & 1)))
            .collect();
        c.push((
            "K",
            f64::from(((self.0 >> Self::K_SHIFT) & Self::K_MASK) + 1),
        ));
        c.push(("DRIFT", f64::from(u16::from(self.0 & Self::DRIFT != 0))));
        c.push((
            "LONG_FADE",
            f64::from(u16::from(self.0 & Self::LONG_FADE != 0)),
        ));
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn variant_constants_follow_the_parameters() {
        let p = PassParams {
            tileable: 1,
            full_distance: 1,
            periodic: 1,
            k: 3,
            ..Default::default()
        };
        let v = Variant::of(&p);
        let c = v.constants();
        let get = |n: &str| c.iter().find(|(name, _)| *name == n).unwrap().1;
        assert_eq!(
            [
                get("TILEABLE"),
                get("FULL_DISTANCE"),
                get("KSET_INTERP"),
                get("MASKED"),
                get("PERIODIC"),
                get("K")
            ],
            [1.0, 1.0, 0.0, 0.0, 1.0, 3.0]
        );
        // Other passes keep the exemplar and output switches, not the correction's.
        let g = v.for_kind(PassKind::Gather).constants();
        let get = |n: &str| g.iter().find(|(name, _)| *name == n).unwrap().1;
        assert_eq!(
            [
                get("TILEABLE"),
                get("FULL_DISTANCE"),
                get("PERIODIC"),
                get("K")
            ],
            [1.0, 0.0, 1.0, 1.0]
        );
        assert_eq!(v.for_kind(PassKind::CorrectAniso), v);
        // The gathers' switches reach the gathers only.
        let w = Variant::of(&PassParams {
            nearest: 1,
            seam_blend: 1,
            ..p
        });
        let on = |v: Variant, n: &str| v.constants().iter().find(|(name, _)| *name == n).unwrap().1;
        for kind in [PassKind::Gather, PassKind::GatherAniso] {
            assert_eq!(
                [
                    on(w.for_kind(kind), "NEAREST"),
                    on(w.for_kind(kind), "SEAM_BLEND")
                ],
                [1.0, 1.0]
            );
        }
        for kind in [PassKind::CorrectAniso, PassKind::Upsample, PassKind::Advect] {
            assert_eq!(
                [
                    on(w.for_kind(kind), "NEAREST"),
                    on(w.for_kind(kind), "SEAM_BLEND")
                ],
                [0.0, 0.0]
            );
        }
        assert_eq!(w.for_kind(PassKind::Correct), v);
    }
}
