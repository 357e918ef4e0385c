//! Wavefront MTL material libraries (the `mtllib` of an OBJ), read line by line so that
//! every error names the file and line.
//!
//! ```text
//! newmtl red_plastic
//! Kd 0.8 0.1 0.1          # diffuse colour (one value: grey)
//! Ks 0.5 0.5 0.5          # specular colour
//! Ns 200                  # Phong exponent
//! map_Kd -s 1 1 1 wood.png
//! Ke 10 10 10             # emitted radiance
//! illum 2
//! ```
//!
//! Statements read: `newmtl`, `Kd`, `Ks`, `Ke`, `Tf`, `Ns`, `Ni`, `d`, `Tr`, `illum`,
//! `map_Kd`, `map_Ks`, `map_Ke`, `map_Bump`/`bump`/`norm`, `map_d`. Other statements
//! (`Ka`, `map_Ka`, `Pr`, ...) are ignored. Keywords are case-insensitive. Texture
//! statements may carry options (`-s u v w`, `-o`, `-bm`, `-clamp on`, ...): they are
//! skipped (a warning is logged for a scale or offset, which are not applied); the rest
//! of the line is the file name, relative to the MTL file, spaces and `\` separators
//! allowed. Colours given as `spectral` or `xyz` are errors. How a material becomes a
//! lightpath material is decided by the OBJ scene loader ([`super::obj`]).

use std::path::{Path, PathBuf};

use glam::Vec3;

use crate::error::{Error, Location, Result};

/// A texture map statement: the file (resolved against the MTL file's folder) and the
/// line that named it.
#[derive(Debug, Clone, PartialEq)]
pub struct MapRef {
    pub path: PathBuf,
    pub line: u32,
}

/// One `newmtl` block; `None`: the statement was absent.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MtlMaterial {
    pub name: String,
    /// The MTL file and the line of the `newmtl`.
    pub file: PathBuf,
    pub line: u32,
    pub kd: Option<Vec3>,
    pub ks: Option<Vec3>,
    pub ke: Option<Vec3>,
    /// Transmission filter.
    pub tf: Option<Vec3>,
    /// Phong exponent.
    pub ns: Option<f32>,
    /// Index of refraction.
    pub ni: Option<f32>,
    /// Dissolve (opacity): `d`, or `1 - Tr` when only `Tr` is given.
    pub dissolve: Option<f32>,
    pub illum: Option<u32>,
    pub map_kd: Option<MapRef>,
    pub map_ks: Option<MapRef>,
    pub map_ke: Option<MapRef>,
    /// `map_Bump`, `bump` or `norm`.
    pub map_normal: Option<MapRef>,
    /// `map_d`: a coverage (opacity) map that cuts the surface out where it is below
    /// one half.
    pub map_d: Option<MapRef>,
}

/// Reads an MTL file.
pub fn load_mtl(path: &Path) -> Result<Vec<MtlMaterial>> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    parse_mtl(&String::from_utf8_lossy(&bytes), path)
}

/// Parses MTL text; `path` names the file in errors and resolves texture paths.
pub fn parse_mtl(text: &str, path: &Path) -> Result<Vec<MtlMaterial>> {
    let folder = path.parent().unwrap_or(Path::new(""));
    let mut materials: Vec<MtlMaterial> = Vec::new();
    // `Tr` applies only when the block has no `d`.
    let mut tr: Option<f32> = None;
    let finish = |m: &mut MtlMaterial, tr: &mut Option<f32>| {
        if m.dissolve.is_none() {
            m.dissolve = tr.map(|t| 1.0 - t);
        }
        *tr = None;
    };
    for (index, raw) in text.lines().enumerate() {
        let line = index as u32 + 1;
        let error = |message: String| {
            Error::scene(
                Location {
                    file: path.to_path_buf(),
                    line,
                    column: 1,
                },
                message,
            )
        };
        let content = raw.split('#').next().unwrap_or("").trim();
        let Some(keyword) = content.split_whitespace().next() else {
            continue;
        };
        let rest = content[keyword.len()..].trim();
        let keyword = keyword.to_ascii_lowercase();
        if keyword == "newmtl" {
            if rest.is_empty() {
                return Err(error("`newmtl` needs a material name".into()));
            }
            if let Some(m) = materials.last_mut() {
                finish(m, &mut tr);
            }
            materials.push(MtlMaterial {
                name: rest.to_string(),
                file: path.to_path_buf(),
                line,
                ..Default::default()
            });
            continue;
        }
        let Some(m) = materials.last_mut() else {
            return Err(error(format!("`{keyword}` before any `newmtl`")));
        };
        let float = |s: &str| -> Result<f32> {
            s.parse::<f32>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| error(format!("`{keyword}`: `{s}` is not a finite number")))
        };
        let number = || -> Result<f32> {
            let values: Vec<&str> = rest.split_whitespace().collect();
            match values.as_slice() {
                [v] => float(v),
                _ => Err(error(format!("`{keyword}` needs one number, got `{rest}`"))),
            }
        };
        let colour = || -> Result<Vec3> {
            let values: Vec<&str> = rest.split_whitespace().collect();
            match values.as_slice() {
                [s, ..] if s.eq_ignore_ascii_case("spectral") || s.eq_ignore_ascii_case("xyz") => {
                    Err(error(format!(
                        "`{keyword} {s}` colours are not supported; give r g b"
                    )))
                }
                [v] => Ok(Vec3::splat(float(v)?)),
                [r, g, b] => Ok(Vec3::new(float(r)?, float(g)?, float(b)?)),
                _ => Err(error(format!(
                    "`{keyword}` needs one or three numbers, got `{rest}`"
                ))),
            }
        };
        let map = || -> Result<MapRef> {
            let file = map_file(rest, &keyword, path, line).map_err(error)?;
            Ok(MapRef {
                path: folder.join(file.replace('\\', "/")),
                line,
            })
        };
        match keyword.as_str() {
            "kd" => m.kd = Some(colour()?),
            "ks" => m.ks = Some(colour()?),
            "ke" => m.ke = Some(colour()?),
            "tf" => m.tf = Some(colour()?),
            "ns" => m.ns = Some(number()?.max(0.0)),
            "ni" => {
                let ni = number()?;
                if ni <= 0.0 {
                    return Err(error(format!("`Ni` must be positive, got {ni}")));
                }
                m.ni = Some(ni);
            }
            "d" => m.dissolve = Some(number()?.clamp(0.0, 1.0)),
            "tr" => tr = Some(number()?.clamp(0.0, 1.0)),
            "illum" => {
                let v = rest
                    .parse::<u32>()
                    .ok()
                    .filter(|v| *v <= 10)
                    .ok_or_else(|| error(format!("`illum` needs a model 0 to 10, got `{rest}`")))?;
                m.illum = Some(v);
            }
            "map_kd" => m.map_kd = Some(map()?),
            "map_ks" => m.map_ks = Some(map()?),
            "map_ke" => m.map_ke = Some(map()?),
            "map_bump" | "bump" | "norm" => m.map_normal = Some(map()?),
            "map_d" => m.map_d = Some(map()?),
            _ => {}
        }
    }
    if let Some(m) = materials.last_mut() {
        finish(m, &mut tr);
    }
    Ok(materials)
}

/// The file name of a texture statement: options skipped, the rest joined.
fn map_file(
    rest: &str,
    keyword: &str,
    path: &Path,
    line: u32,
) -> std::result::Result<String, String> {
    // Options and how many arguments each takes (`-o`, `-s`, `-t`: up to three numbers).
    const ONE: &[&str] = &[
        "-blendu", "-blendv", "-boost", "-texres", "-clamp", "-bm", "-imfchan", "-type", "-cc",
    ];
    let mut tokens = rest.split_whitespace().peekable();
    let mut words: Vec<&str> = Vec::new();
    while let Some(t) = tokens.next() {
        let option = t.to_ascii_lowercase();
        if !words.is_empty() || !t.starts_with('-') {
            words.push(t);
        } else if ONE.contains(&option.as_str()) {
            tokens
                .next()
                .ok_or_else(|| format!("`{keyword}`: option `{t}` needs a value"))?;
        } else if option == "-mm" {
            for _ in 0..2 {
                tokens
                    .next()
                    .ok_or_else(|| format!("`{keyword}`: option `-mm` needs two values"))?;
            }
        } else if matches!(option.as_str(), "-o" | "-s" | "-t") {
            let mut values = Vec::new();
            while values.len() < 3 {
                match tokens.peek().and_then(|v| v.parse::<f32>().ok()) {
                    Some(v) => {
                        values.push(v);
                        tokens.next();
                    }
                    None => break,
                }
            }
            if values.is_empty() {
                return Err(format!("`{keyword}`: option `{t}` needs numbers"));
            }
            let neutral = if option == "-s" { 1.0 } else { 0.0 };
            if option != "-t" && values.iter().any(|v| *v != neutral) {
                log::warn!(
                    "{}:{line}: `{keyword}` option `{t}` is not supported; the texture is \
                     applied without it",
                    path.display()
                );
            }
        } else {
            return Err(format!("`{keyword}`: unknown option `{t}`"));
        }
    }
    if words.is_empty() {
        return Err(format!("`{keyword}` needs a file name"));
    }
    Ok(words.join(" "))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Vec<MtlMaterial>> {
        parse_mtl(text, Path::new("/models/lib.mtl"))
    }

    #[test]
    fn statements_and_texture_options() {
        let m = parse(
            "# comment\n\
             newmtl a\n  Kd 0.5 0.25 1 # trailing\nKS 0.2\nNs 100\nmap_Kd -s 2 2 1 -clamp on tex\\wood grain.png\n\
             newmtl glass\nd 1\nTr 0.9\nNi 1.33\nillum 7\nTf 1 0.9 0.8\nnorm n.png\n\
             newmtl b\nTr 0.25\nKe 1 2 3\nmap_Ke -bm 1 glow.png\n",
        )
        .expect("parse");
        assert_eq!(m.len(), 3);
        assert_eq!(m[0].name, "a");
        assert_eq!(m[0].line, 2);
        assert_eq!(m[0].kd, Some(Vec3::new(0.5, 0.25, 1.0)));
        assert_eq!(m[0].ks, Some(Vec3::splat(0.2)));
        assert_eq!(m[0].ns, Some(100.0));
        assert_eq!(
            m[0].map_kd,
            Some(MapRef {
                path: PathBuf::from("/models/tex/wood grain.png"),
                line: 6
            })
        );
        assert_eq!(m[0].dissolve, None);
        // `d` wins over `Tr`.
        assert_eq!(m[1].dissolve, Some(1.0));
        assert_eq!(m[1].ni, Some(1.33));
        assert_eq!(m[1].illum, Some(7));
        assert_eq!(m[1].tf, Some(Vec3::new(1.0, 0.9, 0.8)));
        assert_eq!(
            m[1].map_normal.as_ref().map(|r| r.path.clone()),
            Some(PathBuf::from("/models/n.png"))
        );
        assert_eq!(m[2].dissolve, Some(0.75));
        assert_eq!(m[2].ke, Some(Vec3::new(1.0, 2.0, 3.0)));
        assert_eq!(m[2].map_ke.as_ref().unwrap().line, 17);
    }

    #[test]
    fn errors_name_file_and_line() {
        for (text, line, what) in [
            ("newmtl a\nKd 1 x 1\n", 2, "`x` is not a finite number"),
            ("newmtl a\n\nKd 1 1\n", 3, "one or three numbers"),
            ("Kd 1 1 1\n", 1, "before any `newmtl`"),
            ("newmtl\n", 1, "needs a material name"),
            ("newmtl a\nNi 0\n", 2, "must be positive"),
            ("newmtl a\nillum two\n", 2, "`illum`"),
            ("newmtl a\nKd spectral foo.spd\n", 2, "not supported"),
            ("newmtl a\nmap_Kd -s 1 1\n", 2, "needs a file name"),
            ("newmtl a\nmap_Kd -zz 1 a.png\n", 2, "unknown option `-zz`"),
            ("newmtl a\nNs inf\n", 2, "not a finite number"),
        ] {
            let message = parse(text).expect_err(text).to_string();
            assert!(
                message.starts_with(&format!("/models/lib.mtl:{line}:")),
                "{text:?}: {message}"
            );
            assert!(message.contains(what), "{text:?}: {message}");
        }
    }
}
