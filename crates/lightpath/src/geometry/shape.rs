//! The closed set of shapes, dispatched by `match` in the hot path.

use super::{
    Csg, CubicCurves, Cuboid, Cylinder, Disk, LinearCurves, Plane, Rectangle, Sphere,
    SurfaceInteraction, TriangleMesh,
};
use crate::accel::RayStats;
use crate::math::PI;
use crate::math::{Bounds3, Ray};
use crate::sampling::warp;
use glam::{Vec2, Vec3};
use std::sync::Arc;

/// What a shape's intersection test returns: enough to rebuild the full interaction for
/// the closest hit only.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShapeHit {
    pub t: f32,
    /// Primitive within the shape (triangle, cylinder part, box face; for CSG the leaf
    /// and its primitive, see [`Csg`]).
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
    Csg(Arc<Csg>),
    LinearCurves(Arc<LinearCurves>),
    CubicCurves(Arc<CubicCurves>),
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
            Shape::Csg(s) => s.bounds(),
            Shape::LinearCurves(s) => s.bounds(),
            Shape::CubicCurves(s) => s.bounds(),
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
            Shape::Csg(s) => s.intersect(ray, stats),
            Shape::LinearCurves(s) => s.intersect(ray, stats),
            Shape::CubicCurves(s) => s.intersect(ray, stats),
        }
    }

    /// Whether anything blocks the ray within its range.
    #[inline]
    pub fn occluded(&self, ray: &Ray, stats: &mut RayStats) -> bool {
        match self {
            Shape::TriangleMesh(s) => s.occluded(ray, stats),
            Shape::Csg(s) => s.intersect(ray, stats).is_some(),
            Shape::LinearCurves(s) => s.occluded(ray, stats),
            Shape::CubicCurves(s) => s.occluded(ray, stats),
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
            Shape::Csg(s) => s.interaction(ray, hit),
            Shape::LinearCurves(s) => s.interaction(ray, hit),
            Shape::CubicCurves(s) => s.interaction(ray, hit),
        }
    }

    /// A tight render-space box of the shape under `render_from_object`: exact for the
    /// analytic shapes (a rotated sphere's box is not the rotated box's box), and for
    /// meshes the union of the transformed boxes at the top of their BVH.
    pub fn render_bounds(&self, render_from_object: &crate::math::Transform) -> Bounds3 {
        let t = render_from_object;
        if !t.is_affine() {
            return t.bounds(&self.bounds());
        }
        let m = glam::Mat3::from_mat4(*t.matrix());
        // Half-extent per render axis of the unit circle in the object xy plane.
        let circle = Vec3::new(
            m.row(0).truncate().length(),
            m.row(1).truncate().length(),
            m.row(2).truncate().length(),
        );
        let disk_at = |z: f32| {
            let c = t.point(Vec3::new(0.0, 0.0, z));
            Bounds3::new(c - circle, c + circle)
        };
        match self {
            Shape::Sphere(_) => {
                let c = t.point(Vec3::ZERO);
                let e = Vec3::new(m.row(0).length(), m.row(1).length(), m.row(2).length());
                Bounds3::new(c - e, c + e)
            }
            Shape::Disk(_) => disk_at(0.0),
            Shape::Cylinder(_) => disk_at(0.0).union(&disk_at(1.0)),
            Shape::TriangleMesh(mesh) => mesh
                .accel
                .cover(64)
                .iter()
                .fold(Bounds3::EMPTY, |acc, b| acc.union(&t.bounds(b))),
            _ => t.bounds(&self.bounds()),
        }
    }

    /// Object-space surface area (infinite for the plane; NaN, unknown, for CSG and curves).
    pub fn area(&self) -> f32 {
        match self {
            Shape::Sphere(_) => 4.0 * PI,
            Shape::Plane(_) => f32::INFINITY,
            Shape::Rectangle(s) => s.area(),
            Shape::Disk(s) => s.area(),
            Shape::Cuboid(_) => 24.0,
            Shape::Cylinder(c) => {
                if c.caps {
                    4.0 * PI
                } else {
                    2.0 * PI
                }
            }
            Shape::TriangleMesh(m) => m.area(),
            Shape::Csg(_) | Shape::LinearCurves(_) | Shape::CubicCurves(_) => f32::NAN,
        }
    }

    /// A point on the surface, uniform in object-space area: its interaction (object
    /// space, `wo` along the normal) and the area density. `None` for the plane, CSG, curves and
    /// shapes without area. `u_prim` picks a cuboid's face or a cylinder's side or cap;
    /// meshes choose their triangle with `u.x` (see [`TriangleMesh::sample_area`]).
    pub fn sample_area(&self, u_prim: f32, u: Vec2) -> Option<(SurfaceInteraction, f32)> {
        let area = self.area();
        if !(area.is_finite() && area > 0.0) {
            return None;
        }
        let (p, n, hit) = match self {
            Shape::Sphere(_) => {
                let p = warp::square_to_uniform_sphere(u);
                (
                    p,
                    p,
                    ShapeHit {
                        t: 1.0,
                        prim: 0,
                        uv: Vec2::ZERO,
                    },
                )
            }
            Shape::Plane(_) | Shape::Csg(_) | Shape::LinearCurves(_) | Shape::CubicCurves(_) => {
                return None
            }
            Shape::Rectangle(_) => {
                let xy = u * 2.0 - Vec2::ONE;
                (
                    xy.extend(0.0),
                    Vec3::Z,
                    ShapeHit {
                        t: 1.0,
                        prim: 0,
                        uv: xy,
                    },
                )
            }
            Shape::Disk(_) => {
                let xy = warp::square_to_uniform_disk_concentric(u);
                (
                    xy.extend(0.0),
                    Vec3::Z,
                    ShapeHit {
                        t: 1.0,
                        prim: 0,
                        uv: xy,
                    },
                )
            }
            Shape::Cuboid(_) => {
                let face = ((u_prim * 6.0) as u32).min(5);
                let axis = (face / 2) as usize;
                let sign = if face % 2 == 1 { 1.0 } else { -1.0 };
                let (a1, a2) = ((axis + 1) % 3, (axis + 2) % 3);
                let mut p = Vec3::ZERO;
                p[axis] = sign;
                p[a1] = u.x * 2.0 - 1.0;
                p[a2] = u.y * 2.0 - 1.0;
                let mut n = Vec3::ZERO;
                n[axis] = sign;
                (
                    p,
                    n,
                    ShapeHit {
                        t: 1.0,
                        prim: face,
                        uv: Vec2::ZERO,
                    },
                )
            }
            Shape::Cylinder(c) => {
                // Side 2π, each cap π.
                let side = if c.caps { 0.5 } else { 1.0 };
                if u_prim < side {
                    let phi = 2.0 * PI * u.x;
                    let n = Vec3::new(phi.cos(), phi.sin(), 0.0);
                    (
                        n + Vec3::Z * u.y,
                        n,
                        ShapeHit {
                            t: 1.0,
                            prim: 0,
                            uv: Vec2::ZERO,
                        },
                    )
                } else {
                    let top = u_prim >= 0.75;
                    let xy = warp::square_to_uniform_disk_concentric(u);
                    let z = if top { 1.0 } else { 0.0 };
                    let n = if top { Vec3::Z } else { -Vec3::Z };
                    let prim = if top { 2 } else { 1 };
                    (
                        xy.extend(z),
                        n,
                        ShapeHit {
                            t: 1.0,
                            prim,
                            uv: Vec2::ZERO,
                        },
                    )
                }
            }
            Shape::TriangleMesh(m) => {
                let (hit, pdf) = m.sample_area(u)?;
                let ray = Ray::new(Vec3::ZERO, Vec3::Z);
                let si = m.interaction(&ray, &hit);
                return Some((SurfaceInteraction { wo: si.n, ..si }, pdf));
            }
        };
        // The analytic shapes rebuild their interaction from a ray that reaches `p` at t = 1.
        let ray = Ray::new(p + n, -n);
        let si = self.interaction(&ray, &hit);
        Some((SurfaceInteraction { wo: n, ..si }, 1.0 / area))
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
            Shape::Csg(_) => "csg",
            Shape::LinearCurves(_) => "curves",
            Shape::CubicCurves(_) => "cubic curves",
        }
    }
}
