//! A smooth mirror. The course's form reflects with weight = `reflectance` (no Fresnel);
//! with a complex index of refraction (`eta` and `k` colours, or a named `material` from
//! [`fresnel::METALS`](super::fresnel::METALS)) the weight is reflectance × the exact
//! conductor Fresnel term. Reflects on both sides of the surface.
//!
//! ```xml
//! <bsdf type="conductor">
//!     <texture name="reflectance" type="constant" value="1,0.7,0.3"/>
//! </bsdf>
//! <bsdf type="conductor">
//!     <string name="material" value="Au"/>           <!-- or: -->
//!     <!-- <color name="eta" value="0.18,0.41,1.42"/> <color name="k" value="3.3,2.6,1.9"/> -->
//! </bsdf>
//! ```

use super::fresnel::fresnel_conductor;
use super::BsdfSample;
use crate::texture::{TexCoord, Texture};
use glam::{Vec2, Vec3};
use std::sync::Arc;

/// A conductor's complex index of refraction η + ik relative to the outside, per channel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ComplexIor {
    pub eta: Vec3,
    pub k: Vec3,
}

/// The Fresnel factor of an optional complex index (1 without one, the course's form).
#[inline]
pub fn conductor_fresnel(ior: Option<ComplexIor>, cos_i: f32) -> Vec3 {
    match ior {
        None => Vec3::ONE,
        Some(c) => fresnel_conductor(cos_i, c.eta, c.k),
    }
}

#[derive(Debug, Clone)]
pub struct Conductor {
    pub reflectance: Arc<Texture>,
    pub ior: Option<ComplexIor>,
}

impl Conductor {
    /// A delta lobe: zero for any given pair of directions.
    #[inline]
    pub fn eval(&self, _uv: TexCoord, _wo: Vec3, _wi: Vec3) -> Vec3 {
        Vec3::ZERO
    }

    #[inline]
    pub fn pdf(&self, _uv: TexCoord, _wo: Vec3, _wi: Vec3) -> f32 {
        0.0
    }

    #[inline]
    pub fn sample(&self, uv: TexCoord, wo: Vec3, _u_lobe: f32, _u: Vec2) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        Some(BsdfSample {
            wi: Vec3::new(-wo.x, -wo.y, wo.z),
            weight: self.reflectance.eval(uv) * conductor_fresnel(self.ior, wo.z),
            pdf: 1.0,
            delta: true,
        })
    }
}
