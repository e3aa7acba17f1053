//! The GPU coordinate buffer's layout: every level's coordinates, then the flag region,
//! the advection drift and the fade state.

use super::SynthPlan;
use crate::passes::fill::SurfaceLayout;

impl SynthPlan {
    /// Where advection keeps its per-pixel distortion flags, and a synthesis its
    /// corrections' change stamps (see [`Self::schedule_with`]): after every level's
    /// coordinates. A coordinate buffer holds [`Self::coord_buffer_len`] entries.
    pub fn flag_base(&self) -> u32 {
        self.coord_count as u32
    }

    /// Entries of a GPU coordinate buffer for this plan: the coordinates, then the flag
    /// region ([`Self::flag_base`], [`Self::flag_count`]), then the two entries of the
    /// advection frames' drift ([`Self::drift_index`]).
    pub fn coord_buffer_len(&self) -> u64 {
        self.coord_count + self.flag_count() + 2
    }

    /// Where an advection keeps its drift: the whole finest pixels the flow's centre
    /// has moved since frame 0 (the sum of its velocity rounded frame by frame), before
    /// and after the current frame (`PassParams::drift`; zero at frame 0).
    pub fn drift_index(&self) -> u32 {
        (self.coord_count + self.flag_count()) as u32
    }

    /// Where an advection with fading keeps its two halves of fade state
    /// (`passes::fade`): after the drift, each [`Self::fade_half_len`] entries.
    pub fn fade_base(&self) -> u32 {
        self.drift_index() + 2
    }

    /// Entries of one half of the fade state: [`crate::passes::fade::STATE_ENTRIES`] per pixel
    /// of the finest level's region.
    pub fn fade_half_len(&self) -> u64 {
        let fin = self.levels.last().expect("a plan has levels");
        crate::passes::fade::STATE_ENTRIES as u64 * fin.size[0] as u64 * fin.size[1] as u64
    }

    /// Entries of an advection's coordinate buffer: [`Self::coord_buffer_len`], plus
    /// the two halves of fade state with `fade`.
    pub fn advect_buffer_len(&self, fade: bool) -> u64 {
        self.coord_buffer_len() + if fade { 2 * self.fade_half_len() } else { 0 }
    }

    /// Entries of the flag region (the largest level).
    pub fn flag_count(&self) -> u64 {
        self.levels
            .iter()
            .map(|l| l.size[0] as u64 * l.size[1] as u64)
            .max()
            .unwrap_or(0)
    }

    /// The surface buffer (chart masks and indirection entries) of an atlas synthesis;
    /// empty otherwise.
    pub fn surface_words(&self) -> (Vec<u32>, Vec<SurfaceLayout>) {
        match &self.params.surface {
            Some(d) => d.surface_words(self.levels.len()),
            None => (Vec::new(), Vec::new()),
        }
    }
}
