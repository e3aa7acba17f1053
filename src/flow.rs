//! Velocity fields for advection: presets and user fields, sampled per output pixel in
//! pixels per unit time (a frame moves the texture by `velocity * dt`).

use std::path::Path;

use crate::error::{Error, Result};

/// A velocity field over the output (or atlas), pixel units; [`Flow::sample`] gives the
/// 2D meaning below, [`crate::surface::flow::atlas_velocity`] the one on a mesh.
#[derive(Clone, Debug, PartialEq)]
pub enum Flow {
    /// The same velocity everywhere.
    Uniform {
        /// Horizontal velocity, pixels per unit time (positive: to the right).
        vx: f32,
        /// Vertical velocity, pixels per unit time (positive: down).
        vy: f32,
    },
    /// Rigid rotation about `(cx, cy)` (fractions of the size) at `omega` radians per unit
    /// time: velocity `omega * (-(y - cy), x - cx)`, clockwise on screen (y down) for
    /// positive omega.
    Vortex {
        /// Centre x as a fraction of the output width (0.5 = middle).
        cx: f32,
        /// Centre y as a fraction of the output height (0.5 = middle).
        cy: f32,
        /// Angular velocity, radians per unit time.
        omega: f32,
    },
    /// A Lamb-Oseen vortex about `(cx, cy)` (fractions of the size): it spins at `omega`
    /// radians per unit time at the centre, like [`Flow::Vortex`], but the tangential speed
    /// `omega * rc^2 / r * (1 - exp(-r^2 / rc^2))` peaks near the core radius `rc` (0.64
    /// `omega rc` at 1.12 `rc`) and falls as `1 / r` beyond it, as in a fluid: the texture
    /// turns inside the core and shears outside it.
    LambOseen {
        /// Centre x as a fraction of the output width (0.5 = middle).
        cx: f32,
        /// Centre y as a fraction of the output height (0.5 = middle).
        cy: f32,
        /// Angular velocity at the centre, radians per unit time (positive: clockwise on
        /// screen, as for [`Flow::Vortex`]).
        omega: f32,
        /// Core radius `rc` as a fraction of the output's smaller side (> 0).
        core: f32,
    },
    /// Radial flow from `(cx, cy)` (negative strength: a sink); the speed is `strength`
    /// pixels per unit time at every radius beyond 8 pixels (and falls to 0 at the
    /// centre), so the texture stretches near the source.
    Source {
        /// Source x as a fraction of the output width (0.5 = middle).
        cx: f32,
        /// Source y as a fraction of the output height (0.5 = middle).
        cy: f32,
        /// Outward speed beyond 8 pixels from the source, pixels per unit time; negative
        /// flows inward.
        strength: f32,
    },
    /// A time-varying flow: a uniform drift of `speed` whose direction turns at `turn`
    /// radians per unit time, plus a travelling sine shear of amplitude `speed / 2`.
    Gusts {
        /// Drift speed, pixels per unit time; the drift points along +x at time 0.
        speed: f32,
        /// Rate at which the drift direction turns, radians per unit time.
        turn: f32,
    },
    /// A user field: one velocity per pixel (row-major), pixels per unit time, of
    /// exactly the output's size.
    Map {
        /// Width in pixels; must equal the output's.
        width: u32,
        /// Height in pixels; must equal the output's.
        height: u32,
        /// `width * height` velocities `[vx, vy]`, row-major, top row first, pixels per
        /// unit time (y down).
        data: std::sync::Arc<Vec<[f32; 2]>>,
    },
}

/// Help text for the flow SPEC syntax parsed by `Flow`'s `FromStr` (`texsyn advect --flow`),
/// with the preset defaults.
pub const FLOW_HELP: &str = "\
Velocity fields (pixels per unit time; a frame moves the texture by velocity * dt):
  uniform:VX,VY            the same everywhere
  vortex[:CX,CY,OMEGA]     rigid rotation about (CX, CY) (fractions of the size, default
                           0.5,0.5) at OMEGA radians per unit time (default 0.01)
  vortex:CX,CY,OMEGA,CORE  a fluid (Lamb-Oseen) vortex: spins at OMEGA at the centre, the
                           speed peaking near the core radius CORE (a fraction of the
                           smaller side, > 0) and falling as 1/r beyond it
  source[:CX,CY,SPEED]     radial flow from (CX, CY) at SPEED px per unit time (default
                           0.5,0.5,1); a negative SPEED is a sink
  gusts[:SPEED,TURN]       time-varying: a drift of SPEED (default 1) turning at TURN
                           radians per unit time (default 0.02), plus a travelling shear
  image:FILE               red, green = vx, vy mapped from 0..1 to -8..8 px (8-bit or
                           16-bit image), or an EXR's first two channels as pixels directly;
                           must have the output's size";

/// The largest rate (OMEGA, SPEED, TURN) a preset flow takes, in size: larger ones
/// overflow 32-bit floats when sampled, and move every pixel by the most a frame does
/// ([`crate::passes::advect::MAX_SPEED`]) long before that.
pub const MAX_RATE: f32 = 1e9;

/// `v`, or an error if any velocity is not finite: a flow sampled at a time so large
/// (frames x `--dt`) that its terms overflow.
pub(crate) fn finite_velocities(v: Vec<[f32; 2]>, t: f32) -> Result<Vec<[f32; 2]>> {
    if v.iter().flatten().all(|c| c.is_finite()) {
        return Ok(v);
    }
    Err(Error::InvalidParameter(format!(
        "the flow sampled at time {t} gives velocities that are not finite numbers (its \
         terms overflow 32-bit floats): use a smaller time step (--dt) or slower rates"
    )))
}

/// The most pixels [`Flow::sample`] fills (16384 x 16384).
pub const MAX_SAMPLED_PIXELS: usize = 1 << 28;

impl Flow {
    /// Velocities of every pixel of a `width` x `height` output at time `t`.
    pub fn sample(&self, width: u32, height: u32, t: f32) -> Result<Vec<[f32; 2]>> {
        let (w, h) = (width as f32, height as f32);
        // One velocity per pixel is allocated: refuse what no device synthesizes.
        let n = (width as usize)
            .checked_mul(height as usize)
            .filter(|&n| n <= MAX_SAMPLED_PIXELS)
            .ok_or_else(|| {
                Error::InvalidParameter(format!(
                    "velocity field of {width}x{height}: at most {} Mpixel",
                    MAX_SAMPLED_PIXELS >> 20
                ))
            })?;
        let at = |f: &dyn Fn(f32, f32) -> [f32; 2]| {
            let mut out = Vec::with_capacity(n);
            for y in 0..height {
                for x in 0..width {
                    out.push(f(x as f32 + 0.5, y as f32 + 0.5));
                }
            }
            out
        };
        let v = match self {
            Flow::Uniform { vx, vy } => vec![[*vx, *vy]; n],
            Flow::Vortex { cx, cy, omega } => {
                let (cx, cy) = (cx * w, cy * h);
                at(&|x, y| [-omega * (y - cy), omega * (x - cx)])
            }
            Flow::LambOseen {
                cx,
                cy,
                omega,
                core,
            } => {
                let (cx, cy) = (cx * w, cy * h);
                let rc = core * w.min(h);
                at(&|x, y| {
                    let (dx, dy) = (x - cx, y - cy);
                    let s = lamb_oseen_rate(*omega, rc, dx * dx + dy * dy);
                    [-s * dy, s * dx]
                })
            }
            Flow::Source { cx, cy, strength } => {
                let (cx, cy) = (cx * w, cy * h);
                at(&|x, y| {
                    let (dx, dy) = (x - cx, y - cy);
                    let r = (dx * dx + dy * dy).sqrt();
                    let s = strength * (r / 8.0).min(1.0) / r.max(1e-6);
                    [dx * s, dy * s]
                })
            }
            Flow::Gusts { speed, turn } => {
                let a = turn * t;
                let (c, s) = (a.cos(), a.sin());
                at(&|_x, y| {
                    let shear =
                        0.5 * speed * ((y / h * 6.0 + t * 0.05) * std::f32::consts::TAU).sin();
                    [speed * c + shear, speed * s]
                })
            }
            Flow::Map {
                width: mw,
                height: mh,
                data,
            } => {
                if (*mw, *mh) != (width, height) {
                    return Err(Error::InvalidParameter(format!(
                        "the velocity map is {mw}x{mh} but the output is {width}x{height}: a \
                         map (--flow image:FILE) must have the output's size; resize it, or \
                         make the output its size (--size {mw}x{mh})"
                    )));
                }
                if data.len() != n {
                    return Err(Error::InvalidParameter(format!(
                        "velocity field of {mw}x{mh} holds {} velocities",
                        data.len()
                    )));
                }
                data.as_ref().clone()
            }
        };
        finite_velocities(v, t)
    }

    /// The centre `[cx, cy]` of a vortex or a source (fractions of the output size).
    pub fn centre(&self) -> Option<[f32; 2]> {
        match self {
            Flow::Vortex { cx, cy, .. }
            | Flow::LambOseen { cx, cy, .. }
            | Flow::Source { cx, cy, .. } => Some([*cx, *cy]),
            _ => None,
        }
    }

    /// The same flow centred at `c` (flows without a centre unchanged): on a mesh the
    /// presets are centred on the mesh ([`crate::surface::flow::atlas_velocity`]), so the
    /// CLI checks them with the output's middle instead of a centre they do not use.
    pub fn with_centre(&self, c: [f32; 2]) -> Flow {
        let mut f = self.clone();
        if let Flow::Vortex { cx, cy, .. }
        | Flow::LambOseen { cx, cy, .. }
        | Flow::Source { cx, cy, .. } = &mut f
        {
            (*cx, *cy) = (c[0], c[1]);
        }
        f
    }

    /// Checks that every parameter (or every velocity of a map) is finite;
    /// [`Error::InvalidParameter`] otherwise.
    pub fn validate(&self) -> Result<()> {
        let finite = |v: &[f32]| v.iter().all(|x| x.is_finite());
        let ok = match self {
            Flow::Uniform { vx, vy } => finite(&[*vx, *vy]),
            Flow::Vortex { cx, cy, omega } => finite(&[*cx, *cy, *omega]),
            Flow::LambOseen {
                cx,
                cy,
                omega,
                core,
            } => {
                if finite(&[*core]) && *core <= 0.0 {
                    return Err(Error::InvalidParameter(format!(
                        "vortex core radius {core}: give a fraction of the size > 0 (or three \
                         numbers for a rigid rotation)"
                    )));
                }
                finite(&[*cx, *cy, *omega, *core])
            }
            Flow::Source { cx, cy, strength } => finite(&[*cx, *cy, *strength]),
            Flow::Gusts { speed, turn } => finite(&[*speed, *turn]),
            Flow::Map {
                width,
                height,
                data,
            } => {
                if data.len() != *width as usize * *height as usize {
                    return Err(Error::InvalidParameter(format!(
                        "velocity field of {width}x{height} holds {} velocities",
                        data.len()
                    )));
                }
                data.iter().all(|v| finite(v))
            }
        };
        // Centres are fractions of the output size (unlike `--field vortex`, in pixels):
        // one far outside is almost surely pixels given by mistake.
        if let Flow::Vortex { cx, cy, .. }
        | Flow::LambOseen { cx, cy, .. }
        | Flow::Source { cx, cy, .. } = self
        {
            if ok && (cx.abs() > 4.0 || cy.abs() > 4.0) {
                return Err(Error::InvalidParameter(format!(
                    "flow centre ({cx}, {cy}): flow centres are fractions of the output size \
                     (0.5,0.5 is the middle; divide pixels by the width and height)"
                )));
            }
        }
        if !ok {
            return Err(Error::InvalidParameter(
                "velocity field has NaN or infinite values".into(),
            ));
        }
        // Rates so large that sampling them overflows 32-bit floats: refused now, not
        // as a non-finite velocity frames later. (A uniform velocity of any size is
        // clamped to a frame's most, MAX_SPEED pixels per component.)
        let rates: &[(&str, f32)] = match self {
            Flow::Vortex { omega, .. } | Flow::LambOseen { omega, .. } => &[("OMEGA", *omega)],
            Flow::Source { strength, .. } => &[("SPEED", *strength)],
            Flow::Gusts { speed, turn } => &[("SPEED", *speed), ("TURN", *turn)],
            _ => &[],
        };
        if let Some((name, r)) = rates.iter().find(|(_, r)| r.abs() > MAX_RATE) {
            return Err(Error::InvalidParameter(format!(
                "flow {name} {r:e}: at most {MAX_RATE:e} in size (per unit time; a frame moves \
                 a pixel by at most 64 pixels per axis anyway)"
            )));
        }
        Ok(())
    }

    /// Reads a user velocity image (see [`FLOW_HELP`]).
    pub fn load(path: &Path) -> Result<Flow> {
        let (img, exr_channels) = crate::image_io::open_image_exr_channels(path)?;
        let values = exr_channels
            .unwrap_or(img.color().channel_count() as u32 - img.color().has_alpha() as u32);
        if values < 2 {
            return Err(Error::BadImage {
                path: path.to_path_buf(),
                reason: "it holds one value per pixel (grey); a velocity field needs two, x in \
                         red and y in green (or an EXR's first two channels)"
                    .into(),
            });
        }
        let (width, height) = (img.width(), img.height());
        // Floating-point samples (an EXR, whatever the file's name) are pixels as they
        // are; 8- and 16-bit ones are mapped from 0..1.
        let is_exr = exr_channels.is_some()
            || matches!(
                img,
                image::DynamicImage::ImageRgb32F(_) | image::DynamicImage::ImageRgba32F(_)
            );
        let rgb = img.to_rgb32f();
        let data: Vec<[f32; 2]> = rgb
            .pixels()
            .map(|p| {
                if is_exr {
                    [p.0[0], p.0[1]]
                } else {
                    [(p.0[0] - 0.5) * 16.0, (p.0[1] - 0.5) * 16.0]
                }
            })
            .collect();
        let flow = Flow::Map {
            width,
            height,
            data: std::sync::Arc::new(data),
        };
        flow.validate().map_err(|_| Error::BadImage {
            path: path.to_path_buf(),
            reason: "velocity field has NaN or infinite values".into(),
        })?;
        Ok(flow)
    }
}

/// Angular rate `v_theta / r` of a Lamb-Oseen vortex spinning at `omega` at its centre,
/// core radius `rc`, at squared distance `r2`: `omega rc^2 / r^2 (1 - exp(-r^2 / rc^2))`,
/// which tends to `omega` at the centre (computed there from its series, so that small
/// `r2` loses no precision); 0 for a core radius that is not positive.
pub(crate) fn lamb_oseen_rate(omega: f32, rc: f32, r2: f32) -> f32 {
    // A core of 0 (refused by `validate`), or one so small that its square underflows,
    // gives a field still everywhere but at the centre, not NaN there (0 / 0).
    let rr = rc * rc;
    let x = if rr > 0.0 {
        r2 / rr
    } else if r2 > 0.0 {
        f32::INFINITY
    } else {
        0.0
    };
    if x < 1e-4 {
        omega * (1.0 - 0.5 * x)
    } else {
        omega * (-(-x).exp_m1()) / x
    }
}

impl std::str::FromStr for Flow {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let (kind, rest) = s.split_once(':').unwrap_or((s, ""));
        let nums = |n: usize, defaults: &[f32]| -> std::result::Result<Vec<f32>, String> {
            if rest.is_empty() {
                return if defaults.len() == n {
                    Ok(defaults.to_vec())
                } else {
                    Err(format!("'{s}': {kind} needs {n} number(s)"))
                };
            }
            let v: std::result::Result<Vec<f32>, _> =
                rest.split(',').map(|x| x.trim().parse::<f32>()).collect();
            match v {
                Ok(v) if v.len() == n && v.iter().all(|x| x.is_finite()) => Ok(v),
                _ if kind == "vortex" => Err(format!(
                    "'{s}': vortex takes 3 finite numbers separated by commas (CX,CY,OMEGA: a \
                     rigid rotation) or 4 (CX,CY,OMEGA,CORE: a fluid vortex)"
                )),
                _ => Err(format!(
                    "'{s}': {kind} takes {n} finite numbers separated by commas"
                )),
            }
        };
        Ok(match kind {
            "uniform" => {
                let v = nums(2, &[])?;
                Flow::Uniform { vx: v[0], vy: v[1] }
            }
            "vortex" if rest.split(',').count() == 4 => {
                let v = nums(4, &[])?;
                let flow = Flow::LambOseen {
                    cx: v[0],
                    cy: v[1],
                    omega: v[2],
                    core: v[3],
                };
                flow.validate().map_err(|e| format!("'{s}': {e}"))?;
                flow
            }
            "vortex" => {
                let v = nums(3, &[0.5, 0.5, 0.01])?;
                Flow::Vortex {
                    cx: v[0],
                    cy: v[1],
                    omega: v[2],
                }
            }
            "source" => {
                let v = nums(3, &[0.5, 0.5, 1.0])?;
                Flow::Source {
                    cx: v[0],
                    cy: v[1],
                    strength: v[2],
                }
            }
            "gusts" => {
                let v = nums(2, &[1.0, 0.02])?;
                Flow::Gusts {
                    speed: v[0],
                    turn: v[1],
                }
            }
            "image" if !rest.is_empty() => {
                Flow::load(Path::new(rest)).map_err(|e| e.to_string())?
            }
            "image" => return Err("image: give the velocity image's file (image:FILE)".into()),
            _ => return Err(format!("'{s}': unknown flow (see --help)\n{FLOW_HELP}")),
        })
    }
}

/// What a frame moves each pixel by: velocity x dt, clamped per component as the
/// advection clamps it ([`crate::passes::advect::MAX_SPEED`] pixels a frame); the
/// displacement the temporal figures warp the previous frame by.
pub fn displacement(velocity: &[[f32; 2]], dt: f32) -> Vec<[f32; 2]> {
    let m = crate::passes::advect::MAX_SPEED;
    velocity
        .iter()
        .map(|p| p.map(|c| (c * dt).clamp(-m, m)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A core radius whose square underflows (`vortex:0.5,0.5,0.01,1e-30`) used to give
    /// NaN at the centre (0 / 0), refused only when the first frame was uploaded.
    #[test]
    fn a_vanishing_core_gives_finite_velocities() {
        assert_eq!(lamb_oseen_rate(0.01, 1e-30, 0.0), 0.01);
        assert_eq!(lamb_oseen_rate(0.01, 1e-30, 1.0), 0.0);
        assert_eq!(lamb_oseen_rate(0.01, 0.0, 0.0), 0.01);
        let flow: Flow = "vortex:0.5,0.5,0.01,1e-30".parse().unwrap();
        flow.validate().unwrap();
        let v = flow.sample(255, 255, 0.0).unwrap();
        assert!(v.iter().flatten().all(|x| x.is_finite()));
    }
}
