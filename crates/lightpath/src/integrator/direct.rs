//! Direct illumination: light reaching the camera after at most one bounce. At the first
//! hit, one light chosen by the light sampler is sampled with a shadow ray (next-event
//! estimation), and the BSDF is sampled once to find the environment; where both
//! strategies can find the same light they are combined by multiple importance sampling
//! (power heuristic). Rays that miss see the environment.
//!
//! ```xml
//! <integrator type="direct">
//!     <scene>...</scene>
//!     <sampler type="independent" count="64"/>
//! </integrator>
//! ```

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
    pub fn li(
        &self,
        scene: &Scene,
        ray: &Ray,
        sampler: &mut Sampler,
        stats: &mut RayStats,
    ) -> Vec3 {
        let Some(si) = scene.intersect_with_stats(ray, stats) else {
            return scene.background(ray.direction.normalize());
        };
        let mut l = Vec3::ZERO;
        let Some(material) = scene.instances[si.instance as usize].material.as_deref() else {
            return l;
        };
        let wo = si.wo;

        // Next-event estimation: one light, one shadow ray.
        let u_light = sampler.next_1d();
        let u_point = sampler.next_2d();
        if let Some((index, pick)) = scene.light_sampler.sample(u_light) {
            let light = &scene.lights[index];
            if let Some(ls) = light.sample(si.p, u_point) {
                let f = material.eval(&si, wo, ls.wi);
                if f != Vec3::ZERO {
                    let shadow = if ls.distance.is_finite() {
                        si.spawn_ray_to(si.p + ls.wi * ls.distance)
                    } else {
                        si.spawn_ray(ls.wi)
                    };
                    if !scene.occluded(&shadow) {
                        let mis = if light.is_delta() {
                            1.0
                        } else {
                            power_heuristic(pick * ls.pdf, material.pdf(&si, wo, ls.wi))
                        };
                        l += f * ls.weight * mis / pick;
                    }
                }
            }
        }

        // BSDF sampling: finds the environment (area lights come with emission).
        if let Some(bs) = material.sample(&si, wo, sampler.next_1d(), sampler.next_2d()) {
            let next = si.spawn_ray(bs.wi);
            if scene.intersect_with_stats(&next, stats).is_none() {
                if let Some(env_index) = scene.environment {
                    let crate::light::Light::Environment(env) = &scene.lights[env_index] else {
                        unreachable!()
                    };
                    let pick = scene.light_sampler.probability(env_index);
                    let mis = if pick > 0.0 && !bs.delta {
                        power_heuristic(bs.pdf, pick * env.pdf(bs.wi))
                    } else {
                        1.0
                    };
                    l += bs.weight * env.eval(bs.wi) * mis;
                }
            }
        }
        l
    }
}
