//! `--also`: the material maps of `texsyn synth`, `[normal:|normal-dx:|plain:]IN=OUT`.

use std::path::{Path, PathBuf};

/// One `--also` map.
#[derive(Clone, Debug)]
pub struct AlsoMap {
    /// The map, aligned with the exemplar.
    pub input: PathBuf,
    /// Where its resynthesized version goes.
    pub output: PathBuf,
    /// A tangent-space normal map.
    pub normal: bool,
    /// A normal map with green = y down (DirectX), `normal-dx:`.
    pub green_down: bool,
}

impl AlsoMap {
    /// The map as the library takes it.
    pub fn material_map(&self) -> texsyn::MaterialMap {
        texsyn::MaterialMap {
            path: self.input.clone(),
            normal: self.normal,
            green_down: self.green_down,
        }
    }
}

pub fn parse_also(s: &str) -> Result<AlsoMap, String> {
    // normal: green up (OpenGL, glTF, Blender); normal-dx: green down (DirectX).
    let (kind, green_down, rest) = if let Some(r) = s.strip_prefix("normal:") {
        (Some(true), false, r)
    } else if let Some(r) = s.strip_prefix("normal-dx:") {
        (Some(true), true, r)
    } else if let Some(r) = s.strip_prefix("plain:") {
        (Some(false), false, r)
    } else {
        (None, false, s)
    };
    let (input, output) = split_in_out(rest).map_err(|why| format!("'{s}': {why}"))?;
    // `word:IN=OUT` with an unknown word is a typo of a kind, not a file name.
    if kind.is_none() {
        if let Some((prefix, _)) = input.split_once(':') {
            if prefix.len() > 1
                && prefix
                    .bytes()
                    .all(|b| b.is_ascii_alphanumeric() || b == b'-')
            {
                return Err(format!(
                    "'{s}': unknown map kind '{prefix}:' (normal:, normal-dx: or plain:)"
                ));
            }
        }
    }
    if input.is_empty() || output.is_empty() {
        return Err(format!("'{s}': both IN and OUT must be given"));
    }
    let input = PathBuf::from(input);
    let normal = kind.unwrap_or_else(|| {
        input
            .file_name()
            .is_some_and(|n| n.to_string_lossy().to_lowercase().contains("normal"))
    });
    Ok(AlsoMap {
        input,
        output: output.into(),
        normal,
        green_down,
    })
}

/// Splits `IN=OUT`. A name may contain `=`: with several, the split is the one whose
/// `IN` is an existing file (it must be the only one).
fn split_in_out(rest: &str) -> Result<(&str, &str), String> {
    let splits: Vec<(&str, &str)> = rest
        .match_indices('=')
        .map(|(i, _)| (&rest[..i], &rest[i + 1..]))
        .collect();
    match splits[..] {
        [] => Err("expected IN=OUT, e.g. normal.png=out_normal.png".into()),
        [one] => Ok(one),
        _ => {
            let existing: Vec<_> = splits
                .iter()
                .filter(|(input, _)| !input.is_empty() && Path::new(input).is_file())
                .collect();
            match existing[..] {
                [one] => Ok(*one),
                [] => Err(format!(
                    "{} '=' signs and no split whose IN is an existing file: check the input's \
                     name",
                    splits.len()
                )),
                _ => Err(format!(
                    "ambiguous: {} are all existing files; rename the input or the output so \
                     that only one '=' separates IN from OUT",
                    existing
                        .iter()
                        .map(|(i, _)| format!("'{i}'"))
                        .collect::<Vec<_>>()
                        .join(" and ")
                )),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn also_names_with_equals_signs() {
        let dir = std::env::temp_dir().join(format!("texsyn-also-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = |name: &str| {
            let p = dir.join(name);
            std::fs::write(&p, b"x").unwrap();
            p.to_str().unwrap().to_string()
        };
        // One '=': split there, whether IN exists or not.
        let a = parse_also("in.png=out.png").unwrap();
        assert_eq!((a.input, a.output), ("in.png".into(), "out.png".into()));
        // Several: the split whose IN is an existing file.
        let eq_in = file("rough=0.5.png");
        let a = parse_also(&format!("{eq_in}=out.png")).unwrap();
        assert_eq!(
            (a.input, a.output),
            (eq_in.clone().into(), "out.png".into())
        );
        let a = parse_also(&format!("plain:{eq_in}=o=1.png")).unwrap();
        assert_eq!((a.input, a.output), (eq_in.into(), "o=1.png".into()));
        let plain_in = file("plain.png");
        let a = parse_also(&format!("{plain_in}=o=2.png")).unwrap();
        assert_eq!((a.input, a.output), (plain_in.into(), "o=2.png".into()));
        // No existing split, or two: errors that say so.
        let e = parse_also("missing=a=b.png").unwrap_err();
        assert!(e.contains("no split whose IN is an existing file"), "{e}");
        let (x, _) = (file("x"), file("x=y"));
        let e = parse_also(&format!("{x}=y=z")).unwrap_err();
        assert!(e.contains("ambiguous"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
