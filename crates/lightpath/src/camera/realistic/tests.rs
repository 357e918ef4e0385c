use super::*;
use crate::io::lens::parse_lens;
use crate::sampling::Pcg32;

/// A biconvex BK7 singlet behind a front stop (f ≈ 49.2 mm).
const SINGLET: &str = "0 2 0 10\n50 5 1.5168 20 64.17\n-50 47 1 20\n";
/// A cemented achromat (BK7 crown, F2 flint) behind a front stop, designed for 50 mm.
const DOUBLET: &str = "0 3 0 16\n30 6 1.5168 20 64.17\n-17.854 2.5 1.62 20 36.37\n-72.46 45 1 20\n";
/// Two f = 100 mm achromats mirrored about the stop.
const DOUBLE_DOUBLET: &str = "166.67 5 1.5168 24 64.17\n-25.863 2.5 1.62 24 36.37\n-56.936 4 1 24\n\
                              0 4 0 16\n56.936 2.5 1.62 24 36.37\n25.863 5 1.5168 24 64.17\n-166.67 45 1 24\n";

fn camera(text: &str, res: UVec2, options: &RealisticOptions) -> Realistic {
    let surfaces = parse_lens(text).unwrap();
    Realistic::new(res, Transform::IDENTITY, &surfaces, options).unwrap()
}

fn sample(film: Vec2, lens: Vec2) -> CameraSample {
    CameraSample { film, lens }
}

/// The thick-lens focal length of a single lens in air.
fn lensmaker(n: f64, r1: f64, r2: f64, t: f64) -> f64 {
    1.0 / ((n - 1.0) * (1.0 / r1 - 1.0 / r2 + (n - 1.0) * t / (n * r1 * r2)))
}

#[test]
fn singlet_focal_length_and_dispersion_follow_the_lensmaker_equation() {
    let cam = camera(SINGLET, UVec2::new(64, 64), &RealisticOptions::default());
    let glass = Medium::new(1.5168, 64.17, true);
    // The Cauchy fit passes through n_d and spreads n_F - n_C = (n_d - 1) / V_d.
    assert!((glass.eta(LAMBDA_D) - 1.5168).abs() < 1e-12);
    let spread = glass.eta(LAMBDA_F) - glass.eta(LAMBDA_C);
    assert!((spread - 0.5168 / 64.17).abs() < 1e-12, "{spread}");
    for lambda in [LAMBDA_F, LAMBDA_D, LAMBDA_C, 420.0] {
        let want = lensmaker(glass.eta(lambda), 50.0, -50.0, 5.0);
        let got = cam.effective_focal_length(lambda).unwrap();
        assert!(
            (got - want).abs() < 1e-5 * want,
            "{lambda} nm: {got} vs {want}"
        );
    }
    // Blue focuses shorter than red by about f / V_d.
    let df = cam.effective_focal_length(LAMBDA_C).unwrap()
        - cam.effective_focal_length(LAMBDA_F).unwrap();
    assert!((df - 49.2 / 64.17).abs() < 0.03, "{df}");
    // Without dispersion every wavelength focuses alike.
    let flat = camera(
        SINGLET,
        UVec2::new(64, 64),
        &RealisticOptions {
            dispersion: false,
            ..Default::default()
        },
    );
    assert_eq!(
        flat.effective_focal_length(LAMBDA_F),
        flat.effective_focal_length(LAMBDA_C)
    );
}

#[test]
fn the_f_number_follows_the_stop() {
    // The singlet's stop is its first surface: the entrance pupil is the stop itself.
    for (diameter, want) in [(None, 5.0), (Some(4.0), 2.0)] {
        let cam = camera(
            SINGLET,
            UVec2::new(8, 8),
            &RealisticOptions {
                aperture_diameter: diameter,
                ..Default::default()
            },
        );
        assert!((cam.entrance_pupil_radius() - want).abs() < 1e-9);
    }
    // Behind the double doublet's front group the stop looks larger (the front achromat
    // magnifies it): the pupil is wider than the 16 mm stop, f/3.1.
    let cam = camera(
        DOUBLE_DOUBLET,
        UVec2::new(8, 8),
        &RealisticOptions::default(),
    );
    let r = cam.entrance_pupil_radius();
    assert!(r > 8.0 && r < 12.0, "{r}");
    let d = cam.describe();
    assert!(d.starts_with("f = 52.9 mm, f/3.1"), "{d}");
}

#[test]
fn an_achromat_brings_blue_and_red_together() {
    let singlet = camera(SINGLET, UVec2::new(64, 64), &RealisticOptions::default());
    let doublet = camera(DOUBLET, UVec2::new(64, 64), &RealisticOptions::default());
    let spread = |c: &Realistic| {
        let f = |l| c.effective_focal_length(l).unwrap();
        (f(LAMBDA_C) - f(LAMBDA_F)) / f(LAMBDA_D)
    };
    let f = doublet.effective_focal_length(LAMBDA_D).unwrap();
    assert!((f - 50.0).abs() < 3.0, "{f}");
    assert!(spread(&doublet).abs() < 0.1 * spread(&singlet).abs());
}

/// Where a camera-space ray meets the plane z = `z`.
fn at_plane(ray: &Ray, z: f32) -> Vec2 {
    let t = (z - ray.origin.z) / ray.direction.z;
    let p = ray.at(t);
    Vec2::new(p.x, p.y)
}

#[test]
fn rays_of_a_film_point_meet_on_the_plane_in_focus() {
    for focus in [0.7f32, 3.0] {
        let res = UVec2::new(100, 100);
        let cam = camera(
            DOUBLE_DOUBLET,
            res,
            &RealisticOptions {
                focus_distance: focus as f64,
                aperture_diameter: Some(2.0),
                dispersion: false,
                ..Default::default()
            },
        );
        let mut rng = Pcg32::new(5, 6);
        for film in [Vec2::new(50.0, 50.0), Vec2::new(54.0, 47.0)] {
            // The RMS spread of the bundle on planes at, before and beyond the focus.
            let spread = |z: f32, rng: &mut Pcg32| {
                let pts: Vec<Vec2> = (0..200)
                    .filter_map(|_| {
                        let u = Vec2::new(rng.next_f32(), rng.next_f32());
                        cam.sample_ray(&sample(film, u), Vec2::splat(0.5))
                    })
                    .map(|(r, _)| at_plane(&r, z))
                    .collect();
                assert!(pts.len() > 50);
                let mean = pts.iter().copied().sum::<Vec2>() / pts.len() as f32;
                let ms = pts
                    .iter()
                    .map(|p| (*p - mean).length_squared())
                    .sum::<f32>();
                (ms / pts.len() as f32).sqrt()
            };
            let at = spread(focus, &mut rng);
            let near = spread(0.8 * focus, &mut rng);
            let far = spread(1.25 * focus, &mut rng);
            if film == Vec2::splat(50.0) {
                assert!(
                    at < 0.1 * near && at < 0.1 * far,
                    "{focus}: {at} {near} {far}"
                );
                let closer = spread(0.97 * focus, &mut rng);
                let farther = spread(1.03 * focus, &mut rng);
                assert!(
                    at < closer && at < farther,
                    "{focus}: {at} {closer} {farther}"
                );
            } else {
                // Off the axis the lens' field curvature and astigmatism blur a little.
                assert!(
                    at < 0.3 * near && at < 0.3 * far,
                    "{focus}: {at} {near} {far}"
                );
            }
        }
    }
}

#[test]
fn the_image_is_upright_with_the_lens_field_of_view() {
    let res = UVec2::new(120, 80);
    let cam = camera(
        DOUBLE_DOUBLET,
        res,
        &RealisticOptions {
            focus_distance: 1e6,
            aperture_diameter: Some(2.0),
            dispersion: false,
            ..Default::default()
        },
    );
    let f = cam.effective_focal_length(LAMBDA_D).unwrap();
    let mean_direction = |film: Vec2| {
        let mut d = Vec3::ZERO;
        for k in 0..64 {
            let u = Vec2::new((k % 8) as f32 + 0.5, (k / 8) as f32 + 0.5) / 8.0;
            if let Some((r, _)) = cam.sample_ray(&sample(film, u), Vec2::splat(0.5)) {
                d += r.direction;
            }
        }
        d.normalize()
    };
    let centre = mean_direction(Vec2::new(60.0, 40.0));
    assert!(centre.z > 0.9999, "{centre}");
    // Right edge: +x; bottom edge: +y (camera space looks along +z, y down).
    let right = mean_direction(Vec2::new(120.0, 40.0));
    let bottom = mean_direction(Vec2::new(60.0, 80.0));
    assert!(right.x > 0.0 && right.y.abs() < 1e-3, "{right}");
    assert!(bottom.y > 0.0 && bottom.x.abs() < 1e-3, "{bottom}");
    // The angle of the field's edge: atan(half film width / f), up to distortion.
    let want = (cam.film_half.x / f).atan();
    let got = (right.x as f64).atan2(right.z as f64);
    assert!((got - want).abs() < 0.01 * want, "{got} vs {want}");
    // The film's half-width: 35 mm diagonal over a 3:2 frame.
    assert!((cam.film_half.x - 17.5 * 120.0 / 120f64.hypot(80.0)).abs() < 1e-9);
}

#[test]
fn the_centre_is_exposed_at_one_and_the_corners_fall_off() {
    let res = UVec2::new(60, 40);
    for text in [SINGLET, DOUBLET, DOUBLE_DOUBLET] {
        let cam = camera(text, res, &RealisticOptions::default());
        assert!(cam.uses_path_sample(), "the glasses disperse");
        let mean = |film: Vec2| {
            let mut rng = Pcg32::new(7, 8);
            let n = 40_000;
            let mut sum = DVec3::ZERO;
            for k in 0..n {
                let u = Vec2::new(rng.next_f32(), rng.next_f32());
                // Wavelengths stratified: the spectral weights alone are noisy.
                let up = Vec2::new((k as f32 + rng.next_f32()) / n as f32, rng.next_f32());
                if let Some((_, w)) = cam.sample_ray(&sample(film, u), up) {
                    sum += w.as_dvec3();
                }
            }
            sum / n as f64
        };
        let centre = mean(Vec2::new(30.0, 20.0));
        // Every colour alike: the exit pupil's solid angle hardly changes with the
        // wavelength, even through the singlet.
        for c in 0..3 {
            assert!((centre[c] - 1.0).abs() < 0.01, "{text}: {centre}");
        }
        let corner = mean(Vec2::new(0.5, 0.5));
        assert!(corner.x < centre.x && corner.y < centre.y, "{corner}");
        assert!(corner.y > 0.2, "{corner}");
    }
}

#[test]
fn sensor_weights_average_to_white() {
    let s = Sensor::new();
    let mut mean = DVec3::ZERO;
    let mut prev = 0.0;
    for (k, w) in s.weights.iter().enumerate() {
        mean += w.as_dvec3() * (s.cdf[k] - prev);
        prev = s.cdf[k];
    }
    assert!((mean - DVec3::ONE).abs().max_element() < 1e-5, "{mean}");
    // Sampled: wavelengths in range, the weights' mean white.
    let mut rng = Pcg32::new(1, 1);
    let mut m = DVec3::ZERO;
    let n = 200_000;
    for _ in 0..n {
        let (l, w) = s.sample(rng.next_f32() as f64);
        assert!((SENSOR_MIN_NM..SENSOR_MIN_NM + SENSOR_BINS as f64).contains(&l));
        m += w.as_dvec3();
    }
    assert!(
        (m / n as f64 - DVec3::ONE).abs().max_element() < 0.01,
        "{m}"
    );
    // Blue wavelengths weigh blue, red ones red.
    assert!(s.sample(0.02).1.z > 2.5 && s.sample(0.98).1.x > 2.5);
}

#[test]
fn reflectance_of_bare_and_coated_glass() {
    let n = 1.52f64;
    let bare = ((n - 1.0) / (n + 1.0)).powi(2);
    assert!((reflectance(1.0, 1.0, n, 550.0, false) - bare).abs() < 1e-12);
    // A quarter-wave layer at its design wavelength: ((n - n_c²) / (n + n_c²))².
    let c2 = COATING_ETA * COATING_ETA;
    let quarter = ((n - c2) / (n + c2)).powi(2);
    assert!((reflectance(1.0, 1.0, n, 550.0, true) - quarter).abs() < 1e-12);
    // Away from it the coating reflects more, and at grazing angles everything reflects.
    assert!(reflectance(1.0, 1.0, n, 420.0, true) > quarter * 1.3);
    assert!(reflectance(1e-4, 1.0, n, 550.0, true) > 0.99);
    // Reciprocal: the same from either side at refracted angles; total internal
    // reflection inside the glass.
    for coated in [false, true] {
        for cos_i in [0.95f64, 0.7, 0.4, 0.15] {
            let sin_t = (1.0 - cos_i * cos_i).sqrt() / n;
            let cos_t = (1.0 - sin_t * sin_t).sqrt();
            let a = reflectance(cos_i, 1.0, n, 500.0, coated);
            let b = reflectance(cos_t, n, 1.0, 500.0, coated);
            assert!((a - b).abs() < 1e-12, "{coated} {cos_i}: {a} {b}");
        }
        assert_eq!(reflectance(0.5, n, 1.0, 500.0, coated), 1.0);
    }
}

#[test]
fn a_polygonal_stop_has_flat_sides() {
    let cam = camera(
        DOUBLET,
        UVec2::new(8, 8),
        &RealisticOptions {
            blades: Some((6, 0.0)),
            ..Default::default()
        },
    );
    let r = 4.0;
    let corner = DVec3::new(r * 0.999, 0.0, 0.0);
    let mid = 30f64.to_radians();
    let apothem = r * mid.cos();
    assert!(cam.inside_stop(corner, r));
    assert!(cam.inside_stop(DVec3::new(mid.cos(), mid.sin(), 0.0) * apothem * 0.999, r));
    assert!(!cam.inside_stop(DVec3::new(mid.cos(), mid.sin(), 0.0) * apothem * 1.001, r));
    assert!(!cam.inside_stop(DVec3::new(r * 1.001, 0.0, 0.0), r));
}

/// The camera's estimate of the irradiance at a film point, E[weight · L(direction)],
/// for the direct path and for the ghosts, against a quadrature of the same integral
/// over the whole rear disk that ignores the pupil bounds and the path probabilities.
#[test]
fn flare_weights_estimate_the_sum_over_paths() {
    let res = UVec2::new(40, 40);
    let cam = camera(
        DOUBLE_DOUBLET,
        res,
        &RealisticOptions {
            flare: true,
            coated: false,
            dispersion: false,
            focus_distance: 5.0,
            flare_sampling: FlareSampling::Camera,
            ..Default::default()
        },
    );
    assert!(!cam.spectral && cam.ghosts.len() == 15);
    let radiance = |d: Vec3| 1.0 + 0.8 * d.x as f64 - 0.5 * d.y as f64;
    for film_px in [Vec2::new(20.0, 20.0), Vec2::new(31.0, 12.0)] {
        let nf = normalized_film(film_px, res).as_dvec2();
        let film = DVec3::new(-nf.x * cam.film_half.x, -nf.y * cam.film_half.y, 0.0);
        // Quadrature over a fine grid of the rear disk, per path.
        let g = 400;
        let rho = cam.ghost_disk;
        let cell = (2.0 * rho / g as f64).powi(2);
        let z = cam.interfaces.last().unwrap().z;
        let mut want_direct = 0.0;
        let mut want_ghost = 0.0;
        for k in 0..g * g {
            let x = -rho + ((k % g) as f64 + 0.5) * 2.0 * rho / g as f64;
            let y = -rho + ((k / g) as f64 + 0.5) * 2.0 * rho / g as f64;
            if x * x + y * y > rho * rho {
                continue;
            }
            let d = (DVec3::new(x, y, z) - film).normalize();
            let paths = std::iter::once(LensPath::Direct).chain(
                cam.ghosts
                    .iter()
                    .map(|&(front, rear)| LensPath::Ghost { front, rear }),
            );
            for path in paths {
                let mut ray = LensRay { o: film, d };
                if let Some(t) = cam.trace_from_film(&mut ray, path, LAMBDA_D) {
                    let out = Vec3::new(ray.d.x as f32, ray.d.y as f32, -ray.d.z as f32);
                    let v = cam.irradiance(d, cell) * t * cam.exposure * radiance(out);
                    if path == LensPath::Direct {
                        want_direct += v;
                    } else {
                        want_ghost += v;
                    }
                }
            }
        }
        assert!(want_ghost > 0.0 && want_ghost < 0.1 * want_direct);
        // The camera's estimate, split by the path the sample chose.
        let mut rng = Pcg32::new(11, 12);
        let n = 400_000;
        let (mut direct, mut ghost) = (Vec::new(), Vec::new());
        for _ in 0..n {
            let u = Vec2::new(rng.next_f32(), rng.next_f32());
            let up = Vec2::new(0.5, rng.next_f32());
            let v = cam
                .sample_ray(&sample(film_px, u), up)
                .map(|(r, w)| w.y as f64 * radiance(r.direction))
                .unwrap_or(0.0);
            let is_ghost = (up.y as f64) < GHOST_PROBABILITY;
            direct.push(if is_ghost { 0.0 } else { v });
            ghost.push(if is_ghost { v } else { 0.0 });
        }
        for (name, values, want) in [
            ("direct", &direct, want_direct),
            ("ghosts", &ghost, want_ghost),
        ] {
            let mean = values.iter().sum::<f64>() / n as f64;
            let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64;
            let err = (var / n as f64).sqrt();
            assert!(
                (mean - want).abs() < 4.0 * err + 2e-3 * want,
                "{name} at {film_px}: {mean} ± {err} vs {want}"
            );
        }
    }
}

#[test]
fn impossible_lenses_are_refused() {
    let surfaces = parse_lens(DOUBLET).unwrap();
    let res = UVec2::new(8, 8);
    let err = |o: RealisticOptions| {
        Realistic::new(res, Transform::IDENTITY, &surfaces, &o)
            .unwrap_err()
            .to_string()
    };
    let e = err(RealisticOptions {
        aperture_diameter: Some(20.0),
        ..Default::default()
    });
    assert!(e.contains("the lens' stop of 16 mm"), "{e}");
    let e = err(RealisticOptions {
        focus_distance: 0.04,
        ..Default::default()
    });
    assert!(e.contains("cannot focus at 0.04"), "{e}");
    let e = err(RealisticOptions {
        blades: Some((2, 0.0)),
        ..Default::default()
    });
    assert!(e.contains("blades"), "{e}");
    let e = err(RealisticOptions {
        film_diagonal: 0.0,
        ..Default::default()
    });
    assert!(e.contains("filmDiagonal"), "{e}");
    let no_stop = parse_lens("50 5 1.5168 20\n-50 47 1 20\n").unwrap();
    let e = Realistic::new(
        res,
        Transform::IDENTITY,
        &no_stop,
        &RealisticOptions {
            aperture_diameter: Some(5.0),
            ..Default::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("aperture stop"), "{e}");
}
