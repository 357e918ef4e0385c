//! Hair and fur: the scattering of a rough dielectric cylinder with an absorbing
//! interior, after Chiang, Bitterli, Tappan and Burley, "A practical and controllable
//! hair and fur model for production path tracing" (2016), in the form pbrt-v3/v4 give
//! it. Light reflects off the fibre (R), passes through it (TT), reflects once inside
//! (TRT), and the rest is lumped into one lobe. Each lobe is a longitudinal term M_p
//! (d'Eon et al.'s, with variance from `betaM`) times an azimuthal term N_p (a logistic
//! of width from `betaN`, trimmed to [-π, π], centred on the exit azimuth of a smooth
//! cylinder) times an attenuation A_p (dielectric Fresnel at index `eta` and the
//! absorption σa along the refracted path). The cuticle's scales tilt the lobes by
//! `alpha` degrees (R by -2α, TT by α, TRT by 4α). With σa = 0 the fibre neither
//! absorbs nor emits: every lobe together scatters all the light it gets.
//!
//! The fibre runs along the shading frame's second axis (n × ∂p/∂u): on curves, whose
//! ∂p/∂u goes round the strand, that is the strand's direction. The offset h ∈ [-1, 1]
//! across the fibre at which light enters is that of a round fibre, sin γo, where γo is
//! the angle between the normal and wo's projection across the fibre.
//!
//! ```xml
//! <bsdf type="hair">
//!     <float name="eumelanin" value="1.3"/>      <!-- brown; 8: black; 0.3: blond -->
//!     <float name="pheomelanin" value="0"/>      <!-- red pigment -->
//!     <!-- or <texture name="color" type="constant" value="0.3,0.2,0.1"/> (the colour
//!          after multiple scattering, via Chiang et al.'s inverse), or
//!          <rgb name="sigmaA" value="0.8,1.2,2"/> (absorption per unit of diameter) -->
//!     <float name="betaM" value="0.3"/>          <!-- longitudinal roughness, 0..1 -->
//!     <float name="betaN" value="0.3"/>          <!-- azimuthal roughness, 0..1 -->
//!     <float name="alpha" value="2"/>            <!-- scale tilt in degrees -->
//!     <float name="eta" value="1.55"/>
//! </bsdf>
//! ```

use super::fresnel::fresnel_dielectric;
use super::{valid_pdf, BsdfSample};
use crate::texture::{TexCoord, Texture};
use glam::{Vec2, Vec3};
use std::f32::consts::PI;
use std::sync::Arc;

/// Lobes R, TT, TRT, and the rest (P_MAX).
const P_MAX: usize = 3;

/// Absorption of eumelanin and pheomelanin per unit concentration (Chiang et al.).
const EUMELANIN_SIGMA_A: Vec3 = Vec3::new(0.419, 0.697, 1.37);
const PHEOMELANIN_SIGMA_A: Vec3 = Vec3::new(0.187, 0.4, 1.05);

/// Where the fibre's absorption comes from.
#[derive(Debug, Clone)]
pub enum HairAbsorption {
    /// σa per unit of fibre diameter.
    SigmaA(Vec3),
    /// A colour (the fibre's albedo after multiple scattering), turned into σa for the
    /// azimuthal roughness by Chiang et al.'s fit.
    Color(Arc<Texture>),
}

/// The hair BSDF (see the module notes).
#[derive(Debug, Clone)]
pub struct Hair {
    pub absorption: HairAbsorption,
    pub eta: f32,
    pub beta_m: f32,
    pub beta_n: f32,
    /// Scale tilt in radians.
    pub alpha: f32,
    /// Longitudinal variance per lobe.
    v: [f32; P_MAX + 1],
    /// Logistic scale of the azimuthal lobes.
    s: f32,
    /// sin and cos of 2^k α, k = 0, 1, 2.
    sin_2k_alpha: [f32; 3],
    cos_2k_alpha: [f32; 3],
}

/// σa of a fibre with these melanin concentrations.
pub fn sigma_a_from_melanin(eumelanin: f32, pheomelanin: f32) -> Vec3 {
    EUMELANIN_SIGMA_A * eumelanin + PHEOMELANIN_SIGMA_A * pheomelanin
}

/// σa that gives a fibre of azimuthal roughness `beta_n` the colour `color` after
/// multiple scattering (Chiang et al.'s fit).
pub fn sigma_a_from_color(color: Vec3, beta_n: f32) -> Vec3 {
    let b = beta_n;
    let d = 5.969 - 0.215 * b + 2.532 * b * b - 10.73 * b.powi(3)
        + 5.574 * b.powi(4)
        + 0.245 * b.powi(5);
    let ln = color
        .clamp(Vec3::splat(1e-4), Vec3::ONE)
        .to_array()
        .map(f32::ln);
    Vec3::from_array(ln.map(|l| (l / d) * (l / d)))
}

/// A hair BSDF's parameters as a scene gives them (each optional; see the module notes).
#[derive(Debug, Clone, Default)]
pub struct HairParameters {
    pub sigma_a: Option<Vec3>,
    pub color: Option<Arc<Texture>>,
    pub eumelanin: Option<f32>,
    pub pheomelanin: Option<f32>,
    pub eta: Option<f32>,
    pub beta_m: Option<f32>,
    pub beta_n: Option<f32>,
    pub alpha: Option<f32>,
}

impl HairParameters {
    /// The BSDF, or what is wrong with the parameters. The absorption is σa, a colour,
    /// or melanin concentrations (each 0 when the other is given; eumelanin 1.3, brown,
    /// when none of these is), one of the three.
    pub fn build(self) -> Result<Hair, String> {
        let melanin = self.eumelanin.is_some() || self.pheomelanin.is_some();
        let given = [self.sigma_a.is_some(), self.color.is_some(), melanin];
        if given.iter().filter(|g| **g).count() > 1 {
            return Err("give the hair's absorption one way: sigma_a, color, or melanin".into());
        }
        let absorption = if let Some(s) = self.sigma_a {
            if !(s.is_finite() && s.min_element() >= 0.0) {
                return Err(format!("sigma_a must be finite and not negative, got {s}"));
            }
            HairAbsorption::SigmaA(s)
        } else if let Some(c) = self.color {
            HairAbsorption::Color(c)
        } else {
            // Brown (eumelanin 1.3) when nothing is given, as in pbrt.
            let (e, p) = match (self.eumelanin, self.pheomelanin) {
                (None, None) => (1.3, 0.0),
                (e, p) => (e.unwrap_or(0.0), p.unwrap_or(0.0)),
            };
            if !(e.is_finite() && p.is_finite() && e >= 0.0 && p >= 0.0) {
                return Err(format!(
                    "melanin concentrations must be finite and not negative, got {e} and {p}"
                ));
            }
            HairAbsorption::SigmaA(sigma_a_from_melanin(e, p))
        };
        let eta = self.eta.unwrap_or(1.55);
        if !(eta.is_finite() && (1.0..=4.0).contains(&eta)) {
            return Err(format!("the hair's eta must be between 1 and 4, got {eta}"));
        }
        let mut betas = [0.3, 0.3];
        for (b, given) in betas.iter_mut().zip([self.beta_m, self.beta_n]) {
            if let Some(v) = given {
                if !(v > 0.0 && v <= 1.0) {
                    return Err(format!("hair roughness must be in (0, 1], got {v}"));
                }
                *b = v;
            }
        }
        let alpha = self.alpha.unwrap_or(2.0);
        if !(alpha.is_finite() && alpha.abs() <= 45.0) {
            return Err(format!(
                "the scale tilt alpha must be within ±45 degrees, got {alpha}"
            ));
        }
        Ok(Hair::new(absorption, eta, betas[0], betas[1], alpha))
    }
}

impl Hair {
    /// A hair BSDF; `alpha_degrees` is the scale tilt. The roughnesses are clamped to
    /// [0.01, 1] (below that the lobes are too narrow for single precision).
    pub fn new(
        absorption: HairAbsorption,
        eta: f32,
        beta_m: f32,
        beta_n: f32,
        alpha_degrees: f32,
    ) -> Hair {
        let beta_m = beta_m.clamp(0.01, 1.0);
        let beta_n = beta_n.clamp(0.01, 1.0);
        let v0 = (0.726 * beta_m + 0.812 * beta_m * beta_m + 3.7 * beta_m.powi(20)).powi(2);
        let v = [v0, 0.25 * v0, 4.0 * v0, 4.0 * v0];
        let s = (PI / 8.0).sqrt()
            * (0.265 * beta_n + 1.194 * beta_n * beta_n + 5.372 * beta_n.powi(22));
        let alpha = alpha_degrees.to_radians();
        let mut sin_2k_alpha = [alpha.sin(), 0.0, 0.0];
        let mut cos_2k_alpha = [
            (1.0 - sin_2k_alpha[0] * sin_2k_alpha[0]).max(0.0).sqrt(),
            0.0,
            0.0,
        ];
        for i in 1..3 {
            sin_2k_alpha[i] = 2.0 * cos_2k_alpha[i - 1] * sin_2k_alpha[i - 1];
            cos_2k_alpha[i] = cos_2k_alpha[i - 1] * cos_2k_alpha[i - 1]
                - sin_2k_alpha[i - 1] * sin_2k_alpha[i - 1];
        }
        Hair {
            absorption,
            eta,
            beta_m,
            beta_n,
            alpha,
            v,
            s,
            sin_2k_alpha,
            cos_2k_alpha,
        }
    }

    /// σa at `uv`.
    #[inline]
    fn sigma_a(&self, uv: TexCoord) -> Vec3 {
        match &self.absorption {
            HairAbsorption::SigmaA(s) => *s,
            HairAbsorption::Color(t) => sigma_a_from_color(t.eval(uv), self.beta_n),
        }
    }

    /// The fibre's colour, for albedo buffers: the given colour, or e^(-2σa) (two
    /// diameters of absorption).
    pub fn albedo(&self, uv: TexCoord) -> Vec3 {
        match &self.absorption {
            HairAbsorption::Color(t) => t.eval(uv),
            HairAbsorption::SigmaA(s) => (-2.0 * *s).exp(),
        }
    }

    /// The scattering f·|cos θi| (the fibre's scattering function S) for local `wo`, `wi`.
    pub fn eval(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> Vec3 {
        let o = FibreDirection::new(wo);
        let geo = self.geometry(&o);
        let ap = self.attenuation(&o, &geo, self.sigma_a(uv));
        let terms = self.lobe_terms(&o, &FibreDirection::new(wi), &geo);
        let sum: Vec3 = ap.iter().zip(terms).map(|(a, t)| *a * t).sum();
        if sum.is_finite() {
            sum
        } else {
            Vec3::ZERO
        }
    }

    /// The density of `sample` choosing local `wi`.
    pub fn pdf(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> f32 {
        let o = FibreDirection::new(wo);
        let geo = self.geometry(&o);
        let lobe = lobe_pdf(&self.attenuation(&o, &geo, self.sigma_a(uv)));
        let terms = self.lobe_terms(&o, &FibreDirection::new(wi), &geo);
        let pdf: f32 = lobe.iter().zip(terms).map(|(w, t)| w * t).sum();
        if pdf.is_finite() {
            pdf
        } else {
            0.0
        }
    }

    /// M_p · N_p of each lobe for the pair (o, i): the lobes' shapes, which `eval`
    /// weights by their attenuation and `pdf` by their probability.
    #[inline]
    fn lobe_terms(&self, o: &FibreDirection, i: &FibreDirection, geo: &FibreGeometry) -> [f32; 4] {
        let phi = i.phi - o.phi;
        std::array::from_fn(|p| {
            let (sin_op, cos_op) = self.tilted(p, o);
            let m = mp(i.cos_theta, cos_op, i.sin_theta, sin_op, self.v[p]);
            let n = if p < P_MAX {
                np(phi, p, self.s, geo.gamma_o, geo.gamma_t)
            } else {
                1.0 / (2.0 * PI)
            };
            m * n
        })
    }

    /// Samples a lobe in proportion to its attenuation (`u_lobe`, reused for the
    /// azimuth), then its longitudinal and azimuthal terms exactly (`u`).
    pub fn sample(&self, uv: TexCoord, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        let o = FibreDirection::new(wo);
        let geo = self.geometry(&o);
        let ap = self.attenuation(&o, &geo, self.sigma_a(uv));
        let lobe = lobe_pdf(&ap);
        let mut uc = u_lobe;
        let mut p = 0;
        while p < P_MAX && uc >= lobe[p] {
            uc -= lobe[p];
            p += 1;
        }
        let uc = (uc / lobe[p]).clamp(0.0, 1.0 - f32::EPSILON);
        // The longitudinal angle around the lobe's tilted mirror direction.
        let (sin_op, cos_op) = self.tilted(p, &o);
        let v = self.v[p];
        let u0 = u.x.max(1e-5);
        let cos_theta = 1.0 + v * (u0 + (1.0 - u0) * (-2.0 / v).exp()).ln();
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        let cos_phi = (2.0 * PI * u.y).cos();
        let sin_theta_i = -cos_theta * sin_op + sin_theta * cos_phi * cos_op;
        let cos_theta_i = (1.0 - sin_theta_i * sin_theta_i).max(0.0).sqrt();
        // The azimuth.
        let dphi = if p < P_MAX {
            exit_azimuth(p, geo.gamma_o, geo.gamma_t) + sample_trimmed_logistic(uc, self.s, -PI, PI)
        } else {
            2.0 * PI * uc
        };
        let phi_i = o.phi + dphi;
        let wi = FibreDirection::to_local(sin_theta_i, cos_theta_i, phi_i);
        // f and the density of wi over all lobes, from one set of lobe shapes.
        let terms = self.lobe_terms(&o, &FibreDirection::new(wi), &geo);
        let pdf: f32 = lobe.iter().zip(terms).map(|(w, t)| w * t).sum();
        let f: Vec3 = ap.iter().zip(terms).map(|(a, t)| *a * t).sum();
        if !valid_pdf(pdf) || !f.is_finite() {
            return None;
        }
        Some(BsdfSample {
            wi,
            weight: f / pdf,
            pdf,
            delta: false,
        })
    }

    /// sin and cos of θo tilted for lobe `p` (the rest is not tilted).
    #[inline]
    fn tilted(&self, p: usize, o: &FibreDirection) -> (f32, f32) {
        let (s, c) = (o.sin_theta, o.cos_theta);
        let (sa, ca) = (&self.sin_2k_alpha, &self.cos_2k_alpha);
        let (sin_op, cos_op) = match p {
            0 => (s * ca[1] - c * sa[1], c * ca[1] + s * sa[1]),
            1 => (s * ca[0] + c * sa[0], c * ca[0] - s * sa[0]),
            2 => (s * ca[2] + c * sa[2], c * ca[2] - s * sa[2]),
            _ => (s, c),
        };
        (sin_op, cos_op.abs())
    }

    /// The refracted path through the fibre for `o`.
    #[inline]
    fn geometry(&self, o: &FibreDirection) -> FibreGeometry {
        let sin_theta_t = o.sin_theta / self.eta;
        let cos_theta_t = (1.0 - sin_theta_t * sin_theta_t).max(0.0).sqrt();
        // The index that refraction across the fibre sees (Bravais).
        let etap = (self.eta * self.eta - o.sin_theta * o.sin_theta)
            .max(0.0)
            .sqrt()
            / o.cos_theta.max(1e-6);
        let sin_gamma_t = (o.h / etap).clamp(-1.0, 1.0);
        let cos_gamma_t = (1.0 - sin_gamma_t * sin_gamma_t).max(0.0).sqrt();
        FibreGeometry {
            gamma_o: o.h.clamp(-1.0, 1.0).asin(),
            gamma_t: sin_gamma_t.asin(),
            // The path length across the fibre (in diameters), over cos θt.
            path: 2.0 * cos_gamma_t / cos_theta_t.max(1e-6),
        }
    }

    /// A_p for the four lobes.
    #[inline]
    fn attenuation(&self, o: &FibreDirection, geo: &FibreGeometry, sigma_a: Vec3) -> [Vec3; 4] {
        let cos_gamma_o = (1.0 - o.h * o.h).max(0.0).sqrt();
        let f = fresnel_dielectric(o.cos_theta * cos_gamma_o, self.eta);
        let t = (-sigma_a * geo.path).exp();
        let a0 = Vec3::splat(f);
        let a1 = (1.0 - f) * (1.0 - f) * t;
        let a2 = a1 * t * f;
        let a3 = a2 * f * t / (Vec3::ONE - t * f);
        [a0, a1, a2, a3]
    }
}

/// A direction in the fibre's terms: θ from the plane across the fibre (sin θ = the
/// component along it), φ around it from the frame's first axis toward the normal, and
/// for wo the offset h = sin γ across the fibre.
struct FibreDirection {
    sin_theta: f32,
    cos_theta: f32,
    phi: f32,
    h: f32,
}

impl FibreDirection {
    /// The local frame has the fibre along y and the normal along z.
    #[inline]
    fn new(w: Vec3) -> FibreDirection {
        let sin_theta = w.y.clamp(-1.0, 1.0);
        let cos_theta = (1.0 - sin_theta * sin_theta).max(0.0).sqrt();
        let across = w.x.hypot(w.z);
        // γ = φ - π/2 (the normal's azimuth), so h = sin γ = -cos φ.
        let h = if across > 0.0 { -w.x / across } else { 0.0 };
        FibreDirection {
            sin_theta,
            cos_theta,
            phi: w.z.atan2(w.x),
            h,
        }
    }

    #[inline]
    fn to_local(sin_theta: f32, cos_theta: f32, phi: f32) -> Vec3 {
        Vec3::new(cos_theta * phi.cos(), sin_theta, cos_theta * phi.sin())
    }
}

struct FibreGeometry {
    gamma_o: f32,
    gamma_t: f32,
    path: f32,
}

/// The azimuth at which lobe `p` leaves a smooth fibre, relative to the entering one.
#[inline]
fn exit_azimuth(p: usize, gamma_o: f32, gamma_t: f32) -> f32 {
    2.0 * p as f32 * gamma_t - 2.0 * gamma_o + p as f32 * PI
}

/// The probability of each lobe: its attenuation (mean over RGB) over the sum.
#[inline]
fn lobe_pdf(ap: &[Vec3; 4]) -> [f32; 4] {
    let w = ap.map(|a| a.element_sum() / 3.0);
    let sum: f32 = w.iter().sum();
    if sum > 0.0 && sum.is_finite() {
        w.map(|x| x / sum)
    } else {
        [1.0, 0.0, 0.0, 0.0]
    }
}

/// d'Eon et al.'s longitudinal scattering with variance `v` (in double precision; the
/// logarithmic form where the Bessel function would overflow).
fn mp(cos_theta_i: f32, cos_theta_o: f32, sin_theta_i: f32, sin_theta_o: f32, v: f32) -> f32 {
    let (v, ci, co, si, so) = (
        v as f64,
        cos_theta_i as f64,
        cos_theta_o as f64,
        sin_theta_i as f64,
        sin_theta_o as f64,
    );
    let a = ci * co / v;
    let b = si * so / v;
    let m = if v <= 0.1 {
        (log_i0(a) - b - 1.0 / v + std::f64::consts::LN_2 + (1.0 / (2.0 * v)).ln()).exp()
    } else {
        (-b).exp() * i0(a) / ((1.0 / v).sinh() * 2.0 * v)
    };
    m as f32
}

/// The modified Bessel function of the first kind, order 0 (its series).
fn i0(x: f64) -> f64 {
    let mut sum = 0.0;
    let mut term = 1.0;
    let q = x * x / 4.0;
    for k in 0..200 {
        if k > 0 {
            term *= q / (k * k) as f64;
        }
        sum += term;
        if term < 1e-17 * sum {
            break;
        }
    }
    sum
}

/// ln I0(x): the series up to 12, then the asymptotic expansion
/// I0(x) ≈ e^x / √(2πx) · Σ ((2k-1)!!)² / (k! (8x)^k) to five terms (relative error
/// under 2e-7 from x = 12; pbrt's one-term form, with half the 1/(8x) term, is 0.5% off
/// there and leaves narrow lobes 0.1-0.2% short of normalised).
fn log_i0(x: f64) -> f64 {
    if x <= 12.0 {
        return i0(x).ln();
    }
    let y = 1.0 / (8.0 * x);
    let mut term = 1.0;
    let mut sum = 1.0;
    for k in 1..=5 {
        let odd = (2 * k - 1) as f64;
        term *= odd * odd * y / k as f64;
        sum += term;
    }
    x - 0.5 * (2.0 * std::f64::consts::PI * x).ln() + sum.ln()
}

/// The azimuthal distribution of lobe `p` at relative azimuth `phi`.
#[inline]
fn np(phi: f32, p: usize, s: f32, gamma_o: f32, gamma_t: f32) -> f32 {
    let mut dphi = phi - exit_azimuth(p, gamma_o, gamma_t);
    // Into [-π, π].
    dphi = (dphi + PI).rem_euclid(2.0 * PI) - PI;
    trimmed_logistic(dphi, s, -PI, PI)
}

#[inline]
fn logistic(x: f32, s: f32) -> f32 {
    let e = (-x.abs() / s).exp();
    e / (s * (1.0 + e) * (1.0 + e))
}

#[inline]
fn logistic_cdf(x: f32, s: f32) -> f32 {
    1.0 / (1.0 + (-x / s).exp())
}

#[inline]
fn trimmed_logistic(x: f32, s: f32, a: f32, b: f32) -> f32 {
    logistic(x, s) / (logistic_cdf(b, s) - logistic_cdf(a, s))
}

/// Inverts the trimmed logistic's distribution for a uniform `u`.
#[inline]
fn sample_trimmed_logistic(u: f32, s: f32, a: f32, b: f32) -> f32 {
    let k = logistic_cdf(b, s) - logistic_cdf(a, s);
    let x = -s * (1.0 / (u * k + logistic_cdf(a, s)) - 1.0).ln();
    x.clamp(a, b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bessel_and_logistic() {
        // I0(1) = 1.2660658777520082, I0(5) = 27.239871823604442.
        assert!((i0(1.0) - 1.2660658777520082).abs() < 1e-12);
        assert!((i0(5.0) / 27.239871823604442 - 1.0).abs() < 1e-12);
        // The asymptotic form joins the series at the switch, and agrees with it beyond.
        for x in [12.0001, 20.0, 60.0] {
            assert!((log_i0(x) - i0(x).ln()).abs() < 1e-6, "{x}");
        }
        // The trimmed logistic integrates to 1 over [-π, π], and sampling inverts its CDF.
        for s in [0.05f32, 0.3, 1.0] {
            let n = 20_000;
            let h = 2.0 * PI / n as f32;
            let total: f32 = (0..n)
                .map(|k| trimmed_logistic(-PI + (k as f32 + 0.5) * h, s, -PI, PI) * h)
                .sum();
            assert!((total - 1.0).abs() < 1e-3, "{s}: {total}");
            let x = sample_trimmed_logistic(0.8, s, -PI, PI);
            let cdf = (logistic_cdf(x, s) - logistic_cdf(-PI, s))
                / (logistic_cdf(PI, s) - logistic_cdf(-PI, s));
            assert!((cdf - 0.8).abs() < 1e-4, "{s}: {cdf}");
        }
    }

    #[test]
    fn mp_is_normalised_over_the_sphere() {
        // ∫ Mp(θi) cos θi dθi = 1 over θi in [-π/2, π/2], for narrow and wide lobes.
        for v in [0.004f32, 0.02, 0.09, 0.3, 1.5] {
            for theta_o in [0.0f32, 0.5, 1.2] {
                let n = 20_000;
                let h = PI / n as f32;
                let total: f64 = (0..n)
                    .map(|k| {
                        let t = -PI / 2.0 + (k as f32 + 0.5) * h;
                        (mp(t.cos(), theta_o.cos(), t.sin(), theta_o.sin(), v) * t.cos() * h) as f64
                    })
                    .sum();
                assert!((total - 1.0).abs() < 2e-4, "v {v} θo {theta_o}: {total}");
            }
        }
    }

    /// A smooth, untilted, strongly absorbing fibre reflects like a mirror: the R lobe
    /// leaves at the mirror image of wo about the normal at the hit point, which fixes
    /// the sign of h (the offset across the fibre) against the azimuth.
    #[test]
    fn a_smooth_dark_fibre_is_a_mirror() {
        let hair = Hair::new(
            HairAbsorption::SigmaA(Vec3::splat(50.0)),
            1.55,
            0.02,
            0.02,
            0.0,
        );
        let mut rng = crate::sampling::Pcg32::new(9, 9);
        for wo in [
            Vec3::new(0.5, 0.2, 0.8),
            Vec3::new(-0.6, -0.4, 0.5),
            Vec3::new(0.1, 0.7, 0.3),
        ] {
            let wo = wo.normalize();
            let mirror = Vec3::new(-wo.x, -wo.y, wo.z);
            let mut mean = Vec3::ZERO;
            let n = 2000;
            for _ in 0..n {
                let u = Vec2::new(rng.next_f32(), rng.next_f32());
                let bs = hair
                    .sample(Vec2::ZERO.into(), wo, rng.next_f32(), u)
                    .unwrap();
                mean += bs.wi;
            }
            let mean = mean.normalize();
            assert!(mean.dot(mirror) > 0.995, "wo {wo}: {mean} vs {mirror}");
            // And f is far larger there than at the azimuth mirrored the other way.
            let wrong = Vec3::new(wo.x, -wo.y, wo.z).normalize();
            let (at, off) = (
                hair.eval(Vec2::ZERO.into(), wo, mirror).x,
                hair.eval(Vec2::ZERO.into(), wo, wrong).x,
            );
            assert!(at > 100.0 * off, "{at} {off}");
        }
    }

    #[test]
    fn melanin_and_colour() {
        assert_eq!(sigma_a_from_melanin(1.0, 0.0), EUMELANIN_SIGMA_A);
        // A colour and the σa it gives: darker colours absorb more, white not at all.
        let dark = sigma_a_from_color(Vec3::splat(0.1), 0.3);
        let light = sigma_a_from_color(Vec3::splat(0.6), 0.3);
        assert!(dark.x > light.x && light.x > 0.0);
        assert!(sigma_a_from_color(Vec3::ONE, 0.3).max_element() < 1e-12);
    }
}
