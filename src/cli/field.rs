//! `--field SPEC`: the Jacobian field of anisometric synthesis, parsed into a spec and
//! resolved against the output size (presets default to its centre).

use std::path::PathBuf;
use std::sync::Arc;

use texsyn::field::{self, Field};

use super::{fail, CliResult};

pub const FIELD_HELP: &str = "Anisometric synthesis along a Jacobian field. SPEC is one of:
  rotate:DEG                  the texture rotated by DEG degrees
  scale:S[,SY]                magnified by S (or S along x, SY along y)
  constant:DEG,SX,SY,SHEAR    rotation, scales and shear together
  vortex[:CX,CY[,S]]          the texture's x axis circles around (CX, CY)
  swirl[:CX,CY,R,TURNS[,S]]   rotated by TURNS*360 deg at the centre, fading to 0 at radius R
  radial[:CX,CY,R,S,GROWTH]   'up' points at the centre; magnified by S at radius R and
                              S*GROWTH at the centre
  perspective[:HORIZON,S[,BOTTOM,CX]]
                              ground plane: horizon at row HORIZON, magnification S at row
                              BOTTOM (default: the output's last), vanishing point at
                              column CX (default: the output's centre)
  image:FILE                  per pixel: red = rotation (0..1 = 0..360 deg), green =
                              magnification (0..1 = 1/8..8, log scale, 0.5 = 1); the output's size
  exr:FILE                    per pixel 2x2 Jacobian (R, G, B, A = J00, J01, J10, J11; exemplar
                              pixels per output pixel); the output's size
Positions are output pixels; defaults: the output's centre, R = half its smaller side, S = 1.
The defaults follow the --window: give every position for windows of one field to fit together.
The scales of scale: and constant: lie in 1/8..8; varying fields are clamped to it per pixel.";

/// A parsed `--field` argument (numbers still unresolved against the output size).
#[derive(Clone, Debug)]
pub enum FieldSpec {
    Constant {
        angle_deg: f64,
        scale: [f64; 2],
        shear: f64,
    },
    Vortex(Vec<f64>),
    Swirl(Vec<f64>),
    Radial(Vec<f64>),
    Perspective(Vec<f64>),
    Image(PathBuf),
    Exr(PathBuf),
}

fn numbers(s: &str, what: &str) -> Result<Vec<f64>, String> {
    if s.is_empty() {
        return Ok(Vec::new());
    }
    s.split(',')
        .map(|v| {
            let x: f64 = v
                .trim()
                .parse()
                .map_err(|_| format!("{what}: '{v}' is not a number"))?;
            if x.is_finite() {
                Ok(x)
            } else {
                Err(format!("{what}: '{v}' is not a finite number"))
            }
        })
        .collect()
}

pub fn parse_field(s: &str) -> Result<FieldSpec, String> {
    let (name, rest) = s.split_once(':').unwrap_or((s, ""));
    let count = |v: &Vec<f64>, allowed: &[usize]| -> Result<(), String> {
        if allowed.contains(&v.len()) {
            Ok(())
        } else {
            Err(format!(
                "{name}: expected {} number(s), got {}",
                allowed
                    .iter()
                    .map(|n| n.to_string())
                    .collect::<Vec<_>>()
                    .join(" or "),
                v.len()
            ))
        }
    };
    match name {
        "rotate" => {
            let v = numbers(rest, name)?;
            count(&v, &[1])?;
            Ok(FieldSpec::Constant { angle_deg: v[0], scale: [1.0, 1.0], shear: 0.0 })
        }
        "scale" => {
            let v = numbers(rest, name)?;
            count(&v, &[1, 2])?;
            Ok(FieldSpec::Constant {
                angle_deg: 0.0,
                scale: [v[0], *v.get(1).unwrap_or(&v[0])],
                shear: 0.0,
            })
        }
        "constant" => {
            let v = numbers(rest, name)?;
            count(&v, &[4])?;
            Ok(FieldSpec::Constant { angle_deg: v[0], scale: [v[1], v[2]], shear: v[3] })
        }
        "vortex" => {
            let v = numbers(rest, name)?;
            count(&v, &[0, 2, 3])?;
            Ok(FieldSpec::Vortex(v))
        }
        "swirl" => {
            let v = numbers(rest, name)?;
            count(&v, &[0, 4, 5])?;
            Ok(FieldSpec::Swirl(v))
        }
        "radial" => {
            let v = numbers(rest, name)?;
            count(&v, &[0, 5])?;
            Ok(FieldSpec::Radial(v))
        }
        "perspective" => {
            let v = numbers(rest, name)?;
            count(&v, &[0, 2, 4])?;
            Ok(FieldSpec::Perspective(v))
        }
        "image" if !rest.is_empty() => Ok(FieldSpec::Image(rest.into())),
        "exr" if !rest.is_empty() => Ok(FieldSpec::Exr(rest.into())),
        "image" => Err("image: give a file, e.g. image:field.png".into()),
        "exr" => Err("exr: give a file, e.g. exr:jacobian.exr".into()),
        _ => Err(format!(
            "unknown field '{name}' (rotate, scale, constant, vortex, swirl, radial, perspective, image, exr)"
        )),
    }
}

impl FieldSpec {
    /// The file an `image:` or `exr:` field is read from.
    pub fn file(&self) -> Option<&std::path::Path> {
        match self {
            FieldSpec::Image(p) | FieldSpec::Exr(p) => Some(p),
            _ => None,
        }
    }

    /// The field's file as a labelled input (for `check_outputs_not_inputs`).
    pub fn input(field: &Option<FieldSpec>) -> Option<(&'static str, &std::path::Path)> {
        field
            .as_ref()
            .and_then(|f| f.file())
            .map(|f| ("--field file", f))
    }

    /// The spec as `--field` takes it (for reports).
    pub fn spec(&self) -> String {
        let list = |name: &str, v: &[f64]| {
            if v.is_empty() {
                name.to_string()
            } else {
                let nums: Vec<String> = v.iter().map(|x| x.to_string()).collect();
                format!("{name}:{}", nums.join(","))
            }
        };
        match self {
            FieldSpec::Constant {
                angle_deg,
                scale,
                shear,
            } => format!("constant:{angle_deg},{},{},{shear}", scale[0], scale[1]),
            FieldSpec::Vortex(v) => list("vortex", v),
            FieldSpec::Swirl(v) => list("swirl", v),
            FieldSpec::Radial(v) => list("radial", v),
            FieldSpec::Perspective(v) => list("perspective", v),
            FieldSpec::Image(p) => format!("image:{}", p.display()),
            FieldSpec::Exr(p) => format!("exr:{}", p.display()),
        }
    }

    /// The field for an output window `origin`, `width` x `height`: presets default to
    /// the window's centre; maps must have the window's size.
    pub fn resolve(&self, origin: [i32; 2], width: u32, height: u32) -> CliResult<Field> {
        let c = [
            origin[0] as f64 + width as f64 / 2.0,
            origin[1] as f64 + height as f64 / 2.0,
        ];
        let r = width.min(height) as f64 / 2.0;
        let f = match self {
            FieldSpec::Constant {
                angle_deg,
                scale,
                shear,
            } => Field::Constant {
                angle: angle_deg.to_radians(),
                scale: *scale,
                shear: *shear,
            },
            FieldSpec::Vortex(v) => Field::Vortex {
                center: if v.is_empty() { c } else { [v[0], v[1]] },
                scale: *v.get(2).unwrap_or(&1.0),
            },
            FieldSpec::Swirl(v) => {
                if v.is_empty() {
                    Field::Swirl {
                        center: c,
                        radius: r,
                        turns: 0.5,
                        scale: 1.0,
                    }
                } else {
                    Field::Swirl {
                        center: [v[0], v[1]],
                        radius: v[2],
                        turns: v[3],
                        scale: *v.get(4).unwrap_or(&1.0),
                    }
                }
            }
            FieldSpec::Radial(v) => {
                if v.is_empty() {
                    Field::Radial {
                        center: c,
                        radius: r,
                        scale: 1.0,
                        growth: 3.0,
                    }
                } else {
                    Field::Radial {
                        center: [v[0], v[1]],
                        radius: v[2],
                        scale: v[3],
                        growth: v[4],
                    }
                }
            }
            FieldSpec::Perspective(v) => {
                let (horizon, scale) = if v.is_empty() {
                    (origin[1] as f64 - height as f64 / 2.0, 1.5)
                } else {
                    (v[0], v[1])
                };
                // Absolute, so that windows of one field agree: the defaults follow the
                // window.
                let (bottom, center) = if v.len() == 4 {
                    (v[2], v[3])
                } else {
                    (origin[1] as f64 + height as f64 - 1.0, c[0])
                };
                Field::Perspective {
                    horizon,
                    bottom,
                    center,
                    scale,
                }
            }
            FieldSpec::Image(p) | FieldSpec::Exr(p) => {
                let map = if matches!(self, FieldSpec::Image(_)) {
                    field::load_direction_scale_image(p)?
                } else {
                    field::load_jacobian_exr(p)?
                };
                if map.width != width || map.height != height {
                    return Err(fail(format!(
                        "field {}: {}x{} pixels, but the output is {width}x{height} (as \
                         synthesized, before any --magnify); the field must have that size",
                        p.display(),
                        map.width,
                        map.height
                    )));
                }
                if origin != [0, 0] {
                    return Err(fail(
                        "a field from a file covers the output at window 0,0; it cannot be \
                         combined with --window",
                    ));
                }
                Field::Map(Arc::new(map))
            }
        };
        f.validate()?;
        Ok(f)
    }
}
