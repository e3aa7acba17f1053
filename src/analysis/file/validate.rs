//! Consistency of an analysis's public fields, as a file must have them.

use super::*;

impl Analysis {
    /// Checks that the public fields agree with each other as an analysis file must
    /// (sizes, k, the level pyramid, every table's length): [`Analysis::load`] does it
    /// for files, [`crate::gpu::synth::GpuSynthesizer::new`] and
    /// [`crate::passes::synthesize_cpu`] for analyses built or edited by hand, so those
    /// fail with [`Error::InvalidParameter`] instead of indexing out of bounds later.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(Error::InvalidParameter(format!("analysis: {m}")));
        let (width, height) = (self.width, self.height);
        if !(MIN_SIDE..=MAX_SIDE).contains(&width) || !(MIN_SIDE..=MAX_SIDE).contains(&height) {
            return bad(format!(
                "{width}x{height}: sides must be {MIN_SIDE}..={MAX_SIDE}"
            ));
        }
        if self.channels != 1 && self.channels != 3 {
            return bad(format!("{} channels, expected 1 or 3", self.channels));
        }
        if !(1..=MAX_K).contains(&self.k) {
            return bad(format!("k is {}, expected 1..={MAX_K}", self.k));
        }
        let pixels = width as usize * height as usize;
        if self.colors.len() != pixels {
            return bad(format!("{} colours for {pixels} pixels", self.colors.len()));
        }
        let top = level_count(width, height);
        if self.levels.len() != top as usize + 1 {
            return bad(format!(
                "{} levels, expected {} for a {width}x{height} exemplar",
                self.levels.len(),
                top + 1
            ));
        }
        for (l, level) in self.levels.iter().enumerate() {
            let expected_spacing = 1u32 << (top - l as u32);
            if level.spacing != expected_spacing {
                return bad(format!(
                    "level {l} spacing is {}, expected {expected_spacing}",
                    level.spacing
                ));
            }
            if level.margin.saturating_mul(2) >= width.min(height) {
                return bad(format!("level {l} margin {} is too large", level.margin));
            }
            if level.shift >= 32 {
                return bad(format!("level {l} shift is {}, expected < 32", level.shift));
            }
            let offsets = pixels * (self.k as usize - 1);
            // The finest level's sets may be left out (AnalysisOptions::finest_sets), and
            // with them its tables; level 0 never has tables (LevelData::et).
            let finest = l + 1 == self.levels.len();
            let tables = if level.et.is_empty() && (l == 0 || finest) {
                0
            } else {
                pixels
            };
            for (name, len, expected) in [
                ("et", level.et.len(), tables),
                ("qe", level.qe.len(), tables),
                ("offsets", level.offsets.len(), offsets),
            ] {
                if len != expected && !(finest && name == "offsets" && len == 0) {
                    return bad(format!(
                        "level {l} {name} has {len} entries, expected {expected}"
                    ));
                }
            }
            // A finest level without tables cannot have sets: they serve its correction.
            if finest && tables == 0 && !level.offsets.is_empty() {
                return bad(format!("level {l} has similarity sets but no et/qe tables"));
            }
        }
        Ok(())
    }
}
