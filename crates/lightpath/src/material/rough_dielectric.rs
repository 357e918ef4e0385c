//! Rough glass (Walter et al. 2007, "Microfacet Models for Refraction through Rough
//! Surfaces") with GGX microfacets, separable Smith masking and visible-normal sampling.
//! A sampled microfacet m reflects with probability F(wo·m) and refracts otherwise.
//! With η = η(wi's side)/η(wo's side) (η = ior when entering) and the half vectors
//! m = normalize(wo + wi) (reflection) and normalize(wo + η·wi) (refraction, flipped up):
//!
//! - reflection: f·|cos θi| = R·F·D·G1(wo)·G1(wi)/(4|cos θo|), sample weight R·G1(wi);
//! - refraction: f·|cos θi| = T·(1 − F)·D·G1(wo)·G1(wi)·|wo·m|·|wi·m| /
//!   (|cos θo|·(wo·m + η wi·m)²), sample weight T·G1(wi)/η² (radiance transport, the
//!   1/η² of the smooth dielectric).
//!
//! An `ior` within 1e-4 of 1 is an index-matched boundary: light passes straight through
//! (wi = −wo, a delta with weight `transmittance`).
//!
//! ```xml
//! <bsdf type="roughdielectric">
//!     <float name="ior" value="1.5"/>
//!     <float name="roughness" value="0.3"/>
//!     <texture name="reflectance" type="constant" value="1"/>     <!-- optional -->
//!     <texture name="transmittance" type="constant" value="1"/>   <!-- optional -->
//! </bsdf>
//! ```

use super::fresnel::fresnel_dielectric_cos;
use super::microfacet::{reflect, refract, roughness_to_alpha, Distribution, Microfacet};
use super::{mirror_to_upper, scalar, valid_pdf, BsdfSample};
use crate::texture::{TexCoord, Texture};
use glam::{Vec2, Vec3};
use std::sync::Arc;

#[derive(Debug, Clone)]
pub struct RoughDielectric {
    pub ior: f32,
    pub roughness: Arc<Texture>,
    pub reflectance: Arc<Texture>,
    pub transmittance: Arc<Texture>,
    pub distribution: Distribution,
}

/// One scattering event in the canonical configuration (wo.z > 0).
struct Lobe {
    /// f·|cos θi| without the reflectance/transmittance colour.
    value: f32,
    pdf: f32,
    reflection: bool,
}

impl RoughDielectric {
    /// True when the boundary is index-matched and light passes straight through.
    #[inline]
    pub fn is_pass_through(&self) -> bool {
        (self.ior - 1.0).abs() < 1e-4
    }

    #[inline]
    fn ggx(&self, uv: TexCoord) -> Microfacet {
        Microfacet::isotropic(roughness_to_alpha(scalar(&self.roughness, uv)))
            .with_distribution(self.distribution)
    }

    /// Relative index across the boundary for wo on the side `wo_z` says.
    #[inline]
    fn eta(&self, wo_z: f32) -> f32 {
        if wo_z > 0.0 {
            self.ior
        } else {
            1.0 / self.ior
        }
    }

    /// Value and density for canonical directions (wo.z > 0) and relative index `eta`.
    fn lobe(ggx: &Microfacet, eta: f32, wo: Vec3, wi: Vec3) -> Option<Lobe> {
        if wo.z <= 0.0 || wi.z == 0.0 {
            return None;
        }
        let reflection = wi.z > 0.0;
        let m = if reflection { wo + wi } else { wo + eta * wi };
        let m = m.normalize_or_zero();
        let m = if m.z < 0.0 { -m } else { m };
        if m.z <= 0.0 {
            return None;
        }
        let (wo_m, wi_m) = (wo.dot(m), wi.dot(m));
        // wo must see the front of m; wi the front (reflection) or the back (refraction).
        if wo_m <= 0.0 || (reflection && wi_m <= 0.0) || (!reflection && wi_m >= 0.0) {
            return None;
        }
        let (f, _) = fresnel_dielectric_cos(wo_m, eta);
        let d = ggx.d(m);
        let g1o = ggx.g1(wo, m);
        // The masking of wi is evaluated on wi's own side (G1 is even in the direction).
        let g1i = ggx.g1(if reflection { wi } else { -wi }, m);
        let pdf_m = g1o * wo_m * d / wo.z;
        let (value, pdf) = if reflection {
            let jacobian = 1.0 / (4.0 * wo_m);
            (f * d * g1o * g1i / (4.0 * wo.z), f * pdf_m * jacobian)
        } else {
            let denom = wo_m + eta * wi_m;
            let denom2 = denom * denom;
            let jacobian = eta * eta * wi_m.abs() / denom2;
            (
                (1.0 - f) * d * g1o * g1i * wo_m * wi_m.abs() / (wo.z * denom2),
                (1.0 - f) * pdf_m * jacobian,
            )
        };
        if !valid_pdf(pdf) {
            return None;
        }
        Some(Lobe {
            value,
            pdf,
            reflection,
        })
    }

    pub fn eval(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> Vec3 {
        if self.is_pass_through() || wo.z == 0.0 {
            return Vec3::ZERO;
        }
        let eta = self.eta(wo.z);
        let (wo, wi) = mirror_to_upper(wo, wi);
        match Self::lobe(&self.ggx(uv), eta, wo, wi) {
            Some(l) if l.reflection => self.reflectance.eval(uv) * l.value,
            Some(l) => self.transmittance.eval(uv) * l.value,
            None => Vec3::ZERO,
        }
    }

    pub fn pdf(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> f32 {
        if self.is_pass_through() || wo.z == 0.0 {
            return 0.0;
        }
        let eta = self.eta(wo.z);
        let (wo, wi) = mirror_to_upper(wo, wi);
        Self::lobe(&self.ggx(uv), eta, wo, wi).map_or(0.0, |l| l.pdf)
    }

    pub fn sample(&self, uv: TexCoord, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        if self.is_pass_through() {
            return Some(BsdfSample {
                wi: -wo,
                weight: self.transmittance.eval(uv),
                pdf: 1.0,
                delta: true,
            });
        }
        let flip = wo.z < 0.0;
        let eta = self.eta(wo.z);
        let (wo, _) = mirror_to_upper(wo, wo);
        let ggx = self.ggx(uv);
        let m = ggx.sample_visible(wo, u);
        let wo_m = wo.dot(m);
        if m.z <= 0.0 || wo_m <= 0.0 {
            return None;
        }
        let (f, cos_t) = fresnel_dielectric_cos(wo_m, eta);
        let pdf_m = ggx.g1(wo, m) * wo_m * ggx.d(m) / wo.z;
        let (wi, weight, pdf) = if u_lobe < f {
            let wi = reflect(wo, m);
            if wi.z <= 0.0 {
                return None;
            }
            let weight = self.reflectance.eval(uv) * ggx.g1(wi, m);
            (wi, weight, f * pdf_m / (4.0 * wo_m))
        } else {
            let wi = refract(wo, m, eta, cos_t);
            if wi.z >= 0.0 {
                return None;
            }
            let wi_m = wi.dot(m);
            let denom = wo_m + eta * wi_m;
            let jacobian = eta * eta * wi_m.abs() / (denom * denom);
            let weight = self.transmittance.eval(uv) * ggx.g1(-wi, m) / (eta * eta);
            (wi, weight, (1.0 - f) * pdf_m * jacobian)
        };
        if !valid_pdf(pdf) {
            return None;
        }
        Some(BsdfSample {
            wi: if flip {
                Vec3::new(wi.x, wi.y, -wi.z)
            } else {
                wi
            },
            weight,
            pdf,
            delta: false,
        })
    }
}
