//! The closed set of shapes, dispatched by `match` in the hot path.

use super::{Cuboid, Cylinder, Disk, Plane, Rectangle, Sphere, SurfaceInteraction, TriangleMesh};
use crate::accel::RayStats;
use crate::math::{Bounds3, Ray};
use glam::Vec2;
use std::sync::Arc;

/// What a shape's intersection test returns: enough to rebuild the full interaction for
/// the closest hit only.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShapeHit {
    pub t: f32,
    /// Primitive within the shape (triangle, cylinder part, box face).
    pub prim: u32,
    /// Shape-specific coordinates: barycentrics (b1, b2) for triangles, the hit's x and y
    /// for planar shapes.
    pub uv: Vec2,
}

/// A shape in its own object space.
#[derive(Debug, Clone)]
pub enum Shape {
    Sphere(Sphere),
    Plane(Plane),
    Rectangle(Rectangle),
    Disk(Disk),
    Cuboid(Cuboid),
    Cylinder(Cylinder),
    TriangleMesh(Arc<TriangleMesh>),
}

impl Shape {
    /// Object-space bounds (infinite for the plane).
    pub fn bounds(&self) -> Bounds3 {
        match self {
            Shape::Sphere(s) => s.bounds(),
            Shape::Plane(s) => s.bounds(),
            Shape::Rectangle(s) => s.bounds(),
            Shape::Disk(s) => s.bounds(),
            Shape::Cuboid(s) => s.bounds(),
            Shape::Cylinder(s) => s.bounds(),
            Shape::TriangleMesh(s) => s.bounds(),
        }
    }

    /// Closest hit within `[ray.t_min, ray.t_max]`.
    #[inline]
    pub fn intersect(&self, ray: &Ray, stats: &mut RayStats) -> Option<ShapeHit> {
        match self {
            Shape::Sphere(s) => s.intersect(ray),
            Shape::Plane(s) => s.intersect(ray),
            Shape::Rectangle(s) => s.intersect(ray),
            Shape::Disk(s) => s.intersect(ray),
            Shape::Cuboid(s) => s.intersect(ray),
            Shape::Cylinder(s) => s.intersect(ray),
            Shape::TriangleMesh(s) => s.intersect(ray, stats),
        }
    }

    /// Whether anything blocks the ray within its range.
    #[inline]
    pub fn occluded(&self, ray: &Ray, stats: &mut RayStats) -> bool {
        match self {
            Shape::TriangleMesh(s) => s.occluded(ray, stats),
            _ => self.intersect(ray, stats).is_some(),
        }
    }

    /// The full interaction for a hit, in object space.
    pub fn interaction(&self, ray: &Ray, hit: &ShapeHit) -> SurfaceInteraction {
        match self {
            Shape::Sphere(s) => s.interaction(ray, hit),
            Shape::Plane(s) => s.interaction(ray, hit),
            Shape::Rectangle(s) => s.interaction(ray, hit),
            Shape::Disk(s) => s.interaction(ray, hit),
            Shape::Cuboid(s) => s.interaction(ray, hit),
            Shape::Cylinder(s) => s.interaction(ray, hit),
            Shape::TriangleMesh(s) => s.interaction(ray, hit),
        }
    }

    /// A short name for logs and statistics.
    pub fn kind_name(&self) -> &'static str {
        match self {
            Shape::Sphere(_) => "sphere",
            Shape::Plane(_) => "plane",
            Shape::Rectangle(_) => "rectangle",
            Shape::Disk(_) => "disk",
            Shape::Cuboid(_) => "cube",
            Shape::Cylinder(_) => "cylinder",
            Shape::TriangleMesh(_) => "mesh",
        }
    }
}
