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
use crate::texture::Texture;
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
    pub fn eval(&self, _uv: Vec2, _wo: Vec3, _wi: Vec3) -> Vec3 {
        Vec3::ZERO
    }

    #[inline]
    pub fn pdf(&self, _uv: Vec2, _wo: Vec3, _wi: Vec3) -> f32 {
        0.0
    }

    pub fn sample(&self, uv: Vec2, wo: Vec3, u_lobe: f32, _u: Vec2) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        let (f, cos_t) = fresnel_dielectric_cos(wo.z, self.ior);
        if u_lobe < f {
            return Some(BsdfSample {
                wi: Vec3::new(-wo.x, -wo.y, wo.z),
                weight: self.reflectance.eval(uv),
                pdf: f,
                delta: true,
            });
        }
        // Relative index across the interface as seen from wo's side.
        let eta = if wo.z > 0.0 { self.ior } else { 1.0 / self.ior };
        let wi = Vec3::new(-wo.x / eta, -wo.y / eta, -cos_t.copysign(wo.z));
        Some(BsdfSample {
            wi,
            weight: self.transmittance.eval(uv) / (eta * eta),
            pdf: 1.0 - f,
            delta: true,
        })
    }
}
