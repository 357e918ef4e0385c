//! Smooth glass, the course's form: entering when cos θo > 0 (η = ior), else leaving
//! (η = 1/ior). F = the exact dielectric Fresnel term of cos θo (1 under total internal
//! reflection); with probability F the mirror direction with weight = `reflectance`,
//! otherwise the refracted direction with weight = `transmittance`/η² (radiance
//! transport). Both lobes are deltas.
//!
//! ```xml
//! <bsdf type="dielectric">
//!     <float name="ior" value="1.5"/>                  <!-- or a constant <texture name="ior"> -->
//!     <texture name="reflectance" type="constant" value="1"/>
//!     <texture name="transmittance" type="constant" value="1"/>
//! </bsdf>
//! ```

use super::fresnel::fresnel_dielectric_cos;
use super::BsdfSample;
use crate::texture::{TexCoord, Texture};
use glam::{Vec2, Vec3};
use std::sync::Arc;

#[derive(Debug, Clone)]
pub struct Dielectric {
    /// Interior index over exterior index.
    pub ior: f32,
    pub reflectance: Arc<Texture>,
    pub transmittance: Arc<Texture>,
}

impl Dielectric {
    #[inline]
    pub fn eval(&self, _uv: TexCoord, _wo: Vec3, _wi: Vec3) -> Vec3 {
        Vec3::ZERO
    }

    #[inline]
    pub fn pdf(&self, _uv: TexCoord, _wo: Vec3, _wi: Vec3) -> f32 {
        0.0
    }

    pub fn sample(&self, uv: TexCoord, wo: Vec3, u_lobe: f32, _u: Vec2) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        let (f, cos_t) = fresnel_dielectric_cos(wo.z, self.ior);
        // Choose reflection or refraction in proportion to what each carries (Fresnel
        // times the tint's mean), not by Fresnel alone: a black transmittance never
        // wastes a sample on refraction. Unbiased either way.
        let reflectance = self.reflectance.eval(uv);
        let transmittance = self.transmittance.eval(uv);
        let (r_mean, t_mean) = (
            reflectance.element_sum() / 3.0,
            transmittance.element_sum() / 3.0,
        );
        let (pr, pt) = (f * r_mean, (1.0 - f) * t_mean);
        let p_reflect = if pr + pt > 0.0 { pr / (pr + pt) } else { f };
        if u_lobe < p_reflect {
            return Some(BsdfSample {
                wi: Vec3::new(-wo.x, -wo.y, wo.z),
                weight: reflectance * (f / p_reflect),
                pdf: p_reflect,
                delta: true,
            });
        }
        // Relative index across the interface as seen from wo's side.
        let eta = if wo.z > 0.0 { self.ior } else { 1.0 / self.ior };
        let wi = Vec3::new(-wo.x / eta, -wo.y / eta, -cos_t.copysign(wo.z));
        let p_refract = 1.0 - p_reflect;
        if p_refract <= 0.0 {
            return None;
        }
        Some(BsdfSample {
            wi,
            weight: transmittance * ((1.0 - f) / p_refract) / (eta * eta),
            pdf: p_refract,
            delta: true,
        })
    }
}
