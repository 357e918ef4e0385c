//! Lens prescription files for the realistic camera ([`crate::camera::Realistic`]):
//! pbrt's format, one surface per line from the front (scene side) to the rear (film
//! side), lengths in millimetres, with an optional fifth column for the glass's Abbe
//! number. Lines starting with `#` are comments; blank lines are skipped.
//!
//! ```text
//! # radius  thickness  eta    aperture  [abbe]
//!   30.81   6.0        1.5168  20       64.17   # front of a cemented doublet
//!  -22.39   2.5        1.6200  20       36.37
//! -408.0    3.0        1        20
//!    0      44.0       0        16              # the aperture stop
//! ```
//!
//! - `radius`: the surface's radius of curvature; positive when its centre lies on the
//!   film side (the surface bulges toward the scene); 0 for the aperture stop.
//! - `thickness`: the distance along the axis to the next surface (for the last one, to
//!   the film: the camera refocuses by changing it).
//! - `eta`: the index of refraction (at the d line, 587.6 nm) of the medium between this
//!   surface and the next; 0 or 1 for air. The stop sits in air.
//! - `aperture`: the diameter of the surface's clear aperture.
//! - `abbe`: the Abbe number V_d of that medium, (n_d - 1)/(n_F - n_C); 0 or absent for
//!   no dispersion.

use super::props::Node;
use super::xml::resolve_path;
use crate::camera::{Camera, FlareSampling, Realistic, RealisticOptions};
use crate::error::{Error, Result};
use crate::math::Transform;
use glam::UVec2;
use std::path::Path;

/// The names a scene dialect gives the realistic camera's parameters (the boolean ones,
/// `dispersion`, `flare`, `coated` and the integer `blades`, are the same in both;
/// `flare_sampling` is `light` or `camera`).
pub(crate) struct RealisticNames {
    pub lens_file: &'static str,
    pub aperture_diameter: &'static str,
    pub focus_distance: &'static str,
    pub film_diagonal: &'static str,
    pub blade_rotation: &'static str,
    pub flare_sampling: &'static str,
}

/// A realistic camera from a scene node ([`crate::camera::Realistic`]); errors name the
/// node's location.
pub(crate) fn realistic_camera(
    node: &Node,
    resolution: UVec2,
    render_from_camera: Transform,
    names: &RealisticNames,
) -> Result<Camera> {
    let file = node
        .string(names.lens_file)
        .ok_or_else(|| node.error(format!("a realistic camera needs a `{}`", names.lens_file)))?;
    let path = resolve_path(&node.location.file, &file);
    let surfaces =
        load_lens(&path).map_err(|e| node.error(format!("cannot load the lens: {e}")))?;
    let blades = match node.int("blades")? {
        None => None,
        Some(b) => Some((
            u32::try_from(b).unwrap_or(0),
            (node.float_or(names.blade_rotation, 0.0)? as f64).to_radians(),
        )),
    };
    let flare_sampling = match node.string(names.flare_sampling) {
        None => FlareSampling::default(),
        Some(name) => FlareSampling::from_name(&name).ok_or_else(|| {
            node.error(format!(
                "`{}` must be `light` or `camera`, got `{name}`",
                names.flare_sampling
            ))
        })?,
    };
    let options = RealisticOptions {
        aperture_diameter: node.float(names.aperture_diameter)?.map(f64::from),
        focus_distance: node.float_or(names.focus_distance, 10.0)? as f64,
        film_diagonal: node.float_or(names.film_diagonal, 35.0)? as f64,
        dispersion: node.bool_or("dispersion", true)?,
        flare: node.bool_or("flare", false)?,
        coated: node.bool_or("coated", true)?,
        blades,
        flare_sampling,
    };
    let camera = Realistic::new(resolution, render_from_camera, &surfaces, &options)
        .map_err(|e| node.error(format!("{} ({})", e, path.display())))?;
    Ok(Camera::Realistic(Box::new(camera)))
}

/// One surface of a lens prescription (millimetres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LensSurface {
    /// Radius of curvature; 0 for the aperture stop.
    pub curvature_radius: f64,
    /// Axial distance to the next surface (or, for the last, to the film).
    pub thickness: f64,
    /// Index of refraction at 587.6 nm of the medium behind the surface (toward the
    /// film); 1 for air.
    pub eta: f64,
    /// Diameter of the clear aperture.
    pub aperture_diameter: f64,
    /// Abbe number V_d of the medium behind the surface; 0 for none.
    pub abbe: f64,
}

impl LensSurface {
    /// Whether this is the aperture stop (a flat opening, not a glass surface).
    pub fn is_stop(&self) -> bool {
        self.curvature_radius == 0.0
    }
}

/// Reads a lens file (see the module notes).
pub fn load_lens(path: &Path) -> Result<Vec<LensSurface>> {
    let text = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let text = String::from_utf8(text)
        .map_err(|_| Error::mesh(path, "a lens file must be text (UTF-8)"))?;
    parse_lens(&text).map_err(|m| Error::mesh(path, m))
}

/// Parses the text of a lens file; errors name the line.
pub fn parse_lens(text: &str) -> std::result::Result<Vec<LensSurface>, String> {
    let mut surfaces = Vec::new();
    let mut lines = Vec::new();
    let mut stop_line = None;
    for (i, line) in text.lines().enumerate() {
        let number = i + 1;
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split_whitespace().collect();
        if !(4..=5).contains(&fields.len()) {
            return Err(format!(
                "line {number}: expected `radius thickness eta aperture [abbe]`, found {} field(s): `{line}`",
                fields.len()
            ));
        }
        let mut v = [0.0f64; 5];
        for (k, f) in fields.iter().enumerate() {
            v[k] = f
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| format!("line {number}: `{f}` is not a finite number"))?;
        }
        let surface = LensSurface {
            curvature_radius: v[0],
            thickness: v[1],
            eta: if v[2] == 0.0 { 1.0 } else { v[2] },
            aperture_diameter: v[3],
            abbe: v[4],
        };
        if surface.thickness < 0.0 {
            return Err(format!(
                "line {number}: the thickness must not be negative, got {}",
                surface.thickness
            ));
        }
        if !(surface.eta >= 1.0 && surface.eta < 4.0) {
            return Err(format!(
                "line {number}: the index of refraction must be 0 (air) or between 1 and 4, got {}",
                v[2]
            ));
        }
        if surface.aperture_diameter <= 0.0 {
            return Err(format!(
                "line {number}: the aperture diameter must be positive, got {}",
                surface.aperture_diameter
            ));
        }
        if surface.abbe < 0.0 || (surface.abbe > 0.0 && surface.abbe < 5.0) {
            return Err(format!(
                "line {number}: the Abbe number must be 0 (none) or at least 5, got {}",
                surface.abbe
            ));
        }
        if surface.curvature_radius != 0.0
            && surface.curvature_radius.abs() < surface.aperture_diameter / 2.0
        {
            return Err(format!(
                "line {number}: a surface of radius {} cannot have an aperture of diameter {}",
                surface.curvature_radius, surface.aperture_diameter
            ));
        }
        if surface.is_stop() {
            if let Some(first) = stop_line {
                return Err(format!(
                    "line {number}: a second aperture stop (radius 0); the first is on line {first}"
                ));
            }
            if surface.eta != 1.0 {
                return Err(format!(
                    "line {number}: the aperture stop must sit in air (eta 0 or 1), got {}",
                    v[2]
                ));
            }
            stop_line = Some(number);
        }
        surfaces.push(surface);
        lines.push(number);
    }
    // Neighbouring surfaces must not cross inside the smaller of their apertures.
    let sag = |s: &LensSurface, r: f64| {
        let c = s.curvature_radius;
        if c == 0.0 {
            0.0
        } else {
            c - c.signum() * (c * c - r * r).max(0.0).sqrt()
        }
    };
    for i in 1..surfaces.len() {
        let (a, b) = (&surfaces[i - 1], &surfaces[i]);
        let r_max = 0.5 * a.aperture_diameter.min(b.aperture_diameter);
        for k in 0..=32 {
            let r = r_max * k as f64 / 32.0;
            if sag(a, r) > a.thickness + sag(b, r) + 1e-9 {
                return Err(format!(
                    "lines {} and {}: the surfaces cross {r:.3} mm off the axis, inside their apertures (the gap between them is too thin)",
                    lines[i - 1],
                    lines[i]
                ));
            }
        }
    }
    if surfaces.iter().all(|s| s.is_stop()) {
        return Err("the lens has no glass surface".into());
    }
    if surfaces.last().is_some_and(|s| s.eta != 1.0) {
        return Err("the last surface must be followed by air (eta 0 or 1)".into());
    }
    Ok(surfaces)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_the_documented_example() {
        let text = "# radius thickness eta aperture [abbe]\n\
                    30.81 6.0 1.5168 20 64.17 # front\n\
                    -22.39 2.5 1.62 20 36.37\n\
                    \n\
                    -408.0 3.0 1 20\n\
                    0 44.0 0 16\n";
        let s = parse_lens(text).unwrap();
        assert_eq!(s.len(), 4);
        assert_eq!(s[0].curvature_radius, 30.81);
        assert_eq!(s[0].abbe, 64.17);
        assert_eq!(s[2].abbe, 0.0);
        assert_eq!(s[2].eta, 1.0);
        assert!(s[3].is_stop() && s[3].eta == 1.0 && s[3].aperture_diameter == 16.0);
    }

    #[test]
    fn errors_name_the_line() {
        for (text, want) in [
            (
                "10 2 1.5 5\n-10 2 1 5\nx 1 1 1\n",
                "line 3: `x` is not a finite number",
            ),
            (
                "10 2 1.5\n",
                "line 1: expected `radius thickness eta aperture [abbe]`",
            ),
            (
                "10 -2 1.5 5\n",
                "line 1: the thickness must not be negative",
            ),
            ("10 2 0.5 5\n-10 2 1 5\n", "line 1: the index of refraction"),
            (
                "10 2 1.5 0\n",
                "line 1: the aperture diameter must be positive",
            ),
            ("3 2 1.5 10\n", "line 1: a surface of radius 3 cannot have"),
            (
                "0 1 0 5\n10 2 1.5 5\n-10 1 1 5\n0 1 0 4\n",
                "line 4: a second aperture stop",
            ),
            (
                "0 1 1.5 5\n10 2 1.5 5\n-10 1 1 5\n",
                "line 1: the aperture stop must sit in air",
            ),
            ("10 2 1.5 5 2\n-10 1 1 5\n", "line 1: the Abbe number"),
            ("10 2 1.5 5 NaN\n", "line 1: `NaN` is not a finite number"),
            ("0 1 0 5\n", "no glass surface"),
            ("10 2 1.5 5\n", "followed by air"),
            (
                "10 0.5 1.5 8\n-10 5 1 8\n",
                "lines 1 and 2: the surfaces cross",
            ),
        ] {
            let e = parse_lens(text).unwrap_err();
            assert!(e.contains(want), "{text:?}: {e}");
        }
    }

    #[test]
    fn load_names_the_file() {
        let e = load_lens(Path::new("/nonexistent/lens.dat")).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/lens.dat"), "{e}");
    }
}
