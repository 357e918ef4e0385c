//! Rough plastic: a diffuse base under a rough dielectric coating, after Mitsuba 3's
//! `roughplastic`. Two lobes, with η the coating's relative index:
//!
//! - specular: microfacet reflection off the coating,
//!   f·cos θi = specularReflectance·F(wo·m)·D(m)·G1(wo)·G1(wi)/(4 cos θo), m the half
//!   vector (GGX or Beckmann, isotropic, separable Smith masking);
//! - diffuse: f·cos θi = diff·T(cos θo)·T(cos θi)/η² · cos θi/π, where T(μ) is the
//!   coating's transmittance at incident cosine μ and diff sums the internal
//!   reflections, ρ/(1 − R_int) (`nonlinear="false"`, the default: the texture's colour
//!   is preserved) or ρ/(1 − ρ·R_int) (`nonlinear="true"`).
//!
//! Like Mitsuba, the coating's tables are computed once, at construction, by fixed
//! Gauss–Legendre quadrature over the visible-normal sample space (no randomness):
//! T(μ) = E_m[(1 − F(wo·m))·G1(refracted wo, m)] at 64 equally spaced μ (32×32 nodes),
//! linearly interpolated; R_int = 2·mean_μ(μ·E_m[F(wo·m)·G1(reflected wo, m)]) with the
//! inverse index 1/η (128×128 nodes: total internal reflection makes the integrand
//! discontinuous) over the same 64 μ (Mitsuba's discretisation, kept so that the two
//! renderers agree). Both include the masking of the scattered direction, so energy lost
//! to single-scattering microfacets is lost here too. Tables are shared between
//! materials with the same distribution, α and η.
//!
//! The specular lobe (visible normals) is picked with probability
//! (1 − T(cos θo))·s/((1 − T(cos θo))·s + T(cos θo)·(1 − s)),
//! s = mean(specular)/(mean(diffuse) + mean(specular)), the diffuse lobe (cosine
//! weighted) otherwise; `pdf` is the mixture and a sample's weight is eval/pdf.
//! One-sided: black when wo or wi is below the shading normal (wrap it in `twosided`).
//!
//! Created by the Mitsuba dialect, with Mitsuba's parameter names and defaults; `alpha`
//! becomes our roughness √α, which [`RoughPlastic::new`] squares back (as for
//! `roughconductor`):
//!
//! ```xml
//! <bsdf type="roughplastic">
//!     <rgb name="diffuse_reflectance" value="0.1,0.2,0.6"/>
//!     <float name="alpha" value="0.1"/>                      <!-- default 0.1 -->
//!     <string name="distribution" value="beckmann"/>         <!-- default; or ggx -->
//!     <float name="int_ior" value="1.49"/>                   <!-- defaults 1.49 / 1.000277 -->
//!     <float name="ext_ior" value="1.000277"/>
//!     <rgb name="specular_reflectance" value="1"/>           <!-- optional -->
//!     <boolean name="nonlinear" value="false"/>              <!-- optional -->
//! </bsdf>
//! ```

use super::fresnel::fresnel_dielectric_cos;
use super::microfacet::{
    reflect, reflection, refract, roughness_to_alpha, Distribution, Microfacet,
};
use super::BsdfSample;
use crate::math::INV_PI;
use crate::sampling::warp;
use crate::texture::{TexCoord, Texture};
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::sync::{Arc, Mutex};

/// Number of tabulated incident cosines (Mitsuba's `MI_ROUGH_TRANSMITTANCE_RES`).
const TABLE_SIZE: usize = 64;

#[derive(Debug, Clone)]
pub struct RoughPlastic {
    pub diffuse: Arc<Texture>,
    pub specular: Arc<Texture>,
    /// Interior index over exterior index.
    pub eta: f32,
    /// The microfacet distribution's α (isotropic).
    pub alpha: f32,
    pub distribution: Distribution,
    pub nonlinear: bool,
    coating: Arc<Coating>,
    /// Weight steering samples to the specular lobe.
    specular_sampling_weight: f32,
}

/// The coating's precomputed transport.
#[derive(Debug)]
struct Coating {
    /// T(μ) at μ = i/(TABLE_SIZE − 1), seen from outside.
    transmittance: [f32; TABLE_SIZE],
    /// Diffuse reflectance of the coating seen from inside.
    internal_reflectance: f32,
}

type CoatingKey = (Distribution, u32, u32);

/// Coatings computed so far: a scene's materials usually share a few.
static COATINGS: Mutex<Vec<(CoatingKey, Arc<Coating>)>> = Mutex::new(Vec::new());

impl RoughPlastic {
    /// A rough plastic with roughness `roughness` (α = max(1e-3, roughness²), as for the
    /// other microfacet materials) and relative index `ior`.
    pub fn new(
        diffuse: Arc<Texture>,
        specular: Arc<Texture>,
        ior: f32,
        roughness: f32,
        distribution: Distribution,
        nonlinear: bool,
    ) -> RoughPlastic {
        let alpha = roughness_to_alpha(roughness);
        let d_mean = diffuse.average().dot(Vec3::splat(1.0 / 3.0)).max(0.0);
        let s_mean = specular.average().dot(Vec3::splat(1.0 / 3.0)).max(0.0);
        let total = d_mean + s_mean;
        RoughPlastic {
            diffuse,
            specular,
            eta: ior,
            alpha,
            distribution,
            nonlinear,
            coating: Coating::shared(distribution, alpha, ior),
            specular_sampling_weight: if total > 0.0 { s_mean / total } else { 0.5 },
        }
    }

    #[inline]
    fn microfacet(&self) -> Microfacet {
        Microfacet::isotropic(self.alpha).with_distribution(self.distribution)
    }

    /// The coating's transmittance at incident cosine `mu`.
    #[inline]
    pub fn transmittance(&self, mu: f32) -> f32 {
        self.coating.transmittance(mu)
    }

    /// The coating's diffuse reflectance seen from inside.
    pub fn internal_reflectance(&self) -> f32 {
        self.coating.internal_reflectance
    }

    /// Probability of picking the specular lobe given T(cos θo).
    #[inline]
    fn prob_specular(&self, t_o: f32) -> f32 {
        let ps = (1.0 - t_o) * self.specular_sampling_weight;
        let pd = t_o * (1.0 - self.specular_sampling_weight);
        if ps + pd > 0.0 {
            ps / (ps + pd)
        } else {
            1.0
        }
    }

    /// The diffuse base's colour after the internal reflections.
    #[inline]
    fn base(&self, uv: TexCoord) -> Vec3 {
        let rho = self.diffuse.eval(uv);
        let r = self.coating.internal_reflectance;
        if self.nonlinear {
            rho / (Vec3::ONE - rho * r)
        } else {
            rho / (1.0 - r)
        }
    }

    /// f·cos θi of both lobes, and the density of sampling `wi`.
    fn eval_pdf(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let t_o = self.transmittance(wo.z);
        let t_i = self.transmittance(wi.z);
        let p_spec = self.prob_specular(t_o);
        // Specular: the coating's microfacets.
        let (specular, spec_pdf) = match reflection(&self.microfacet(), wo, wi) {
            Some((m, value, pdf)) => {
                let (f, _) = fresnel_dielectric_cos(wo.dot(m), self.eta);
                (self.specular.eval(uv) * (f * value), pdf)
            }
            None => (Vec3::ZERO, 0.0),
        };
        // Diffuse: through the coating, off the base, and out again.
        let diffuse = self.base(uv) * (t_o * t_i / (self.eta * self.eta) * wi.z * INV_PI);
        let pdf = p_spec * spec_pdf + (1.0 - p_spec) * wi.z * INV_PI;
        (specular + diffuse, pdf)
    }

    pub fn eval(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> Vec3 {
        self.eval_pdf(uv, wo, wi).0
    }

    pub fn pdf(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> f32 {
        self.eval_pdf(uv, wo, wi).1
    }

    pub fn sample(&self, uv: TexCoord, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let p_spec = self.prob_specular(self.transmittance(wo.z));
        let wi = if u_lobe < p_spec {
            let m = self.microfacet().sample_visible(wo, u);
            reflect(wo, m)
        } else {
            warp::square_to_cosine_hemisphere(u)
        };
        if wi.z <= 0.0 {
            return None;
        }
        let (value, pdf) = self.eval_pdf(uv, wo, wi);
        BsdfSample::from_eval(wi, value, pdf)
    }
}

impl Coating {
    /// The coating for (distribution, α, η), computed on first use.
    fn shared(distribution: Distribution, alpha: f32, eta: f32) -> Arc<Coating> {
        let key = (distribution, alpha.to_bits(), eta.to_bits());
        let find = |cache: &[(CoatingKey, Arc<Coating>)]| {
            cache
                .iter()
                .find(|(k, _)| *k == key)
                .map(|(_, c)| c.clone())
        };
        let lock = || COATINGS.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(c) = find(&lock()) {
            return c;
        }
        // Computed without holding the lock (the computation runs on rayon's pool,
        // which may be running other constructions); the first one stored wins.
        let c = Arc::new(Coating::compute(distribution, alpha, eta));
        let mut cache = lock();
        if let Some(existing) = find(&cache) {
            return existing;
        }
        cache.push((key, c.clone()));
        c
    }

    fn compute(distribution: Distribution, alpha: f32, eta: f32) -> Coating {
        let mf = Microfacet::isotropic(alpha).with_distribution(distribution);
        let outer = gauss_legendre_01(32);
        let inner = gauss_legendre_01(128);
        // One row per tabulated cosine, in parallel (Beckmann's visible normals are
        // costly to sample); each row's sum has a fixed order, so the result does not
        // depend on the thread count.
        let rows: Vec<(f32, f64)> = (0..TABLE_SIZE)
            .into_par_iter()
            .map(|i| {
                let mu = (i as f32 / (TABLE_SIZE - 1) as f32).max(1e-6);
                let wo = Vec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
                let t = visible_normal_mean(&mf, wo, &outer, |m| {
                    // Refraction into the coating through the microfacet m.
                    let (f, cos_t) = fresnel_dielectric_cos(wo.dot(m), eta);
                    if f >= 1.0 {
                        return 0.0;
                    }
                    let wt = refract(wo, m, eta, cos_t);
                    if wt.z >= 0.0 {
                        return 0.0;
                    }
                    (1.0 - f) * mf.g1(wt, m)
                });
                let r = visible_normal_mean(&mf, wo, &inner, |m| {
                    // Reflection inside the coating (relative index 1/η).
                    let wr = reflect(wo, m);
                    if wr.z <= 0.0 {
                        return 0.0;
                    }
                    fresnel_dielectric_cos(wo.dot(m), 1.0 / eta).0 * mf.g1(wr, m)
                });
                (t as f32, r * mu as f64)
            })
            .collect();
        let mut transmittance = [0.0f32; TABLE_SIZE];
        for (t, row) in transmittance.iter_mut().zip(&rows) {
            *t = row.0;
        }
        let internal: f64 = rows.iter().map(|row| row.1).sum();
        Coating {
            transmittance,
            internal_reflectance: (2.0 * internal / TABLE_SIZE as f64) as f32,
        }
    }

    /// T(μ) by linear interpolation in the table.
    #[inline]
    fn transmittance(&self, mu: f32) -> f32 {
        let x = mu.clamp(0.0, 1.0) * (TABLE_SIZE - 1) as f32;
        let i = (x as usize).min(TABLE_SIZE - 2);
        let w = x - i as f32;
        (1.0 - w) * self.transmittance[i] + w * self.transmittance[i + 1]
    }
}

/// The mean of `f(m)` over the visible normals of `wo`: the tensor-product Gauss–Legendre
/// rule on the unit square pushed through the visible-normal sampling map.
fn visible_normal_mean(
    mf: &Microfacet,
    wo: Vec3,
    rule: &[(f64, f64)],
    f: impl Fn(Vec3) -> f32,
) -> f64 {
    let mut sum = 0.0f64;
    for &(x, wx) in rule {
        for &(y, wy) in rule {
            let m = mf.sample_visible(wo, Vec2::new(x as f32, y as f32));
            sum += wx * wy * f(m) as f64;
        }
    }
    sum
}

/// The n-point Gauss–Legendre rule on [0, 1]: (node, weight) pairs, weights summing to 1.
/// The roots of P_n by Newton's method from the usual cosine guesses.
fn gauss_legendre_01(n: usize) -> Vec<(f64, f64)> {
    use std::f64::consts::PI;
    let mut rule = Vec::with_capacity(n);
    for i in 0..n {
        let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            // P_n(x) and P_n'(x) by the three-term recurrence.
            let (mut p0, mut p1) = (1.0f64, x);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            let p = if n == 0 { 1.0 } else { p1 };
            dp = n as f64 * (x * p - p0) / (x * x - 1.0);
            let dx = p / dp;
            x -= dx;
            if dx.abs() < 1e-15 {
                break;
            }
        }
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        rule.push((0.5 * x + 0.5, 0.5 * w));
    }
    rule
}

#[cfg(test)]
mod tests {
    use super::*;

    fn constant(v: f32) -> Arc<Texture> {
        Arc::new(Texture::Constant(Vec3::splat(v)))
    }

    #[test]
    fn gauss_legendre_integrates_polynomials_exactly() {
        for n in [1, 2, 5, 32, 128] {
            let rule = gauss_legendre_01(n);
            let total: f64 = rule.iter().map(|(_, w)| w).sum();
            assert!((total - 1.0).abs() < 1e-12, "n={n}: {total}");
            // ∫ x^k dx over [0, 1] = 1/(k + 1), exact up to degree 2n − 1.
            for k in 0..(2 * n).min(40) {
                let q: f64 = rule.iter().map(|(x, w)| w * x.powi(k as i32)).sum();
                assert!((q - 1.0 / (k + 1) as f64).abs() < 1e-12, "n={n} k={k}: {q}");
            }
        }
    }

    /// A nearly smooth coating transmits 1 − F(μ), and seen from inside reflects the
    /// smooth interface's hemispherical reflectance (up to Mitsuba's 64-point mean).
    #[test]
    fn smooth_limit_matches_the_fresnel_equations() {
        let p = RoughPlastic::new(
            constant(0.5),
            constant(1.0),
            1.5,
            0.001f32.sqrt(),
            Distribution::Ggx,
            false,
        );
        for mu in [0.1f32, 0.3, 0.6, 1.0] {
            let t = p.transmittance(mu);
            let expected = 1.0 - super::super::fresnel::fresnel_dielectric(mu, 1.5);
            assert!((t - expected).abs() < 5e-3, "μ={mu}: {t} vs {expected}");
        }
        let fdr = super::super::fresnel::fresnel_diffuse_reflectance(1.0 / 1.5);
        let r = p.internal_reflectance();
        assert!((r - fdr).abs() < 0.02, "{r} vs {fdr}");
    }

    /// The tables are shared between equal coatings, transmittances lie in [0, 1] and
    /// grow with μ, and roughness changes them.
    #[test]
    fn tables_are_sane_and_shared() {
        let make = |r: f32| {
            RoughPlastic::new(
                constant(0.5),
                constant(1.0),
                1.49,
                r,
                Distribution::Beckmann,
                false,
            )
        };
        let (a, b) = (make(0.3), make(0.3));
        assert!(Arc::ptr_eq(&a.coating, &b.coating));
        let c = make(0.7);
        assert!(!Arc::ptr_eq(&a.coating, &c.coating));
        for p in [&a, &c] {
            let t = &p.coating.transmittance;
            assert!(t.iter().all(|&v| (0.0..=1.0).contains(&v)), "{t:?}");
            for w in t.windows(2).skip(1) {
                assert!(w[1] >= w[0] - 1e-4, "{t:?}");
            }
            assert!(p.internal_reflectance() > 0.3 && p.internal_reflectance() < 0.7);
        }
    }
}
