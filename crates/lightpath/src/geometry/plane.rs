//! The infinite plane z = 0 with normal +z. Its uv are the x and y coordinates.
//!
//! ```xml
//! <instance>
//!     <shape type="plane"/>
//!     <transform><rotate axis="1,0,0" angle="-90"/></transform>
//! </instance>
//! ```

use super::{ShapeHit, SurfaceInteraction};
use crate::math::{gamma, Bounds3, Ray};
use glam::{Vec2, Vec3};

#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Plane;

/// Where a ray meets z = 0, with the hit point, if within the ray's range.
#[inline]
pub(super) fn intersect_z0(ray: &Ray) -> Option<(f32, Vec3)> {
    if ray.direction.z == 0.0 {
        return None;
    }
    let t = -ray.origin.z / ray.direction.z;
    if !(t > ray.t_min && t < ray.t_max) {
        return None;
    }
    let mut p = ray.at(t);
    p.z = 0.0;
    Some((t, p))
}

/// The interaction for a hit on z = 0 with normal +z.
#[inline]
pub(super) fn z0_interaction(
    ray: &Ray,
    hit: &ShapeHit,
    p: Vec3,
    uv: Vec2,
    dpdu: Vec3,
    dpdv: Vec3,
) -> SurfaceInteraction {
    SurfaceInteraction {
        p,
        // z is exact by construction; x and y carry the error of o + t d.
        p_error: Vec3::new(gamma(5) * p.x.abs(), gamma(5) * p.y.abs(), 0.0),
        t: hit.t,
        n: Vec3::Z,
        shading_n: Vec3::Z,
        dpdu,
        dpdv,
        uv,
        color: Vec3::ONE,
        wo: -ray.direction.normalize(),
        instance: 0,
        prim: 0,
    }
}

impl Plane {
    pub fn bounds(&self) -> Bounds3 {
        Bounds3 {
            min: Vec3::new(f32::NEG_INFINITY, f32::NEG_INFINITY, 0.0),
            max: Vec3::new(f32::INFINITY, f32::INFINITY, 0.0),
        }
    }

    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<ShapeHit> {
        let (t, _) = intersect_z0(ray)?;
        Some(ShapeHit {
            t,
            prim: 0,
            uv: Vec2::ZERO,
        })
    }

    pub fn interaction(&self, ray: &Ray, hit: &ShapeHit) -> SurfaceInteraction {
        let mut p = ray.at(hit.t);
        p.z = 0.0;
        z0_interaction(ray, hit, p, Vec2::new(p.x, p.y), Vec3::X, Vec3::Y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_hits() {
        let h = Plane
            .intersect(&Ray::new(Vec3::new(5.0, -7.0, 2.0), -Vec3::Z))
            .unwrap();
        assert_eq!(h.t, 2.0);
        let si = Plane.interaction(&Ray::new(Vec3::new(5.0, -7.0, 2.0), -Vec3::Z), &h);
        assert_eq!(si.p, Vec3::new(5.0, -7.0, 0.0));
        assert_eq!(si.n, Vec3::Z);
        assert!(Plane
            .intersect(&Ray::new(Vec3::new(0.0, 0.0, 2.0), Vec3::X))
            .is_none());
        assert!(Plane
            .intersect(&Ray::new(Vec3::new(0.0, 0.0, 2.0), Vec3::Z))
            .is_none());
        // From below.
        assert!(Plane
            .intersect(&Ray::new(Vec3::new(0.0, 0.0, -2.0), Vec3::Z))
            .is_some());
    }
}
