//! Unidirectional path tracing: at every vertex one light is sampled with a shadow ray
//! (next-event estimation) and the BSDF is sampled to continue the path; emitters and the
//! environment found by either strategy are combined by multiple importance sampling
//! (power heuristic), so no light is counted twice. Paths end at `depth` vertices (the
//! course's meaning: depth 1 sees only emitters and the environment, depth 2 is direct
//! lighting), or earlier by Russian roulette, which keeps the estimate unbiased.
//!
//! ```xml
//! <integrator type="pathtracer" depth="8">
//!     <scene>...</scene>
//!     <sampler type="independent" count="64"/>
//! </integrator>
//! ```
//!
//! `depth="-1"` removes the limit (Russian roulette alone ends paths).

use super::power_heuristic;
use crate::accel::RayStats;
use crate::geometry::SurfaceInteraction;
use crate::light::Light;
use crate::material::Material;
use crate::math::Ray;
use crate::sampling::Sampler;
use crate::scene::Scene;
use glam::{Vec2, Vec3, Vec3A};

#[derive(Debug, Clone)]
pub struct PathTracer {
    /// Maximum number of path vertices (surface hits); `u32::MAX` for no limit.
    pub max_depth: u32,
    /// Russian roulette starts after this many vertices (`u32::MAX`: never).
    pub rr_depth: u32,
    /// Each sample's contribution is clamped to this luminance-free maximum per channel
    /// (biased; off by default).
    pub clamp: Option<f32>,
    /// Emitters and the environment seen directly by camera rays are black (Mitsuba's
    /// `hide_emitters`); their light still reaches the scene, and is seen in reflections
    /// and through refractions.
    pub hide_emitters: bool,
}

impl Default for PathTracer {
    fn default() -> Self {
        PathTracer {
            max_depth: 2,
            rr_depth: 4,
            clamp: None,
            hide_emitters: false,
        }
    }
}

/// What the previous vertex knows about how the path continued from it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Previous {
    pub(crate) p: Vec3,
    pub(crate) bsdf_pdf: f32,
    pub(crate) delta: bool,
}

/// A path between two of its vertices: what [`PathTracer::li`] carries around its loop,
/// held outside it so that a renderer can advance many paths together and trace their
/// rays in batches ([`PathTracer::step`]).
#[derive(Debug, Clone, Copy)]
pub struct PathState {
    /// The ray to trace next.
    pub ray: Ray,
    /// Radiance so far and throughput, in 4-lane arithmetic (the same operations per
    /// channel as with `Vec3`, bit for bit).
    pub(crate) l: Vec3A,
    pub(crate) beta: Vec3A,
    pub(crate) prev: Option<Previous>,
    pub(crate) depth: u32,
}

impl PathState {
    /// A path about to trace its camera ray.
    pub fn new(camera_ray: &Ray) -> Self {
        PathState {
            ray: *camera_ray,
            l: Vec3A::ZERO,
            beta: Vec3A::ONE,
            prev: None,
            depth: 1,
        }
    }
}

/// A vertex's shadow ray (next-event estimation) and the radiance it adds to its path
/// when nothing blocks it.
#[derive(Debug, Clone, Copy)]
pub struct ShadowQuery {
    pub ray: Ray,
    pub(crate) contribution: Vec3A,
}

impl ShadowQuery {
    /// Adds the light to the path: call when the shadow ray is unoccluded, before the
    /// path's next [`PathTracer::step`].
    #[inline(always)]
    pub fn add_to(&self, path: &mut PathState) {
        ShadowQuery::add_light(path, self.contribution);
    }

    /// [`ShadowQuery::add_to`] for a query's `contribution` kept apart from its ray.
    #[inline(always)]
    pub(crate) fn add_light(path: &mut PathState, contribution: Vec3A) {
        path.l += contribution;
    }
}

/// The sample numbers a path vertex draws, in the order [`PathTracer::step`] draws
/// them: the light and its primitive (one 2D sample: stratified together, and one
/// dimension pair of a low-discrepancy sampler instead of two), the point on the light,
/// then the BSDF lobe and direction.
#[derive(Debug, Clone, Copy)]
pub(crate) struct VertexSamples {
    pub u_light: f32,
    pub u_prim: f32,
    pub u_point: Vec2,
    pub u_lobe: f32,
    pub u_dir: Vec2,
}

impl VertexSamples {
    #[inline(always)]
    pub(crate) fn draw(sampler: &mut Sampler) -> Self {
        if let Sampler::Independent(s) = sampler {
            // The same seven numbers, drawn side by side.
            let [u_light, u_prim, px, py, u_lobe, dx, dy] = s.next_1ds();
            return VertexSamples {
                u_light,
                u_prim,
                u_point: Vec2::new(px, py),
                u_lobe,
                u_dir: Vec2::new(dx, dy),
            };
        }
        let Vec2 {
            x: u_light,
            y: u_prim,
        } = sampler.next_2d();
        let u_point = sampler.next_2d();
        let u_lobe = sampler.next_1d();
        let u_dir = sampler.next_2d();
        VertexSamples {
            u_light,
            u_prim,
            u_point,
            u_lobe,
            u_dir,
        }
    }
}

impl PathTracer {
    #[inline(always)]
    pub fn li(
        &self,
        scene: &Scene,
        camera_ray: &Ray,
        sampler: &mut Sampler,
        stats: &mut RayStats,
    ) -> Vec3 {
        let mut path = PathState::new(camera_ray);
        loop {
            let hit = scene.intersect_with_stats(&path.ray, stats);
            let mut shadow = None;
            let more = self.step(scene, &mut path, hit, sampler, &mut shadow);
            if let Some(q) = shadow {
                if !scene.occluded_with_stats(&q.ray, stats) {
                    q.add_to(&mut path);
                }
            }
            if !more {
                return self.finish(&path);
            }
        }
    }

    /// Advances `path` past the hit (or miss) of its ray: adds what the hit emits, sets
    /// `shadow` to the vertex's shadow ray (whose light the caller adds, when the ray is
    /// unoccluded, before the next step) and samples the next ray into `path.ray`.
    /// Returns whether the path goes on; once it does not, [`PathTracer::finish`] gives
    /// its value. Draws the same samples in the same order as one turn of
    /// [`PathTracer::li`]'s loop, which is this function between ray queries.
    #[inline(always)]
    pub fn step(
        &self,
        scene: &Scene,
        path: &mut PathState,
        hit: Option<SurfaceInteraction>,
        sampler: &mut Sampler,
        shadow: &mut Option<ShadowQuery>,
    ) -> bool {
        let Some(si) = hit else {
            self.miss(scene, path);
            return false;
        };
        let Some(material) = self.arrive(scene, path, &si) else {
            return false;
        };
        let u = VertexSamples::draw(sampler);
        self.scatter(scene, path, &si, material, &u, sampler, shadow)
    }

    /// The first part of [`PathTracer::step`] for a ray that left the scene: adds the
    /// environment's light. The path ends.
    #[inline(always)]
    pub(crate) fn miss(&self, scene: &Scene, path: &mut PathState) {
        // Without an environment, a ray that leaves the scene brings no light: nothing
        // to normalise or look up.
        if scene.environment.is_none() || (self.hide_emitters && path.prev.is_none()) {
            return;
        }
        let dir = path.ray.direction.normalize();
        let le = scene.background(dir);
        if le != Vec3::ZERO {
            path.l +=
                path.beta * Vec3A::from(le) * self.environment_mis(scene, path.prev.as_ref(), dir);
        }
    }

    /// The first part of [`PathTracer::step`] at a hit: adds what the hit emits, and
    /// gives the material that scatters the path on, or `None` where the path ends
    /// (its depth reached, or a surface that absorbs all light).
    #[inline(always)]
    pub(crate) fn arrive<'s>(
        &self,
        scene: &'s Scene,
        path: &mut PathState,
        si: &SurfaceInteraction,
    ) -> Option<&'s Material> {
        // The unit ray direction (the scene sets `wo` to exactly its negation).
        let dir = -si.wo;
        let inst = &scene.instances[si.instance as usize];
        if inst.emission.is_some() && !(self.hide_emitters && path.prev.is_none()) {
            let le = scene.emitted(si, si.wo);
            if le != Vec3::ZERO {
                let mis = match &path.prev {
                    Some(pv) if !pv.delta => {
                        power_heuristic(pv.bsdf_pdf, scene.emitter_pdf(pv.p, si, dir))
                    }
                    _ => 1.0,
                };
                path.l += path.beta * Vec3A::from(le) * mis;
            }
        }
        if path.depth >= self.max_depth {
            return None;
        }
        scene.material(si)
    }

    /// The rest of [`PathTracer::step`] after [`PathTracer::arrive`]: next-event
    /// estimation into `shadow` and the next ray by BSDF sampling, from the vertex's
    /// sample numbers `u` (Russian roulette draws its own number from `sampler`).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub(crate) fn scatter(
        &self,
        scene: &Scene,
        path: &mut PathState,
        si: &SurfaceInteraction,
        material: &Material,
        u: &VertexSamples,
        sampler: &mut Sampler,
        shadow: &mut Option<ShadowQuery>,
    ) -> bool {
        let beta = path.beta;
        // The shading frame and local wo, shared by the light and BSDF samples.
        let bsdf = material.bsdf(si, si.wo);

        // Next-event estimation: one light, one shadow ray.
        if !material.is_delta() {
            if let Some((index, pick)) = scene.light_sampler.sample(u.u_light) {
                let light = &scene.lights[index];
                if let Some(ls) = light.sample(si.p, u.u_prim, u.u_point) {
                    let wi_local = bsdf.to_local(ls.wi);
                    let f = bsdf.eval_local(wi_local);
                    if f != Vec3::ZERO && ls.weight != Vec3::ZERO {
                        let ray = if ls.distance.is_finite() {
                            si.spawn_ray_to(si.p + ls.wi * ls.distance)
                        } else {
                            si.spawn_ray(ls.wi)
                        };
                        let mis = if !light.reachable_by_rays() {
                            1.0
                        } else {
                            power_heuristic(pick * ls.pdf, bsdf.pdf_local(wi_local))
                        };
                        *shadow = Some(ShadowQuery {
                            ray,
                            contribution: beta
                                * Vec3A::from(f)
                                * Vec3A::from(ls.weight)
                                * (mis / pick),
                        });
                    }
                }
            }
        }

        // Continue the path by sampling the BSDF.
        let Some(bs) = bsdf.sample(u.u_lobe, u.u_dir) else {
            return false;
        };
        let mut beta = beta * Vec3A::from(bs.weight);
        if beta == Vec3A::ZERO || !beta.is_finite() {
            return false;
        }
        path.prev = Some(Previous {
            p: si.p,
            bsdf_pdf: bs.pdf,
            delta: bs.delta,
        });
        path.ray = si.spawn_ray(bs.wi);
        path.depth += 1;
        if path.depth > self.rr_depth {
            let q = beta.max_element().min(0.95);
            if sampler.next_1d() >= q {
                return false;
            }
            beta /= q;
        }
        path.beta = beta;
        true
    }

    /// The value of a path that has ended (the clamp applied).
    #[inline(always)]
    pub fn finish(&self, path: &PathState) -> Vec3 {
        let l = Vec3::from(path.l);
        match self.clamp {
            Some(c) => l.min(Vec3::splat(c)),
            None => l,
        }
    }

    /// The MIS weight of the environment found by a ray leaving `prev` in direction `d`.
    fn environment_mis(&self, scene: &Scene, prev: Option<&Previous>, d: Vec3) -> f32 {
        let Some(pv) = prev else { return 1.0 };
        if pv.delta {
            return 1.0;
        }
        let Some(env_index) = scene.environment else {
            return 1.0;
        };
        let pick = scene.light_sampler.probability(env_index);
        if pick == 0.0 {
            return 1.0;
        }
        let Light::Environment(env) = &scene.lights[env_index] else {
            return 1.0;
        };
        power_heuristic(pv.bsdf_pdf, pick * env.pdf(d))
    }
}
