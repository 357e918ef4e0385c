//! Integrators: what a camera ray's sample value is.

mod ambient_occlusion;
mod aov;
mod camera_direction;
mod direct;
// The lanes run only in the AVX-512 packet render tile (their tests run everywhere).
#[cfg_attr(not(all(target_arch = "x86_64", lightpath_avx512)), allow(dead_code))]
mod path_lanes;
mod path_tracer;

pub use ambient_occlusion::AmbientOcclusion;
pub use aov::{first_hit, Aov, AovLayer, AovVariable, FirstHit};
pub use camera_direction::CameraDirection;
pub use direct::{power_heuristic, Direct};
pub(crate) use path_lanes::LaneInstances;
#[cfg(target_arch = "x86_64")]
pub(crate) use path_lanes::{DiffuseLanes, LaneResult};
pub use path_tracer::{PathState, PathTracer, ShadowQuery};

use crate::accel::RayStats;
use crate::math::Ray;
use crate::sampling::Sampler;
use crate::scene::Scene;
use glam::Vec3;

/// An integrator of any kind.
#[derive(Debug, Clone)]
pub enum Integrator {
    Aov(Aov),
    AmbientOcclusion(AmbientOcclusion),
    CameraDirection(CameraDirection),
    Direct(Direct),
    PathTracer(PathTracer),
}

impl Integrator {
    /// The value carried by a camera ray.
    #[inline(always)]
    pub fn li(
        &self,
        scene: &Scene,
        ray: &Ray,
        sampler: &mut Sampler,
        stats: &mut RayStats,
    ) -> Vec3 {
        match self {
            Integrator::Aov(i) => i.li(scene, ray, stats),
            Integrator::AmbientOcclusion(i) => i.li(scene, ray, sampler, stats),
            Integrator::CameraDirection(i) => i.li(ray, sampler),
            Integrator::Direct(i) => i.li(scene, ray, sampler, stats),
            Integrator::PathTracer(i) => i.li(scene, ray, sampler, stats),
        }
    }

    /// The path tracer this integrator runs, if it is one (the direct integrator is a
    /// path tracer of depth 2): renderers may advance its paths in batches
    /// ([`PathTracer::step`]) instead of calling [`Integrator::li`].
    pub fn path_tracer(&self) -> Option<&PathTracer> {
        match self {
            Integrator::PathTracer(p) => Some(p),
            Integrator::Direct(_) => Some(&Direct::PATH_TRACER),
            _ => None,
        }
    }

    /// Whether a camera ray's weight ([`crate::camera::Camera::sample_ray`]) scales the
    /// value: for the radiometric integrators, not for the AOVs and camera directions.
    #[inline(always)]
    pub fn weighs_camera_rays(&self) -> bool {
        matches!(
            self,
            Integrator::AmbientOcclusion(_) | Integrator::Direct(_) | Integrator::PathTracer(_)
        )
    }

    /// The value of a pixel sample where the camera produced no ray.
    pub fn no_ray_value(&self) -> Vec3 {
        Vec3::ZERO
    }
}
