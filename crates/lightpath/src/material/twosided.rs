//! Makes a one-sided BSDF two-sided: when wo is below the shading normal, both wo and wi
//! are mirrored to the upper side (z → −z) and the nested BSDF is used there.
//!
//! ```xml
//! <bsdf type="twosided">
//!     <bsdf type="plastic"><texture name="diffuseReflectance" type="constant" value="0.5"/></bsdf>
//! </bsdf>
//! ```

use super::{mirror_z, BsdfSample, Material};
use glam::{Vec2, Vec3};
use std::sync::Arc;

#[derive(Debug, Clone)]
pub struct TwoSided {
    pub inner: Arc<Material>,
}

impl TwoSided {
    pub fn eval(&self, uv: Vec2, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z < 0.0 {
            self.inner.eval_local(uv, mirror_z(wo), mirror_z(wi))
        } else {
            self.inner.eval_local(uv, wo, wi)
        }
    }

    pub fn pdf(&self, uv: Vec2, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z < 0.0 {
            self.inner.pdf_local(uv, mirror_z(wo), mirror_z(wi))
        } else {
            self.inner.pdf_local(uv, wo, wi)
        }
    }

    pub fn sample(&self, uv: Vec2, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if wo.z < 0.0 {
            let mut bs = self.inner.sample_local(uv, mirror_z(wo), u_lobe, u)?;
            bs.wi = mirror_z(bs.wi);
            Some(bs)
        } else {
            self.inner.sample_local(uv, wo, u_lobe, u)
        }
    }
}
