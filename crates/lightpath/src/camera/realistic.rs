//! The realistic camera: a lens system from a prescription file, traced surface by
//! surface in double precision, with the aberrations, distortion, vignetting and cos⁴
//! falloff of the real lens, chromatic aberration from each glass's dispersion, and lens
//! flare: the ghosts that light makes by reflecting twice inside the lens.
//!
//! ```xml
//! <camera type="realistic">
//!     <integer name="width" value="640"/>
//!     <integer name="height" value="426"/>
//!     <string name="lensFile" value="lenses/double-doublet.50mm.dat"/>
//!     <float name="apertureDiameter" value="12"/>  <!-- mm; stops the lens down -->
//!     <float name="focusDistance" value="3"/>       <!-- from the film, scene units (m) -->
//!     <float name="filmDiagonal" value="35"/>       <!-- mm -->
//!     <boolean name="dispersion" value="true"/>     <!-- chromatic aberration -->
//!     <boolean name="flare" value="true"/>          <!-- ghosts -->
//!     <string name="flareSampling" value="light"/>  <!-- or "camera" -->
//!     <boolean name="coated" value="true"/>         <!-- MgF2 anti-reflection coating -->
//!     <integer name="blades" value="6"/>            <!-- a polygonal stop -->
//!     <transform><lookat origin="0,1,-4" target="0,1,0"/></transform>
//! </camera>
//! ```
//!
//! The lens file lists the surfaces from front to rear in millimetres, in pbrt's format
//! with an optional Abbe number per glass ([`crate::io::lens`]). Scene units are metres
//! (as in pbrt): the lens is 1000 times smaller than its millimetres, and the camera's
//! position is the film's centre, with the lens in front of it along the view axis.
//!
//! - **Focus.** The film moves (the last surface's thickness changes) until an axial
//!   point at `focusDistance` from the film images onto it: first in paraxial rays, then,
//!   within 5% of that, where the rays through the whole aperture make the smallest RMS
//!   spot (spherical aberration moves a real lens' sharpest focus off the paraxial one).
//! - **Rays.** A film point sends its ray toward a point of the lens' exit pupil, bounded
//!   per film radius as pbrt does (64 rings, a 128² grid of trial rays each, widened by two
//!   grid cells), and the ray is traced through every surface; a ray that misses a
//!   surface's clear aperture or the stop is blocked (the sample is black).
//! - **Exposure.** A sample's weight is the irradiance estimate cos⁴θ · A / d² (θ the
//!   ray's angle to the axis at the film, A the area the pupil point was drawn from, d the
//!   film's distance from the rear surface), divided by its mean at the film's centre:
//!   the centre of a uniform white scene renders white at any aperture, as a pinhole
//!   camera does, and the corners show the lens's falloff.
//! - **Dispersion.** Each glass's index follows a Cauchy fit n(λ) = A + B/λ² through its
//!   n_d and V_d. Each sample takes a wavelength drawn in proportion to the summed
//!   response of three smooth sensor curves (blue 450 nm, green 545 nm, red 605 nm) and
//!   weights the RGB radiance it finds by 3·s(λ)/(s_r + s_g + s_b)(λ), whose mean is
//!   (1, 1, 1): a lens without dispersion renders exactly as in RGB, one with it spreads
//!   each colour's image as the glass does.
//! - **Flare.** With `flare`, each surface reflects part of the light by the Fresnel
//!   equations (for an unpolarised ray; with `coated`, through a quarter-wave MgF2 layer
//!   for 550 nm on every air-glass surface, which tints the ghosts) and transmits the
//!   rest. The image is the sum of the direct image (with the lens' transmission loss)
//!   and every two-reflection ghost; paths of four and more reflections are left out. A
//!   ghost reflects at two glass surfaces, a pair chosen in proportion to their
//!   reflectances at normal incidence (every pair at least a tenth of the mean share),
//!   and is found one of two ways (`flareSampling`):
//!   - `light` (the default): camera rays take the direct path only, and the renderer
//!     traces light paths ([`Realistic::ghost_splat`], driven by `render::flare`): a
//!     point on a disk of the front vertex plane, a light sampled from it, the ghost path
//!     backwards through the lens to the film, splatted into the pixel it lands in.
//!     The lens conserves étendue, so the camera rays' measure cos⁴θ·dA_rear/d²·dA_film
//!     is cos θ·dω·dA_front on the scene side, and the weight is the camera estimate's
//!     turned around. Nearly free of noise; ghosts of lit surfaces are left out.
//!   - `camera`: a camera sample follows, with probability 1/4, a ghost path drawn over
//!     the whole rear surface, weighted by its throughput over its probability. It
//!     finds every ghost, but rare paths make them converge slowly.

use super::{normalized_film, CameraSample};
use crate::error::{Error, Result};
use crate::io::lens::LensSurface;
use crate::math::{Ray, Transform};
use glam::{DVec2, DVec3, UVec2, Vec2, Vec3};
use rayon::prelude::*;
use std::f64::consts::PI;

/// The wavelength of the d line (nm), at which lens files give their indices.
pub const LAMBDA_D: f64 = 587.56;
const LAMBDA_F: f64 = 486.13;
const LAMBDA_C: f64 = 656.27;
/// The probability that a sample follows a ghost path (with `flare`).
const GHOST_PROBABILITY: f64 = 0.25;
/// Exit pupil rings over the film's half-diagonal, and trial rays per ring side.
const PUPIL_RINGS: usize = 64;
const PUPIL_GRID: usize = 128;
/// The anti-reflection coating: MgF2, a quarter wave thick at 550 nm.
const COATING_ETA: f64 = 1.38;
const COATING_DESIGN_NM: f64 = 550.0;
/// The sensor's wavelength range (nm) and its curves (centre, standard deviation).
const SENSOR_MIN_NM: f64 = 380.0;
const SENSOR_BINS: usize = 340;
const SENSOR_CURVES: [(f64, f64); 3] = [(605.0, 30.0), (545.0, 28.0), (450.0, 22.0)];

/// What a scene sets on a realistic camera besides its lens file.
#[derive(Debug, Clone, PartialEq)]
pub struct RealisticOptions {
    /// Diameter of the stop (mm); `None`: the lens file's.
    pub aperture_diameter: Option<f64>,
    /// Distance of the plane in focus from the film (scene units, metres).
    pub focus_distance: f64,
    /// Diagonal of the film (mm).
    pub film_diagonal: f64,
    /// Whether glasses with an Abbe number disperse light.
    pub dispersion: bool,
    /// Whether ghost paths (two reflections inside the lens) are traced.
    pub flare: bool,
    /// Whether air-glass surfaces carry an anti-reflection coating.
    pub coated: bool,
    /// A polygonal stop: blade count and rotation (radians).
    pub blades: Option<(u32, f64)>,
    /// How ghost paths are sampled (with `flare`).
    pub flare_sampling: FlareSampling,
}

/// Where a realistic camera's ghost paths start (see the module notes).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FlareSampling {
    /// From the lights, through the lens to the film ([`Realistic::ghost_splat`]): the
    /// ghosts of every emitter (also outside the frame), without noise to speak of;
    /// ghosts of lit surfaces are left out.
    #[default]
    Light,
    /// From the film, by camera rays: the ghosts of everything in front of the lens, lit
    /// surfaces too, but noisy where a small light makes them.
    Camera,
}

impl FlareSampling {
    /// The sampling a scene names (`light` or `camera`).
    pub fn from_name(name: &str) -> Option<FlareSampling> {
        match name {
            "light" => Some(FlareSampling::Light),
            "camera" => Some(FlareSampling::Camera),
            _ => None,
        }
    }
}

impl Default for RealisticOptions {
    fn default() -> Self {
        RealisticOptions {
            aperture_diameter: None,
            focus_distance: 10.0,
            film_diagonal: 35.0,
            dispersion: true,
            flare: false,
            coated: true,
            blades: None,
            flare_sampling: FlareSampling::Light,
        }
    }
}

/// A medium's index of refraction, n(λ) = a + b/λ² (λ in micrometres).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Medium {
    a: f64,
    b: f64,
}

impl Medium {
    const AIR: Medium = Medium { a: 1.0, b: 0.0 };

    fn new(eta_d: f64, abbe: f64, dispersion: bool) -> Medium {
        if !dispersion || abbe <= 0.0 || eta_d == 1.0 {
            return Medium { a: eta_d, b: 0.0 };
        }
        let um = |nm: f64| nm * 1e-3;
        let inv2 = |nm: f64| 1.0 / (um(nm) * um(nm));
        // n_F - n_C = (n_d - 1) / V_d.
        let b = (eta_d - 1.0) / abbe / (inv2(LAMBDA_F) - inv2(LAMBDA_C));
        Medium {
            a: eta_d - b * inv2(LAMBDA_D),
            b,
        }
    }

    #[inline]
    fn eta(&self, lambda_nm: f64) -> f64 {
        let um = lambda_nm * 1e-3;
        self.a + self.b / (um * um)
    }

    fn is_air(&self) -> bool {
        self.a == 1.0 && self.b == 0.0
    }
}

/// A surface placed in lens space: the film at z = 0, the scene toward -z (mm).
#[derive(Debug, Clone, Copy)]
struct Interface {
    /// Radius of curvature (its centre at `z + radius`); 0 for the stop.
    radius: f64,
    /// The vertex's position on the axis.
    z: f64,
    /// Radius of the clear aperture.
    aperture: f64,
    /// The media on the scene side and the film side.
    front: Medium,
    back: Medium,
}

impl Interface {
    fn is_stop(&self) -> bool {
        self.radius == 0.0
    }
}

/// A ray in lens space (mm), with a unit direction.
#[derive(Debug, Clone, Copy)]
struct LensRay {
    o: DVec3,
    d: DVec3,
}

/// The sensor's three spectral curves, tabulated per nanometre, and the distribution of
/// wavelengths in proportion to their sum.
#[derive(Debug, Clone)]
struct Sensor {
    /// Per bin: 3·s_c / Σs (the RGB weight of a wavelength in the bin).
    weights: Vec<Vec3>,
    /// Cumulative distribution over the bins (last entry 1).
    cdf: Vec<f64>,
}

impl Sensor {
    fn new() -> Sensor {
        let curve = |c: usize, nm: f64| {
            let (mu, sigma) = SENSOR_CURVES[c];
            (-0.5 * ((nm - mu) / sigma).powi(2)).exp()
        };
        let centre = |k: usize| SENSOR_MIN_NM + k as f64 + 0.5;
        // Each curve normalised to integrate to 1 over the bins.
        let totals: Vec<f64> = (0..3)
            .map(|c| (0..SENSOR_BINS).map(|k| curve(c, centre(k))).sum())
            .collect();
        let s = |c: usize, k: usize| curve(c, centre(k)) / totals[c];
        let mut weights = Vec::with_capacity(SENSOR_BINS);
        let mut cdf = Vec::with_capacity(SENSOR_BINS);
        let mut acc = 0.0;
        for k in 0..SENSOR_BINS {
            let sum = s(0, k) + s(1, k) + s(2, k);
            weights.push(Vec3::new(
                (3.0 * s(0, k) / sum) as f32,
                (3.0 * s(1, k) / sum) as f32,
                (3.0 * s(2, k) / sum) as f32,
            ));
            // The density of a wavelength is Σs / 3 (each s integrates to 1).
            acc += sum / 3.0;
            cdf.push(acc);
        }
        let last = acc;
        for c in &mut cdf {
            *c /= last;
        }
        Sensor { weights, cdf }
    }

    /// A wavelength (nm) and its RGB weight for a uniform `u`.
    #[inline]
    fn sample(&self, u: f64) -> (f64, Vec3) {
        let k = self.cdf.partition_point(|&c| c <= u).min(SENSOR_BINS - 1);
        let lo = if k == 0 { 0.0 } else { self.cdf[k - 1] };
        let frac = ((u - lo) / (self.cdf[k] - lo)).clamp(0.0, 1.0 - 1e-9);
        (SENSOR_MIN_NM + k as f64 + frac, self.weights[k])
    }
}

/// Which path a sample takes through the lens.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum LensPath {
    /// Through every surface.
    Direct,
    /// Reflected at surface `front`, then at surface `rear` (`front < rear`), both
    /// counted from the front of the lens.
    Ghost { front: usize, rear: usize },
}

/// A camera with a real lens (see the module notes).
#[derive(Debug, Clone)]
pub struct Realistic {
    pub resolution: UVec2,
    pub render_from_camera: Transform,
    interfaces: Vec<Interface>,
    /// Half-extents of the film (mm).
    film_half: DVec2,
    /// Per film ring: the exit pupil's bounds on the rear vertex plane, for film points
    /// on the +x axis (x0, y0, x1, y1); empty rings are fully vignetted.
    pupil: Vec<[f64; 4]>,
    /// Radius of the disk on the rear vertex plane that ghost rays are drawn from.
    ghost_disk: f64,
    /// Radius of the disk on the front vertex plane that light-traced ghosts enter by.
    front_disk: f64,
    flare_sampling: FlareSampling,
    /// 1 / the mean irradiance weight at the film's centre.
    exposure: f64,
    /// Whether samples draw a wavelength (dispersion, or a coating that depends on it).
    spectral: bool,
    flare: bool,
    coated: bool,
    ghosts: Vec<(usize, usize)>,
    /// The probability of each ghost among the ghosts, and their running sum.
    ghost_probability: Vec<f64>,
    ghost_cdf: Vec<f64>,
    blades: Option<(u32, f64)>,
    sensor: Sensor,
}

impl Realistic {
    /// The camera for a lens prescription (front to rear, mm) and options. Errors say
    /// what cannot be built (a stop too wide, a lens that cannot focus there, no light
    /// through the lens).
    pub fn new(
        resolution: UVec2,
        render_from_camera: Transform,
        surfaces: &[LensSurface],
        options: &RealisticOptions,
    ) -> Result<Realistic> {
        let invalid = |m: String| Error::Invalid(m);
        if !(options.film_diagonal > 0.0 && options.film_diagonal.is_finite()) {
            return Err(invalid(format!(
                "filmDiagonal must be a positive number of millimetres, got {}",
                options.film_diagonal
            )));
        }
        if !positive(options.focus_distance) {
            return Err(invalid(format!(
                "focusDistance must be positive, got {}",
                options.focus_distance
            )));
        }
        if surfaces.is_empty() {
            return Err(invalid("the lens has no surfaces".into()));
        }
        let mut surfaces = surfaces.to_vec();
        if let Some(diameter) = options.aperture_diameter {
            let stop = surfaces.iter_mut().find(|s| s.is_stop()).ok_or_else(|| {
                invalid(
                    "apertureDiameter needs a lens with an aperture stop (a surface of radius 0)"
                        .into(),
                )
            })?;
            if !positive(diameter) || diameter > stop.aperture_diameter {
                return Err(invalid(format!(
                    "apertureDiameter must be between 0 and the lens' stop of {} mm, got {diameter}",
                    stop.aperture_diameter
                )));
            }
            stop.aperture_diameter = diameter;
        }
        if let Some((n, _)) = options.blades {
            if !(3..=64).contains(&n) {
                return Err(invalid(format!(
                    "the stop's `blades` must be between 3 and 64, got {n}"
                )));
            }
        }
        let dispersive = options.dispersion && surfaces.iter().any(|s| s.abbe > 0.0);
        let diag = (resolution.x as f64).hypot(resolution.y as f64);
        let half = 0.5 * options.film_diagonal / diag;
        let mut cam = Realistic {
            resolution,
            render_from_camera,
            // Placed by `focus`, then again at the film distance it finds.
            interfaces: Vec::new(),
            film_half: DVec2::new(half * resolution.x as f64, half * resolution.y as f64),
            pupil: Vec::new(),
            ghost_disk: 0.0,
            front_disk: 0.0,
            flare_sampling: options.flare_sampling,
            exposure: 1.0,
            spectral: dispersive || (options.flare && options.coated),
            flare: options.flare,
            coated: options.coated,
            ghosts: Vec::new(),
            ghost_probability: Vec::new(),
            ghost_cdf: Vec::new(),
            blades: options.blades,
            sensor: Sensor::new(),
        };
        let paraxial = cam.focus(&surfaces, options.focus_distance * 1000.0)?;
        let film_distance =
            cam.sharpest_focus(&surfaces, options.focus_distance * 1000.0, paraxial);
        cam.interfaces = layout(&surfaces, film_distance, options.dispersion);
        let glass: Vec<usize> = (0..cam.interfaces.len())
            .filter(|&i| !cam.interfaces[i].is_stop())
            .collect();
        if options.flare {
            for (k, &a) in glass.iter().enumerate() {
                for &b in &glass[k + 1..] {
                    cam.ghosts.push((a, b));
                }
            }
            // Ghosts are chosen in proportion to their two surfaces' reflectance at
            // normal incidence (550 nm), with a floor of a tenth of the mean so that
            // every ghost is sampled: a cemented surface's ghosts are ~100x fainter.
            let normal_r = |i: usize| {
                let s = &cam.interfaces[i];
                let coated = cam.coated && (s.front.is_air() != s.back.is_air());
                let (a, b) = (
                    s.front.eta(COATING_DESIGN_NM),
                    s.back.eta(COATING_DESIGN_NM),
                );
                reflectance(1.0, a, b, COATING_DESIGN_NM, coated)
            };
            let w: Vec<f64> = cam
                .ghosts
                .iter()
                .map(|&(a, b)| normal_r(a) * normal_r(b))
                .collect();
            let floor = 0.1 * w.iter().sum::<f64>() / w.len().max(1) as f64;
            let w: Vec<f64> = w.iter().map(|x| x.max(floor)).collect();
            let total: f64 = w.iter().sum();
            let mut acc = 0.0;
            for x in &w {
                cam.ghost_probability.push(x / total);
                acc += x / total;
                cam.ghost_cdf.push(acc);
            }
            if let Some(last) = cam.ghost_cdf.last_mut() {
                *last = 1.0;
            }
        }
        cam.ghost_disk = cam.rear_sampling_radius();
        cam.front_disk = cam.front_sampling_radius();
        cam.pupil = cam.exit_pupil_bounds(dispersive);
        let e0 = cam.centre_irradiance();
        if !positive(e0) {
            return Err(invalid(
                "no light passes through the lens at the film's centre (is the stop closed?)"
                    .into(),
            ));
        }
        cam.exposure = 1.0 / e0;
        Ok(cam)
    }

    /// Whether samples need [`Realistic::sample_ray`]'s `u_path` (a wavelength, or a
    /// choice of ghost path).
    pub fn uses_path_sample(&self) -> bool {
        self.spectral || (self.flare && self.flare_sampling == FlareSampling::Camera)
    }

    /// Whether the ghosts come from light tracing ([`Realistic::ghost_splat`]): a
    /// renderer then adds them to the image, and camera rays take the direct path only.
    pub fn traces_ghosts_from_lights(&self) -> bool {
        !self.ghosts.is_empty() && self.flare_sampling == FlareSampling::Light
    }

    /// The distance from the film to the rear surface's vertex (mm).
    pub fn film_distance(&self) -> f64 {
        -self.interfaces.last().unwrap().z
    }

    /// The effective focal length (mm) at `lambda_nm`: the height of a paraxial ray
    /// parallel to the axis over the slope it leaves the lens with.
    pub fn effective_focal_length(&self, lambda_nm: f64) -> Option<f64> {
        let h = self.paraxial_height();
        let front = self.interfaces[0].z;
        let mut ray = LensRay {
            o: DVec3::new(h, 0.0, front - 1.0),
            d: DVec3::Z,
        };
        self.trace_from_scene(&mut ray, lambda_nm)?;
        if ray.d.x == 0.0 {
            return None;
        }
        Some(-h * ray.d.z / ray.d.x)
    }

    /// The radius of the entrance pupil (mm): the highest ray parallel to the axis, at
    /// 587.6 nm, that passes the whole lens (bisection).
    pub fn entrance_pupil_radius(&self) -> f64 {
        let front = self.interfaces[0];
        let passes = |h: f64| {
            let mut ray = LensRay {
                o: DVec3::new(h, 0.0, front.z - 1.0),
                d: DVec3::Z,
            };
            self.trace_from_scene(&mut ray, LAMBDA_D).is_some()
        };
        let (mut lo, mut hi) = (0.0, front.aperture);
        if passes(hi) {
            return hi;
        }
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if passes(mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo
    }

    /// A line for reports: focal length, f-number, the film's distance behind the rear
    /// surface, and the lens' effects that are on.
    pub fn describe(&self) -> String {
        let f = self.effective_focal_length(LAMBDA_D).unwrap_or(f64::NAN);
        let mut s = format!(
            "f = {f:.1} mm, f/{:.1}, film {:.2} mm behind the lens",
            f / (2.0 * self.entrance_pupil_radius()),
            self.film_distance()
        );
        if self.spectral {
            s += ", spectral";
        }
        if self.flare {
            s += &format!(", flare ({} ghosts)", self.ghosts.len());
        }
        s
    }

    /// Where on the axis (z, mm; the film is at 0) a paraxial ray from an axial point at
    /// `object_z` (or parallel to the axis for `None`) crosses it behind the lens.
    fn axial_image(&self, object_z: Option<f64>, lambda_nm: f64) -> Option<f64> {
        let h = self.paraxial_height();
        let front = self.interfaces[0].z;
        let mut ray = match object_z {
            None => LensRay {
                o: DVec3::new(h, 0.0, front - 1.0),
                d: DVec3::Z,
            },
            Some(z) => {
                let o = DVec3::new(0.0, 0.0, z);
                LensRay {
                    o,
                    d: (DVec3::new(h, 0.0, front) - o).normalize(),
                }
            }
        };
        self.trace_from_scene(&mut ray, lambda_nm)?;
        if ray.d.x == 0.0 || ray.d.z <= 0.0 {
            return None;
        }
        let t = -ray.o.x / ray.d.x;
        Some(ray.o.z + t * ray.d.z)
    }

    fn paraxial_height(&self) -> f64 {
        let min_aperture = self
            .interfaces
            .iter()
            .map(|s| s.aperture)
            .fold(f64::INFINITY, f64::min);
        1e-4 * min_aperture
    }

    /// The film distance that focuses an axial point `distance` mm from the film
    /// (paraxially, at the d line), by the secant method on the image's offset.
    fn focus(&mut self, surfaces: &[LensSurface], distance: f64) -> Result<f64> {
        let fail = || {
            Error::Invalid(format!(
                "the lens cannot focus at {} (from the film): no real image forms behind it",
                distance / 1000.0
            ))
        };
        let length: f64 = surfaces[..surfaces.len() - 1]
            .iter()
            .map(|s| s.thickness)
            .sum();
        let offset = |cam: &mut Realistic, film: f64| -> Option<f64> {
            cam.interfaces = layout(surfaces, film, false);
            if distance <= film + length {
                return None; // the object would be inside the lens
            }
            cam.axial_image(Some(-distance), LAMBDA_D)
        };
        // Start from the focus at infinity.
        self.interfaces = layout(surfaces, surfaces.last().unwrap().thickness, false);
        let at_infinity = self.axial_image(None, LAMBDA_D).ok_or_else(fail)?;
        let mut f0 = surfaces.last().unwrap().thickness + at_infinity;
        if !positive(f0) {
            return Err(fail());
        }
        let mut g0 = offset(self, f0).ok_or_else(fail)?;
        let mut f1 = f0 + g0;
        for _ in 0..100 {
            if !positive(f1) {
                return Err(fail());
            }
            let g1 = offset(self, f1).ok_or_else(fail)?;
            if g1.abs() < 1e-9 * f1.max(1.0) {
                return Ok(f1);
            }
            let slope = (g1 - g0) / (f1 - f0);
            let next = if slope.is_finite() && slope != 0.0 {
                f1 - g1 / slope
            } else {
                f1 + g1
            };
            (f0, g0, f1) = (f1, g1, next);
        }
        Err(fail())
    }

    /// The film distance within 5% of the paraxial one where the rays from an axial
    /// point `distance` mm from the film through the whole aperture (a grid over the front
    /// surface, at the d line) make the smallest RMS spot on the film: the focus a
    /// photographer sets by eye, which a lens' spherical aberration moves away from the
    /// paraxial focus. Golden-section search.
    fn sharpest_focus(&mut self, surfaces: &[LensSurface], distance: f64, paraxial: f64) -> f64 {
        let spot = |cam: &mut Realistic, film: f64| -> f64 {
            cam.interfaces = layout(surfaces, film, false);
            let front = cam.interfaces[0];
            let object = DVec3::new(0.0, 0.0, -distance);
            if object.z >= front.z {
                return f64::INFINITY;
            }
            let n = 48;
            let (mut sum, mut count) = (0.0, 0);
            for k in 0..n * n {
                let x = front.aperture * (2.0 * ((k % n) as f64 + 0.5) / n as f64 - 1.0);
                let y = front.aperture * (2.0 * ((k / n) as f64 + 0.5) / n as f64 - 1.0);
                if x * x + y * y > front.aperture * front.aperture {
                    continue;
                }
                let mut ray = LensRay {
                    o: object,
                    d: (DVec3::new(x, y, front.z) - object).normalize(),
                };
                if cam.trace_from_scene(&mut ray, LAMBDA_D).is_some() && ray.d.z > 0.0 {
                    let q = ray.o + ray.d * (-ray.o.z / ray.d.z);
                    sum += q.x * q.x + q.y * q.y;
                    count += 1;
                }
            }
            if count == 0 {
                f64::INFINITY
            } else {
                sum / count as f64
            }
        };
        let ratio = 0.5 * (5f64.sqrt() - 1.0);
        let (mut a, mut b) = (0.95 * paraxial, 1.05 * paraxial);
        let mut c = b - ratio * (b - a);
        let mut d = a + ratio * (b - a);
        let (mut fc, mut fd) = (spot(self, c), spot(self, d));
        for _ in 0..60 {
            if fc < fd {
                (b, d, fd) = (d, c, fc);
                c = b - ratio * (b - a);
                fc = spot(self, c);
            } else {
                (a, c, fc) = (c, d, fd);
                d = a + ratio * (b - a);
                fd = spot(self, d);
            }
        }
        let best = 0.5 * (a + b);
        if spot(self, best) < spot(self, paraxial) {
            best
        } else {
            paraxial
        }
    }

    /// Radius of the disk on the rear vertex plane that holds every ray able to enter
    /// the rear surface's clear aperture from the film (the surface's sag lets a slanted
    /// ray cross the plane outside the aperture).
    fn rear_sampling_radius(&self) -> f64 {
        let rear = self.interfaces.last().unwrap();
        let sag = self.sag(self.interfaces.len() - 1);
        let d = -rear.z;
        let slope = (self.film_half.length() + rear.aperture + sag) / d.max(1e-9);
        rear.aperture + sag * slope.max(1.0) + 1e-6
    }

    /// Radius of the disk on the front vertex plane that holds every ray able to enter
    /// the front surface's clear aperture at up to 72° from the axis (tan 72° ≈ 3).
    fn front_sampling_radius(&self) -> f64 {
        self.interfaces[0].aperture + 3.0 * self.sag(0) + 1e-6
    }

    /// How far surface `i` bulges from its vertex plane at the rim of its aperture (0
    /// for the stop).
    fn sag(&self, i: usize) -> f64 {
        let s = &self.interfaces[i];
        if s.is_stop() {
            return 0.0;
        }
        let r = s.radius.abs();
        r - (r * r - s.aperture * s.aperture).max(0.0).sqrt()
    }

    /// The ghost for a uniform `v`, drawn in proportion to the ghost probabilities.
    #[inline]
    fn pick_ghost(&self, v: f64) -> usize {
        self.ghost_cdf
            .partition_point(|&c| c <= v)
            .min(self.ghosts.len() - 1)
    }

    /// A point of the disk on the front vertex plane through which light-traced ghosts
    /// enter the lens, uniform in area for uniform `u`: in lens space (mm, for
    /// [`Realistic::ghost_splat`]) and in camera space (metres).
    pub fn front_point(&self, u: Vec2) -> (DVec3, Vec3) {
        let q = crate::sampling::warp::square_to_uniform_disk_concentric(u).as_dvec2()
            * self.front_disk;
        let p = DVec3::new(q.x, q.y, self.interfaces[0].z);
        (p, (DVec3::new(p.x, p.y, -p.z) * 1e-3).as_vec3())
    }

    /// Light arriving at the front point `x` (lens space, from [`Realistic::front_point`])
    /// along the camera-space direction `travel`, carried along a ghost path (two
    /// reflections, the pair drawn with `u_ghost` in proportion to the camera's ghost
    /// probabilities) at a wavelength drawn with `u_lambda` to the film. Returns the
    /// raster position where it lands and the weight by which the incident radiance
    /// (over its solid-angle density at `x`) estimates that pixel's value,
    /// `exposure · T · cos θ · A_front / (P(ghost) · A_pixel)` times the wavelength's RGB
    /// weight; a renderer averages these splats over all the paths it traces. It is the
    /// camera-ray estimate turned around: the lens conserves étendue, so the film-side
    /// measure cos⁴θ·dA_rear/d²·dA_film of a camera ray equals cos θ·dω·dA_front on the
    /// scene side.
    pub fn ghost_splat(
        &self,
        x: DVec3,
        travel: Vec3,
        u_ghost: f32,
        u_lambda: f32,
    ) -> Option<(Vec2, Vec3)> {
        if self.ghosts.is_empty() {
            return None;
        }
        let d = DVec3::new(travel.x as f64, travel.y as f64, -travel.z as f64).normalize();
        // Toward the film (+z in lens space).
        if d.z.is_nan() || d.z <= 0.0 {
            return None;
        }
        let (lambda, rgb) = if self.spectral {
            self.sensor.sample(u_lambda as f64)
        } else {
            (LAMBDA_D, Vec3::ONE)
        };
        let k = self.pick_ghost(u_ghost as f64);
        let (front, rear) = self.ghosts[k];
        // Start well in front of the front surface's cap.
        let back = (self.front_disk + 1.0) / d.z;
        let mut ray = LensRay { o: x - d * back, d };
        let n = self.interfaces.len();
        let mut t = 1.0;
        for i in 0..rear {
            t *= self.cross(i, &mut ray, false, lambda)?;
        }
        t *= self.cross(rear, &mut ray, true, lambda)?;
        for i in (front + 1..rear).rev() {
            t *= self.cross(i, &mut ray, false, lambda)?;
        }
        t *= self.cross(front, &mut ray, true, lambda)?;
        for i in front + 1..n {
            t *= self.cross(i, &mut ray, false, lambda)?;
        }
        if ray.d.z.is_nan() || ray.d.z <= 0.0 {
            return None;
        }
        let f = ray.o + ray.d * (-ray.o.z / ray.d.z);
        let nf = DVec2::new(-f.x / self.film_half.x, -f.y / self.film_half.y);
        if !(nf.x.abs() < 1.0 && nf.y.abs() < 1.0) {
            return None;
        }
        let raster = (nf + DVec2::ONE) * 0.5 * self.resolution.as_dvec2();
        let pixel_area = 4.0 * self.film_half.x * self.film_half.y
            / (self.resolution.x as f64 * self.resolution.y as f64);
        let front_area = PI * self.front_disk * self.front_disk;
        let w = self.exposure * t * d.z * front_area / (self.ghost_probability[k] * pixel_area);
        if !(w > 0.0 && w.is_finite()) {
            return None;
        }
        Some((raster.as_vec2(), rgb * w as f32))
    }

    /// The exit pupil's bounds per film ring (see the module notes); with dispersion,
    /// the trial rays cycle through three wavelengths.
    fn exit_pupil_bounds(&self, dispersive: bool) -> Vec<[f64; 4]> {
        let r_max = self.film_half.length();
        let extent = self
            .ghost_disk
            .max(1.5 * self.interfaces.last().unwrap().aperture);
        let cell = 2.0 * extent / PUPIL_GRID as f64;
        let rear_z = self.interfaces.last().unwrap().z;
        let lambdas = if dispersive {
            [LAMBDA_D, 400.0, 700.0]
        } else {
            [LAMBDA_D; 3]
        };
        (0..PUPIL_RINGS)
            .into_par_iter()
            .map(|ring| {
                let r0 = r_max * ring as f64 / PUPIL_RINGS as f64;
                let r1 = r_max * (ring + 1) as f64 / PUPIL_RINGS as f64;
                let mut b = [f64::INFINITY, f64::INFINITY, -f64::INFINITY, -f64::INFINITY];
                for k in 0..PUPIL_GRID * PUPIL_GRID {
                    let (i, j) = (k % PUPIL_GRID, k / PUPIL_GRID);
                    let x = -extent + (i as f64 + 0.5) * cell;
                    let y = -extent + (j as f64 + 0.5) * cell;
                    // Film radii spread over the ring (van der Corput in base 2).
                    let r = r0 + (r1 - r0) * radical_inverse(k as u32);
                    let film = DVec3::new(r, 0.0, 0.0);
                    let mut ray = LensRay {
                        o: film,
                        d: (DVec3::new(x, y, rear_z) - film).normalize(),
                    };
                    if self
                        .trace_from_film(&mut ray, LensPath::Direct, lambdas[k % 3])
                        .is_some()
                    {
                        b = [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)];
                    }
                }
                if b[0] > b[2] {
                    return b; // nothing passes: an empty ring
                }
                let m = 2.0 * cell;
                [b[0] - m, b[1] - m, b[2] + m, b[3] + m]
            })
            .collect()
    }

    /// The mean irradiance weight of the direct path at the film's centre (at 550 nm),
    /// over a stratified grid of the centre ring's pupil.
    fn centre_irradiance(&self) -> f64 {
        let b = self.pupil[0];
        if b[0] > b[2] {
            return 0.0;
        }
        let n = 128;
        let mut sum = 0.0;
        for k in 0..n * n {
            let u = DVec2::new(
                ((k % n) as f64 + 0.5) / n as f64,
                ((k / n) as f64 + 0.5) / n as f64,
            );
            if let Some(w) = self.direct_weight(DVec3::ZERO, u, COATING_DESIGN_NM) {
                sum += w;
            }
        }
        sum / (n * n) as f64
    }

    /// The unnormalised weight of the direct path from `film` through the pupil point
    /// of `u` at one wavelength: cos⁴θ·A/d² times the lens' transmission (with flare).
    fn direct_weight(&self, film: DVec3, u: DVec2, lambda: f64) -> Option<f64> {
        let (p, area) = self.sample_pupil(film, u)?;
        let d = (p - film).normalize();
        let mut ray = LensRay { o: film, d };
        let t = self.trace_from_film(&mut ray, LensPath::Direct, lambda)?;
        Some(self.irradiance(d, area) * t)
    }

    #[inline]
    fn irradiance(&self, d: DVec3, area: f64) -> f64 {
        let rear_z = self.interfaces.last().unwrap().z;
        let cos2 = d.z * d.z;
        cos2 * cos2 * area / (rear_z * rear_z)
    }

    /// A point of the exit pupil for the film point `film` (on the rear vertex plane)
    /// and the area it was drawn from; `None` if no light reaches that film ring.
    #[inline]
    fn sample_pupil(&self, film: DVec3, u: DVec2) -> Option<(DVec3, f64)> {
        let r = film.x.hypot(film.y);
        let r_max = self.film_half.length();
        let ring = ((r / r_max * PUPIL_RINGS as f64) as usize).min(PUPIL_RINGS - 1);
        let b = self.pupil[ring];
        if b[0] > b[2] {
            return None;
        }
        let x = b[0] + u.x * (b[2] - b[0]);
        let y = b[1] + u.y * (b[3] - b[1]);
        // The bounds are for film points on +x: rotate to this one's angle.
        let (c, s) = if r > 0.0 {
            (film.x / r, film.y / r)
        } else {
            (1.0, 0.0)
        };
        let p = DVec3::new(
            c * x - s * y,
            s * x + c * y,
            self.interfaces.last().unwrap().z,
        );
        Some((p, (b[2] - b[0]) * (b[3] - b[1])))
    }

    /// The ray of a film sample, in render space, and its RGB weight (see the module
    /// notes); `None` where the lens blocks it. `u_path` draws the wavelength (x) and the
    /// path through the lens (y) where [`Realistic::uses_path_sample`].
    pub fn sample_ray(&self, sample: &CameraSample, u_path: Vec2) -> Option<(Ray, Vec3)> {
        let nf = normalized_film(sample.film, self.resolution).as_dvec2();
        // A lens inverts the image: the film point mirrors the pixel's position.
        let film = DVec3::new(-nf.x * self.film_half.x, -nf.y * self.film_half.y, 0.0);
        let (lambda, rgb) = if self.spectral {
            self.sensor.sample(u_path.x as f64)
        } else {
            (LAMBDA_D, Vec3::ONE)
        };
        let u = sample.lens.as_dvec2();
        let (path, probability) = self.choose_path(u_path.y as f64);
        let (p, area) = match path {
            LensPath::Direct => self.sample_pupil(film, u)?,
            LensPath::Ghost { .. } => {
                let q = crate::sampling::warp::square_to_uniform_disk_concentric(sample.lens)
                    .as_dvec2()
                    * self.ghost_disk;
                let z = self.interfaces.last().unwrap().z;
                (
                    DVec3::new(q.x, q.y, z),
                    PI * self.ghost_disk * self.ghost_disk,
                )
            }
        };
        let d = (p - film).normalize();
        let mut ray = LensRay { o: film, d };
        let throughput = self.trace_from_film(&mut ray, path, lambda)?;
        let w = self.irradiance(d, area) * throughput / probability * self.exposure;
        if !(w > 0.0 && w.is_finite()) {
            return None;
        }
        // Lens space to camera space: the scene lies toward +z; millimetres to metres.
        let o = DVec3::new(ray.o.x, ray.o.y, -ray.o.z) * 1e-3;
        let dir = DVec3::new(ray.d.x, ray.d.y, -ray.d.z);
        let to = &self.render_from_camera;
        let out = Ray::new(to.point(o.as_vec3()), to.vector(dir.as_vec3()).normalize());
        Some((out, rgb * w as f32))
    }

    /// The path of a sample for a uniform `u`, and the probability of choosing it.
    #[inline]
    fn choose_path(&self, u: f64) -> (LensPath, f64) {
        if self.ghosts.is_empty() || self.flare_sampling == FlareSampling::Light {
            return (LensPath::Direct, 1.0);
        }
        if u >= GHOST_PROBABILITY {
            return (LensPath::Direct, 1.0 - GHOST_PROBABILITY);
        }
        let k = self.pick_ghost(u / GHOST_PROBABILITY);
        let (front, rear) = self.ghosts[k];
        (
            LensPath::Ghost { front, rear },
            GHOST_PROBABILITY * self.ghost_probability[k],
        )
    }

    /// Traces a ray from the film out of the front of the lens along `path`; returns
    /// its throughput (1 without flare; the Fresnel factors with it), `None` if blocked.
    fn trace_from_film(&self, ray: &mut LensRay, path: LensPath, lambda: f64) -> Option<f64> {
        let n = self.interfaces.len();
        let mut t = 1.0;
        match path {
            LensPath::Direct => {
                for i in (0..n).rev() {
                    t *= self.cross(i, ray, false, lambda)?;
                }
            }
            LensPath::Ghost { front, rear } => {
                for i in (front + 1..n).rev() {
                    t *= self.cross(i, ray, false, lambda)?;
                }
                t *= self.cross(front, ray, true, lambda)?;
                for i in front + 1..rear {
                    t *= self.cross(i, ray, false, lambda)?;
                }
                t *= self.cross(rear, ray, true, lambda)?;
                for i in (0..rear).rev() {
                    t *= self.cross(i, ray, false, lambda)?;
                }
            }
        }
        Some(t)
    }

    /// Traces a ray from the scene side through every surface toward the film.
    fn trace_from_scene(&self, ray: &mut LensRay, lambda: f64) -> Option<f64> {
        let mut t = 1.0;
        for i in 0..self.interfaces.len() {
            t *= self.cross(i, ray, false, lambda)?;
        }
        Some(t)
    }

    /// Moves `ray` through (or, with `reflect`, off) surface `i`: its factor (Fresnel
    /// transmittance or reflectance with flare, else 1), or `None` where the ray misses
    /// the surface, its aperture or the stop, or is totally reflected.
    #[inline]
    fn cross(&self, i: usize, ray: &mut LensRay, reflect: bool, lambda: f64) -> Option<f64> {
        let s = &self.interfaces[i];
        if s.is_stop() {
            if ray.d.z == 0.0 {
                return None;
            }
            let t = (s.z - ray.o.z) / ray.d.z;
            if !positive(t) {
                return None;
            }
            let p = ray.o + ray.d * t;
            if !self.inside_stop(p, s.aperture) {
                return None;
            }
            ray.o = p;
            return Some(1.0);
        }
        let centre = DVec3::new(0.0, 0.0, s.z + s.radius);
        // From far away (an object point in focusing), step up to two radii short of
        // the vertex plane first: b² - c below would cancel catastrophically.
        let to_plane = (s.z - ray.o.z) / ray.d.z;
        let skip = to_plane - 2.0 * s.radius.abs() / ray.d.z.abs();
        if skip > 0.0 && skip.is_finite() {
            ray.o += ray.d * skip;
        }
        let oc = ray.o - centre;
        let b = oc.dot(ray.d);
        let c = oc.length_squared() - s.radius * s.radius;
        let disc = b * b - c;
        if disc < 0.0 {
            return None;
        }
        let root = disc.sqrt();
        // The cap around the vertex: the nearer root for a ray meeting the sphere from
        // the side its centre is not on.
        let closer = (ray.d.z > 0.0) ^ (s.radius < 0.0);
        let t = if closer { -b - root } else { -b + root };
        if !positive(t - 1e-9) {
            return None;
        }
        let p = ray.o + ray.d * t;
        if p.x * p.x + p.y * p.y > s.aperture * s.aperture {
            return None;
        }
        let mut n = (p - centre) / s.radius.abs();
        if n.dot(ray.d) > 0.0 {
            n = -n;
        }
        let (eta_i, eta_t) = if ray.d.z > 0.0 {
            (s.front.eta(lambda), s.back.eta(lambda))
        } else {
            (s.back.eta(lambda), s.front.eta(lambda))
        };
        let cos_i = -n.dot(ray.d);
        let coated = self.coated && (s.front.is_air() != s.back.is_air());
        let r = if self.flare {
            reflectance(cos_i, eta_i, eta_t, lambda, coated)
        } else {
            0.0
        };
        ray.o = p;
        if reflect {
            ray.d = (ray.d + 2.0 * cos_i * n).normalize();
            return Some(r);
        }
        let eta = eta_i / eta_t;
        let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
        if sin2_t >= 1.0 {
            return None;
        }
        let cos_t = (1.0 - sin2_t).sqrt();
        ray.d = (eta * ray.d + (eta * cos_i - cos_t) * n).normalize();
        Some(1.0 - r)
    }

    /// Whether a point on the stop's plane passes its opening (a disk, or a regular
    /// polygon with that circumradius).
    #[inline]
    fn inside_stop(&self, p: DVec3, radius: f64) -> bool {
        let r2 = p.x * p.x + p.y * p.y;
        match self.blades {
            None => r2 <= radius * radius,
            Some((n, rotation)) => {
                let sector = 2.0 * PI / n as f64;
                let a = (p.y.atan2(p.x) - rotation).rem_euclid(2.0 * PI);
                let mid = rotation + ((a / sector).floor() + 0.5) * sector;
                p.x * mid.cos() + p.y * mid.sin() <= radius * (PI / n as f64).cos()
            }
        }
    }
}

/// Places the surfaces in lens space with the film `film_distance` behind the last.
fn layout(surfaces: &[LensSurface], film_distance: f64, dispersion: bool) -> Vec<Interface> {
    let n = surfaces.len();
    let mut out = Vec::with_capacity(n);
    let mut z = -film_distance;
    for i in (0..n).rev() {
        let s = &surfaces[i];
        if i + 1 < n {
            z -= s.thickness;
        }
        let back = Medium::new(s.eta, s.abbe, dispersion);
        let front = if i == 0 {
            Medium::AIR
        } else {
            Medium::new(surfaces[i - 1].eta, surfaces[i - 1].abbe, dispersion)
        };
        out.push(Interface {
            radius: s.curvature_radius,
            z,
            aperture: 0.5 * s.aperture_diameter,
            front,
            back,
        });
    }
    out.reverse();
    out
}

/// The reflectance of an unpolarised ray meeting a surface between indices `eta_i`
/// (its side) and `eta_t` at `cos_i`: the Fresnel equations, or with `coated` those of
/// a quarter-wave MgF2 layer for 550 nm between the two (thin-film interference).
pub(crate) fn reflectance(cos_i: f64, eta_i: f64, eta_t: f64, lambda_nm: f64, coated: bool) -> f64 {
    let sin2_i = (1.0 - cos_i * cos_i).max(0.0);
    let cos_after = |eta: f64| {
        let s2 = (eta_i / eta).powi(2) * sin2_i;
        (s2 < 1.0).then(|| (1.0 - s2).sqrt())
    };
    let rs = |n1: f64, c1: f64, n2: f64, c2: f64| (n1 * c1 - n2 * c2) / (n1 * c1 + n2 * c2);
    let rp = |n1: f64, c1: f64, n2: f64, c2: f64| (n2 * c1 - n1 * c2) / (n2 * c1 + n1 * c2);
    let Some(cos_t) = cos_after(eta_t) else {
        return 1.0;
    };
    if !coated {
        let s = rs(eta_i, cos_i, eta_t, cos_t);
        let p = rp(eta_i, cos_i, eta_t, cos_t);
        return 0.5 * (s * s + p * p);
    }
    let Some(cos_c) = cos_after(COATING_ETA) else {
        return 1.0;
    };
    let thickness = COATING_DESIGN_NM / (4.0 * COATING_ETA);
    let delta = 4.0 * PI * COATING_ETA * thickness * cos_c / lambda_nm;
    let film = |r12: f64, r23: f64| {
        let x = 2.0 * r12 * r23 * delta.cos();
        (r12 * r12 + r23 * r23 + x) / (1.0 + r12 * r12 * r23 * r23 + x)
    };
    let s = film(
        rs(eta_i, cos_i, COATING_ETA, cos_c),
        rs(COATING_ETA, cos_c, eta_t, cos_t),
    );
    let p = film(
        rp(eta_i, cos_i, COATING_ETA, cos_c),
        rp(COATING_ETA, cos_c, eta_t, cos_t),
    );
    0.5 * (s + p)
}

/// Whether `x` is above zero (false for NaN).
#[inline]
fn positive(x: f64) -> bool {
    x > 0.0
}

/// The base-2 radical inverse of `k` in [0, 1).
fn radical_inverse(k: u32) -> f64 {
    k.reverse_bits() as f64 / 4294967296.0
}

#[cfg(test)]
mod tests;
