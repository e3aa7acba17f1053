//! Text forms of the field sources for the CLI: parsing and printing
//! [`DirectionSource`] and [`ScaleSource`], and reading direction-constraint files.

use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use glam::Vec3;

use super::field::invalid;
use super::{DirectionSource, ScaleSource, DEFAULT_SYMMETRIC_ITERATIONS, MAX_SYMMETRIC_ITERATIONS};
use crate::error::{Error, Result};

fn parse_f32(s: &str, what: &str) -> std::result::Result<f32, String> {
    let v: f32 = s
        .trim()
        .parse()
        .map_err(|_| format!("{what}: `{s}` is not a number"))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("{what}: `{s}` is not finite"))
    }
}

fn parse_vec3(s: &str, what: &str) -> std::result::Result<Vec3, String> {
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != 3 {
        return Err(format!("{what}: `{s}` is not three numbers X,Y,Z"));
    }
    let v = Vec3::new(
        parse_f32(parts[0], what)?,
        parse_f32(parts[1], what)?,
        parse_f32(parts[2], what)?,
    );
    if v == Vec3::ZERO {
        return Err(format!("{what}: `{s}` is the zero vector"));
    }
    Ok(v)
}

fn fmt_vec3(v: Vec3) -> String {
    format!("{},{},{}", v.x, v.y, v.z)
}

/// Parses constraint lines `px py pz dx dy dz` (numbers separated by white space or
/// commas; `#` starts a comment; blank lines are skipped). `name` is used in messages.
pub fn parse_constraints(text: &str, name: &str) -> Result<Vec<(Vec3, Vec3)>> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("");
        let fields: Vec<&str> = line
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|f| !f.is_empty())
            .collect();
        if fields.is_empty() {
            continue;
        }
        let here = format!("{name} line {}", i + 1);
        if fields.len() != 6 {
            return Err(invalid(format!(
                "{here}: expected 6 numbers `px py pz dx dy dz`, found {} fields",
                fields.len()
            )));
        }
        let mut v = [0.0f32; 6];
        for (k, f) in fields.iter().enumerate() {
            v[k] = parse_f32(f, &here).map_err(invalid)?;
        }
        let d = Vec3::new(v[3], v[4], v[5]);
        if d == Vec3::ZERO {
            return Err(invalid(format!("{here}: the direction is the zero vector")));
        }
        out.push((Vec3::new(v[0], v[1], v[2]), d));
    }
    if out.is_empty() {
        return Err(invalid(format!(
            "{name}: no constraints (expected lines `px py pz dx dy dz`)"
        )));
    }
    Ok(out)
}

/// Reads a constraint file; see [`parse_constraints`].
pub fn read_constraints(path: &Path) -> Result<Vec<(Vec3, Vec3)>> {
    // A text file of a few lines per constraint: 64 MiB is far more than any real list.
    let bytes = crate::image_io::read_file_capped(path, 64 << 20, "constraint files")?;
    let text = String::from_utf8(bytes).map_err(|_| Error::Io {
        path: path.to_path_buf(),
        source: std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            "not a UTF-8 text file (a constraint file holds lines of numbers)",
        ),
    })?;
    parse_constraints(&text, &path.display().to_string())
}

/// A direction as written (the syntax of [`DIRECTION_HELP`](super::DIRECTION_HELP))
/// with a `constraints:FILE` not read yet: parsing checks the text, [`Self::load`] reads
/// the file (so that a command line is parsed before any input is opened).
#[derive(Clone, Debug)]
pub enum DirectionSpec {
    /// A direction that needs no file.
    Parsed(DirectionSource),
    /// `constraints:FILE`: the constraint file to read.
    ConstraintsFile(PathBuf),
}

impl DirectionSpec {
    /// The direction, with the constraint file read ([`read_constraints`]).
    pub fn load(&self) -> Result<DirectionSource> {
        match self {
            DirectionSpec::Parsed(d) => Ok(d.clone()),
            DirectionSpec::ConstraintsFile(path) => {
                read_constraints(path).map(DirectionSource::Constraints)
            }
        }
    }
}

impl FromStr for DirectionSpec {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        match s.strip_prefix("constraints:").map(str::trim) {
            Some(path) if !path.is_empty() => Ok(DirectionSpec::ConstraintsFile(path.into())),
            _ => s.parse().map(DirectionSpec::Parsed),
        }
    }
}

impl FromStr for DirectionSource {
    type Err = Error;

    /// The syntax of [`DIRECTION_HELP`](super::DIRECTION_HELP). `constraints:FILE` reads the file.
    fn from_str(s: &str) -> Result<Self> {
        let text = s.trim();
        let fail = |reason: String| {
            invalid(format!(
                "direction `{text}`: {reason}; expected up, up:X,Y,Z, tangents, \
                 symmetric:N[:X,Y,Z[:ITERATIONS]], random[:SEED] or constraints:FILE"
            ))
        };
        let (head, rest) = match text.split_once(':') {
            Some((h, r)) => (h, Some(r)),
            None => (text, None),
        };
        match (head.to_ascii_lowercase().as_str(), rest) {
            ("up", None) => Ok(DirectionSource::Up(Vec3::Y)),
            ("up", Some(r)) => Ok(DirectionSource::Up(parse_vec3(r, "up").map_err(fail)?)),
            ("tangents", None) => Ok(DirectionSource::MeshTangents),
            ("symmetric", Some(r)) => {
                let parts: Vec<&str> = r.split(':').collect();
                if parts.len() > 3 {
                    return Err(fail("too many fields".into()));
                }
                let n: u32 = parts[0]
                    .trim()
                    .parse()
                    .map_err(|_| fail(format!("N = `{}` is not a whole number", parts[0])))?;
                if !matches!(n, 1 | 2 | 4 | 6) {
                    return Err(fail(format!("N = {n}; use 1, 2, 4 or 6")));
                }
                let up = match parts.get(1) {
                    Some(v) => parse_vec3(v, "up").map_err(fail)?,
                    None => Vec3::Y,
                };
                let iterations = match parts.get(2) {
                    Some(v) => v
                        .trim()
                        .parse()
                        .map_err(|_| fail(format!("ITERATIONS = `{v}` is not a whole number")))?,
                    None => DEFAULT_SYMMETRIC_ITERATIONS,
                };
                if iterations > MAX_SYMMETRIC_ITERATIONS {
                    return Err(fail(format!(
                        "ITERATIONS = {iterations}; use 0 to {MAX_SYMMETRIC_ITERATIONS} (default {DEFAULT_SYMMETRIC_ITERATIONS})"
                    )));
                }
                Ok(DirectionSource::Symmetric { n, up, iterations })
            }
            ("symmetric", None) => Err(fail("give N (symmetric:N)".into())),
            ("random", None) => Ok(DirectionSource::RandomPerRegion { seed: 0 }),
            ("random", Some(r)) => Ok(DirectionSource::RandomPerRegion {
                seed: r.trim().parse().map_err(|_| {
                    fail(format!(
                        "SEED = `{r}` is not a whole number from 0 to {}",
                        u32::MAX
                    ))
                })?,
            }),
            ("constraints", Some(path)) if !path.trim().is_empty() => Ok(
                DirectionSource::Constraints(read_constraints(Path::new(path.trim()))?),
            ),
            ("constraints", _) => Err(fail("give a file (constraints:FILE)".into())),
            ("tangents", Some(_)) => Err(fail("`tangents` takes no argument".into())),
            _ => Err(fail("unknown direction source".into())),
        }
    }
}

impl fmt::Display for DirectionSource {
    /// The [`FromStr`] form, which parses back to the same value, except for
    /// `Constraints`, written `constraints(N pairs)` (its file name is not kept).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DirectionSource::Up(v) if *v == Vec3::Y => write!(f, "up"),
            DirectionSource::Up(v) => write!(f, "up:{}", fmt_vec3(*v)),
            DirectionSource::MeshTangents => write!(f, "tangents"),
            DirectionSource::Constraints(list) => write!(f, "constraints({} pairs)", list.len()),
            DirectionSource::Symmetric { n, up, iterations } => {
                if *iterations != DEFAULT_SYMMETRIC_ITERATIONS {
                    write!(f, "symmetric:{n}:{}:{iterations}", fmt_vec3(*up))
                } else if *up != Vec3::Y {
                    write!(f, "symmetric:{n}:{}", fmt_vec3(*up))
                } else {
                    write!(f, "symmetric:{n}")
                }
            }
            DirectionSource::RandomPerRegion { seed } => write!(f, "random:{seed}"),
        }
    }
}

impl FromStr for ScaleSource {
    type Err = Error;

    /// `S` (a number > 0) or `linear:AX,AY,AZ:S_MIN:S_MAX`.
    fn from_str(s: &str) -> Result<Self> {
        let text = s.trim();
        let fail = |reason: String| {
            invalid(format!(
                "scale `{text}`: {reason}; expected a number > 0 (world units per exemplar \
                 texel) or linear:AX,AY,AZ:S_MIN:S_MAX"
            ))
        };
        let positive = |v: f32, what: &str| {
            if v > 0.0 {
                Ok(v)
            } else {
                Err(fail(format!("{what} = {v} must be > 0")))
            }
        };
        if let Some(rest) = text
            .strip_prefix("linear:")
            .or_else(|| text.strip_prefix("LINEAR:"))
        {
            let parts: Vec<&str> = rest.split(':').collect();
            if parts.len() != 3 {
                return Err(fail("linear needs AXIS:S_MIN:S_MAX".into()));
            }
            let axis = parse_vec3(parts[0], "axis").map_err(fail)?;
            let at_min = positive(parse_f32(parts[1], "S_MIN").map_err(fail)?, "S_MIN")?;
            let at_max = positive(parse_f32(parts[2], "S_MAX").map_err(fail)?, "S_MAX")?;
            return Ok(ScaleSource::Linear {
                axis,
                at_min,
                at_max,
            });
        }
        let v = parse_f32(text, "scale").map_err(fail)?;
        Ok(ScaleSource::Constant(positive(v, "scale")?))
    }
}

impl fmt::Display for ScaleSource {
    /// The [`FromStr`] form, except for `PerVertex`, written `per-vertex(N values)`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ScaleSource::Constant(s) => write!(f, "{s}"),
            ScaleSource::PerVertex(v) => write!(f, "per-vertex({} values)", v.len()),
            ScaleSource::Linear {
                axis,
                at_min,
                at_max,
            } => write!(f, "linear:{}:{at_min}:{at_max}", fmt_vec3(*axis)),
        }
    }
}
