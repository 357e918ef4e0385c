//! Materials: they turn a surface interaction into a BSDF, evaluated and sampled in the
//! local shading frame (normal = +z). `eval` returns f·|cos θi|; `sample` returns a
//! direction with its weight f·|cos θi|/pdf.
//!
//! ```xml
//! <bsdf type="diffuse">
//!     <texture name="albedo" type="constant" value="0.8"/>
//! </bsdf>
//! ```

mod diffuse;

pub use diffuse::Diffuse;

use crate::geometry::SurfaceInteraction;
use crate::math::Frame;
use glam::{Vec2, Vec3};

/// A sampled direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BsdfSample {
    /// Incident direction in render space.
    pub wi: Vec3,
    /// f·|cos θi| / pdf.
    pub weight: Vec3,
    /// Solid-angle density of `wi` (for a delta lobe, the discrete probability of
    /// choosing it).
    pub pdf: f32,
    /// True when `wi` comes from a delta (specular) lobe: `eval`/`pdf` cannot find it
    /// and MIS must not weight it.
    pub delta: bool,
}

/// A material of any kind.
#[derive(Debug, Clone)]
pub enum Material {
    Diffuse(Diffuse),
}

/// The shading frame of an interaction.
#[inline]
pub fn shading_frame(si: &SurfaceInteraction) -> Frame {
    Frame::from_normal(si.shading_n)
}

impl Material {
    /// f(wo, wi)·|cos θi| for render-space directions.
    pub fn eval(&self, si: &SurfaceInteraction, wo: Vec3, wi: Vec3) -> Vec3 {
        let frame = shading_frame(si);
        let (wo, wi) = (frame.to_local(wo), frame.to_local(wi));
        match self {
            Material::Diffuse(m) => m.eval(si.uv, wo, wi),
        }
    }

    /// Density with which `sample` picks `wi`.
    pub fn pdf(&self, si: &SurfaceInteraction, wo: Vec3, wi: Vec3) -> f32 {
        let frame = shading_frame(si);
        let (wo, wi) = (frame.to_local(wo), frame.to_local(wi));
        match self {
            Material::Diffuse(m) => m.pdf(wo, wi),
        }
    }

    /// Samples an incident direction: `u_lobe` picks a lobe, `u` the direction in it.
    pub fn sample(
        &self,
        si: &SurfaceInteraction,
        wo: Vec3,
        u_lobe: f32,
        u: Vec2,
    ) -> Option<BsdfSample> {
        let _ = u_lobe;
        let frame = shading_frame(si);
        let wo_local = frame.to_local(wo);
        let (wi, weight, pdf) = match self {
            Material::Diffuse(m) => m.sample(si.uv, wo_local, u)?,
        };
        Some(BsdfSample {
            wi: frame.to_world(wi),
            weight,
            pdf,
            delta: false,
        })
    }

    /// True when every lobe is a delta (a mirror or smooth glass): next-event estimation
    /// is useless there.
    pub fn is_delta(&self) -> bool {
        match self {
            Material::Diffuse(_) => false,
        }
    }
}
