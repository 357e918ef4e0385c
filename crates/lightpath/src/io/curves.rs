//! Curve files as Mitsuba 3's `linearcurve` and `bsplinecurve` read them: one control point per line,
//! `x y z radius` (whitespace-separated), and an empty line before each new curve.
//! Lines starting with `#` are comments. A curve needs at least two control points, or
//! what its cubic basis needs ([`CubicBasis::check_count`]).
//!
//! ```text
//! # a straight strand and a tapering one
//! -1.0 0.1 0.1 0.5
//!  1.0 1.4 1.2 0.5
//!
//! -1.0 5.0 2.2 1
//! -2.3 4.0 2.3 2
//!  4.0 1.0 2.2 5
//! ```

use crate::error::{Error, Result};
use crate::geometry::CubicBasis;
use glam::Vec3;
use std::path::Path;

/// A curve: its control points, each a position and a radius.
pub type CurvePoints = Vec<(Vec3, f32)>;

/// Reads a curve file (see the module notes) for linear segments (`basis` `None`) or
/// cubic ones in the given basis.
pub fn load_curves(path: &Path, basis: Option<CubicBasis>) -> Result<Vec<CurvePoints>> {
    let text = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let text = String::from_utf8(text)
        .map_err(|_| Error::mesh(path, "a curve file must be text (UTF-8)"))?;
    parse_curves(&text, basis).map_err(|m| Error::mesh(path, m))
}

/// Parses the text of a curve file; errors name the line. Each curve must have as many
/// control points as `basis` needs (two or more for linear segments).
pub fn parse_curves(
    text: &str,
    basis: Option<CubicBasis>,
) -> std::result::Result<Vec<CurvePoints>, String> {
    let mut curves: Vec<CurvePoints> = Vec::new();
    let mut current: CurvePoints = Vec::new();
    let mut first_line = 0;
    let mut finish = |current: &mut CurvePoints, first_line: usize| {
        if current.is_empty() {
            return Ok(());
        }
        match basis {
            None if current.len() == 1 => {
                return Err(format!(
                    "line {first_line}: a curve needs at least two control points, this one \
                     has one"
                ))
            }
            None => {}
            Some(b) => b
                .check_count(current.len())
                .map_err(|m| format!("line {first_line}: {m}"))?,
        }
        curves.push(std::mem::take(current));
        Ok(())
    };
    for (i, line) in text.lines().enumerate() {
        let number = i + 1;
        let line = line.trim();
        if line.is_empty() {
            finish(&mut current, first_line)?;
            continue;
        }
        if line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line.split_whitespace().collect();
        if fields.len() != 4 {
            return Err(format!(
                "line {number}: expected four numbers `x y z radius`, found {} field(s): `{line}`",
                fields.len()
            ));
        }
        let mut v = [0.0f32; 4];
        for (k, f) in fields.iter().enumerate() {
            v[k] = f
                .parse::<f32>()
                .map_err(|_| format!("line {number}: `{f}` is not a number"))?;
            if !v[k].is_finite() {
                return Err(format!("line {number}: `{f}` is not a finite number"));
            }
        }
        if v[3] < 0.0 {
            return Err(format!("line {number}: the radius {} is negative", v[3]));
        }
        if current.is_empty() {
            first_line = number;
        }
        current.push((Vec3::new(v[0], v[1], v[2]), v[3]));
    }
    finish(&mut current, first_line)?;
    if curves.is_empty() {
        return Err("no control points: the file holds no curve".into());
    }
    Ok(curves)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_mitsubas_example() {
        let c = parse_curves(
            "-1.0 0.1 0.1 0.5\n 1.0 1.4 1.2 0.5\n\n# second\n-1.0 5.0 2.2 1\n-2.3 4.0 2.3 2\n\
             4.0 1.0 2.2 5\r\n4.0 0.0 2.3 6\n\n\n",
            None,
        )
        .unwrap();
        assert_eq!(c.len(), 2);
        assert_eq!(c[0].len(), 2);
        assert_eq!(c[1].len(), 4);
        assert_eq!(c[1][3], (Vec3::new(4.0, 0.0, 2.3), 6.0));
    }

    #[test]
    fn errors_name_the_line() {
        for (text, expected) in [
            ("0 0 0 1\n1 1 1\n", "line 2: expected four numbers"),
            ("0 0 0 1\n1 x 1 1\n", "line 2: `x` is not a number"),
            ("0 0 0 1\n1 1 1 -1\n", "line 2: the radius -1 is negative"),
            (
                "0 0 0 1\n1 1 1 1\n\n5 5 5 1\n",
                "line 4: a curve needs at least two",
            ),
            ("0 0 0 1\n1 1 nan 1\n", "line 2: `nan` is not a finite"),
            ("\n# nothing\n", "no control points"),
        ] {
            let e = parse_curves(text, None).unwrap_err();
            assert!(e.contains(expected), "{text:?}: {e}");
        }
    }

    #[test]
    fn cubic_bases_check_their_counts() {
        let four = "0 0 0 1\n1 0 0 1\n2 0 0 1\n3 0 0 1\n";
        let three = "\n0 0 0 1\n1 0 0 1\n2 0 0 1\n";
        let five = "0 0 0 1\n1 0 0 1\n2 0 0 1\n3 0 0 1\n4 0 0 1\n";
        for basis in [
            CubicBasis::BSpline,
            CubicBasis::Bezier,
            CubicBasis::CatmullRom,
        ] {
            assert_eq!(parse_curves(four, Some(basis)).unwrap()[0].len(), 4);
            let e = parse_curves(&format!("{four}{three}"), Some(basis)).unwrap_err();
            assert!(e.starts_with("line 6: a "), "{basis:?}: {e}");
        }
        assert!(parse_curves(five, Some(CubicBasis::BSpline)).is_ok());
        let e = parse_curves(five, Some(CubicBasis::Bezier)).unwrap_err();
        assert!(e.contains("line 1: a Bézier curve needs 3k + 1"), "{e}");
    }
}
