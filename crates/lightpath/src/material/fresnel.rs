//! Fresnel reflectance: the exact unpolarized dielectric and conductor equations,
//! Schlick's approximation, the hemispherical (diffuse) Fresnel reflectance, and a small
//! table of metals' complex indices of refraction in RGB.

use glam::Vec3;

/// Exact unpolarized Fresnel reflectance of a dielectric interface, with the cosine of
/// the incident direction and the relative index `eta` = η(far side)/η(near side) for a
/// direction on the +normal side. A negative `cos_i` means the direction is on the other
/// side, and `eta` is inverted. Returns (F, |cos θt|); total internal reflection gives
/// (1, 0).
#[inline]
pub fn fresnel_dielectric_cos(cos_i: f32, eta: f32) -> (f32, f32) {
    let (cos_i, eta) = if cos_i < 0.0 {
        (-cos_i, 1.0 / eta)
    } else {
        (cos_i, eta)
    };
    let cos_i = cos_i.min(1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return (1.0, 0.0);
    }
    let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
    let rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    (0.5 * (rs * rs + rp * rp), cos_t)
}

/// [`fresnel_dielectric_cos`] without the refracted cosine.
#[inline]
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    fresnel_dielectric_cos(cos_i, eta).0
}

/// Exact unpolarized Fresnel reflectance of a conductor with complex relative index
/// `eta + i k` (per channel), for |cos θi| = `cos_i` (the formula of pbrt-v3's
/// `FrConductor`, written with a² + b² = |η² − k² − sin²θ + 2iηk|).
pub fn fresnel_conductor(cos_i: f32, eta: Vec3, k: Vec3) -> Vec3 {
    let c = cos_i.abs().min(1.0);
    let cos2 = Vec3::splat(c * c);
    let sin2 = Vec3::ONE - cos2;
    let eta2 = eta * eta;
    let k2 = k * k;
    let t0 = eta2 - k2 - sin2;
    let a2b2 = (t0 * t0 + 4.0 * eta2 * k2).max(Vec3::ZERO);
    let a2b2 = Vec3::new(a2b2.x.sqrt(), a2b2.y.sqrt(), a2b2.z.sqrt());
    let t1 = a2b2 + cos2;
    let a = (0.5 * (a2b2 + t0)).max(Vec3::ZERO);
    let a = Vec3::new(a.x.sqrt(), a.y.sqrt(), a.z.sqrt());
    let t2 = 2.0 * c * a;
    let rs = (t1 - t2) / (t1 + t2);
    let t3 = cos2 * a2b2 + sin2 * sin2;
    let t4 = t2 * sin2;
    let rp = rs * (t3 - t4) / (t3 + t4);
    0.5 * (rp + rs)
}

/// Schlick's approximation F0 + (1 − F0)(1 − cos)⁵.
#[inline]
pub fn schlick(f0: f32, cos: f32) -> f32 {
    let m = (1.0 - cos.abs()).clamp(0.0, 1.0);
    let m2 = m * m;
    f0 + (1.0 - f0) * m2 * m2 * m
}

/// The cosine-weighted hemispherical average of the dielectric Fresnel reflectance,
/// ∫ F(μ, eta) 2μ dμ over μ ∈ [0, 1], by the midpoint rule in μ² (exact to ~1e-7; the
/// polynomial fits in the literature are good to ~1e-3 only). `eta` is the relative index
/// seen from the side the light arrives from: eta < 1 is the inside of a denser medium.
pub fn fresnel_diffuse_reflectance(eta: f32) -> f32 {
    let eta = eta as f64;
    let n = 20_000;
    let mut sum = 0.0f64;
    for i in 0..n {
        // x = μ², dx = 2μ dμ.
        let x = (i as f64 + 0.5) / n as f64;
        let cos_i = x.sqrt();
        let sin2_t = (1.0 - x) / (eta * eta);
        let f = if sin2_t >= 1.0 {
            1.0
        } else {
            let cos_t = (1.0 - sin2_t).sqrt();
            let rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
            let rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
            0.5 * (rs * rs + rp * rp)
        };
        sum += f;
    }
    (sum / n as f64) as f32
}

/// Complex indices of refraction (η, k) of metals in RGB: the spectra of Mitsuba 0.6's
/// `data/ior` tables (luxpop.com / Palik), box-averaged over 600–700 nm (R), 500–600 nm
/// (G) and 400–500 nm (B) with linear interpolation between the tabulated wavelengths
/// (computed for this table; the normal-incidence reflectance of the averaged (η, k) is
/// within 0.015 of the band-averaged spectral reflectance for every entry).
pub const METALS: &[(&str, [f32; 3], [f32; 3])] = &[
    ("Ag", [0.1363, 0.1251, 0.1501], [4.1272, 3.3367, 2.4620]),
    ("Al", [1.4869, 0.9672, 0.6217], [7.7954, 6.6799, 5.4706]),
    ("Au", [0.1761, 0.4119, 1.4178], [3.3022, 2.5953, 1.8808]),
    ("Cr", [3.6370, 3.0849, 1.9749], [4.3648, 4.4196, 4.1225]),
    ("Cu", [0.2427, 0.8756, 1.1624], [3.6046, 2.6449, 2.3807]),
    ("Ni", [2.0208, 1.7733, 1.6357], [3.8043, 3.2506, 2.6546]),
    ("W", [3.6965, 3.4902, 3.3348], [2.9130, 2.7559, 2.5299]),
];

/// The (η, k) of a named metal of [`METALS`].
pub fn metal(name: &str) -> Option<(Vec3, Vec3)> {
    METALS
        .iter()
        .find(|(n, _, _)| *n == name)
        .map(|(_, eta, k)| (Vec3::from_array(*eta), Vec3::from_array(*k)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dielectric_fresnel_known_values_and_tir() {
        // Normal incidence: ((η − 1)/(η + 1))², from either side.
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
        assert!((fresnel_dielectric(-1.0, 1.5) - 0.04).abs() < 1e-6);
        // Brewster's angle: rp = 0, so F = rs²/2.
        let tb = 1.5f32.atan();
        let f = fresnel_dielectric(tb.cos(), 1.5);
        let (ci, ct) = (tb.cos(), (1.0 - tb.sin().powi(2) / 2.25).sqrt());
        let rs = (ci - 1.5 * ct) / (ci + 1.5 * ct);
        assert!((f - 0.5 * rs * rs).abs() < 1e-6);
        // Total internal reflection inside glass beyond asin(1/1.5) ≈ 41.8°.
        assert_eq!(
            fresnel_dielectric_cos(-(50f32.to_radians().cos()), 1.5),
            (1.0, 0.0)
        );
        assert!(fresnel_dielectric(-(30f32.to_radians().cos()), 1.5) < 1.0);
        // Index-matched: nothing reflects.
        assert!(fresnel_dielectric(0.3, 1.0) < 1e-12);
    }

    #[test]
    fn conductor_fresnel_matches_dielectric_and_complex_reference() {
        // k = 0 is a dielectric.
        for c in [0.05f32, 0.3, 0.7, 1.0] {
            let f = fresnel_conductor(c, Vec3::splat(1.7), Vec3::ZERO);
            assert!((f.x - fresnel_dielectric(c, 1.7)).abs() < 1e-5, "{c}");
        }
        // Against the complex-amplitude formula evaluated in double precision
        // (rs = (c − n cosθt)/(c + n cosθt), rp = (n c − cosθt)/(n c + cosθt), n = η + ik).
        let cases = [
            (1.0, [0.1761, 3.3022], 0.9426745),
            (0.5, [0.1761, 3.3022], 0.9374573),
            (0.1, [1.4869, 7.7954], 0.8393702),
            (0.3, [3.6370, 4.3648], 0.575_435),
        ];
        for (c, [eta, k], expected) in cases {
            let f = fresnel_conductor(c, Vec3::splat(eta), Vec3::splat(k)).x;
            assert!((f - expected).abs() < 1e-4, "cos {c}: {f} vs {expected}");
        }
        // Grazing incidence reflects everything.
        assert!((fresnel_conductor(0.0, Vec3::splat(0.2), Vec3::splat(3.0)).x - 1.0).abs() < 1e-6);
    }

    #[test]
    fn diffuse_fresnel_reflectance_obeys_the_eta_squared_law() {
        // The cosine-weighted transmittance from inside is the outside one over η².
        for eta in [1.2f32, 1.5, 2.0] {
            let ext = fresnel_diffuse_reflectance(eta);
            let int = fresnel_diffuse_reflectance(1.0 / eta);
            assert!(
                ((1.0 - int) - (1.0 - ext) / (eta * eta)).abs() < 2e-5,
                "{eta}"
            );
        }
        // Known value for η = 1.5 (external): about 0.092.
        assert!((fresnel_diffuse_reflectance(1.5) - 0.0918).abs() < 1e-3);
        assert!(fresnel_diffuse_reflectance(1.0) < 1e-12);
    }

    #[test]
    fn schlick_endpoints_and_metal_table() {
        assert_eq!(schlick(0.04, 1.0), 0.04);
        assert_eq!(schlick(0.04, 0.0), 1.0);
        let (eta, k) = metal("Au").unwrap();
        let r = fresnel_conductor(1.0, eta, k);
        // Gold reflects red much more than blue.
        assert!(r.x > 0.9 && r.z < 0.45, "{r}");
        assert!(metal("Unobtainium").is_none());
    }
}
