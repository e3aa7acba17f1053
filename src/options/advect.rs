//! The options of an advection: how each frame treats the pyramid.

use crate::error::{Error, Result};

/// The default pop test ([`crate::passes::advect::AdvectOptions::fade_change`],
/// `PassParams::fade_change`): a pixel that jumped fades where the jumps around it
/// ([`crate::passes::fade::popped`]) changed the colour by more than this on average (of 255;
/// `(|dR| + 2 |dG| + |dB|) / 4`). Most jumps are not pops: seams that moved, patches
/// remade alike.
pub const FADE_CHANGE: u32 = 45;

/// How an advection frame treats the pyramid (Lefebvre & Hoppe 2006 §7 and extensions).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdvectOptions {
    /// Levels each frame works on (the finest ones; the coarser ones keep frame 0's
    /// synthesis): with [`Self::upsample_finest`] the finest of them is upsampled, the
    /// [`Self::resynthesize`] levels below it re-synthesized and the others advected and
    /// corrected; otherwise all are advected and corrected. At least 2 with
    /// `upsample_finest`, `resynthesize + 2` with re-synthesized levels.
    pub levels: usize,
    /// Make the finest level each frame by upsampling the advected level above it, without
    /// correcting it, as a synthesis makes its finest level; that level is then corrected
    /// with whole passes every frame. Off: the finest level is advected and corrected too
    /// (the paper's scheme). On by default: cheaper per frame, and the texture keeps better.
    pub upsample_finest: bool,
    /// With [`Self::upsample_finest`]: levels below the finest that each frame
    /// re-synthesizes (upsampled following the drift's phase, corrected, no jitter)
    /// instead of advecting them. The texture energy stays near frame 0's under turning
    /// flows, at the price of more change between frames and more time. 0 (default)
    /// advects every level but the finest; the pyramid must have `resynthesize + 2`
    /// levels ([`Self::check_for_pyramid`]).
    pub resynthesize: usize,
    /// Distortion threshold `c` on `|J_obs - J|_F` (Jacobian units): pixels beyond it are
    /// upsampled again from the coarser level. A step off by a whole pixel on both sides
    /// is a patch seam and does not count; pixels with a seam on both sides of both axes
    /// continue no patch and are renewed at any `c` (see `distortion.wgsl`).
    pub threshold: f32,
    /// Correction passes per advected level and frame (the advected coordinates are
    /// nearly right already: one pass keeps a frame a fraction of a synthesis).
    pub passes: u32,
    /// Correction passes per frame of the coarsest advected level where it is not the most
    /// corrected one. `None` (default): 2 with [`Self::keep_look`] where the desired
    /// Jacobian is constant, else `passes` ([`SynthPlan::advect_coarsest_passes`]). A
    /// second pass there is cheap and lets renewals settle before the finer levels are
    /// remade from them; where `J` varies, more passes churn the level and pop more.
    ///
    /// [`SynthPlan::advect_coarsest_passes`]: crate::passes::plan::SynthPlan::advect_coarsest_passes
    pub coarsest_passes: Option<u32>,
    /// Gather the exemplar texel nearest to each coordinate instead of interpolating: the
    /// coordinates of a moving texture are fractional everywhere, and bilinear gathering
    /// blurs it visibly. On by default.
    pub nearest: bool,
    /// Score the most corrected level's similarity-set candidates at their bilinearly
    /// interpolated position, as the coherent ones (4 reads each), instead of at their
    /// nearest texel as synthesis does. Off by default: about the same quality for more
    /// time per frame.
    pub interpolate_sets: bool,
    /// Read the most corrected level's `Et` and `qe` (projected distance) at the quarter
    /// pixel nearest to each interpolated position ([`PassParams::quarter`]: one read of
    /// supersampled tables instead of four). On by default: the same quality, faster.
    ///
    /// [`PassParams::quarter`]: crate::passes::common::PassParams::quarter
    pub quarter_reads: bool,
    /// Leave the pixels inside coherent patches out of the corrections
    /// ([`PassParams::coherent_skip`]: all 8 neighbours continue the pixel's patch within
    /// a quarter pixel, so a correction would keep them). On by default: the same
    /// quality, faster.
    ///
    /// [`PassParams::coherent_skip`]: crate::passes::common::PassParams::coherent_skip
    pub skip_coherent: bool,
    /// Score the similarity-set candidates on every `sets_every`-th correction of a pixel,
    /// 1..=16 (the frames' own [`crate::SynthParams::sets_every`]); the other corrections
    /// score the coherent candidates only. With one pass this spreads over the frames on
    /// the most corrected level (and, with [`Self::keep_look`], on every advected level);
    /// with more, it applies to each frame's passes. Default 2: cheaper, nearly the same.
    pub sets_every: u32,
    /// Keep the texture's look under turning and divergent flows (with
    /// [`Self::upsample_finest`], no [`Self::resynthesize`]; [`Self::keep_look()`] gives
    /// tuned settings). The coarsest advected level is renewed past [`Self::threshold`] as
    /// usual; the advected levels below it are remade (upsampled, then corrected) wherever
    /// they moved other than rigidly (Jacobian off by more than
    /// [`KEEP_LOOK_REMAKE_THRESHOLD`]) and kept as advected elsewhere, so a uniform flow
    /// still moves them exactly. Every advected level runs all its subpasses every frame,
    /// and frame 0 makes the lower levels as the frames do. The price: under a turning flow
    /// the texture is continuously remade as it moves, and a frame costs more. Off by
    /// default.
    pub keep_look: bool,
    /// Fade pops in over this many frames (0: off, the default; at most
    /// [`MAX_FADE_FRAMES`]): a pixel whose coordinate jumped, where the jumps around it
    /// changed the colour by more than [`Self::fade_change`], shows a blend of its old
    /// content (carried with the flow) and its new one instead of changing at once
    /// ([`crate::passes::fade`]). The blend keeps the contrast (variance-preserving); only
    /// colours are blended, not coordinates.
    pub fade: u32,
    /// The fade's pop test (with [`Self::fade`]): a pixel that jumped fades where the mean
    /// colour change over its 3x3 neighbourhood (pixels that did not jump count 0)
    /// exceeds this, of 255 (`(|dR| + 2 |dG| + |dB|) / 4`). Lower fades more pops for a
    /// higher texture energy. Default [`FADE_CHANGE`].
    pub fade_change: u32,
    /// Anchored renewals on the coarsest advected level (0: off, the paper's scheme; at
    /// most [`MAX_ANCHOR_SPACING`]): a flagged pixel continues, along the desired
    /// Jacobian, the advected coordinate of one of the four anchors around it (a grid of
    /// this spacing; the continuation landing nearest the pixel's own) instead of being
    /// upsampled again, so a renewed patch shows nearly what it showed and pops less.
    /// Pixels no anchor continues (another patch, outside the chart, a different `J`) are
    /// upsampled, and so is a share of the others ([`Self::anchor_upsample`]). Off in
    /// [`Self::keep_look()`]: it raises the energy of textures with large structures.
    pub anchor_spacing: u32,
    /// With [`Self::anchor_spacing`]: the share of renewals (0 to 1) upsampled from the
    /// coarser level anyway, decided per anchor block. Anchors keep the content but never
    /// bring back the coarse levels' large structures, which then break up. Default 0.5.
    pub anchor_upsample: f32,
}

/// Widest anchor spacing ([`AdvectOptions::anchor_spacing`]).
pub const MAX_ANCHOR_SPACING: u32 = 64;

/// Longest fade in frames ([`AdvectOptions::fade`]).
pub const MAX_FADE_FRAMES: u32 = 64;

/// The fade of [`AdvectOptions::recommended`] (and of the CLI's `--keep-look`): the
/// fewest pops within the texture-energy target.
pub const KEEP_LOOK_FADE: u32 = 2;

/// The distortion threshold (Jacobian units) beyond which [`AdvectOptions::keep_look`]
/// remakes a pixel of the advected levels below the coarsest one: about 0.2 degrees of
/// turning. The 1/256-pixel rounding of neighbouring coordinates stays below it at every
/// level, so rigid motion keeps the advected texture.
pub const KEEP_LOOK_REMAKE_THRESHOLD: f32 = 0.005;

impl AdvectOptions {
    /// Options that keep the texture's look under turning and divergent flows (CLI
    /// `texsyn advect --keep-look`): [`Self::keep_look`] on 4 levels, a distortion
    /// threshold of 0.12 for the coarsest of them (about 5 degrees of turning or 12% of
    /// stretch, against 0.5) and the similarity sets on every fourth correction.
    pub fn keep_look() -> Self {
        Self {
            levels: 4,
            threshold: 0.12,
            sets_every: 4,
            keep_look: true,
            ..Self::default()
        }
    }

    /// The options to use for a synthesis with these parameters (the CLI's default):
    /// where the desired Jacobian is the same everywhere
    /// ([`SynthParams::constant_jacobian`]), [`Self::keep_look()`] with pops faded over
    /// [`KEEP_LOOK_FADE`] frames; on an atlas or along a varying field
    /// [`Self::default()`], the paper's scheme, which carries the texture there (keeping
    /// the look would remake it all over).
    ///
    /// [`SynthParams::constant_jacobian`]: crate::SynthParams::constant_jacobian
    pub fn recommended(params: &crate::SynthParams) -> Self {
        if params.constant_jacobian() {
            Self {
                fade: KEEP_LOOK_FADE,
                ..Self::keep_look()
            }
        } else {
            Self::default()
        }
    }

    /// [`crate::passes::common::PassParams::anchor`] for the coarsest advected level's distortion pass: the
    /// spacing, and the upsampled share of 256 above it (0 when off).
    pub fn anchor_param(&self) -> u32 {
        if self.anchor_spacing == 0 {
            return 0;
        }
        let share = (self.anchor_upsample.clamp(0.0, 1.0) * 256.0).round() as u32;
        self.anchor_spacing.min(MAX_ANCHOR_SPACING) | (share << 8)
    }

    /// Checks the options (1-16 levels, at least 2 with the finest upsampled and
    /// `resynthesize + 2` with re-synthesized levels, which need the finest upsampled; a
    /// positive finite threshold, at most 16 passes, similarity sets every 1-16
    /// corrections); [`crate::gpu::advect::Advection::new`] and
    /// [`crate::gpu::advect::Advection::set_options`] call it through
    /// [`Self::check_for_pyramid`].
    pub fn check(&self) -> Result<()> {
        let least = if self.upsample_finest { 2 } else { 1 };
        if !(least..=16).contains(&self.levels) {
            return Err(Error::InvalidParameter(if self.upsample_finest {
                format!(
                    "advection of {} levels with the finest one upsampled: use 2-16 levels \
                     (--levels; the finest is upsampled from the advected ones), or 1-16 \
                     with the finest level advected too (AdvectOptions::upsample_finest = \
                     false, --advect-finest)",
                    self.levels
                )
            } else {
                format!(
                    "advection of {} levels: use 1-16 levels (--levels)",
                    self.levels
                )
            }));
        }
        if !self.threshold.is_finite()
            || self.threshold <= 0.0
            || self.passes > 16
            || self.coarsest_passes.is_some_and(|c| c > 16)
            || !(1..=16).contains(&self.sets_every)
        {
            return Err(Error::InvalidParameter(format!(
                "advection with threshold {}, {} passes ({} on the coarsest advected level), \
                 similarity sets every {} corrections: use a positive threshold, at most 16 \
                 passes and sets every 1-16 corrections",
                self.threshold,
                self.passes,
                self.coarsest_passes
                    .map_or("automatic".into(), |c| c.to_string()),
                self.sets_every
            )));
        }
        if self.resynthesize > 14 {
            return Err(Error::InvalidParameter(format!(
                "{} re-synthesized levels: use at most 14 (--resynthesize)",
                self.resynthesize
            )));
        }
        if self.resynthesize > 0 && !self.upsample_finest {
            return Err(Error::InvalidParameter(format!(
                "{} re-synthesized levels with the finest level advected: re-synthesized \
                 levels need the finest level upsampled, so drop --advect-finest \
                 (AdvectOptions::upsample_finest = true) or --resynthesize",
                self.resynthesize
            )));
        }
        if self.fade > MAX_FADE_FRAMES {
            return Err(Error::InvalidParameter(format!(
                "a fade of {} frames: use 0 (off) to {MAX_FADE_FRAMES} (--fade)",
                self.fade
            )));
        }
        if self.fade_change > 255 {
            return Err(Error::InvalidParameter(format!(
                "a pop test of {}: the mean change is of 255, so use 0 to 255 (--fade-change)",
                self.fade_change
            )));
        }
        if self.anchor_spacing > MAX_ANCHOR_SPACING || !(0.0..=1.0).contains(&self.anchor_upsample)
        {
            return Err(Error::InvalidParameter(format!(
                "anchored renewals with spacing {} and an upsampled share of {}: use a \
                 spacing of 0 (off) to {MAX_ANCHOR_SPACING} (--anchor) and a share of 0 to 1 \
                 (--anchor-upsample)",
                self.anchor_spacing, self.anchor_upsample
            )));
        }
        if self.keep_look && self.levels < 3 {
            return Err(Error::InvalidParameter(format!(
                "keep_look (--keep-look, the CLI's default in 2D without a varying field) on \
                 {} levels: it remakes the advected levels below the coarsest one, so use at \
                 least 3 levels (--levels; the finest is upsampled), or carry the texture \
                 (--carry; AdvectOptions::default())",
                self.levels
            )));
        }
        if self.keep_look && (self.resynthesize > 0 || !self.upsample_finest) {
            return Err(Error::InvalidParameter(
                "keep_look remakes the advected levels itself: it needs the finest level \
                 upsampled and no re-synthesized levels (drop --advect-finest and \
                 --resynthesize with --keep-look)"
                    .into(),
            ));
        }
        if self.resynthesize > 0 && self.levels < self.resynthesize + 2 {
            return Err(Error::InvalidParameter(format!(
                "advection of {} levels with {} re-synthesized below the finest: the frames \
                 need at least one advected level, so use at least {} levels (--levels) or \
                 fewer re-synthesized levels (--resynthesize)",
                self.levels,
                self.resynthesize,
                self.resynthesize + 2
            )));
        }
        Ok(())
    }

    /// [`Self::check`], and that the re-synthesized levels and the advected level above
    /// them fit in a pyramid of `pyramid_levels` levels (the finest upsampled, at least
    /// one advected): otherwise fewer would be re-synthesized than asked, silently.
    pub fn check_for_pyramid(&self, pyramid_levels: usize) -> Result<()> {
        self.check()?;
        if self.keep_look && pyramid_levels < 3 {
            return Err(Error::InvalidParameter(format!(
                "keep_look needs at least 3 levels, but this synthesis has {pyramid_levels}: \
                 a larger output or exemplar has more levels"
            )));
        }
        if self.resynthesize > 0 && self.resynthesize + 2 > pyramid_levels {
            return Err(Error::InvalidParameter(format!(
                "{} re-synthesized levels, but this synthesis has {} levels: at most {} \
                 can be re-synthesized (--resynthesize; the finest level is upsampled and at \
                 least one level above them advected); a larger output or exemplar has \
                 more levels",
                self.resynthesize,
                pyramid_levels,
                pyramid_levels.saturating_sub(2)
            )));
        }
        Ok(())
    }
}

impl Default for AdvectOptions {
    fn default() -> Self {
        Self {
            levels: 3,
            threshold: 0.5,
            passes: 1,
            coarsest_passes: None,
            nearest: true,
            interpolate_sets: false,
            quarter_reads: true,
            skip_coherent: true,
            sets_every: 2,
            upsample_finest: true,
            resynthesize: 0,
            keep_look: false,
            fade: 0,
            fade_change: FADE_CHANGE,
            anchor_spacing: 0,
            anchor_upsample: 0.5,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The look kept where J is constant, the texture carried along a varying field.
    #[test]
    fn recommended_options_follow_the_jacobian() {
        use crate::field::Field;
        let mut params = crate::SynthParams::default();
        let kept = AdvectOptions::recommended(&params);
        assert!(kept.keep_look);
        assert_eq!(kept.fade, KEEP_LOOK_FADE);
        assert_eq!(kept.levels, AdvectOptions::keep_look().levels);
        params.field = Some(Field::Constant {
            angle: 0.5,
            scale: [2.0, 1.0],
            shear: 0.0,
        });
        assert!(AdvectOptions::recommended(&params).keep_look);
        params.field = Some(Field::Swirl {
            center: [32.0, 32.0],
            radius: 20.0,
            turns: 1.0,
            scale: 1.0,
        });
        let carried = AdvectOptions::recommended(&params);
        assert!(!carried.keep_look);
        assert_eq!(carried.fade, 0);
        assert_eq!(carried.levels, AdvectOptions::default().levels);
    }
}
