//! A one-sided wrapper: the wrapped BSDF reflects light only on the side its shading
//! normal faces and is black from behind, as every reflective BSDF of Mitsuba 3 is (only
//! its `twosided` adapter makes one reflect on both sides). The Mitsuba dialect wraps its
//! `diffuse`, `conductor` and `roughconductor` in it, so a Mitsuba scene renders as
//! Mitsuba renders it; the lightwave dialect's BSDFs keep the course's two-sided
//! behaviour.
//!
//! ```xml
//! <scene version="3.0.0">
//!     <shape type="rectangle"><bsdf type="diffuse"/></shape>  <!-- black from behind -->
//! </scene>
//! ```

use super::{BsdfSample, Material};
use crate::texture::TexCoord;
use glam::{Vec2, Vec3};
use std::sync::Arc;

#[derive(Debug, Clone)]
pub struct OneSided {
    pub inner: Arc<Material>,
}

impl OneSided {
    pub fn eval(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> Vec3 {
        Self::eval_with(wo, wi, || self.inner.eval_local(uv, wo, wi))
    }

    pub fn pdf(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> f32 {
        Self::pdf_with(wo, wi, || self.inner.pdf_local(uv, wo, wi))
    }

    pub fn sample(&self, uv: TexCoord, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        Self::sample_with(wo, || self.inner.sample_local(uv, wo, u_lobe, u))
    }

    /// [`OneSided::eval`] around the inner material's evaluation `inner` (so a caller
    /// that knows the inner material's kind can inline it).
    #[inline(always)]
    pub(crate) fn eval_with(wo: Vec3, wi: Vec3, inner: impl FnOnce() -> Vec3) -> Vec3 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        inner()
    }

    /// [`OneSided::pdf`] around the inner material's density `inner`.
    #[inline(always)]
    pub(crate) fn pdf_with(wo: Vec3, wi: Vec3, inner: impl FnOnce() -> f32) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        inner()
    }

    /// [`OneSided::sample`] around the inner material's sample `inner`.
    #[inline(always)]
    pub(crate) fn sample_with(
        wo: Vec3,
        inner: impl FnOnce() -> Option<BsdfSample>,
    ) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        inner().filter(|bs| bs.wi.z > 0.0)
    }
}
