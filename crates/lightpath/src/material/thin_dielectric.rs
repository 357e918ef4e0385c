//! A thin dielectric slab (a window pane): light either reflects, with the slab's
//! total reflectance R' = R + T²R/(1 − R²) = 2R/(1 + R) summed over its internal
//! bounces (R = the Fresnel term of cos θo, T = 1 − R), or passes straight through
//! (wi = −wo) with no net refraction and no η² scaling. Both lobes are deltas; the
//! weights are `reflectance` and `transmittance`.
//!
//! ```xml
//! <bsdf type="thindielectric">
//!     <float name="ior" value="1.5"/>
//!     <texture name="transmittance" type="constant" value="0.9"/>
//! </bsdf>
//! ```

use super::fresnel::fresnel_dielectric;
use super::BsdfSample;
use crate::texture::{TexCoord, Texture};
use glam::{Vec2, Vec3};
use std::sync::Arc;

#[derive(Debug, Clone)]
pub struct ThinDielectric {
    pub ior: f32,
    pub reflectance: Arc<Texture>,
    pub transmittance: Arc<Texture>,
}

impl ThinDielectric {
    /// The slab's reflectance for |cos θo| = `cos_o`.
    #[inline]
    pub fn slab_reflectance(&self, cos_o: f32) -> f32 {
        let r = fresnel_dielectric(cos_o.abs(), self.ior);
        if r < 1.0 {
            let t = 1.0 - r;
            r + t * t * r / (1.0 - r * r)
        } else {
            1.0
        }
    }

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
        let r = self.slab_reflectance(wo.z);
        Some(if u_lobe < r {
            BsdfSample {
                wi: Vec3::new(-wo.x, -wo.y, wo.z),
                weight: self.reflectance.eval(uv),
                pdf: r,
                delta: true,
            }
        } else {
            BsdfSample {
                wi: -wo,
                weight: self.transmittance.eval(uv),
                pdf: 1.0 - r,
                delta: true,
            }
        })
    }
}
