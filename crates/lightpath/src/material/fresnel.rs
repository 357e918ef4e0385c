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
    f0 + (1.0 - f0) * schlick_weight(cos.abs())
}

/// Schlick's weight (1 − cos)⁵, cos clamped to [0, 1].
#[inline]
pub fn schlick_weight(cos: f32) -> f32 {
    let m = (1.0 - cos).clamp(0.0, 1.0);
    let m2 = m * m;
    m2 * m2 * m
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

/// The RGB complex indices of refraction (η, k) that Mitsuba 3's RGB variants use for
/// its named conductors (`<string name="material" value="Au"/>`): Mitsuba reduces the
/// spectra of its `data/ior` tables to sRGB itself; these values were read back from
/// Mitsuba 3.9.1 `scalar_rgb` (`mi.traverse` of a `conductor`), so Mitsuba scenes render
/// with the same colours in both renderers.
pub const MITSUBA_METALS: &[(&str, [f32; 3], [f32; 3])] = &[
    ("a-C", [2.9440, 2.2271, 1.9682], [0.8875, 0.7993, 0.8153]),
    ("Ag", [0.1553, 0.1167, 0.1384], [4.8284, 3.1222, 2.1469]),
    ("Al", [1.6575, 0.8804, 0.5212], [9.2238, 6.2695, 4.8370]),
    ("AlAs", [3.6053, 3.2329, 2.2163], [0.0007, 0.0000, 0.0075]),
    ("AlSb", [0.0000, 4.1394, 4.6693], [0.0000, 0.0940, 1.3006]),
    ("Au", [0.1430, 0.3753, 1.4420], [3.9830, 2.3856, 1.6034]),
    ("Be", [4.1850, 3.1850, 2.7841], [3.8355, 3.0101, 2.8690]),
    ("Cr", [4.3697, 2.9165, 1.6549], [5.2065, 4.2313, 3.7547]),
    ("CsI", [2.1449, 1.7023, 1.6624], [0.0000, 0.0000, 0.0000]),
    ("Cu", [0.2010, 0.9237, 1.1022], [3.9133, 2.4530, 2.1421]),
    ("Cu2O", [3.5518, 2.9499, 2.7519], [0.1142, 0.1939, 0.6061]),
    ("CuO", [3.2475, 2.4478, 2.2102], [0.5211, 0.5700, 0.7222]),
    ("d-C", [2.7087, 2.3188, 2.2289], [0.0000, 0.0000, 0.0000]),
    ("Hg", [2.3989, 1.4400, 0.9096], [6.3276, 4.3719, 3.4218]),
    ("HgTe", [4.7790, 3.2312, 2.6599], [1.6316, 1.5808, 1.7293]),
    ("Ir", [3.0863, 2.0822, 1.6179], [5.5922, 4.0671, 3.2673]),
    ("K", [0.0640, 0.0464, 0.0382], [2.1042, 1.3489, 0.9131]),
    ("Li", [0.2658, 0.1956, 0.2209], [3.5402, 2.3111, 1.6686]),
    ("MgO", [2.0896, 1.6507, 1.5949], [0.0000, 0.0000, 0.0000]),
    ("Mo", [4.4840, 3.5251, 2.7763], [4.1114, 3.4208, 3.1506]),
    (
        "Na_palik",
        [0.0603, 0.0561, 0.0620],
        [3.1793, 2.1125, 1.5790],
    ),
    ("Nb", [3.4201, 2.7901, 2.3956], [3.4414, 2.7377, 2.5797]),
    (
        "Ni_palik",
        [2.3673, 1.6634, 1.4671],
        [4.4988, 3.0502, 2.3454],
    ),
    ("Rh", [2.5858, 1.8602, 1.5543], [6.7823, 4.7030, 3.9761]),
    ("Se", [4.0583, 2.8429, 2.8209], [0.7540, 0.6384, 0.5218]),
    ("SiC", [3.1723, 2.5260, 2.4794], [0.0000, 0.0000, 0.0000]),
    ("SnTe", [4.5242, 1.9816, 1.2816], [0.0000, 0.0000, 0.0000]),
    ("Ta", [2.0627, 2.3929, 2.6279], [2.4084, 1.7415, 1.9470]),
    ("Te", [7.3902, 4.4821, 2.6371], [3.2560, 3.5271, 3.2921]),
    ("ThF4", [1.8307, 1.4422, 1.3876], [0.0000, 0.0000, 0.0000]),
    ("TiC", [3.7005, 2.8374, 2.5823], [3.2656, 2.3516, 2.1728]),
    ("TiN", [1.6484, 1.1505, 1.3798], [3.3683, 1.9435, 1.1021]),
    ("TiO2", [3.4566, 2.8017, 2.9052], [0.0001, 0.0000, 0.0007]),
    ("VC", [3.6576, 2.7527, 2.5327], [3.0683, 2.1987, 1.9632]),
    ("VN", [2.8656, 2.1192, 1.9401], [3.0322, 2.0561, 1.6163]),
    ("W", [4.3708, 3.3002, 2.9984], [3.5006, 2.6049, 2.2732]),
];

/// The (η, k) of a named conductor of [`MITSUBA_METALS`].
pub fn mitsuba_metal(name: &str) -> Option<(Vec3, Vec3)> {
    MITSUBA_METALS
        .iter()
        .find(|(n, _, _)| *n == name)
        .map(|(_, eta, k)| (Vec3::from_array(*eta), Vec3::from_array(*k)))
}

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
