//! The options of an advection: how each frame treats the pyramid.

use crate::error::{Error, Result};

/// How an advection frame treats the pyramid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdvectOptions {
    /// Levels each frame works on (the finest ones; the coarser ones keep the first
    /// frame's synthesis): with [`Self::upsample_finest`] the finest of them is
    /// upsampled, the [`Self::resynthesize`] levels below it re-synthesized, and the
    /// others advected and corrected, otherwise all are advected and corrected. At least
    /// 2 with `upsample_finest` (one advected level), `resynthesize + 2` with
    /// re-synthesized levels.
    pub levels: usize,
    /// Make the finest level each frame by upsampling the advected second-finest level,
    /// without correcting it, as a synthesis makes its finest level by default; the
    /// second-finest level (or, with [`Self::resynthesize`], the advected level above the
    /// re-synthesized ones) is then corrected with whole passes every frame. Off: the
    /// finest level is advected in place and corrected too (the paper's scheme; half of
    /// its subpasses per frame with one pass), and frame 0 corrects it. On by default
    /// (forty-fifth session): a 512x512 frame costs a third of a whole synthesis
    /// instead of about half, and the texture keeps better. Measured on lavapipe
    /// (256x256, default vortex, 300 frames, on against off): texture energy at frame 300
    /// gravel 0.00472 against 0.00634, brick 0.00114 against 0.00218, grass 0.00322
    /// against 0.00470; flow-warped difference 0.0587 against 0.0612 (gravel);
    /// sharpness at frame 300 1.13 against 1.23 (frame 0: 1.08 and 1.05). A uniform flow
    /// of whole pixels still moves every level's coordinates exactly, patch seams
    /// included (the frames' drift, see `SynthPlan::drift_index`), but at odd speeds the
    /// corrections retouch more pixels than with the finest level advected.
    pub upsample_finest: bool,
    /// With [`Self::upsample_finest`]: how many levels below the finest each frame
    /// re-synthesizes instead of advecting them. They are upsampled from the finest
    /// advected level (following the drift's phase, so whole-pixel uniform flows still
    /// move them exactly) and corrected with `passes` passes, without jitter, as in a
    /// synthesis; only the coarser levels move with the flow, in place. A turning flow
    /// then breaks up only the coarse advected level's patches, and the finer levels
    /// are made whole again every frame, so the texture energy stays near frame 0's;
    /// the price is more change between frames (the re-synthesized detail follows the
    /// advected coarse coordinates, but not pixel for pixel). `levels` counts them: at
    /// least `resynthesize + 2`, and the synthesis's pyramid must have as many levels
    /// ([`Self::check_for_pyramid`]). 0 (the default) advects every level but the finest.
    /// Measured (forty-sixth session, lavapipe, 256x256, default vortex, 300 frames,
    /// 3 against 0 with `levels` 5 against 3): texture energy at frame 300 gravel
    /// 0.0022 against 0.0047, brick 0.0007 against 0.0011, grass 0.0016 against
    /// 0.0032; flow-warped difference 30-92% higher; a frame 54-72% of a synthesis
    /// against 32-37% (48% against 36% at 512x512). Off by default for the popping
    /// (README, *Advection*).
    pub resynthesize: usize,
    /// Distortion threshold `c` on `|J_obs - J|_F` (Jacobian units): pixels beyond it
    /// are upsampled again from the coarser level. A step off by a whole pixel on both
    /// sides is a patch seam and does not count, so `c` of about 1 or more flags
    /// little: only the pixels with a seam on both sides of both axes, which continue no
    /// patch and are upsampled again at any `c` (left alone, they spread under a turning
    /// flow and blur the texture; see `distortion.wgsl`).
    pub threshold: f32,
    /// Correction passes per advected level and frame (the advected coordinates are
    /// already nearly right: one pass keeps the cost at a fraction of a synthesis).
    pub passes: u32,
    /// Correction passes per frame of the coarsest advected level, where it is not the
    /// most corrected one. `None` (default): with [`Self::keep_look`] and a desired
    /// Jacobian that is the same everywhere (no atlas; no field, or a constant one), 2 (or
    /// `passes` if that is 0 or more), else `passes` ([`SynthPlan::advect_coarsest_passes`]).
    /// The level holds a sixteenth of the most corrected level's pixels or fewer, so a
    /// second pass there costs little: the renewals (upsampled from the levels above, or
    /// continuing an anchor) settle into their surroundings before the finer levels are
    /// remade from them (fifty-sixth session, gravel under the vortex, 300 frames: 1.14% of
    /// the 8x8 blocks popping per frame at x1.00 of frame 0's texture energy, against 1.61%
    /// at x1.12 with one pass; two passes on both coarser levels 1.28%, for more time).
    /// Where the Jacobian varies the level is renewed all over and more passes churn it:
    /// the bunny's atlas under the vortex popped 19.3% with two, 10.7% with one; along a
    /// `swirl` field 5.7% against 3.4% (README, *Advection*).
    ///
    /// [`SynthPlan::advect_coarsest_passes`]: super::plan::SynthPlan::advect_coarsest_passes
    pub coarsest_passes: Option<u32>,
    /// Gather the exemplar texel nearest to each coordinate instead of interpolating.
    /// Sub-pixel motion makes the coordinates fractional everywhere, so interpolating
    /// blurs the whole texture (it does not accumulate, but it is visible). Measured
    /// (gravel, 256x256, vortex, 300 frames), nearest vs bilinear: sharpness
    /// (high-frequency energy / exemplar's) 1.19 vs 0.53, texture energy 0.0055 vs
    /// 0.0043, flow-warped frame difference 0.058 vs 0.031. On by default: it looks
    /// like the exemplar; bilinear looks soft.
    pub nearest: bool,
    /// Score the similarity-set candidates of the most corrected level's correction (the
    /// finest advected level) at their bilinearly interpolated position, as the coherent ones (4 reads each), instead of
    /// at their nearest texel as synthesis does. Off by default: measured (256x256, vortex,
    /// 300 frames, energy at frame 300, on against off) at about the same figures (gravel
    /// 0.00572 against 0.00578; brick 0.00117 against 0.00131, but keeping less of its
    /// mortar) for a fifth more time per frame at 512x512.
    pub interpolate_sets: bool,
    /// Read the most corrected level's `Et` and `qe` (where it uses the projected
    /// distance) at the quarter pixel nearest to each interpolated position (`PassParams::quarter`: the GPU then reads them from tables
    /// supersampled at quarter pixels, one read instead of four). On by default:
    /// measured (256x256, vortex, 300 frames, on against off) at figures a few percent
    /// either way (energy at frame 300: gravel 0.00588 against 0.00578, brick 0.00121
    /// against 0.00131), for three quarters of the finest level's correction time.
    pub quarter_reads: bool,
    /// Leave the pixels inside coherent patches out of the corrections
    /// (`PassParams::coherent_skip`: all 8 neighbours continue the pixel's patch within a
    /// quarter pixel; the correction would keep them or nudge them within the pixel). On
    /// by default: measured (256x256, vortex, 300 frames, on against off) at figures
    /// within 3% (energy at frame 300: gravel 0.00623 against 0.00626, brick 0.00216
    /// against 0.00209; warped difference 0.0608 against 0.0610), for about a seventh
    /// less of the finest level's correction time at 512x512 (31.9 against 37.1 ms).
    pub skip_coherent: bool,
    /// Score the similarity-set candidates on every `sets_every`-th correction of a
    /// pixel, 1..=16 (the frames' own [`crate::SynthParams::sets_every`], which frame 0's
    /// synthesis keeps); the other corrections score the coherent candidates only. With
    /// one pass (the default) this spreads over the frames on the most corrected level
    /// (the coarser advected levels keep their sets, but with [`Self::keep_look`], where
    /// every advected level runs all its subpasses every frame, they follow it too);
    /// with more, it applies to each
    /// frame's passes, the first of which always scores them.
    /// Default 2: measured with the finest level advected (forty-fourth session; 256x256,
    /// vortex, 300 frames, 2 against 1) at energies 1-2%
    /// higher at frame 300 (gravel 0.00634 against 0.00623, brick 0.00218 against
    /// 0.00216, grass 0.00470 against 0.00463), the same warped difference (0.0612,
    /// 0.0310, 0.0532 against 0.0608, 0.0310, 0.0528), for about an eighth less of a
    /// 512x512 frame's time once the vortex has broken the patches up (100 frames).
    pub sets_every: u32,
    /// Keep the texture's look under turning and divergent flows (with
    /// [`Self::upsample_finest`], no [`Self::resynthesize`]; [`Self::keep_look()`] gives
    /// the measured settings). The coarsest advected level works as usual, its
    /// [`Self::threshold`] renewing it from the coarser level where it has turned or
    /// stretched too far. The advected levels below it are remade (upsampled from the
    /// level above, then corrected) wherever they moved other than rigidly, their
    /// Jacobian off by more than [`KEEP_LOOK_REMAKE_THRESHOLD`], and kept as advected
    /// elsewhere: a turning flow remakes them every frame, so the texture is neither
    /// turned nor broken up and its energy stays near frame 0's, while a uniform flow
    /// still moves them exactly (where `J` is constant: along a varying field or on an
    /// atlas, moving through `J` distorts them, and they are remade there too). Every
    /// advected level runs all its correction subpasses every frame, none skipping
    /// coherent pixels, and frame 0 makes the levels below the coarsest advected one as
    /// the frames do (no jitter, the frames' passes). The price: under a turning flow the texture is continuously remade as it moves (over
    /// tens of frames most of it is new, and whole regions change at once where the
    /// coarse level is renewed), and a frame costs more. Off by default.
    pub keep_look: bool,
    /// Fade pops in over this many frames (0: off, the default; at most
    /// [`MAX_FADE_FRAMES`]): a pixel whose coordinate lands away from where the flow
    /// carried the previous frame's, where the jumps around it changed the colour by more
    /// than [`Self::fade_change`] on average (a renewed or remade patch), shows a blend of
    /// its old content, carried on with the flow, and its new one, the old fading out over
    /// the frames, instead of changing at once (`passes::fade`). The blend keeps the
    /// contrast (variance-preserving). Coordinates (`read_coords`, the CPU mirror) are not
    /// blended, only the colours; a uniform flow of whole pixels moves the texture as
    /// exactly as without. One frame trades best: measured (fifty-fourth session,
    /// lavapipe; 256x256, 300 frames of the default vortex, with [`Self::keep_look`]) the
    /// 8x8 blocks that pop per frame on gravel 0.20% against 1.41% without, at a texture
    /// energy at frame 300 of x1.17 frame 0's against x1.12 (blended pixels match no
    /// exemplar neighbourhood); longer fades cost more energy for little (README,
    /// *Advection*). On lavapipe the pass takes about 12 ms of a 512x512 frame, against
    /// 3 ms for the gather it replaces.
    pub fade: u32,
    /// The fade's pop test (with [`Self::fade`]): a pixel that jumped fades where the
    /// mean change of colour over its 3x3 neighbourhood (within the pass's 8x8 tile;
    /// pixels that did not jump count 0) exceeds this (of 255, `(|dR| + 2 |dG| + |dB|) /
    /// 4`; at most 255; default [`crate::passes::fade::FADE_CHANGE`], 45). Lower fades more pops
    /// for a higher texture energy: measured (as for [`Self::fade`], 1-frame fades,
    /// gravel; the energy's mean over frames 10-300) 35: x1.20, 0.08% of the blocks
    /// popping; 40: x1.18, 0.12%; 45: x1.17, 0.20% (fifty-third session's build: 50:
    /// x1.17, 0.38%; 55: x1.16, 0.59%).
    pub fade_change: u32,
    /// Anchored renewals on the coarsest advected level (0: off, the paper's scheme;
    /// at most [`MAX_ANCHOR_SPACING`]): a pixel the distortion flags there continues,
    /// along the desired Jacobian, the advected coordinate of one of the four anchors
    /// around it (pixels of a grid of this spacing; the one whose continuation lands
    /// nearest the pixel's own advected coordinate, within a pixel step) instead of
    /// being upsampled again from the coarser level. The renewed pixel then shows nearly
    /// what it showed, only turned or stretched back, where an upsampling brings unrelated
    /// content: a renewed patch no longer pops. Pixels no anchor continues (another
    /// patch, outside the chart, or where the desired Jacobian differs between the anchor
    /// and the pixel) are upsampled, and so is a share of the others
    /// ([`Self::anchor_upsample`]). The Jacobian rule keeps anchors to constant fields:
    /// along a varying one (`swirl`, an atlas) the content must be turned back all the
    /// time as it flows through the field, and continuing anchors there popped more than
    /// upsampling (gravel, `swirl` field, 100 frames: 5.2% of the blocks against 3.5%;
    /// bunny atlas 15.2% against 11.5%); with the rule 3.2% and 9.9%, and under constant
    /// fields `rotate:30` 1.33% against 1.99%, `scale:2` 1.59% against 2.12%. Measured
    /// (fifty-fifth session, lavapipe; 256x256,
    /// 300 frames of the default vortex, [`Self::keep_look`], gravel; pops are 8x8
    /// blocks changing by more than 0.15 per frame, energy the mean over frames 10-300
    /// of frame 0's): spacing 4 0.63% pops at x1.12 all anchored, 1.09% at x1.12 half
    /// anchored, against 1.61% at x1.12 upsampled; with `fade: 1` 0.11% at x1.15 and
    /// 0.16% at x1.16 against 0.24% at x1.16 (brick 0.05% against 0.09%, grass 0.21%
    /// against 0.26%, at about the same energies). An earlier form at spacing 8 (all
    /// anchored, anchors clamped onto the region's edge) measured 0.96% at x1.09. The
    /// marble's energy rises, half anchored: mean x1.14 against x1.09, frame 300 x1.27
    /// against x1.10 (its energy swings by 20% from frame to frame either way), so
    /// [`Self::keep_look()`] leaves this off. The cost is the same (the coarsest advected
    /// level is an eighth of the output's side).
    pub anchor_spacing: u32,
    /// With [`Self::anchor_spacing`]: the share of the renewals (0 to 1) upsampled from
    /// the coarser level anyway, decided per anchor block and the content it shows.
    /// Anchored renewals keep the content but never bring back the coarse levels'
    /// large structures, which break at the anchor blocks' edges and are never made
    /// whole again: measured on pink_marble over 900 frames (as for `anchor_spacing`),
    /// all anchored at spacing 4, its veins broke into short pieces (sharpness after
    /// frame 300 0.77 against 1.07 upsampled; an earlier form, anchors clamped onto the
    /// region's edge), half anchored (0.5, the default) they kept (1.05).
    pub anchor_upsample: f32,
}

/// Widest anchor spacing ([`AdvectOptions::anchor_spacing`]).
pub const MAX_ANCHOR_SPACING: u32 = 64;

pub const MAX_FADE_FRAMES: u32 = 64;

/// The fade of [`AdvectOptions::recommended`] (and of the CLI's `--keep-look`): 2 frames
/// popped least within the texture-energy target (gravel, 300 frames of the vortex:
/// 0.058% of the 8x8 blocks per frame at x1.17, against 0.175% at x1.06 with 1 and 1.14%
/// at x1.00 without).
pub const KEEP_LOOK_FADE: u32 = 2;

/// The distortion threshold (Jacobian units) beyond which [`AdvectOptions::keep_look`]
/// remakes a pixel of the advected levels below the coarsest one: about 0.2 degrees of
/// turning. Below the 1/256-pixel rounding of neighbouring coordinates (which stays
/// under it at every level) nothing is remade, so rigid motion keeps the advected
/// texture; the default vortex (0.01 radian per frame) remakes every pixel every frame.
pub const KEEP_LOOK_REMAKE_THRESHOLD: f32 = 0.005;

impl AdvectOptions {
    /// Options that keep the texture's look under turning and divergent flows (CLI
    /// `texsyn advect --keep-look`): [`Self::keep_look`] on 4 levels with a distortion
    /// threshold of 0.12 for the coarsest of them (about 5 degrees of turning or 12% of
    /// stretch, against 0.5). Measured (forty-eighth session, lavapipe; 256x256, 300
    /// frames of the default vortex, against the defaults): texture energy at frame 300
    /// over frame 0's gravel 1.13 against 2.50, brick 0.86 against 2.28, grass 0.94
    /// against 1.92, pink_marble 1.09 against 1.65, craters 0.97 against 0.92;
    /// flow-warped difference 22-81% higher (27-51% of a resynthesis from scratch's); a
    /// uniform flow of whole pixels moves the texture as exactly as by default; a
    /// 512x512 frame 38-46% of a whole synthesis against 26-31% (README, *Advection*);
    /// since the fifty-fourth session, with the similarity sets on every fourth
    /// correction (`sets_every: 4`) at every advected level, 23-33% against 25-30%.
    /// Since the fifty-sixth session the coarsest advected level runs two correction
    /// passes per frame where `J` is constant ([`Self::coarsest_passes`]): gravel 1.14% of the 8x8 blocks
    /// popping per frame at x1.00 of frame 0's energy at frame 300, against 1.61% at
    /// x1.12; brick x0.80, grass x0.83, pink_marble x0.95, craters x0.83.
    /// Anchored renewals ([`Self::anchor_spacing`]) pop less with it on the stochastic
    /// textures but stay off here: they raise the marble's energy (see there).
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
    /// ([`SynthParams::constant_jacobian`]: 2D, no field or a constant one),
    /// [`Self::keep_look()`] with pops faded over [`KEEP_LOOK_FADE`] frames; on an atlas
    /// or along a varying field, [`Self::default()`], the paper's scheme, which carries
    /// the texture there. Measured (fifty-sixth session, lavapipe; gravel, 300 frames of
    /// the default vortex): in 2D 0.058% of the 8x8 blocks popping per frame at x1.17 of
    /// frame 0's texture energy at frame 300, where the default breaks the texture up
    /// (x2.5); on the bunny's atlas the default pops 0.04% against 10.7% with
    /// `keep_look` (README, *Advection*).
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

    /// [`PassParams::anchor`] for the coarsest advected level's distortion pass: the
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
            fade_change: crate::passes::fade::FADE_CHANGE,
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
