//! Makes a one-sided BSDF two-sided: when wo is below the shading normal, both wo and wi
//! are mirrored to the upper side (z → −z) and the nested BSDF is used there. With a
//! second nested BSDF (Mitsuba's `twosided` with two), that one serves the back side.
//!
//! ```xml
//! <bsdf type="twosided">
//!     <bsdf type="plastic"><texture name="diffuseReflectance" type="constant" value="0.5"/></bsdf>
//! </bsdf>
//!
//! <!-- Mitsuba 3: red in front, blue behind -->
//! <bsdf type="twosided">
//!     <bsdf type="diffuse"><rgb name="reflectance" value="0.8, 0.1, 0.1"/></bsdf>
//!     <bsdf type="diffuse"><rgb name="reflectance" value="0.1, 0.1, 0.8"/></bsdf>
//! </bsdf>
//! ```

use super::{mirror_z, BsdfSample, Material};
use crate::texture::TexCoord;
use glam::{Vec2, Vec3};
use std::sync::Arc;

#[derive(Debug, Clone)]
pub struct TwoSided {
    /// The front side's BSDF (and the back's, without `back`).
    pub inner: Arc<Material>,
    /// The back side's BSDF, if it differs.
    pub back: Option<Arc<Material>>,
}

impl TwoSided {
    /// The same BSDF on both sides.
    pub fn new(inner: Arc<Material>) -> TwoSided {
        TwoSided { inner, back: None }
    }

    /// The back side's BSDF.
    #[inline]
    fn back(&self) -> &Material {
        self.back.as_deref().unwrap_or(&self.inner)
    }

    pub fn eval(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z < 0.0 {
            self.back().eval_local(uv, mirror_z(wo), mirror_z(wi))
        } else {
            self.inner.eval_local(uv, wo, wi)
        }
    }

    pub fn pdf(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z < 0.0 {
            self.back().pdf_local(uv, mirror_z(wo), mirror_z(wi))
        } else {
            self.inner.pdf_local(uv, wo, wi)
        }
    }

    pub fn sample(&self, uv: TexCoord, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if wo.z < 0.0 {
            let mut bs = self.back().sample_local(uv, mirror_z(wo), u_lobe, u)?;
            bs.wi = mirror_z(bs.wi);
            Some(bs)
        } else {
            self.inner.sample_local(uv, wo, u_lobe, u)
        }
    }

    /// Whether both sides are delta BSDFs.
    pub fn is_delta(&self) -> bool {
        self.inner.is_delta() && self.back().is_delta()
    }
}
