//! Ambient occlusion: the cosine-weighted fraction of the hemisphere above each hit that
//! is open within `distance`, the "clay render" look; rays that leave the scene see a
//! white sky. An unbiased estimate of (1/π) ∫ V(ω) cos θ dω.
//!
//! ```xml
//! <integrator type="ao" distance="2">
//!     <scene>...</scene>
//!     <sampler type="independent" count="64"/>
//! </integrator>
//! ```

use crate::accel::RayStats;
use crate::math::{Frame, Ray};
use crate::sampling::{warp, Sampler};
use crate::scene::Scene;
use glam::Vec3;

#[derive(Debug, Clone)]
pub struct AmbientOcclusion {
    /// Occluders farther than this (in render-space units) do not count.
    pub distance: f32,
}

impl AmbientOcclusion {
    pub fn li(
        &self,
        scene: &Scene,
        ray: &Ray,
        sampler: &mut Sampler,
        stats: &mut RayStats,
    ) -> Vec3 {
        let Some(si) = scene.intersect_with_stats(ray, stats) else {
            return Vec3::ONE;
        };
        // The hemisphere on the side the ray came from.
        let n = if si.n.dot(si.wo) < 0.0 { -si.n } else { si.n };
        let ns = if si.shading_n.dot(n) < 0.0 {
            -si.shading_n
        } else {
            si.shading_n
        };
        let wi =
            Frame::from_normal(ns).to_world(warp::square_to_cosine_hemisphere(sampler.next_2d()));
        if wi.dot(n) <= 0.0 {
            return Vec3::ZERO;
        }
        let mut shadow = si.spawn_ray(wi);
        shadow.t_max = self.distance;
        if scene.occluded_with_stats(&shadow, stats) {
            Vec3::ZERO
        } else {
            Vec3::ONE
        }
    }
}
