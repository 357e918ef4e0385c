//! Direct illumination: light reaching the camera after at most one bounce. At the first
//! hit, one light chosen by the light sampler is sampled with a shadow ray (next-event
//! estimation), and the BSDF is sampled once to find emitters and the environment; where
//! both strategies can find the same light they are combined by multiple importance
//! sampling (power heuristic). Rays that miss see the environment. This is the path
//! tracer limited to two vertices, with no Russian roulette.
//!
//! ```xml
//! <integrator type="direct">
//!     <scene>...</scene>
//!     <sampler type="independent" count="64"/>
//! </integrator>
//! ```

use super::PathTracer;
use crate::accel::RayStats;
use crate::math::Ray;
use crate::sampling::Sampler;
use crate::scene::Scene;
use glam::Vec3;

#[derive(Debug, Clone, Default)]
pub struct Direct;

/// The power heuristic with β = 2.
#[inline]
pub fn power_heuristic(pdf_a: f32, pdf_b: f32) -> f32 {
    let (a, b) = (pdf_a * pdf_a, pdf_b * pdf_b);
    if a + b == 0.0 {
        0.0
    } else if a.is_infinite() {
        1.0
    } else {
        a / (a + b)
    }
}

impl Direct {
    /// The path tracer this integrator is: paths of two vertices (the camera ray's hit
    /// and one light sample or BSDF sample from it, combined by MIS), no roulette.
    pub const PATH_TRACER: PathTracer = PathTracer {
        max_depth: 2,
        rr_depth: u32::MAX,
        clamp: None,
        hide_emitters: false,
    };

    #[inline]
    pub fn li(
        &self,
        scene: &Scene,
        ray: &Ray,
        sampler: &mut Sampler,
        stats: &mut RayStats,
    ) -> Vec3 {
        Self::PATH_TRACER.li(scene, ray, sampler, stats)
    }
}
