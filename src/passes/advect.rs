//! Mirrors of `shaders/advect.wgsl` and `shaders/distortion.wgsl`: texture advection
//! (paper section 7, ALGORITHM.md "Advection"). Per frame, the finest levels' continuous
//! coordinates are advected without resampling, `S[p] = S'[p - k] - J(p) (V(p) - k)`
//! with `k` one whole shift of the level for all pixels (so neighbours stay coherent): in
//! frames the change of the drift's whole level pixels ([`whole_shift`]; the drift sums
//! the velocity at the window's centre in whole finest pixels), so the texture moves with the
//! flow (a uniform flow of whole pixels translates it exactly, seams included); where the
//! advected coordinates no longer follow the desired Jacobian (`|J_obs - J|_F > c`,
//! divergent or shearing flows stretch them; steps off by a whole pixel on both sides
//! are seams, not distortion) the pixel is upsampled again from the coarser level (or,
//! with anchored renewals on the coarsest advected level, continues a nearby anchor
//! straightened along `J`); then the usual correction passes run.

use super::common::{fit_coord, region_index, scaled_jd, wrap, PassParams};
use super::fill::in_chart;
use crate::error::{Error, Result};

/// Fractional bits of velocities (1/1024 output pixel per frame). The precision matters
/// because a smooth flow's quantization error is the same every frame and adds up: at 1/16 pixel,
/// a vortex's velocities came in bands a few pixels wide whose edges tore the texture
/// by a whole pixel every 16 frames.
pub const VELOCITY_FRAC: u32 = 10;
/// Largest speed, output pixels per frame.
pub const MAX_SPEED: f32 = 64.0;
/// Bits dropped from `J V` (1/2^(JAC_FRAC + VELOCITY_FRAC)) to reach coordinates
/// (1/2^COORD_FRAC).
const JV_SHIFT: u32 = 10 + VELOCITY_FRAC - super::common::COORD_FRAC;

/// The rounding offset of `J V` at `frame` (0 .. 2^JV_SHIFT): the frame index with its
/// bits reversed, a low-discrepancy sequence. Rounding the same fraction down and up in
/// this proportion makes the error of a pixel's displacement stay within a few 1/256
/// exemplar pixels however many frames add up (rounding to nearest repeats the same
/// error, up to half a 1/256 step, every frame, and differently for neighbours). The
/// same for every pixel, so uniform flows stay exactly coherent.
pub fn dither(frame: u64) -> u32 {
    (frame as u32).reverse_bits() >> (32 - JV_SHIFT)
}

/// Velocity (1/1024 px) at the finest pixel under level pixel `abs` (absolute).
pub fn velocity_at(p: &PassParams, velocity: &[[i32; 2]], abs: [i32; 2]) -> [i32; 2] {
    let half = (1i32 << p.steps) >> 1;
    let f = |a: i32, o: i32, n: i32| ((a << p.steps) + half - o).clamp(0, n - 1);
    let x = f(abs[0], p.window_origin[0], p.window_size[0]);
    let y = f(abs[1], p.window_origin[1], p.window_size[1]);
    velocity[(y * p.window_size[0] + x) as usize]
}

/// The velocity at the output window's centre (1/1024 px per frame).
fn centre_velocity(p: &PassParams, velocity: &[[i32; 2]]) -> [i32; 2] {
    let ws = p.window_size;
    velocity[((ws[1] / 2) * ws[0] + ws[0] / 2) as usize]
}

/// Mirror of `drift.wgsl`: adds the centre velocity, rounded to whole finest pixels, to
/// the frames' drift (`p.drift`: the entry before this frame, then the one after).
pub fn drift(p: &PassParams, coords: &mut [[i32; 2]], velocity: &[[i32; 2]]) {
    let i = p.drift as usize;
    let vc = centre_velocity(p, velocity);
    let k = vc.map(|c| (c + (1 << (VELOCITY_FRAC - 1))) >> VELOCITY_FRAC);
    let a = coords[i + 1];
    coords[i] = a;
    coords[i + 1] = [a[0] + k[0], a[1] + k[1]];
}

/// The whole pixels of a level (`2^steps` finest pixels each) by which a frame moves its
/// coordinates: with the drift, the change of the drift's whole level pixels (rounded
/// down), so that over the frames a level moves by its share of the drift and a uniform
/// flow of whole pixels moves the patch seams of every level with the texture; without
/// it (`p.drift` 0), the centre velocity rounded to whole level pixels.
pub fn whole_shift(p: &PassParams, coords: &[[i32; 2]], velocity: &[[i32; 2]]) -> [i32; 2] {
    if p.drift != 0 {
        let (a0, a1) = (coords[p.drift as usize], coords[p.drift as usize + 1]);
        return [0, 1].map(|c| (a1[c] >> p.steps) - (a0[c] >> p.steps));
    }
    let unit = 1i32 << (VELOCITY_FRAC + p.steps);
    centre_velocity(p, velocity).map(|c| (c + (unit >> 1)) >> (VELOCITY_FRAC + p.steps))
}

/// One component of `J (V - k 2^steps)` in coordinate units (1/2^COORD_FRAC exemplar
/// pixel), rounded down after adding this frame's offset `dither`: `jv` is the row of
/// `J V` (1/2^(10 + VELOCITY_FRAC)), `jk` the row of `J k` (1/1024, k in whole level
/// pixels). `J k 2^steps` is split into whole coordinate units and a remainder, so the
/// result is exact without forming `J (V - k 2^steps)`, which overflows i32 on coarse
/// levels (a level pixel 256 finest pixels wide is 2^18 velocity units, times `J` up to
/// 2^13): the frames' drift shifts such a level by a whole pixel on the frame its share
/// of the drift crosses one, however slow the flow.
pub fn displacement(jv: i32, jk: i32, steps: u32, dither: i32) -> i32 {
    // `J k 2^(steps + VELOCITY_FRAC)` = hi 2^JV_SHIFT + lo, 0 <= lo < 2^JV_SHIFT.
    let up = steps + VELOCITY_FRAC;
    let (hi, lo) = if up >= JV_SHIFT {
        (jk << (up - JV_SHIFT), 0)
    } else {
        let hi = jk >> (JV_SHIFT - up);
        (hi, (jk - (hi << (JV_SHIFT - up))) << up)
    };
    ((jv - lo + dither) >> JV_SHIFT) - hi
}

/// `J (V - k 2^steps)` in coordinate units, rounded with the frame's `dither`
/// ([`displacement`] per component): what a frame subtracts from the coordinate it
/// carries from `k` level pixels upstream (`shared/advect.wgsl`, `displacement`).
pub fn offset(p: &PassParams, j: [i32; 4], vq: [i32; 2], k: [i32; 2]) -> [i32; 2] {
    let d = p.dither as i32;
    [
        displacement(
            j[0] * vq[0] + j[1] * vq[1],
            j[0] * k[0] + j[1] * k[1],
            p.steps,
            d,
        ),
        displacement(
            j[2] * vq[0] + j[3] * vq[1],
            j[2] * k[0] + j[3] * k[1],
            p.steps,
            d,
        ),
    ]
}

/// Mirror of `advect.wgsl`: the level's advected coordinates, into the scratch region
/// (`flag_base`), from which [`distortion`] copies them back.
pub fn advect(p: &PassParams, coords: &mut [[i32; 2]], jac: &[[i32; 4]], velocity: &[[i32; 2]]) {
    let k = whole_shift(p, coords, velocity);
    for y in 0..p.size[1] {
        for x in 0..p.size[0] {
            let i = p.coord_base as usize + (y * p.size[0] + x) as usize;
            let vq = velocity_at(p, velocity, [p.origin[0] + x, p.origin[1] + y]);
            let (sx, sy) = if p.periodic != 0 {
                (wrap(x - k[0], p.size[0]), wrap(y - k[1], p.size[1]))
            } else {
                (
                    (x - k[0]).clamp(0, p.size[0] - 1),
                    (y - k[1]).clamp(0, p.size[1] - 1),
                )
            };
            let prev = coords[p.coord_base as usize + (sy * p.size[0] + sx) as usize];
            let o = offset(p, jac[i], vq, k);
            coords[p.flag_base as usize + (y * p.size[0] + x) as usize] =
                fit_coord([prev[0] - o[0], prev[1] - o[1]], p);
        }
    }
}

fn step_err(p: &PassParams, d: [i32; 2]) -> u32 {
    let mut e = d;
    if p.tileable != 0 {
        for (ek, size) in e.iter_mut().zip(p.ex_size) {
            let n = size << p.coord_frac;
            if *ek > n / 2 {
                *ek -= n;
            }
            if *ek < -n / 2 {
                *ek += n;
            }
        }
    }
    let c = e.map(|v| v.clamp(-16384, 16384).unsigned_abs());
    c[0] * c[0] + c[1] * c[1]
}

/// Whether the distortion pass flags region pixel `(x, y)` for upsampling again, from
/// the advected coordinates in the scratch region (see `distortion.wgsl`).
pub fn flagged(
    p: &PassParams,
    coords: &[[i32; 2]],
    jac: &[[i32; 4]],
    surface: &[u32],
    x: i32,
    y: i32,
) -> bool {
    let t = (y * p.size[0] + x) as usize;
    if p.distortion_max == u32::MAX || !in_chart(p, surface, t as u32) {
        return false;
    }
    let scratch = p.flag_base as usize;
    let s = coords[scratch + t];
    let (j, h) = (jac[p.coord_base as usize + t], p.spacing);
    let at = |dx: i32, dy: i32| coords[scratch + region_index([x + dx, y + dy], p)];
    // None: a seam on both sides (a strip between two seams, see distortion.wgsl).
    let axis = |e: [i32; 2]| {
        let ex = scaled_jd(h, j, e);
        let f = at(e[0], e[1]);
        let b = at(-e[0], -e[1]);
        let fwd = [f[0] - s[0] - ex[0], f[1] - s[1] - ex[1]];
        let bwd = [s[0] - b[0] - ex[0], s[1] - b[1] - ex[1]];
        let err = step_err(p, fwd).min(step_err(p, bwd));
        (err <= seam_err(p.spacing)).then_some(err)
    };
    let (ex, ey) = (axis([1, 0]), axis([0, 1]));
    // A pixel between seams on both axes continues no neighbour: it is upsampled again
    // too (else such pixels spread and blur the texture, distortion.wgsl).
    let isolated = ex.is_none() && ey.is_none();
    let err = ex.unwrap_or(0) + ey.unwrap_or(0);
    isolated || err > p.distortion_max
}

/// Mirror of `distortion.wgsl`: writes the advected coordinates from the scratch region
/// back to the level, and in place of the [`flagged`] ones their upsampling from the
/// coarser level ([`super::upsample_aniso::upsample_pixel`]; it reads only that level) or
/// their anchored renewal (`renewal`).
pub fn distortion(p: &PassParams, coords: &mut [[i32; 2]], jac: &[[i32; 4]], surface: &[u32]) {
    let base = p.coord_base as usize;
    let scratch = p.flag_base as usize;
    let mut out = Vec::with_capacity((p.size[0] * p.size[1]) as usize);
    for y in 0..p.size[1] {
        for x in 0..p.size[0] {
            let t = (y * p.size[0] + x) as usize;
            out.push(if flagged(p, coords, jac, surface, x, y) {
                renewal(p, coords, jac, surface, [x, y])
            } else {
                coords[scratch + t]
            });
        }
    }
    coords[base..base + out.len()].copy_from_slice(&out);
}

/// The new coordinate of flagged region pixel `q` (see `renewal` in `distortion.wgsl`):
/// upsampled again from the coarser level, or with anchored renewals
/// ([`PassParams::anchor`]) mostly the continuation of the nearest-landing of the four
/// anchors around it.
fn renewal(
    p: &PassParams,
    coords: &[[i32; 2]],
    jac: &[[i32; 4]],
    surface: &[u32],
    q: [i32; 2],
) -> [i32; 2] {
    let upsample = || super::upsample_aniso::upsample_pixel(p, coords, jac, q);
    let b = (p.anchor & 255) as i32;
    if b == 0 {
        return upsample();
    }
    let scratch = p.flag_base as usize;
    let advected = |a: [i32; 2]| coords[scratch + region_index(a, p)];
    let last = [p.size[0] - 1, p.size[1] - 1];
    let own = [0, 1].map(|k| (q[k] / b * b + b / 2).min(last[k]));
    let key = advected(own).map(|v| (v >> 10) as u32);
    let roll =
        super::common::hash32(key[0].wrapping_mul(73_856_093) ^ key[1].wrapping_mul(19_349_663));
    if roll & 255 < p.anchor >> 8 {
        return upsample();
    }
    let t = (q[1] * p.size[0] + q[0]) as usize;
    let s = coords[scratch + t];
    let j = jac[p.coord_base as usize + t];
    let k0 = [0, 1].map(|k| (q[k] - b / 2).div_euclid(b));
    // The first nearest continuation, within a whole pixel step.
    let mut best = seam_err(p.spacing) + 1;
    let mut pick = None;
    for k in 0..4 {
        let a = [0, 1].map(|ax| (k0[ax] + (k >> ax & 1)) * b + b / 2);
        if (0..2).any(|ax| a[ax] < 0 || a[ax] > last[ax]) {
            continue;
        }
        let ta = (a[1] * p.size[0] + a[0]) as u32;
        if !in_chart(p, surface, ta) || jac[p.coord_base as usize + ta as usize] != j {
            continue;
        }
        let (aa, d) = (
            advected(a),
            scaled_jd(p.spacing, j, [q[0] - a[0], q[1] - a[1]]),
        );
        let c = fit_coord([aa[0] + d[0], aa[1] + d[1]], p);
        let e = step_err(p, [c[0] - s[0], c[1] - s[1]]);
        if e < best {
            best = e;
            pick = Some(c);
        }
    }
    pick.unwrap_or_else(upsample)
}

/// Squared step error of a whole pixel step at spacing `h`, `(h 256)^2`: beyond it an
/// axis is a seam on both sides and does not count as distortion.
pub fn seam_err(h: i32) -> u32 {
    // Capped (no overflow): step errors stay below 2^30 anyway.
    let h = h.min(128);
    ((h * h) as u32) << 16
}

/// `distortion_max` for threshold `c` (Jacobian units) at spacing `h`.
pub fn distortion_max(c: f32, h: i32) -> u32 {
    let v = (c as f64 * h as f64 * 256.0).powi(2);
    v.min(i32::MAX as f64) as u32
}

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
    /// 4`; at most 255; default [`super::fade::FADE_CHANGE`], 45). Lower fades more pops
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
            fade_change: super::fade::FADE_CHANGE,
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

    fn flags(coords: &mut Vec<[i32; 2]>, c: f32) -> Vec<i32> {
        let p = PassParams {
            ex_size: [4096, 4096],
            size: [8, 8],
            spacing: 1,
            flag_base: 64,
            distortion_max: distortion_max(c, 1),
            ..Default::default()
        };
        let jac = vec![[1024, 0, 0, 1024]; 64];
        // The advected coordinates in the scratch region, as the advect pass leaves them.
        coords.resize(128, [0, 0]);
        coords.copy_within(0..64, 64);
        let f: Vec<i32> = (0..64)
            .map(|t| flagged(&p, coords, &jac, &[], t % 8, t / 8) as i32)
            .collect();
        distortion(&p, coords, &jac, &[]);
        for t in 0..64 {
            if f[t] == 0 {
                assert_eq!(
                    coords[t],
                    coords[64 + t],
                    "unflagged pixels are copied back"
                );
            }
        }
        f
    }

    #[test]
    fn anchored_renewals_keep_the_content_and_follow_j() {
        // A 16x16 level at spacing 2 whose advected coordinates turned by 0.1 radian
        // about its centre: every pixel is flagged at threshold 0.05.
        let (n, h) = (16, 2);
        let p = PassParams {
            ex_size: [4096, 4096],
            size: [n, n],
            spacing: h,
            coord_frac: 8,
            flag_base: (n * n) as u32,
            distortion_max: distortion_max(0.05, h),
            ..Default::default()
        };
        let jac = vec![[1024, 0, 0, 1024]; (n * n) as usize];
        let (c, sn) = (0.1f64.cos(), 0.1f64.sin());
        let mut advected: Vec<[i32; 2]> = (0..n * n)
            .map(|t| {
                let (x, y) = ((t % n) as f64 - 7.5, (t / n) as f64 - 7.5);
                let u = (h * 256) as f64;
                [
                    (2000.0 * 256.0 + u * (c * x - sn * y)).round() as i32,
                    (2000.0 * 256.0 + u * (sn * x + c * y)).round() as i32,
                ]
            })
            .collect();
        // Pixel (9, 9) shows another patch: no anchor continues it.
        advected[9 * 16 + 9] = [3000 << 8, 900 << 8];
        let run_along = |anchor: u32, jac: &[[i32; 4]]| {
            let mut coords = advected.clone();
            coords.extend_from_slice(&advected);
            let p = PassParams { anchor, ..p };
            for t in 0..n * n {
                assert!(flagged(&p, &coords, jac, &[], t % n, t / n));
            }
            distortion(&p, &mut coords, jac, &[]);
            coords.truncate((n * n) as usize);
            coords
        };
        let run = |anchor: u32| run_along(anchor, &jac);
        // Upsampled (no coarser level here: the exemplar's corner, fit_coord(0)).
        let corner = fit_coord([0, 0], &p);
        assert!(run(0).iter().all(|&c| c == corner));
        assert!(run(4 | (256 << 8)).iter().all(|&c| c == corner));
        let anchored = run(4);
        let step = h * 256;
        let mut straight = 0;
        for y in 0..n {
            for x in 0..n {
                let t = (y * n + x) as usize;
                let (a, s) = (anchored[t], advected[t]);
                if (x, y) == (9, 9) {
                    assert_eq!(a, corner, "a pixel no anchor continues is upsampled");
                    continue;
                }
                // Nearly what it showed: within the turn times the distance to its anchor
                // (at most 2 sqrt 2 pixels, 0.1 x 2.83 x 512 = 145 units, against 512
                // for one pixel).
                let d = ((a[0] - s[0]) as f64).hypot((a[1] - s[1]) as f64);
                assert!(d <= 150.0, "({x}, {y}) moved by {d}");
                if x + 1 < n && anchored[t + 1] == [a[0] + step, a[1]] {
                    straight += 1;
                }
            }
        }
        // The turned field follows J again within each anchor's pixels (a pixel takes
        // the anchor nearest to it, so about half of the steps are inside one); none of
        // its steps did before.
        assert!(straight >= 120, "{straight} straight steps of 240");
        assert!(!advected
            .windows(2)
            .any(|w| w[1] == [w[0][0] + step, w[0][1]]));
        // Along a varying field (J differs by a unit from pixel to pixel) only an anchor
        // continues an anchor (itself: it keeps its coordinate); the rest are upsampled.
        let varying: Vec<[i32; 4]> = (0..n * n).map(|t| [1024 + t, 0, 0, 1024]).collect();
        for (t, c) in run_along(4, &varying).into_iter().enumerate() {
            let anchor = t as i32 % n % 4 == 2 && t as i32 / n % 4 == 2;
            assert_eq!(c, if anchor { advected[t] } else { corner }, "pixel {t}");
        }
        // Half upsampled: decided per anchor block, so a block is either.
        let half = run(4 | (128 << 8));
        let up = half.iter().filter(|&&c| c == corner).count();
        assert!((40..=216).contains(&up), "{up} of 256 upsampled");
        for (t, &c) in half.iter().enumerate() {
            assert!(c == corner || c == anchored[t], "pixel {t}");
        }
    }

    #[test]
    fn rounding_errors_do_not_add_up_over_frames() {
        // A shear flow, v_y = 0.0123 x pixels per frame, for 300 frames along a row: each
        // pixel must move by the exact sum within a few 1/256, and neighbours stay
        // smooth (always rounding to nearest drifts by up to 300/512 pixel, in steps).
        let n = 64;
        let p = PassParams {
            ex_size: [4096, 4096],
            size: [n, 1],
            window_size: [n, 1],
            tileable: 1,
            coord_frac: 8,
            flag_base: n as u32,
            ..Default::default()
        };
        let jac = vec![[1024, 0, 0, 1024]; n as usize];
        let speed = |x: i32| 0.0123 * x as f64;
        let velocity: Vec<[i32; 2]> = (0..n)
            .map(|x| [0, (speed(x) * (1 << VELOCITY_FRAC) as f64).round() as i32])
            .collect();
        let start = |x: i32| [(1000 + x) << 8, 2000 << 8];
        let mut coords: Vec<[i32; 2]> = (0..2 * n).map(start).collect();
        let frames = 300;
        for frame in 0..frames {
            let p = PassParams {
                dither: dither(frame),
                ..p
            };
            advect(&p, &mut coords, &jac, &velocity);
            // Copied back from the scratch region, nothing flagged (as on the coarsest
            // advected level).
            let back = PassParams {
                distortion_max: u32::MAX,
                ..p
            };
            distortion(&back, &mut coords, &jac, &[]);
        }
        for x in 0..n {
            // Exact for the quantized velocity, in 1/256 exemplar pixel.
            let exact = velocity[x as usize][1] as f64 * frames as f64 / 4.0;
            let moved = (start(x)[1] - coords[x as usize][1]) as f64;
            assert!(
                (moved - exact).abs() <= 3.0,
                "x {x}: moved {moved}, exact {exact}"
            );
        }
    }

    #[test]
    fn largest_speeds_and_scales_do_not_overflow() {
        // A level 128 pixels coarser than the finest, the centre moving at +64 pixels
        // per frame and this pixel at -64 (residual -192) per component, J = 8 x a
        // 45-degree rotation: J V must not wrap around.
        let p = PassParams {
            ex_size: [1 << 14, 1 << 14],
            size: [1, 1],
            window_size: [3, 1],
            steps: 7,
            tileable: 1,
            coord_frac: 8,
            flag_base: 1,
            ..Default::default()
        };
        let c = 5793; // 8 cos 45 degrees, in 1/1024
        let jac = [[c, -c, c, c]];
        let fast = 64 << VELOCITY_FRAC;
        let velocity = [[-fast, -fast], [fast, fast], [-fast, -fast]];
        let start = [8000 << 8, 8000 << 8];
        let mut coords = vec![start, [0, 0]];
        advect(&p, &mut coords, &jac, &velocity);
        coords[0] = coords[1];
        // k = 1 level pixel = 128 pixels: S[p] = S'[p - k] - J (V - k), exactly.
        let v = -192.0 * 1024.0;
        let expected = [
            start[0] as f64 - 0.0,
            start[1] as f64 - 2.0 * c as f64 * v / 4096.0,
        ];
        let got = coords[0];
        assert!(
            (got[0] as f64 - expected[0]).abs() <= 1.0,
            "{got:?} vs {expected:?}"
        );
        assert!(
            (got[1] as f64 - expected[1]).abs() <= 1.0,
            "{got:?} vs {expected:?}"
        );
    }

    #[test]
    fn a_strip_between_two_seams_is_not_distortion() {
        // Identity coordinates, but column 4 comes from elsewhere in the exemplar: both
        // of its x steps are seams.
        let mut coords: Vec<[i32; 2]> = (0..64)
            .map(|i| {
                let (x, y) = (i % 8, i / 8);
                let jump = if x == 4 { 40 } else { 0 };
                [(x + jump) << 8, y << 8]
            })
            .collect();
        assert!(flags(&mut coords, 0.5).iter().all(|&f| f == 0));
    }

    #[test]
    fn a_pixel_between_seams_on_both_axes_is_flagged() {
        // Identity coordinates, but pixel (3, 4) comes from elsewhere in the exemplar:
        // it continues no neighbour, whatever the threshold; its neighbours, each with a
        // seam on one side only, are left alone.
        let coords: Vec<[i32; 2]> = (0..64)
            .map(|i| {
                let (x, y) = (i % 8, i / 8);
                let jump = if (x, y) == (3, 4) { 40 } else { 0 };
                [(x + jump) << 8, (y + jump) << 8]
            })
            .collect();
        for c in [0.5, 100.0] {
            let f = flags(&mut coords.clone(), c);
            assert_eq!(f.iter().sum::<i32>(), 1, "threshold {c}");
            assert_eq!(f[4 * 8 + 3], 1);
        }
        // Level 0 flags nothing (it has no coarser level to upsample from).
        let p = PassParams {
            ex_size: [4096, 4096],
            size: [8, 8],
            spacing: 1,
            flag_base: 64,
            distortion_max: u32::MAX,
            ..Default::default()
        };
        let mut c = coords.clone();
        c.extend_from_within(0..64);
        distortion(&p, &mut c, &vec![[1024, 0, 0, 1024]; 64], &[]);
        assert_eq!(&c[..64], &coords[..]);
    }

    #[test]
    fn stretched_coordinates_are_flagged() {
        // 1.6 exemplar pixels per output pixel along x against J = I: 0.6 > c = 0.5.
        let mut coords: Vec<[i32; 2]> = (0..64).map(|i| [(i % 8) * 410, (i / 8) << 8]).collect();
        assert!(flags(&mut coords.clone(), 0.5).iter().all(|&f| f == 1));
        // Below the threshold (0.6 < 0.7): nothing.
        assert!(flags(&mut coords, 0.7).iter().all(|&f| f == 0));
    }

    #[test]
    fn displacement_is_exact_at_every_level() {
        // J (V - k 2^steps) rounded down with the dither, against 64-bit arithmetic, for
        // every level a pyramid can have, the largest J and speeds, and k up to the
        // shifts the drift or the centre velocity give.
        let exact = |jv: i64, jk: i64, steps: u32, d: i64| {
            (jv - (jk << (steps + VELOCITY_FRAC)) + d).div_euclid(1 << JV_SHIFT)
        };
        let fast: i32 = 64 << VELOCITY_FRAC;
        let j: i32 = 8 << 10;
        for steps in 0..=15u32 {
            for jv in [
                -2 * j * fast,
                -j * 777 - 5,
                -1,
                0,
                3,
                4095,
                j * fast + 12345,
                2 * j * fast,
            ] {
                for jk in [
                    -2 * j * 65,
                    -j - 1,
                    -3,
                    -1,
                    0,
                    1,
                    2,
                    5,
                    j * 3 + 7,
                    2 * j * 65,
                ] {
                    if steps >= 6 && jk.abs() > 2 * j * 2 {
                        continue; // a coarse level moves at most a level pixel or two
                    }
                    for d in [0, 1, 2047, 4095] {
                        assert_eq!(
                            displacement(jv, jk, steps, d) as i64,
                            exact(jv as i64, jk as i64, steps, d as i64),
                            "jv {jv}, jk {jk}, steps {steps}, dither {d}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn coarse_levels_cross_a_drift_pixel_exactly() {
        // A level 2^steps finest pixels per pixel under a uniform flow of 8 pixels per
        // frame, on the frame where the drift's share of the level crosses a whole
        // pixel (k = 1 however slow the flow): a coherent patch moves by exactly 8 finest
        // pixels of exemplar. It came out 120 and 376 pixels off at steps 8 and 9 while
        // V - k was clamped to 128 pixels to keep J (V - k) within i32.
        for steps in [2u32, 6, 8, 9, 12] {
            let h = 1i32 << steps;
            let (n, drift, flag_base) = (16i32, 40u32, 20u32);
            let p = PassParams {
                ex_size: [1 << 17, 1 << 17],
                size: [n, 1],
                spacing: h,
                step: [h, h],
                tileable: 1,
                coord_frac: 8,
                steps,
                window_size: [64, 1],
                flag_base,
                drift,
                ..Default::default()
            };
            let mut coords = vec![[0i32; 2]; 64];
            for x in 0..n {
                coords[x as usize] = [(1000 + x * h) << 8, 5 << 8];
            }
            coords[drift as usize] = [h * 3 - 3, 0];
            coords[drift as usize + 1] = [h * 3 + 5, 0];
            let velocity = vec![[8 << VELOCITY_FRAC, 0]; 64];
            let jac = vec![[1024, 0, 0, 1024]; 64];
            let k = whole_shift(&p, &coords, &velocity);
            assert_eq!(k, [if steps >= 3 { 1 } else { 8 >> steps }, 0]);
            advect(&p, &mut coords, &jac, &velocity);
            for x in k[0]..n {
                // S[x] = S'[x - k] - (V - k h) = S'[x] - V.
                let want = [(1000 + x * h - 8) << 8, 5 << 8];
                assert_eq!(
                    coords[(flag_base as i32 + x) as usize],
                    want,
                    "steps {steps}, pixel {x}"
                );
            }
        }
    }
}
