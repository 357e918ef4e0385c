//! The immutable scene: instances of shapes in a top-level acceleration structure, the
//! camera, and (later) lights and materials.

mod builder;

pub use builder::SceneBuilder;

use crate::accel::{Accel, RayStats};
use crate::camera::Camera;
use crate::geometry::{Shape, ShapeHit, SurfaceInteraction};
use crate::math::{Bounds3, Ray, Transform};
use std::sync::Arc;

/// A shape placed in the scene.
#[derive(Debug, Clone)]
pub struct Instance {
    pub shape: Arc<Shape>,
    pub render_from_object: Transform,
    /// Render-space bounds.
    pub bounds: Bounds3,
}

impl Instance {
    pub fn new(shape: Arc<Shape>, render_from_object: Transform) -> Self {
        let bounds = render_from_object.bounds(&shape.bounds());
        Instance {
            shape,
            render_from_object,
            bounds,
        }
    }

    /// Closest hit in object space; the returned `t` is valid for the render-space ray
    /// because the object-space ray keeps the parameterisation.
    #[inline]
    fn intersect(&self, ray: &Ray, t_max: f32, stats: &mut RayStats) -> Option<ShapeHit> {
        let object_from_render = self.render_from_object.inverse();
        let r = Ray {
            origin: object_from_render.point(ray.origin),
            direction: object_from_render.vector(ray.direction),
            t_min: ray.t_min,
            t_max,
        };
        self.shape.intersect(&r, stats)
    }

    #[inline]
    fn occluded(&self, ray: &Ray, stats: &mut RayStats) -> bool {
        let object_from_render = self.render_from_object.inverse();
        let r = Ray {
            origin: object_from_render.point(ray.origin),
            direction: object_from_render.vector(ray.direction),
            ..*ray
        };
        self.shape.occluded(&r, stats)
    }

    /// The render-space interaction of a hit found by `intersect`.
    fn interaction(&self, ray: &Ray, hit: &ShapeHit) -> SurfaceInteraction {
        let object_from_render = self.render_from_object.inverse();
        let r = Ray {
            origin: object_from_render.point(ray.origin),
            direction: object_from_render.vector(ray.direction),
            ..*ray
        };
        let mut si = self
            .shape
            .interaction(&r, hit)
            .transformed(&self.render_from_object);
        si.wo = -ray.direction.normalize();
        si
    }
}

/// Everything needed to render: geometry, camera, and later lights and materials.
#[derive(Debug, Clone)]
pub struct Scene {
    pub instances: Vec<Instance>,
    /// Top-level accelerator over the bounded instances (indices into `bounded`).
    tlas: Accel,
    bounded: Vec<u32>,
    /// Instances with infinite bounds (planes), tested by every ray.
    unbounded: Vec<u32>,
    pub camera: Option<Camera>,
    bounds: Bounds3,
}

impl Scene {
    pub(crate) fn new(
        instances: Vec<Instance>,
        camera: Option<Camera>,
        accel: crate::accel::AccelKind,
    ) -> Scene {
        let finite = |b: &Bounds3| b.min.is_finite() && b.max.is_finite();
        let bounded: Vec<u32> = (0..instances.len() as u32)
            .filter(|&i| finite(&instances[i as usize].bounds))
            .collect();
        let unbounded: Vec<u32> = (0..instances.len() as u32)
            .filter(|&i| !finite(&instances[i as usize].bounds))
            .collect();
        let boxes: Vec<Bounds3> = bounded
            .iter()
            .map(|&i| instances[i as usize].bounds)
            .collect();
        let tlas = Accel::build(accel, &boxes);
        let bounds = boxes.iter().fold(Bounds3::EMPTY, |a, b| a.union(b));
        Scene {
            instances,
            tlas,
            bounded,
            unbounded,
            camera,
            bounds,
        }
    }

    /// Bounds of all bounded instances.
    pub fn bounds(&self) -> Bounds3 {
        self.bounds
    }

    /// The closest hit along the ray, with the full interaction.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<SurfaceInteraction> {
        self.intersect_with_stats(ray, &mut RayStats::default())
    }

    /// The closest hit, counting traversal work into `stats`.
    pub fn intersect_with_stats(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
    ) -> Option<SurfaceInteraction> {
        let mut best: Option<(u32, ShapeHit)> = None;
        let mut t_max = ray.t_max;
        for &i in &self.unbounded {
            if let Some(h) = self.instances[i as usize].intersect(ray, t_max, stats) {
                t_max = h.t;
                best = Some((i, h));
            }
        }
        let mut local_stats = RayStats::default();
        let ray_in = Ray { t_max, ..*ray };
        self.tlas.intersect(&ray_in, &mut local_stats, |k, t_max| {
            let i = self.bounded[k as usize];
            match self.instances[i as usize].intersect(ray, *t_max, stats) {
                Some(h) => {
                    *t_max = h.t;
                    best = Some((i, h));
                    true
                }
                None => false,
            }
        });
        // Top-level nodes count as nodes; instance tests are not primitive tests.
        stats.nodes_visited += local_stats.nodes_visited;
        let (i, hit) = best?;
        let mut si = self.instances[i as usize].interaction(ray, &hit);
        si.instance = i;
        si.prim = hit.prim;
        Some(si)
    }

    /// Whether anything blocks the ray within its range (shadow rays).
    pub fn occluded(&self, ray: &Ray) -> bool {
        let stats = &mut RayStats::default();
        if self
            .unbounded
            .iter()
            .any(|&i| self.instances[i as usize].occluded(ray, stats))
        {
            return true;
        }
        let mut local = RayStats::default();
        self.tlas.occluded(ray, &mut local, |k| {
            self.instances[self.bounded[k as usize] as usize].occluded(ray, stats)
        })
    }

    /// Bytes used by the top-level structure and every distinct mesh's BLAS.
    pub fn accel_memory_bytes(&self) -> usize {
        let mut seen = std::collections::HashSet::new();
        let mut total = self.tlas.memory_bytes();
        for inst in &self.instances {
            if let Shape::TriangleMesh(m) = &*inst.shape {
                if seen.insert(Arc::as_ptr(m)) {
                    total += m.accel.memory_bytes();
                }
            }
        }
        total
    }
}
