//! A rough conductor: GGX microfacets with separable Smith masking, sampled by visible
//! normals. The course's form (no Fresnel) is f·cos θi = R·D(m)·G1(wi)·G1(wo)/(4|cos θo|)
//! with sample weight R·G1(wi); with a complex index of refraction the Fresnel term
//! F(wo·m) multiplies both. α = max(1e-3, roughness²); `roughnessU`/`roughnessV` give
//! the roughness along the shading tangent (dp/du) and bitangent. Reflects on both sides
//! of the surface (the directions are mirrored to the upper side, as the course's
//! sign-symmetric helpers do).
//!
//! ```xml
//! <bsdf type="roughconductor">
//!     <texture name="reflectance" type="constant" value="0.9"/>
//!     <float name="roughness" value="0.2"/>            <!-- or a <texture name="roughness"> -->
//!     <!-- anisotropic: <float name="roughnessU" value="0.1"/> <float name="roughnessV" value="0.5"/> -->
//!     <!-- optional Fresnel: <string name="material" value="Cu"/> or eta/k colours -->
//! </bsdf>
//! ```

use super::conductor::{conductor_fresnel, ComplexIor};
use super::microfacet::{reflect, reflection, roughness_to_alpha, Distribution, Microfacet};
use super::{mirror_to_upper, scalar, valid_pdf, BsdfSample};
use crate::texture::{TexCoord, Texture};
use glam::{Vec2, Vec3};
use std::sync::Arc;

#[derive(Debug, Clone)]
pub struct RoughConductor {
    pub reflectance: Arc<Texture>,
    /// Roughness along the tangent (the first channel is used).
    pub roughness_u: Arc<Texture>,
    /// Roughness along the bitangent; the same texture as `roughness_u` when isotropic.
    pub roughness_v: Arc<Texture>,
    pub ior: Option<ComplexIor>,
    pub distribution: Distribution,
}

impl RoughConductor {
    /// An isotropic rough conductor.
    pub fn isotropic(reflectance: Arc<Texture>, roughness: Arc<Texture>) -> RoughConductor {
        RoughConductor {
            reflectance,
            roughness_u: roughness.clone(),
            roughness_v: roughness,
            ior: None,
            distribution: Distribution::Ggx,
        }
    }

    /// The microfacet distribution at `uv`.
    #[inline]
    pub fn ggx(&self, uv: TexCoord) -> Microfacet {
        let au = roughness_to_alpha(scalar(&self.roughness_u, uv));
        let av = if Arc::ptr_eq(&self.roughness_u, &self.roughness_v) {
            au
        } else {
            roughness_to_alpha(scalar(&self.roughness_v, uv))
        };
        Microfacet::new(au, av).with_distribution(self.distribution)
    }

    pub fn eval(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z * wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        let (wo, wi) = mirror_to_upper(wo, wi);
        match reflection(&self.ggx(uv), wo, wi) {
            Some((m, value, _)) => {
                self.reflectance.eval(uv) * conductor_fresnel(self.ior, wo.dot(m)) * value
            }
            None => Vec3::ZERO,
        }
    }

    pub fn pdf(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z * wi.z <= 0.0 {
            return 0.0;
        }
        let (wo, wi) = mirror_to_upper(wo, wi);
        reflection(&self.ggx(uv), wo, wi).map_or(0.0, |(_, _, pdf)| pdf)
    }

    pub fn sample(&self, uv: TexCoord, wo: Vec3, _u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        let flip = wo.z < 0.0;
        let (wo, _) = mirror_to_upper(wo, wo);
        let ggx = self.ggx(uv);
        let m = ggx.sample_visible(wo, u);
        let wi = reflect(wo, m);
        if wi.z <= 0.0 || m.z <= 0.0 {
            return None;
        }
        let pdf = ggx.d(m) * ggx.g1(wo, m) / (4.0 * wo.z);
        if !valid_pdf(pdf) {
            return None;
        }
        let weight =
            self.reflectance.eval(uv) * conductor_fresnel(self.ior, wo.dot(m)) * ggx.g1(wi, m);
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
