//! The immutable scene: instances of shapes in a top-level acceleration structure, the
//! camera, and (later) lights and materials.

mod builder;
mod merged;

pub use builder::SceneBuilder;
pub use merged::MergedMesh;

use crate::accel::{Accel, RayStats};
use crate::camera::Camera;
use crate::geometry::{MeshHits, Shape, ShapeHit, SurfaceInteraction, TriangleMesh};
use crate::light::{AreaLight, Emission, Light, LightSampler};
use crate::material::Material;
use crate::math::{Bounds3, Ray, Transform};
use glam::Vec3;
use std::sync::Arc;

/// Sizes and build times of the acceleration structures ([`Scene::accel_report`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct AccelReport {
    pub instances: usize,
    /// Instances in the top-level BVH (the rest are flattened or unbounded).
    pub tlas_instances: usize,
    pub tlas_bytes: usize,
    pub tlas_build_seconds: f64,
    /// Distinct bottom-level structures (shared meshes count once).
    pub blas_count: usize,
    pub blas_bytes: usize,
    pub blas_build_seconds: f64,
    pub blas_triangles: usize,
}

/// A shape placed in the scene.
#[derive(Debug, Clone)]
pub struct Instance {
    pub shape: Arc<Shape>,
    pub render_from_object: Transform,
    /// Render-space bounds.
    pub bounds: Bounds3,
    /// The surface's material; `None` absorbs all light.
    pub material: Option<Arc<Material>>,
    /// Light the surface emits (an area light).
    pub emission: Option<Emission>,
    /// Index in `Scene::lights` of the area light made from this instance.
    pub light: Option<u32>,
    /// How often next-event estimation picks that light, relative to a weight of 1 (0:
    /// never; its emission is then found by BSDF sampling alone).
    pub light_weight: f32,
    /// Whether the surface's normals point the other way (Mitsuba's `flip_normals`):
    /// its geometric and shading normals are negated, so a one-sided BSDF and an area
    /// light's emission face the other side.
    pub flip_normals: bool,
}

impl Instance {
    pub fn new(shape: Arc<Shape>, render_from_object: Transform) -> Self {
        let bounds = shape.render_bounds(&render_from_object);
        Instance {
            shape,
            render_from_object,
            bounds,
            material: None,
            emission: None,
            light: None,
            light_weight: 1.0,
            flip_normals: false,
        }
    }

    /// The ray in object space. `t` keeps its meaning because the direction is
    /// transformed without renormalising.
    #[inline]
    fn object_ray(&self, ray: &Ray) -> Ray {
        let object_from_render = self.render_from_object.inverse();
        Ray {
            origin: object_from_render.point(ray.origin),
            direction: object_from_render.vector(ray.direction),
            ..*ray
        }
    }

    /// Closest hit in object space within `[ray.t_min, t_max]`.
    #[inline]
    fn intersect(&self, ray: &Ray, t_max: f32, stats: &mut RayStats) -> Option<ShapeHit> {
        let r = Ray {
            t_max,
            ..self.object_ray(ray)
        };
        self.shape.intersect(&r, stats)
    }

    #[inline]
    fn occluded(&self, ray: &Ray, stats: &mut RayStats) -> bool {
        self.shape.occluded(&self.object_ray(ray), stats)
    }

    /// The render-space interaction of a hit found by `intersect`.
    fn interaction(&self, ray: &Ray, hit: &ShapeHit) -> SurfaceInteraction {
        let mut si = self
            .shape
            .interaction(&self.object_ray(ray), hit)
            .transformed(&self.render_from_object);
        si.wo = -ray.direction.normalize();
        if self.flip_normals {
            si.flip_normals();
        }
        si
    }
}

/// A rectangle of the camera's image, in pixels: its top-left corner and its size. Its
/// pixels render exactly as they do in the whole image (the same samples, filter and
/// camera rays); the image is the rectangle alone.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CropWindow {
    pub offset: glam::UVec2,
    pub size: glam::UVec2,
}

impl CropWindow {
    /// Whether the window holds a pixel and lies inside an image of `resolution`.
    pub fn fits(&self, resolution: glam::UVec2) -> bool {
        let end = self.offset.as_u64vec2() + self.size.as_u64vec2();
        self.size.x > 0
            && self.size.y > 0
            && end.x <= u64::from(resolution.x)
            && end.y <= u64::from(resolution.y)
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
    /// Meshes used by one instance each, flattened into render-space meshes.
    merged: Vec<MergedMesh>,
    pub camera: Option<Camera>,
    /// The film's pixel reconstruction filter.
    pub filter: crate::film::Filter,
    /// Near and far clip distances along the camera's viewing axis (Mitsuba's
    /// `near_clip`/`far_clip`); `None`: no clipping.
    pub clip: Option<(f32, f32)>,
    /// The part of the camera's image that is rendered (Mitsuba's film crop, a render
    /// region); `None`: all of it.
    pub crop: Option<CropWindow>,
    bounds: Bounds3,
    /// Lights for next-event estimation and the environment.
    pub lights: Vec<Light>,
    pub light_sampler: LightSampler,
    /// Index in `lights` of the environment, if any.
    pub environment: Option<usize>,
}

/// A closest hit found by [`Scene::intersect_batch`], not yet made into its interaction
/// ([`Scene::batch_interaction`]): small, so that batches of hits stay cheap to move.
#[derive(Debug, Clone)]
pub struct BatchHit(BatchHitKind);

#[derive(Debug, Clone)]
enum BatchHitKind {
    /// A triangle of the scene's one merged mesh.
    Merged(ShapeHit),
    /// Any hit, traced ray by ray.
    Interaction(Box<SurfaceInteraction>),
}

impl Scene {
    pub(crate) fn new(
        instances: Vec<Instance>,
        camera: Option<Camera>,
        accel: crate::accel::AccelKind,
    ) -> Scene {
        let finite = |b: &Bounds3| b.min.is_finite() && b.max.is_finite();
        let (merged, is_merged) = MergedMesh::build(&instances, accel);
        let bounded: Vec<u32> = (0..instances.len() as u32)
            .filter(|&i| finite(&instances[i as usize].bounds) && !is_merged[i as usize])
            .collect();
        let unbounded: Vec<u32> = (0..instances.len() as u32)
            .filter(|&i| !finite(&instances[i as usize].bounds))
            .collect();
        let boxes: Vec<Bounds3> = bounded
            .iter()
            .map(|&i| instances[i as usize].bounds)
            .collect();
        let tlas = Accel::build(accel, &boxes);
        let bounds = boxes
            .iter()
            .chain(
                merged
                    .iter()
                    .map(|m| m.mesh.bounds())
                    .collect::<Vec<_>>()
                    .iter(),
            )
            .fold(Bounds3::EMPTY, |a, b| a.union(b));
        let light_sampler = LightSampler::new(&[], &[], &bounds);
        Scene {
            instances,
            tlas,
            bounded,
            unbounded,
            merged,
            camera,
            filter: crate::film::Filter::Box,
            clip: None,
            crop: None,
            bounds,
            lights: Vec::new(),
            light_sampler,
            environment: None,
        }
    }

    /// Sets the lights; `weights[i]` scales how often light `i` is picked for next-event
    /// estimation (0: never). Every instance with an emission becomes an area light of
    /// its `light_weight` after them (area lights in `lights` are dropped, except those that are
    /// not scene geometry, [`AreaLight::unplaced`]). Fails if there is more than one
    /// environment.
    pub fn set_lights(&mut self, lights: Vec<Light>, weights: &[f32]) -> Result<(), String> {
        let (mut lights, mut weights): (Vec<Light>, Vec<f32>) = lights
            .into_iter()
            .zip(weights.iter().copied().chain(std::iter::repeat(1.0)))
            .filter(|(l, _)| !matches!(l, Light::Area(a) if a.placed))
            .unzip();
        for inst in &mut self.instances {
            inst.light = None;
            if let Some(e) = &inst.emission {
                if !inst.shape.area().is_finite() {
                    return Err(format!(
                        "a {} cannot emit light: it has no finite area that can be sampled",
                        inst.shape.kind_name()
                    ));
                }
                inst.light = Some(lights.len() as u32);
                let light = AreaLight::new(inst.shape.clone(), inst.render_from_object, e.clone());
                lights.push(Light::Area(if inst.flip_normals {
                    light.with_flipped_normals()
                } else {
                    light
                }));
                weights.push(inst.light_weight);
            }
        }
        let weights = &weights[..];
        let envs: Vec<usize> = (0..lights.len())
            .filter(|&i| matches!(lights[i], Light::Environment(_)))
            .collect();
        if envs.len() > 1 {
            return Err("a scene can have only one environment light".into());
        }
        self.environment = envs.first().copied();
        self.light_sampler = LightSampler::new(&lights, weights, &self.bounds);
        self.lights = lights;
        Ok(())
    }

    /// Radiance arriving along a ray that leaves the scene in direction `d`.
    #[inline]
    pub fn background(&self, d: glam::Vec3) -> glam::Vec3 {
        match self.environment.map(|i| &self.lights[i]) {
            Some(Light::Environment(e)) => e.eval(d),
            _ => glam::Vec3::ZERO,
        }
    }

    /// Radiance emitted by the surface at `si` towards `w` (unit, leaving the surface).
    #[inline]
    pub fn emitted(&self, si: &SurfaceInteraction, w: glam::Vec3) -> glam::Vec3 {
        match &self.instances[si.instance as usize].emission {
            Some(e) => e.eval(si, w),
            None => glam::Vec3::ZERO,
        }
    }

    /// The material at a hit: the CSG leaf's own when it has one, else the instance's.
    /// `None` absorbs all light.
    #[inline]
    pub fn material(&self, si: &SurfaceInteraction) -> Option<&Material> {
        let inst = &self.instances[si.instance as usize];
        if let Shape::Csg(csg) = &*inst.shape {
            if let Some(m) = csg.leaf_material(si.prim) {
                return Some(m);
            }
        }
        inst.material.as_deref()
    }

    /// Solid-angle density with which next-event estimation from `p` (light selection
    /// included) picks the emitter hit at `si` by a ray in direction `wi`.
    pub fn emitter_pdf(&self, p: glam::Vec3, si: &SurfaceInteraction, wi: glam::Vec3) -> f32 {
        let Some(index) = self.instances[si.instance as usize].light else {
            return 0.0;
        };
        let pick = self.light_sampler.probability(index as usize);
        if pick == 0.0 {
            return 0.0;
        }
        match &self.lights[index as usize] {
            Light::Area(a) => pick * a.pdf(p, si, wi),
            _ => 0.0,
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

    /// The closest hit, counting traversal work into `stats`. The interaction's `wo` is
    /// exactly `-ray.direction.normalize()`.
    #[inline(always)]
    pub fn intersect_with_stats(
        &self,
        ray: &Ray,
        stats: &mut RayStats,
    ) -> Option<SurfaceInteraction> {
        stats.rays += 1;
        if let ([m], true) = (&self.merged[..], self.only_merged()) {
            // All the geometry in one merged mesh (the common case of scenes made of
            // triangle meshes): one query, no instance bookkeeping.
            let hit = m.intersect(ray, stats)?;
            return Some(m.interaction(ray, &hit));
        }
        let mut best: Option<(u32, ShapeHit)> = None;
        let mut t_max = ray.t_max;
        let mut merged_hit: Option<(usize, ShapeHit)> = None;
        for (k, m) in self.merged.iter().enumerate() {
            // Until a hit shortens it, the range is the ray's own: pass the ray itself
            // rather than a copy (the copy's mixed-width stores stall the loads that
            // set up the triangle test).
            let h = if merged_hit.is_none() {
                m.intersect(ray, stats)
            } else {
                m.intersect(&Ray { t_max, ..*ray }, stats)
            };
            if let Some(h) = h {
                t_max = h.t;
                merged_hit = Some((k, h));
            }
        }
        for &i in &self.unbounded {
            if let Some(h) = self.instances[i as usize].intersect(ray, t_max, stats) {
                t_max = h.t;
                best = Some((i, h));
            }
        }
        if !self.bounded.is_empty() {
            let ray_in = Ray { t_max, ..*ray };
            self.tlas
                .intersect(&ray_in, &mut RayStats::default(), |k, t_max| {
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
        }
        // The counters record bottom-level work only (as the course's `bvh` view does):
        // top-level nodes and instance tests are not counted.
        let Some((i, hit)) = best else {
            let (k, hit) = merged_hit?;
            return Some(self.merged[k].interaction(ray, &hit));
        };
        let mut si = self.instances[i as usize].interaction(ray, &hit);
        si.instance = i;
        si.prim = hit.prim;
        Some(si)
    }

    /// Whether [`Scene::intersect_batch`] and [`Scene::occluded_batch`] trace packets of
    /// rays together here (all the geometry in one merged `bvh8` mesh, on a processor
    /// with AVX-512), which pays for gathering rays into batches; elsewhere they trace
    /// ray by ray.
    pub fn traces_packets(&self) -> bool {
        matches!((&self.merged[..], self.only_merged()), ([m], true) if m.mesh.traces_packets())
    }

    /// Whether the renderer's path tracer advances many paths together here, gathering
    /// their rays into batches ([`Scene::intersect_batch`]) and their diffuse vertices
    /// into lanes: all the geometry is one merged triangle mesh, whose batches run as
    /// packets where [`Scene::traces_packets`] and ray by ray elsewhere.
    pub fn advances_paths_together(&self) -> bool {
        matches!((&self.merged[..], self.only_merged()), ([_], true))
    }

    /// The merged mesh's triangles, in render space, where all the geometry is one
    /// merged mesh ([`Scene::advances_paths_together`]): its positions and its vertex
    /// indices, in the order of the triangle ids of [`Scene::intersect_batch`]'s hits.
    pub fn merged_triangles(&self) -> Option<(&[Vec3], &[[u32; 3]])> {
        match (&self.merged[..], self.only_merged()) {
            ([m], true) => Some((&m.mesh.positions, &m.mesh.indices)),
            _ => None,
        }
    }

    /// The closest hits of many rays (`hits[i]` for `rays[i]`), as
    /// [`Scene::intersect_with_stats`] finds them one by one: the same distances, but
    /// where two triangles are hit at exactly the same distance either may be reported.
    /// [`Scene::batch_interaction`] makes a hit into its interaction.
    pub fn intersect_batch(
        &self,
        rays: &[Ray],
        hits: &mut [Option<BatchHit>],
        stats: &mut RayStats,
    ) {
        assert_eq!(rays.len(), hits.len(), "one hit per ray");
        if let ([m], true) = (&self.merged[..], self.only_merged()) {
            // Packets of sixteen rays (`crate::accel::PACKET` where packets run).
            const N: usize = 16;
            for (rays, hits) in rays.chunks(N).zip(hits.chunks_mut(N)) {
                let mut found = [None; N];
                // The rays are counted here whether or not the mesh counts them.
                let counted = stats.rays;
                m.mesh
                    .intersect_packets(rays, &mut found[..rays.len()], stats);
                stats.rays = counted + rays.len() as u32;
                for (hit, found) in hits.iter_mut().zip(found) {
                    *hit = found.map(|h| BatchHit(BatchHitKind::Merged(h)));
                }
            }
            return;
        }
        for (ray, hit) in rays.iter().zip(hits.iter_mut()) {
            *hit = self
                .intersect_with_stats(ray, stats)
                .map(|si| BatchHit(BatchHitKind::Interaction(Box::new(si))));
        }
    }

    /// The interaction of a hit that [`Scene::intersect_batch`] found for `ray`: the
    /// same as [`Scene::intersect_with_stats`] gives for the hit.
    #[inline(always)]
    pub fn batch_interaction(&self, ray: &Ray, hit: BatchHit) -> SurfaceInteraction {
        match hit.0 {
            BatchHitKind::Merged(h) => self.merged[0].interaction(ray, &h),
            BatchHitKind::Interaction(si) => *si,
        }
    }

    /// The closest hits of many rays where all the scene's geometry is one merged mesh
    /// ([`Scene::merged_triangle_count`]), as [`Scene::intersect_batch`] finds them, into
    /// `hits` (their triangles index the merged mesh).
    pub(crate) fn intersect_merged(&self, rays: &[Ray], hits: &mut MeshHits, stats: &mut RayStats) {
        let ([m], true) = (&self.merged[..], self.only_merged()) else {
            panic!("intersect_merged needs a scene that is one merged mesh");
        };
        // The rays are counted here whether or not the mesh counts them.
        let counted = stats.rays;
        m.mesh.intersect_to(rays, hits, stats);
        stats.rays = counted + rays.len() as u32;
    }

    /// The triangles of the scene's merged mesh, where all its geometry is that mesh
    /// (the hits [`Scene::intersect_batch`] gives are then all on it).
    pub(crate) fn merged_triangle_count(&self) -> Option<usize> {
        match (&self.merged[..], self.only_merged()) {
            ([m], true) => Some(m.mesh.triangle_count()),
            _ => None,
        }
    }

    /// Merged triangle `k`: the mesh that builds its interaction, its index there, and
    /// its instance.
    #[inline(always)]
    pub(crate) fn merged_triangle(&self, k: u32) -> (&TriangleMesh, u32, u32) {
        self.merged[0].triangle(k)
    }

    /// The interaction of a hit on the merged mesh (see [`Scene::intersect_merged`]).
    #[inline]
    pub(crate) fn merged_interaction(&self, ray: &Ray, hit: &ShapeHit) -> SurfaceInteraction {
        self.merged[0].interaction(ray, hit)
    }

    /// Whether anything blocks each of many shadow rays (`occluded[i]` for `rays[i]`),
    /// as [`Scene::occluded_with_stats`] answers one by one.
    pub fn occluded_batch(&self, rays: &[Ray], occluded: &mut [bool], stats: &mut RayStats) {
        assert_eq!(rays.len(), occluded.len(), "one answer per ray");
        if let ([m], true) = (&self.merged[..], self.only_merged()) {
            // The rays are counted here whether or not the mesh counts them.
            let counted = stats.rays;
            m.mesh.occluded_packets(rays, occluded, stats);
            stats.rays = counted + rays.len() as u32;
            stats.shadow_rays += rays.len() as u32;
            return;
        }
        for (ray, o) in rays.iter().zip(occluded.iter_mut()) {
            *o = self.occluded_with_stats(ray, stats);
        }
    }

    /// Whether the merged meshes are all the geometry (no other instances).
    #[inline]
    fn only_merged(&self) -> bool {
        self.bounded.is_empty() && self.unbounded.is_empty()
    }

    /// Whether anything blocks the ray within its range (shadow rays).
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.occluded_with_stats(ray, &mut RayStats::default())
    }

    /// `occluded`, counting the ray into `stats`.
    #[inline(always)]
    pub fn occluded_with_stats(&self, ray: &Ray, stats: &mut RayStats) -> bool {
        stats.rays += 1;
        stats.shadow_rays += 1;
        if let ([m], true) = (&self.merged[..], self.only_merged()) {
            return m.occluded(ray, stats);
        }
        if self.merged.iter().any(|m| m.occluded(ray, stats)) {
            return true;
        }
        if self
            .unbounded
            .iter()
            .any(|&i| self.instances[i as usize].occluded(ray, stats))
        {
            return true;
        }
        if self.bounded.is_empty() {
            return false;
        }
        let mut local = RayStats::default();
        self.tlas.occluded(ray, &mut local, |k| {
            self.instances[self.bounded[k as usize] as usize].occluded(ray, stats)
        })
    }

    /// Sizes and build times of the two levels: the top-level structure over instances
    /// and the bottom-level structures of the distinct meshes and curves (the flattened
    /// meshes count as bottom level).
    pub fn accel_report(&self) -> AccelReport {
        let mut seen = std::collections::HashSet::new();
        let mut r = AccelReport {
            instances: self.instances.len(),
            tlas_instances: self.bounded.len(),
            tlas_bytes: self.tlas.memory_bytes(),
            tlas_build_seconds: self.tlas.build_seconds(),
            ..Default::default()
        };
        let mut flattened = vec![false; self.instances.len()];
        for m in &self.merged {
            for &i in m.instances() {
                flattened[i as usize] = true;
            }
            r.blas_count += 1;
            r.blas_bytes += m.memory_bytes();
            r.blas_build_seconds += m.mesh.accel.build_seconds();
            r.blas_triangles += m.mesh.triangle_count();
        }
        for (i, inst) in self.instances.iter().enumerate() {
            // (bytes, build seconds, triangles) of a distinct bottom level.
            let blas = match &*inst.shape {
                Shape::TriangleMesh(m) if !flattened[i] => {
                    seen.insert(Arc::as_ptr(m) as *const ()).then(|| {
                        (
                            m.accel_memory_bytes(),
                            m.accel.build_seconds(),
                            m.triangle_count(),
                        )
                    })
                }
                Shape::LinearCurves(c) => seen
                    .insert(Arc::as_ptr(c) as *const ())
                    .then(|| (c.memory_bytes(), c.build_seconds(), 0)),
                Shape::CubicCurves(c) => seen
                    .insert(Arc::as_ptr(c) as *const ())
                    .then(|| (c.memory_bytes(), c.build_seconds(), 0)),
                _ => None,
            };
            if let Some((bytes, seconds, triangles)) = blas {
                r.blas_count += 1;
                r.blas_bytes += bytes;
                r.blas_build_seconds += seconds;
                r.blas_triangles += triangles;
            }
        }
        r
    }

    /// Bytes used by the top-level structure and every distinct mesh's and curve set's
    /// BLAS.
    pub fn accel_memory_bytes(&self) -> usize {
        let mut seen = std::collections::HashSet::new();
        let mut total =
            self.tlas.memory_bytes() + self.merged.iter().map(|m| m.memory_bytes()).sum::<usize>();
        for inst in &self.instances {
            total += match &*inst.shape {
                Shape::TriangleMesh(m) if seen.insert(Arc::as_ptr(m) as *const ()) => {
                    m.accel_memory_bytes()
                }
                Shape::LinearCurves(c) if seen.insert(Arc::as_ptr(c) as *const ()) => {
                    c.memory_bytes()
                }
                Shape::CubicCurves(c) if seen.insert(Arc::as_ptr(c) as *const ()) => {
                    c.memory_bytes()
                }
                _ => 0,
            };
        }
        total
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Cuboid, Cylinder, Disk, Rectangle, Sphere, TriangleMesh};
    use crate::math::Transform;
    use crate::sampling::{warp, Pcg32};
    use crate::scene::SceneBuilder;
    use glam::{Vec2, Vec3};

    fn random_transform(rng: &mut Pcg32) -> Transform {
        let s = Vec3::new(
            rng.next_f32() * 3.0 + 0.2,
            rng.next_f32() * 3.0 + 0.2,
            rng.next_f32() * 3.0 + 0.2,
        );
        let flip = if rng.next_f32() < 0.3 {
            Vec3::new(-1.0, 1.0, 1.0)
        } else {
            Vec3::ONE
        };
        let axis = warp::square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
        let t = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * 20.0;
        Transform::scale(s * flip)
            .unwrap()
            .then(&Transform::rotate(axis, rng.next_f32() * 360.0).unwrap())
            .then(&Transform::translate(t))
    }

    /// Rays spawned from a hit, to either side, never hit the surface they leave at a
    /// distance that is only rounding error (no acne), for every shape under random
    /// scale, mirror, rotation and translation.
    #[test]
    fn spawned_rays_do_not_self_intersect() {
        let mesh = TriangleMesh::new(
            crate::geometry::MeshData {
                positions: vec![
                    Vec3::new(-1.0, -1.0, 0.0),
                    Vec3::new(1.0, -1.0, 0.0),
                    Vec3::new(0.0, 1.0, 0.3),
                ],
                normals: vec![],
                uvs: vec![],
                indices: vec![[0, 1, 2]],
                colors: Vec::new(),
                face_colors: Vec::new(),
            },
            false,
            crate::accel::AccelKind::Bvh2,
        )
        .unwrap();
        let shapes = [
            Shape::Sphere(Sphere),
            Shape::Rectangle(Rectangle),
            Shape::Disk(Disk),
            Shape::Cuboid(Cuboid),
            Shape::Cylinder(Cylinder { caps: true }),
            Shape::TriangleMesh(std::sync::Arc::new(mesh)),
        ];
        let mut rng = Pcg32::new(5, 9);
        let mut acne = 0;
        let mut spawned = 0;
        for shape in &shapes {
            for _ in 0..200 {
                let mut b = SceneBuilder::new();
                let id = b.add_shape(shape.clone());
                let to = random_transform(&mut rng);
                b.add_instance(id, to);
                let scene = b.build();
                let centre = to.point(Vec3::ZERO);
                for _ in 0..50 {
                    let o = centre
                        + warp::square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()))
                            * 30.0;
                    let target = to.point(
                        (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * 1.6,
                    );
                    let Some(si) = scene.intersect(&Ray::new(o, target - o)) else {
                        continue;
                    };
                    for side in [1.0f32, -1.0] {
                        let n = si.n * side;
                        let w = crate::math::Frame::from_normal(n).to_world(
                            warp::square_to_cosine_hemisphere(Vec2::new(
                                rng.next_f32(),
                                rng.next_f32(),
                            )),
                        );
                        spawned += 1;
                        if let Some(h) = scene.intersect(&si.spawn_ray(w)) {
                            // Another face of a box or cylinder may legitimately be that close
                            // near an edge: only the same primitive counts as acne.
                            let near =
                                (h.p - si.p).length() < 1e-4 * (1.0 + si.p.abs().max_element());
                            if near && h.prim == si.prim {
                                eprintln!("acne on {}: {:?} -> {:?}", shape.kind_name(), si.p, h.p);
                                acne += 1;
                            }
                        }
                    }
                }
            }
        }
        assert!(spawned > 10_000, "{spawned}");
        assert_eq!(
            acne, 0,
            "{acne} of {spawned} spawned rays re-hit their own surface"
        );
    }

    /// Instance boxes contain the whole transformed shape and are tight: surface samples
    /// reach every face of the box (within 2% of its size) for the analytic shapes, and a
    /// rotated mesh's box is smaller than the box of its rotated object box.
    #[test]
    fn instance_bounds_are_conservative_and_tight() {
        let mut rng = Pcg32::new(8, 1);
        let mut data = crate::geometry::MeshData::default();
        for i in 0..200 {
            let a = i as f32 * 0.0314;
            let p = Vec3::new(a.cos(), a.sin(), (i as f32 / 200.0) * 2.0 - 1.0);
            data.positions.extend([p, p * 0.95, p + Vec3::Z * 0.01]);
            data.indices.push([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        let mesh = TriangleMesh::new(data, false, crate::accel::AccelKind::Bvh2).unwrap();
        let shapes = [
            Shape::Sphere(Sphere),
            Shape::Disk(Disk),
            Shape::Cylinder(Cylinder { caps: true }),
            Shape::Cuboid(Cuboid),
            Shape::Rectangle(Rectangle),
            Shape::TriangleMesh(std::sync::Arc::new(mesh)),
        ];
        for shape in &shapes {
            for _ in 0..20 {
                let t = random_transform(&mut rng);
                let b = shape.render_bounds(&t);
                let mut reach = Bounds3::EMPTY;
                for _ in 0..4000 {
                    let (si, _) = shape
                        .sample_area(rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()))
                        .unwrap();
                    let p = t.point(si.p);
                    let slack = 1e-4 * (1.0 + p.abs().max_element());
                    assert!(
                        (p - b.min).min_element() >= -slack && (b.max - p).min_element() >= -slack,
                        "{}: {p:?} outside {b:?}",
                        shape.kind_name()
                    );
                    reach.expand(p);
                }
                let size = b.diagonal().max_element();
                let gap = (reach.min - b.min).max(b.max - reach.max).max_element();
                if !matches!(shape, Shape::TriangleMesh(_)) {
                    assert!(
                        gap < 0.02 * size,
                        "{}: box not tight, gap {gap}",
                        shape.kind_name()
                    );
                } else {
                    let loose = t.bounds(&shape.bounds());
                    assert!(b.surface_area() <= loose.surface_area() * 1.0001);
                }
            }
        }
    }

    #[test]
    fn shadow_rays_stop_before_their_target() {
        let mut b = SceneBuilder::new();
        let s = b.add_shape(Shape::Rectangle(Rectangle));
        b.add_instance(s, Transform::IDENTITY);
        let scene = b.build();
        let si = scene
            .intersect(&Ray::new(Vec3::new(0.2, 0.1, 3.0), -Vec3::Z))
            .unwrap();
        // A target on the same plane is not blocked by it, one behind it is.
        assert!(!scene.occluded(&si.spawn_ray_to(Vec3::new(5.0, 5.0, 1.0))));
        let other = scene
            .intersect(&Ray::new(Vec3::new(0.5, 0.5, -3.0), Vec3::Z))
            .unwrap();
        assert!(!scene.occluded(&si.spawn_ray_to(other.p)) || other.p.z.abs() < 1e-6);
        assert!(scene.occluded(&Ray::with_range(
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.0, 0.0, -2.0),
            0.0,
            1.0
        )));
    }
}
