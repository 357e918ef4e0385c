//! The course's principled BSDF: a Lambertian lobe plus a rough-conductor (GGX) lobe.
//! With α = max(1e-3, roughness²) and F = specular·Schlick(F0 = (1 − metallic)·0.08,
//! |cos θo|):
//!
//! - diffuse colour = (1 − F)(1 − metallic)·baseColor (Lambertian, wo and wi on the same
//!   side of the shading normal);
//! - specular colour = F + (1 − F)·metallic·baseColor, times the rough conductor's
//!   D·G1(wi)·G1(wo)/(4|cos θo|);
//!
//! eval is their sum. Sampling picks the diffuse lobe with probability
//! p_d = mean(diffuse)/(mean(diffuse) + mean(specular)) (1 when both are 0), else a
//! visible-normal reflection. The returned pdf is the mixture p_d·pdf_d + (1 − p_d)·pdf_s
//! and the weight is eval/pdf (the course divides the chosen lobe's weight by its choice
//! probability instead: the same expectation, usually a little more noise).
//! Because F depends on θo only, the BSDF is not reciprocal (as in the course).
//!
//! ```xml
//! <bsdf type="principled">
//!     <texture name="baseColor" type="constant" value="0.9,0.1,0.1"/>
//!     <texture name="roughness" type="constant" value="0.3"/>
//!     <texture name="metallic" type="constant" value="0"/>
//!     <texture name="specular" type="constant" value="1"/>
//! </bsdf>
//! ```

use super::fresnel::schlick;
use super::microfacet::{reflect, reflection, roughness_to_alpha, Microfacet};
use super::{mirror_to_upper, scalar, BsdfSample};
use crate::math::INV_PI;
use crate::sampling::warp;
use crate::texture::{TexCoord, Texture};
use glam::{Vec2, Vec3};
use std::sync::Arc;

#[derive(Debug, Clone)]
pub struct Principled {
    pub base_color: Arc<Texture>,
    pub roughness: Arc<Texture>,
    pub metallic: Arc<Texture>,
    pub specular: Arc<Texture>,
}

/// The two lobes at one point for one wo.
struct Lobes {
    diffuse: Vec3,
    specular: Vec3,
    ggx: Microfacet,
    /// Probability of sampling the diffuse lobe.
    p_diffuse: f32,
}

impl Principled {
    fn lobes(&self, uv: TexCoord, cos_o: f32) -> Lobes {
        let base = self.base_color.eval(uv);
        let metallic = scalar(&self.metallic, uv);
        let specular = scalar(&self.specular, uv);
        let f = specular * schlick((1.0 - metallic) * 0.08, cos_o.abs());
        let diffuse = (1.0 - f) * (1.0 - metallic) * base;
        let specular = Vec3::splat(f) + (1.0 - f) * metallic * base;
        let (md, ms) = (mean(diffuse), mean(specular));
        let p_diffuse = if md + ms > 0.0 { md / (md + ms) } else { 1.0 };
        Lobes {
            diffuse,
            specular,
            ggx: Microfacet::isotropic(roughness_to_alpha(scalar(&self.roughness, uv))),
            p_diffuse,
        }
    }

    /// f·|cos θi| and the mixture density, for directions already mirrored up.
    fn eval_pdf(&self, lobes: &Lobes, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let mut value = lobes.diffuse * (INV_PI * wi.z);
        let mut pdf = lobes.p_diffuse * INV_PI * wi.z;
        if let Some((_, v, p)) = reflection(&lobes.ggx, wo, wi) {
            value += lobes.specular * v;
            pdf += (1.0 - lobes.p_diffuse) * p;
        }
        (value, pdf)
    }

    pub fn eval(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z * wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        let (wo, wi) = mirror_to_upper(wo, wi);
        self.eval_pdf(&self.lobes(uv, wo.z), wo, wi).0
    }

    pub fn pdf(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z * wi.z <= 0.0 {
            return 0.0;
        }
        let (wo, wi) = mirror_to_upper(wo, wi);
        self.eval_pdf(&self.lobes(uv, wo.z), wo, wi).1
    }

    pub fn sample(&self, uv: TexCoord, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        let flip = wo.z < 0.0;
        let (wo, _) = mirror_to_upper(wo, wo);
        let lobes = self.lobes(uv, wo.z);
        let wi = if u_lobe < lobes.p_diffuse {
            warp::square_to_cosine_hemisphere(u)
        } else {
            reflect(wo, lobes.ggx.sample_visible(wo, u))
        };
        if wi.z <= 0.0 {
            return None;
        }
        let (value, pdf) = self.eval_pdf(&lobes, wo, wi);
        let wi = if flip {
            Vec3::new(wi.x, wi.y, -wi.z)
        } else {
            wi
        };
        BsdfSample::from_eval(wi, value, pdf)
    }
}

#[inline]
fn mean(v: Vec3) -> f32 {
    (v.x + v.y + v.z) / 3.0
}
