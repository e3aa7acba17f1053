//! Value parsers of the command line: sizes, seeds, window origins, randomness,
//! coherence, time steps.

use super::{fail, CliResult};

/// `--dt` of `advect` and `eval --flow`, read as f64 so that a step too large for the
/// frames' f32 arithmetic is named as such (as f32 it would read as `inf`).
pub fn time_step(dt: f64) -> CliResult<f32> {
    if dt.is_nan() || dt <= 0.0 {
        return Err(fail(format!(
            "--dt {dt}: the time step must be a positive number"
        )));
    }
    if dt > f32::MAX as f64 {
        return Err(fail(format!(
            "--dt {dt:e}: too large for 32-bit floats (at most {:e}; a frame moves at most {} \
             pixels anyway)",
            f32::MAX,
            texsyn::passes::advect::MAX_SPEED
        )));
    }
    if (dt as f32) <= 0.0 {
        return Err(fail(format!(
            "--dt {dt:e}: too small for 32-bit floats (it rounds to 0): give a positive \
             step of at least {:e}",
            f32::from_bits(1)
        )));
    }
    Ok(dt as f32)
}

/// A seed: an integer in `0..=u32::MAX`. Negative and other values get a message
/// naming the range (clap's default for `u32` says only "invalid digit").
pub fn parse_seed(s: &str) -> Result<u32, String> {
    s.trim()
        .parse::<u32>()
        .map_err(|_| format!("seed \"{s}\": give an integer from 0 to {}", u32::MAX))
}

/// `N` or `NxM` (also `N×M` / `NXM`), both at least 1.
pub fn parse_size(s: &str) -> Result<[u32; 2], String> {
    let t = s.trim();
    let usage = || format!("\"{s}\" is not a size: expected N or NxM, e.g. 512 or 1024x768");
    let parts: Vec<&str> = t.split(['x', 'X', '×']).collect();
    let side = |p: &str| -> Result<u32, String> {
        let p = p.trim();
        if p.is_empty() || !p.bytes().all(|b| b.is_ascii_digit()) {
            return Err(usage());
        }
        let v: u32 = p.parse().map_err(|_| {
            format!(
                "size \"{s}\": {p} is too large (at most {} pixels a side)",
                u32::MAX
            )
        })?;
        if v == 0 {
            return Err(format!("size \"{s}\": width and height must be at least 1"));
        }
        Ok(v)
    };
    match parts.as_slice() {
        [n] => {
            let n = side(n)?;
            Ok([n, n])
        }
        [w, h] => Ok([side(w)?, side(h)?]),
        _ => Err(usage()),
    }
}

/// A list of sizes (a newtype: clap treats a bare `Vec` field as repeated values).
#[derive(Clone, Debug, PartialEq)]
pub struct Sizes(pub Vec<[u32; 2]>);

/// A comma-separated list of sizes.
pub fn parse_sizes(s: &str) -> Result<Sizes, String> {
    let sizes: Vec<[u32; 2]> = s.split(',').map(parse_size).collect::<Result<_, _>>()?;
    if sizes.is_empty() {
        return Err("give at least one size".into());
    }
    Ok(Sizes(sizes))
}

/// Per-level randomness values (a newtype, see [`Sizes`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Randomness(pub Vec<f32>);

/// `R` or `R0,R1,...`: finite values in [0, 2].
pub fn parse_randomness(s: &str) -> Result<Randomness, String> {
    let mut out = Vec::new();
    for part in s.split(',') {
        let p = part.trim();
        let v: f32 = p.parse().map_err(|_| {
            format!("\"{p}\" is not a number (expected R or R0,R1,... with values in [0, 2])")
        })?;
        if !v.is_finite() || !(0.0..=2.0).contains(&v) {
            return Err(format!("randomness {p} must be between 0 and 2"));
        }
        out.push(v);
    }
    Ok(Randomness(out))
}

/// `X,Y` (integers, may be negative).
pub fn parse_window(s: &str) -> Result<[i32; 2], String> {
    let usage = || {
        format!("\"{s}\" is not a window origin: expected X,Y (integers, e.g. 0,0 or -512,1024)")
    };
    let parts: Vec<&str> = s.split(',').collect();
    let [x, y] = parts.as_slice() else {
        return Err(usage());
    };
    let x: i32 = x.trim().parse().map_err(|_| usage())?;
    let y: i32 = y.trim().parse().map_err(|_| usage())?;
    // Keep well inside i32 so the plan's margins cannot overflow.
    const LIMIT: i32 = 1 << 28;
    if x.unsigned_abs() > LIMIT as u32 || y.unsigned_abs() > LIMIT as u32 {
        return Err(format!(
            "window origin {x},{y}: coordinates must lie within +-{LIMIT}"
        ));
    }
    Ok([x, y])
}

/// Coherence in [0, 1].
pub fn parse_coherence(s: &str) -> Result<f32, String> {
    let v: f32 = s
        .trim()
        .parse()
        .map_err(|_| format!("\"{s}\" is not a number"))?;
    if !v.is_finite() || !(0.0..=4.0).contains(&v) {
        return Err(format!("coherence {s} must be between 0 and 4"));
    }
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes() {
        assert_eq!(parse_size("64"), Ok([64, 64]));
        assert_eq!(parse_size("64x32"), Ok([64, 32]));
        assert_eq!(parse_size(" 7X9 "), Ok([7, 9]));
        for bad in [
            "0",
            "0x5",
            "5x0",
            "",
            "x",
            "abc",
            "5x",
            "x5",
            "1x2x3",
            "-4",
            "+4",
            "4.5",
            "99999999999",
        ] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
        assert_eq!(
            parse_sizes("256,512x128"),
            Ok(Sizes(vec![[256, 256], [512, 128]]))
        );
        assert!(parse_sizes("256,,512").is_err());
    }

    #[test]
    fn randomness_and_window() {
        assert_eq!(parse_randomness("0.5"), Ok(Randomness(vec![0.5])));
        assert_eq!(
            parse_randomness("1,0.5, 0"),
            Ok(Randomness(vec![1.0, 0.5, 0.0]))
        );
        for bad in ["", "nan", "inf", "-0.1", "2.5", "1,,2", "a"] {
            assert!(parse_randomness(bad).is_err(), "{bad}");
        }
        assert_eq!(parse_window("-5,7"), Ok([-5, 7]));
        for bad in [
            "",
            "1",
            "1,2,3",
            "a,b",
            "1.5,2",
            "999999999,0",
            "-2147483648,0",
            "0,-2147483648",
        ] {
            assert!(parse_window(bad).is_err(), "{bad}");
        }
        assert!(parse_coherence("4.5").is_err());
        assert_eq!(parse_coherence("0.25"), Ok(0.25));
    }
}
