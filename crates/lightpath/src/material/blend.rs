//! A linear blend of two BSDFs: f = (1 − w)·f₀ + w·f₁ with `weight` w (a texture's first
//! channel, clamped to [0, 1]; 0 = the first child). The pdf is the same mixture.
//! Sampling picks a child with `u_lobe` (remapped to [0, 1) for the child's own lobe
//! choice); a delta sample keeps the child's weight (the choice probability cancels) and
//! scales its probability, a non-delta sample gets weight = eval/pdf of the mixture.
//!
//! ```xml
//! <bsdf type="blend">
//!     <float name="weight" value="0.3"/>          <!-- or a <texture name="weight"> -->
//!     <bsdf type="diffuse"/>
//!     <bsdf type="roughconductor"><float name="roughness" value="0.2"/></bsdf>
//! </bsdf>
//! ```

use super::{scalar, valid_pdf, BsdfSample, Material};
use crate::texture::{TexCoord, Texture};
use glam::{Vec2, Vec3};
use std::sync::Arc;

#[derive(Debug, Clone)]
pub struct Blend {
    pub weight: Arc<Texture>,
    pub first: Arc<Material>,
    pub second: Arc<Material>,
}

/// The largest f32 below 1.
const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

impl Blend {
    #[inline]
    fn w(&self, uv: TexCoord) -> f32 {
        let w = scalar(&self.weight, uv);
        if w.is_nan() {
            0.0
        } else {
            w.clamp(0.0, 1.0)
        }
    }

    pub fn eval(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> Vec3 {
        let w = self.w(uv);
        let mut f = Vec3::ZERO;
        if w < 1.0 {
            f += (1.0 - w) * self.first.eval_local(uv, wo, wi);
        }
        if w > 0.0 {
            f += w * self.second.eval_local(uv, wo, wi);
        }
        f
    }

    pub fn pdf(&self, uv: TexCoord, wo: Vec3, wi: Vec3) -> f32 {
        let w = self.w(uv);
        let mut p = 0.0;
        if w < 1.0 {
            p += (1.0 - w) * self.first.pdf_local(uv, wo, wi);
        }
        if w > 0.0 {
            p += w * self.second.pdf_local(uv, wo, wi);
        }
        p
    }

    pub fn sample(&self, uv: TexCoord, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        let w = self.w(uv);
        let (child, prob, u_child) = if u_lobe < 1.0 - w {
            (&self.first, 1.0 - w, u_lobe / (1.0 - w))
        } else {
            (&self.second, w, (u_lobe - (1.0 - w)) / w)
        };
        let mut bs = child.sample_local(uv, wo, u_child.min(ONE_MINUS_EPSILON), u)?;
        if bs.delta {
            bs.pdf *= prob;
            return Some(bs);
        }
        let pdf = self.pdf(uv, wo, bs.wi);
        if !valid_pdf(pdf) {
            return None;
        }
        bs.weight = self.eval(uv, wo, bs.wi) / pdf;
        bs.pdf = pdf;
        Some(bs)
    }
}
